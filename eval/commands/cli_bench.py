"""``cnnslam bench [SUITE]``: run a benchmark suite and write its results: arguments -> :class:`BenchOptions` ->
:func:`eval.bench.run_bench` -> a summary. Everything the command does is the library call's (its module docstring
says what, in which order, and the exit status); the suites are :mod:`eval.bench.suites`, ``--list`` prints them.

Examples::

    cnnslam bench                                   # table1, whole sequences (the paper's) -> results/table1.md
    cnnslam bench table1 --methods CNN-SLAM oracle --sequences office0 living1 --frames 100
    cnnslam bench table1 --external MySLAM=out/myslam  # score a third-party system's output too
    cnnslam bench table1 --sequences ~/data/rgbd_dataset_freiburg1_desk   # a downloaded TUM sequence
    cnnslam bench transfer --frames all --camera clean,kinect   # whole sequences only, two simulated cameras
    cnnslam bench quick --update-baseline           # after an intended change: rewrite the gate's baseline
    cnnslam bench table1 --executor ray --address auto

Checked before any run (exit 2, one line): the options' numbers (``--frames`` and ``--lengths`` >= 2, ``--runs``
and ``--jobs`` >= 1, ``--timeout`` > 0); every chosen method's module imported and its class found: a module that is
not there or a misspelt class (a method file's ``"mymod:MySlma"``) is refused. A method whose module needs a package
this machine lacks (ORB-SLAM3 without pyorbslam3, COLMAP without pycolmap, Open3D-odometry without open3d) is skipped
with the reason when it comes with the suite (no ``--methods``), and refused when ``--methods`` names it, unless
``--allow-skips``. ``--out`` and ``--results`` are tried (created, a temporary file written in them); ``--report-only``
needs an ``--out`` that holds finished runs of the selection. A selection other than the suite's never writes into
the repository's ``results/``, however ``--results`` names it. A run is stopped after ``--timeout`` seconds, by
default 4 s a frame of the longest run planned and at least 900 s (``eval.bench.benchmark.TIMEOUT_PER_FRAME_S``);
the reports' command quotes the limit.

Exit status: 0 when every requested run finished (and the gate passed); 1 when a run failed or timed out, a requested
method, external folder or listed dataset folder was skipped (``--allow-skips``: only reported), or the gate failed
or refused an update; 2 on bad arguments, before any run (one line naming the value and what is valid); 130 on
Ctrl-C (the runs finished before it are kept).
"""

from __future__ import annotations

import argparse
import logging
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path

from eval.bench.benchmark import DEFAULT_JOBS, BenchOptions, BenchOutcome, ExecutorOptions, describe_suites, run_bench
from eval.bench.executors import EXECUTORS
from eval.bench.methods import ALIGNMENTS, EXTERNAL_LAYOUT, method_table
from eval.bench.regress import GateAction
from eval.bench.suites import SUITES
from eval.errors import InputError
from eval.reports.style import DEFAULT_FIGURE_FORMAT, FIGURE_FORMATS


def _frames(text: str) -> int | str:
    """``--frames`` / ``--lengths``: a number of frames, or ``all`` (whole sequences)."""
    if text == "all":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of frames or 'all', got {text!r}") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = f"external method folder layout (--external NAME=FOLDER):\n{EXTERNAL_LAYOUT}"
    add = parser.add_argument_group("what to run").add_argument
    add("suite", nargs="?", default="table1", choices=list(SUITES), help="suite (default: table1)")
    add("--sequences", nargs="+", metavar="NAME", help="only these sequences (or others: a sequence name, a "
        "dataset-list name, the path of an RGB-D folder: TUM RGB-D, ICL-NUIM, 7-Scenes, RGB-only)")
    add("--methods", nargs="+", metavar="NAME", help="only these methods of the method table")
    add("--frames", type=_frames, help="first N frames of each sequence, or 'all' (default: the suite's)")
    add("--lengths", type=_frames, nargs="+", metavar="N", help="the lengths and transfer suites' lengths: numbers "
        "of frames and/or 'all' (default: 200 400 800 all)")
    add("--runs", type=int, metavar="N", help="runs per cell, seeds 0..N-1 (default: 3; eval/methods.toml says what "
        "a seed changes)")
    add("--seeds", nargs="+", type=int, metavar="N", help="these seeds (whole numbers >= 0) instead of --runs")
    add("--list", action="store_true", help="list the suites and the method table, run nothing")
    add = parser.add_argument_group("the sequences' images").add_argument
    add("--camera", metavar="PRESET|FILE", help="simulated sequences: kinect (default), clean or hard "
        "(sim_envs/sensor/camera_effects.py; NAME@PRESET in --sequences for one sequence; transfer: comma-separated "
        "simulated domains, e.g. clean,kinect+lit); folder sequences: a calibration preset (tum_fr1, icl, 7scenes, "
        "...) or camera file (TOML/YAML: fx fy cx cy [width height] [k1 k2 p1 p2 k3])")
    add("--image-size", metavar="WxH", help="folder sequences' resolution (default 320x240; 'native')")
    add("--undistort", choices=["crop", "full", "none"], help="a folder's distorted lens: crop (default), full "
        "(whole frame, black border) or none; not crop runs as <name>~<choice>")
    add("--motion", action="append", default=[], type=Path, metavar="TUM_FILE", help="transfer: a recorded camera "
        "motion replayed in the simulated rooms as a simulated domain of its own (repeatable)")
    add("--sim-sequences", nargs="+", metavar="NAME", help="transfer: these registered simulated sequences in place "
        "of the Table-1 analogues (e.g. office_fr1motion living_fr1motion, moving as TUM fr1/desk's camera does)")
    add("--renderer", choices=("mujoco", "pyrender"), default="mujoco", help="renderer backend")
    add("--no-frame-cache", action="store_true", help="render every run's frames anew (default: once per sequence, "
        "read back from <out>/.frames/: the same bytes)")
    add = parser.add_argument_group("the methods").add_argument
    add("--set", action="append", default=[], metavar="KEY=VALUE", help="a configuration field of every chosen "
        "method whose configuration has it (repeatable; e.g. refinement.enabled=false; cnnslam config METHOD lists "
        "the keys); checked, key and type, before any run")
    add("--method-file", type=Path, help="a method table (TOML, shaped like eval/methods.toml) added to the default")
    add("--override", action="store_true", help="let --method-file redefine a built-in method of the same name")
    add("--external", action="append", default=[], metavar="NAME=FOLDER",
        help="score a third-party system's output in FOLDER as method NAME (repeatable)")
    add("--no-check", action="store_true", help="check only that each agent imports (not that it builds and steps)")
    add = parser.add_argument_group("how runs are run").add_argument
    add("--jobs", type=int, default=DEFAULT_JOBS, help=f"runs in parallel (default: {DEFAULT_JOBS})")
    add("--executor", choices=EXECUTORS, default="local", help="local process pool (default), serial or ray")
    add("--address", help="Ray cluster address (auto, ray://host:10001, local)")
    add("--reuse-workers", action="store_true", help="local: several runs per worker process (faster start; a "
        "run's last digits may then depend on what its worker ran before)")
    add("--timeout", type=float, metavar="S", help="stop a run after S seconds and record it as failed (timed out; "
        "default: 4 s a frame of the longest run, at least 900 s)")
    add("--rerun", action="store_true", help="run every run again, even finished ones")
    add("--report-only", action="store_true", help="run nothing: write the tables from the finished runs in --out")
    add("--out", type=Path, default=Path("runs"), help="per-run artifacts (default: runs/)")
    add = parser.add_argument_group("results").add_argument
    add("--results", type=Path, help="tables and plots (default: results/ for a suite as defined, else "
        "<out>/reports/<suite>-<selection>/; a selection of other sequences or methods never writes into results/)")
    add("--align", choices=ALIGNMENTS, help="alignment of the headline ATE (default: the suite's, se3 as in the "
        "paper; a method's own align wins); every run records the SE(3) and the Sim(3) ATE")
    add("--figure-format", choices=FIGURE_FORMATS, default=DEFAULT_FIGURE_FORMAT, help="the report's figures: png "
        "(default), pdf (with a PNG twin for the Markdown and HTML) or svg")
    add("--no-plots", action="store_true", help="no per-run plots (faster)")
    add("--no-progress", action="store_true", help="no progress bars")
    add("--allow-skips", action="store_true", help="exit 0 even when a requested method or folder was skipped")
    add = parser.add_argument_group("the regression gate").add_argument
    add("--baseline", type=Path, help="compare with this baseline (default for quick: results/baselines/quick.json)")
    add("--update-baseline", action="store_true", help="write the suite's gated figures as its baseline (keeping "
        "its calibrated tolerances; refused when it would drop figures the baseline gates); perf: the speed baseline")
    add("--replace", action="store_true", help="with --update-baseline: replace the baseline's figures even where "
        "the runs lack some")
    add("--calibrate", action="store_true", help="run the suite under the perturbation matrix (eval/bench/"
        "calibrate.py) and write the baseline with tolerances from the spread it measures")
    add("--no-gate", action="store_true", help="do not compare with the baseline")


def bench_parser() -> argparse.ArgumentParser:
    """The argument parser of ``cnnslam bench`` (:func:`add_arguments`), as ``cnnslam results make`` parses the
    ``cnnslam bench`` lines that results record."""
    parser = argparse.ArgumentParser(prog="cnnslam bench", exit_on_error=False)
    add_arguments(parser)
    return parser


def bench_args(command: str, folder: Path, out: Path, extra: Sequence[str] = ()) -> argparse.Namespace:
    """The parsed arguments of a ``cnnslam bench`` line run into ``folder`` with runs under ``out``; ``extra``:
    further options (``--jobs 2``). :class:`InputError` when the line does not parse."""
    words = shlex.split(command)
    if words[:2] != ["cnnslam", "bench"]:
        raise InputError(f"{command!r} is no cnnslam bench line")
    try:
        return bench_parser().parse_args([*words[2:], "--results", str(folder), "--out", str(out), *extra])
    except (argparse.ArgumentError, SystemExit) as exc:
        raise InputError(f"{command!r} does not parse as cnnslam bench options: {exc}") from None


def _command(args: argparse.Namespace) -> str:
    """The command line that reproduces the run (the options that shape the results), for the reports."""
    words = ["cnnslam", "bench", args.suite]
    renderer = None if args.renderer == "mujoco" else args.renderer
    for flag, value in (("--frames", args.frames), ("--runs", args.runs), ("--renderer", renderer),
                        ("--align", args.align), ("--camera", args.camera), ("--undistort", args.undistort),
                        ("--image-size", args.image_size), ("--method-file", args.method_file)):  # fmt: skip
        words += [flag, str(value)] if value is not None else []
    for flag, values in (("--sequences", args.sequences), ("--methods", args.methods), ("--seeds", args.seeds),
                         ("--lengths", args.lengths), ("--external", args.external), ("--motion", args.motion),
                         ("--sim-sequences", args.sim_sequences)):
        words += [flag, *map(str, values)] if values else []
    return " ".join(shlex.quote(w) for w in words)


def _gate_action(args: argparse.Namespace) -> GateAction:
    if args.calibrate:
        return GateAction.CALIBRATE
    if args.update_baseline:
        return GateAction.REPLACE if args.replace else GateAction.UPDATE
    return GateAction.OFF if args.no_gate else GateAction.COMPARE


def options_of(args: argparse.Namespace) -> BenchOptions:
    """The library's options for the parsed arguments."""
    lengths = None if args.lengths is None else tuple(None if n == "all" else n for n in args.lengths)
    executor = ExecutorOptions(args.executor, args.jobs, args.address, args.reuse_workers, args.timeout)
    return BenchOptions(
        sequences=tuple(args.sequences) if args.sequences else None, frames=args.frames,
        seeds=tuple(args.seeds) if args.seeds else None, runs=args.runs, lengths=lengths, motions=tuple(args.motion),
        sim_sequences=tuple(args.sim_sequences) if args.sim_sequences else None,
        camera=args.camera, image_size=args.image_size, undistort=args.undistort, align=args.align,
        settings=tuple(args.set), executor=executor, renderer=args.renderer, frame_cache=not args.no_frame_cache,
        check=not args.no_check, rerun=args.rerun, report_only=args.report_only, plots=not args.no_plots,
        progress=not args.no_progress, out=args.out, results=args.results, command=_command(args),
        figure_format=args.figure_format,
        gate=_gate_action(args), baseline=args.baseline, allow_skips=args.allow_skips,
    )  # fmt: skip


def run(args: argparse.Namespace) -> int:
    handler = logging.StreamHandler(sys.stdout)  # the library's progress lines (eval.bench.benchmark, INFO)
    logger = logging.getLogger("eval.bench")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        table = method_table(args.method_file, args.external, args.override)
        if args.list:
            print(describe_suites(table))
            return 0
        outcome = run_bench(args.suite, args.methods, options_of(args), table)
    except InputError as exc:
        print(f"cnnslam bench: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"cnnslam bench: interrupted; finished runs are kept under {args.out}/ (rerun the same command to "
              "resume)", file=sys.stderr)  # fmt: skip
        return 130
    finally:
        logger.removeHandler(handler)
    return summary(outcome)


def summary(outcome: BenchOutcome) -> int:
    """Print what the call did (settings, runs, skips, failures, files, the gate); return its exit status."""
    for key, names in outcome.settings:
        print(f"--set {key}: applied to {', '.join(names)} (cnnslam config METHOD --set ... prints the result)")
    counts = outcome.counts()
    print(f"{outcome.suite}: {len(outcome.runs)} runs ({counts.get('done', 0)} run now, {counts.get('cached', 0)} "
          f"reused, {counts.get('failed', 0)} failed); "
          f"{sum(s.what == 'method' for s in outcome.skipped)} method(s) skipped")  # fmt: skip
    for skip in outcome.skipped:
        print(f"  skipped {'' if skip.what == 'method' else 'sequence '}{skip.name}: {skip.reason}")
    for row in outcome.failed:
        print(f"  FAILED {row.key}: {row.error}")
    for row in outcome.runs:
        if row.coverage is not None:
            print(f"  partial {row.key}: {row.coverage[0]} of {row.coverage[1]} frames scored")
    for note in outcome.notes:  # nothing ran: the note is why
        print(f"cnnslam bench: {note}" if not outcome.parts else f"  {note}", file=sys.stdout if outcome.parts
              else sys.stderr)  # fmt: skip
    if outcome.reports:
        print("wrote " + ", ".join(str(p) for p in outcome.reports))
        pages = [str(p) for p in outcome.reports if p.suffix == ".html"]
        if pages:
            print("report (opens in a browser): " + ", ".join(pages))
    if outcome.gate is not None:
        print(outcome.gate.message)
    if outcome.skipped and outcome.exit_status and not outcome.failed:
        print(f"cnnslam bench: {len(outcome.skipped)} requested method(s) or listed sequence(s) skipped "
              f"({', '.join(s.name for s in outcome.skipped)}): exit status 1 (--allow-skips to accept)",
              file=sys.stderr)  # fmt: skip
    return outcome.exit_status
