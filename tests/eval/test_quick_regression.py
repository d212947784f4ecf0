"""The CI regression gate: the quick suite with the real agents (3 runs per cell), its gated figures (medians over
the runs) compared with the committed baseline results/baselines/quick.json, whose tolerances were measured over a
perturbation matrix (eval/bench/calibrate.py). After an intended change of results: ``cnnslam bench quick
--update-baseline`` (or ``--calibrate`` when the spread may have changed) and commit the baseline like code.

Proved here, as the baseline's calibration promises:

- the unchanged tree passes (on this machine the reference configuration gives the baseline's bytes);
- the network's outputs perturbed in their last bits in every run (what another CPU does) with torch's oneDNN off
  still pass: the gate holds across machines (two are measured in the baseline: its reference machine's figures
  and each record in results/baselines/machines/quick/ pass it, see docs/benchmarks.md);
- four injected regressions of CNN-SLAM are each caught: refinement off, a 3 % depth scale bias, tracking at half
  resolution, a 2 deg yaw bias in the answered poses (1 deg is below the gate's resolution for a heading bias: see
  injected_regressions.toml); halving the tracking iterations changes no byte of any run
  (the caps are never reached) and must not alarm;
- a doctored run (a worse ATE, a worse depth, a lost run) fails;
- the suite speed gate: every method's runs, in frames per machine unit, are not 1.5 times slower than in
  results/baselines/suite_speed.json (eval/bench/suite_speed.py), and a run doctored 1.6 times slower fails.
"""

import math
from pathlib import Path

import pytest

from eval.bench.calibrate import MATRIX, Perturbation, run_configuration
from eval.bench.gate_baseline import load_baseline
from eval.bench.methods import load_methods
from eval.bench.regress import compare, format_report, gate_metrics
from eval.bench.suite_speed import load_suite_speed_baseline, suite_speed_regressions, suite_speeds
from eval.bench.suites import get_suite

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
BASELINE = ROOT / "results" / "baselines" / "quick.json"
INJECTED = Path(__file__).with_name("injected_regressions.toml")
NETWORK_METHODS = ("CNN-SLAM", "Laina")  # the only quick-suite methods whose results depend on the network's bits


@pytest.fixture(scope="module")
def baseline():
    if not BASELINE.is_file():
        pytest.fail(f"no committed baseline at {BASELINE}; create it with: cnnslam bench quick --calibrate")
    return load_baseline(BASELINE)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    # the reference configuration of the calibration: 2 runs at a time, a fresh worker per run, no plots
    out = tmp_path_factory.mktemp("quick-runs")
    return run_configuration(get_suite("quick"), load_methods(), out, MATRIX[0], progress=False)


def test_the_quick_suite_passes_the_committed_baseline(quick_run, baseline):
    assert not quick_run.failed, [f"{o.key}: {o.error}" for o in quick_run.failed]
    assert not quick_run.skipped_methods
    report = compare(baseline, gate_metrics(quick_run.records))
    assert report.passed, format_report(report, only_changes=True)
    assert len(report.rows) >= len(baseline.metrics)


def test_no_method_of_the_quick_suite_is_slower_than_its_speed_baseline(quick_run):
    """Frames per machine unit, each method's best run against results/baselines/suite_speed.json (a neighbour's
    burst slows some runs, a real slowdown all of them); CNN-SLAM's figure doctored to 1.6 times the baseline's
    time fails."""
    baseline = load_suite_speed_baseline()
    speeds = suite_speeds(quick_run)
    assert suite_speed_regressions(speeds, baseline) == [], speeds
    slowed = {**speeds, "CNN-SLAM": baseline.figures["CNN-SLAM"] / 1.6}
    failures = suite_speed_regressions(slowed, baseline)
    assert len(failures) == 1 and failures[0].startswith("CNN-SLAM "), failures


def test_the_gate_holds_with_the_network_perturbed_as_on_another_cpu(quick_run, baseline, tmp_path):
    other_cpu = Perturbation("another-cpu+onednn-off", 2, {}, "",
                             {"jitter_seed_fallback": 7919, "onednn": False})
    suite = get_suite("quick").select(methods=list(NETWORK_METHODS))
    perturbed = run_configuration(suite, load_methods(), tmp_path, other_cpu, progress=False)
    assert not perturbed.failed, [f"{o.key}: {o.error}" for o in perturbed.failed]
    figures = {**gate_metrics(quick_run.records), **gate_metrics(perturbed.records)}
    report = compare(baseline, figures)
    assert report.passed, format_report(report, only_changes=True)
    # the perturbation did reach the runs: CNN-SLAM's figures are not all byte-identical to the unperturbed ones
    reference = gate_metrics(quick_run.records)
    moved = [k for k, v in gate_metrics(perturbed.records).items() if k.split("/")[1] == "CNN-SLAM"
             and not math.isclose(v, reference[k], rel_tol=0, abs_tol=0)]  # fmt: skip
    assert moved, "the perturbation changed nothing: the predictor options did not reach the agents"
    # explicit: the perturbed runs are other runs (their fingerprints carry the options), not the same ones
    fingerprints = {r.metadata["fingerprint"] for r in quick_run.records}
    assert not fingerprints & {r.metadata["fingerprint"] for r in perturbed.records}


@pytest.fixture(scope="module")
def injected_runs(tmp_path_factory):
    methods = load_methods(INJECTED)
    suite = get_suite("quick").select(methods=list(methods))
    out = tmp_path_factory.mktemp("injected-runs")
    return run_configuration(suite, methods, out, MATRIX[0], progress=False)


def _as_cnn_slam(run, injected):
    assert not run.failed, [f"{o.key}: {o.error}" for o in run.failed]
    records = [r.replace(method="CNN-SLAM") for r in run.records if r.method == injected]
    assert len(records) == 9  # 3 sequences x 3 runs
    return records


@pytest.mark.parametrize(
    "injected", ["refinement-off", "depth-scale-3pc", "tracking-half-resolution", "yaw-bias-2deg"]
)
def test_the_gate_catches_an_injected_regression(quick_run, injected_runs, baseline, injected):
    figures = {**gate_metrics(quick_run.records), **gate_metrics(_as_cnn_slam(injected_runs, injected))}
    report = compare(baseline, figures)
    caught = [r.metric for r in report.rows if r.status in report.failing]
    assert caught and all(m.split("/")[1] == "CNN-SLAM" for m in caught), format_report(report, True)


def test_a_change_without_effect_does_not_alarm(quick_run, injected_runs, baseline):
    records = _as_cnn_slam(injected_runs, "half-iterations")
    reference = [r for r in quick_run.records if r.method == "CNN-SLAM"]
    assert [r.metrics for r in records] == [r.metrics for r in reference]  # the same bytes, run by run
    report = compare(baseline, {**gate_metrics(quick_run.records), **gate_metrics(records)})
    assert report.passed, format_report(report, only_changes=True)


def test_the_gate_fails_on_a_doctored_run(quick_run, baseline):
    first = get_suite("quick").sequences[0].name  # office0 through the suite's camera

    def doctored(r):  # every run of a cell worse: its median moves
        if r.method != "CNN-SLAM" or r.sequence != first:
            return r
        m = r.metrics
        return r.replace(metrics={**m, "ate_rmse": 1.5 * m["ate_rmse"] + 0.05,
                                  "depth_percent_correct": m["depth_percent_correct"] - 5.0})

    # the ORB runs of that sequence crashed: their metrics are missing
    records = [doctored(r) for r in quick_run.records if not (r.method == "ORB" and r.sequence == first)]
    report = compare(baseline, gate_metrics(records))
    status = {row.metric: row.status for row in report.rows}
    assert not report.passed
    assert status[f"{first}/CNN-SLAM/ate_rmse"] == "regressed"
    assert status[f"{first}/CNN-SLAM/depth_percent_correct"] == "regressed"
    assert status["avg/CNN-SLAM/ate_rmse"] == "regressed"
    assert status[f"{first}/ORB/frames"] == "missing"
