"""A simulated sequence as a :class:`~sim_envs.source.FrameSource`: a spec's room, trajectory and camera, rendered on
demand.

Everything is lazy: the room is generated on first use of the poses or a frame (and cached per process by
``(style, seed, texture density)``, so several environments of one room generate it once), the trajectory likewise
(cached per spec), and the renderer (an OpenGL context) on the first :meth:`SimulatedSequence.frame`. A sequence can
therefore be pickled to a spawned worker before use; pickling drops the renderer, which the copy re-creates.

Determinism: frame ``i`` is a function of the spec and ``i`` only. Sensor noise is drawn from a generator seeded by
``(spec.seed, i)``, so frames come out the same in any access order; motion blur averages renders at
``pose_at(t_i - k * dt)`` sub-frame times.

Camera effects (``spec.camera_effects``, :mod:`sim_envs.sensor.camera_effects`): the RGB is the camera's image
(exposure,
vignetting, noise, response, blur over the exposure, rolling shutter, lens distortion). Auto-exposure needs the
brightness of frames 0..i-1: the sequence renders them at :data:`BRIGHTNESS_SIZE` with a second renderer the first
time a frame needs them, and caches the series (a few milliseconds per frame, once). A distorted camera's image is
delivered undistorted (:meth:`SimulatedSequence.rgb`, ``frame(i).rgb``), exactly as a real distorted camera's
images are by :class:`sim_envs.folders.datasets.RgbdFolder`, because agents receive pinhole intrinsics only: cropped to
what
the lens saw, so the delivered intrinsics (``intrinsics``) are :meth:`sim_envs.camera.CameraModel.rectified`, a few
per cent longer in focal length than the rendered camera's (``sensor_intrinsics``); the raw sensor image is
:meth:`SimulatedSequence.raw_rgb`. Ground truth (depth, labels, instances) is the exact pinhole render at the
frame's pose, on the delivered image's pixel grid (resampled by nearest neighbour when the lens is distorted).
With depth noise on, frames also carry a Kinect-like ``sensor_depth`` (its own generator, ``(spec.seed, 3, i)``).
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from functools import lru_cache
from typing import Any

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import Frame
from sim_envs.motion.trajectories import Trajectory, make_trajectory
from sim_envs.sequences import SequenceSpec

RENDERER_BACKENDS: tuple[str, ...] = ("mujoco", "pyrender")
_TRAJECTORY_STREAM, _NOISE_STREAM, _DEPTH_NOISE_STREAM, _EXPOSURE_STREAM = 1, 2, 3, 4  # streams of a spec's seed (ours)
BRIGHTNESS_SIZE: tuple[int, int] = (40, 30)  # (width, height) of the renders auto-exposure measures (ours)
_ALL_OUTPUTS = ("rgb", "depth", "labels", "instances")


@lru_cache(maxsize=8)
def cached_scene(style: str, seed: int, texture_density: float = 1.0, lighting: str = "flat",
                 detail: str = "standard") -> Any:  # fmt: skip
    """The room ``generate_scene(style, seed, texture_density, lighting=lighting, detail=detail)``, generated once
    per process (settled by physics). Scenes are treated as immutable by every user; the cache holds the last 8.
    """
    from sim_envs.scenes.scenegen import generate_scene

    return generate_scene(style, int(seed), texture_density=float(texture_density), lighting=lighting, detail=detail)


@lru_cache(maxsize=64)
def cached_trajectory(spec: SequenceSpec) -> Trajectory:
    """The trajectory of ``spec``: its kind and parameters in its room, drawn from ``default_rng((seed, 1))``."""
    scene = cached_scene(spec.style, spec.scene_seed, spec.texture_density)
    rng = np.random.default_rng((spec.seed, _TRAJECTORY_STREAM))
    return make_trajectory(spec.trajectory, scene, rng, spec.n_frames, fps=spec.fps, **spec.params)


def frame_rng(spec_seed: int, index: int) -> np.random.Generator:
    """The generator of frame ``index``'s sensor noise: ``default_rng((spec_seed, 2, index))``."""
    return np.random.default_rng((int(spec_seed), _NOISE_STREAM, int(index)))


class SimulatedSequence:
    """A :class:`~sim_envs.source.FrameSource` rendering a :class:`SequenceSpec`.

    name: the spec's name; intrinsics: the camera of the delivered frames (the spec's camera, or its undistorted crop
    when the camera effects have lens distortion); sensor_intrinsics: the spec's camera, as rendered; timestamps:
    (N,) float64 seconds; poses: (N, 4, 4) float64 ground-truth ``T_world_cam``; ``frame(i)`` renders RGB, depth,
    labels and instances; ``rgb(i)`` renders the image alone (the same bytes as ``frame(i).rgb``, cheaper).
    ``renderer``: "mujoco" or "pyrender".
    """

    def __init__(self, spec: SequenceSpec, renderer: str = "mujoco") -> None:
        if renderer not in RENDERER_BACKENDS:
            raise UnknownNameError(f"unknown renderer {renderer!r}; valid renderers: {', '.join(RENDERER_BACKENDS)}")
        if spec.lighting != "flat" and renderer != "mujoco":
            raise SimEnvError(
                f"sequence {spec.name!r}: lighting {spec.lighting!r} (lamps, shadows, highlights) is drawn by the "
                f"mujoco renderer only, not {renderer!r}"
            )
        self.spec = spec
        self.name: str = spec.name
        self.sensor_intrinsics: Intrinsics = spec.intrinsics()
        self.backend = renderer
        self._renderer: Any = None
        self.camera_effects = spec.camera_effects_model()
        self._brightness_renderer: Any = None
        self._brightness = np.empty(0)  # mean linear brightness of frames 0..len-1 (auto-exposure), cached
        self._jitter = np.empty(0)  # the exposure jitter draws of frames 0..len-1, cached
        self._exposure: tuple[np.ndarray, np.ndarray] = (np.empty(0), np.empty(0))  # exposures() of 0..len-1
        self._geometry: Any = None
        self._pool: ThreadPoolExecutor | None = None
        self._pool_pid = 0
        self.intrinsics: Intrinsics = self._delivered_intrinsics()

    # -- FrameSource -----------------------------------------------------------------------------------------------

    def __len__(self) -> int:
        return int(self.spec.n_frames)

    @property
    def scene(self) -> Any:
        """The room (``sim_envs.scenes.scene.Scene``), generated on first use."""
        spec = self.spec
        return cached_scene(spec.style, spec.scene_seed, spec.texture_density, spec.lighting, spec.detail)

    @property
    def trajectory(self) -> Trajectory:
        """The camera trajectory, generated on first use."""
        return cached_trajectory(self.spec)

    @property
    def timestamps(self) -> np.ndarray:
        """(N,) float64 seconds (read-only)."""
        return self.trajectory.timestamps

    @property
    def poses(self) -> np.ndarray:
        """(N, 4, 4) float64 ground-truth camera-to-world poses (read-only)."""
        return self.trajectory.T_world_cam

    def frame(self, index: int) -> Frame:
        """Frame ``index`` with RGB (sensor effects applied) and exact ground truth (depth, labels, instances)."""
        index = self._check_index(index)
        out = self._render(index, _ALL_OUTPUTS)
        return Frame(
            index=index,
            timestamp=float(self.timestamps[index]),
            rgb=out["rgb"],
            depth=out["depth"],
            T_world_cam=self.poses[index].copy(),
            labels=out["labels"],
            instances=out["instances"],
            sensor_depth=out.get("sensor_depth"),
        )

    def rgb(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8 image of frame ``index`` (sensor effects applied), without the ground-truth passes."""
        return self._render(self._check_index(index), ("rgb",))["rgb"]

    def raw_rgb(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8 raw sensor image of frame ``index``: :meth:`rgb` before undistortion (distorted by the
        camera's lens when it has distortion; the same bytes as :meth:`rgb` otherwise)."""
        return self._render(self._check_index(index), ("rgb",), undistort=False)["rgb"]

    def exposures(self, upto: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Exposure times (s) and analogue gains of frames ``0..upto`` (default: all), two (n,) float64 arrays
        (:func:`sim_envs.sensor.camera_effects.auto_exposure`; constant when auto-exposure is off)."""
        n = len(self) if upto is None else int(upto) + 1
        done = self._exposure[0].shape[0]
        if n > done:  # the controller is causal: a longer run keeps the values of a shorter one, so the series
            self._extend_exposures(min(len(self), max(n, 2 * done)))  # grows by doubling (linear, not quadratic)
        return self._exposure[0][:n].copy(), self._exposure[1][:n].copy()

    def _extend_exposures(self, n: int) -> None:
        """Compute the exposure series of frames 0..n-1 into the cache (jitter drawn only for the new frames)."""
        from sim_envs.sensor.camera_effects import auto_exposure

        fx = self.camera_effects
        if fx.exposure_jitter > 0:  # one draw per frame from its own generator: any access order, same values
            seed = int(self.spec.seed)
            new = [np.random.default_rng((seed, _EXPOSURE_STREAM, i)).standard_normal()
                   for i in range(self._jitter.shape[0], n)]  # fmt: skip
            self._jitter = np.concatenate([self._jitter, np.asarray(new, dtype=np.float64)])
        jitter = self._jitter[:n] if fx.exposure_jitter > 0 else None
        brightness = self._brightness_series(n) if fx.auto_exposure else np.ones(n)
        self._exposure = auto_exposure(brightness, fx, jitter)

    def close(self) -> None:
        """Release the renderers; a later frame creates new ones."""
        for attr in ("_renderer", "_brightness_renderer"):
            if getattr(self, attr) is not None:
                getattr(self, attr).close()
                setattr(self, attr, None)
        if self._pool is not None and self._pool_pid == os.getpid():
            self._pool.shutdown()
        self._pool = None

    def __enter__(self) -> SimulatedSequence:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderer"] = None  # an OpenGL context does not travel; the copy makes its own
        state["_brightness_renderer"] = None
        state["_pool"] = None  # nor does a thread
        return state

    def __repr__(self) -> str:
        return f"SimulatedSequence({self.spec.name!r}, renderer={self.backend!r}, n_frames={len(self)})"

    # -- rendering -------------------------------------------------------------------------------------------------

    def _check_index(self, index: int) -> int:
        i = int(index)
        if not 0 <= i < len(self):
            raise SimEnvError(f"frame index {index} out of range for {self.name!r} with {len(self)} frames")
        return i

    def _delivered_intrinsics(self) -> Intrinsics:
        if not self.camera_effects.distorted:
            return self.sensor_intrinsics
        from sim_envs.sensor.camera_effects import sensor_geometry

        self._geometry = sensor_geometry(self.sensor_intrinsics, self.camera_effects)  # refuses a lens wider than the
        return self._geometry.delivered  # render at once, not at the first frame

    def _get_renderer(self) -> Any:
        if self._renderer is None:
            from sim_envs.render import make_renderer

            self._renderer = make_renderer(self.scene, self.sensor_intrinsics, backend=self.backend)
        return self._renderer

    def _brightness_series(self, n: int) -> np.ndarray:
        """(n,) mean linear brightness of frames 0..n-1 at the reference exposure, rendered at
        :data:`BRIGHTNESS_SIZE` (cached; only the frames not yet measured are rendered)."""
        from sim_envs.sensor.camera_effects import mean_brightness, vignette

        done = self._brightness.shape[0]
        if n > done:
            if self._brightness_renderer is None:
                from sim_envs.render import make_renderer

                small = self.sensor_intrinsics.scaled(*BRIGHTNESS_SIZE)
                self._brightness_renderer = make_renderer(self.scene, small, backend=self.backend)
                self._brightness_vignette = vignette(small, self.camera_effects.vignette_corner)
            fx, renderer = self.camera_effects, self._brightness_renderer
            new = [
                mean_brightness(renderer.render(self.poses[i], outputs=("rgb",)).rgb, fx, self._brightness_vignette)
                for i in range(done, n)
            ]
            self._brightness = np.concatenate([self._brightness, np.asarray(new, dtype=np.float64)])
        return self._brightness[:n]

    def _render(self, index: int, outputs: tuple[str, ...], undistort: bool = True) -> dict[str, np.ndarray | None]:
        """Render ``outputs`` of frame ``index``. The RGB gets the spec's camera effects
        (:func:`sim_envs.sensor.camera_effects.sensor_image`, then undistortion unless ``undistort`` is False). Ground
        truth
        (depth, labels, instances) is exact, at the frame's own pose."""
        renderer = self._get_renderer()
        out = renderer.render(self.poses[index], outputs=outputs)
        result: dict[str, np.ndarray | None] = {
            "rgb": out.rgb,
            "depth": out.depth,
            "labels": out.labels,
            "instances": out.instances,
        }
        if self.camera_effects.any or self.camera_effects.depth_noise:
            return self._camera_render(index, result, undistort)
        return result

    def _camera_render(self, index: int, result: dict[str, Any], undistort: bool) -> dict[str, Any]:
        """``result`` (the renders at the frame's pose) with the camera's RGB and, when on, its sensor depth.

        The sensor depth and the image noise's draws are computed on a worker thread while this one renders the
        blur sub-frames (NumPy and OpenCV release the GIL there); each has its own generator, so the bytes are
        those of a serial run."""
        from sim_envs.sensor.camera_effects import (
            ground_truth_on_delivered_grid,
            noise_draws,
            sensor_geometry,
            sensor_image,
            undistort_image,
        )

        fx = self.camera_effects
        if self._geometry is None:
            self._geometry = sensor_geometry(self.sensor_intrinsics, fx)
        for name in ("depth", "labels", "instances"):  # exact renders, onto the delivered grid
            if result[name] is not None:
                result[name] = ground_truth_on_delivered_grid(result[name], self._geometry)
        if result["rgb"] is not None and fx.any:
            exposure, gain = self.exposures(index)
            renderer = self._get_renderer()
            rng = frame_rng(self.spec.seed, index)
            shape = (self.sensor_intrinsics.height, self.sensor_intrinsics.width, 3)
            normals = self._worker().submit(noise_draws, shape, fx, rng)  # first: the image needs it sooner
            sensor_depth = self._submit_sensor_depth(index, result)
            raw = sensor_image(
                lambda T: renderer.render(T, outputs=("rgb",)).rgb,
                self.trajectory.pose_at,
                float(self.timestamps[index]),
                fx,
                self.sensor_intrinsics,
                rng,
                exposure_s=float(exposure[index]),
                gain=float(gain[index]),
                geometry=self._geometry,
                own_render=result["rgb"],
                normals=normals.result,
            )
            result["rgb"] = undistort_image(raw, self._geometry) if undistort else raw
        else:
            sensor_depth = self._submit_sensor_depth(index, result)
        if sensor_depth is not None:
            result["sensor_depth"] = sensor_depth.result()
        return result

    def _submit_sensor_depth(self, index: int, result: dict[str, Any]) -> Future[np.ndarray] | None:
        """The Kinect-like sensor depth of frame ``index``, queued on the worker (None when the camera has none)."""
        from sim_envs.sensor.camera_effects import kinect_depth

        if not self.camera_effects.depth_noise or result["depth"] is None:
            return None
        rng = np.random.default_rng((int(self.spec.seed), _DEPTH_NOISE_STREAM, int(index)))
        return self._worker().submit(kinect_depth, result["depth"], rng)

    def _worker(self) -> ThreadPoolExecutor:
        """The one worker thread of this sequence's per-frame side computations (made on first use, and anew in a
        forked child process, where the parent's thread does not exist)."""
        if self._pool is None or self._pool_pid != os.getpid():
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="simsource")
            self._pool_pid = os.getpid()
        return self._pool


class FrameListSource:
    """A :class:`~sim_envs.source.FrameSource` over frames already in memory (recorded arrays, test fixtures).

    frames: at least one :class:`Frame`, with strictly increasing timestamps, all of the ``intrinsics``' image size.
    ``frame(i)`` returns the stored frame ``i`` (its arrays are not copied); ``close`` does nothing.
    """

    def __init__(self, name: str, intrinsics: Intrinsics, frames: list[Frame]) -> None:
        if not frames:
            raise SimEnvError(f"frame list {name!r} is empty")
        size = (intrinsics.height, intrinsics.width)
        for i, f in enumerate(frames):
            if f.rgb.shape != (*size, 3) or f.rgb.dtype != np.uint8 or f.depth.shape != size:
                raise SimEnvError(
                    f"frame list {name!r}: frame {i} needs rgb {(*size, 3)} uint8 and depth {size}, got "
                    f"{f.rgb.shape} {f.rgb.dtype} and {f.depth.shape}"
                )
        self.name = name
        self.intrinsics = intrinsics
        self._frames = list(frames)
        self.timestamps = np.array([f.timestamp for f in frames], dtype=np.float64)
        if len(frames) > 1 and not (np.diff(self.timestamps) > 0).all():
            raise SimEnvError(f"frame list {name!r}: timestamps must be strictly increasing")
        self.poses = np.stack([np.asarray(f.T_world_cam, dtype=np.float64) for f in frames])

    def __len__(self) -> int:
        return len(self._frames)

    def frame(self, index: int) -> Frame:
        """The stored frame ``index``."""
        if not 0 <= int(index) < len(self._frames):
            raise SimEnvError(f"frame index {index} out of range for {self.name!r} with {len(self)} frames")
        return self._frames[int(index)]

    def close(self) -> None:
        """Nothing to release."""
