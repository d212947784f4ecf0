"""The Laina baseline on the exactly known analytic room: with exact "CNN" depth, frame-to-model ICP tracking must be
near perfect, key-frames must carry the eq.-5-adjusted prediction, and the in-between photometric option must
track too."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from cnnslam.baselines.laina import GroundTruthAidedLainaAgent, LainaAgent, LainaConfig, area_downsample_depth
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import rotation_angle_deg, se3_inverse
from cnnslam.model.global_model import GlobalModel, GlobalModelConfig
from cnnslam.model.icp import (
    IcpConfig,
    depth_surface_pyramid,
    icp_point_to_plane,
    surface_maps_from_depth,
    surface_pyramid,
)
from slamcommon.errors import ConfigError

TRAIN_FOCAL = 200.0  # the stub network's training focal length; the room's camera has f = 240.3 px


@dataclass(frozen=True)
class _Prediction:
    depth: np.ndarray
    label_probs: np.ndarray


class TablePredictor:
    """A stand-in network that knows the exact depth of each image, and outputs it as a network trained with focal
    length ``TRAIN_FOCAL`` would (D f_tr / f_cur), so eq. 5 must undo it. Class 1 everywhere."""

    def __init__(self, frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]], f_cur: float) -> None:
        self.train_focal = TRAIN_FOCAL
        self.table = {rgb.tobytes(): depth for rgb, depth, _ in frames}
        self.scale = TRAIN_FOCAL / f_cur
        self.calls = 0

    def predict_raw(self, rgb: np.ndarray) -> _Prediction:
        self.calls += 1
        depth = self.table[np.ascontiguousarray(rgb).tobytes()]
        probs = np.zeros((*depth.shape, 4), np.float32)
        probs[..., 1] = 1.0
        return _Prediction((depth * self.scale).astype(np.float32), probs)


def _run(agent, frames, intrinsics, info=False):
    agent.reset(intrinsics, frames[0][0].shape[:2])
    poses, tracked = [], []
    for k, (rgb, depth, _) in enumerate(frames):
        obs = {"rgb": rgb, "timestamp": np.array([k / 30.0]), "intrinsics": intrinsics}
        action = agent.step(obs, {"gt_depth": depth}) if info else agent.step(obs)
        poses.append(action["T_world_cam"])
        tracked.append(action["tracked"])
    return np.stack(poses), np.array(tracked), agent.finish()


def _worst_errors(poses: np.ndarray, frames) -> tuple[float, float]:
    t_err = r_err = 0.0
    for T_est, (_, _, T_gt) in zip(poses, frames, strict=True):
        E = se3_inverse(T_gt) @ T_est
        t_err = max(t_err, float(np.linalg.norm(E[:3, 3])))
        r_err = max(r_err, rotation_angle_deg(E))
    return t_err, r_err


@pytest.mark.slow  # > 5 s: the full lane only
@pytest.mark.parametrize("icp_downsample", [1, 2])  # the camera's pixels (the default); the network's
def test_frame_to_model_icp_tracks_exact_depth_and_keyframes_carry_the_adjusted_prediction(room, room_sequence,
                                                                                          icp_downsample):
    f_cur = float(np.mean(room.intrinsics[:2]))
    predictor = TablePredictor(room_sequence, f_cur)
    agent = LainaAgent(config={"keyframe_every": 10, "model.normal_smoothing_px": 0.0,
                               "icp_downsample": icp_downsample}, predictor=predictor)
    poses, tracked, out = _run(agent, room_sequence, room.intrinsics)
    assert tracked.all() and predictor.calls == len(room_sequence)  # the CNN on every frame
    t_err, r_err = _worst_errors(poses, room_sequence)
    assert t_err < 0.005 and r_err < 0.3
    assert [round(k.timestamp * 30) for k in out.keyframes] == [0, 10, 20]
    for kf in out.keyframes:
        k = round(kf.timestamp * 30)
        exact = room_sequence[k][1]
        assert np.allclose(kf.depth, exact, rtol=1e-5)  # eq. 5 applied: D~ f_cur / f_tr = D
        assert kf.uncertainty is None and kf.labels.shape == (*exact.shape, 4)
        assert np.allclose(kf.T_world_cam, poses[k])
    assert out.extras["fused"] == len(room_sequence) and out.extras["model_surfels"] == len(agent.global_model)
    assert out.extras["lost"] == 0


def test_cnn_every_third_frame_tracks_the_others_photometrically(room, room_sequence):
    predictor = TablePredictor(room_sequence, float(np.mean(room.intrinsics[:2])))
    agent = LainaAgent(config={"cnn_every": 3, "keyframe_every": 6, "model.normal_smoothing_px": 0.0},
                       predictor=predictor)
    poses, tracked, out = _run(agent, room_sequence, room.intrinsics)
    assert predictor.calls == 8 and out.extras["photometric"] == 16
    assert tracked.mean() > 0.9
    t_err, r_err = _worst_errors(poses, room_sequence)
    assert t_err < 0.02 and r_err < 0.5
    assert all(round(k.timestamp * 30) % 3 == 0 for k in out.keyframes)  # only predicted frames


def test_development_variant_feeds_ground_truth_to_the_predictor_only(room, room_sequence):
    frames = room_sequence[:3]
    agent = GroundTruthAidedLainaAgent(predictor_options={"seed": 3})
    assert agent.uses_ground_truth and not LainaAgent.uses_ground_truth
    poses, tracked, out = _run(agent, frames, room.intrinsics, info=True)
    assert tracked[0] == 1 and len(out.keyframes) == 1 and out.extras["predictor"] == "degraded_ground_truth"
    rel = np.abs(out.keyframes[0].depth - frames[0][1]) / frames[0][1]
    assert 0.005 < float(np.median(rel)) < 0.2  # an imitation of a CNN: near the truth, not equal to it
    with pytest.raises(CnnSlamError, match="GroundTruthAidedLainaAgent"):
        LainaAgent(predictor="degraded_ground_truth")


def test_config_overrides_are_validated():
    cfg = LainaConfig().with_overrides({"cnn_every": 2, "icp.max_distance": 0.3, "model.voxel_size": 0.05})
    assert cfg.cnn_every == 2 and cfg.icp.max_distance == 0.3 and cfg.model.voxel_size == 0.05
    with pytest.raises(ConfigError, match="unknown config key 'cnn_evry'; valid keys: cnn_every"):
        LainaConfig().with_overrides({"cnn_evry": 2})
    with pytest.raises(ConfigError, match="valid keys of icp"):
        LainaConfig().with_overrides({"icp.distance": 0.3})
    with pytest.raises(CnnSlamError, match="cnn_every"):
        LainaConfig(cnn_every=0)
    with pytest.raises(CnnSlamError, match="icp_downsample must be 1, 2, 4 or 8, got 3"):
        LainaConfig(icp_downsample=3)
    with pytest.raises(CnnSlamError, match="divisible"):
        LainaAgent(config={"icp_downsample": 4}).reset(np.array([100.0, 100.0, 20.0, 15.0]), (30, 40))
    with pytest.raises(CnnSlamError, match="reset"):
        LainaAgent().step({"rgb": np.zeros((8, 8, 3), np.uint8), "timestamp": np.zeros(1)})


def test_area_downsample_depth_known_answers():
    depth = np.arange(1, 17, dtype=np.float32).reshape(4, 4)
    assert np.array_equal(area_downsample_depth(depth, 2), np.array([[3.5, 5.5], [11.5, 13.5]], np.float32))
    assert np.array_equal(area_downsample_depth(depth, 1), depth)
    holes = depth.copy()
    holes[0, 0], holes[0, 1] = 0.0, np.nan  # a block with two valid depths: their mean
    holes[2:, 2:] = 0.0  # a block with none: 0 (no depth)
    out = area_downsample_depth(holes, 2)
    assert out.dtype == np.float32
    assert np.array_equal(out, np.array([[5.5, 5.5], [11.5, 0.0]], np.float32))  # (5 + 6) / 2
    with pytest.raises(CnnSlamError, match="cannot be shrunk by 2"):
        area_downsample_depth(np.ones((3, 4), np.float32), 2)


# ------------------------------------------------------------------------------------------ the numba kernels


def _noisy(depth: np.ndarray, seed: int) -> np.ndarray:
    """Exact depth with CNN-like multiplicative noise (2 %), so that normals vary and thresholds are exercised."""
    rng = np.random.default_rng(seed)
    return (depth * (1.0 + 0.02 * rng.standard_normal(depth.shape))).astype(np.float32)


def test_depth_surface_pyramid_known_answer_on_a_fronto_parallel_plane():
    intr = np.array([200.0, 200.0, 15.5, 11.5])
    depth = np.full((24, 32), 2.0, np.float32)
    depth[5, 7] = 0.0  # a hole: no vertex, and no normal at it or its 4 neighbours
    pyr = depth_surface_pyramid(depth, intr, 3, 0.05)
    assert [p.valid.shape for p in pyr] == [(24, 32), (12, 16), (6, 8)]
    v, u = 10, 20
    assert np.allclose(pyr[0].vertices[v, u], [(u - 15.5) / 200.0 * 2.0, (v - 11.5) / 200.0 * 2.0, 2.0], atol=1e-6)
    inner = np.zeros((24, 32), bool)
    inner[1:-1, 1:-1] = True
    inner[5, 6:9] = inner[4:7, 7] = False
    assert np.array_equal(pyr[0].valid, inner)
    assert np.allclose(pyr[0].normals[inner], [0.0, 0.0, -1.0])  # facing the camera
    assert np.allclose(pyr[1].intrinsics, [100.0, 100.0, 7.5, 5.5])
    # level 1: the mean of the valid vertices of each 2x2 block (the block at (3, 3) lost pixel (6, 7) to the hole)
    assert pyr[1].valid[4, 4] and np.allclose(pyr[1].vertices[4, 4], pyr[0].vertices[8:10, 8:10].mean(axis=(0, 1)))
    block = pyr[0].vertices[6:8, 6:8][inner[6:8, 6:8]]
    assert pyr[1].valid[3, 3] and len(block) == 3 and np.allclose(pyr[1].vertices[3, 3], block.mean(axis=0))
    assert pyr[1].valid[0, 0] and np.allclose(pyr[1].vertices[0, 0], pyr[0].vertices[1, 1])  # one valid pixel
    assert np.allclose(pyr[2].normals[pyr[2].valid], [0.0, 0.0, -1.0]) and pyr[2].valid.sum() == 48


def test_depth_surface_pyramid_matches_the_reference(room, room_sequence):
    depth = _noisy(room_sequence[3][1], 1)
    ref = surface_pyramid(surface_maps_from_depth(depth, room.intrinsics, 0.05, 0.0), 3, 0.05)
    fast = depth_surface_pyramid(depth, room.intrinsics, 3, 0.05)
    for a, b in zip(ref, fast, strict=True):
        assert np.array_equal(a.valid, b.valid) and np.allclose(a.intrinsics, b.intrinsics)
        assert np.allclose(a.vertices, b.vertices, atol=1e-6) and np.allclose(a.normals, b.normals, atol=1e-6)


def test_render_surface_known_answer_one_surfel_facing_the_camera():
    model = GlobalModel(GlobalModelConfig(pixel_stride=1, normal_smoothing_px=0.0))
    intr = np.array([100.0, 100.0, 15.5, 11.5])
    depth = np.zeros((24, 32), np.float32)
    depth[10:13, 14:17] = 2.0  # a 3x3 patch: one measurement at its centre (15, 11) with a normal
    model.integrate(depth, np.eye(4), intr)
    assert len(model) == 1
    maps = model.render_surface(np.eye(4), intr, (24, 32))
    assert maps.valid[11, 15] and np.allclose(maps.normals[11, 15], [0.0, 0.0, -1.0])
    assert np.allclose(maps.vertices[11, 15], [(15 - 15.5) / 100.0 * 2.0, (11 - 11.5) / 100.0 * 2.0, 2.0])
    assert np.allclose(maps.vertices[maps.valid][:, 2], 2.0)  # the ray meets the disc plane at z = 2
    assert not model.render_surface(np.eye(4), intr, (24, 32), min_confidence=5.0).valid.any()


def test_laina_fuses_into_the_global_model_itself(room, room_sequence):
    """No shadow copy: the agent's model is CNN-SLAM's GlobalModel class, and its ICP reference is that model's
    ray-cast."""
    agent = LainaAgent(predictor=TablePredictor(room_sequence, float(np.mean(room.intrinsics[:2]))))
    agent.reset(room.intrinsics, room_sequence[0][1].shape)
    assert type(agent.global_model) is GlobalModel


def test_icp_on_the_compiled_pyramids_recovers_the_motion(room, room_sequence):
    (_, d0, T0), (_, d1, T1) = room_sequence[0], room_sequence[2]
    ref_pyr = depth_surface_pyramid(d0, room.intrinsics, 3)
    cur_pyr = depth_surface_pyramid(d1, room.intrinsics, 3)
    cfg = IcpConfig(smoothing_px=0.0)
    b = icp_point_to_plane(ref_pyr, cur_pyr, np.eye(4), cfg)
    assert b.tracked
    E = se3_inverse(se3_inverse(T0) @ T1) @ b.T_ref_cur  # the known answer: the true relative motion
    assert np.linalg.norm(E[:3, 3]) < 1e-3 and rotation_angle_deg(E) < 0.05
    c = icp_point_to_plane(ref_pyr, cur_pyr, np.eye(4), replace(cfg, convergence=6e-3))  # InfiniTAM's test
    assert sum(c.iterations) < sum(b.iterations) and np.allclose(c.T_ref_cur, b.T_ref_cur, atol=1e-3)
