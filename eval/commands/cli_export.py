"""``cnnslam export SEQUENCE FOLDER``: write a registered simulated sequence as a TUM RGB-D folder.

The folder layout (rgb/, depth/ 16-bit x5000, labels/, instances/, rgb.txt, depth.txt, groundtruth.txt and the
``cnnslam.json`` side file with the intrinsics) is described in :mod:`sim_envs.datasets`. The sequence registry
(:mod:`sim_envs.sequences`) and the renderers are imported only when the command runs. The folder is written under a
temporary name and renamed at the end (:func:`sim_envs.datasets.export_tum_rgbd`): Ctrl-C leaves nothing in the way
of the next export. Exit status: 0 written, 1 the export failed, 2 a bad argument (an unknown sequence, a file where
the folder goes, a camera or lighting that does not exist), 130 on Ctrl-C.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from sim_envs.camera_effects import DEFAULT_CAMERA_EFFECTS
from sim_envs.datasets import export_tum_rgbd
from sim_envs.errors import SimEnvError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("sequence", help="a registered sequence name (see sim_envs.sequences), maybe with the room "
                                         "marks +lit / +rich (office0+rich)")
    parser.add_argument("folder", help="output folder (must not exist or be empty, unless --overwrite)")
    parser.add_argument("--renderer", default="mujoco", help="renderer backend (default: mujoco)")
    parser.add_argument("--frames", type=int, default=None, help="export only the first N frames")
    parser.add_argument("--camera-effects", default=DEFAULT_CAMERA_EFFECTS, metavar="PRESET",
                        help=f"simulated camera (sim_envs.camera_effects): {DEFAULT_CAMERA_EFFECTS} (default, the "
                             "one the suites score), clean (the renderer's images) or hard; a non-clean camera also "
                             "writes its photometric calibration (times.txt, pcalib.txt, vignette.png) and camera "
                             "files")  # fmt: skip
    parser.add_argument("--lighting", default="flat", metavar="LIGHTING",
                        help="flat (default) or lit: the room with lamps, shadows and highlights "
                             "(sim_envs/lighting.py; mujoco renderer only)")  # fmt: skip
    parser.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def open_sequence(name: str, renderer: str, camera_effects: str = DEFAULT_CAMERA_EFFECTS, lighting: str = "flat",
                  ) -> Any:
    """A registered sequence, maybe with room variant marks (``office0+rich``, ``office0+lit``:
    :func:`sim_envs.sequences.variant_spec`), seen through the ``camera_effects`` preset in its room lit
    ``lighting``, as a frame source (lazy imports: the registry pulls in scenes and renderers)."""
    from dataclasses import replace

    from sim_envs.sequences import variant_spec, with_camera
    from sim_envs.simsource import SimulatedSequence

    spec = variant_spec(name)
    spec = with_camera(spec, camera_effects) if camera_effects != "clean" else spec
    spec = replace(spec, lighting=lighting) if lighting != "flat" else spec
    return SimulatedSequence(spec, renderer=renderer)


def run(args: argparse.Namespace) -> int:
    folder = Path(args.folder)
    if folder.exists() and not folder.is_dir():  # refused before anything renders
        print(f"cnnslam export: error: {folder} is a file; an export writes a folder: name a folder that does not "
              "exist yet", file=sys.stderr)  # fmt: skip
        return 2
    try:  # the sequence, its camera and lighting: bad arguments are found before anything renders
        source = open_sequence(args.sequence, args.renderer, args.camera_effects, args.lighting)
    except SimEnvError as exc:
        print(f"cnnslam export: error: {exc}", file=sys.stderr)
        return 2
    try:
        written = export_tum_rgbd(source, folder, overwrite=args.overwrite, progress=not args.no_progress,
                                  max_frames=args.frames)  # fmt: skip
    except SimEnvError as exc:
        print(f"cnnslam export: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"cnnslam export: interrupted; no partial export was left at {folder} (a new folder appears only "
              "when complete)", file=sys.stderr)  # fmt: skip
        return 130
    finally:
        source.close()
    print(f"exported {args.sequence} to {written}")
    return 0
