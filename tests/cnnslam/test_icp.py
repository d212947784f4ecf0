import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import relative_pose, rotation_angle_deg, se3_inverse
from cnnslam.model.global_model import GlobalModel, GlobalModelConfig
from cnnslam.model.icp import (
    IcpConfig,
    SurfaceMaps,
    _evaluate,
    depth_pyramid,
    depth_surface_pyramid,
    icp_point_to_plane,
    maps_surface_pyramid,
    normal_map,
    point_to_plane_residuals,
    reference_pyramid,
    surface_maps_from_depth,
    surface_pyramid,
)

INTRINSICS_320 = np.array([240.6, 240.0, 159.5, 119.5])  # the analytic room's camera (tests/cnnslam/conftest.py)
SIZE = (240, 320)


def pose(t: tuple[float, float, float], rotvec_deg: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


T0 = pose((0.1, 0.0, 0.2), (2, -3, 1))
T1 = pose((0.16, -0.03, 0.26), (4, 0, 2))  # 9 cm and 3.7 degrees from T0


@pytest.fixture(scope="module")
def depths(room):
    assert np.allclose(room.intrinsics, INTRINSICS_320) and tuple(room.size) == SIZE
    return room.render(T0, supersample=1)[1], room.render(T1, supersample=1)[1]


def _errors(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    E = se3_inverse(T_true) @ T_est
    return float(np.linalg.norm(E[:3, 3])), rotation_angle_deg(E)


def test_normal_map_of_a_tilted_plane_faces_the_camera():
    # plane z = 2 + 0.5 x seen by a camera at the origin
    fx, fy, cx, cy = INTRINSICS_320
    u = (np.arange(SIZE[1]) - cx) / fx
    depth = np.tile(2.0 / (1.0 - 0.5 * u), (SIZE[0], 1)).astype(np.float32)
    V = np.stack([np.tile(u, (SIZE[0], 1)) * depth, ((np.arange(SIZE[0]) - cy) / fy)[:, None] * depth, depth], -1)
    N = normal_map(V.astype(np.float32))
    expected = np.array([0.5, 0.0, -1.0]) / np.sqrt(1.25)
    inner = N[1:-1, 1:-1].reshape(-1, 3)
    assert np.allclose(inner, expected, atol=1e-4)
    assert (N[0] == 0).all() and (N[:, -1] == 0).all()  # border: no normal


def test_icp_recovers_a_known_motion_between_two_rendered_depth_maps(depths):
    ref = surface_maps_from_depth(depths[0], INTRINSICS_320)
    cur = surface_maps_from_depth(depths[1], INTRINSICS_320)
    res = icp_point_to_plane(ref, cur, np.eye(4))
    t_err, r_err = _errors(res.T_ref_cur, relative_pose(T0, T1))
    assert res.tracked and res.inlier_share > 0.5
    assert t_err < 0.005 and r_err < 0.5
    assert res.rmse < 0.005 and res.iterations[-1] >= 1  # the coarsest level did work
    residuals = point_to_plane_residuals(cur.vertices[cur.valid], ref, res.T_ref_cur, max_distance=0.1)
    assert np.nanmedian(np.abs(residuals)) < 0.002
    # from the identity the residuals were large: the motion was real
    before = point_to_plane_residuals(cur.vertices[cur.valid], ref, np.eye(4), max_distance=0.5)
    assert np.nanmedian(np.abs(before)) > 0.01


def test_frame_to_model_icp_against_the_rendered_global_model(depths):
    model = GlobalModel(GlobalModelConfig(normal_smoothing_px=0.0))  # exact depth: raw normals, sharp creases
    model.integrate(depths[0], T0, INTRINSICS_320)
    view = model.render(T0, INTRINSICS_320, SIZE)
    valid = (view.index >= 0) & (np.abs(view.normals).sum(axis=2) > 0)
    assert valid.mean() > 0.9
    reference = SurfaceMaps(view.vertices, view.normals, valid, INTRINSICS_320)
    current = surface_maps_from_depth(depths[1], INTRINSICS_320)
    res = icp_point_to_plane(reference, current, np.eye(4))
    t_err, r_err = _errors(T0 @ res.T_ref_cur, T1)
    assert res.tracked and t_err < 0.005 and r_err < 0.5


def test_pyramid_halves_with_consistent_intrinsics(depths):
    pyr = surface_pyramid(surface_maps_from_depth(depths[0], INTRINSICS_320), 3)
    assert [p.valid.shape for p in pyr] == [(240, 320), (120, 160), (60, 80)]
    # a coarse vertex projects onto its own pixel with the coarse intrinsics (exactly where its block was complete;
    # within the block where only some of its pixels had a vertex, at the border)
    coarse = pyr[2]
    vs, us = np.nonzero(coarse.valid)
    fx, fy, cx, cy = coarse.intrinsics
    p = coarse.vertices[vs, us]
    du = np.abs(fx * p[:, 0] / p[:, 2] + cx - us)
    dv = np.abs(fy * p[:, 1] / p[:, 2] + cy - vs)
    assert np.mean((du < 0.05) & (dv < 0.05)) > 0.9
    assert du.max() < 1.0 and dv.max() < 1.0


def test_nothing_to_align_is_reported_lost_and_bad_config_is_rejected(depths):
    ref = surface_maps_from_depth(np.zeros(SIZE, np.float32), INTRINSICS_320)
    res = icp_point_to_plane(ref, surface_maps_from_depth(depths[1], INTRINSICS_320), np.eye(4))
    assert not res.tracked and res.inliers == 0
    with pytest.raises(CnnSlamError, match="iterations"):
        IcpConfig(levels=2, iterations=(10, 5, 4))
    with pytest.raises(CnnSlamError, match="max_distance"):
        IcpConfig(max_distance=0.0)


def _normal_equations_numpy(cur: SurfaceMaps, ref: SurfaceMaps, T: np.ndarray, cfg: IcpConfig):
    """The normal equations written out in numpy (the definition the kernel follows): (H, g, sum r^2, inliers)."""
    R, t = T[:3, :3], T[:3, 3]
    p = cur.vertices[cur.valid].astype(np.float64) @ R.T + t
    n_cur = cur.normals[cur.valid].astype(np.float64) @ R.T
    fx, fy, cx, cy = ref.intrinsics
    front = p[:, 2] > 1e-6
    z = np.where(front, p[:, 2], 1.0)
    u = np.floor(fx * p[:, 0] / z + cx + 0.5).astype(int)
    v = np.floor(fy * p[:, 1] / z + cy + 0.5).astype(int)
    h, w = ref.valid.shape
    ok = front & (u >= 0) & (v >= 0) & (u < w) & (v < h)
    ok[ok] &= ref.valid[v[ok], u[ok]]
    p, n_cur, u, v = p[ok], n_cur[ok], u[ok], v[ok]
    d = p - ref.vertices[v, u]
    n = ref.normals[v, u].astype(np.float64)
    keep = ((d**2).sum(axis=1) <= cfg.max_distance**2) & \
        ((n_cur * n).sum(axis=1) >= np.cos(np.radians(cfg.max_normal_angle_deg)))
    p, d, n = p[keep], d[keep], n[keep]
    r = (n * d).sum(axis=1)
    J = np.hstack([n, np.cross(p, n)])
    wgt = np.where(np.abs(r) <= cfg.huber_delta, 1.0, cfg.huber_delta / np.maximum(np.abs(r), 1e-300))
    return (J * wgt[:, None]).T @ J, (J * wgt[:, None]).T @ r, float(r @ r), len(r)


def test_the_normal_equations_kernel_is_the_numpy_definition(depths):
    cfg = IcpConfig()
    ref = surface_maps_from_depth(depths[0], INTRINSICS_320)
    cur = surface_maps_from_depth(depths[1], INTRINSICS_320)
    T = relative_pose(T0, T1) @ pose((0.004, -0.002, 0.003), (0.3, -0.2, 0.1))  # near the answer, not at it
    H, g, err, n = _evaluate(cur, ref, T, cfg)
    H_np, g_np, err_np, n_np = _normal_equations_numpy(cur, ref, T, cfg)
    assert n == n_np and n > 0.5 * cur.valid.sum()
    assert np.allclose(H, H_np, rtol=1e-9, atol=1e-9) and np.allclose(g, g_np, rtol=1e-9, atol=1e-12)
    assert err == pytest.approx(err_np, rel=1e-9) and np.array_equal(H, H.T)


def test_the_pyramids_take_the_compiled_path_unless_the_depth_is_smoothed(depths):
    raw, smoothed = IcpConfig(smoothing_px=0.0), IcpConfig()
    fast = depth_pyramid(depths[0], INTRINSICS_320, raw)
    numpy_form = surface_pyramid(surface_maps_from_depth(depths[0], INTRINSICS_320, 0.05, 0.0), 3, 0.05)
    for a, b, c in zip(fast, depth_surface_pyramid(depths[0], INTRINSICS_320, 3, 0.05), numpy_form, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.valid, b.valid)
        assert np.array_equal(a.valid, c.valid) and np.allclose(a.vertices, c.vertices, atol=1e-6)
        assert np.allclose(a.normals, c.normals, atol=1e-6) and np.allclose(a.intrinsics, c.intrinsics)
    slow = depth_pyramid(depths[0], INTRINSICS_320, smoothed)  # pre-smoothing: the numpy path itself
    expected = surface_pyramid(surface_maps_from_depth(depths[0], INTRINSICS_320, 0.05, 2.0, 0.05), 3, 0.05)
    assert all(np.array_equal(a.vertices, b.vertices) and np.array_equal(a.valid, b.valid)
               for a, b in zip(slow, expected, strict=True))
    maps = numpy_form[0]
    for a, b, c in zip(reference_pyramid(maps, raw), maps_surface_pyramid(maps, 3, 0.05), numpy_form, strict=True):
        assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.valid, c.valid)
        assert np.allclose(a.vertices, c.vertices, atol=1e-6) and np.allclose(a.normals, c.normals, atol=1e-6)
