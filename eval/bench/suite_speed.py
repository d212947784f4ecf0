"""The suite speed gate: every method of a suite, in frames per machine unit, against a committed baseline
(``results/baselines/suite_speed.json``); a method more than 1.5 times slower fails CI.

Each run times the machine unit (:mod:`slamcommon.machine_unit`, the frozen workload of CNN-SLAM's speed gate) in its
own process just before and just after itself and records its ``frames_per_unit`` (``timing.json``: frames x the
unit's CPU seconds / the run's CPU seconds, :mod:`eval.bench.run`): a figure that carries the machine's speed, so
that a baseline made on one machine judges another, and in CPU time, which the other processes on the cores do not
inflate (wall time did: ``make test`` runs two test files beside the quick suite's two jobs, and the unit, timed
for a few milliseconds around a run of a minute, did not see that share: CNN-SLAM read 1.6 times slower). A
method's figure in a suite run is the best of its runs (the quick suite: 3 sequences x 3 seeds): a neighbour's
burst slows some runs, a real slowdown slows them all. The gate runs in ``make test`` on the quick suite's runs
(``tests/eval/test_quick_regression.py``); ``python -m eval.commands.cli_suite_speed --update`` remakes the baseline
after an intended change (the quick suite as the gate runs it, ``--repeats`` times, the median of each method's
figure).
"""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from eval.bench.perf import BaselineRecord, PerfError, load_baseline_record, machine_info, too_slow
from slamcommon.machine_unit import UNIT_VERSION

SUITE_SPEED_BASELINE: Path = Path(__file__).resolve().parents[2] / "results" / "baselines" / "suite_speed.json"
SUITE_SPEED_SCHEMA = "cnnslam-suite-speed/1"
GATED_SUITE = "quick"


@dataclass(frozen=True)
class SuiteSpeedBaseline(BaselineRecord):
    """Per method (``figures``) the frames per machine unit a suite's runs reached (:func:`method_speeds`), with
    the fields of every speed baseline (:class:`eval.bench.perf.BaselineRecord`)."""

    suite: str
    SCHEMA: ClassVar[str] = SUITE_SPEED_SCHEMA


def method_speeds(runs: Iterable[tuple[str, Mapping[str, Any]]], unit_version: str = UNIT_VERSION,
                  ) -> dict[str, float]:
    """Per method (first-seen order) the best ``frames_per_unit`` of its runs, ``runs`` being (method, timing.json
    content); runs timed in another unit, or without the figure, are left out."""
    best: dict[str, float] = {}
    for method, timing in runs:
        value = timing.get("frames_per_unit")
        if timing.get("unit_version") != unit_version or not isinstance(value, int | float) or not value > 0:
            continue
        best[method] = max(best.get(method, 0.0), float(value))
    return best


def suite_speeds(suite_run: Any) -> dict[str, float]:
    """:func:`method_speeds` of a :class:`eval.bench.runner.SuiteRun`'s finished runs."""
    return method_speeds((r.method, suite_run.timings.get(r.run or "", {})) for r in suite_run.records)


def baseline_from(speeds: Sequence[Mapping[str, float]], suite: str = GATED_SUITE,
                  git_revision: str | None = None) -> SuiteSpeedBaseline:
    """The median of each method's figure over several suite runs (``speeds``: :func:`method_speeds` of each)."""
    if not speeds:
        raise PerfError("a suite speed baseline needs at least one suite run")
    methods = list(dict.fromkeys(m for s in speeds for m in s))
    figures = {m: float(statistics.median(s[m] for s in speeds if m in s)) for m in methods}
    return SuiteSpeedBaseline(suite, unit_version=UNIT_VERSION, figures=figures, runs=tuple(dict(s) for s in speeds),
                              machine=machine_info(), git_revision=git_revision)


def load_suite_speed_baseline(path: str | Path | None = None) -> SuiteSpeedBaseline:
    """Read a suite speed baseline (default :data:`SUITE_SPEED_BASELINE`); one clear error when it cannot be used."""
    return load_baseline_record(Path(path) if path is not None else SUITE_SPEED_BASELINE, SUITE_SPEED_SCHEMA,
                                SuiteSpeedBaseline, "the suite speed baseline")


def suite_speed_regressions(speeds: Mapping[str, float], baseline: SuiteSpeedBaseline,
                            unit_version: str = UNIT_VERSION) -> list[str]:
    """One line per method of the baseline that is more than ``baseline.max_slowdown`` times slower in ``speeds``
    (:func:`method_speeds`), or has no figure there (empty: the gate passes); figures of another unit version fail
    with that reason. Methods the baseline does not hold are not judged."""
    if unit_version != baseline.unit_version:
        return [f"runs timed in machine unit {unit_version!r}, the baseline in {baseline.unit_version!r}: remake the "
                "baseline (python -m eval.commands.cli_suite_speed --update)"]
    failures = []
    for method, reference in baseline.figures.items():
        value = speeds.get(method)
        if value is None or not value > 0:
            failures.append(f"{method}: no frames-per-unit figure in this suite run")
        elif too_slow(value, reference, baseline.max_slowdown):
            failures.append(f"{method} {value:.4g} frames per unit is {reference / value:.2f}x slower than the "
                            f"baseline's {reference:.4g} (allowed {baseline.max_slowdown:g}x)")
    return failures


def measure_quick(out_root: Path, progress: bool = False) -> dict[str, float]:
    """The quick suite run as the CI gate runs it (the reference configuration of its calibration: 2 jobs, a fresh
    worker per run, no plots) under ``out_root``; its :func:`suite_speeds`."""
    from eval.bench.calibrate import MATRIX, run_configuration
    from eval.bench.methods import load_methods
    from eval.bench.suites import get_suite

    run = run_configuration(get_suite(GATED_SUITE), load_methods(), out_root, MATRIX[0], progress=progress)
    if run.failed:
        raise PerfError(f"{len(run.failed)} quick-suite run(s) failed: {run.failed[0].key}: {run.failed[0].error}")
    return suite_speeds(run)
