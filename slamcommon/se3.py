"""Rigid transforms as 4x4 matrices ``T_a_b`` (maps b coordinates into a's; poses are ``T_world_cam``, OpenCV axes:
x right, y down, z forward), for stacks (..., 4, 4) float64."""

from __future__ import annotations

import numpy as np


def se3_inverse(T_a_b: np.ndarray) -> np.ndarray:
    """``T_b_a`` of ``T_a_b`` ((..., 4, 4) float64), using the rigid form [R^T, -R^T t]."""
    T_a_b = np.asarray(T_a_b, dtype=np.float64)
    Rt = np.swapaxes(T_a_b[..., :3, :3], -1, -2)
    out = np.zeros_like(T_a_b)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T_a_b[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def relative_pose(T_world_a: np.ndarray, T_world_b: np.ndarray) -> np.ndarray:
    """``T_a_b = T_world_a^-1 T_world_b`` for stacks (..., 4, 4): the pose of b expressed in the frame of a."""
    return se3_inverse(T_world_a) @ np.asarray(T_world_b, dtype=np.float64)


def sim3_matrix(rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """4x4 similarity [s R t; 0 1]."""
    S = np.eye(4)
    S[:3, :3] = scale * np.asarray(rotation, dtype=np.float64)
    S[:3, 3] = np.asarray(translation, dtype=np.float64)
    return S


def transform_poses(T_world_cam: np.ndarray, rotation: np.ndarray, translation: np.ndarray,
                    scale: float = 1.0) -> np.ndarray:
    """Apply the similarity x -> s R x + t to the world frame of poses (N, 4, 4).

    The camera axes stay orthonormal: R' = R R_i, t' = s R t_i + t (the scale moves positions, it does not shrink
    the cameras). Returns a new (N, 4, 4) float64 array.
    """
    T = np.asarray(T_world_cam, dtype=np.float64)
    R = np.asarray(rotation, dtype=np.float64)
    out = T.copy()
    out[..., :3, :3] = R @ T[..., :3, :3]
    out[..., :3, 3] = scale * (T[..., :3, 3] @ R.T) + np.asarray(translation, dtype=np.float64)
    return out
