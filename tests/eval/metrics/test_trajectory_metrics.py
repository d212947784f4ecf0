"""Known answers for the trajectory metrics, and the reference figures of tests/reference_facts.toml (the TUM
tools' association and evo's nearest match, SE(3) and Sim(3), max. difference 0.02 s; sources there) pinned to the
digits printed there."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.errors import EvalError
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import (
    RpeUnit,
    error_statistics,
    evaluate_trajectory,
    parse_rpe_unit,
    relative_pose_errors,
    rpe_pair_indices,
    scale_error,
    tracked_share,
)


@pytest.fixture(scope="module")
def fr2_desk(tum_dir):
    gt = PoseTrajectory.from_tum_file(tum_dir / "fr2_desk_groundtruth.txt", duplicate_timestamps="last")
    return gt, PoseTrajectory.from_tum_file(tum_dir / "fr2_desk_ORB.txt")


@pytest.fixture(scope="module")
def fr1_xyz(tum_dir):
    gt = PoseTrajectory.from_tum_file(tum_dir / "freiburg1_xyz-groundtruth.txt")
    return gt, PoseTrajectory.from_tum_file(tum_dir / "freiburg1_xyz-rgbdslam.txt")


def reference_case(facts: dict, name: str) -> dict:
    """The reference figures of one case (ground truth / estimate) of reference_facts.toml's trajectory section."""
    return next(case for case in facts["trajectory"]["cases"] if case["name"] == name)


@pytest.mark.parametrize(("association", "alignment"), [("tum", "se3"), ("nearest", "se3"), ("tum", "sim3"),
                                                        ("nearest", "sim3")])  # fmt: skip
def test_reference_fr2_desk_orb(fr2_desk, reference_facts, association, alignment):
    case = reference_case(reference_facts, "fr2_desk/ORB")
    max_difference = reference_facts["trajectory"]["max_difference"]
    pairs = case["pairs"] if association == "tum" else 2225  # evo's nearest match reuses ground-truth poses
    m = evaluate_trajectory(*fr2_desk, alignment=alignment, association=association, max_difference=max_difference)
    assert f"{m.ate.rmse:.6f}" == case["rmse"][association][alignment]
    assert m.ate.pairs == pairs and len(m.association) == pairs
    assert m.association.rule.value == association and m.association.max_difference == max_difference == 0.02
    assert m.alignment.used == alignment
    if alignment == "sim3":
        assert f"{m.alignment.scale:.4f}" == case["scale"]
    assert f"{m.scale:.4f}" == case["scale"]  # the Sim(3) scale is reported whatever the alignment


@pytest.mark.parametrize("association", ["tum", "nearest"])
@pytest.mark.parametrize("alignment", ["se3", "sim3"])
def test_reference_fr1_xyz_rgbdslam(fr1_xyz, reference_facts, association, alignment):
    case = reference_case(reference_facts, "fr1_xyz/rgbdslam")
    m = evaluate_trajectory(*fr1_xyz, alignment=alignment, association=association)
    assert f"{m.ate.rmse:.6f}" == case["rmse"][association][alignment] and m.ate.pairs == case["pairs"]
    assert f"{m.scale:.4f}" == case["scale"]
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
    assert set(d) == {"alignment", "association", "rpe", "warnings", "metrics"} and d["metrics"] == m.flat_metrics()
    assert d["alignment"]["used"] == "se3" and d["alignment"]["sim3"]["used"] == "sim3"
    flat = m.flat_metrics()
    assert flat["ate_pairs"] == 31 and flat["tracked_share"] == pytest.approx(23 / 31)
    assert all(isinstance(v, float) for v in flat.values())  # numbers only, flags included
    assert flat["ate_alignment_degenerate"] == 0.0 and flat["ate_alignment_fallback"] == 0.0
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
    flat = m.flat_metrics()
    assert flat["ate_alignment_fallback"] == 1.0 and flat["ate_alignment_degenerate"] == 1.0
    assert "rotation-only" in m.warnings[0] and flat["rot_deg_orient_rmse"] < 0.6


R_OFF = Rotation.from_rotvec([0.4, -0.9, 0.3]).as_matrix()  # a known world rotation of the estimate (~58 deg)


def rotation_dominant(n=90, seed=0, orient_noise_deg=0.5, gt_jitter=0.01, est_cloud=0.1):
    """A nearly pure rotation (camera turning +-40 deg on the spot, ground-truth positions jittering ~1 cm) and an
    estimate: orientations rotated by R_OFF in the world plus ``orient_noise_deg`` per axis, positions an
    uncorrelated ``est_cloud`` m cloud (a monocular system on pure rotation). Returns gt, est, noise angles (deg)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.radians(40) * np.sin(t * 2), [0.1, 1.0, 0.2])).as_matrix()
    T[:, :3, 3] = [1.0, 0.5, 1.4] + rng.normal(0, gt_jitter, (n, 3))
    noise = Rotation.from_rotvec(rng.normal(0, np.radians(orient_noise_deg), (n, 3)))
    T_est = T.copy()
    T_est[:, :3, :3] = R_OFF @ T[:, :3, :3] @ noise.as_matrix()
    T_est[:, :3, 3] = rng.normal(0, est_cloud, (n, 3))
    return PoseTrajectory(t, T), PoseTrajectory(t, T_est), np.degrees(noise.magnitude())


def test_orientation_only_rotation_error_is_the_noise_where_the_se3_fit_is_arbitrary():
    gt, est, noise_deg = rotation_dominant()
    m = evaluate_trajectory(gt, est)
    flat = m.flat_metrics()
    expected = float(np.sqrt(np.mean(noise_deg**2)))  # ~0.87 deg
    assert flat["rot_deg_orient_rmse"] == pytest.approx(expected, rel=0.05)
    np.testing.assert_allclose(m.orientation_rotation, R_OFF.T, atol=np.radians(0.3))  # the offset, recovered
    # the SE(3) fit on positions is still evo's (defined), but its rotation comes from noise, and says so
    assert m.alignment.used == "se3" and m.alignment.degenerate and not m.alignment.fallback
    assert flat["ate_alignment_degenerate"] == 1.0 and flat["ate_alignment_fallback"] == 0.0
    assert "ill-conditioned" in m.warnings[0] and "rot_deg_orient" in m.warnings[0]
    assert flat["rot_deg_rmse"] > 10 * expected  # arbitrary: tens of degrees
    # RPE rotation is alignment-free: the same under any alignment, and small (noise of two poses)
    assert flat["rpe_rot_deg_rmse"] < 2 * expected
    for alignment in ("sim3", "origin", "none"):
        other = evaluate_trajectory(gt, est, alignment=alignment).flat_metrics()
        assert other["rpe_rot_deg_rmse"] == pytest.approx(flat["rpe_rot_deg_rmse"], rel=1e-9)
        assert other["rot_deg_orient_rmse"] == pytest.approx(flat["rot_deg_orient_rmse"], rel=1e-9)


def test_orientation_only_alignment_ignores_positions_and_scale():
    gt, est, _ = rotation_dominant(orient_noise_deg=0.0)
    T = est.T_world_cam.copy()
    T[:, :3, 3] = 5.0 * gt.positions + 3.0  # any positions at all
    m = evaluate_trajectory(gt, PoseTrajectory(gt.timestamps, T))
    assert m.rotation_orient_deg.max == pytest.approx(0.0, abs=1e-6) and m.rotation_orient_deg.pairs == 90


def similar(traj, R, t, s):
    """The trajectory's world frame moved by x -> s R x + t (what an estimate in its own frame and scale looks like)."""
    T = traj.T_world_cam.copy()
    T[:, :3, :3] = R @ T[:, :3, :3]
    T[:, :3, 3] = s * traj.positions @ R.T + t
    return PoseTrajectory(traj.timestamps, T)


def test_sim3_ate_of_an_estimate_twice_the_size_is_zero():
    gt = line_trajectory()
    est = similar(gt, R_OFF, np.array([0.3, -2.0, 1.0]), 2.0)
    flat = evaluate_trajectory(gt, est).flat_metrics()
    assert flat["ate_sim3_rmse"] == pytest.approx(0.0, abs=1e-9)
    assert flat["ate_se3_rmse"] == flat["ate_rmse"] and flat["ate_rmse"] > 0.5  # metric ATE sees the scale
    assert flat["scale"] == pytest.approx(0.5) and flat["scale_error"] == pytest.approx(1.0)
    sim3 = evaluate_trajectory(gt, est, alignment="sim3").flat_metrics()  # the run's alignment changes ate_*
    assert sim3["ate_rmse"] == pytest.approx(0.0, abs=1e-9) and sim3["ate_se3_rmse"] == flat["ate_se3_rmse"]


def test_se3_ate_of_a_scaled_square_by_hand():
    """Square of half-diagonal 1 m, estimate 1.2 times as large, rotated and moved: the best rigid fit puts the
    centres together with no rotation left, each corner 0.2 m off: ATE 0.2 m; Sim(3): 0 m, scale 1/1.2."""
    T = np.tile(np.eye(4), (4, 1, 1))
    T[:, :3, 3] = [[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]]
    gt = PoseTrajectory(np.arange(4.0), T)
    flat = evaluate_trajectory(gt, similar(gt, R_OFF, np.array([1.0, 2.0, 3.0]), 1.2)).flat_metrics()
    assert flat["ate_rmse"] == pytest.approx(0.2) and flat["ate_min"] == pytest.approx(0.2)
    assert flat["ate_sim3_rmse"] == pytest.approx(0.0, abs=1e-12) and flat["scale"] == pytest.approx(1 / 1.2)


def test_se3_ate_equals_a_closed_form_planar_fit():
    """Positions in a plane, the estimate turned about the plane's normal: the optimal rotation is planar,
    theta = atan2(sum x_i cross y_i, sum x_i . y_i) on centred points (Kabsch in 2-D), independent of the SVD."""
    rng = np.random.default_rng(5)
    n = 25
    y = np.c_[rng.uniform(-2, 2, (n, 2)), np.zeros(n)]
    a = np.radians(20.0)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    x = (y + np.c_[rng.normal(0, 0.05, (n, 2)), np.zeros(n)]) @ Rz.T + [0.5, -1.0, 0.0]  # noisy, turned, moved
    xc, yc = x - x.mean(axis=0), y - y.mean(axis=0)
    theta = np.arctan2(np.sum(xc[:, 0] * yc[:, 1] - xc[:, 1] * yc[:, 0]), np.sum(xc * yc))
    R = np.array([[np.cos(theta), -np.sin(theta), 0], [np.sin(theta), np.cos(theta), 0], [0, 0, 1]])
    expected = np.sqrt(np.mean(np.sum((yc - xc @ R.T) ** 2, axis=1)))
    T_gt, T_est = np.tile(np.eye(4), (n, 1, 1)), np.tile(np.eye(4), (n, 1, 1))
    T_gt[:, :3, 3], T_est[:, :3, 3] = y, x
    stamps = np.arange(n, dtype=float)
    m = evaluate_trajectory(PoseTrajectory(stamps, T_gt), PoseTrajectory(stamps, T_est))
    assert m.ate.rmse == pytest.approx(expected, rel=1e-12) and m.ate_se3_rmse == m.ate.rmse
    assert np.degrees(theta) == pytest.approx(-20.0, abs=1.0)


def evo_umeyama(x, y, with_scale):
    """evo.core.geometry.umeyama_alignment's arithmetic (x, y: (3, N)), for comparison; raises on rank < 2."""
    m, n = x.shape
    mean_x, mean_y = x.mean(axis=1), y.mean(axis=1)
    sigma_x = 1.0 / n * (np.linalg.norm(x - mean_x[:, np.newaxis]) ** 2)
    outer_sum = np.zeros((m, m))
    for i in range(n):
        outer_sum += np.outer((y[:, i] - mean_y), (x[:, i] - mean_x))
    u, d, v = np.linalg.svd(np.multiply(1.0 / n, outer_sum))
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < m - 1:
        raise ValueError("degenerate")
    s = np.eye(m)
    if np.linalg.det(u) * np.linalg.det(v) < 0.0:
        s[m - 1, m - 1] = -1
    r = u.dot(s).dot(v)
    c = 1 / sigma_x * np.trace(np.diag(d).dot(s)) if with_scale else 1.0
    return r, mean_y - np.multiply(c, r.dot(mean_x)), c


@pytest.mark.parametrize("alignment", ["se3", "sim3"])
def test_nearly_collinear_positions_keep_evos_fit_and_say_so(alignment):
    """A short, nearly straight run (the 60-frame case that used to fall back silently): the figure is evo's."""
    rng = np.random.default_rng(1)
    n = 60
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 0.3, n), [0, 1, 0])).as_matrix()
    T[:, :3, 3] = np.outer(np.linspace(0, 1.0, n), [1.0, 0.2, 0.0]) + rng.normal(0, 0.002, (n, 3))
    gt = PoseTrajectory(np.arange(n) / 30, T)
    T_est = similar(gt, R_OFF, np.array([1.0, 0.0, 0.0]), 0.8).T_world_cam.copy()
    T_est[:, :3, 3] += rng.normal(0, 0.03, (n, 3))  # 3 cm of noise on a 2 mm wide path
    est = PoseTrajectory(gt.timestamps, T_est)
    m = evaluate_trajectory(gt, est, alignment=alignment)
    r, t, c = evo_umeyama(est.positions.T, gt.positions.T, alignment == "sim3")
    expected = np.sqrt(np.mean(np.sum((gt.positions - (c * est.positions @ r.T + t)) ** 2, axis=1)))
    assert m.ate.rmse == pytest.approx(expected, rel=1e-9)
    assert m.alignment.used == alignment and m.alignment.degenerate and not m.alignment.fallback
    assert "collinear" in m.warnings[0] or "across" in m.warnings[0]
    assert m.flat_metrics()["ate_alignment_degenerate"] == 1.0


def test_path_distance_pairs_take_the_nearest_pose_within_the_tolerance():
    from eval.metrics.trajectory_metrics import path_distance_pairs

    d = np.array([0.0, 1.0, 1.0, 1.0, 3.0])
    i, j = path_distance_pairs(d, 1.4, 0.5)  # from 0: 1.0 (index 1, the first of three) misses by 0.4, 3.0 by 1.6
    assert list(zip(i.tolist(), j.tolist(), strict=True)) == [(0, 1)]
    i, j = path_distance_pairs(d, 2.0, 0.0)  # exactly 2 m: from each 1.0 to 3.0
    assert list(zip(i.tolist(), j.tolist(), strict=True)) == [(1, 4), (2, 4), (3, 4)]
    with pytest.raises(EvalError, match="positive number of metres"):
        path_distance_pairs(d, 0.0, 0.1)


def test_relative_error_of_a_path_ten_percent_too_long():
    """A straight 1 m path in 1 cm steps, estimated 10 % too long and not aligned: at 10-50 % of the path (0.1-0.5
    m; a tolerance under one step, so only pairs exactly that far apart) every pair's translation error is 10 % of
    its distance, its rotation error 0; with the default 20 % tolerance, pairs near the end come in too."""
    from eval.metrics.trajectory_metrics import relative_distance, relative_errors

    n = 101
    T = np.repeat(np.eye(4)[None], n, axis=0)
    T[:, 0, 3] = np.linspace(0.0, 1.0, n)
    est = T.copy()
    est[:, 0, 3] *= 1.1
    stamps = np.arange(n) / 30.0
    rel = relative_errors(PoseTrajectory(stamps, T), PoseTrajectory(stamps, est), tolerance=0.01)
    assert [r.distance_m for r in rel] == [0.1, 0.2, 0.3, 0.4, 0.5]
    for r in rel:
        assert r.translation.size == n - round(100 * r.distance_m)  # every start with a pose d further on
        np.testing.assert_allclose(r.translation, 0.1 * r.distance_m, atol=1e-12)
        np.testing.assert_allclose(r.rotation_deg, 0.0, atol=1e-9)
    loose = relative_errors(PoseTrajectory(stamps, T), PoseTrajectory(stamps, est))[0]  # pairs 0.09 m apart too
    assert loose.translation.size > n - 10 and loose.translation.min() == pytest.approx(0.009)
    assert relative_distance(13.0838, 10) == 1.3 and relative_distance(0.0, 50) == 0.0


def test_the_run_record_names_of_the_relative_error():
    n = 61
    T = np.repeat(np.eye(4)[None], n, axis=0)
    T[:, 0, 3] = np.linspace(0.0, 0.6, n)
    T[:, 1, 3] = 0.1 * np.sin(np.linspace(0, 3, n))  # not a line: a defined fit
    stamps = np.arange(n) / 30.0
    flat = evaluate_trajectory(PoseTrajectory(stamps, T), PoseTrajectory(stamps, T), association="index").flat_metrics()
    for share in (10, 20, 30, 40, 50):
        assert flat[f"rpe_trans_rmse_p{share}"] == pytest.approx(0.0, abs=1e-9)
        assert flat[f"rpe_rot_deg_rmse_p{share}"] == pytest.approx(0.0, abs=1e-6)
        assert flat[f"rpe_dist_m_p{share}"] > 0
    static = np.repeat(np.eye(4)[None], 5, axis=0)  # no path: no distance, no pairs, NaN
    flat = evaluate_trajectory(PoseTrajectory(stamps[:5], static), PoseTrajectory(stamps[:5], static),
                               association="index").flat_metrics()  # fmt: skip
    assert flat["rpe_dist_m_p10"] == 0.0 and np.isnan(flat["rpe_trans_rmse_p10"])
