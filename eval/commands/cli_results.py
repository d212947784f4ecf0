"""``cnnslam results status [NAME ...] [--json]``: every committed result, the revision it was made at, and whether
the current code would give the same (:func:`eval.bench.provenance.results_status`: each run's fingerprint
recomputed for the same run specs, nothing run; timings excluded).

Exit status: 0 when every listed result is current, 1 when any is stale, 2 for bad input (an unknown result name,
a results folder that is not there).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from eval.bench.provenance import RESULTS_ROOT, format_status, results_status
from eval.errors import InputError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    status = sub.add_parser("status", help="list the committed results and whether the current code gives the same")
    status.add_argument("names", nargs="*", metavar="NAME",
                        help="results to judge (e.g. table1, bench/table1; default: all under the results folder)")
    status.add_argument("--results", type=Path, default=RESULTS_ROOT,
                        help="the folder holding the results (default: the repository's results/)")
    status.add_argument("--json", action="store_true", help="print the status as JSON instead of a table")


def run(args: argparse.Namespace) -> int:
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
