from eval.metrics.bench_metrics import main, synthetic_pair
from eval.metrics.trajectory_metrics import evaluate_trajectory


def test_benchmark_runs_and_prints_figures(capsys):
    assert main(["2000"]) == 0
    out = capsys.readouterr().out
    assert "poses: 2000" in out and "SE(3) alignment + ATE + RPE(1 s):" in out and " ms" in out


def test_synthetic_pair_is_recovered_by_alignment():
    gt, est = synthetic_pair(3000)
    m = evaluate_trajectory(gt, est)
    assert len(m.association) == 3000 and 0.012 < m.ate.rmse < 0.022  # 1 cm noise per axis: about sqrt(3) cm
