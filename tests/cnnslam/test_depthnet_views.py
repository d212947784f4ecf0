"""Camera views of the depth network's training data: rotation axes, sampled poses in free space and hand-held,
usability of a rendered view."""

from __future__ import annotations

import numpy as np
import pytest

import cnnslam.depthnet.data as data
from cnnslam.depthnet.views import (
    CLOSE_KINDS,
    ViewConfig,
    camera_rotation,
    sample_close_view_pose,
    sample_view_pose,
    view_is_usable,
)
from cnnslam.errors import CnnSlamError


def test_camera_rotation_axes() -> None:
    R = camera_rotation(np.array([1.0, 0.0, 0.0]), 0.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 2], [1, 0, 0], atol=1e-12)  # optical axis forward
    np.testing.assert_allclose(R[:, 0], [0, -1, 0], atol=1e-12)  # image x to the right of +x, z up: -y
    np.testing.assert_allclose(R[:, 1], [0, 0, -1], atol=1e-12)  # image y down
    R_roll = camera_rotation(np.array([1.0, 0.0, 0.0]), np.radians(90))
    np.testing.assert_allclose(R_roll[:, 2], [1, 0, 0], atol=1e-12)
    with pytest.raises(CnnSlamError):
        camera_rotation(np.array([0.0, 0.0, -1.0]), 0.0)


def test_sampled_views_are_in_free_space_and_hand_held() -> None:
    from sim_envs.scenes.scenegen import generate_scene

    scene = generate_scene("study", 10_007, texture_density=0.5)
    cfg = ViewConfig()
    rng = np.random.default_rng(0)
    for _ in range(40):
        T, mode = sample_view_pose(scene, rng, cfg)
        assert mode in ("interest", "free", "look_down")
        assert scene.free_space(T[None, :3, 3], margin=cfg.margin_m)[0]
        assert cfg.low_height_m[0] <= T[2, 3] <= cfg.height_m[1]
        R = T[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
        pitch = np.degrees(np.arcsin(R[2, 2]))
        bounds = {
            "free": cfg.free_pitch_deg,
            "look_down": cfg.look_down_pitch_deg,
            "interest": (-cfg.max_pitch_down_deg, 90.0),  # aimed at a target, which may sit above the camera
        }[mode]
        assert bounds[0] - 1e-9 <= pitch <= bounds[1] + 1e-9
        # roll: image x stays within max_roll of horizontal
        assert abs(np.degrees(np.arcsin(np.clip(R[2, 0], -1, 1)))) <= cfg.max_roll_deg + 1e-6


def test_close_views_aim_at_a_surface_close_by() -> None:
    from sim_envs.scenes.scenegen import generate_scene

    scene = generate_scene("study", 10_007, texture_density=0.5)
    cfg = ViewConfig()
    rng = np.random.default_rng(1)
    room = np.asarray(scene.room_size)
    kinds = set()
    for _ in range(60):
        T, mode = sample_close_view_pose(scene, rng, cfg)
        kinds.add(mode)
        eye, forward = T[:3, 3], T[:3, 2]
        assert scene.free_space(eye[None], margin=cfg.close_margin_m)[0]
        assert cfg.close_height_m[0] <= eye[2] <= cfg.close_height_m[1]
        pitch = np.degrees(np.arcsin(forward[2]))
        lo, hi = {"close_down": cfg.close_down_pitch_deg, "close_desk": cfg.close_desk_pitch_deg,
                  "close_wall": cfg.close_wall_pitch_deg}[mode]
        assert lo - 1e-9 <= pitch <= hi + 1e-9
        if mode == "close_wall":  # the optical axis meets a wall within close_distance_m
            t = min(((room[a] if forward[a] > 0 else 0.0) - eye[a]) / forward[a] for a in (0, 1) if abs(forward[a])
                    > 1e-9)
            assert cfg.close_distance_m[0] - 1e-9 <= t <= cfg.close_distance_m[1] + 1e-9
    assert kinds == set(CLOSE_KINDS)
    a = [sample_close_view_pose(scene, np.random.default_rng(4), cfg)[0] for _ in range(2)]
    np.testing.assert_array_equal(a[0], a[1])  # a function of the generator's state


def test_view_usability() -> None:
    cfg = ViewConfig()
    assert view_is_usable(np.full((10, 10), 2.0, np.float32), cfg)
    assert not view_is_usable(np.full((10, 10), 0.3, np.float32), cfg)  # pressed against a surface
    d = np.full((10, 10), 2.0, np.float32)
    d[:2] = 0
    assert not view_is_usable(d, cfg)  # 20 % without a surface
    assert view_is_usable(np.full((10, 10), 0.45, np.float32), cfg, "close_down")  # close views may be close
    assert not view_is_usable(np.full((10, 10), 2.5, np.float32), cfg, "close_wall")  # ... and must be
    assert not view_is_usable(np.full((10, 10), 0.2, np.float32), cfg, "close_desk")


def test_data_reexports_the_views() -> None:
    assert data.sample_view_pose is sample_view_pose and data.ViewConfig is ViewConfig
