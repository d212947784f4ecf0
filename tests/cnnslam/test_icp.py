import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import relative_pose, rotation_angle_deg, se3_inverse
from cnnslam.global_model import GlobalModel, GlobalModelConfig
from cnnslam.icp import (
    IcpConfig,
    SurfaceMaps,
    icp_point_to_plane,
    normal_map,
    point_to_plane_residuals,
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
