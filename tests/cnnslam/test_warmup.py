"""cnnslam.warmup: the install-time run that fills numba's on-disk cache."""

import pytest

from cnnslam.warmup import BASELINE_AGENTS, PARTS, main, split_parts, warm_up, warm_up_baselines


def test_the_warm_up_runs_the_system_and_counts_the_kernels(capsys):
    figures = warm_up(frames=12)
    assert figures["frames"] == 12 and figures["tracked_share"] > 0
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert main(["--frames", "8", "--parts", "system"]) == 0
    assert "numba warm-up (system " in capsys.readouterr().out


def test_the_baselines_warm_up_runs_each_agent_through_the_driver():
    figures = warm_up_baselines(frames=6, agents=(BASELINE_AGENTS["laina"],))
    assert figures["frames"] == 6 and figures["seconds_LainaAgent"] > 0
    # Laina's ICP kernels are among those the baselines' part calls
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert {entry.partition(":")[0] for entry, _ in BASELINE_AGENTS.values()} == {
        "cnnslam.baselines.orb", "cnnslam.baselines.remode", "cnnslam.baselines.laina"}


def test_the_groups_of_parts_run_side_by_side_in_their_own_processes(capsys):
    assert main(["--jobs", "2", "--frames", "6", "--parts", "system", "laina", "orb"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2 and out[0].startswith("numba warm-up (system ") and ", laina " not in out[0]
    assert out[1].startswith("numba warm-up (orb ") and ", laina " in out[1]


def test_the_parts_are_split_by_their_usual_time():
    assert split_parts(PARTS, 1) == [list(PARTS)]
    assert split_parts(PARTS, 2) == [["system", "laina"], ["orb", "remode"]]
    assert split_parts(["remode"], 2) == [["remode"]]
    assert sorted(p for g in split_parts(PARTS, 3) for p in g) == sorted(PARTS)


def test_a_bad_jobs_count_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--jobs", "0"])
    assert "--jobs must be >= 1" in capsys.readouterr().err
