"""``python -m eval.commands.cli_suite_speed [--update [--repeats N]]``: the suite speed gate on this tree
(:mod:`eval.bench.suite_speed`): runs the quick suite as CI does, prints each method's frames per machine unit
beside the baseline's and exits 1 past the allowed slowdown; ``--update`` writes the baseline first (the median of
``--repeats`` quick-suite runs)."""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from eval.bench.suite_speed import (
    SUITE_SPEED_BASELINE,
    baseline_from,
    load_suite_speed_baseline,
    measure_quick,
    suite_speed_regressions,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m eval.commands.cli_suite_speed",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--update", action="store_true", help="write the baseline (after an intended change)")
    parser.add_argument("--repeats", type=int, default=1, help="quick-suite runs for --update (the median)")
    parser.add_argument("--baseline", type=Path, default=SUITE_SPEED_BASELINE)
    args = parser.parse_args(argv)
    from eval.bench.runner import git_revision

    speeds = []
    for k in range(max(1, args.repeats if args.update else 1)):
        with tempfile.TemporaryDirectory(prefix=f"cnnslam-suite-speed-{k}-") as tmp:
            speeds.append(measure_quick(Path(tmp), progress=True))
    if args.update:
        baseline = baseline_from(speeds, git_revision=git_revision())
        args.baseline.parent.mkdir(parents=True, exist_ok=True)
        args.baseline.write_text(json.dumps(baseline.to_dict(), indent=2, allow_nan=False) + "\n")
        print(f"wrote {args.baseline}")
    baseline = load_suite_speed_baseline(args.baseline)
    for method, value in speeds[-1].items():
        reference = baseline.figures.get(method)
        ratio = f"{reference / value:.2f}" if reference else "-"
        print(f"{method:20s} {value:.4g} frames per unit (baseline {reference or '-'}, baseline / this run {ratio})")
    failures = suite_speed_regressions(speeds[-1], baseline)
    print("\n".join(failures) if failures else "passed")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
