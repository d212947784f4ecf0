"""``cnnslam config``: every method prints its one configuration tree (the agent's ``config``), ``--set`` merged
in as ``cnnslam bench --set`` merges it."""

from __future__ import annotations

import tomllib

import pytest

from cnnslam.cli import main


@pytest.mark.parametrize(("method", "key", "value"), [
    ("CNN-SLAM", "tracking", {"pyramid_levels": 4}),
    ("Laina", "icp", None),
    ("REMODE", "patch_size", 5),
    ("ORB", "n_features", 1000),
    ("ORB-SLAM3", "n_features", 1000),
    ("COLMAP", "overlap", 10),
    ("oracle", "keyframe_every", 10),
    ("constant-pose", "tracked", True),
])
def test_every_method_prints_its_configuration(capsys, method, key, value):
    if method == "COLMAP":
        pytest.importorskip("thirdparty.colmap_sfm", reason="COLMAP's bindings are not installed (the sfm extra: "
                            "pip install -c constraints.txt -e '.[sfm]')")
    assert main(["config", method]) == 0
    text = capsys.readouterr().out
    assert text.startswith(f"# {method}: ") and "exposes no configuration" not in text
    tree = tomllib.loads(text)
    assert key in tree
    if isinstance(value, dict):
        assert value.items() <= tree[key].items()
    elif value is not None:
        assert tree[key] == value


def test_set_values_are_checked_against_the_configuration(capsys):
    assert main(["config", "oracle", "--set", "keyframe_every=4"]) == 0
    assert "keyframe_every = 4" in capsys.readouterr().out
    assert main(["config", "CNN-SLAM", "--set", "tracking.pyramid_levels=abc"]) == 2
    err = capsys.readouterr().err
    assert "'tracking.pyramid_levels' must be an integer, got 'abc'" in err and len(err.strip().splitlines()) == 1
    assert main(["config", "NoSuch"]) == 2
    assert "unknown method 'NoSuch'; valid methods: CNN-SLAM" in capsys.readouterr().err


@pytest.mark.parametrize(("arguments", "files", "named", "valid"), [
    (["NoSuch"], {}, "unknown method 'NoSuch'", "valid methods: CNN-SLAM"),
    (["CNN-SLAM", "--set", "tracking.pyramid_levels"], {}, "got 'tracking.pyramid_levels'", "KEY=VALUE"),
    (["CNN-SLAM", "--set", "nosuch.key=1"], {}, "unknown config key 'nosuch.key'", "valid keys: tracking.*"),
    (["CNN-SLAM", "--set", "tracking.pyramid_levels=0"], {}, "tracking.pyramid_levels must be in 1..8", "got 0"),
    (["CNN-SLAM", "--set", "system.seed=7"], {}, "--set system.seed=7", "set it with --seed"),
    (["CNN-SLAM", "--seed", "-1"], {}, "system.seed must be >= 0", "got -1"),
    (["oracle", "--set", "keyframe_every=0"], {}, "keyframe_every must be >= 1", "got 0"),
    (["Mine", "--method-file", "{tmp}/missing.toml"], {}, "{tmp}/missing.toml: cannot read", "No such file"),
    (["Mine", "--method-file", "{tmp}/bad.toml"], {"bad.toml": "[x\n"}, "{tmp}/bad.toml: not valid TOML", "line 1"),
    (["Mine", "--method-file", "{tmp}/m.toml"], {"m.toml": '[methods.Mine]\nentry_point = "no_such_mod:A"\n'},
     "cannot import the agent module 'no_such_mod'", "no_such_mod:A"),
    (["Mine", "--method-file", "{tmp}/m.toml"],
     {"m.toml": '[methods.Mine]\nentry_point = "cnnslam.agent:GroundTruthAidedAgent"\nkwargs = {nope = 1}\n'},
     "method 'Mine' (cnnslam.agent:GroundTruthAidedAgent): TypeError:", "unexpected keyword argument 'nope'"),
    (["Mine", "--method-file", "{tmp}/m.toml"],
     {"m.toml": '[methods.Mine]\nentry_point = "agent_that_fails:A"\n',
      "agent_that_fails.py": 'raise RuntimeError("first line\\nsecond line")\n'},
     "method 'Mine' (agent_that_fails:A): RuntimeError: first line second line", ""),
])
def test_bad_input_exits_2_with_one_line(tmp_path, monkeypatch, capsys, arguments, files, named, valid):
    """An unknown method, a bad --set (no KEY=VALUE, an unknown key, a value out of range, the key the seed goes
    into), a bad --seed, a missing or malformed method file, an agent that cannot be imported or built (its message
    folded into the one line): exit 2 and one line naming the value and what is valid, nothing on stdout."""
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    arguments = [a.replace("{tmp}", str(tmp_path)) for a in arguments]
    assert main(["config", *arguments]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cnnslam config: error: "), captured.err
    assert named.replace("{tmp}", str(tmp_path)) in lines[0] and valid in lines[0] and captured.out == ""
