"""Trajectory and index files of the usual SLAM benchmarks (TUM RGB-D, KITTI odometry, ICL-NUIM, 7-Scenes) as the
world raises their errors.

The formats are defined once in :mod:`slamcommon.formats` (the world and the judge read them; see there for the
formats themselves). This module keeps the names that code and users import from ``sim_envs.folders.formats`` and raises
the world's :class:`~sim_envs.errors.FormatError` (a ``SimEnvError`` and a ``slamcommon.errors.FormatError``, same
message) where the shared readers raise the shared one.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TypeVar

from sim_envs.errors import FormatError
from slamcommon import formats as _shared
from slamcommon.errors import FormatError as SharedFormatError
from slamcommon.formats import (
    DUPLICATE_POLICIES,
    QUATERNION_TOL,
    ROTATION_TOL,
    DuplicatePolicy,
    matrices_to_quaternions,
    quaternions_to_matrices,
)

_F = TypeVar("_F", bound=Callable)


def world_errors(function: _F) -> _F:
    """``function`` raising :class:`sim_envs.errors.FormatError` where it raises the shared ``FormatError``."""

    @functools.wraps(function)
    def call(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        except SharedFormatError as exc:
            if isinstance(exc, FormatError):
                raise
            raise FormatError(str(exc)) from exc

    return call  # type: ignore[return-value]


read_tum_trajectory = world_errors(_shared.read_tum_trajectory)
format_tum_trajectory = world_errors(_shared.format_tum_trajectory)
write_tum_trajectory = world_errors(_shared.write_tum_trajectory)
read_tum_image_list = world_errors(_shared.read_tum_image_list)
write_tum_image_list = world_errors(_shared.write_tum_image_list)
read_kitti_poses = world_errors(_shared.read_kitti_poses)
write_kitti_poses = world_errors(_shared.write_kitti_poses)
read_icl_associations = world_errors(_shared.read_icl_associations)
read_pose_matrix = world_errors(_shared.read_pose_matrix)
associate_greedy = world_errors(_shared.associate_greedy)

__all__ = [
    "DUPLICATE_POLICIES",
    "QUATERNION_TOL",
    "ROTATION_TOL",
    "DuplicatePolicy",
    "associate_greedy",
    "format_tum_trajectory",
    "matrices_to_quaternions",
    "quaternions_to_matrices",
    "read_icl_associations",
    "read_kitti_poses",
    "read_pose_matrix",
    "read_tum_image_list",
    "read_tum_trajectory",
    "world_errors",
    "write_kitti_poses",
    "write_tum_image_list",
    "write_tum_trajectory",
]
