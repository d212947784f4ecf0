"""A simulated sequence as a :class:`~sim_envs.source.FrameSource`: a spec's room, trajectory and camera, rendered on
demand.

Everything is lazy: the room is generated on first use of the poses or a frame (and cached per process by
``(style, seed, texture density)``, so several environments of one room generate it once), the trajectory likewise
(cached per spec), and the renderer (an OpenGL context) on the first :meth:`SimulatedSequence.frame`. A sequence can
therefore be pickled to a spawned worker before use; pickling drops the renderer, which the copy re-creates.

Determinism: frame ``i`` is a function of the spec and ``i`` only. Sensor noise is drawn from a generator seeded by
``(spec.seed, i)``, so frames come out the same in any access order; motion blur averages renders at
``pose_at(t_i - k * dt)`` sub-frame times.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import Frame
from sim_envs.sequences import SequenceSpec
from sim_envs.trajectories import Trajectory, make_trajectory

RENDERER_BACKENDS: tuple[str, ...] = ("mujoco", "pyrender")
_TRAJECTORY_STREAM, _NOISE_STREAM = 1, 2  # seed-sequence streams of a spec's seed (ours)
_ALL_OUTPUTS = ("rgb", "depth", "labels", "instances")


@lru_cache(maxsize=8)
def cached_scene(style: str, seed: int, texture_density: float = 1.0) -> Any:
    """The room ``generate_scene(style, seed, texture_density)``, generated once per process (settled by physics).

    Scenes are treated as immutable by every user; the cache holds the last 8.
    """
    from sim_envs.scenegen import generate_scene

    return generate_scene(style, int(seed), texture_density=float(texture_density))


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

    name: the spec's name; intrinsics: the spec's camera; timestamps: (N,) float64 seconds; poses: (N, 4, 4) float64
    ground-truth ``T_world_cam``; ``frame(i)`` renders RGB, depth, labels and instances; ``rgb(i)`` renders the
    image alone (the same bytes as ``frame(i).rgb``, cheaper). ``renderer``: "mujoco" or "pyrender".
    """

    def __init__(self, spec: SequenceSpec, renderer: str = "mujoco") -> None:
        if renderer not in RENDERER_BACKENDS:
            raise UnknownNameError(f"unknown renderer {renderer!r}; valid renderers: {', '.join(RENDERER_BACKENDS)}")
        self.spec = spec
        self.name: str = spec.name
        self.intrinsics: Intrinsics = spec.intrinsics()
        self.backend = renderer
        self._renderer: Any = None

    # -- FrameSource -----------------------------------------------------------------------------------------------

    def __len__(self) -> int:
        return int(self.spec.n_frames)

    @property
    def scene(self) -> Any:
        """The room (``sim_envs.scene.Scene``), generated on first use."""
        return cached_scene(self.spec.style, self.spec.scene_seed, self.spec.texture_density)

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
        )

    def rgb(self, index: int) -> np.ndarray:
        """(H, W, 3) uint8 image of frame ``index`` (sensor effects applied), without the ground-truth passes."""
        return self._render(self._check_index(index), ("rgb",))["rgb"]

    def close(self) -> None:
        """Release the renderer; a later frame creates a new one."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> SimulatedSequence:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_renderer"] = None  # an OpenGL context does not travel; the copy makes its own
        return state

    def __repr__(self) -> str:
        return f"SimulatedSequence({self.spec.name!r}, renderer={self.backend!r}, n_frames={len(self)})"

    # -- rendering -------------------------------------------------------------------------------------------------

    def _check_index(self, index: int) -> int:
        i = int(index)
        if not 0 <= i < len(self):
            raise SimEnvError(f"frame index {index} out of range for {self.name!r} with {len(self)} frames")
        return i

    def _get_renderer(self) -> Any:
        if self._renderer is None:
            from sim_envs.render import make_renderer

            self._renderer = make_renderer(self.scene, self.intrinsics, backend=self.backend)
        return self._renderer

    def _render(self, index: int, outputs: tuple[str, ...]) -> dict[str, np.ndarray | None]:
        """Render ``outputs`` of frame ``index``. The RGB gets the spec's sensor effects: motion blur (the mean of
        renders at ``pose_at(t + offset)`` for the shutter's sub-frame offsets), then exposure and noise drawn from
        :func:`frame_rng`. Ground truth (depth, labels, instances) is exact, at the frame's own pose."""
        from sim_envs.render.effects import apply_sensor_effects, average_frames, blur_offsets

        renderer = self._get_renderer()
        out = renderer.render(self.poses[index], outputs=outputs)
        result: dict[str, np.ndarray | None] = {
            "rgb": out.rgb,
            "depth": out.depth,
            "labels": out.labels,
            "instances": out.instances,
        }
        effects = self.spec.effects
        if effects is None or not effects.any or out.rgb is None:
            return result
        rgb = out.rgb
        offsets = blur_offsets(effects)
        if offsets.shape[0] > 1:
            t = float(self.timestamps[index])
            subframes = [renderer.render(T, outputs=("rgb",)).rgb for T in self.trajectory.pose_at(t + offsets[:-1])]
            rgb = average_frames([*subframes, rgb])  # the last offset is 0: the frame's own render
        result["rgb"] = apply_sensor_effects(rgb, effects, frame_rng(self.spec.seed, index))
        return result


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
