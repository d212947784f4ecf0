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
        pytest.importorskip("thirdparty.colmap_sfm")
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
