"""The ``cnnslam`` command: one entry point, one module per subcommand, imported only when used.

Each subcommand module provides ``add_arguments(parser: argparse.ArgumentParser) -> None`` and
``run(args: argparse.Namespace) -> int``. Modules are loaded lazily so that ``cnnslam eval`` does not pay for
importing torch or OpenGL.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# name -> (module, one-line help). Command lines sit at the edge: the judge's commands live in eval, the world's in
# sim_envs, the network's in cnnslam.depthnet.
SUBCOMMANDS: dict[str, tuple[str, str]] = {}


def register(name: str, module: str, help_text: str) -> None:
    """Add a subcommand (used by the table below; kept as a function so the table stays one line per command)."""
    SUBCOMMANDS[name] = (module, help_text)


register("eval", "eval.commands.cli_eval", "score an estimated trajectory against ground truth (like evo_ape)")
register("regress", "eval.commands.cli_regress", "compare a run's metrics with a committed baseline (regression gate)")
register("export", "eval.commands.cli_export", "write a registered sequence as a TUM RGB-D folder")
register("reference", "eval.commands.cli_reference",
         "an SfM reference (COLMAP, self-calibrated camera) for a real RGB-D folder")
register("contact-sheet", "sim_envs.cli_contact_sheet", "render RGB / depth / labels of named sequences to a PNG")
register("bench-render", "sim_envs.bench_render", "render throughput of the MuJoCo and pyrender renderers (fps)")
register("train", "cnnslam.depthnet.cli_train", "depth network: generate data, train, validate, export")
register("bench-slam", "cnnslam.bench_slam", "CNN-SLAM speed: tracking and whole-system frames per second")
register("bench", "eval.commands.cli_bench",
         "run a benchmark suite (table1, lengths, transfer, preprocessing, quick, ...)")
register("generate", "eval.commands.cli_generate",
         "generate rotation stress sequences (and export them as TUM RGB-D folders)")
register("config", "eval.commands.cli_config",
         "print the exact configuration a method's runs use (with --set overrides)")
register("map", "cnnslam.cli_map", "run an agent, fuse its key-frames into the global model: PLY, pictures, metrics")


def _top_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cnnslam",
        description="CNN-SLAM simulation and evaluation harness. Run 'cnnslam COMMAND --help' for a command's options.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in SUBCOMMANDS.items():
        sub.add_parser(name, help=help_text, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` (default ``sys.argv[1:]``), run the subcommand, return its exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in SUBCOMMANDS:
        parser = _top_parser()
        if argv and not argv[0].startswith("-"):
            parser.error(f"unknown command {argv[0]!r}; valid commands: {', '.join(SUBCOMMANDS)}")
        parser.parse_args(argv)  # prints --help, or the usage error
        parser.print_help()
        return 2
    name = argv[0]
    module_name, help_text = SUBCOMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"cnnslam {name}", description=help_text)
    module.add_arguments(parser)
    args = parser.parse_args(argv[1:])
    return int(module.run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
