"""Run an agent over one episode of a :class:`~sim_envs.env.SlamEnv` and hand back what the judge needs.

:func:`run_episode` resets the env, feeds every observation to the agent, checks each action, records the estimated
and ground-truth trajectories and the agent's own time per step, collects the agent's key-frames from ``finish()``,
and fetches the ground-truth frame of each key-frame from ``env.unwrapped.source`` after the episode. An agent that
hands back a final trajectory (:class:`~sim_envs.agent.FinalTrajectory`) has its poses put in place of the per-step
answers (:func:`apply_final_trajectory`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from sim_envs.agent import AgentOutput, FinalTrajectory, KeyframeDepth, MapModel, takes_distortion
from sim_envs.camera import Intrinsics
from sim_envs.env import delivered_distortion
from sim_envs.errors import SimEnvError
from sim_envs.frames import Frame
from sim_envs.source import FrameSource
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED

logger = logging.getLogger(__name__)

KEYFRAME_TIME_TOLERANCE: float = 1e-3  # seconds; a key-frame's timestamp must match an observation's this closely
RIGID_TOLERANCE: float = 1e-4  # max |R^T R - I| entry accepted for an action's rotation block (ours)


@dataclass(frozen=True)
class EpisodeResult:
    """One episode of one agent on one sequence.

    sequence: the frame source's name; env_id: the Gymnasium id when the env was made by id, else None; agent: the
    agent's name; intrinsics: the camera; frame_indices: (N,) int64 source frame of each step; timestamps: (N,)
    float64 seconds; T_world_cam_est: (N, 4, 4) float64 the agent's poses (its own world frame and scale);
    tracked: (N,) bool; T_world_cam_gt: (N, 4, 4) float64 ground truth; keyframes: the agent's key-frames from
    ``finish()``; keyframe_gt: the ground-truth :class:`Frame` at each key-frame's timestamp (same order);
    step_seconds: (N,) float64 wall-clock seconds spent in the agent's ``step`` (rendering excluded);
    uses_ground_truth: whether the agent received ground truth (``info``); extras: the agent's diagnostics plus
    the driver's (``finish_seconds``, ``unmatched_keyframes``); model: the agent's global 3D model, if it hands
    one back (:class:`~sim_envs.agent.MapModel`).
    """

    sequence: str
    env_id: str | None
    agent: str
    intrinsics: Intrinsics
    frame_indices: np.ndarray
    timestamps: np.ndarray
    T_world_cam_est: np.ndarray
    tracked: np.ndarray
    T_world_cam_gt: np.ndarray
    keyframes: list[KeyframeDepth]
    keyframe_gt: list[Frame]
    step_seconds: np.ndarray
    uses_ground_truth: bool
    extras: dict[str, Any] = field(default_factory=dict)
    model: MapModel | None = None

    @property
    def n_frames(self) -> int:
        """Number of steps (frames) in the episode."""
        return int(self.timestamps.shape[0])


def agent_name(agent: Any) -> str:
    """The agent's ``name`` attribute, else ``"module:Class"`` of its type."""
    name = getattr(agent, "name", None)
    if isinstance(name, str) and name:
        return name
    return f"{type(agent).__module__}:{type(agent).__qualname__}"


def run_episode(env: gym.Env, agent: Any, max_frames: int | None = None, progress: bool = True) -> EpisodeResult:
    """Run ``agent`` (see :mod:`sim_envs.agent`) over one episode of ``env`` (a :class:`SlamEnv`, wrapped or not).

    Stops at the end of the episode or after ``max_frames`` steps. An agent whose class sets
    ``uses_ground_truth = True`` gets ``step(observation, info)`` and the episode is reset with full ground truth
    (``gt_depth``, ``gt_labels``). Raises :class:`SimEnvError` naming the step when an action is malformed (not a
    dict with a finite rigid (4, 4) ``T_world_cam`` and a 0/1 ``tracked``). ``progress`` shows a tqdm bar.
    """
    base = env.unwrapped
    source: FrameSource | None = getattr(base, "source", None)
    if source is None:
        raise SimEnvError(f"run_episode needs a sim_envs SlamEnv (env.unwrapped.source), got {type(base).__name__}")
    if max_frames is not None and int(max_frames) < 1:
        raise SimEnvError(f"max_frames must be >= 1 or None, got {max_frames}")
    name = agent_name(agent)
    uses_gt = bool(getattr(agent, "uses_ground_truth", False))
    obs, info = env.reset(options={"ground_truth": "full"} if uses_gt else None)
    intrinsics, image_size = np.array(obs["intrinsics"], dtype=np.float64), tuple(obs["rgb"].shape[:2])
    if takes_distortion(agent):  # the images' lens distortion, for an agent that undistorts them itself
        agent.reset(intrinsics, image_size, distortion=delivered_distortion(source))
    else:
        agent.reset(intrinsics, image_size)

    total = int(getattr(base, "n_frames", len(source)))
    if max_frames is not None:
        total = min(total, int(max_frames))
    indices: list[int] = []
    stamps: list[float] = []
    est: list[np.ndarray] = []
    gt: list[np.ndarray] = []
    tracked: list[bool] = []
    seconds: list[float] = []
    with tqdm(total=total, desc=f"{name} on {source.name}", unit="frame", disable=not progress, leave=False) as bar:
        while True:
            step = len(est)
            t0 = time.perf_counter()
            action = agent.step(obs, info) if uses_gt else agent.step(obs)
            seconds.append(time.perf_counter() - t0)
            T, ok = _check_action(action, name, step, int(info["frame_index"]))
            indices.append(int(info["frame_index"]))
            stamps.append(float(obs["timestamp"][0]))
            est.append(T)
            gt.append(np.array(info["gt_T_world_cam"], dtype=np.float64))
            tracked.append(ok)
            bar.update(1)
            obs, _, terminated, truncated, info = env.step({T_WORLD_CAM: T, TRACKED: int(ok)})
            if terminated or truncated or len(est) >= total:
                break

    t0 = time.perf_counter()
    output = _agent_output(agent.finish(), name)
    extras = dict(output.extras)
    extras["finish_seconds"] = time.perf_counter() - t0
    keyframes, keyframe_gt, unmatched = _match_keyframes(output.keyframes, source, name)
    if unmatched:
        extras["unmatched_keyframes"] = unmatched
    est_poses, tracked_flags = np.stack(est), np.asarray(tracked, dtype=bool)
    if output.trajectory is not None:
        est_poses, tracked_flags, matched, unmatched_poses = apply_final_trajectory(
            output.trajectory, np.asarray(stamps, dtype=np.float64), est_poses, name)  # fmt: skip
        extras["final_trajectory"] = {"poses": len(output.trajectory), "frames_matched": matched}
        if unmatched_poses:
            extras["final_trajectory"]["unmatched_timestamps"] = unmatched_poses
    spec = getattr(env, "spec", None)
    return EpisodeResult(
        sequence=source.name,
        env_id=None if spec is None else spec.id,
        agent=name,
        intrinsics=source.intrinsics,
        frame_indices=np.asarray(indices, dtype=np.int64),
        timestamps=np.asarray(stamps, dtype=np.float64),
        T_world_cam_est=est_poses,
        tracked=tracked_flags,
        T_world_cam_gt=np.stack(gt),
        keyframes=keyframes,
        keyframe_gt=keyframe_gt,
        step_seconds=np.asarray(seconds, dtype=np.float64),
        uses_ground_truth=uses_gt,
        extras=extras,
        model=output.model,
    )


def apply_final_trajectory(trajectory: FinalTrajectory, timestamps: np.ndarray, poses: np.ndarray,
                           agent: str) -> tuple[np.ndarray, np.ndarray, int, list[float]]:
    """An episode's poses and tracked flags once the agent's final trajectory replaces its per-step answers.

    ``timestamps`` (N,) seconds and ``poses`` (N, 4, 4) are the episode's steps. Each pose of ``trajectory`` goes
    to the step whose timestamp it matches (:func:`match_timestamp`) with the trajectory's tracked flag (default
    True); the other steps keep their per-step pose and are not tracked. Each pose is checked as an action is
    (finite, rigid).
    Returns (poses, tracked, steps matched, timestamps of the trajectory that match no step).
    """
    out = np.array(poses, dtype=np.float64, copy=True)
    tracked = np.zeros(len(out), dtype=bool)
    unmatched: list[float] = []
    stamps = np.asarray(trajectory.timestamps, dtype=np.float64)
    flags = np.ones(len(stamps), dtype=bool) if trajectory.tracked is None else np.asarray(trajectory.tracked, bool)
    matched = 0
    for k, (t, T) in enumerate(zip(stamps, np.asarray(trajectory.T_world_cam), strict=True)):
        i = match_timestamp(timestamps, float(t))
        if i is None:
            unmatched.append(float(t))
            continue
        out[i], _ = _check_action({T_WORLD_CAM: T}, agent, i, i)  # named by the step it replaces
        tracked[i] = bool(flags[k])
        matched += 1
    return out, tracked, matched, unmatched


def _check_action(action: Any, agent: str, step: int, frame: int) -> tuple[np.ndarray, bool]:
    """(pose (4, 4) float64, tracked) of an action, or :class:`SimEnvError` saying what is wrong and where."""
    where = f"agent {agent!r}, step {step} (frame {frame})"
    if not isinstance(action, dict) or T_WORLD_CAM not in action:
        raise SimEnvError(
            f"{where}: step() must return a dict with 'T_world_cam' ((4, 4) float64 camera-to-world) and 'tracked' "
            f"(0 or 1), got {type(action).__name__}"
            + (f" with keys {sorted(action)}" if isinstance(action, dict) else "")
        )
    try:
        T = np.array(action[T_WORLD_CAM], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SimEnvError(f"{where}: T_world_cam is not numeric: {exc}") from exc
    if T.shape != (4, 4):
        raise SimEnvError(f"{where}: T_world_cam must have shape (4, 4), got {T.shape}")
    if not np.isfinite(T).all():
        raise SimEnvError(f"{where}: T_world_cam holds NaN or inf")
    R = T[:3, :3]
    ortho = float(np.abs(R.T @ R - np.eye(3)).max())
    if ortho > RIGID_TOLERANCE or np.linalg.det(R) <= 0:
        raise SimEnvError(
            f"{where}: T_world_cam is not a rigid transform (|R^T R - I| = {ortho:.2e}, det R = "
            f"{np.linalg.det(R):.4f}); the rotation block must be orthonormal with det +1"
        )
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0]):
        raise SimEnvError(f"{where}: the last row of T_world_cam must be [0, 0, 0, 1], got {T[3].tolist()}")
    tracked = action.get(TRACKED, 1)
    try:
        tracked_int = int(np.asarray(tracked).item())
    except (TypeError, ValueError):
        tracked_int = -1
    if tracked_int not in (0, 1):
        raise SimEnvError(f"{where}: 'tracked' must be 0 or 1 (or a bool), got {tracked!r}")
    return T, bool(tracked_int)


def _from_fields(value: Any, cls: type, key: str, agent: str) -> Any:
    """``value`` built as ``cls`` when finish() gave it as a dict of the class's fields; anything else as it is."""
    if not isinstance(value, dict):
        return value
    try:
        return cls(**value)
    except TypeError as exc:
        raise SimEnvError(f"agent {agent!r}: {key!r} is not a valid {cls.__name__}: {exc}") from exc


def _agent_output(output: Any, agent: str) -> AgentOutput:
    """``finish()``'s result as an :class:`AgentOutput` (a dict with ``keyframes`` / ``extras`` / ``model`` is
    accepted; so are key-frames given as dicts of :class:`KeyframeDepth` fields and a model as a dict of
    :class:`MapModel` fields)."""
    if isinstance(output, dict):
        unknown = sorted(set(output) - {"keyframes", "extras", "model", "trajectory"})
        if unknown:
            raise SimEnvError(f"agent {agent!r}: finish() returned unknown key(s) {unknown}; valid: keyframes, extras, "
                              "model, trajectory")
        output = AgentOutput(keyframes=list(output.get("keyframes", [])), extras=dict(output.get("extras", {})),
                             model=_from_fields(output.get("model"), MapModel, "model", agent),
                             trajectory=_from_fields(output.get("trajectory"), FinalTrajectory, "trajectory", agent))
    if not isinstance(output, AgentOutput):
        got = type(output).__name__
        raise SimEnvError(f"agent {agent!r}: finish() must return an AgentOutput or a dict, got {got}")
    keyframes = []
    for i, kf in enumerate(output.keyframes):
        if isinstance(kf, dict):
            try:
                kf = KeyframeDepth(**kf)
            except TypeError as exc:
                raise SimEnvError(f"agent {agent!r}: key-frame {i} is not a valid KeyframeDepth: {exc}") from exc
        if not isinstance(kf, KeyframeDepth):
            raise SimEnvError(f"agent {agent!r}: key-frame {i} must be a KeyframeDepth, got {type(kf).__name__}")
        depth, T = np.asarray(kf.depth), np.asarray(kf.T_world_cam)
        if depth.ndim != 2 or T.shape != (4, 4):
            raise SimEnvError(
                f"agent {agent!r}: key-frame {i} (t={kf.timestamp}) needs depth (H, W) and T_world_cam (4, 4), got "
                f"{depth.shape} and {T.shape}"
            )
        keyframes.append(kf)
    if output.model is not None and not isinstance(output.model, MapModel):
        raise SimEnvError(f"agent {agent!r}: 'model' must be a MapModel (points, labels, normals, colours), got "
                          f"{type(output.model).__name__}")
    if output.trajectory is not None and not isinstance(output.trajectory, FinalTrajectory):
        raise SimEnvError(f"agent {agent!r}: 'trajectory' must be a FinalTrajectory (timestamps, T_world_cam), got "
                          f"{type(output.trajectory).__name__}")
    return AgentOutput(keyframes=keyframes, extras=dict(output.extras), model=output.model,
                       trajectory=output.trajectory)


def match_timestamp(stamps: np.ndarray, t: float, tolerance: float = KEYFRAME_TIME_TOLERANCE) -> int | None:
    """The index of the timestamp of ``stamps`` (seconds) nearest to ``t``, or None when none lies within
    ``tolerance`` seconds: how a key-frame (or any estimate named by its time) finds its frame, everywhere."""
    stamps = np.asarray(stamps, dtype=np.float64)
    if stamps.size == 0:
        return None
    i = int(np.argmin(np.abs(stamps - float(t))))
    return i if abs(stamps[i] - float(t)) <= tolerance else None


def _match_keyframes(
    keyframes: list[KeyframeDepth], source: FrameSource, agent: str
) -> tuple[list[KeyframeDepth], list[Frame], list[float]]:
    """Key-frames that match a source frame (within :data:`KEYFRAME_TIME_TOLERANCE`), their ground-truth frames, and
    the timestamps of those that match none (dropped with a warning, so the rest of the episode is kept)."""
    stamps = np.asarray(source.timestamps, dtype=np.float64)
    kept: list[KeyframeDepth] = []
    frames: list[Frame] = []
    unmatched: list[float] = []
    cache: dict[int, Frame] = {}
    for kf in keyframes:
        i = match_timestamp(stamps, float(kf.timestamp))
        if i is None:
            unmatched.append(float(kf.timestamp))
            continue
        if i not in cache:
            cache[i] = source.frame(i)
        kept.append(kf)
        frames.append(cache[i])
    if unmatched:
        logger.warning(
            "agent %r: %d key-frame(s) match no frame of %r within %.0e s and were dropped: %s",
            agent,
            len(unmatched),
            source.name,
            KEYFRAME_TIME_TOLERANCE,
            unmatched[:5],
        )
    return kept, frames, unmatched
