"""The agent contract: what a SLAM system plugged into the environment implements, and what it hands back.

An agent is any object with ``reset``, ``step`` and ``finish`` (duck-typed; it need not import this module):

- ``reset(intrinsics, image_size)``: a new episode; ``intrinsics`` is ``[fx, fy, cx, cy]`` (float64, pixels, OpenCV
  convention), ``image_size`` is ``(H, W)``. An agent whose class sets ``takes_distortion = True`` (one that
  undistorts what it sees itself, as ORB-SLAM3 undistorts its key-points) is called ``reset(intrinsics, image_size,
  distortion=coeffs)`` instead: ``coeffs`` the (5,) float64 ``k1 k2 p1 p2 k3`` (OpenCV model) of the images it will
  see, all zeros for pinhole ones (:func:`takes_distortion`). Every other agent is called as before.
- ``step(observation) -> action``: ``observation`` is the env's observation dict (``rgb`` (H, W, 3) uint8,
  ``timestamp`` (1,) float64 seconds, ``intrinsics`` (4,) float64). The action is a dict with ``T_world_cam``
  ((4, 4) float64, the agent's current camera-to-world estimate) and ``tracked`` (1 if tracking succeeded for this
  frame, 0 if the agent considers itself lost).
- ``finish() -> AgentOutput`` (or a dict with the same fields): key-frames with the agent's final depth maps and
  poses, for the depth metric, and optionally the agent's global 3D model (:class:`MapModel`, the paper's Sec. 3.5
  map with its fused labels), for the reconstruction and label metrics, and optionally its final trajectory
  (:class:`FinalTrajectory`): an offline method (structure from motion) or a system that revises its poses at the
  end hands back the poses it would write to a TUM file, and the judge scores those instead of the per-step answers.

Agents are named by ``"module:Class"`` strings and built with keyword arguments (:func:`load_agent`), so a user's
agent plugs in exactly like ours. An agent whose class sets ``uses_ground_truth = True`` (the oracle, scale
bootstrapping) also receives the env's ``info`` as ``step(observation, info)``; the driver records that it did.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from sim_envs.errors import SimEnvError


@dataclass(frozen=True)
class KeyframeDepth:
    """One key-frame as the agent finally holds it.

    timestamp: seconds (matches an observation's timestamp); depth: (H, W) float32 metres, 0 or NaN where the agent
    has no estimate; T_world_cam: (4, 4) float64 estimated pose; uncertainty: optional (H, W) float32 depth variance
    (m^2); labels: optional (H, W) uint8 semantic classes or (H, W, C) float class probabilities (float16 or float32;
    scored by their argmax).
    """

    timestamp: float
    depth: np.ndarray
    T_world_cam: np.ndarray
    uncertainty: np.ndarray | None = None
    labels: np.ndarray | None = None


@dataclass(frozen=True)
class MapModel:
    """The agent's global 3D model at the end of an episode, in the agent's world frame (the frame of its poses).

    points: (N, 3) float32 metres; labels: (N,) uint8 fused semantic classes (``sim_envs.frames.NO_LABEL`` = none)
    or None; normals: (N, 3) float32 unit or None; colours: (N, 3) uint8 RGB or None. The judge aligns the points
    with the same transform as the key-frame poses and scores accuracy, completeness and labels against the
    scene's surfaces.
    """

    points: np.ndarray
    labels: np.ndarray | None = None
    normals: np.ndarray | None = None
    colours: np.ndarray | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise SimEnvError(f"MapModel.points must be (N, 3) metres, got shape {pts.shape}")
        for name in ("labels", "normals", "colours"):
            value = getattr(self, name)
            if value is not None and len(value) != len(pts):
                raise SimEnvError(f"MapModel.{name} must have one row per point ({len(pts)}), got {len(value)}")

    def __len__(self) -> int:
        return int(np.asarray(self.points).shape[0])


@dataclass(frozen=True)
class FinalTrajectory:
    """An agent's final estimate of the episode's poses, handed back by ``finish()``: what an offline or globally
    optimised system writes as its trajectory file.

    timestamps: (M,) float64 seconds, each matching an observation's (within the driver's key-frame tolerance);
    T_world_cam: (M, 4, 4) float64 camera-to-world, OpenCV camera axes, the agent's world frame and scale;
    tracked: optional (M,) bool, False for a pose the agent only filled in (held or interpolated across frames it
    could not place); default all True. The driver puts these poses in place of the per-step answers of the frames
    they name, and those frames' tracked flags in place of theirs: a frame with no pose here is not tracked (it
    keeps its per-step answer, so the trajectory stays whole).
    """

    timestamps: np.ndarray
    T_world_cam: np.ndarray
    tracked: np.ndarray | None = None

    def __post_init__(self) -> None:
        stamps, T = np.asarray(self.timestamps), np.asarray(self.T_world_cam)
        if stamps.ndim != 1 or T.shape != (len(stamps), 4, 4):
            raise SimEnvError(f"FinalTrajectory needs timestamps (M,) and T_world_cam (M, 4, 4), got {stamps.shape} "
                              f"and {T.shape}")  # fmt: skip
        if not (np.isfinite(stamps).all() and np.isfinite(T).all()):
            raise SimEnvError("FinalTrajectory holds NaN or inf")
        if self.tracked is not None and np.asarray(self.tracked).shape != stamps.shape:
            raise SimEnvError(f"FinalTrajectory.tracked must be (M,) = {stamps.shape} bool, got "
                              f"{np.asarray(self.tracked).shape}")  # fmt: skip

    def __len__(self) -> int:
        return int(np.asarray(self.timestamps).shape[0])


@dataclass(frozen=True)
class AgentOutput:
    """What an agent hands back at the end of an episode. ``model``: its global 3D model, if it builds one;
    ``trajectory``: its final poses, if it revises them (:class:`FinalTrajectory`); ``extras``: free-form,
    JSON-serialisable diagnostics."""

    keyframes: list[KeyframeDepth] = field(default_factory=list)
    extras: dict[str, Any] = field(default_factory=dict)
    model: MapModel | None = None
    trajectory: FinalTrajectory | None = None


@runtime_checkable
class Agent(Protocol):
    """Structural type of an agent (see the module docstring)."""

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None: ...

    def step(self, observation: dict[str, np.ndarray]) -> dict[str, Any]: ...

    def finish(self) -> AgentOutput: ...


def takes_distortion(agent: Any) -> bool:
    """Whether ``agent`` declares (``takes_distortion = True``) that its ``reset`` takes the images' lens
    distortion as the keyword ``distortion`` (module docstring)."""
    return getattr(agent, "takes_distortion", False) is True


def load_agent(entry_point: str, **kwargs: Any) -> Agent:
    """Build an agent from a ``"module:Class"`` string (or ``"module:factory"``) with keyword arguments."""
    module_name, sep, attr = entry_point.partition(":")
    if not sep or not module_name or not attr:
        raise SimEnvError(f"agent entry point must look like 'package.module:Class', got {entry_point!r}")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise SimEnvError(f"cannot import the agent module {module_name!r} of {entry_point!r}: {exc}") from exc
    try:
        factory = getattr(module, attr)
    except AttributeError:
        raise SimEnvError(f"module {module_name!r} has no attribute {attr!r} (agent {entry_point!r})") from None
    agent = factory(**kwargs)
    missing = [m for m in ("reset", "step", "finish") if not callable(getattr(agent, m, None))]
    if missing:
        raise SimEnvError(f"agent {entry_point!r} lacks the method(s) {', '.join(missing)}; see sim_envs.agent")
    return agent
