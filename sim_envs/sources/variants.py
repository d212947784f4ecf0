"""World variants that a :class:`~sim_envs.sequences.SequenceSpec` cannot express, for the difficulty sweep of the
benchmark suites: the sequence rendered with other focal lengths (``focal_ratio`` x the training camera's, at the
spec's resolution, principal point kept: the field of view changes) and its trajectory with an extra pan, a rotation
about the camera's y axis (down in the image) sweeping +-:data:`ADDED_PAN_AMPLITUDE_DEG` at a set angular speed.

Conventions: poses ``T_world_cam`` (4, 4) camera-to-world, OpenCV camera axes; angles in degrees at the interface.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from sim_envs.camera import preset
from sim_envs.errors import SimEnvError
from sim_envs.motion.trajectories import Trajectory, sweep_angles
from sim_envs.sequences import TRAIN_CAMERA, SequenceSpec
from sim_envs.sources.simsource import SimulatedSequence

ADDED_PAN_AMPLITUDE_DEG = 20.0  # amplitude of the sweep's extra pan (ours: keeps the view on the room's content)


class VariantSequence(SimulatedSequence):
    """A simulated sequence with what :class:`~sim_envs.sequences.SequenceSpec` cannot express: other focal lengths
    (``focal_ratio`` x the training camera's, at the spec's resolution) and an extra pan sweeping
    +-:data:`ADDED_PAN_AMPLITUDE_DEG` at ``added_pan_deg_s`` deg/s about the camera's y axis (down in the image).

    Rendering, ground truth and determinism are :class:`SimulatedSequence`'s: the renderer is built from
    ``self.intrinsics`` and ``self.poses``, both set here before the first frame.
    """

    def __init__(
        self,
        spec: SequenceSpec,
        renderer: str = "mujoco",
        *,
        name: str | None = None,
        focal_ratio: float | None = None,
        added_pan_deg_s: float = 0.0,
    ) -> None:
        super().__init__(spec, renderer)
        self.name = name or spec.name
        if focal_ratio is not None:
            if not (math.isfinite(focal_ratio) and focal_ratio > 0):
                raise SimEnvError(f"focal_ratio must be a positive number, got {focal_ratio!r}")
            train = preset(TRAIN_CAMERA, spec.width, spec.height)
            self.intrinsics = self.intrinsics.with_focal(focal_ratio * train.fx, focal_ratio * train.fy)
        if not (math.isfinite(added_pan_deg_s) and added_pan_deg_s >= 0):
            raise SimEnvError(f"added_pan_deg_s must be a number >= 0, got {added_pan_deg_s!r}")
        self.added_pan_deg_s = float(added_pan_deg_s)
        self._panned: Trajectory | None = None

    @property
    def trajectory(self) -> Trajectory:
        """The spec's trajectory, with the extra pan when one is set (computed once)."""
        base = super().trajectory
        if self.added_pan_deg_s == 0.0:
            return base
        if self._panned is None:
            angles = sweep_angles(
                base.timestamps, np.radians(ADDED_PAN_AMPLITUDE_DEG), np.radians(self.added_pan_deg_s)
            )
            pan = np.tile(np.eye(4), (len(base), 1, 1))
            pan[:, :3, :3] = Rotation.from_euler("y", angles[:, None]).as_matrix()
            self._panned = Trajectory(base.timestamps, base.T_world_cam @ pan, kind=f"{base.kind}+pan")
        return self._panned
