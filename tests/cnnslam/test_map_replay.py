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
