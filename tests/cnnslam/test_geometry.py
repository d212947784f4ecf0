"""Tests of SE(3) exp/log, the projection of eq. 3, the vertex map of eq. 4 and the key-frame warps."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cnnslam.geometry import (
    adjoint,
    depth_of_neighbour_in,
    hat,
    orthonormalize,
    perspective_projection,
    project_to_pixels,
    pyramid_intrinsics,
    relative_pose,
    se3_exp,
    se3_inverse,
    se3_log,
    vertex_map,
    warp_keyframe_pixels,
)

K = np.array([240.6, 240.0, 159.5, 119.5])


def test_exp_of_pure_translation_and_known_rotation() -> None:
    T = se3_exp(np.array([0.1, -0.2, 0.3, 0.0, 0.0, 0.0]))
    expected = np.eye(4)
    expected[:3, 3] = [0.1, -0.2, 0.3]
    np.testing.assert_allclose(T, expected)
    # rotation of pi/2 about z with translation along x: t = V v, V = I + (1-cos)/t^2 W + (t-sin)/t^3 W^2
    T = se3_exp(np.array([1.0, 0.0, 0.0, 0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(T[:3, :3], Rotation.from_euler("z", 90, degrees=True).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [2 / np.pi, 2 / np.pi, 0.0], atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-4, 0.5, 2.0, 3.1])
def test_exp_log_round_trip(angle: float) -> None:
    rng = np.random.default_rng(int(angle * 1000))
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        xi = np.concatenate([rng.normal(scale=2.0, size=3), axis * angle])
        np.testing.assert_allclose(se3_log(se3_exp(xi)), xi, atol=1e-9)
        T = se3_exp(xi)
        np.testing.assert_allclose(se3_exp(se3_log(T)), T, atol=1e-12)


def test_batched_exp_log_and_inverse() -> None:
    rng = np.random.default_rng(1)
    xi = rng.normal(scale=0.5, size=(7, 6))
    T = se3_exp(xi)
    assert T.shape == (7, 4, 4)
    np.testing.assert_allclose(se3_log(T), xi, atol=1e-10)
    np.testing.assert_allclose(se3_inverse(T) @ T, np.broadcast_to(np.eye(4), (7, 4, 4)), atol=1e-12)
    np.testing.assert_allclose(hat(xi[:, 3:]) @ xi[:, :3, None], np.cross(xi[:, 3:], xi[:, :3])[..., None],
                               atol=1e-12)


def test_adjoint_moves_twists_through_a_transform() -> None:
    rng = np.random.default_rng(2)
    T = se3_exp(rng.normal(size=6))
    xi = rng.normal(scale=0.3, size=6)
    np.testing.assert_allclose(se3_exp(adjoint(T) @ xi), T @ se3_exp(xi) @ se3_inverse(T), atol=1e-10)


def test_relative_pose_direction() -> None:
    T_world_a = se3_exp(np.array([1.0, 0, 0, 0, 0.3, 0]))
    T_world_b = se3_exp(np.array([0, 2.0, 0, 0.1, 0, 0]))
    T_a_b = relative_pose(T_world_a, T_world_b)
    p_b = np.array([0.3, -0.2, 2.0, 1.0])
    np.testing.assert_allclose(T_world_a @ (T_a_b @ p_b), T_world_b @ p_b, atol=1e-12)


def test_eq3_projection_and_eq4_vertex_map_invert_each_other() -> None:
    np.testing.assert_allclose(perspective_projection(np.array([2.0, -4.0, 2.0])), [1.0, -2.0])
    depth = np.full((240, 320), 2.5, np.float32)
    depth[100, 200] = 1.25
    V = vertex_map(depth, K)
    np.testing.assert_allclose(V[119, 160], [(160 - 159.5) / 240.6 * 2.5, (119 - 119.5) / 240 * 2.5, 2.5])
    np.testing.assert_allclose(V[100, 200], [(200 - 159.5) / 240.6 * 1.25, (100 - 119.5) / 240 * 1.25, 1.25])
    uv = project_to_pixels(V, K)
    v, u = np.mgrid[0:240, 0:320]
    np.testing.assert_allclose(uv[..., 0], u, atol=1e-9)
    np.testing.assert_allclose(uv[..., 1], v, atol=1e-9)


def test_pyramid_intrinsics_keep_pixel_centres() -> None:
    np.testing.assert_allclose(pyramid_intrinsics(K, 1), [120.3, 120.0, 79.5, 59.5])
    np.testing.assert_allclose(pyramid_intrinsics(K, 0), K)


def test_warp_and_neighbour_depth_of_a_plane() -> None:
    # a fronto-parallel plane at 3 m seen from i; camera j is 0.5 m forward: the plane is at 2.5 m in j
    depth = np.full((240, 320), 3.0)
    T_world_i = np.eye(4)
    T_world_j = se3_exp(np.array([0.0, 0.0, 0.5, 0.0, 0.0, 0.0]))
    T_j_i = relative_pose(T_world_j, T_world_i)
    uv, z_j = warp_keyframe_pixels(depth, K, T_j_i)
    np.testing.assert_allclose(z_j, 2.5)
    np.testing.assert_allclose(uv[119, 159], [159.5 + (159 - 159.5) * 3 / 2.5, 119.5 + (119 - 119.5) * 3 / 2.5])
    d_in_i, d_at_v, valid = depth_of_neighbour_in(depth, np.full((240, 320), 2.5), K, T_j_i)
    assert valid[60:180, 80:240].all()
    np.testing.assert_allclose(d_in_i[valid], 3.0, atol=1e-9)  # j's depth re-expressed in i: the same plane
    np.testing.assert_allclose(d_at_v[valid], 2.5)  # D_kj(v) itself


def test_orthonormalize_repairs_drift() -> None:
    T = se3_exp(np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]))
    drifted = T.copy()
    drifted[:3, :3] *= 1.001
    fixed = orthonormalize(drifted)
    np.testing.assert_allclose(fixed[:3, :3].T @ fixed[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(fixed, T, atol=1e-9)


def test_se3_exp_of_one_small_twist_is_the_batched_arithmetic():
    """One twist with |w| < 1e-2 goes through the compiled copy of the numpy path: the same transform to the last
    bits (within 2 ulp here, as numpy's own kernels may round differently on another machine), at every scale of
    small rotation, and a larger rotation still goes the numpy way."""
    rng = np.random.default_rng(7)
    mags = rng.choice([0.0, 1e-8, 1e-6, 1e-4, 1e-3, 3e-3, 6e-3], 3000)
    xis = rng.normal(size=(3000, 6)) * mags[:, None]
    xis = xis[np.linalg.norm(xis[:, 3:], axis=1) < 1e-2]
    for xi in xis:
        one, batched = se3_exp(xi), se3_exp(xi[None])[0]
        np.testing.assert_allclose(one, batched, rtol=0, atol=4.5e-16 * max(1.0, np.abs(xi[:3]).max()))
    xi = np.array([0.5, -0.2, 0.1, 0.3, -0.4, 0.2])
    np.testing.assert_array_equal(se3_exp(xi), se3_exp(xi[None])[0])
