"""The ``cnnslam`` command: one entry point, one module per subcommand, imported only when used.

Each subcommand module provides ``add_arguments(parser: argparse.ArgumentParser) -> None`` and
``run(args: argparse.Namespace) -> int``. Modules are loaded lazily so that ``cnnslam eval`` does not pay for
importing torch or OpenGL. ``cnnslam --help`` lists the commands by role (:data:`GROUPS`), then the developer tools
that run as ``python -m`` modules (:data:`DEVELOPER_TOOLS`: used to make the project's own files and figures, not
by a benchmark's user). A closed pipe (``cnnslam config CNN-SLAM | head``) ends a command quietly.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

# the roles the commands are listed under, in this order
GROUPS: tuple[str, ...] = ("run and score", "data", "the network", "speed")
# name -> (module, one-line help, group). Command lines sit at the edge: the judge's commands live in eval.commands,
# the world's in sim_envs, the network's in cnnslam.depthnet.
SUBCOMMANDS: dict[str, tuple[str, str, str]] = {}
# `python -m` modules that are developer tools (they make the project's own files and figures), with what they do
DEVELOPER_TOOLS: tuple[tuple[str, str], ...] = (
    ("sim_envs.tools.cli_camera_calibration",
     "measure real frames' image statistics against each simulated camera preset (results/camera_calibration.md)"),
    ("sim_envs.tools.bench_folder", "frames per second a real RGB-D folder delivers (read-ahead, prepared images)"),
    ("cnnslam.tools.warmup", "compile the agent's numba kernels into numba's cache (make venv runs it)"),
    ("cnnslam.depthnet.bench", "the depth network's warm milliseconds per 320x240 frame"),
    ("eval.metrics.bench_metrics", "time the trajectory metrics on 100 000 poses"),
    ("thirdparty.orb_vocabulary", "build ORB-SLAM3's vocabulary from simulated training frames"),
    ("eval.commands.cli_readme", "render the README's generated blocks from the committed results (--check)"),
)  # fmt: skip


def register(name: str, module: str, help_text: str, group: str) -> None:
    """Add a subcommand under one of :data:`GROUPS` (the table below stays one line per command)."""
    if group not in GROUPS:
        raise ValueError(f"command {name!r}: group must be one of {GROUPS}, got {group!r}")
    SUBCOMMANDS[name] = (module, help_text, group)


register("bench", "eval.commands.cli_bench", "run a benchmark suite (table1, lengths, transfer, quick, ...)", GROUPS[0])
register("eval", "eval.commands.cli_eval", "score an estimated trajectory against ground truth (like evo_ape)",
         GROUPS[0])
register("regress", "eval.commands.cli_regress", "compare a run's metrics with a committed baseline (the gate)",
         GROUPS[0])
register("results", "eval.commands.cli_results", "the committed results: made at which revision, still current?",
         GROUPS[0])
register("config", "eval.commands.cli_config", "print the exact configuration a method's runs use (with --set)",
         GROUPS[0])
register("map", "cnnslam.tools.cli_map",
         "run an agent, fuse its key-frames into the global model: PLY, pictures, metrics", GROUPS[0])
register("export", "eval.commands.cli_export", "write a registered sequence as a TUM RGB-D folder", GROUPS[1])
register("generate", "eval.commands.cli_generate", "generate rotation stress sequences (and export them)", GROUPS[1])
register("reference", "eval.commands.cli_reference", "an SfM reference (COLMAP) for a real RGB-D folder", GROUPS[1])
register("contact-sheet", "sim_envs.tools.cli_contact_sheet", "render RGB / depth / labels of named sequences to a PNG",
         GROUPS[1])
register("train", "cnnslam.depthnet.cli_train", "depth network: generate data, train, validate, export", GROUPS[2])
register("bench-slam", "cnnslam.tools.bench_slam", "CNN-SLAM speed: tracking and whole-system frames per second",
         GROUPS[3])
register("bench-render", "sim_envs.tools.bench_render", "render throughput of the MuJoCo and pyrender renderers (fps)",
         GROUPS[3])


def commands_text() -> str:
    """The commands by role, then the developer tools (``cnnslam --help``'s list)."""
    lines = []
    for group in GROUPS:
        lines.append(f"{group}:")
        lines += [f"  {name:<14} {text}" for name, (_, text, g) in SUBCOMMANDS.items() if g == group]
    lines.append("developer tools (python -m MODULE; not needed to run or score a benchmark):")
    lines += [f"  {module:<33} {text}" for module, text in DEVELOPER_TOOLS]
    return "\n".join(lines)


def _top_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cnnslam", formatter_class=argparse.RawDescriptionHelpFormatter, epilog=commands_text(),
        description="CNN-SLAM simulation and evaluation harness. Run 'cnnslam COMMAND --help' for a command's options.",
    )  # fmt: skip
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", help="one of the commands below, by role")
    for name in SUBCOMMANDS:
        sub.add_parser(name, add_help=False)
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
    module_name, help_text, _ = SUBCOMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"cnnslam {name}", description=help_text)
    module.add_arguments(parser)
    args = parser.parse_args(argv[1:])
    try:
        return int(module.run(args) or 0)
    except BrokenPipeError:  # the reader went away (| head): no traceback, and none when Python flushes at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1


if __name__ == "__main__":
    sys.exit(main())
