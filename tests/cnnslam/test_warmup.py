"""cnnslam.warmup: the install-time run that fills numba's on-disk cache."""

from cnnslam.warmup import main, warm_up


def test_the_warm_up_runs_the_system_and_counts_the_kernels(capsys):
    figures = warm_up(frames=12)
    assert figures["frames"] == 12 and figures["tracked_share"] > 0
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert main(["--frames", "8"]) == 0
    assert "numba warm-up:" in capsys.readouterr().out
