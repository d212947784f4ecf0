"""The file formats of the usual SLAM benchmarks, defined once for the world (reading real folders, writing
exports) and the judge (reading trajectories), importing neither and no Gymnasium:

- :mod:`~slamcommon.formats.tum`: TUM RGB-D trajectories (``timestamp tx ty tz qx qy qz qw``, a fast path bit for
  bit equal to the line-by-line reader) and image lists (``rgb.txt``, ``depth.txt``);
- :mod:`~slamcommon.formats.kitti`: KITTI odometry pose files;
- :mod:`~slamcommon.formats.icl`: ICL-NUIM ``associations.txt``;
- :mod:`~slamcommon.formats.seven_scenes`: 7-Scenes ``frame-XXXXXX.pose.txt`` and the layout's constants;
- :mod:`~slamcommon.formats.association`: the TUM tools' greedy timestamp association;
- :mod:`~slamcommon.formats.lines`: the shared text rules (comments, separators, increasing timestamps).

Reading is strict: the first bad line raises one :class:`~slamcommon.errors.FormatError` that names the file, the
line, what was found and what is valid (``sim_envs.folders.formats`` re-raises it as the world's ``FormatError``).
"""

from slamcommon.errors import FormatError
from slamcommon.formats.association import associate_greedy
from slamcommon.formats.icl import ICL_FPS, read_icl_associations
from slamcommon.formats.kitti import ROTATION_TOL, read_kitti_poses, write_kitti_poses
from slamcommon.formats.lines import DUPLICATE_POLICIES, DuplicatePolicy
from slamcommon.formats.seven_scenes import POSE_ROTATION_TOL, read_pose_matrix
from slamcommon.formats.tum import (
    QUATERNION_TOL,
    format_tum_trajectory,
    matrices_to_quaternions,
    quaternions_to_matrices,
    read_tum_image_list,
    read_tum_trajectory,
    read_tum_trajectory_by_line,
    write_tum_image_list,
    write_tum_trajectory,
)

__all__ = [
    "DUPLICATE_POLICIES",
    "ICL_FPS",
    "POSE_ROTATION_TOL",
    "QUATERNION_TOL",
    "ROTATION_TOL",
    "DuplicatePolicy",
    "FormatError",
    "associate_greedy",
    "format_tum_trajectory",
    "matrices_to_quaternions",
    "quaternions_to_matrices",
    "read_icl_associations",
    "read_kitti_poses",
    "read_pose_matrix",
    "read_tum_image_list",
    "read_tum_trajectory",
    "read_tum_trajectory_by_line",
    "write_kitti_poses",
    "write_tum_image_list",
    "write_tum_trajectory",
]
