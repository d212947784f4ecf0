"""Known answers for the trajectory metrics, and the reference figures of reference-facts.md pinned to the digits
printed there (TUM-tools association and evo's nearest match, SE(3) and Sim(3), max. difference 0.02 s)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.errors import EvalError
from eval.metrics import (
    RpeUnit,
    error_statistics,
    evaluate_trajectory,
    parse_rpe_unit,
    relative_pose_errors,
    rpe_pair_indices,
    scale_error,
    tracked_share,
)
from eval.trajectory import PoseTrajectory

TUM = Path("/work/shared/data/tum")


@pytest.fixture(scope="module")
def fr2_desk():
    gt = PoseTrajectory.from_tum_file(TUM / "fr2_desk_groundtruth.txt", duplicate_timestamps="last")
    return gt, PoseTrajectory.from_tum_file(TUM / "fr2_desk_ORB.txt")


@pytest.fixture(scope="module")
def fr1_xyz():
    gt = PoseTrajectory.from_tum_file(TUM / "freiburg1_xyz-groundtruth.txt")
    return gt, PoseTrajectory.from_tum_file(TUM / "freiburg1_xyz-rgbdslam.txt")


@pytest.mark.parametrize(
    ("association", "alignment", "rmse", "pairs", "scale"),
    [
        ("tum", "se3", "0.008144", 2223, None),
        ("nearest", "se3", "0.008146", 2225, None),
        ("tum", "sim3", "0.006186", 2223, "0.9970"),
        ("nearest", "sim3", "0.006187", 2225, "0.9970"),
    ],
)
def test_reference_fr2_desk_orb(fr2_desk, association, alignment, rmse, pairs, scale):
    m = evaluate_trajectory(*fr2_desk, alignment=alignment, association=association, max_difference=0.02)
    assert f"{m.ate.rmse:.6f}" == rmse
    assert m.ate.pairs == pairs and len(m.association) == pairs
    assert m.association.rule.value == association and m.association.max_difference == 0.02
    assert m.alignment.used == alignment
    if scale is not None:
        assert f"{m.alignment.scale:.4f}" == scale
    assert f"{m.scale:.4f}" == "0.9970"  # the Sim(3) scale is reported whatever the alignment


@pytest.mark.parametrize("association", ["tum", "nearest"])
@pytest.mark.parametrize(("alignment", "rmse"), [("se3", "0.013473"), ("sim3", "0.013394")])
def test_reference_fr1_xyz_rgbdslam(fr1_xyz, association, alignment, rmse):
    m = evaluate_trajectory(*fr1_xyz, alignment=alignment, association=association)
    assert f"{m.ate.rmse:.6f}" == rmse and m.ate.pairs == 786
    assert f"{m.scale:.4f}" == "1.0079"
    assert m.scale_error == pytest.approx(abs(1 / m.scale - 1))


def test_error_statistics_known_values():
    s = error_statistics(np.array([3.0, 4.0, 0.0, 1.0]))
    assert s.rmse == pytest.approx(np.sqrt(26 / 4)) and s.mean == 2.0 and s.median == 2.0
    assert s.std == pytest.approx(np.sqrt(2.5)) and (s.min, s.max, s.pairs) == (0.0, 4.0, 4)
    empty = error_statistics(np.zeros(0))
    assert empty.pairs == 0 and np.isnan(empty.rmse)


def line_trajectory(n=31, speed=0.1):
    """A camera moving along x at ``speed`` m per frame at 30 Hz while turning about z (positions span a plane)."""
    t = np.arange(n) / 30.0
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 1, n), [0, 0, 1])).as_matrix()
    T[:, 0, 3] = speed * np.arange(n)
    T[:, 1, 3] = 0.5 * np.sin(np.arange(n) / 5)
    return PoseTrajectory(t, T)


def test_constant_offset_is_removed_by_alignment_but_not_by_none():
    gt = line_trajectory()
    T = gt.T_world_cam.copy()
    T[:, 2, 3] += 0.3
    est = PoseTrajectory(gt.timestamps, T)
    assert evaluate_trajectory(gt, est).ate.rmse == pytest.approx(0.0, abs=1e-12)
    none = evaluate_trajectory(gt, est, alignment="none")
    assert none.ate.rmse == pytest.approx(0.3) and none.ate.min == pytest.approx(0.3)
    assert none.rotation_deg.max == pytest.approx(0.0, abs=1e-6)


def test_scaled_estimate_scale_and_scale_error():
    gt = line_trajectory()
    T = gt.T_world_cam.copy()
    T[:, :3, 3] *= 2.0  # the estimate is twice the size of the truth
    m = evaluate_trajectory(gt, PoseTrajectory(gt.timestamps, T), alignment="sim3")
    assert m.scale == pytest.approx(0.5) and m.scale_error == pytest.approx(1.0)
    assert m.ate.rmse == pytest.approx(0.0, abs=1e-12) and m.rpe_translation.rmse == pytest.approx(0.0, abs=1e-12)
    rigid = evaluate_trajectory(gt, PoseTrajectory(gt.timestamps, T))
    assert rigid.ate.rmse > 0.1 and rigid.scale == pytest.approx(0.5)
    assert scale_error(1.25) == pytest.approx(0.2) and np.isnan(scale_error(0.0))


def test_rpe_known_drift():
    """The estimate moves 10 % too far per frame: RPE over k frames = 0.1 * distance travelled in k frames."""
    gt = line_trajectory(speed=0.1)
    gt_pure = PoseTrajectory(gt.timestamps, gt.T_world_cam.copy())
    T = gt_pure.T_world_cam.copy()
    T[:, :3, 3] *= 1.1
    est = PoseTrajectory(gt.timestamps, T)
    i, j = rpe_pair_indices(np.arange(31.0), 3)
    trans, rot = relative_pose_errors(gt.T_world_cam, est.T_world_cam, i, j)
    expected = 0.1 * np.linalg.norm(gt.positions[j] - gt.positions[i], axis=1)
    np.testing.assert_allclose(trans, expected, atol=1e-12)
    np.testing.assert_allclose(rot, 0.0, atol=1e-6)
    m = evaluate_trajectory(gt, est, alignment="none", rpe_delta=3, rpe_unit="frames")
    assert m.rpe_translation.pairs == 28 and m.rpe_translation.rmse == pytest.approx(np.sqrt(np.mean(expected**2)))


def test_rpe_rotation_error_in_degrees():
    gt = line_trajectory()
    T = gt.T_world_cam.copy()
    # a 2 degree jump between frames 14 and 15 (a world-frame rotation applied to the later orientations)
    T[15:, :3, :3] = Rotation.from_rotvec([0, np.radians(2.0), 0]).as_matrix() @ T[15:, :3, :3]
    m = evaluate_trajectory(gt, PoseTrajectory(gt.timestamps, T), alignment="none", rpe_delta=1, rpe_unit="f")
    assert m.rpe_rotation_deg.max == pytest.approx(2.0) and m.rpe_rotation_deg.median == pytest.approx(0.0, abs=1e-9)
    assert m.rpe_rotation_deg.pairs == 30 and m.rpe_rotation_deg.mean == pytest.approx(2.0 / 30)  # one pair of 30


def test_rpe_pair_rules():
    i, j = rpe_pair_indices(np.arange(5.0), 1)
    assert list(zip(i.tolist(), j.tolist(), strict=True)) == [(0, 1), (1, 2), (2, 3), (3, 4)]
    i, j = rpe_pair_indices(np.array([0.0, 0.3, 1.05, 1.3, 2.2]), 1.0)  # seconds: closest to t + 1
    assert list(zip(i.tolist(), j.tolist(), strict=True)) == [(0, 2), (1, 3), (2, 4)]
    assert rpe_pair_indices(np.array([0.0]), 1.0)[0].size == 0
    with pytest.raises(EvalError, match="positive"):
        rpe_pair_indices(np.arange(3.0), 0.0)
    assert parse_rpe_unit("f") == RpeUnit.FRAMES and parse_rpe_unit("m") == RpeUnit.METRES
    with pytest.raises(EvalError, match="frames"):
        parse_rpe_unit("deg")


def test_rpe_in_metres_uses_distance_along_the_ground_truth():
    gt = line_trajectory()
    m = evaluate_trajectory(gt, gt, rpe_delta=0.5, rpe_unit="m")
    assert m.rpe_translation.pairs > 0 and m.rpe_translation.max == pytest.approx(0.0, abs=1e-12)


def test_tracked_share_length_and_dict():
    gt = line_trajectory()
    tracked = np.ones(31, dtype=bool)
    tracked[:8] = False
    m = evaluate_trajectory(gt, gt, tracked=tracked)
    assert m.tracked_share == pytest.approx(23 / 31) and tracked_share(np.zeros(0)) != tracked_share(tracked)
    assert m.length_gt == pytest.approx(m.length_est) and m.length_gt > 3.0
    d = m.to_dict()
    for key in ("rmse", "mean", "median", "std", "min", "max", "pairs", "alignment", "association", "scale"):
        assert key in d
    flat = m.flat_metrics()
    assert flat["ate_pairs"] == 31 and flat["tracked_share"] == pytest.approx(23 / 31)
    with pytest.raises(EvalError, match="tracked has 3 entries"):
        evaluate_trajectory(gt, gt, tracked=np.ones(3))


def test_pure_rotation_trajectory_does_not_crash_and_reports_the_fallback():
    n = 60
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 2, n), [0.1, 1, 0])).as_matrix()
    gt = PoseTrajectory(np.arange(n) / 30, T)
    T_est = T.copy()
    T_est[:, :3, :3] = T[:, :3, :3] @ Rotation.from_rotvec([0.01, 0, 0]).as_matrix()
    m = evaluate_trajectory(gt, PoseTrajectory(gt.timestamps, T_est), alignment="sim3")
    assert m.alignment.used == "rotation_only" and m.warnings and np.isnan(m.scale)
    assert m.rotation_deg.rmse < 0.6 and m.ate.rmse == pytest.approx(0.0, abs=1e-12)
