"""The shell every baseline agent shares: the agent contract of :mod:`sim_envs.agent` (``reset``, ``step``,
``finish``) around three hooks a baseline implements.

:class:`BaselineAgent` does, once for all baselines:

- ``reset(intrinsics, image_size)``: checks ``intrinsics`` ([fx, fy, cx, cy] pixels, finite, positive focal lengths)
  and ``image_size`` ((H, W), positive), keeps them as ``self._intrinsics`` ((4,) float64) and ``self._size``
  ((H, W) ints), empties the episode's record and calls the baseline's :meth:`~BaselineAgent._start`;
- ``step(observation[, info])``: refuses a step before ``reset`` and a frame whose size is not the episode's, reads
  the timestamp (seconds, float), calls :meth:`~BaselineAgent._track` for the pose and the tracked flag, records
  them (``self._timestamps``, ``self._poses``, ``self._tracked``) and answers ``{"T_world_cam": (4, 4),
  "tracked": 0|1}``;
- ``finish()``: refuses a finish before ``reset`` and returns the baseline's :meth:`~BaselineAgent._finish`, an
  ``AgentOutput``; :meth:`~BaselineAgent.episode_extras` gives the extras every baseline reports (frames stepped,
  share tracked: :mod:`slamcommon.agent_keys`).

A new baseline is one module with a subclass (``name``, ``uses_ground_truth`` and the three hooks) plus one
``[methods."NAME"]`` table in ``eval/methods.toml`` naming it ``"module:Class"`` (with ``warmup`` there when it has
numba kernels for :mod:`cnnslam.tools.warmup` to compile, and ``table1 = true`` when it is a column of the Table-1
suite). ``info`` (the env's ground truth) reaches ``_track`` only for a class with ``uses_ground_truth = True``: the
driver passes it to no other agent.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError
from slamcommon.agent_keys import FRAMES, T_WORLD_CAM, TRACKED, TRACKED_SHARE


def checked_intrinsics(intrinsics: Any) -> np.ndarray:
    """``intrinsics`` as (4,) float64 [fx, fy, cx, cy] pixels; :class:`CnnSlamError` unless four finite numbers with
    positive focal lengths."""
    k = np.asarray(intrinsics, dtype=np.float64).reshape(-1)
    if k.shape != (4,) or not np.isfinite(k).all() or k[0] <= 0 or k[1] <= 0:
        raise CnnSlamError(f"intrinsics must be [fx, fy, cx, cy] with positive focal lengths, got {intrinsics!r}")
    return k


def checked_image_size(image_size: Any) -> tuple[int, int]:
    """``image_size`` as (H, W) ints; :class:`CnnSlamError` unless two positive whole numbers."""
    try:
        h, w = (int(v) for v in image_size)
    except (TypeError, ValueError):
        raise CnnSlamError(f"image_size must be (H, W) pixels, got {image_size!r}") from None
    if h <= 0 or w <= 0:
        raise CnnSlamError(f"image_size must be (H, W) with positive sides, got {image_size!r}")
    return h, w


class BaselineAgent(ABC):
    """A ``sim_envs`` agent's shell (module docstring); subclasses implement :meth:`_start`, :meth:`_track` and
    :meth:`_finish` and set :attr:`name` (the run record's ``agent``) and :attr:`uses_ground_truth`."""

    name: str = "baseline"
    uses_ground_truth: bool = False

    def __init__(self) -> None:
        self._intrinsics = np.zeros(4)
        self._size: tuple[int, int] = (0, 0)
        self._started = False
        self._timestamps: list[float] = []
        self._poses: list[np.ndarray] = []
        self._tracked: list[bool] = []

    # ------------------------------------------------------------------------------------------------ the contract
    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """Start a new episode: ``intrinsics`` [fx, fy, cx, cy] pixels, ``image_size`` (H, W)."""
        self._started = False
        self._intrinsics, self._size = checked_intrinsics(intrinsics), checked_image_size(image_size)
        self._timestamps, self._poses, self._tracked = [], [], []
        self._start(self._intrinsics, self._size)
        self._started = True

    def step(self, observation: dict[str, np.ndarray], info: dict[str, Any] | None = None) -> dict[str, Any]:
        """Process one observation (``rgb`` (H, W, 3) uint8, ``timestamp`` (1,) seconds; ``info``: the env's ground
        truth, given to agents with ``uses_ground_truth`` only); answer ``{"T_world_cam": (4, 4), "tracked": 0|1}``."""
        if not self._started:
            raise CnnSlamError("call reset(intrinsics, image_size) before step()")
        shape = np.shape(observation["rgb"])[:2]
        if shape != self._size:
            raise CnnSlamError(f"frame of size {shape} but the agent was reset for {self._size}")
        stamp = float(np.asarray(observation["timestamp"]).reshape(-1)[0])
        T_world_cam, tracked = self._track(observation, stamp, info)
        self._timestamps.append(stamp)
        self._poses.append(T_world_cam)
        self._tracked.append(bool(tracked))
        return {T_WORLD_CAM: T_world_cam, TRACKED: int(tracked)}

    def finish(self) -> Any:
        """End the episode: the baseline's ``AgentOutput`` (:meth:`_finish`)."""
        if not self._started:
            raise CnnSlamError("finish() before reset()")
        return self._finish()

    def episode_extras(self) -> dict[str, Any]:
        """The extras every baseline reports (:mod:`slamcommon.agent_keys`): the frames stepped and their share
        tracked (0 for none)."""
        n = len(self._tracked)
        return {FRAMES: n, TRACKED_SHARE: float(np.mean(self._tracked)) if n else 0.0}

    # --------------------------------------------------------------------------------------- what a baseline does
    @abstractmethod
    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """Build the episode's state for the checked ``intrinsics`` ((4,) float64, also ``self._intrinsics``) and
        ``image_size`` ((H, W) ints, also ``self._size``); may raise :class:`CnnSlamError` for a size it cannot take
        (the episode then does not start)."""

    @abstractmethod
    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        """One frame of the episode (its size checked, ``timestamp`` in seconds): (T_world_cam (4, 4) float64, the
        agent's current camera-to-world estimate; whether it tracked the frame)."""

    @abstractmethod
    def _finish(self) -> Any:
        """The episode's ``AgentOutput`` (``sim_envs.agent``): key-frames, extras, optionally a model or a final
        trajectory."""
