"""cnnslam.tools.warmup: the install-time run that fills numba's on-disk cache."""

import pytest

from cnnslam.errors import CnnSlamError
from cnnslam.tools.warmup import METHODS_FILE, _baselines_of, main, warm_up, warm_up_baselines, warmup_agents


def test_the_warm_up_runs_the_system_and_counts_the_kernels(capsys):
    figures = warm_up(frames=12)
    assert figures["frames"] == 12 and figures["tracked_share"] > 0
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0
    assert main(["--frames", "8", "--parts", "system"]) == 0
    assert "numba warm-up (system):" in capsys.readouterr().out


def test_the_baselines_warm_up_runs_each_agent_through_the_driver():
    laina = warmup_agents()["system"]
    figures = warm_up_baselines(frames=6, agents=laina)
    assert figures["frames"] == 6 and figures["seconds_LainaAgent"] > 0
    # Laina's ICP kernels are among those the baselines' part calls
    assert figures["numba_signatures_compiled"] + figures["numba_signatures_from_cache"] > 0


def test_the_agents_come_from_the_method_tables_warmup_entries():
    parts = warmup_agents()
    assert METHODS_FILE.name == "methods.toml" and METHODS_FILE.parent.name == "eval"
    # the baselines with numba kernels of their own, built with their tables' keyword arguments
    assert parts == {"system": (("cnnslam.baselines.laina:LainaAgent", {}),),
                     "baselines": (("cnnslam.baselines.orb:OrbSlamAgent", {}),
                                   ("cnnslam.baselines.remode:RemodeAgent", {"threads": False}))}
    assert _baselines_of(False) == {"system": (), "baselines": parts["system"] + parts["baselines"]}
    assert _baselines_of(True) == parts


def test_a_new_table_with_warmup_is_warmed_up_and_a_bad_one_refused(tmp_path, capsys):
    table = tmp_path / "methods.toml"
    table.write_text('[methods.mine]\nentry_point = "my_agents:Mine"\nkwargs = { k = 1 }\nwarmup = "baselines"\n'
                     '[methods.other]\nentry_point = "my_agents:Other"\n')
    assert warmup_agents(table) == {"system": (), "baselines": (("my_agents:Mine", {"k": 1}),)}
    table.write_text('[methods.mine]\nentry_point = "my_agents:Mine"\nwarmup = "later"\n')
    with pytest.raises(CnnSlamError, match=r"methods.mine.warmup = 'later' needs an entry_point and one of system"):
        warmup_agents(table)
    with pytest.raises(SystemExit) as exit_:
        main(["--method-file", str(tmp_path / "absent.toml")])
    assert exit_.value.code == 2 and "cannot read the method table" in capsys.readouterr().err


def test_the_two_parts_run_side_by_side_in_their_own_processes(capsys):
    assert main(["--jobs", "2", "--frames", "6"]) == 0
    out = capsys.readouterr().out
    # Laina (whose global model is the system's) runs in the system's process, after it; each baseline once
    assert "numba warm-up (system, then LainaAgent):" in out and "numba warm-up (baselines):" in out


def test_a_bad_jobs_count_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--jobs", "0"])
    assert "--jobs must be >= 1" in capsys.readouterr().err
