"""The CI regression gate: the quick suite with the real agents, compared metric by metric with the committed
baseline results/baselines/quick.json (eval.regress). After an intended change of results, update the baseline with
``cnnslam bench quick --update-baseline`` and commit it like code.

The second test makes sure the gate can fail: the same run, doctored (a worse ATE, a worse depth, a lost run),
must not pass.
"""

import copy
import math
from pathlib import Path

import pytest

from eval.executors import LocalExecutor
from eval.methods import load_methods
from eval.regress import compare, format_report, load_baseline, suite_metrics
from eval.runner import run_suite
from eval.suites import get_suite

pytestmark = pytest.mark.slow
BASELINE = Path(__file__).resolve().parents[2] / "results" / "baselines" / "quick.json"


@pytest.fixture(scope="module")
def baseline():
    if not BASELINE.is_file():
        pytest.fail(f"no committed baseline at {BASELINE}; create it with: cnnslam bench quick --update-baseline")
    return load_baseline(BASELINE)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    # the configuration `cnnslam bench quick --update-baseline` makes the baseline with: local pool of 2 workers,
    # a fresh worker per run, no plots
    out = tmp_path_factory.mktemp("quick-runs")
    return run_suite(get_suite("quick"), load_methods(), out, executor=LocalExecutor(jobs=2), plots=False,
                     progress=False)  # fmt: skip


def test_the_quick_suite_passes_the_committed_baseline(quick_run, baseline):
    assert not quick_run.failed, [f"{o.key}: {o.error}" for o in quick_run.failed]
    report = compare(baseline, suite_metrics(quick_run.records))
    assert report.passed, format_report(report, only_changes=True)
    assert report.counts().get("equal", 0) >= 0.9 * len(baseline.metrics)


def test_the_gate_fails_on_a_doctored_run(quick_run, baseline):
    records = copy.deepcopy(quick_run.records)
    ate = next(r for r in records if r["method"] != "oracle" and math.isfinite(r["metrics"].get("ate_rmse", math.nan)))
    ate["metrics"]["ate_rmse"] = 1.5 * ate["metrics"]["ate_rmse"] + 0.05
    depth = next(r for r in records if r["metrics"].get("depth_percent_correct", 0) > 5)
    depth["metrics"]["depth_percent_correct"] -= 5.0
    lost = records.pop()  # a run that crashed: its metrics are missing
    report = compare(baseline, suite_metrics(records))
    status = {row.metric: row.status for row in report.rows}
    assert not report.passed
    assert status[f"{ate['sequence']}/{ate['method']}/ate_rmse"] == "regressed"
    assert status[f"{depth['sequence']}/{depth['method']}/depth_percent_correct"] == "regressed"
    assert status[f"{lost['sequence']}/{lost['method']}/frames"] == "missing"
