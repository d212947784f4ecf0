"""cnnslam.tools.map_replay: the numeric core of ``cnnslam map`` (known answers; the command end to end is in
test_model_io.py)."""

import numpy as np
import pytest

from cnnslam.geometry import se3_exp
from cnnslam.tools.map_replay import corrected_trajectory


def _pose(x: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x
    return T


def test_corrected_trajectory_moves_each_frame_with_its_last_keyframe():
    online = np.stack([_pose(float(i)) for i in range(6)])
    steps = np.array([0, 3])  # key-frames at frames 0 and 3
    final = np.stack([_pose(0.0), se3_exp(np.array([0.0, 0.5, 0.0, 0.0, 0.0, 0.1])) @ _pose(3.0)])
    out = corrected_trajectory(online, steps, online[steps], final)
    np.testing.assert_allclose(out[:3], online[:3])  # key-frame 0 did not move: nor did frames 0..2
    np.testing.assert_allclose(out[3], final[1], atol=1e-12)  # a key-frame lands on its final pose
    correction = final[1] @ np.linalg.inv(online[3])
    for f in (4, 5):  # later frames: the same correction as their key-frame
        np.testing.assert_allclose(out[f], correction @ online[f], atol=1e-12)
    assert corrected_trajectory(online, np.zeros(0, np.int64), online[:0], online[:0]) == pytest.approx(online)


def _plane_keyframes(n: int = 3) -> tuple[list, list, np.ndarray, list]:
    """``n`` key-frames 5 cm apart looking at a wall 2 m ahead, the CNN right (class 1) on the left half and wrong
    (class 2) on the right; their ground-truth frames say class 1 everywhere."""
    from types import SimpleNamespace

    from sim_envs.agent import KeyframeDepth

    h, w = 24, 32
    probs = np.zeros((h, w, 4), np.float32)
    probs[:, : w // 2, 1] = 1.0
    probs[:, w // 2 :, 2] = 1.0
    keyframes = [KeyframeDepth(float(i), np.full((h, w), 2.0, np.float32), _pose(0.05 * i),
                               np.full((h, w), 1e-3, np.float32), probs) for i in range(n)]  # fmt: skip
    images = [np.full((h, w, 3), 128, np.uint8) for _ in range(n)]
    gt = [SimpleNamespace(labels=np.ones((h, w), np.uint8)) for _ in range(n)]
    return keyframes, images, np.array([30.0, 30.0, 16.0, 12.0]), gt


def test_measurement_scores_replay_the_fusion_they_score():
    """The scores are those of the key-frames' own fusion, made here or handed in; a model of other geometry (an
    agent's live model, whose thread re-placed surfels between key-frames) is refused as the replay's."""
    from cnnslam.model.global_model import GlobalModelConfig
    from cnnslam.tools.map_replay import evidence_maps, fuse_keyframes, measurement_scores

    keyframes, images, intr, gt = _plane_keyframes()
    config = GlobalModelConfig()
    evidence = evidence_maps(keyframes, gt, config.num_classes)
    own, _ = fuse_keyframes(keyframes, images, intr, None, config)
    scores = measurement_scores(keyframes, images, intr, None, config, evidence)
    assert scores == measurement_scores(keyframes, images, intr, None, config, evidence, own)
    assert scores["n_elements"] > 100 and 0.3 < scores["framewise_accuracy"] < 0.7  # half the pixels right
    moved = [_pose(0.05 * i + 0.5) for i in range(len(keyframes))]
    other, _ = fuse_keyframes([type(k)(k.timestamp, k.depth, T, k.uncertainty, k.labels) for k, T in
                               zip(keyframes, moved, strict=True)], images, intr, None, config)  # fmt: skip
    with pytest.raises(Exception, match="different model"):
        measurement_scores(keyframes, images, intr, None, config, evidence, other)
