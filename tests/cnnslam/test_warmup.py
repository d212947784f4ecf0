"""cnnslam.warmup: the install-time run that fills numba's on-disk cache."""

import pytest

from cnnslam.warmup import BASELINE_AGENTS, SYSTEM_SIDE_BASELINES, main, warm_up, warm_up_baselines


def test_the_warm_up_runs_the_system_and_counts_the_kernels(capsys):
    figures = warm_up(frames=12)
    assert figures["frames"] == 12 and figures["tracked_share"] > 0
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert main(["--frames", "8", "--parts", "system"]) == 0
    assert "numba warm-up (system):" in capsys.readouterr().out


def test_the_baselines_warm_up_runs_each_agent_through_the_driver():
    laina = tuple(a for a in BASELINE_AGENTS if a[0].endswith(":LainaAgent"))
    figures = warm_up_baselines(frames=6, agents=laina)
    assert figures["frames"] == 6 and figures["seconds_LainaAgent"] > 0
    # Laina's ICP kernels are among those the baselines' part calls
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert {entry.partition(":")[0] for entry, _ in BASELINE_AGENTS} == {
        "cnnslam.baselines.orb", "cnnslam.baselines.remode", "cnnslam.baselines.laina"}


def test_the_two_parts_run_side_by_side_in_their_own_processes(capsys):
    assert main(["--jobs", "2", "--frames", "6"]) == 0
    out = capsys.readouterr().out
    # Laina (whose global model is the system's) runs in the system's process, after it; each baseline once
    assert "numba warm-up (system, then LainaAgent):" in out and "numba warm-up (baselines):" in out
    assert set(SYSTEM_SIDE_BASELINES) < {entry for entry, _ in BASELINE_AGENTS}


def test_a_bad_jobs_count_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--jobs", "0"])
    assert "--jobs must be >= 1" in capsys.readouterr().err
