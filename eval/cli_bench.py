"""``cnnslam bench [SUITE]``: run a benchmark suite and write its results (tables, plots, long-form CSV).

Suites (``--list`` prints them with their sequences and methods): ``table1`` (default), ``rotation``, ``ablation``,
``sweep``, ``perf``, ``quick``; see :mod:`eval.suites`. Runs go to ``--out`` (one folder per run, see
:mod:`eval.runner`), results to ``--results`` (see :mod:`eval.reports`). A rerun skips finished runs and retries
failed ones; methods that cannot run here are skipped and reported.

Examples::

    cnnslam bench                                   # table1 at bench size -> results/table1.md
    cnnslam bench rotation --jobs 2 --frames 90
    cnnslam bench table1 --methods CNN-SLAM oracle --sequences office0 living1 --frames 100
    cnnslam bench table1 --external MySLAM=out/myslam  # score a third-party system's output too
    cnnslam bench quick                             # the CI suite, compared with results/baselines/quick.json
    cnnslam bench quick --update-baseline           # after an intended change: rewrite the baseline
    cnnslam bench table1 --executor ray --address auto

Exit status: 0 when every run finished (and the gate passed, where one runs), 1 when a run failed or the gate
failed (the results are written all the same), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from eval.errors import EvalError
from eval.executors import EXECUTORS, make_executor
from eval.methods import EXTERNAL_LAYOUT, load_methods, parse_external
from eval.suites import SUITES, get_suite

DEFAULT_BASELINE_DIR = Path("results") / "baselines"
GATED_SUITES = ("quick",)  # suites compared with their baseline unless --no-gate


def _names(values: list[str] | None) -> list[str] | None:
    """Names given as separate words and/or comma-separated."""
    if not values:
        return None
    return [n for v in values for n in v.split(",") if n]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = f"external method folder layout (--external NAME=FOLDER):\n{EXTERNAL_LAYOUT}"
    parser.add_argument("suite", nargs="?", default="table1", choices=list(SUITES), help="suite (default: table1)")
    parser.add_argument("--frames", type=int, default=None, help="first N frames of each sequence (suite default)")
    parser.add_argument("--sequences", nargs="+", metavar="NAME", help="only these sequences (or others by name)")
    parser.add_argument("--methods", nargs="+", metavar="NAME", help="only these methods of the method table")
    parser.add_argument("--seeds", nargs="+", type=int, metavar="N", help="seeds (default: 0)")
    parser.add_argument("--jobs", type=int, default=2, help="runs in parallel (default: 2)")
    parser.add_argument("--executor", choices=EXECUTORS, default="local",
                        help="local process pool (spawn, default), serial (in this process) or ray")  # fmt: skip
    parser.add_argument("--address", default=None, help="Ray cluster address (auto, ray://host:10001, local)")
    parser.add_argument("--reuse-workers", action="store_true",
                        help="local executor: run several runs per worker process (faster start; a run's last digits "
                             "may then depend on what its worker ran before)")  # fmt: skip
    parser.add_argument("--out", type=Path, default=Path("runs"), help="per-run artifacts (default: runs/)")
    parser.add_argument("--results", type=Path, default=Path("results"), help="tables and plots (default: results/)")
    parser.add_argument("--external", action="append", default=[], metavar="NAME=FOLDER",
                        help="score a third-party system's output in FOLDER as method NAME (repeatable)")  # fmt: skip
    parser.add_argument("--method-file", type=Path, default=None,
                        help="a method table (TOML, shaped like eval/methods.toml) added to the default")  # fmt: skip
    parser.add_argument("--renderer", choices=("mujoco", "pyrender"), default="mujoco", help="renderer backend")
    parser.add_argument("--no-plots", action="store_true", help="no per-run plots (faster)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--no-check", action="store_true",
                        help="check only that each method's agent imports (not that it builds and steps)")  # fmt: skip
    parser.add_argument("--baseline", type=Path, default=None,
                        help="compare the suite's metrics with this baseline (default for quick: "
                             "results/baselines/quick.json)")  # fmt: skip
    parser.add_argument("--update-baseline", action="store_true", help="write the suite's metrics as its baseline")
    parser.add_argument("--no-gate", action="store_true", help="do not compare with the baseline")
    parser.add_argument("--list", action="store_true", help="list the suites and the method table, run nothing")


def _command(args: argparse.Namespace) -> str:
    """The command line that reproduces the run (the options that shape the results), for the reports."""
    words = ["cnnslam", "bench", args.suite]
    renderer = None if args.renderer == "mujoco" else args.renderer
    for flag, value in (("--frames", args.frames), ("--renderer", renderer)):
        if value is not None:
            words += [flag, str(value)]
    for flag, values in (("--sequences", _names(args.sequences)), ("--methods", _names(args.methods)),
                         ("--seeds", args.seeds)):  # fmt: skip
        if values:
            words += [flag, *map(str, values)]
    for text in args.external:
        words += ["--external", text]
    if args.method_file is not None:
        words += ["--method-file", str(args.method_file)]
    return " ".join(shlex.quote(w) for w in words)


def _list(methods: dict) -> str:
    lines = ["suites:"]
    for suite in SUITES.values():
        lines.append(f"  {suite.name:<9} {suite.description}")
        if suite.kind == "runs":
            frames = "all" if suite.frames is None else suite.frames
            lines.append(f"            frames {frames}; sequences: {', '.join(s.name for s in suite.sequences)}")
            lines.append(f"            methods: {', '.join(suite.methods)}")
    lines.append("methods:")
    for m in methods.values():
        target = m.entry_point or m.folder
        lines.append(f"  {m.name:<17} {target}  {dict(m.agent_kwargs())}  [{', '.join(m.metrics)}]")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    command = _command(args)
    try:
        methods = load_methods()
        if args.method_file is not None:
            methods.update(load_methods(args.method_file))
        externals = [parse_external(text) for text in args.external]
        for method in externals:
            methods[method.name] = method
        if args.list:
            print(_list(methods))
            return 0
        suite = get_suite(args.suite)
        if suite.kind == "perf":
            from eval.perf import run_perf

            report = run_perf(args.results, frames=args.frames, progress=not args.no_progress)
            print(f"wrote {args.results / 'perf.md'} and {args.results / 'perf.json'}")
            return 0 if report.ok else 1
        chosen = _names(args.methods) or list(suite.methods)
        chosen += [m.name for m in externals if m.name not in chosen]
        suite = suite.select(_names(args.sequences), chosen, args.frames, args.seeds)
        executor = make_executor(args.executor, args.jobs, args.address, fresh_workers=not args.reuse_workers)
    except EvalError as exc:
        print(f"cnnslam bench: error: {exc}", file=sys.stderr)
        return 2
    from eval.reports import write_report
    from eval.runner import run_suite

    result = run_suite(
        suite,
        methods,
        args.out,
        executor=executor,
        renderer=args.renderer,
        plots=not args.no_plots,
        progress=not args.no_progress,
        check=not args.no_check,
    )
    paths = write_report(result, args.results, command)
    counts = result.counts()
    print(
        f"{suite.name}: {len(result.specs)} runs ({counts.get('done', 0)} run now, {counts.get('cached', 0)} reused, "
        f"{counts.get('failed', 0)} failed); {len(result.skipped_methods)} method(s) skipped"
    )
    for name, reason in result.skipped_methods.items():
        print(f"  skipped {name}: {reason}")
    for outcome in result.failed:
        print(f"  FAILED {outcome.key}: {outcome.error}")
    print("wrote " + ", ".join(str(p) for p in paths))
    status = 1 if result.failed else 0
    return max(status, _gate(args, result))


def _gate(args: argparse.Namespace, result) -> int:
    """Update or compare with the suite's baseline; the exit status of the gate (0 pass, 1 fail)."""
    from eval.regress import (
        DEFAULT_TOLERANCES,
        Baseline,
        compare,
        format_report,
        load_baseline,
        save_baseline,
        suite_metrics,
    )

    suite = result.suite
    path = args.baseline or DEFAULT_BASELINE_DIR / f"{suite.name}.json"
    metrics = suite_metrics(result.records)
    if args.update_baseline:
        if result.failed:
            print(f"not updating {path}: {len(result.failed)} run(s) failed", file=sys.stderr)
            return 1
        old = load_baseline(path) if path.exists() else None
        frames = "all" if suite.frames is None else suite.frames
        skipped = f"; skipped: {', '.join(result.skipped_methods)}" if result.skipped_methods else ""
        description = (
            f"cnnslam bench {suite.name}: {frames} frames, sequences {', '.join(s.name for s in suite.sequences)}; "
            f"methods {', '.join(m.name for m in result.methods)}{skipped}"
        )
        save_baseline(Baseline(metrics, old.tolerances if old else DEFAULT_TOLERANCES, description), path)
        print(f"updated {path}: {len(metrics)} metrics")
        return 0
    if args.no_gate or (args.baseline is None and suite.name not in GATED_SUITES):
        return 0
    if not path.exists():
        print(f"no baseline at {path}; create it with: cnnslam bench {suite.name} --update-baseline")
        return 0 if args.baseline is None else 1
    report = compare(load_baseline(path), metrics)
    print(format_report(report, only_changes=True))
    return 0 if report.passed else 1
