"""``cnnslam regress BASELINE.json RUN.json``: the regression gate (see :mod:`eval.bench.regress` for the file formats).

Prints the diff table and PASS/FAIL. Exit status: 0 when nothing regressed or went missing (improvements pass), 1 on
a regression (a tracked share that became a failure is one whatever the tolerance) or a missing metric, 2 in one line
when a file is missing, unreadable or malformed (a baseline of another schema, with no figures, with a tolerance rule
that can never match or a tolerance that can never fail inside its metric's bounds) or an update is refused.
``--update`` rewrites BASELINE with the run's metrics (keeping its tolerances) and exits 0: review the diff and commit
it like code. An update that would drop gated figures (the run lacks some the baseline holds) is refused in one
line: ``--replace`` to mean it, ``--merge`` to rewrite only the run's figures (a run of the one method that changed),
``--only-new`` to add the run's new figures only.
"""

from __future__ import annotations

import argparse
import sys

from eval.bench.gate_baseline import load_baseline, update_baseline
from eval.bench.regress import compare, format_report, load_run_metrics
from eval.errors import InputError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("baseline", help="baseline JSON (committed under results/)")
    parser.add_argument("run", help="the run's metrics JSON (a run record, a flat object, or a list of run records)")
    parser.add_argument("--update", action="store_true", help="write the run's metrics into the baseline instead")
    parser.add_argument("--only-new", action="store_true",
                        help="with --update: add only the figures the baseline does not hold yet (newly gated "
                             "metrics), keeping every other figure and its calibration")
    parser.add_argument("--merge", action="store_true",
                        help="with --update: rewrite only the figures the run holds and keep the others (e.g. a run "
                             "of the one method whose results changed)")
    parser.add_argument("--replace", action="store_true",
                        help="with --update: replace the baseline's figures by the run's even where the run lacks "
                             "some (they are dropped from the gate)")
    parser.add_argument("--changes-only", action="store_true", help="list only metrics whose status is not 'equal'")


def run(args: argparse.Namespace) -> int:
    try:
        metrics = load_run_metrics(args.run)
        if args.update:
            new = update_baseline(args.baseline, metrics, only_new=args.only_new, replace_all=args.replace,
                                  merge=args.merge)
            print(f"updated {args.baseline}: {len(new.metrics)} metrics, {len(new.tolerances)} tolerance rules")
            return 0
        report = compare(load_baseline(args.baseline), metrics)
    except InputError as exc:  # the gate's own errors (GateError) are input errors too
        print(f"cnnslam regress: error: {exc}", file=sys.stderr)
        return 2
    print(format_report(report, only_changes=args.changes_only))
    return 0 if report.passed else 1
