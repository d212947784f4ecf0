"""The suite speed gate's arithmetic (known answers): a method's figure is its best run in the current unit; exactly
the allowed slowdown passes, just past it fails, a missing method fails, another unit never compares. The gate on
real runs: tests/eval/test_quick_regression.py."""

from __future__ import annotations

import json

import pytest

from eval.bench.perf import PerfError
from eval.bench.suite_speed import (
    SUITE_SPEED_BASELINE,
    baseline_from,
    load_suite_speed_baseline,
    method_speeds,
    suite_speed_regressions,
)
from slamcommon.machine_unit import UNIT_VERSION


def _t(value: float, unit: str = UNIT_VERSION) -> dict:
    return {"frames_per_unit": value, "unit_version": unit, "wall_s": 1.0}


def test_a_methods_figure_is_its_best_run_in_this_unit() -> None:
    runs = [("A", _t(0.1)), ("B", _t(0.3)), ("A", _t(0.2)), ("A", _t(9.0, "other/0")), ("B", {"wall_s": 1.0})]
    assert method_speeds(runs) == {"A": 0.2, "B": 0.3}


def test_the_gate_reads_ratios_and_units(tmp_path) -> None:
    baseline = baseline_from([{"A": 0.3, "B": 1.0}, {"A": 0.1, "B": 3.0}, {"A": 0.2}])
    assert baseline.figures == {"A": 0.2, "B": 2.0} and baseline.max_slowdown == 1.5
    assert suite_speed_regressions({"A": 0.2 / 1.5, "B": 2.0 / 1.5}, baseline) == []
    slower = suite_speed_regressions({"A": 0.2 / 1.5 * 0.99, "B": 2.0}, baseline)
    assert len(slower) == 1 and slower[0].startswith("A ") and "1.52x slower" in slower[0]
    assert suite_speed_regressions({"B": 2.0}, baseline) == ["A: no frames-per-unit figure in this suite run"]
    other = suite_speed_regressions({"A": 0.2, "B": 2.0}, baseline, unit_version="other/0")
    assert len(other) == 1 and "remake the baseline" in other[0]
    path = tmp_path / "suite_speed.json"
    path.write_text(json.dumps(baseline.to_dict()))
    assert load_suite_speed_baseline(path).figures == baseline.figures
    path.write_text("{}")
    with pytest.raises(PerfError, match="schema"):
        load_suite_speed_baseline(path)


def test_the_committed_baseline_is_in_this_unit() -> None:
    baseline = load_suite_speed_baseline(SUITE_SPEED_BASELINE)
    assert baseline.unit_version == UNIT_VERSION and baseline.suite == "quick" and baseline.figures
    assert all(v > 0 for v in baseline.figures.values())
