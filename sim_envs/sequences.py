"""The registry of named, fully seeded sequences: analogues of CNN-SLAM's Table-1 sequences, rotation stress tests,
and a disjoint training split.

A :class:`SequenceSpec` fixes everything a sequence is made of (room style and seed, trajectory kind, parameters and
seed, camera preset and resolution, length, texture density, sensor effects), so the same name renders the same bytes
on every machine. Test sequences use the test room styles and scene seeds below :data:`TEST_SEED_LIMIT`; training
sequences (:func:`training_specs`) use the training styles, NYU intrinsics and scene seeds from
:data:`TRAIN_SEED_BASE` up, so the two never share a room or a camera.

Table-1 analogues (CNN-SLAM Sec. 5: ICL-NUIM office 0-2 and living room 0-2 with ICL intrinsics; TUM fr3
long_office_household, nostructure_texture_near_withloop and structure_texture_far with fr3 intrinsics), lengths
close to the originals within 20-60 s at 30 Hz. As in ICL-NUIM, the three office sequences share one room and so do
the three living-room sequences; only their hand-held trajectories differ. :data:`FR1_MOTION_SEQUENCES`: close-range
hand-held sequences at TUM fr1/desk's motion statistics, in rooms of their own, for the ``fr1`` camera.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cache
from typing import TYPE_CHECKING, Any, Literal, get_args

import numpy as np

from sim_envs.camera import DEFAULT_HEIGHT, DEFAULT_WIDTH, Intrinsics, camera_presets, preset
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.motion.trajectories import FPS, TRAJECTORY_KINDS, parse_axes, trajectory_params
from sim_envs.scenes.scene import DETAILS, LIGHTINGS

if TYPE_CHECKING:
    from sim_envs.sensor.camera_effects import CameraEffects

Split = Literal["test", "train"]
SPLITS: tuple[str, ...] = get_args(Split)
TEST_SEED_LIMIT: int = 1000  # every test sequence's scene seed is below this (ours)
TRAIN_SEED_BASE: int = 10_000  # every training sequence's scene seed is at least this (ours)
TRAIN_CAMERA: str = "nyu"  # the paper's network was trained on NYU Depth v2 (Kinect) images
ENV_NAMESPACE: str = "sim_envs"


def _freeze(value: Any) -> Any:
    """Lists (e.g. a range given as a list) become tuples, so specs stay hashable."""
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    return value


@dataclass(frozen=True)
class SequenceSpec:
    """Everything a simulated sequence is made of. Frozen and hashable; same spec, same bytes.

    name: registry name; style: room style (``sim_envs.scenes.scenegen``); scene_seed: room generator seed; trajectory:
    a kind of :data:`sim_envs.motion.trajectories.TRAJECTORY_KINDS`; trajectory_params: its keyword parameters as sorted
    ``(name, value)`` pairs (a mapping is accepted and converted); camera: a :func:`sim_envs.camera.preset` name;
    n_frames: frames at ``fps`` Hz; split: "test" or "train"; seed: seeds the trajectory and the per-frame sensor
    noise; texture_density: in [0, 1], passed to the room generator; width, height: image size in pixels;
    description: one line for listings; camera_effects: what the camera does to the image
    (:mod:`sim_envs.sensor.camera_effects`): a preset name (``clean``, ``kinect``, ``hard``; kept as the name, so it is
    part of the spec's repr) or a ``CameraEffects``; default ``clean``, the renderer's bytes (see
    :func:`with_camera`); lighting:
    ``flat`` (every registered sequence) or ``lit`` (lamps, shadows, bright windows, highlights:
    :mod:`sim_envs.scenes.lighting`; MuJoCo renderer only); the trajectory does not depend on it; detail: ``standard``
    (every registered sequence) or ``rich`` (the same room with clutter and texture detail:
    :mod:`sim_envs.scenes.scenegen`);
    the trajectory does not depend on it either (it is the standard room's).
    """

    name: str
    style: str
    scene_seed: int
    trajectory: str
    trajectory_params: tuple[tuple[str, Any], ...] = ()
    camera: str = "icl"
    n_frames: int = 900
    split: Split = "test"
    seed: int = 0
    texture_density: float = 1.0
    width: int = DEFAULT_WIDTH
    height: int = DEFAULT_HEIGHT
    fps: float = FPS
    description: str = ""
    camera_effects: str | CameraEffects = "clean"
    lighting: str = "flat"
    detail: str = "standard"

    def __post_init__(self) -> None:
        self._check_camera_effects()
        if self.lighting not in LIGHTINGS:
            raise SimEnvError(
                f"sequence {self.name!r}: lighting must be one of {', '.join(LIGHTINGS)}, got {self.lighting!r}"
            )
        if self.detail not in DETAILS:
            raise SimEnvError(
                f"sequence {self.name!r}: detail must be one of {', '.join(DETAILS)}, got {self.detail!r}"
            )
        params = self.trajectory_params
        items = params.items() if isinstance(params, Mapping) else params
        object.__setattr__(self, "trajectory_params", tuple(sorted((str(k), _freeze(v)) for k, v in items)))
        if self.trajectory not in TRAJECTORY_KINDS:
            raise UnknownNameError(
                f"sequence {self.name!r}: unknown trajectory kind {self.trajectory!r}; "
                f"valid kinds: {', '.join(TRAJECTORY_KINDS)}"
            )
        valid = trajectory_params(self.trajectory)
        bad = [k for k, _ in self.trajectory_params if k not in valid or k in ("fps", "t0")]
        if bad:
            raise SimEnvError(
                f"sequence {self.name!r}: trajectory {self.trajectory!r} takes no parameter(s) {', '.join(bad)}; "
                f"valid: {', '.join(v for v in valid if v not in ('fps', 't0'))} (fps is the spec's own field)"
            )
        if self.camera not in camera_presets():
            raise UnknownNameError(
                f"sequence {self.name!r}: unknown camera preset {self.camera!r}; valid: {', '.join(camera_presets())}"
            )
        if self.split not in SPLITS:
            raise SimEnvError(f"sequence {self.name!r}: split must be one of {SPLITS}, got {self.split!r}")
        if int(self.n_frames) < 2:
            raise SimEnvError(f"sequence {self.name!r}: n_frames must be >= 2, got {self.n_frames}")
        if not 0.0 <= float(self.texture_density) <= 1.0:
            raise SimEnvError(f"sequence {self.name!r}: texture_density must be in [0, 1], got {self.texture_density}")
        if self.split == "test" and not 0 <= self.scene_seed < TEST_SEED_LIMIT:
            raise SimEnvError(f"test sequence {self.name!r}: scene_seed must be in [0, {TEST_SEED_LIMIT})")
        if self.split == "train" and self.scene_seed < TRAIN_SEED_BASE:
            raise SimEnvError(f"training sequence {self.name!r}: scene_seed must be >= {TRAIN_SEED_BASE}")

    def _check_camera_effects(self) -> None:
        value = self.camera_effects
        if isinstance(value, str) and value == "clean":
            return
        from sim_envs.sensor.camera_effects import CameraEffects, camera_effects_preset

        if isinstance(value, str):
            try:
                camera_effects_preset(value)
            except UnknownNameError as exc:
                raise UnknownNameError(f"sequence {self.name!r}: {exc}") from None
        elif not isinstance(value, CameraEffects):
            raise SimEnvError(
                f"sequence {self.name!r}: camera_effects must be a preset name or a CameraEffects, got {value!r}"
            )

    def camera_effects_model(self) -> CameraEffects:
        """The spec's camera effects as a :class:`~sim_envs.sensor.camera_effects.CameraEffects` (a preset resolved)."""
        from sim_envs.sensor.camera_effects import resolve_camera_effects

        return resolve_camera_effects(self.camera_effects)

    @property
    def params(self) -> dict[str, Any]:
        """The trajectory parameters as a dict."""
        return dict(self.trajectory_params)

    @property
    def duration_s(self) -> float:
        """Length of the sequence in seconds, ``n_frames / fps``."""
        return self.n_frames / self.fps

    def intrinsics(self) -> Intrinsics:
        """The camera: the preset scaled to ``width`` x ``height``."""
        return preset(self.camera, self.width, self.height)

    def with_frames(self, n_frames: int) -> SequenceSpec:
        """The same sequence with another length (a shorter trajectory is generated, not cut from the longer one)."""
        return replace(self, n_frames=int(n_frames))

    @property
    def gym_id(self) -> str:
        """The Gymnasium id of this sequence, ``sim_envs/<name>-v0``."""
        return gym_id(self.name)


def with_camera(spec: SequenceSpec, camera_effects: str | CameraEffects) -> SequenceSpec:
    """``spec`` seen through another camera (a preset name of
    :func:`sim_envs.sensor.camera_effects.camera_effect_presets` or a ``CameraEffects``); same name, trajectory and
    room.

    The hook for suites: ``with_camera(get_sequence("office0"), "kinect")``. Registered sequences keep ``clean``
    until the benchmark switches its default (which changes every committed result).
    """
    return replace(spec, camera_effects=camera_effects)


# Marks a name may carry after a registered sequence's name, ``office0+lit+rich``: mark -> (SequenceSpec field, value)
VARIANT_MARKS: dict[str, tuple[str, str]] = {
    **{v: ("lighting", v) for v in LIGHTINGS if v != "flat"},
    **{v: ("detail", v) for v in DETAILS if v != "standard"},
}


def split_variant(name: str) -> tuple[str, str, str] | None:
    """``(rest, field, value)`` when ``name`` ends in a variant mark ``+<mark>`` of :data:`VARIANT_MARKS`
    (``office0+lit+rich`` -> ``("office0+lit", "detail", "rich")``), else None."""
    rest, sep, mark = name.rpartition("+")
    if sep and rest and mark in VARIANT_MARKS:
        return (rest, *VARIANT_MARKS[mark])
    return None


def split_variants(name: str) -> tuple[str, dict[str, str]]:
    """``(rest, {field: value})`` of every variant mark ``name`` ends in (``office0+lit+rich`` -> ``("office0",
    {"lighting": "lit", "detail": "rich"})``; marks in any order); :class:`SimEnvError` when a field is marked
    twice."""
    fields: dict[str, str] = {}
    rest = name
    while (split := split_variant(rest)) is not None:
        rest, key, value = split
        if key in fields:
            raise SimEnvError(f"{name!r}: more than one {key} mark")
        fields[key] = value
    return rest, fields


def variant_spec(name: str) -> SequenceSpec:
    """A registered sequence by name, with any variant marks: ``office0+lit`` (lit room), ``office0+rich`` (rich
    room), ``office0+lit+rich`` (both; marks in any order, each at most once). The spec keeps the given name."""
    rest, fields = split_variants(name)
    try:
        spec = get_sequence(rest)
    except UnknownNameError as exc:
        marks = ", ".join(f"+{m}" for m in VARIANT_MARKS)
        raise UnknownNameError(f"{exc}; a name may end in the variant marks {marks}") from None
    return replace(spec, name=name, **fields) if fields else spec


def gym_id(name: str) -> str:
    """Gymnasium id of a named sequence: ``sim_envs/<name>-v0``."""
    return f"{ENV_NAMESPACE}/{name}-v0"


# --------------------------------------------------------------------------------------------------------------------
# The test sequences

ICL_OFFICE_SEED, ICL_LIVING_SEED = 1, 2  # one room per ICL-NUIM scene, shared by its sequences (as in ICL-NUIM)
TUM_LONG_OFFICE_SEED, TUM_NEAR_SEED, TUM_FAR_SEED = 3, 4, 5
FR1_OFFICE_SEED, FR1_LIVING_SEED = 6, 7  # rooms of the fr1/desk-motion sequences (test styles, their own rooms)
FR1_MOTION_SEQUENCES: tuple[str, ...] = ("office_fr1motion", "living_fr1motion")


def _fr1_motion(name: str, style: str, scene_seed: int) -> SequenceSpec:
    """A close-range hand-held sequence moving as TUM fr1/desk's camera does: the ``handheld_stats`` trajectory at
    its defaults (:data:`sim_envs.motion.recorded.FR1_DESK_MOTION`: fr1/desk's ground-truth speeds, angular
    rates and their time scales; distance to a desk or table top as fr1/desk's depths), TUM fr1 intrinsics, 20 s.
    Seen through the ``fr1`` camera as ``<name>@fr1`` (registered with ``clean``, as every sequence)."""
    return SequenceSpec(
        name=name,
        style=style,
        scene_seed=scene_seed,
        trajectory="handheld_stats",
        camera="tum_fr1",
        n_frames=600,
        seed=0,
        description=f"TUM fr1/desk-like: hand-held at fr1/desk's speeds and angular rates, about 1 m from a desk or "
                    f"table top in a {style} room, fr1 intrinsics",
    )  # fmt: skip


def _icl(name: str, style: str, scene_seed: int, seed: int, speed: float, n_frames: int, icl_name: str) -> SequenceSpec:
    return SequenceSpec(
        name=name,
        style=style,
        scene_seed=scene_seed,
        trajectory="handheld",
        trajectory_params={"speed": speed},
        camera="icl",
        n_frames=n_frames,
        seed=seed,
        description=f"ICL-NUIM {icl_name} analogue: hand-held at about {speed} m/s, ICL intrinsics",
    )


def rotation_stress_spec(
    axes: str | Sequence[str] = "yaw",
    speed_deg_s: float = 30.0,
    n_frames: int = 600,
    *,
    amplitude_deg: float | None = None,
    camera: str = "tum_fr1",
    style: str = "office",
    scene_seed: int = ICL_OFFICE_SEED,
    seed: int = 0,
    name: str | None = None,
) -> SequenceSpec:
    """A pure-rotation stress sequence (like TUM fr1/rpy): ``axes`` ("yaw", "pitch", "roll", "rpy", "yaw+pitch")
    sweeping at ``speed_deg_s`` deg/s about a fixed optical centre, TUM fr1 intrinsics by default.

    Named ``rot_<axes>_<speed>`` unless ``name`` is given (``+`` in axes becomes ``-``).
    """
    names = parse_axes(axes)
    label = "rpy" if names == ("yaw", "pitch", "roll") else "-".join(names)
    params: dict[str, Any] = {"axes": "+".join(names), "speed_deg_s": float(speed_deg_s)}
    if amplitude_deg is not None:
        params["amplitude_deg"] = float(amplitude_deg)
    return SequenceSpec(
        name=name or f"rot_{label}_{speed_deg_s:g}",
        style=style,
        scene_seed=scene_seed,
        trajectory="rotation",
        trajectory_params=params,
        camera=camera,
        n_frames=n_frames,
        seed=seed,
        description=f"pure rotation ({label}) at {speed_deg_s:g} deg/s about a fixed optical centre",
    )


def _test_specs() -> list[SequenceSpec]:
    specs = [
        _icl("office0", "office", ICL_OFFICE_SEED, 0, 0.25, 1500, "office room kt0"),
        _icl("office1", "office", ICL_OFFICE_SEED, 1, 0.35, 960, "office room kt1"),
        _icl("office2", "office", ICL_OFFICE_SEED, 2, 0.30, 880, "office room kt2"),
        _icl("living0", "living", ICL_LIVING_SEED, 0, 0.25, 1500, "living room kt0"),
        _icl("living1", "living", ICL_LIVING_SEED, 1, 0.35, 960, "living room kt1"),
        _icl("living2", "living", ICL_LIVING_SEED, 2, 0.30, 880, "living room kt2"),
        SequenceSpec(
            name="tum_long_office",
            style="office",
            scene_seed=TUM_LONG_OFFICE_SEED,
            trajectory="loop",
            trajectory_params={"speed": 0.25},
            camera="tum_fr3",
            n_frames=1800,
            seed=0,
            description="TUM fr3/long_office_household analogue: hand-held loop around the room, back to the start",
        ),
        SequenceSpec(
            name="tum_nostructure_near",
            style="office",
            scene_seed=TUM_NEAR_SEED,
            trajectory="plane_near",
            trajectory_params={"loop": True, "speed": 0.15},
            camera="tum_fr3",
            n_frames=1110,
            seed=0,
            description="TUM fr3/nostructure_texture_near_withloop analogue: 0.6-0.9 m over a textured floor, loops",
        ),
        SequenceSpec(
            name="tum_structure_far",
            style="office",
            scene_seed=TUM_FAR_SEED,
            trajectory="far_structure",
            trajectory_params={"speed": 0.15},
            camera="tum_fr3",
            n_frames=900,
            seed=0,
            description="TUM fr3/structure_texture_far analogue: sideways sweep looking at structure 2-4 m away",
        ),
        SequenceSpec(
            name="low_texture_wall",
            style="office",
            scene_seed=ICL_OFFICE_SEED,
            trajectory="low_texture",
            camera="icl",
            n_frames=600,
            seed=0,
            description="facing the plainest wall stretch of the office room, sliding slowly along it",
        ),
    ]
    for axes, speed in (("yaw", 15), ("yaw", 30), ("yaw", 60), ("pitch", 30), ("roll", 30), ("rpy", 30)):
        specs.append(rotation_stress_spec(axes, speed))
    specs += [_fr1_motion("office_fr1motion", "office", FR1_OFFICE_SEED),
              _fr1_motion("living_fr1motion", "living", FR1_LIVING_SEED)]  # fmt: skip
    return specs


TABLE1_SEQUENCES: tuple[str, ...] = (
    "office0",
    "office1",
    "office2",
    "living0",
    "living1",
    "living2",
    "tum_long_office",
    "tum_nostructure_near",
    "tum_structure_far",
)
N_REGISTERED_TRAINING: int = 3  # training sequences registered by name (train_000...), from training_specs(3, seed=0)


# --------------------------------------------------------------------------------------------------------------------
# The training split

_TRAIN_KINDS = ("handheld", "handheld", "handheld", "loop", "far_structure", "plane_near", "low_texture", "rotation")


def training_specs(n: int, seed: int = 0, n_frames: int = 600, prefix: str | None = None) -> list[SequenceSpec]:
    """``n`` training sequences drawn with ``numpy.random.default_rng(seed)``.

    Rooms of the training styles only (``sim_envs.scenes.scenegen.TRAIN_STYLES``), NYU intrinsics, scene seeds
    >= :data:`TRAIN_SEED_BASE` (test scenes use seeds below :data:`TEST_SEED_LIMIT`), mostly hand-held trajectories
    with some of every other kind, speeds and texture densities varied. Named ``<prefix>_<i:03d>``, prefix
    ``train`` for seed 0 and ``train<seed>`` otherwise.
    """
    from sim_envs.scenes.scenegen import TRAIN_STYLES

    if n < 0:
        raise SimEnvError(f"n must be >= 0, got {n}")
    rng = np.random.default_rng(seed)
    prefix = prefix or ("train" if seed == 0 else f"train{seed}")
    specs = []
    for i in range(n):
        style = str(TRAIN_STYLES[int(rng.integers(len(TRAIN_STYLES)))])
        kind = str(_TRAIN_KINDS[int(rng.integers(len(_TRAIN_KINDS)))])
        params: dict[str, Any] = {}
        if kind in ("handheld", "loop"):
            params["speed"] = round(float(rng.uniform(0.15, 0.45)), 3)
        elif kind == "rotation":
            params["axes"] = str(rng.choice(["yaw", "pitch", "roll", "rpy"]))
            params["speed_deg_s"] = round(float(rng.uniform(10.0, 40.0)), 1)
        specs.append(
            SequenceSpec(
                name=f"{prefix}_{i:03d}",
                style=style,
                scene_seed=TRAIN_SEED_BASE + int(rng.integers(0, 1_000_000)),
                trajectory=kind,
                trajectory_params=params,
                camera=TRAIN_CAMERA,
                n_frames=n_frames,
                split="train",
                seed=int(rng.integers(0, 2**31 - 1)),
                texture_density=round(float(rng.uniform(0.5, 1.0)), 3),
                description=f"training: {style} room, {kind} trajectory, NYU intrinsics",
            )
        )
    return specs


# --------------------------------------------------------------------------------------------------------------------
# Registry


@cache
def _registry() -> dict[str, SequenceSpec]:
    specs = _test_specs() + training_specs(N_REGISTERED_TRAINING, seed=0)
    registry: dict[str, SequenceSpec] = {}
    for spec in specs:
        if spec.name in registry:
            raise SimEnvError(f"duplicate sequence name {spec.name!r}")
        registry[spec.name] = spec
    return registry


def registered_names() -> list[str]:
    """Every registered sequence name, in registry order, without importing the room generator (for registration
    of the Gymnasium ids at import time)."""
    return [s.name for s in _test_specs()] + [f"train_{i:03d}" for i in range(N_REGISTERED_TRAINING)]


def list_sequences(split: Split | Literal["all"] = "all") -> list[str]:
    """Registered sequence names of a split ("test", "train" or "all"), in registry order."""
    if split not in (*SPLITS, "all"):
        raise SimEnvError(f"split must be one of {', '.join((*SPLITS, 'all'))}, got {split!r}")
    return [name for name, spec in _registry().items() if split == "all" or spec.split == split]


def get_sequence(name: str) -> SequenceSpec:
    """The spec of a registered sequence; :class:`UnknownNameError` listing the valid names otherwise."""
    try:
        return _registry()[name]
    except KeyError:
        raise UnknownNameError(f"unknown sequence {name!r}; valid sequences: {', '.join(_registry())}") from None
