"""Tests of the key-frame pose graph: a known graph is recovered, loop edges remove drift, candidates are found,
and key-frame alignment makes consistent edges."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.config import PoseGraphConfig, TrackingConfig
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import relative_pose, se3_exp, se3_inverse, se3_log
from cnnslam.graph.pose_graph import (
    PoseGraph,
    PoseGraphEdge,
    align_keyframes,
    edge_residuals,
    field_of_view,
    neighbour_candidates,
)
from cnnslam.track.tracking import build_image_pyramid, build_tracking_reference, to_gray


def _circle(n: int, radius: float = 2.0) -> list[np.ndarray]:
    poses = []
    for k in range(n):
        a = 2 * np.pi * k / n
        T = se3_exp(np.array([0, 0, 0, 0, -a, 0]))
        T[:3, 3] = [radius * np.cos(a), 0.0, radius * np.sin(a)]
        poses.append(T)
    return poses


def test_recovers_a_known_graph_with_a_loop() -> None:
    truth = _circle(16)
    rng = np.random.default_rng(0)
    drifted = [truth[0]]
    for k in range(1, 16):  # odometry with noise: drift accumulates
        drifted.append(drifted[-1] @ relative_pose(truth[k - 1], truth[k]) @ se3_exp(rng.normal(0, 0.02, 6)))
    graph = PoseGraph()
    for k, T in enumerate(drifted):
        graph.add_keyframe(k, T)
    info = np.diag([1e4, 1e4, 1e4, 1e5, 1e5, 1e5])
    for k in range(1, 16):
        graph.add_edge(PoseGraphEdge(k - 1, k, relative_pose(truth[k - 1], truth[k]), info, "sequential"))
    graph.add_edge(PoseGraphEdge(15, 0, relative_pose(truth[15], truth[0]), info, "loop"))
    before = max(np.linalg.norm(drifted[k][:3, 3] - truth[k][:3, 3]) for k in range(16))
    result = graph.optimise(PoseGraphConfig())
    after = max(np.linalg.norm(result.poses[k][:3, 3] - truth[k][:3, 3]) for k in range(16))
    assert before > 0.1
    assert after < 1e-6 and result.cost_after < 1e-9 * result.cost_before
    np.testing.assert_array_equal(result.poses[0], drifted[0])  # the gauge: the first key-frame is fixed
    assert graph.poses[5] is not None and np.array_equal(graph.poses[5], drifted[5])  # optimise() does not write


def test_residuals_are_zero_at_the_measurement_and_whitened() -> None:
    T_i, T_j = se3_exp(np.array([1.0, 0, 0, 0, 0.2, 0])), se3_exp(np.array([0, 1.0, 0.5, 0.1, 0, 0]))
    meas = relative_pose(T_i, T_j)
    L = np.broadcast_to(np.diag([2.0] * 6), (1, 6, 6))
    np.testing.assert_allclose(edge_residuals(T_i[None], T_j[None], meas[None], L), 0.0, atol=1e-12)
    moved = se3_exp(np.array([0.01, 0, 0, 0, 0, 0])) @ T_j
    r = edge_residuals(T_i[None], moved[None], meas[None], L)
    delta = se3_log(se3_inverse(moved) @ T_i @ meas)
    np.testing.assert_allclose(r[0], 2.0 * delta)


def test_bad_edges_are_refused() -> None:
    graph = PoseGraph()
    graph.add_keyframe(0, np.eye(4))
    with pytest.raises(CnnSlamError, match="existing key-frames"):
        graph.add_edge(PoseGraphEdge(0, 1, np.eye(4), np.eye(6), "sequential"))


def test_neighbour_candidates_by_distance_and_view() -> None:
    cfg = PoseGraphConfig()
    fov = field_of_view(np.array([240.6, 240.0, 159.5, 119.5]), (240, 320))
    new = np.eye(4)
    near = se3_exp(np.array([0.2, 0, 0, 0, 0, 0]))
    far = se3_exp(np.array([3.0, 0, 0, 0, 0, 0]))
    turned = se3_exp(np.array([0.1, 0, 0, 0, np.pi / 2, 0]))
    others = {1: (near, 0.5), 2: (far, 0.5), 3: (turned, 0.5), 4: (np.eye(4), 0.5)}
    assert neighbour_candidates(new, 0.5, others, fov, cfg) == [4, 1]
    assert neighbour_candidates(new, 0.5, others, fov, cfg, exclude={4}) == [1]


def test_keyframe_alignment_makes_a_consistent_edge(room) -> None:
    K = room.intrinsics
    T_world_a, T_world_b = room.pose((0.0, 0.0, 0.0)), room.pose((0.08, -0.02, 0.05), (1.0, 2.0, 0.0))
    frames = {}
    for name, T in (("a", T_world_a), ("b", T_world_b)):
        rgb, d = room.render(T)
        pyr = build_image_pyramid(to_gray(rgb), K, 4)
        frames[name] = (pyr, build_tracking_reference(pyr, d, ((0.02 * d) ** 2).astype(np.float32), TrackingConfig()))
    truth = relative_pose(T_world_a, T_world_b)
    res = align_keyframes(0, frames["a"][1], frames["a"][0], 3.0, 1, frames["b"][1], frames["b"][0],
                          truth @ se3_exp(np.array([0.02, 0.0, -0.02, 0.01, 0.0, 0.0])), TrackingConfig(),
                          PoseGraphConfig(), "neighbour")
    assert res.edge is not None, res.reason
    err = se3_log(se3_inverse(truth) @ res.edge.T_i_j)
    assert np.linalg.norm(err[:3]) < 0.005 and np.degrees(np.linalg.norm(err[3:])) < 0.2
    assert np.all(np.linalg.eigvalsh(res.edge.information) > 0)
    # against a view of something else the alignment is refused
    rgb, d = room.render(room.pose((0.0, 0.0, 0.0), (0.0, 180.0, 0.0)))
    pyr = build_image_pyramid(to_gray(rgb), K, 4)
    other = build_tracking_reference(pyr, d, ((0.02 * d) ** 2).astype(np.float32), TrackingConfig())
    bad = align_keyframes(0, frames["a"][1], frames["a"][0], 3.0, 2, other, pyr, np.eye(4), TrackingConfig(),
                          PoseGraphConfig(), "loop")
    assert bad.edge is None
