"""Open3D's RGB-D odometry as an agent (thirdparty.open3d_odometry): the measured depth, metric poses.

Open3D-odometry is an optional method: open3d (a 400 MB wheel) is in neither the dev nor the test extra, so CI and
``make test`` skip this module, with the reason naming the install command: ``pip install -c constraints.txt -e
'.[open3d]'`` (open3d 0.19.0, pinned; on Debian also ``apt-get install libusb-1.0-0``). With it installed, all four
tests run (the office0 one marked slow)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("open3d", reason="open3d is not installed: the optional Open3D-odometry method (pip install -c "
                              "constraints.txt -e '.[open3d]'; Debian: apt-get install libusb-1.0-0)")


def test_method_is_available():
    from eval.bench.methods import check_available, get_method

    method = get_method("Open3D-odometry")
    assert method.sensor == "rgbd" and method.metrics == ("trajectory",)
    assert check_available(method) is None  # one step on a random image with the smoke test's flat gt_depth


@pytest.mark.slow
def test_tracks_office0_from_the_sensor_depth():
    from eval.bench.sequence_resolve import resolve_sequence
    from eval.metrics.results import evaluate_episode
    from sim_envs.driver import run_episode
    from thirdparty.open3d_odometry import Open3dOdometryAgent

    result = run_episode(resolve_sequence("office0@kinect").make_env(max_frames=30), Open3dOdometryAgent())
    assert result.uses_ground_truth  # how it gets the depth image
    assert result.extras["depth_source"] == {"sensor_depth": 30}  # the Kinect-like depth, not the exact one
    assert result.tracked.all()
    assert np.allclose(result.T_world_cam_est[0], np.eye(4))  # the world is the first camera
    metrics = evaluate_episode(result).metrics
    assert metrics["ate_se3_rmse"] < 0.02  # metres: metric scale from the depth, no scale alignment needed
    assert abs(metrics["scale"] - 1.0) < 0.05


def test_needs_depth_and_a_known_jacobian():
    from thirdparty.open3d_odometry import Open3dOdometryAgent

    with pytest.raises(ValueError, match="jacobian"):
        Open3dOdometryAgent(jacobian="icp")
    agent = Open3dOdometryAgent()
    agent.reset(np.array([200.0, 200.0, 79.5, 59.5]), (120, 160))
    obs = {"rgb": np.zeros((120, 160, 3), np.uint8), "timestamp": np.zeros(1), "intrinsics": np.zeros(4)}
    with pytest.raises(RuntimeError, match="depth"):
        agent.step(obs, {"gt_T_world_cam": np.eye(4)})


def test_lost_frame_keeps_the_last_pose():
    from thirdparty.open3d_odometry import Open3dOdometryAgent

    agent = Open3dOdometryAgent()
    agent.reset(np.array([200.0, 200.0, 79.5, 59.5]), (120, 160))
    rng = np.random.default_rng(0)
    obs = {"rgb": rng.integers(0, 256, (120, 160, 3), dtype=np.uint8), "timestamp": np.zeros(1)}
    first = agent.step(obs, {"gt_depth": np.full((120, 160), 2.0, np.float32)})
    assert first["tracked"] == 1 and np.allclose(first["T_world_cam"], np.eye(4))
    lost = agent.step(obs, {"gt_depth": np.zeros((120, 160), np.float32)})  # no depth at all: nothing to register
    assert lost["tracked"] == 0 and np.allclose(lost["T_world_cam"], np.eye(4))
    out = agent.finish()
    assert out.keyframes == [] and out.extras["tracked_share"] == 0.5
