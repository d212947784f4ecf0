"""The committed baseline results/baselines/tum_reference.json holds the judge's own reference figures
(tests/reference_facts.toml, with their sources) with tight tolerances: the gate, run on the judge itself, must
pass."""

from pathlib import Path

from eval.bench.gate_baseline import load_baseline
from eval.bench.regress import compare, format_report
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import evaluate_trajectory

BASELINE = Path(__file__).resolve().parents[2] / "results" / "baselines" / "tum_reference.json"


def reference_metrics(tum_dir: Path, cases: list[dict]) -> dict[str, float]:
    """The baseline's figures computed now: ATE RMSE, pairs and Sim(3) scale of each reference case, under both
    associations and both alignments."""
    out = {}
    for case in cases:
        gt = PoseTrajectory.from_tum_file(tum_dir / case["groundtruth"], duplicate_timestamps="last")
        est = PoseTrajectory.from_tum_file(tum_dir / case["estimate"])
        for association in ("tum", "nearest"):
            for alignment in ("se3", "sim3"):
                m = evaluate_trajectory(gt, est, alignment=alignment, association=association)
                key = f"{case['name']}/{association}/{alignment}"
                out[f"{key}/ate_rmse"] = m.ate.rmse
                out[f"{key}/ate_pairs"] = float(m.ate.pairs)
                out[f"{key}/scale"] = m.scale
    return out


def test_the_baseline_holds_the_reference_figures_to_their_printed_digits(reference_facts):
    baseline = load_baseline(BASELINE)
    assert len(baseline.metrics) == 24
    for case in reference_facts["trajectory"]["cases"]:
        for association, by_alignment in case["rmse"].items():
            for alignment, rmse in by_alignment.items():
                key = f"{case['name']}/{association}/{alignment}"
                assert f"{baseline.metrics[key + '/ate_rmse']:.6f}" == rmse, key
                assert f"{baseline.metrics[key + '/scale']:.4f}" == case["scale"], key
        assert baseline.metrics[f"{case['name']}/tum/se3/ate_pairs"] == case["pairs"]


def test_the_judge_passes_its_committed_reference_baseline(tum_dir, reference_facts):
    report = compare(load_baseline(BASELINE), reference_metrics(tum_dir, reference_facts["trajectory"]["cases"]))
    assert report.passed, format_report(report, only_changes=True)
    assert report.counts() == {"equal": 24}
