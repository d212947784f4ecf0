"""``cnnslam contact-sheet``: render RGB / depth / labels of a few frames of named sequences into one PNG."""

from __future__ import annotations

import argparse

from sim_envs.tools.contact_sheet import DEFAULT_FRACTIONS, DEFAULT_SEQUENCES, make_contact_sheet


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of the command."""
    parser.add_argument("--out", default="results/contact_sheet.png", help="PNG to write (default: %(default)s)")
    parser.add_argument(
        "--sequences",
        nargs="+",
        default=list(DEFAULT_SEQUENCES),
        metavar="NAME",
        help="named sequences, one row group each (default: %(default)s)",
    )
    parser.add_argument(
        "--fractions",
        nargs="+",
        type=float,
        default=list(DEFAULT_FRACTIONS),
        metavar="F",
        help="where in each sequence to take a frame, 0..1 (default: %(default)s)",
    )
    parser.add_argument("--renderer", choices=("mujoco", "pyrender"), default="mujoco", help="render backend")
    parser.add_argument("--dpi", type=int, default=110, help="resolution of the PNG (default: %(default)s)")


def run(args: argparse.Namespace) -> int:
    """Render and write the sheet; print where it went."""
    path = make_contact_sheet(args.out, args.sequences, args.fractions, args.renderer, args.dpi)
    from slamcommon.provenance import record_outputs  # what made the sheet: `cnnslam results status`

    record_outputs([path], "cnnslam contact-sheet", ["sim_envs.tools.contact_sheet"])
    print(f"wrote {path}")
    return 0
