import json
import math

import pytest

from cnnslam.cli import main
from eval.regress import (
    DEFAULT_TOLERANCES,
    Baseline,
    GateError,
    Tolerance,
    compare,
    compare_metric,
    format_report,
    load_baseline,
    load_run_metrics,
    suite_metrics,
    update_baseline,
)


@pytest.mark.parametrize(
    ("direction", "run", "status"),
    [
        ("lower", 0.105, "equal"),  # +0.005 within max(0.001, 10 % of 0.1)
        ("lower", 0.12, "regressed"),
        ("lower", 0.08, "improved"),
        ("higher", 0.12, "improved"),
        ("higher", 0.08, "regressed"),
        ("match", 0.12, "regressed"),
        ("match", 0.095, "equal"),
    ],
)
def test_directions_and_tolerances(direction, run, status):
    rule = Tolerance("x", direction, abs=0.001, rel=0.10)
    row = compare_metric("x", 0.1, run, rule)
    assert row.status == status and row.allowed == pytest.approx(0.01) and row.delta == pytest.approx(run - 0.1)


def test_absolute_tolerance_dominates_near_zero():
    assert compare_metric("x", 0.0, 0.0009, Tolerance("x", "lower", abs=0.001, rel=0.5)).status == "equal"
    assert compare_metric("x", 0.0, 0.0011, Tolerance("x", "lower", abs=0.001, rel=0.5)).status == "regressed"


def test_missing_nan_and_new_metrics():
    base = Baseline({"a/ate_rmse": 0.1, "a/depth_percent_correct": 20.0, "a/only_nan": math.nan})
    report = compare(base, {"a/ate_rmse": 0.1, "a/depth_percent_correct": math.nan, "a/extra": 1.0})
    status = {r.metric: r.status for r in report.rows}
    assert status == {
        "a/ate_rmse": "equal",
        "a/depth_percent_correct": "missing",  # NaN where the baseline has a number
        "a/only_nan": "missing",  # absent from the run
        "a/extra": "new",
    }
    assert not report.passed and report.counts() == {"equal": 1, "missing": 2, "new": 1}
    text = format_report(report)
    assert text.splitlines()[-1].startswith("FAIL: 4 metrics") and "a/extra" in text
    assert "a/ate_rmse" not in format_report(report, only_changes=True)


def test_default_rules_pick_directions_by_name():
    base = Baseline({})
    assert base.tolerance_for("office0/CNN-SLAM/ate_rmse").direction == "lower"
    assert base.tolerance_for("office0/CNN-SLAM/depth_percent_correct").direction == "higher"
    assert base.tolerance_for("office0/CNN-SLAM/ate_pairs").direction == "match"
    assert base.tolerance_for("whatever").pattern == "*"
    with pytest.raises(GateError, match="direction"):
        Tolerance("x", "up")
    with pytest.raises(GateError, match="abs must be"):
        Tolerance("x", "lower", abs=-1.0)


def test_files_and_suite_flattening(tmp_path):
    records = [
        {"sequence": "s1", "method": "A", "metrics": {"ate_rmse": 0.1}},
        {"sequence": "s1", "method": "A", "metrics": {"ate_rmse": 0.3}},
        {"sequence": "s2", "method": "A", "metrics": {"ate_rmse": None}},
    ]
    flat = suite_metrics(records)
    assert flat["s1/A/ate_rmse"] == pytest.approx(0.2) and math.isnan(flat["s2/A/ate_rmse"])
    (tmp_path / "list.json").write_text(json.dumps(records))
    assert load_run_metrics(tmp_path / "list.json").keys() == flat.keys()
    (tmp_path / "bad.json").write_text('{"metrics": {"a": "fast"}}')
    with pytest.raises(GateError, match="not a number"):
        load_run_metrics(tmp_path / "bad.json")
    (tmp_path / "broken.json").write_text('{"metrics": ')
    with pytest.raises(GateError, match="broken.json:1: not valid JSON"):
        load_run_metrics(tmp_path / "broken.json")
    new = update_baseline(tmp_path / "results" / "base.json", {"x/ate_rmse": 0.5})
    assert new.tolerances == DEFAULT_TOLERANCES
    saved = load_baseline(tmp_path / "results" / "base.json")
    assert saved.metrics == {"x/ate_rmse": 0.5} and saved.tolerances == DEFAULT_TOLERANCES
    custom = json.loads((tmp_path / "results" / "base.json").read_text())
    custom["tolerances"] = [{"pattern": "*", "direction": "higher", "abs": 0.0, "rel": 0.0}]
    (tmp_path / "results" / "base.json").write_text(json.dumps(custom))
    kept = update_baseline(tmp_path / "results" / "base.json", {"x/ate_rmse": 0.4})
    assert kept.tolerances == (Tolerance("*", "higher"),) and kept.metrics == {"x/ate_rmse": 0.4}


def test_command_line_exit_codes(tmp_path, capsys):
    base, run = tmp_path / "base.json", tmp_path / "run.json"
    base.write_text(json.dumps({"schema": "cnnslam-baseline/1", "metrics": {"s/A/ate_rmse": 0.1, "s/A/fps": 30.0}}))
    run.write_text(json.dumps({"metrics": {"s/A/ate_rmse": 0.09, "s/A/fps": 31.0}}))
    assert main(["regress", str(base), str(run)]) == 0  # improvement passes
    out = capsys.readouterr().out
    assert "improved" in out and out.strip().splitlines()[-1].startswith("PASS")
    run.write_text(json.dumps({"metrics": {"s/A/ate_rmse": 0.2, "s/A/fps": 31.0}}))
    assert main(["regress", str(base), str(run)]) == 1
    assert "regressed" in capsys.readouterr().out
    run.write_text(json.dumps({"metrics": {"s/A/fps": 31.0}}))
    assert main(["regress", str(base), str(run)]) == 1  # a missing metric fails
    assert main(["regress", str(tmp_path / "nope.json"), str(run)]) == 2
    assert "cannot read" in capsys.readouterr().err
    assert main(["regress", str(base), str(run), "--update"]) == 0
    assert load_baseline(base).metrics == {"s/A/fps": 31.0}
    assert main(["regress", str(base), str(run)]) == 0
