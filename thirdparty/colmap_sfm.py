"""COLMAP (Schoenberger and Frahm, CVPR 2016) incremental structure from motion as a benchmark method:
``"thirdparty.colmap_sfm:ColmapAgent"``, the offline baseline of a monocular SLAM benchmark.

COLMAP is BSD-licensed and runs in process through pycolmap (``pip install -e '.[sfm]'``; in ``dev``). Importing
this module raises ImportError when pycolmap is missing (found with :func:`importlib.util.find_spec`), so the
benchmark skips the method with that reason.

Offline: at each step the agent stores the colour image (a PNG in a temporary folder) and answers the identity,
``tracked = 0``: it knows no pose until the end. At ``finish`` it runs COLMAP's pipeline on every stored image
(:func:`slamcommon.sfm.reconstruct`) and hands the poses back as a :class:`~sim_envs.agent.FinalTrajectory`, which
the judge scores instead of the per-step answers, as a user scores COLMAP's ``images.txt`` against ground truth.

Configuration (defaults): the camera is the episode's, held fixed (COLMAP ``PINHOLE``, no self-calibration: a SLAM
method gets the intrinsics too); SIFT features on the CPU (COLMAP's defaults: 8192 per image at most); sequential
matching, each image against its next ``overlap`` (10) images, no loop detection (it needs a vocabulary tree file);
incremental mapping with COLMAP's default options, ``threads`` 2, ``random_seed`` = the run's seed. When the mapper
makes several models (the sequence broke), the one with the most registered images is kept.

Answers: ``T_world_cam`` camera-to-world, OpenCV camera axes (COLMAP's camera frame is OpenCV's), in COLMAP's world
frame and units (no metric scale: a monocular method). A frame COLMAP did not register gets the pose of the
nearest registered frame in time, flagged not tracked (the trajectory stays whole, as a SLAM system holds its last
pose while lost). No registered image at all: every frame keeps the identity, not tracked, and ``extras["error"]``
says why. No key-frame depth (the trajectory metrics only); ``extras`` has the counts and COLMAP's figures.
"""

from __future__ import annotations

import importlib.util
import shutil
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from sim_envs.agent import AgentOutput, FinalTrajectory
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED
from slamcommon.config import Configurable, configure
from slamcommon.errors import ConfigError
from slamcommon.sfm import COLMAP_PIXEL_OFFSET, DEFAULT_OVERLAP, SfmError, SfmUnavailableError, model_poses, reconstruct

if importlib.util.find_spec("pycolmap") is None:
    raise ImportError("COLMAP needs the pycolmap package, not installed here: pip install -e '.[sfm]'")


def fill_unregistered(n_frames: int, registered: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses for every one of ``n_frames`` frames from the ``poses`` (k, 4, 4) of the ``registered`` (k,) frame
    indices (sorted): a registered frame keeps its own, any other takes the nearest registered frame's (the earlier
    one on a tie). Returns (poses (n, 4, 4), tracked (n,) bool: True where registered)."""
    registered = np.asarray(registered, dtype=np.int64)
    if registered.size == 0:
        raise SfmError("no registered frame to fill the others from")
    frames = np.arange(n_frames)
    right = np.clip(np.searchsorted(registered, frames), 0, registered.size - 1)
    left = np.clip(right - 1, 0, registered.size - 1)
    nearer_left = np.abs(frames - registered[left]) <= np.abs(registered[right] - frames)
    nearest = np.where(nearer_left, left, right)
    tracked = np.zeros(n_frames, dtype=bool)
    tracked[registered] = True
    return np.asarray(poses, dtype=np.float64)[nearest], tracked


@dataclass(frozen=True)
class ColmapConfig(Configurable):
    """COLMAP's settings as this method runs it (module docstring)."""

    # ours: sequential matching, each image against its next `overlap` images (COLMAP's default 10)
    overlap: int = DEFAULT_OVERLAP
    # ours: COLMAP's CPU threads (the 2-core machines the suites are sized for)
    threads: int = 2

    def __post_init__(self) -> None:
        if self.overlap < 1 or self.threads < 1:
            raise ConfigError(f"COLMAP: overlap and threads must be >= 1, got {self.overlap}, {self.threads}")


class ColmapAgent:
    """COLMAP's incremental SfM over the whole episode, run at ``finish`` (module docstring)."""

    name = "COLMAP"

    def __init__(self, seed: int = 0, overlap: int = DEFAULT_OVERLAP, threads: int = 2,
                 workdir: str | Path | None = None, config: ColmapConfig | Mapping[str, Any] | None = None) -> None:
        """``seed``: COLMAP's random seed; ``overlap``: sequential matching neighbours; ``threads``: COLMAP's CPU
        threads (both :class:`ColmapConfig`, ``config`` overrides them); ``workdir``: where the images and COLMAP's
        database go (default a temporary folder, removed at ``finish``; a given folder is kept)."""
        self.config = configure(ColmapConfig(overlap=int(overlap), threads=int(threads)), config)
        self.seed, self.overlap, self.threads = int(seed), self.config.overlap, self.config.threads
        self._workdir = None if workdir is None else Path(workdir)
        self._work: Path | None = None
        self._intrinsics = np.zeros(4)
        self._stamps: list[float] = []
        self._paths: list[Path] = []

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """A new episode: ``intrinsics`` [fx, fy, cx, cy] pixels (OpenCV), ``image_size`` (H, W)."""
        self._cleanup()
        self._intrinsics = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        self._work = self._workdir if self._workdir is not None else Path(tempfile.mkdtemp(prefix="cnnslam-colmap-"))
        (self._work / "frames").mkdir(parents=True, exist_ok=True)
        self._stamps, self._paths = [], []

    def step(self, observation: dict[str, np.ndarray]) -> dict[str, Any]:
        """Store the frame; answer the identity, not tracked (the poses come at ``finish``)."""
        if self._work is None:
            raise RuntimeError("COLMAP: step() before reset()")
        path = self._work / "frames" / f"{len(self._paths):06d}.png"
        cv2.imwrite(str(path), cv2.cvtColor(np.asarray(observation["rgb"]), cv2.COLOR_RGB2BGR))
        self._paths.append(path)
        self._stamps.append(float(np.asarray(observation["timestamp"]).reshape(-1)[0]))
        return {T_WORLD_CAM: np.eye(4), TRACKED: 0}

    def finish(self) -> AgentOutput:
        """Run COLMAP on the stored frames; the poses as a :class:`FinalTrajectory` (module docstring)."""
        n = len(self._paths)
        extras: dict[str, Any] = {"images": n, "registered": 0}
        if self._work is None or n == 0:
            return AgentOutput(extras=extras)
        t0 = time.perf_counter()
        fx, fy, cx, cy = self._intrinsics
        try:
            model = reconstruct(self._paths, self._work / "colmap", camera_model="PINHOLE", overlap=self.overlap,
                                threads=self.threads, seed=self.seed,
                                fixed_camera=(fx, fy, cx + COLMAP_PIXEL_OFFSET, cy + COLMAP_PIXEL_OFFSET))  # fmt: skip
            rows = model_poses(model)
            extras.update(points=int(model.num_points3D()),
                          reprojection_px=float(model.compute_mean_reprojection_error()))  # fmt: skip
        except SfmUnavailableError:
            raise  # COLMAP itself cannot run here: a failed run, not a method that registered nothing
        except SfmError as exc:
            rows = []
            extras["error"] = str(exc)
        extras["sfm_seconds"] = time.perf_counter() - t0
        extras["registered"] = len(rows)
        stamps = np.asarray(self._stamps, dtype=np.float64)
        self._cleanup()
        if not rows:
            return AgentOutput(extras=extras)
        poses, tracked = fill_unregistered(n, np.array([r[0] for r in rows]), np.stack([r[1] for r in rows]))
        return AgentOutput(trajectory=FinalTrajectory(stamps, poses, tracked), extras=extras)

    def _cleanup(self) -> None:
        """Remove the temporary folder (never a ``workdir`` the user gave)."""
        if self._work is not None and self._workdir is None:
            shutil.rmtree(self._work, ignore_errors=True)
        self._work = None if self._workdir is None else self._work
