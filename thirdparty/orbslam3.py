"""ORB-SLAM3 (Campos et al. 2021), monocular, as a ``sim_envs`` agent: ``"thirdparty.orbslam3:OrbSlam3Agent"``.

ORB-SLAM3 is GPL-3.0 (through the ``pyorbslam3`` wheel, ``pip install -e '.[orbslam3]'``). This module NEVER imports
it: each episode starts ``thirdparty/orbslam3_driver.py`` as a separate program (the same Python) and exchanges only
data with it over pipes (RGB images in, poses and tracking states out). Importing this module raises ImportError
when ``pyorbslam3`` is not installed (found with :func:`importlib.util.find_spec`, without importing it), so the
benchmark skips the method with that reason.

Configuration (written as an ORB-SLAM3 settings file per episode, :func:`settings_yaml`): the episode's pinhole
intrinsics and the lens distortion of the images it is given (``takes_distortion``: the driver hands it to
``reset``; ``Camera.k1 k2 p1 p2 k3``, from which ORB-SLAM3 undistorts its key-points itself, as its TUM examples do
on the raw 640x480 images; all zeros for images already undistorted or rendered as pinhole ones; the method table
gives it real folders at their own size, as recorded: ``input = "native"`` in ``eval/methods.toml``), 30 fps, RGB
order; ORB extractor 1000 features, scale factor 1.2, 8 levels, FAST thresholds 20 / 7 (ORB-SLAM3's TUM
settings); monocular, no viewer, local mapping
and loop closing in ORB-SLAM3's own threads (so runs are NOT deterministic: the ``seed`` keyword is recorded, and
changes nothing fed to ORB-SLAM3). The vocabulary is ours (:mod:`thirdparty.orb_vocabulary`, default
``thirdparty/vocabulary/orbvoc_train_k8l3.txt``: 584 nodes, built from simulated training frames), not ORBvoc.txt.

Answers (the agent contract of :mod:`sim_envs.agent`): ``T_world_cam`` is ORB-SLAM3's ``Twc`` (camera-to-world,
OpenCV camera axes, the world = the first key-frame of ORB-SLAM3's current map, no metric scale), float64 with its
rotation re-orthonormalised. ``tracked = 1`` when ORB-SLAM3's state is OK. Otherwise ``tracked = 0`` and: while
RECENTLY_LOST, ORB-SLAM3's own motion-model pose; while NOT_INITIALIZED or LOST, the last pose answered (the
identity before the first initialisation). After a loss ORB-SLAM3 starts a new map with its own world frame and
scale; ``extras["maps"]`` counts the maps. No key-frame depth is returned (the method has the trajectory metrics
only); ``extras["keyframes"]`` is the number of key-frames ORB-SLAM3 kept.
"""

from __future__ import annotations

import importlib.util
import json
import select
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slamcommon.agent_keys import FRAMES, T_WORLD_CAM, TRACKED, TRACKED_SHARE
from slamcommon.config import Configurable, configure
from slamcommon.errors import ConfigError
from thirdparty.orb_vocabulary import DEFAULT_VOCABULARY

if importlib.util.find_spec("pyorbslam3") is None:
    raise ImportError("ORB-SLAM3 needs the pyorbslam3 package (GPL-3.0), not installed here: "
                      "pip install -e '.[orbslam3]'")

DRIVER = Path(__file__).with_name("orbslam3_driver.py")
TRACKED_STATES = ("OK", "OK_KLT")


def settings_yaml(intrinsics: np.ndarray, image_size: tuple[int, int], fps: float = 30.0, n_features: int = 1000,
                  scale_factor: float = 1.2, n_levels: int = 8, ini_th_fast: int = 20, min_th_fast: int = 7,
                  distortion: np.ndarray | None = None) -> str:
    """An ORB-SLAM3 monocular settings file (OpenCV YAML, the ``Camera.*`` format ORB-SLAM3 reads when the file has
    no ``File.version``) for a pinhole camera: ``intrinsics`` [fx, fy, cx, cy] pixels (OpenCV convention),
    ``image_size`` (H, W), RGB images, ``distortion`` (5,) ``k1 k2 p1 p2 k3`` of OpenCV's model (None or zeros:
    none), which ORB-SLAM3 applies to its key-points (``cv::undistortPoints``)."""
    fx, fy, cx, cy = (float(v) for v in np.asarray(intrinsics, dtype=np.float64).reshape(4))
    h, w = (int(v) for v in image_size)
    coeffs = np.zeros(5) if distortion is None else np.asarray(distortion, dtype=np.float64).reshape(-1)
    if coeffs.shape != (5,) or not np.isfinite(coeffs).all():
        raise ConfigError(f"ORB-SLAM3: distortion must be 5 finite coefficients k1 k2 p1 p2 k3, got {coeffs.tolist()}")
    k1, k2, p1, p2, k3 = (_yaml_float(v) for v in coeffs)
    return f"""%YAML:1.0
Camera.type: "PinHole"
Camera.fx: {fx:.6f}
Camera.fy: {fy:.6f}
Camera.cx: {cx:.6f}
Camera.cy: {cy:.6f}
Camera.k1: {k1}
Camera.k2: {k2}
Camera.p1: {p1}
Camera.p2: {p2}
Camera.k3: {k3}
Camera.width: {w}
Camera.height: {h}
Camera.fps: {float(fps):.1f}
Camera.RGB: 1
ORBextractor.nFeatures: {int(n_features)}
ORBextractor.scaleFactor: {float(scale_factor):.4f}
ORBextractor.nLevels: {int(n_levels)}
ORBextractor.iniThFAST: {int(ini_th_fast)}
ORBextractor.minThFAST: {int(min_th_fast)}
Viewer.KeyFrameSize: 0.05
Viewer.KeyFrameLineWidth: 1.0
Viewer.GraphLineWidth: 0.9
Viewer.PointSize: 2.0
Viewer.CameraSize: 0.08
Viewer.CameraLineWidth: 3.0
Viewer.ViewpointX: 0.0
Viewer.ViewpointY: -0.7
Viewer.ViewpointZ: -1.8
Viewer.ViewpointF: 500.0
"""


def _yaml_float(value: float) -> str:
    """A float as the settings file writes it: ``0.0`` for zero, else the shortest text that reads back the same
    (``repr``), never an integer (OpenCV's YAML reads ``1`` as an int, which ORB-SLAM3's ``real()`` rejects)."""
    text = repr(float(value))
    return "0.0" if float(value) == 0.0 else text


def _rigid(values: list[float]) -> np.ndarray:
    """A (4, 4) float64 pose from 16 row-major values, its rotation made exactly orthonormal (ORB-SLAM3 keeps
    float32 poses)."""
    T = np.asarray(values, dtype=np.float64).reshape(4, 4).copy()
    u, _, vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    T[3] = (0.0, 0.0, 0.0, 1.0)
    return T


@dataclass(frozen=True)
class OrbSlam3Config(Configurable):
    """ORB-SLAM3's settings as this method runs it (module docstring; ORB-SLAM3's own names in its settings file)."""

    # ours: a DBoW2 text vocabulary; empty = ours, built from simulated training frames (thirdparty/vocabulary/)
    vocabulary: str = ""
    # ORB-SLAM3's TUM monocular examples: ORBextractor.nFeatures, scaleFactor, nLevels, iniThFAST, minThFAST
    n_features: int = 1000
    scale_factor: float = 1.2
    n_levels: int = 8
    ini_th_fast: int = 20
    min_th_fast: int = 7
    # the camera rate ORB-SLAM3 is told (Camera.fps; the sequences' 30 Hz)
    fps: float = 30.0
    # ours: how long to wait for one answer of the ORB-SLAM3 program (seconds)
    timeout_s: float = 120.0
    # ours: after each frame, wait up to this long (seconds) until ORB-SLAM3's mapping threads are idle (0: no wait):
    # the time between frames its TUM example gives them (frames fed at the camera's rate, on a machine that keeps
    # up), which a loaded machine fed as fast as tracking answers does not (orbslam3_driver.settle)
    settle_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("n_features", "n_levels", "ini_th_fast", "min_th_fast"):
            if getattr(self, name) < 1:
                raise ConfigError(f"ORB-SLAM3: {name} must be >= 1, got {getattr(self, name)}")
        if not (self.settle_s >= 0 and self.settle_s < self.timeout_s):
            raise ConfigError(f"ORB-SLAM3: settle_s must be >= 0 and below timeout_s ({self.timeout_s}), got "
                              f"{self.settle_s}")
        if not (self.scale_factor > 1 and self.fps > 0 and self.timeout_s > 0):
            raise ConfigError(f"ORB-SLAM3: scale_factor must be > 1, fps and timeout_s > 0, got {self.scale_factor}, "
                              f"{self.fps}, {self.timeout_s}")


class OrbSlam3Agent:
    """ORB-SLAM3 monocular, out of process (see the module docstring for the configuration and the answers).

    vocabulary: a DBoW2 text vocabulary (default: ours); n_features, scale_factor, n_levels, ini_th_fast,
    min_th_fast: ORB extractor settings; fps: the camera rate ORB-SLAM3 is told; seed: recorded only (ORB-SLAM3's
    threads make its runs differ anyway); timeout_s: how long to wait for one answer of the ORB-SLAM3 program;
    settle_s: after each frame, the longest wait for ORB-SLAM3's mapping threads to be idle (0: none).
    """

    uses_ground_truth = False
    takes_distortion = True  # reset(..., distortion=k1 k2 p1 p2 k3): ORB-SLAM3 undistorts its key-points itself
    name = "orb_slam3"

    def __init__(self, vocabulary: str | None = None, n_features: int = 1000, scale_factor: float = 1.2,
                 n_levels: int = 8, ini_th_fast: int = 20, min_th_fast: int = 7, fps: float = 30.0, seed: int = 0,
                 timeout_s: float = 120.0, settle_s: float = 0.0,
                 config: OrbSlam3Config | Mapping[str, Any] | None = None) -> None:
        defaults = OrbSlam3Config(vocabulary or "", int(n_features), float(scale_factor), int(n_levels),
                                  int(ini_th_fast), int(min_th_fast), float(fps), float(timeout_s), float(settle_s))
        self.config = configure(defaults, config)  # the keywords, with `config` overrides on top
        self.vocabulary = Path(self.config.vocabulary) if self.config.vocabulary else DEFAULT_VOCABULARY
        if not self.vocabulary.is_file():
            raise FileNotFoundError(f"ORB vocabulary {self.vocabulary} not found "
                                    "(build one with python -m thirdparty.orb_vocabulary)")
        self.options = {name: getattr(self.config, name) for name in
                        ("n_features", "scale_factor", "n_levels", "ini_th_fast", "min_th_fast", "fps")}
        self.seed = int(seed)
        self.timeout_s = self.config.timeout_s
        self.settle_s = self.config.settle_s
        self._proc: subprocess.Popen[bytes] | None = None
        self._dir: tempfile.TemporaryDirectory[str] | None = None
        self._log: Any = None
        self._clear()

    def _clear(self) -> None:
        self._pose = np.eye(4)
        self._tracked: list[bool] = []
        self._states: dict[str, int] = {}
        self._seconds: list[float] = []
        self._settle_seconds = 0.0
        self._maps = 0
        self._last_state: str | None = None
        self._init_frame: int | None = None
        self._load_seconds = 0.0
        self._camera: dict[str, Any] = {}

    # -- the ORB-SLAM3 program ---------------------------------------------------------------------------------------
    def _request(self, header: dict[str, Any], payload: bytes = b"") -> dict[str, Any]:
        proc = self._proc
        if proc is None or proc.stdin is None or proc.stdout is None:
            raise RuntimeError("ORB-SLAM3 is not running: call reset(intrinsics, image_size) first")
        if payload:
            header = {**header, "nbytes": len(payload)}
        try:
            proc.stdin.write(json.dumps(header).encode() + b"\n" + payload)
            proc.stdin.flush()
            ready, _, _ = select.select([proc.stdout], [], [], self.timeout_s)
            line = proc.stdout.readline() if ready else b""
        except (BrokenPipeError, OSError):
            line = b""
        if not line:
            code = proc.poll()  # before the kill below, whose -9 would hide a hang
            why = f"no answer in {self.timeout_s:g} s" if code is None else f"exit code {code}"
            self._stop(kill=True)
            raise RuntimeError(f"the ORB-SLAM3 program gave no answer to {header['cmd']!r} ({why}); "
                               f"its last output: {self._log_tail()}")
        answer = json.loads(line)
        if "error" in answer:
            raise RuntimeError(f"ORB-SLAM3 failed on {header['cmd']!r}: {answer['error']}; its output: "
                               f"{self._log_tail()}")
        return answer

    def _log_tail(self, n: int = 600) -> str:
        if self._dir is None:
            return ""
        path = Path(self._dir.name) / "orbslam3.log"
        return path.read_text(errors="replace")[-n:].strip() if path.is_file() else ""

    def _stop(self, kill: bool = False) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:
            if proc.stdin is not None:
                try:
                    proc.stdin.close()
                except OSError:
                    pass
            try:
                if kill:
                    proc.kill()
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()
        if self._log is not None:
            self._log.close()
            self._log = None

    def close(self) -> None:
        """Stop the ORB-SLAM3 program and remove its files."""
        self._stop(kill=True)
        if self._dir is not None:
            self._dir.cleanup()
            self._dir = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    # -- the agent contract ------------------------------------------------------------------------------------------
    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int], distortion: np.ndarray | None = None) -> None:
        """A new episode: a fresh ORB-SLAM3 program for ``intrinsics`` [fx, fy, cx, cy] (pixels), ``image_size``
        (H, W) and the images' lens ``distortion`` (5,) k1 k2 p1 p2 k3 (None: pinhole images)."""
        self.close()
        self._clear()
        coeffs = np.zeros(5) if distortion is None else np.asarray(distortion, dtype=np.float64).reshape(-1)
        text = settings_yaml(intrinsics, image_size, distortion=coeffs, **self.options)  # checks the coefficients
        self._camera = {"image_size": [int(v) for v in image_size],
                        "intrinsics": [float(v) for v in np.asarray(intrinsics, dtype=np.float64).reshape(4)],
                        "distortion": [float(v) for v in coeffs]}
        self._dir = tempfile.TemporaryDirectory(prefix="orbslam3_")
        work = Path(self._dir.name)
        settings = work / "settings.yaml"
        settings.write_text(text)
        self._log = open(work / "orbslam3.log", "wb")  # noqa: SIM115 - closed in _stop
        self._proc = subprocess.Popen([sys.executable, str(DRIVER)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      stderr=self._log, cwd=work)
        answer = self._request({"cmd": "init", "vocabulary": str(self.vocabulary.resolve()),
                                "settings": str(settings)})
        self._load_seconds = float(answer["seconds"])

    def step(self, observation: dict[str, np.ndarray]) -> dict[str, Any]:
        """Track one RGB frame; ``{"T_world_cam": (4, 4) float64, "tracked": 0 | 1}`` (module docstring)."""
        rgb = np.ascontiguousarray(observation["rgb"], dtype=np.uint8)
        h, w = rgb.shape[:2]
        stamp = float(np.asarray(observation["timestamp"]).reshape(-1)[0])
        header = {"cmd": "track", "timestamp": stamp, "height": h, "width": w}
        if self.settle_s > 0:
            header["settle_s"] = self.settle_s
        ans = self._request(header, rgb.tobytes())
        self._settle_seconds += float(ans.get("settle_seconds") or 0.0)
        state = str(ans["state"])
        tracked = state in TRACKED_STATES and ans["pose_wc"] is not None
        if ans["pose_wc"] is not None and (tracked or state == "RECENTLY_LOST"):
            self._pose = _rigid(ans["pose_wc"])
        if tracked and self._last_state in (None, "NO_IMAGES_YET", "NOT_INITIALIZED"):  # a map (re)initialised
            self._maps += 1
            if self._init_frame is None:
                self._init_frame = len(self._tracked)
        self._last_state = state
        self._states[state] = self._states.get(state, 0) + 1
        self._tracked.append(tracked)
        self._seconds.append(float(ans["seconds"]))
        return {T_WORLD_CAM: self._pose.copy(), TRACKED: int(tracked)}

    def finish(self) -> Any:
        """Stop ORB-SLAM3; an ``AgentOutput`` without key-frame depth, with ORB-SLAM3's counts in ``extras``."""
        from sim_envs.agent import AgentOutput

        keyframes = 0
        if self._proc is not None and self._dir is not None:
            path = Path(self._dir.name) / "keyframes.tum"
            self._request({"cmd": "finish", "keyframes": str(path)})
            if path.is_file():
                keyframes = sum(1 for line in path.read_text().splitlines() if line.strip())
        self.close()
        n = len(self._tracked)
        secs = np.asarray(self._seconds)
        extras: dict[str, Any] = {
            FRAMES: n,
            TRACKED_SHARE: float(np.mean(self._tracked)) if n else 0.0,
            "states": dict(sorted(self._states.items())),
            "maps": self._maps,
            "init_frame": self._init_frame,
            "keyframes": keyframes,
            "vocabulary": self.vocabulary.name,
            "vocabulary_bytes": self.vocabulary.stat().st_size,
            "camera": dict(self._camera),  # what ORB-SLAM3 was told: (H, W), fx fy cx cy, k1 k2 p1 p2 k3
            "vocabulary_load_seconds": self._load_seconds,
            "options": dict(self.options),
            "mean_track_seconds": float(secs.mean()) if n else 0.0,
            "track_fps": float(n / secs.sum()) if n and secs.sum() > 0 else 0.0,
            "seed": self.seed,
            "settle_s": self.settle_s,
            "settle_seconds": self._settle_seconds,  # waited for the mapping threads, in the steps' time
        }
        return AgentOutput(keyframes=[], extras=extras)
