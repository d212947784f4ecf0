"""The CI regression gate against deliberate changes of CNN-SLAM (injected_regressions.toml): four regressions are
each caught (refinement off, a 3 % depth scale bias, tracking at half resolution, a 2 deg yaw bias in the answered
poses; 1 deg is below the gate's resolution for a heading bias, see the toml), and halving the tracking iterations,
which changes no byte of any run (the caps are never reached), does not alarm.

Each injected method runs the quick suite's CNN-SLAM cells and is judged as CNN-SLAM against the committed
baseline's CNN-SLAM figures; plain CNN-SLAM runs beside them as the reference of the no-effect check. A file of its
own (not test_quick_regression.py), so that under ``pytest -n 2 --dist loadfile`` these runs go on the other worker.
"""

from dataclasses import replace
from pathlib import Path

import pytest

from eval.calibrate import MATRIX, run_configuration
from eval.methods import load_methods, merge_methods
from eval.regress import compare, format_report, gate_metrics, load_baseline
from eval.suites import get_suite

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "results" / "baselines" / "quick.json"
INJECTED = Path(__file__).with_name("injected_regressions.toml")


@pytest.fixture(scope="module")
def cnn_slam_baseline():
    """The committed baseline's CNN-SLAM figures (cells and averages) alone."""
    baseline = load_baseline(BASELINE)
    return replace(baseline, metrics={k: v for k, v in baseline.metrics.items() if k.split("/")[1] == "CNN-SLAM"})


@pytest.fixture(scope="module")
def injected_runs(tmp_path_factory):
    injected = load_methods(INJECTED)
    methods = merge_methods(injected, {"CNN-SLAM": load_methods()["CNN-SLAM"]}, "the reference", False)
    suite = get_suite("quick").select(methods=list(methods))
    return run_configuration(suite, methods, tmp_path_factory.mktemp("injected-runs"), MATRIX[0], progress=False)


def _as_cnn_slam(run, method):
    assert not run.failed, [f"{o.key}: {o.error}" for o in run.failed]
    records = [dict(r, method="CNN-SLAM") for r in run.records if r["method"] == method]
    assert len(records) == 9  # 3 sequences x 3 runs
    return records


def test_the_reference_runs_pass(injected_runs, cnn_slam_baseline):
    report = compare(cnn_slam_baseline, gate_metrics(_as_cnn_slam(injected_runs, "CNN-SLAM")))
    assert report.passed and len(report.rows) == len(cnn_slam_baseline.metrics), format_report(report, True)


@pytest.mark.parametrize(
    "injected", ["refinement-off", "depth-scale-3pc", "tracking-half-resolution", "yaw-bias-2deg"]
)
def test_the_gate_catches_an_injected_regression(injected_runs, cnn_slam_baseline, injected):
    report = compare(cnn_slam_baseline, gate_metrics(_as_cnn_slam(injected_runs, injected)))
    caught = [r.metric for r in report.rows if r.status in report.failing]
    assert caught, format_report(report, True)


def test_a_change_without_effect_does_not_alarm(injected_runs, cnn_slam_baseline):
    records = _as_cnn_slam(injected_runs, "half-iterations")
    reference = _as_cnn_slam(injected_runs, "CNN-SLAM")
    assert [r["metrics"] for r in records] == [r["metrics"] for r in reference]  # the same bytes, run by run
    report = compare(cnn_slam_baseline, gate_metrics(records))
    assert report.passed, format_report(report, only_changes=True)
