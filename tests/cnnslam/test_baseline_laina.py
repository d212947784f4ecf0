"""The Laina baseline on the exactly known analytic room: with exact "CNN" depth, frame-to-model ICP tracking must be
near perfect, key-frames must carry the eq.-5-adjusted prediction, and the in-between photometric option must
track too."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from cnnslam.baselines.laina import GroundTruthAidedLainaAgent, LainaAgent, LainaConfig
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import rotation_angle_deg, se3_inverse

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


def test_frame_to_model_icp_tracks_exact_depth_and_keyframes_carry_the_adjusted_prediction(room, room_sequence):
    f_cur = float(np.mean(room.intrinsics[:2]))
    predictor = TablePredictor(room_sequence, f_cur)
    agent = LainaAgent(config={"keyframe_every": 10, "model.normal_smoothing_px": 0.0}, predictor=predictor)
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
    with pytest.raises(CnnSlamError, match="unknown Laina setting"):
        LainaConfig().with_overrides({"cnn_evry": 2})
    with pytest.raises(CnnSlamError, match="fields of icp"):
        LainaConfig().with_overrides({"icp.distance": 0.3})
    with pytest.raises(CnnSlamError, match="cnn_every"):
        LainaConfig(cnn_every=0)
    with pytest.raises(CnnSlamError, match="reset"):
        LainaAgent().step({"rgb": np.zeros((8, 8, 3), np.uint8), "timestamp": np.zeros(1)})
