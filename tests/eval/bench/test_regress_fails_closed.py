"""The gate fails closed: a baseline that is missing, unreadable, malformed, of another schema, suite or selection is
refused before any run; a tolerance that can never fail inside its metric's bounds and a rule that can never match
are refused when the baseline is loaded (and capped by the writers of a baseline); tracked -> lost is a regression
whatever the tolerance; a built-in suite's baseline is found from the package, not the working folder."""

import json
from pathlib import Path

import pytest

from eval.bench.gate_baseline import (
    Baseline,
    GateError,
    Tolerance,
)
from eval.bench.regress import GateAction, apply_gate, check_gate, compare, format_report
from eval.errors import InputError
from eval.metrics.results import MIN_TRACKED_SHARE, RunRecord

ROOT = Path(__file__).resolve().parents[3]
QUICK = ROOT / "results" / "baselines" / "quick.json"
CELLS = [("s", "A")]


def _write(path, data):
    path.write_text(json.dumps(data))
    return path


def _baseline(tmp_path, metrics=None, **extra):
    data = {"schema": "cnnslam-baseline/2", "metrics": metrics or {"s/A/ate_rmse": 0.1, "s/A/frames": 10.0}}
    return _write(tmp_path / "base.json", {**data, **extra})


# ------------------------------------------------------------------------------------------- tracked -> lost
def _records(share, runs=3):
    return [RunRecord("s", "A", "A", {"ate_rmse": 0.1, "tracked_share": share, "frames": 60.0}) for _ in range(runs)]


def test_tracked_to_lost_is_a_regression_whatever_the_tolerance():
    loose = (Tolerance("*tracked_share", "higher", abs=0.95),)  # 1.0 - 0.95 > 0: crossable, but only by ~0
    base = Baseline({"s/A/tracked_share": 1.0}, loose)
    below = MIN_TRACKED_SHARE - 0.05
    report = compare(base, {"s/A/tracked_share": below})
    assert not report.passed and report.rows[0].status == "regressed"
    assert "tracked -> lost: s/A/tracked_share: tracked 100 % -> tracked" in format_report(report)
    never = compare(base, {"s/A/tracked_share": 0.0})
    assert not never.passed and "never initialised" in format_report(never)
    assert compare(base, {"s/A/tracked_share": MIN_TRACKED_SHARE}).passed  # at the threshold: still tracking
    # a cell that was a failure in the baseline already is held to its tolerance only
    failed = Baseline({"s/A/tracked_share": 0.5}, (Tolerance("*tracked_share", "higher", abs=0.2),))
    assert compare(failed, {"s/A/tracked_share": 0.4}).passed


def test_apply_gate_fails_on_a_lost_cell_and_on_a_missing_baseline(tmp_path):
    path = tmp_path / "base.json"
    made = apply_gate(_records(1.0), GateAction.UPDATE, path, gated=True, description="test")
    assert made.passed and path.is_file()
    assert apply_gate(_records(1.0), GateAction.COMPARE, path, gated=True, description="").passed
    lost = apply_gate(_records(0.5), GateAction.COMPARE, path, gated=True, description="")
    assert not lost.passed and "tracked -> lost" in lost.message
    path.unlink()  # gone after the check before the runs: the gate fails, never passes
    gone = apply_gate(_records(1.0), GateAction.COMPARE, path, gated=True, description="")
    assert gone is not None and not gone.passed and "cannot read" in gone.message


# ------------------------------------------------------------------------------------------ check before runs
def test_check_gate_refuses_a_missing_or_unusable_baseline_before_any_run(tmp_path):
    assert issubclass(GateError, InputError)
    with pytest.raises(GateError, match="no baseline at .*MISSING.json; make it with --update-baseline"):
        check_gate(GateAction.COMPARE, tmp_path / "MISSING.json", gated=True, cells=CELLS)
    with pytest.raises(GateError, match=r"\(a folder\)"):
        check_gate(GateAction.COMPARE, tmp_path, gated=True, cells=CELLS)
    broken = tmp_path / "broken.json"
    broken.write_text('{"metrics": ')
    with pytest.raises(GateError, match="not valid JSON"):
        check_gate(GateAction.COMPARE, broken, gated=True, cells=CELLS)
    with pytest.raises(GateError, match="not valid JSON"):  # an update cannot read what it would keep either
        check_gate(GateAction.UPDATE, broken, gated=True, cells=CELLS)
    # creating one, or no gate: nothing to check
    check_gate(GateAction.UPDATE, tmp_path / "new.json", gated=True, cells=CELLS)
    check_gate(GateAction.REPLACE, tmp_path / "new.json", gated=True, cells=CELLS)
    check_gate(GateAction.OFF, tmp_path / "MISSING.json", gated=True, cells=CELLS)
    check_gate(GateAction.COMPARE, tmp_path / "MISSING.json", gated=False, cells=CELLS)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ({"schema": "cnnslam-run/1", "metrics": {"s/A/ate_rmse": 0.1}}, "schema 'cnnslam-run/1' is not a baseline's"),
        ({"schema": "cnnslam-baseline/2", "metrics": {}}, "holds no figures"),
        ({"metrics": {"s/A/ate_rmse": 0.1}, "tolerances": {"*": 1}}, "each tolerance is"),
        ({"metrics": {"s/A/ate_rmse": 0.1}, "tolerances": [{"pattern": 3}]}, "pattern is a text"),
        ({"metrics": {"s/A/ate_rmse": 0.1}, "calibration": "by hand"}, "'calibration' is an object"),
        ({"metrics": {"s/A/ate_rmse": 0.1}, "calibrated": {"s/A/ate_rmse": {"allowed": -1}}}, "'calibrated' maps"),
        ({"metrics": {"s/A/ate_rmse": 0.1}, "policy": "sideways"}, "policy"),
        ([1, 2], "a JSON object with a 'metrics' object"),
    ],
)
def test_a_malformed_baseline_is_one_clear_error(tmp_path, content, message):
    path = _write(tmp_path / "base.json", content)
    with pytest.raises(GateError, match=message) as info:
        check_gate(GateAction.COMPARE, path, gated=True, cells=CELLS)
    assert "\n" not in str(info.value)


def test_check_gate_refuses_a_baseline_of_another_selection(tmp_path):
    path = _baseline(tmp_path, {"s/A/ate_rmse": 0.1, "s/A/frames": 60.0, "avg/A/ate_rmse": 0.1})
    check_gate(GateAction.COMPARE, path, gated=True, cells=[("s", "A")], frames=60)
    with pytest.raises(GateError, match="lacks 1 sequence/method cell.*e.g. s/B.*pass ungated"):
        check_gate(GateAction.COMPARE, path, gated=True, cells=[("s", "A"), ("s", "B")])
    with pytest.raises(GateError, match="holds figures of 1 sequence/method cell.*e.g. s/A"):
        check_gate(GateAction.COMPARE, path, gated=True, cells=[("t", "A")])
    with pytest.raises(GateError, match="scored 60 frames .*ask for 10"):
        check_gate(GateAction.COMPARE, path, gated=True, cells=[("s", "A")], frames=10)


def test_a_built_in_suites_baseline_is_found_from_the_package_not_the_working_folder(tmp_path, monkeypatch):
    from eval.bench.suites import SUITES, get_suite

    monkeypatch.chdir(tmp_path)  # no results/ here
    path = SUITES["quick"].baseline_path
    assert path.is_absolute() and path.resolve() == QUICK.resolve()
    quick = get_suite("quick")
    # the committed baseline is of the quick suite as defined: every cell, its frames
    cells = [(s.name, m) for s in quick.sequences for m in quick.methods]
    check_gate(GateAction.COMPARE, path, gated=True, cells=cells, frames=quick.frames)
