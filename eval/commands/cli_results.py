"""``cnnslam results status [NAME ...] [--json]``: every committed result, the revision it was made at, and whether
the current code would give the same (:func:`eval.bench.provenance.results_status`: each run's fingerprint
recomputed for the same run specs, nothing run; timings excluded).

``cnnslam results make [NAME ...] [--dry-run]``: remake every stale result (or those named) with the command that
made it, reusing the finished runs under ``--out`` whose fingerprint is current (:mod:`eval.commands.remake`);
``--dry-run`` prints the plan (commands, runs reused and to make, estimated time) and runs nothing.

Exit status: 0 when every listed result is current (make: every remade result current afterwards; a dry run: the
plan printed), 1 when any is stale, 2 for bad input (an unknown result name, a results folder that is not there).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from eval.bench.benchmark import DEFAULT_JOBS
from eval.bench.executors import EXECUTORS
from eval.bench.provenance import RESULTS_ROOT, format_status, results_status
from eval.commands.cli_bench import bench_args, bench_parser  # noqa: F401  (the bench command's parser, names kept here)
from eval.errors import InputError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    status = sub.add_parser("status", help="list the committed results and whether the current code gives the same")
    status.add_argument("names", nargs="*", metavar="NAME",
                        help="results to judge (e.g. table1, bench/table1; default: all under the results folder)")
    status.add_argument("--results", type=Path, default=RESULTS_ROOT,
                        help="the folder holding the results (default: the repository's results/)")
    status.add_argument("--json", action="store_true", help="print the status as JSON instead of a table")
    make = sub.add_parser("make", help="remake the stale results (or those named), reusing runs that are current")
    make.add_argument("names", nargs="*", metavar="NAME", help="results to remake, stale or not (default: every "
                      "stale one)")
    make.add_argument("--results", type=Path, default=RESULTS_ROOT,
                      help="the folder holding the results (default: the repository's results/)")
    make.add_argument("--out", type=Path, default=Path("runs"), help="the runs folder, reused runs included "
                      "(default: runs/)")
    make.add_argument("--jobs", type=int, default=DEFAULT_JOBS, help=f"runs in parallel (default: {DEFAULT_JOBS})")
    make.add_argument("--executor", choices=EXECUTORS, default="local", help="how runs run (default: local)")
    make.add_argument("--dry-run", action="store_true", help="print the plan, run nothing")


def run(args: argparse.Namespace) -> int:
    if args.action == "make":
        return make(args)
    try:
        rows = results_status(args.results, args.names or None)
    except InputError as exc:
        print(f"cnnslam results: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps([r.to_json() for r in rows], indent=1))
    else:
        print(format_status(rows))
    return 0 if all(r.current for r in rows) else 1


def make(args: argparse.Namespace) -> int:
    """``results make``: the plan, then (unless ``--dry-run``) each result remade and judged again."""
    from eval.commands.remake import format_plan, plan_remakes, remake

    if args.jobs < 1:
        print(f"cnnslam results: error: --jobs takes a number of runs in parallel >= 1, got {args.jobs}",
              file=sys.stderr)  # fmt: skip
        return 2
    try:
        plans = plan_remakes(args.results, args.names or None, args.out, args.jobs)
    except InputError as exc:
        print(f"cnnslam results: error: {exc}", file=sys.stderr)
        return 2
    print(format_plan(plans, args.jobs))
    if args.dry_run or not plans:
        return 0
    extra = ["--jobs", str(args.jobs), "--executor", args.executor, "--no-progress"]
    done: set[tuple[str, ...]] = set()
    for plan in plans:
        if not plan.possible:
            print(f"{plan.name}: not remade ({'; '.join(plan.notes) or 'no command'})")
            continue
        if plan.commands in done:  # another result of the same command (reference/<name>/camera and .../reference)
            continue
        print(f"{plan.name}: remaking")
        remake(plan, args.out, extra)
        done.add(plan.commands)
    rows = results_status(args.results, [p.name for p in plans if p.name in _names(args.results)])
    print(format_status(rows))
    return 0 if all(r.current for r in rows) else 1


def _names(root: Path) -> set[str]:
    from eval.bench.provenance import result_groups
    from eval.bench.suites import SUITES

    return set(result_groups(Path(root), list(SUITES)))
