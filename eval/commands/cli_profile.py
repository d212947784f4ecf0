"""``python -m eval.commands.cli_profile``: where a suite's time goes, per method (:mod:`eval.bench.profile`):
renders the sequences, runs each method once as the Table-1 suite does and prints the table (Markdown, or one JSON
object with ``--json``: the perf suite's ``suite`` probe). Exit status 1 when a run failed."""

from __future__ import annotations

import argparse
import json

from eval.bench.profile import DEFAULT_FRAMES, DEFAULT_SEQUENCES, format_table, measure


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m eval.commands.cli_profile", description=__doc__.split("\n\n")[0])
    parser.add_argument("--sequences", nargs="+", default=list(DEFAULT_SEQUENCES), metavar="NAME")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES)
    parser.add_argument("--methods", nargs="+", default=None, metavar="NAME",
                        help="methods of the method table (default: the Table-1 suite's, eval/methods.toml's "
                             "`table1 = true`; one this machine cannot run is skipped and named)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1: none slows another)")
    parser.add_argument("--threads", type=int, default=1, help="math threads per run (default 1, as make bench)")
    parser.add_argument("--json", action="store_true", help="print one JSON object (the perf suite's probe)")
    args = parser.parse_args(argv)
    result = measure(args.sequences, args.frames, args.methods, args.jobs, args.threads)
    if args.json:
        print(json.dumps(result))
    else:
        print(format_table(result))
        print(f"\nrendering {result['rendering_ms_per_frame']} ms per frame, suite {result['suite_wall_s']} s, "
              f"load {result['load_average_1min']}")
        if result["skipped_methods"]:
            print(f"skipped (cannot run here): {result['skipped_methods']}")
    return 0 if not result["failed_runs"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
