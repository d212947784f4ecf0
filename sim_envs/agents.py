"""Two trivial agents for tests and as reference points: a ground-truth oracle and a constant-pose agent.

Both follow the agent contract of :mod:`sim_envs.agent`. The oracle declares ``uses_ground_truth = True`` and so
receives the env's ``info`` (``step(observation, info)``); results of such agents are marked by the driver. Each has
a configuration (:class:`OracleConfig`, :class:`ConstantPoseConfig`; ``config={...}`` overrides, as every method's),
which ``cnnslam config`` prints.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from sim_envs.agent import AgentOutput, KeyframeDepth
from sim_envs.errors import SimEnvError
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED
from slamcommon.config import Configurable, configure


@dataclass(frozen=True)
class OracleConfig(Configurable):
    """The oracle's one setting."""

    # ours: a key-frame (its ground-truth depth and pose) every k frames, frames 0, k, 2k, ...
    keyframe_every: int = 10

    def __post_init__(self) -> None:
        if self.keyframe_every < 1:
            raise SimEnvError(f"keyframe_every must be >= 1, got {self.keyframe_every}")


@dataclass(frozen=True)
class ConstantPoseConfig(Configurable):
    """The constant-pose agent's one setting."""

    # ours: what it claims each frame (True: tracked, so its ATE is read as a tracked method's)
    tracked: bool = True


class OracleAgent:
    """Returns the ground-truth pose every frame and reports a key-frame with ground-truth depth every
    ``keyframe_every`` frames (frames 0, k, 2k, ...; none when the env gives no ``gt_depth``).

    An upper bound for tracking (zero error) and for depth (100 % correct on key-frames), and a check of the
    evaluation pipeline end to end.
    """

    uses_ground_truth = True
    name = "oracle"

    def __init__(self, keyframe_every: int = 10, config: OracleConfig | Mapping[str, Any] | None = None) -> None:
        self.config = configure(OracleConfig(keyframe_every=int(keyframe_every)), config)
        self.keyframe_every = self.config.keyframe_every
        self._keyframes: list[KeyframeDepth] = []
        self._n = 0

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """Forget the previous episode."""
        self._keyframes, self._n = [], 0

    def step(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> dict[str, Any]:
        """The ground-truth pose of this frame (from ``info["gt_T_world_cam"]``), tracked."""
        if "gt_T_world_cam" not in info:
            raise SimEnvError("OracleAgent needs info['gt_T_world_cam'] from the environment")
        T = np.array(info["gt_T_world_cam"], dtype=np.float64)
        if self._n % self.keyframe_every == 0 and "gt_depth" in info:
            self._keyframes.append(
                KeyframeDepth(
                    timestamp=float(observation["timestamp"][0]),
                    depth=np.array(info["gt_depth"], dtype=np.float32),
                    T_world_cam=T.copy(),
                    labels=None if "gt_labels" not in info else np.array(info["gt_labels"], dtype=np.uint8),
                )
            )
        self._n += 1
        return {T_WORLD_CAM: T, TRACKED: 1}

    def finish(self) -> AgentOutput:
        """The key-frames collected (ground-truth depth and pose) and the number of frames seen."""
        return AgentOutput(keyframes=list(self._keyframes), extras={"frames": self._n})


class ConstantPoseAgent:
    """Answers the identity pose for every frame and reports no key-frames: the "does nothing" baseline (its ATE
    after alignment is the spread of the ground-truth trajectory). ``tracked``: what it claims each frame."""

    uses_ground_truth = False
    name = "constant_pose"

    def __init__(self, tracked: bool = True, config: ConstantPoseConfig | Mapping[str, Any] | None = None) -> None:
        self.config = configure(ConstantPoseConfig(tracked=bool(tracked)), config)
        self.tracked = self.config.tracked
        self._n = 0

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """Forget the previous episode."""
        self._n = 0

    def step(self, observation: dict[str, np.ndarray]) -> dict[str, Any]:
        """The identity pose."""
        self._n += 1
        return {T_WORLD_CAM: np.eye(4), TRACKED: int(self.tracked)}

    def finish(self) -> AgentOutput:
        """No key-frames; the number of frames seen."""
        return AgentOutput(keyframes=[], extras={"frames": self._n})


class BiasedPoseAgent:
    """Another agent whose answered poses are turned by a fixed yaw in the camera frame: ``T_world_cam @ R_y(yaw)``
    (y is the camera's down axis, so this is a heading error the camera itself makes; OpenCV camera frame).

    A constant world-frame offset would vanish in the trajectory alignment; a camera-frame one does not: positions
    stay, every orientation is off by ``yaw_deg``. For sensitivity studies, and to prove that a regression gate
    catches a small systematic rotation error. ``agent``: the wrapped agent's ``"module:Class"``; the other keywords
    are its own. It receives ground truth exactly when the wrapped agent does.
    """

    def __init__(self, agent: str, yaw_deg: float = 1.0, **kwargs: Any) -> None:
        from scipy.spatial.transform import Rotation

        from sim_envs.agent import load_agent

        if not np.isfinite(yaw_deg):
            raise SimEnvError(f"yaw_deg must be a finite number, got {yaw_deg!r}")
        self.inner = load_agent(agent, **kwargs)
        self.uses_ground_truth = bool(getattr(self.inner, "uses_ground_truth", False))
        self.name = f"{getattr(self.inner, 'name', agent)}+yaw{yaw_deg:g}"
        self._bias = np.eye(4)
        self._bias[:3, :3] = Rotation.from_euler("y", float(yaw_deg), degrees=True).as_matrix()

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """The wrapped agent's reset."""
        self.inner.reset(intrinsics, image_size)

    def step(self, observation: dict[str, np.ndarray], info: dict[str, Any] | None = None) -> dict[str, Any]:
        """The wrapped agent's answer with the pose turned by the bias."""
        out = dict(self.inner.step(observation, info) if self.uses_ground_truth else self.inner.step(observation))
        out[T_WORLD_CAM] = np.asarray(out[T_WORLD_CAM], dtype=np.float64) @ self._bias
        return out

    def finish(self) -> AgentOutput:
        """The wrapped agent's key-frames and final trajectory (if it hands one back), their poses turned by the bias
        too (the driver puts a final trajectory in place of the per-step answers)."""
        out = self.inner.finish()
        keyframes = [replace(kf, T_world_cam=np.asarray(kf.T_world_cam, dtype=np.float64) @ self._bias)
                     for kf in out.keyframes]
        trajectory = out.trajectory
        if trajectory is not None:
            trajectory = replace(trajectory, T_world_cam=np.asarray(trajectory.T_world_cam, dtype=np.float64)
                                 @ self._bias)
        return replace(out, keyframes=keyframes, trajectory=trajectory)
