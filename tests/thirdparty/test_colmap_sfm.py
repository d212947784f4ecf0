"""COLMAP as an offline agent (thirdparty.colmap_sfm): poses at finish through the contract's FinalTrajectory.
Skipped where pycolmap is not installed."""

from __future__ import annotations

import importlib
import importlib.util
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("pycolmap") is None,
                                reason="pycolmap is not installed (pip install -c constraints.txt -e '.[sfm]')")


def test_unregistered_frames_take_the_nearest_registered_pose_untracked():
    from thirdparty.colmap_sfm import fill_unregistered

    poses = np.stack([np.eye(4) * 1.0, np.eye(4) * 2.0, np.eye(4) * 3.0])
    filled, tracked = fill_unregistered(8, np.array([1, 4, 5]), poses)
    # frame: 0 1 2 3 4 5 6 7 -> nearest registered 1 1 1 (tie: the earlier) 4 4 5 5 5
    assert filled[:, 0, 0].tolist() == [1.0, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 3.0]
    assert tracked.tolist() == [False, True, False, False, True, True, False, False]


def test_method_is_available_and_a_one_frame_episode_fails_softly():
    from eval.bench.methods import check_available, get_method

    assert check_available(get_method("COLMAP")) is None  # builds it, one step, finish (COLMAP needs 3 images)


@pytest.mark.slow  # about 15 s: the full lane only
def test_recovers_office0_up_to_scale_from_the_final_trajectory():
    from eval.bench.sequence_resolve import resolve_sequence
    from eval.metrics.results import evaluate_episode
    from sim_envs.driver import run_episode
    from thirdparty.colmap_sfm import ColmapAgent

    result = run_episode(resolve_sequence("office0@kinect").make_env(max_frames=40), ColmapAgent(), progress=False)
    assert result.extras["final_trajectory"]["frames_matched"] == 40 and result.extras["registered"] >= 36
    assert result.tracked.mean() == pytest.approx(result.extras["registered"] / 40)
    metrics = evaluate_episode(result).metrics
    assert metrics["ate_sim3_rmse"] < 0.01 and metrics["rot_deg_orient_rmse"] < 0.5  # 40 frames, 0.1 m of path


def test_missing_package_is_a_clear_import_error(monkeypatch):
    import thirdparty.colmap_sfm as module

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "pycolmap" else real(name, *a))
    try:
        with pytest.raises(ImportError, match=r"pycolmap.*\[sfm\]"):
            importlib.reload(module)
    finally:
        monkeypatch.undo()
        sys.modules["thirdparty.colmap_sfm"] = importlib.reload(module)
