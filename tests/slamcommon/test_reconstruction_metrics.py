import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.frames import NO_LABEL
from slamcommon.reconstruction_metrics import (
    VISIBILITY_ABS_TOLERANCE,
    VISIBILITY_REL_TOLERANCE,
    ReconstructionMetricsError,
    distance_to_surface,
    image_label_accuracy,
    label_fusion_metrics,
    measurement_label_metrics,
    nearest_labels,
    nearest_tree,
    reconstruction_metrics,
    visible_in_views,
)

SPACING = 0.02


def _plane_samples(size: float = 1.0, spacing: float = SPACING, z: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres on the square [0, size]^2 at height z, normals +z."""
    c = (np.arange(round(size / spacing)) + 0.5) * spacing
    X, Y = np.meshgrid(c, c, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), np.full(X.size, z)], axis=1)
    return pts, np.tile([0.0, 0.0, 1.0], (pts.shape[0], 1))


def test_known_shift_gives_known_accuracy_and_completeness():
    gt, normals = _plane_samples()
    rng = np.random.default_rng(0)
    # model points anywhere over the plane (not on the sample grid), 3 cm above it
    model = np.column_stack([rng.uniform(0.1, 0.9, (5000, 2)), np.full(5000, 0.03)])
    m = reconstruction_metrics(model, gt, normals, SPACING, threshold=0.05)
    assert m.accuracy_mean == pytest.approx(0.03, abs=1e-12)  # the point-to-plane refinement is exact here
    assert m.accuracy_median == pytest.approx(0.03, abs=1e-12) and m.accuracy_within == 1.0
    # completeness: ground truth under the model (0.1..0.9) is within ~3 cm; the 10 cm margins are not
    comp_inner = reconstruction_metrics(model, gt[(gt[:, :2] > 0.12).all(1) & (gt[:, :2] < 0.88).all(1)])
    assert comp_inner.completeness_within == 1.0
    assert 0.03 <= comp_inner.completeness_mean < 0.035
    # ground truth within 5 cm of a point 3 cm up: within 4 cm sideways of the model's square: (0.8 + 0.08)^2
    assert m.completeness_within == pytest.approx(0.88**2, abs=0.02)
    far = reconstruction_metrics(model + [0, 0, 0.04], gt, normals, SPACING, threshold=0.05)
    assert far.accuracy_mean == pytest.approx(0.07) and far.accuracy_within == 0.0
    assert m.n_model == 5000 and m.n_gt == gt.shape[0]


def test_seen_samples_count_for_completeness_and_every_sample_for_accuracy():
    gt, normals = _plane_samples()
    left = gt[:, 0] < 0.5  # the views saw the left half only
    model = gt[left & (gt[:, 1] < 0.5)] + [0.0, 0.0, 0.01]  # the model covers a quarter, 1 cm up
    model = np.vstack([model, [[0.9, 0.9, 0.02]]])  # and one point 2 cm over the unseen half
    m = reconstruction_metrics(model, gt, normals, SPACING, threshold=0.05, seen=left)
    assert m.accuracy_within == 1.0 and m.accuracy_median == pytest.approx(0.01)  # the unseen surface is a surface
    assert m.n_gt == int(left.sum()) and m.completeness_within == pytest.approx(0.5 + 2 / 50, abs=0.03)
    with pytest.raises(ReconstructionMetricsError, match="bool mask"):
        reconstruction_metrics(model, gt, seen=np.ones(3, bool))
    with pytest.raises(ReconstructionMetricsError, match="no ground-truth sample was seen"):
        reconstruction_metrics(model, gt, seen=np.zeros(len(gt), bool))


def test_plain_nearest_sample_distance_has_the_sampling_bias_the_refinement_removes():
    gt, normals = _plane_samples()
    model = np.array([[0.5, 0.5, 0.0], [0.51, 0.51, 0.0]])  # on the surface: between 4 samples, on a sample
    plain, _ = distance_to_surface(model, gt)
    refined, _ = distance_to_surface(model, gt, normals, SPACING)
    assert plain[0] == pytest.approx(SPACING / math.sqrt(2)) and plain[1] == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(refined, 0.0, atol=1e-12)
    beyond, _ = distance_to_surface(np.array([[1.1, 0.5, 0.0]]), gt, normals, SPACING)  # 10 cm past the edge
    assert 0.1 - SPACING / math.sqrt(2) <= beyond[0] <= 0.1


def test_empty_model_is_complete_nowhere_and_bad_input_raises():
    gt, _ = _plane_samples(0.2)
    m = reconstruction_metrics(np.zeros((0, 3)), gt)
    assert math.isnan(m.accuracy_mean) and m.completeness_within == 0.0 and math.isinf(m.completeness_mean)
    with pytest.raises(ReconstructionMetricsError, match=r"\(N, 3\)"):
        reconstruction_metrics(np.zeros((4, 2)), gt)
    with pytest.raises(ReconstructionMetricsError, match="empty"):
        reconstruction_metrics(gt, np.zeros((0, 3)))


def test_visibility_keeps_points_seen_and_not_occluded():
    K = np.array([100.0, 100.0, 49.5, 49.5])
    T = np.eye(4)  # camera at the origin looking down +z
    depth = np.full((100, 100), 2.0, np.float32)  # a wall at z = 2 ...
    depth[:, :50] = 1.0  # ... and its left half hidden behind a board at z = 1
    pts = np.array([[0.5, 0.0, 2.0],  # right half of the wall: seen
                    [-0.5, 0.0, 2.0],  # left half, behind the board: occluded
                    [-0.5, 0.0, 1.0],  # the board: seen
                    [5.0, 0.0, 2.0],  # outside the image
                    [0.0, 0.0, -2.0]])  # behind the camera
    seen = visible_in_views(pts, T[None], [depth], K)
    assert seen.tolist() == [True, False, True, False, False]
    T2 = np.eye(4)
    T2[0, 3] = -1.0  # a second view, 1 m to the left, whose depth map shows the wall without the board
    depth2 = np.full((100, 100), 2.0, np.float32)
    seen2 = visible_in_views(pts, np.stack([T, T2]), [depth, depth2], K)
    assert seen2.tolist() == [True, True, True, False, False]
    with pytest.raises(ReconstructionMetricsError, match="depth maps"):
        visible_in_views(pts, np.stack([T, T2]), [depth], K)


def _visible_numpy(points, poses, depths, intrinsics, abs_tol, rel_tol):
    """visible_in_views as whole-array numpy (its formulation before the compiled kernel): the reference."""
    fx, fy, cx, cy = intrinsics
    seen = np.zeros(len(points), dtype=bool)
    for T, d in zip(poses, depths, strict=True):
        h, w = d.shape
        todo = np.flatnonzero(~seen)
        q = (points[todo] - T[:3, 3]) @ T[:3, :3]
        z = q[:, 2]
        front = z > 1e-6
        todo, q, z = todo[front], q[front], z[front]
        u, v = np.rint(fx * q[:, 0] / z + cx), np.rint(fy * q[:, 1] / z + cy)
        inside = (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
        todo, z = todo[inside], z[inside]
        dz = d[v[inside].astype(np.intp), u[inside].astype(np.intp)]
        seen[todo[(dz > 0) & (np.abs(z - dz) < abs_tol + rel_tol * z)]] = True
    return seen


def test_visibility_kernel_sees_the_points_the_numpy_formulation_sees():
    # a room of random points, 12 random views with depth maps of a noisy wall and holes, maps of two sizes; the
    # points are placed on the maps' surfaces so that many sit at the tolerance's and the pixels' borders
    rng = np.random.default_rng(7)
    K = np.array([240.6, 240.0, 159.5, 119.5])
    poses, depths = [], []
    for k in range(12):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(rng.normal(0, 0.3, 3)).as_matrix()
        T[:3, 3] = rng.normal(0, 0.5, 3)
        h, w = (240, 320) if k % 2 else (120, 160)
        d = (2.0 + rng.normal(0, 0.05, (h, w))).astype(np.float32)
        d[rng.random((h, w)) < 0.1] = 0.0
        poses.append(T)
        depths.append(d)
    on_wall = []
    for T, d in zip(poses[:4], depths[:4], strict=True):  # back-projected pixels, jittered around the tolerance
        h, w = d.shape
        u, v = rng.uniform(-0.5, w - 0.5, 3000), rng.uniform(-0.5, h - 0.5, 3000)
        z = 2.0 * (1 + rng.normal(0, 0.02, 3000)) + rng.choice([-0.07, -0.03, 0.0, 0.03, 0.07], 3000)
        x, y = (u - K[2]) / K[0] * z, (v - K[3]) / K[1] * z
        on_wall.append(np.c_[x, y, z] @ T[:3, :3].T + T[:3, 3])
    pts = np.concatenate([rng.uniform(-4, 4, (20000, 3)), *on_wall])
    seen = visible_in_views(pts, np.stack(poses), depths, K)
    expected = _visible_numpy(pts, np.stack(poses), depths, K, VISIBILITY_ABS_TOLERANCE, VISIBILITY_REL_TOLERANCE)
    assert 1000 < expected.sum() < len(pts) - 1000
    np.testing.assert_array_equal(seen, expected)


def test_label_fusion_metrics_count_the_same_points_for_both():
    gt, _ = _plane_samples(1.0)
    gt_labels = np.where(gt[:, 0] < 0.5, 0, 1).astype(np.uint8)  # floor left, wall right
    # frame-wise points on the plane, labelled with 30 % errors; the model labels them right except near x = 0.5
    rng = np.random.default_rng(1)
    frame_pts = np.column_stack([rng.uniform(0.02, 0.98, (2000, 2)), np.zeros(2000)])
    truth = np.where(frame_pts[:, 0] < 0.5, 0, 1)
    wrong = rng.random(2000) < 0.3
    frame_labels = np.where(wrong, 1 - truth, truth).astype(np.uint8)
    model_pts, _ = _plane_samples(1.0, 0.01)
    model_labels = np.where(model_pts[:, 0] < 0.5, 0, 1).astype(np.uint8)
    model_labels[np.abs(model_pts[:, 0] - 0.5) < 0.05] = 3  # a wrong strip 10 cm wide
    model_labels[:10] = 255  # no label evidence: not scored
    m = label_fusion_metrics(model_pts, model_labels, frame_pts, frame_labels, gt, gt_labels, max_distance=0.1)
    strip = np.abs(frame_pts[:, 0] - 0.5) < 0.05
    assert m.n_points == 2000 and m.coverage == 1.0
    assert m.framewise_accuracy == pytest.approx(1 - wrong.mean())
    assert m.fused_accuracy == pytest.approx(1 - strip.mean(), abs=0.01)
    assert m.gain_points == pytest.approx((m.fused_accuracy - m.framewise_accuracy) * 100)
    assert m.model_accuracy == pytest.approx(0.9, abs=0.01)
    # points 20 cm off the surface get no ground-truth label and are not scored
    labels, d = nearest_labels(np.array([[0.5, 0.5, 0.2], [0.2, 0.5, 0.0]]), gt, gt_labels, 0.1)
    assert labels.tolist() == [255, 0] and d[0] == pytest.approx(0.2, abs=0.01)


def test_image_label_accuracy_scores_pixels_the_model_covers():
    gt = np.array([[0, 0, 1], [1, 255, 2]], np.uint8)
    fused = np.array([[0, 1, 1], [255, 1, 2]], np.uint8)
    frame = np.array([[0, 0, 0], [1, 1, 1]], np.uint8)
    fused_acc, frame_acc, n = image_label_accuracy([fused], [frame], [gt])
    assert n == 4 and fused_acc == pytest.approx(3 / 4) and frame_acc == pytest.approx(2 / 4)
    with pytest.raises(ReconstructionMetricsError, match="as many"):
        image_label_accuracy([fused], [], [gt])


def test_measurement_label_metrics_score_each_fused_measurement_with_its_elements_label():
    """Four elements with hand-counted measurement weights per ground-truth class (see the sums below)."""
    evidence = np.array([[2, 0, 0, 0],   # pure, fused right; frame-wise right on 1.5 of 2
                         [1, 3, 0, 0],   # mixed: the fused label 1 is right for 3 of 4
                         [0, 0, 1, 0],   # pure, no fused label: wrong; frame-wise right
                         [0, 0, 0, 0]],  # nothing labelled fused into it
                        dtype=np.float64)
    fused = np.array([0, 1, NO_LABEL, 2], np.uint8)
    right = np.array([1.5, 2.0, 1.0, 0.0])
    m = measurement_label_metrics(fused, evidence, right)
    assert m.mass == 7 and m.n_elements == 3
    assert np.isclose(m.fused_accuracy, 5 / 7) and np.isclose(m.framewise_accuracy, 4.5 / 7)
    assert np.isclose(m.gain_points, 50 / 7) and np.isclose(m.purity, 6 / 7) and np.isclose(m.pure_share, 3 / 7)
    assert np.isclose(m.pure_fused_accuracy, 2 / 3) and np.isclose(m.pure_framewise_accuracy, 2.5 / 3)
    assert np.isclose(m.mixed_fused_accuracy, 3 / 4) and np.isclose(m.mixed_framewise_accuracy, 2 / 4)
    with pytest.raises(ReconstructionMetricsError, match="exceeds"):
        measurement_label_metrics(fused, evidence, right + 1)
    with pytest.raises(ReconstructionMetricsError, match="one fused label"):
        measurement_label_metrics(fused[:2], evidence, right)
    assert math.isnan(measurement_label_metrics(fused, np.zeros((4, 4)), np.zeros(4)).fused_accuracy)


def test_nearest_tree_finds_the_exact_nearest_sample() -> None:
    """The sliding-midpoint tree answers exact nearest neighbours: distances equal to a brute-force search, on a
    2 cm grid of samples (a sampled wall) and points scattered off it."""
    g = np.arange(0.0, 1.0, 0.02)
    xs, ys = np.meshgrid(g, g)
    samples = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    points = np.random.default_rng(3).uniform([-0.1, -0.1, -0.2], [1.1, 1.1, 0.2], (500, 3))
    d, idx = nearest_tree(samples).query(points, k=1)
    brute = np.linalg.norm(points[:, None, :] - samples[None, :, :], axis=2)
    np.testing.assert_array_equal(d, brute.min(axis=1))
    np.testing.assert_array_equal(brute[np.arange(points.shape[0]), idx], brute.min(axis=1))
