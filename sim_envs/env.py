"""Gymnasium environments in which a monocular SLAM system is the agent: it sees images, it answers with its pose.

:class:`SlamEnv` replays a :class:`~sim_envs.source.FrameSource` (a named simulated sequence, any spec, or a recorded
folder); :class:`SceneEnv` builds the source from scene and trajectory arguments; :class:`ReplayEnv` replays a
source or an RGB-D folder (TUM, ICL-NUIM, 7-Scenes, RGB-only). Registered ids are listed in :mod:`sim_envs`
(``sim_envs/Scene-v0``, ``sim_envs/Replay-v0`` and ``sim_envs/<sequence>-v0``).
"""

from __future__ import annotations

import os
from typing import Any, Literal, get_args

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim_envs.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH, DISTORTION_NAMES
from sim_envs.errors import SimEnvError
from sim_envs.frames import Frame
from sim_envs.sequences import TEST_SEED_LIMIT, TRAIN_SEED_BASE, SequenceSpec, get_sequence
from sim_envs.source import FrameSource
from sim_envs.sources.simsource import RENDERER_BACKENDS, SimulatedSequence
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED

GroundTruth = Literal["pose", "full"]
GROUND_TRUTH_MODES: tuple[str, ...] = get_args(GroundTruth)


def relative_translation_error(
    T_world_prev_est: np.ndarray, T_world_cur_est: np.ndarray, T_world_prev_gt: np.ndarray, T_world_cur_gt: np.ndarray
) -> float:
    """Translational relative-pose error of one motion, metres (TUM RPE with delta = 1 frame).

    ``E = (Q_prev^-1 Q_cur)^-1 (P_prev^-1 P_cur)`` with P the estimate and Q the ground truth, all (4, 4) float64
    camera-to-world; returns ``|| translation(E) ||``. It compares motions, so it needs no alignment of the estimate's
    world frame to the ground truth's. Inverses of the poses use the rigid form ``[R^T, -R^T t]`` so that a
    malformed estimate still gives a finite number.
    """
    R_p = T_world_prev_est[:3, :3]
    t_rel_est = R_p.T @ (T_world_cur_est[:3, 3] - T_world_prev_est[:3, 3])
    R_q = T_world_prev_gt[:3, :3]
    t_rel_gt = R_q.T @ (T_world_cur_gt[:3, 3] - T_world_prev_gt[:3, 3])
    # translation(E) = R_rel_gt^T (t_rel_est - t_rel_gt); R_rel_gt is a rotation, so the norm is that of the difference
    return float(np.linalg.norm(t_rel_est - t_rel_gt))


class SlamEnv(gym.Env[dict[str, np.ndarray], dict[str, Any]]):
    """A monocular camera moving through a simulated (or recorded) scene; the agent is a SLAM system.

    ## Description

    Each step shows the agent the next RGB image of a frame source (a rendered, fully seeded sequence or a
    recorded RGB-D folder) and asks for the agent's estimate of the camera pose of the image it has just seen. The
    agent never sees depth, labels or ground-truth poses: those go to ``info`` for the evaluation side (the judge
    and agents that declare ``uses_ground_truth``). The frame source stays available as ``env.unwrapped.source`` so
    that ground-truth frames can be fetched after an episode (e.g. at the agent's key-frame timestamps).

    ## Action Space

    A ``Dict``:

    | Key           | Space                           | Meaning                                              |
    |---------------|---------------------------------|------------------------------------------------------|
    | "T_world_cam" | Box(-inf, inf, (4, 4), float64) | camera-to-world pose estimate of the image just seen |
    | "tracked"     | Discrete(2)                     | 1 if the agent tracked this frame, 0 if it is lost   |

    Poses use OpenCV camera axes (x right, y down, z forward), metres, in the agent's own world frame (any origin,
    and any scale for a monocular agent). Rigidity is not enforced by the environment (the driver checks it).

    ## Observation Space

    A ``Dict``; H x W is the camera's image size (default 320 x 240):

    | Key          | Space                            | Meaning                                                      |
    |--------------|----------------------------------|--------------------------------------------------------------|
    | "rgb"        | Box(0, 255, (H, W, 3), uint8)    | the colour image                                             |
    | "timestamp"  | Box(0, inf, (1,), float64)       | capture time of the image, seconds                           |
    | "intrinsics" | Box(-inf, inf, (4,), float64)    | ``[fx, fy, cx, cy]`` pixels, OpenCV convention (constant)    |

    ## Rewards

    Minus the translational relative-pose error of the agent's last motion, in metres: after the actions for
    frames k-1 and k, ``reward = -|| trans((Q_{k-1}^-1 Q_k)^-1 (P_{k-1}^-1 P_k)) ||`` with P the agent's poses and Q
    the ground truth (TUM RPE with a one-frame delta). It compares motions, so it needs no alignment; a monocular
    agent whose scale is off is penalised by the scale error of its motion. The first step's reward is 0. The
    reward is a per-step diagnostic; the benchmark's metrics (ATE, RPE, correct depth) are computed by ``eval``.

    The lens distortion of the delivered images is ``env.unwrapped.distortion`` ((5,) float64 ``k1 k2 p1 p2 k3``,
    OpenCV model; all zeros for pinhole images: simulated ones, and a folder's once undistorted), constant; the
    driver hands it to agents that take it (:mod:`sim_envs.agent`). Not part of the observation.

    ## Starting State

    The first frame of the source. The sequence is fixed by its spec, so the ``seed`` of ``reset`` changes
    nothing that is observed (it seeds ``np_random`` as Gymnasium requires; sensor noise is seeded by the spec).
    ``reset(options={"ground_truth": "full"})`` asks for full ground truth for that episode.

    ## Episode End

    Step k takes the action for frame k and returns frame k + 1. After the action for the last frame of the source
    the episode terminates (``terminated=True``); the observation returned then is the last frame again (there is
    nothing new to see). With ``max_frames=M`` the episode ends after the action for frame M - 1 with
    ``truncated=True`` (unless M reaches the end of the source). ``gymnasium.make(..., max_episode_steps=M)``
    truncates through the ``TimeLimit`` wrapper instead. Stepping after the end raises :class:`SimEnvError`.

    ``info`` always holds ``frame_index`` (int, of the returned observation), ``timestamp`` (float, seconds) and
    ``gt_T_world_cam`` ((4, 4) float64); with ``ground_truth="full"`` also ``gt_depth`` ((H, W) float32 metres, 0 =
    no surface), ``sensor_depth`` ((H, W) float32 metres, 0 = no measurement) where the camera has a simulated depth
    sensor (what an RGB-D folder's depth channel is: noisy, with holes), and where the source has them
    ``gt_labels`` ((H, W) uint8 semantic classes, 255 = none) and ``gt_instances`` ((H, W) int32, -1 = none). Full
    ground truth costs extra render passes.

    ## Arguments

    ```python
    gymnasium.make("sim_envs/office0-v0", renderer="mujoco", ground_truth="pose", max_frames=None)
    SlamEnv(sequence="office0" | spec=SequenceSpec(...) | source=FrameSource, renderer="mujoco" | "pyrender",
            ground_truth="pose" | "full", max_frames=None, render_mode=None | "rgb_array")
    ```

    Exactly one of ``sequence`` (a registered name, :func:`sim_envs.sequences.list_sequences`), ``spec`` or
    ``source`` names what is replayed; ``renderer`` picks the backend of simulated sequences (created lazily on the
    first frame, so an env can be sent to a worker process before use); ``render_mode="rgb_array"`` makes
    ``render()`` return the current image.

    ## Version History

    * v0: initial version.

    ## Example

    >>> import gymnasium, sim_envs                                              # doctest: +SKIP
    >>> env = gymnasium.make("sim_envs/office0-v0", max_frames=3)               # doctest: +SKIP
    >>> obs, info = env.reset(seed=0)                                           # doctest: +SKIP
    >>> obs["rgb"].shape, obs["intrinsics"].round(1)                            # doctest: +SKIP
    ((240, 320, 3), array([240.6, 240. , 159.5, 119.5]))
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(
        self,
        sequence: str | None = None,
        *,
        spec: SequenceSpec | None = None,
        source: FrameSource | None = None,
        renderer: str = "mujoco",
        ground_truth: GroundTruth = "pose",
        max_frames: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        given = [n for n, v in (("sequence", sequence), ("spec", spec), ("source", source)) if v is not None]
        if len(given) != 1:
            raise SimEnvError(f"give exactly one of sequence, spec or source; got {given or 'none'}")
        if renderer not in RENDERER_BACKENDS:
            raise SimEnvError(f"unknown renderer {renderer!r}; valid renderers: {', '.join(RENDERER_BACKENDS)}")
        if sequence is not None:
            spec = get_sequence(sequence)
        if spec is not None:
            source = SimulatedSequence(spec, renderer=renderer)
        assert source is not None  # one of the three was given (checked above)
        if not isinstance(source, FrameSource):
            raise SimEnvError(f"source must implement sim_envs.source.FrameSource, got {type(source).__name__}")
        self.source: FrameSource = source
        self.ground_truth: GroundTruth = _check_ground_truth(ground_truth)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            modes = self.metadata["render_modes"]
            raise SimEnvError(f"render_mode must be None or one of {modes}, got {render_mode!r}")
        self.render_mode = render_mode
        n = len(source)
        if max_frames is not None and int(max_frames) < 1:
            raise SimEnvError(f"max_frames must be >= 1 or None, got {max_frames}")
        self.n_frames: int = n if max_frames is None else min(n, int(max_frames))
        intr = source.intrinsics
        self._intrinsics = intr.as_array()
        self.distortion: np.ndarray = delivered_distortion(source)  # (5,) k1 k2 p1 p2 k3 of the delivered images
        self.observation_space = spaces.Dict(
            {
                "rgb": spaces.Box(0, 255, (intr.height, intr.width, 3), np.uint8),
                "timestamp": spaces.Box(0.0, np.inf, (1,), np.float64),
                "intrinsics": spaces.Box(-np.inf, np.inf, (4,), np.float64),
            }
        )
        self.action_space = spaces.Dict(
            {T_WORLD_CAM: spaces.Box(-np.inf, np.inf, (4, 4), np.float64), TRACKED: spaces.Discrete(2)}
        )
        self._episode_gt: GroundTruth = self.ground_truth
        self._index: int | None = None  # frame of the current observation; None before reset
        self._done = False
        self._current: tuple[dict[str, np.ndarray], dict[str, Any]] | None = None
        self._prev_est: np.ndarray | None = None

    # -- Gymnasium API ---------------------------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start at frame 0. ``options``: ``{"ground_truth": "pose" | "full"}`` for this episode."""
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - {"ground_truth"})
        if unknown:
            raise SimEnvError(f"unknown reset option(s) {', '.join(unknown)}; valid: ground_truth")
        self._episode_gt = _check_ground_truth(options.get("ground_truth", self.ground_truth))
        self._index, self._done, self._prev_est = 0, False, None
        self._current = self._observe(0)
        return _copy(self._current)

    def step(self, action: dict[str, Any]) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Take the pose estimate for the current frame; return the next frame (see the class docstring)."""
        if self._index is None:
            raise SimEnvError("call reset() before step()")
        if self._done:
            raise SimEnvError(f"the episode ended at frame {self._index}; call reset() to start a new one")
        k = self._index
        T_est = _action_pose(action, k)
        poses = self.source.poses
        reward = 0.0
        if self._prev_est is not None:
            reward = -relative_translation_error(self._prev_est, T_est, poses[k - 1], poses[k])
        self._prev_est = T_est
        nxt = k + 1
        if nxt >= self.n_frames:
            self._done = True
            terminated, truncated = nxt >= len(self.source), nxt < len(self.source)
        else:
            terminated = truncated = False
            self._index = nxt
            self._current = self._observe(nxt)
        assert self._current is not None
        obs, info = _copy(self._current)
        return obs, float(reward), bool(terminated), bool(truncated), info

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        """The current RGB image (H, W, 3) uint8 when ``render_mode == "rgb_array"``, else None."""
        if self.render_mode != "rgb_array" or self._current is None:
            return None
        return self._current[0]["rgb"].copy()

    def close(self) -> None:
        """Release the source's renderer (an OpenGL context); the source can render again later."""
        self.source.close()
        super().close()

    # -- internals -------------------------------------------------------------------------------------------------

    def _observe(self, index: int) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        source = self.source
        timestamp = float(source.timestamps[index])
        info: dict[str, Any] = {
            "frame_index": index,
            "timestamp": timestamp,
            "gt_T_world_cam": np.array(source.poses[index], dtype=np.float64),
        }
        rgb_only = getattr(source, "rgb", None)
        if self._episode_gt == "pose" and callable(rgb_only):
            rgb = rgb_only(index)
        else:
            frame: Frame = source.frame(index)
            rgb = frame.rgb
            if self._episode_gt == "full":
                info["gt_depth"] = np.array(frame.depth, dtype=np.float32)
                if frame.sensor_depth is not None:
                    info["sensor_depth"] = np.array(frame.sensor_depth, dtype=np.float32)
                if frame.labels is not None:
                    info["gt_labels"] = np.array(frame.labels, dtype=np.uint8)
                if frame.instances is not None:
                    info["gt_instances"] = np.array(frame.instances, dtype=np.int32)
        obs = {
            "rgb": np.ascontiguousarray(rgb, dtype=np.uint8),
            "timestamp": np.array([timestamp], dtype=np.float64),
            "intrinsics": self._intrinsics.copy(),
        }
        return obs, info


class SceneEnv(SlamEnv):
    """:class:`SlamEnv` over a sequence built from arguments (registered as ``sim_envs/Scene-v0``).

    Arguments: ``style`` (room style of ``sim_envs.scenes.scenegen``), ``seed`` (scene seed), ``trajectory`` (a kind of
    :data:`sim_envs.motion.trajectories.TRAJECTORY_KINDS`) with ``trajectory_params`` (its keyword parameters) and
    ``trajectory_seed``, ``camera`` (a :func:`sim_envs.camera.preset` name) at ``width`` x ``height``, ``n_frames``
    at 30 Hz, ``texture_density`` in [0, 1], ``renderer``, ``ground_truth``, ``max_frames``, ``render_mode`` as in
    :class:`SlamEnv`. Everything else (spaces, reward, episode end) is :class:`SlamEnv`'s.
    """

    def __init__(
        self,
        style: str = "office",
        seed: int = 0,
        trajectory: str = "handheld",
        trajectory_params: dict[str, Any] | None = None,
        trajectory_seed: int = 0,
        camera: str = "icl",
        width: int = DEFAULT_WIDTH,
        height: int = DEFAULT_HEIGHT,
        n_frames: int = 300,
        texture_density: float = 1.0,
        renderer: str = "mujoco",
        ground_truth: GroundTruth = "pose",
        max_frames: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        split = "train" if seed >= TRAIN_SEED_BASE else "test"
        if split == "test" and not 0 <= seed < TEST_SEED_LIMIT:
            raise SimEnvError(
                f"scene seed {seed} is outside the test range [0, {TEST_SEED_LIMIT}) and the training range "
                f"[{TRAIN_SEED_BASE}, ...)"
            )
        spec = SequenceSpec(
            name=f"scene_{style}_{seed}_{trajectory}_{trajectory_seed}",
            style=style,
            scene_seed=int(seed),
            trajectory=trajectory,
            trajectory_params=trajectory_params or {},
            camera=camera,
            n_frames=int(n_frames),
            split=split,
            seed=int(trajectory_seed),
            texture_density=float(texture_density),
            width=int(width),
            height=int(height),
        )
        super().__init__(
            spec=spec, renderer=renderer, ground_truth=ground_truth, max_frames=max_frames, render_mode=render_mode
        )


class ReplayEnv(SlamEnv):
    """:class:`SlamEnv` replaying a given frame source or an RGB-D folder (``sim_envs/Replay-v0``).

    Arguments: ``source``, a :class:`~sim_envs.source.FrameSource` or the path of an RGB-D folder of any layout of
    :func:`sim_envs.folders.datasets.detect_layout` (TUM RGB-D, ICL-NUIM, 7-Scenes, RGB-only; read by
    :class:`sim_envs.folders.datasets.RgbdFolder`); for a path only: ``camera`` (a preset name, camera file,
    ``Intrinsics``
    or ``CameraModel``; default: detected) and ``size`` ((width, height) of the delivered frames, e.g. (320, 240)
    as the benchmark suites use; default None: the images' own); ``ground_truth``, ``max_frames``, ``render_mode``
    as in :class:`SlamEnv`. Everything else is :class:`SlamEnv`'s.
    """

    def __init__(
        self,
        source: FrameSource | str | os.PathLike[str] | None = None,
        ground_truth: GroundTruth = "pose",
        max_frames: int | None = None,
        render_mode: str | None = None,
        camera: Any = None,
        size: tuple[int, int] | None = None,
    ) -> None:
        if source is None:
            raise SimEnvError("sim_envs/Replay-v0 needs source=<a FrameSource or the path of an RGB-D folder>")
        if isinstance(source, str | os.PathLike):
            source = _load_folder(os.fspath(source), camera, size)
        elif camera is not None or size is not None:
            raise SimEnvError("camera and size apply to a folder path, not to a given frame source")
        super().__init__(source=source, ground_truth=ground_truth, max_frames=max_frames, render_mode=render_mode)


def _load_folder(path: str, camera: Any, size: tuple[int, int] | None) -> FrameSource:
    """An RGB-D folder as a frame source (imported lazily: the folder reader lives in sim_envs.folders.datasets)."""
    try:
        from sim_envs.folders.datasets import RgbdFolder
    except ImportError as exc:
        raise SimEnvError(f"cannot replay the folder {path!r}: the folder reader is unavailable ({exc})") from exc
    return RgbdFolder(path, camera, size=size)


def delivered_distortion(source: FrameSource) -> np.ndarray:
    """The lens distortion of the images a source delivers: (5,) float64 ``k1 k2 p1 p2 k3`` of OpenCV's model, on
    normalised image coordinates (so they hold at any image size the source resizes to); all zeros for pinhole
    images. A source may say so itself (a ``distortion`` attribute); a folder (``camera``, a
    :class:`~sim_envs.camera.CameraModel`, and ``undistort``) delivers its camera's distortion when it leaves its
    images as they are (``undistort="none"``) and zeros when it undistorts them; a simulated source renders pinhole
    images (zeros)."""
    own = getattr(source, "distortion", None)
    if own is not None:
        coeffs = np.asarray(own, dtype=np.float64).reshape(-1)
    else:
        camera = getattr(source, "camera", None)
        raw = getattr(source, "undistort", "crop") == "none"
        coeffs = np.asarray(getattr(camera, "distortion", ()) if raw else (), dtype=np.float64).reshape(-1)
    if coeffs.size == 0:
        return np.zeros(len(DISTORTION_NAMES), dtype=np.float64)
    if coeffs.shape != (len(DISTORTION_NAMES),) or not np.isfinite(coeffs).all():
        raise SimEnvError(f"a source's distortion must be {len(DISTORTION_NAMES)} finite coefficients "
                          f"({' '.join(DISTORTION_NAMES)}), got {coeffs.tolist()}")
    return coeffs


def _check_ground_truth(value: str) -> GroundTruth:
    if value not in GROUND_TRUTH_MODES:
        raise SimEnvError(f"ground_truth must be one of {', '.join(GROUND_TRUTH_MODES)}, got {value!r}")
    return value  # type: ignore[return-value]


def _action_pose(action: Any, index: int) -> np.ndarray:
    """The (4, 4) float64 pose of an action; :class:`SimEnvError` naming the frame when it is malformed."""
    if not isinstance(action, dict) or T_WORLD_CAM not in action:
        raise SimEnvError(
            f"frame {index}: the action must be a dict with 'T_world_cam' (4, 4) and 'tracked' (0 or 1), "
            f"got {type(action).__name__}"
        )
    T = np.asarray(action[T_WORLD_CAM], dtype=np.float64)
    if T.shape != (4, 4):
        raise SimEnvError(f"frame {index}: action T_world_cam must be (4, 4), got shape {T.shape}")
    if not np.isfinite(T).all():
        raise SimEnvError(f"frame {index}: action T_world_cam holds NaN or inf")
    tracked = action.get(TRACKED, 1)
    if int(np.asarray(tracked).reshape(-1)[0]) not in (0, 1):
        raise SimEnvError(f"frame {index}: action 'tracked' must be 0 or 1, got {tracked!r}")
    return T.copy()


def _copy(pair: tuple[dict[str, Any], dict[str, Any]]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Fresh arrays for the caller (Gymnasium requires that no two calls share data)."""
    obs, info = pair
    return (
        {k: v.copy() for k, v in obs.items()},
        {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in info.items()},
    )
