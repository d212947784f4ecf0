"""The simulated camera as composable stages: one class per thing a camera does to an image, composed in the order of
image formation (Gymnasium's wrappers are the model: one class per transformation). A camera preset is an ordered list
of stages (:data:`PRESET_STAGES`); :class:`sim_envs.sensor.camera_effects.CameraEffects` is the frozen configuration
made
from one (``CameraEffects.from_stages``) and runs its chain (``CameraEffects.stages``).

Image formation of one frame (:func:`sim_envs.sensor.camera_effects.sensor_image`), stage by stage in chain order
(``order``):

1. the renderer's uint8 RGB is read as sRGB-encoded scene radiance and decoded to linear values in [0, 1]; renders
   are made at the sub-frame times of :meth:`MotionBlur.times`;
2. :class:`Distortion` (``warp``): lens distortion (OpenCV radial-tangential) resamples each linear render onto the
   sensor grid with ``cv2.remap`` (pixels seeing rays outside the pinhole render are 0);
3. :class:`MotionBlur` and :class:`RollingShutter`: sensor row r integrates a box of width ``exposure_s`` centred on
   ``t + readout_s * (r / (H - 1) - 1/2)`` (the middle row is exposed around the frame's timestamp, whose pose is the
   ground truth); the box is integrated over the renders by linear interpolation in time;
4. (``signal``, on the linear sensor signal) :class:`Exposure`: ``x = L * scene_light * exposure_s /
   reference_exposure_s`` (at the reference exposure and full light a pixel gets the renderer's value back);
   :class:`Vignetting`: times a radial fall-off ``V``; :class:`FullWell`: saturation at 1;
5. :class:`Noise`: shot and read noise in the linear domain (ICL-NUIM model: std ``sqrt(x) * shot_noise`` and
   ``read_noise`` per channel); :class:`AutoExposure`: times the frame's analogue gain;
6. :class:`Response`: the camera response function ``f``, then 8-bit quantisation (``encode``); then the ``encoded``
   hooks on the uint8 image (none built in).

:class:`AutoExposure` also sets each frame's exposure and gain (a first-order controller on the mean linear brightness
of the previous frames, :func:`sim_envs.sensor.camera_effects.auto_exposure`); :class:`SensorDepth` makes a Kinect-like
"sensor depth" beside the exact ground truth, which no stage touches.

A stage is a frozen dataclass of its parameters, checked in ``__post_init__``. A stage class that names an
``effect`` is a single effect: ``"<effect>:<s>"`` names the clean camera with that effect alone at strength s
(:meth:`CameraStage.alone`, :func:`sim_envs.sensor.camera_effects.single_effect`), and with ``sweep_strengths`` it is
one of
the sweep's camera axes (``eval.bench.suites``). Defining the class registers it (:data:`EFFECT_STAGES`, in
definition order). The built-in stages' parameters are :class:`~sim_envs.sensor.camera_effects.CameraEffects` fields of
the
same names (the rest of the code reads them there); any other stage travels in ``CameraEffects.extra_stages``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, ClassVar, Literal

import cv2
import numpy as np

from sim_envs.camera import NO_DISTORTION, CameraModel, Intrinsics, preset_distortion
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.sensor.camera_sensor import (
    FPS_NOMINAL,
    ICL_READ_NOISE,
    ICL_SHOT_NOISE,
    kinect_depth,
    linear_to_srgb,
    row_times,
    row_weights,
    srgb_to_linear,
)

ResponseCurve = Literal["srgb", "gamma"]
RESPONSES: tuple[str, ...] = ("srgb", "gamma")


@dataclass(frozen=True)
class FrameContext:
    """What the stages of one frame share: its exposure time (s) and analogue gain, the generator of its randomness
    (None when the noise was drawn ahead), the noise's standard normal draws when drawn ahead, and the sensor's
    precomputed maps (vignette (H, W) float32, distortion maps for ``cv2.remap``; None when off)."""

    exposure_s: float
    gain: float = 1.0
    rng: np.random.Generator | None = None
    normals: np.ndarray | None = None
    vignette: np.ndarray | None = None
    distort: tuple[np.ndarray, np.ndarray] | None = None


class CameraStage:
    """One thing a camera does to an image. Subclasses are frozen dataclasses of their parameters.

    Class attributes: ``order``, the stage's place in the chain of image formation (the module docstring; a preset
    runs its stages sorted by it); ``photometric``, whether the stage changes pixel values (rather than moving
    pixels). A single effect also sets ``effect`` (its name, the EFFECT of ``"EFFECT:S"``), ``strength`` (what
    strength s means, s = 1 the kinect preset's value where it has one), ``axis_title`` (the sweep's axis label),
    ``sweep_strengths`` (the sweep's strengths; empty: not a sweep axis), ``max_strength`` and ``max_strength_means``
    (the largest valid strength and why), and implements :meth:`alone`.

    Hooks (identity unless overridden), run by :func:`sim_envs.sensor.camera_effects.sensor_image` for every stage in
    chain
    order: :meth:`warp` (each linear render), :meth:`signal` (the frame's linear sensor signal), :meth:`encoded` (the
    quantised uint8 image)."""

    order: ClassVar[float] = 50.0
    photometric: ClassVar[bool] = True
    effect: ClassVar[str | None] = None
    strength: ClassVar[str] = ""
    axis_title: ClassVar[str] = ""
    sweep_strengths: ClassVar[tuple[float, ...]] = ()
    max_strength: ClassVar[float] = math.inf
    max_strength_means: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        name = cls.__dict__.get("effect")
        if name:
            if name in EFFECT_STAGES and EFFECT_STAGES[name].__qualname__ != cls.__qualname__:
                raise SimEnvError(f"camera effect {name!r} is defined twice: {EFFECT_STAGES[name].__qualname__} and "
                                  f"{cls.__qualname__}")  # fmt: skip
            if getattr(cls.alone, "__func__", None) is CameraStage.alone.__func__:
                raise SimEnvError(f"camera effect {name!r} ({cls.__qualname__}) defines no alone(s): the stages of "
                                  "the clean camera with the effect alone at strength s")  # fmt: skip
            EFFECT_STAGES[name] = cls

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        """The stages of the clean camera with this effect alone at strength ``s`` > 0 (checked by the caller); a
        stage that is no single effect (no ``effect`` name) has none."""
        raise SimEnvError(f"{cls.__name__} is not a single effect; single effects: {', '.join(EFFECT_STAGES)}")

    @property
    def changes_image(self) -> bool:
        """Whether this stage alone changes the renderer's image (False: it keeps the clean camera's bytes)."""
        return True

    def warp(self, linear: np.ndarray, frame: FrameContext) -> np.ndarray:
        """One linear render (H, W, 3) float32 -> the sensor's view of it (same shape)."""
        return linear

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        """The frame's linear sensor signal (H, W, 3) float32 -> the next stage's (may work in place)."""
        return x

    def encoded(self, rgb: np.ndarray, frame: FrameContext) -> np.ndarray:
        """The quantised image (H, W, 3) uint8 -> the delivered one."""
        return rgb

    def params(self) -> dict[str, Any]:
        """The stage's parameters by name (tuples kept)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    def describe(self) -> dict[str, Any]:
        """JSON-ready: the stage's class name and parameters (lists for tuples)."""
        values = {k: list(v) if isinstance(v, tuple) else v for k, v in self.params().items()}
        return {"stage": type(self).__name__, **values}


# effect name -> stage class, in definition order (the sweep's axis order); filled by defining the classes
EFFECT_STAGES: dict[str, type[CameraStage]] = {}


def effect_stage(effect: str) -> type[CameraStage]:
    """The stage class of the single effect ``effect``; :class:`UnknownNameError` listing the valid effects."""
    if effect not in EFFECT_STAGES:
        raise UnknownNameError(f"unknown camera effect {effect!r}; valid effects: {', '.join(EFFECT_STAGES)}")
    return EFFECT_STAGES[effect]


def sweep_effects() -> dict[str, type[CameraStage]]:
    """The single effects that are sweep axes (their ``sweep_strengths`` not empty), in definition order."""
    return {name: cls for name, cls in EFFECT_STAGES.items() if cls.sweep_strengths}


class _EffectMeanings(Mapping[str, str]):
    """A live view of :data:`EFFECT_STAGES`: effect name -> what its strength means."""

    def __getitem__(self, name: str) -> str:
        return EFFECT_STAGES[name].strength

    def __iter__(self) -> Iterator[str]:
        return iter(list(EFFECT_STAGES))

    def __len__(self) -> int:
        return len(EFFECT_STAGES)

    def __repr__(self) -> str:
        return repr(dict(self))


# One camera effect alone on the clean camera, at a strength (the sweep's camera axes): the effect's name and what
# strength s means (a live view of the registered stage classes).
SINGLE_EFFECTS: Mapping[str, str] = _EffectMeanings()


def _positive(stage: CameraStage, *keys: str) -> None:
    for key in keys:
        value = getattr(stage, key)
        if not (np.isfinite(value) and value > 0):
            raise SimEnvError(f"{key} must be a number > 0, got {value!r}")


def _kinect(cls: type[CameraStage]) -> Any:
    """The kinect preset's stage of class ``cls`` (the reference of the single effects' strength 1)."""
    return next(s for s in PRESET_STAGES["kinect"] if type(s) is cls)


# ------------------------------------------------------------------------------------------------- the single effects
# Defined in the sweep's axis order: noise, blur, exposure, rolling_shutter, distortion.
@dataclass(frozen=True)
class Noise(CameraStage):
    """Shot and read noise in the linear domain, per channel R, G, B on intensities in [0, 1], before the gain.

    shot_noise: std ``sqrt(x) * shot_noise``; read_noise: std ``read_noise``; sensor_width: the width in pixels of
    the sensor these stds are for (None: the image's own): an image narrower than the sensor is the sensor's image
    area-averaged, as the folder loader does to real frames (``cv2.INTER_AREA``), so both stds are scaled by
    ``width / sensor_width`` (the mean of (sensor_width / width)^2 independent pixels)."""

    shot_noise: tuple[float, float, float] = (0.0, 0.0, 0.0)
    read_noise: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_width: int | None = None

    order: ClassVar[float] = 60.0
    effect: ClassVar[str | None] = "noise"
    strength: ClassVar[str] = "shot + read noise, s x ICL-NUIM's (640-px sensor, as kinect)"
    axis_title: ClassVar[str] = "camera noise alone, x ICL-NUIM's"
    sweep_strengths: ClassVar[tuple[float, ...]] = (1.0, 2.0, 4.0)

    def __post_init__(self) -> None:
        for key in ("shot_noise", "read_noise"):
            value = tuple(float(v) for v in getattr(self, key))
            if len(value) != 3 or not all(np.isfinite(v) and v >= 0 for v in value):
                raise SimEnvError(f"{key} must be 3 numbers >= 0 (R, G, B), got {getattr(self, key)!r}")
            object.__setattr__(self, key, value)
        if self.sensor_width is not None and int(self.sensor_width) < 1:
            raise SimEnvError(f"sensor_width must be a positive number of pixels or None, got {self.sensor_width}")

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        kinect = _kinect(cls)
        return (cls(shot_noise=tuple(s * v for v in kinect.shot_noise),  # type: ignore[arg-type]
                    read_noise=tuple(s * v for v in kinect.read_noise),  # type: ignore[arg-type]
                    sensor_width=kinect.sensor_width),)  # fmt: skip

    @property
    def changes_image(self) -> bool:
        return any(self.shot_noise) or any(self.read_noise)

    def draws(self, shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray | None:
        """The (H, W, 3) float32 standard normal draws :meth:`apply` makes from ``rng`` for an image of ``shape``,
        or None when there is no noise (no draw)."""
        if not self.changes_image:
            return None
        return rng.standard_normal(shape, dtype=np.float32)

    def apply(self, x: np.ndarray, rng: np.random.Generator | None = None, *,
              normals: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """``x`` (H, W, 3) linear sensor signal plus shot noise (std ``sqrt(x) * shot_noise``) and read noise (std
        ``read_noise``) per channel, both scaled by ``width / sensor_width`` (at most 1) when ``sensor_width`` is
        set, as float32; no draw when both are zero. The standard normal draws come from ``normals`` when given
        (:meth:`draws`), else from ``rng``."""
        if not self.changes_image:
            return x
        if normals is None:
            if rng is None:
                raise ValueError("linear_noise needs rng or normals (the camera has noise)")
            normals = self.draws(x.shape, rng)
        scale = 1.0 if self.sensor_width is None else min(1.0, x.shape[1] / self.sensor_width)
        shot = np.asarray(self.shot_noise, dtype=np.float32) * np.float32(scale)
        read = np.asarray(self.read_noise, dtype=np.float32) * np.float32(scale)
        std = np.maximum(x, 0.0)  # std = sqrt(max(x, 0) shot^2 + read^2), computed in place (the same float32 steps)
        std *= shot**2
        std += read**2
        np.sqrt(std, out=std)
        std *= normals
        std += x
        return std

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        return self.apply(x, frame.rng, normals=frame.normals)


@dataclass(frozen=True)
class MotionBlur(CameraStage):
    """Motion blur over the exposure: ``blur_subframes`` renders per frame spread over the union of the rows'
    exposure windows (1 = one render at the frame's pose: no blur and no rolling shutter, whatever the exposure),
    each row the mean of the renders over its exposure box (:func:`sim_envs.sensor.camera_sensor.row_weights`)."""

    blur_subframes: int = 1

    order: ClassVar[float] = 20.0
    photometric: ClassVar[bool] = False
    effect: ClassVar[str | None] = "blur"
    strength: ClassVar[str] = ("motion blur, exposure s x half the frame interval (kinect's; 2 = the whole interval), "
                               "global shutter")  # fmt: skip
    axis_title: ClassVar[str] = "motion blur alone, exposure x half a frame interval"
    sweep_strengths: ClassVar[tuple[float, ...]] = (0.5, 1.0, 2.0)
    max_strength: ClassVar[float] = 2.0
    max_strength_means: ClassVar[str] = "an exposure of the whole frame interval"

    def __post_init__(self) -> None:
        if int(self.blur_subframes) != self.blur_subframes or self.blur_subframes < 1:
            raise SimEnvError(f"blur_subframes must be an integer >= 1 (1 = one render), got {self.blur_subframes}")

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        exposure = s * 0.5 / FPS_NOMINAL  # the brightness stays the renderer's: reference exposure = exposure
        return Exposure(exposure_s=exposure, reference_exposure_s=exposure), cls(blur_subframes=5)

    @property
    def changes_image(self) -> bool:
        return self.blur_subframes > 1

    def times(self, readout_s: float, exposure_s: float, height: int) -> np.ndarray:
        """(K,) float64 render times relative to the frame's timestamp: ``blur_subframes`` times evenly spread over
        ``[-(readout_s + exposure_s) / 2, +(readout_s + exposure_s) / 2]`` (just ``[0]`` for one sub-frame or a
        zero window). With an odd count the middle time is 0, so the frame's own render is one of them."""
        k = int(self.blur_subframes)
        half = 0.5 * (readout_s * (height > 1) + exposure_s)
        if k == 1 or half == 0:
            return np.zeros(1)
        return np.linspace(-half, half, k)

    def combine(self, renders: list[np.ndarray], times: np.ndarray, readout_s: float,
                exposure_s: float) -> np.ndarray:  # fmt: skip
        """The (H, W, 3) float32 linear image of the renders made at ``times``: each row the mean over its exposure
        box, centred on the row's time under a rolling-shutter readout of ``readout_s``."""
        if len(renders) == 1:
            return renders[0]
        weights = row_weights(times, row_times(renders[0].shape[0], readout_s), exposure_s)
        return np.einsum("kh,khwc->hwc", weights, np.stack(renders), optimize=True)


@dataclass(frozen=True)
class AutoExposure(CameraStage):
    """Auto-exposure and the analogue gain (the ``signal`` hook multiplies by the frame's gain).

    auto_exposure: whether a first-order controller sets each frame's exposure
    (:func:`sim_envs.sensor.camera_effects.auto_exposure`); ae_target: the mean linear brightness it aims at; ae_rate:
    the
    fraction of the log-brightness error corrected per frame (1 = no lag; 0.2 = a time constant of about 5 frames);
    ae_min_s, ae_max_s: exposure limits in seconds (the longest exposure is at most a frame interval); max_gain: the
    analogue gain the controller may add once the exposure is at ``ae_max_s`` (it amplifies noise); exposure_jitter:
    std of a per-frame log-normal factor on the effective exposure (exposure x gain), drawn from the frame's own
    generator, that the controller sees and corrects like any brightness change (real auto-exposure hunts; 0 = off).
    """

    auto_exposure: bool = True
    ae_target: float = 0.18
    ae_rate: float = 0.25
    ae_min_s: float = 1e-4
    ae_max_s: float = 1.0 / FPS_NOMINAL
    max_gain: float = 1.0
    exposure_jitter: float = 0.0

    order: ClassVar[float] = 70.0
    effect: ClassVar[str | None] = "exposure"
    strength: ClassVar[str] = "auto-exposure with kinect's lag, per-frame exposure jitter s x kinect's (1 %)"
    axis_title: ClassVar[str] = "auto-exposure alone, exposure jitter x kinect's"
    sweep_strengths: ClassVar[tuple[float, ...]] = (1.0, 3.0, 6.0)

    def __post_init__(self) -> None:
        _positive(self, "ae_target", "ae_min_s", "ae_max_s")
        if not 0 < self.ae_rate <= 1:
            raise SimEnvError(f"ae_rate must be in (0, 1], got {self.ae_rate}")
        if self.ae_min_s > self.ae_max_s:
            raise SimEnvError(f"ae_min_s ({self.ae_min_s}) must not exceed ae_max_s ({self.ae_max_s})")
        if not (np.isfinite(self.max_gain) and self.max_gain >= 1):
            raise SimEnvError(f"max_gain must be >= 1, got {self.max_gain}")
        if not (np.isfinite(self.exposure_jitter) and self.exposure_jitter >= 0):
            raise SimEnvError(f"exposure_jitter must be >= 0, got {self.exposure_jitter}")

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        kinect = _kinect(cls)
        return (_kinect(Response), _kinect(Exposure),
                dataclasses.replace(kinect, exposure_jitter=s * kinect.exposure_jitter))  # fmt: skip

    @property
    def changes_image(self) -> bool:
        return bool(self.auto_exposure) or self.exposure_jitter > 0

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        x *= np.float32(frame.gain)
        return x


@dataclass(frozen=True)
class RollingShutter(CameraStage):
    """A rolling shutter: ``readout_s`` seconds from the first row's exposure to the last row's (0 = global
    shutter). It acts through :class:`MotionBlur`'s sub-frames (with one render it changes nothing)."""

    readout_s: float = 0.0

    order: ClassVar[float] = 21.0
    photometric: ClassVar[bool] = False
    effect: ClassVar[str | None] = "rolling_shutter"
    strength: ClassVar[str] = "rolling-shutter readout of s frame intervals (kinect: 0.05, hard: 0.5), 1 ms exposure"
    axis_title: ClassVar[str] = "rolling shutter alone, readout in frame intervals"
    sweep_strengths: ClassVar[tuple[float, ...]] = (0.1, 0.5, 1.0)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.readout_s) and self.readout_s >= 0):
            raise SimEnvError(f"readout_s must be >= 0 seconds, got {self.readout_s}")

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        return (Exposure(exposure_s=1e-3, reference_exposure_s=1e-3),
                MotionBlur(blur_subframes=max(3, int(np.ceil(8 * s)))), cls(readout_s=s / FPS_NOMINAL))  # fmt: skip

    @property
    def changes_image(self) -> bool:
        return False  # alone (one render) it changes nothing; with sub-frames, MotionBlur does


@dataclass(frozen=True)
class Distortion(CameraStage):
    """Lens distortion: OpenCV radial-tangential ``(k1, k2, p1, p2, k3)`` (zeros: none); each linear render is
    resampled onto the distorted sensor grid (``warp``). The delivered images are undistorted again
    (:func:`sim_envs.sensor.camera_effects.undistort_image`)."""

    distortion: tuple[float, float, float, float, float] = field(default=NO_DISTORTION)

    order: ClassVar[float] = 10.0
    photometric: ClassVar[bool] = False
    effect: ClassVar[str | None] = "distortion"
    strength: ClassVar[str] = "lens distortion s x TUM fr1's coefficients, undistorted for the agent"
    axis_title: ClassVar[str] = "lens distortion alone, x TUM fr1's"
    sweep_strengths: ClassVar[tuple[float, ...]] = (0.5, 1.0, 2.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "distortion", CameraModel(Intrinsics(1, 1, 0, 0, 1, 1), self.distortion).distortion)

    @classmethod
    def alone(cls, s: float) -> tuple[CameraStage, ...]:
        return (cls(distortion=tuple(s * c for c in preset_distortion("tum_fr1"))),)  # type: ignore[arg-type]

    @property
    def changes_image(self) -> bool:
        return any(c != 0.0 for c in self.distortion)

    def warp(self, linear: np.ndarray, frame: FrameContext) -> np.ndarray:
        if frame.distort is None:
            return linear
        return cv2.remap(linear, *frame.distort, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


# ------------------------------------------------------------------------------------------------ the other stages
@dataclass(frozen=True)
class Exposure(CameraStage):
    """Scene light and exposure: the linear sensor signal is ``L * scene_light * exposure_s / reference_exposure_s``.

    scene_light: scale of the scene's irradiance (1 = as rendered; < 1 a darker room); reference_exposure_s: the
    exposure at which, with scene_light 1, gain 1 and no vignetting, a pixel keeps the renderer's value; exposure_s:
    the exposure time when auto-exposure is off (and the first frame's guess when it is on)."""

    scene_light: float = 1.0
    reference_exposure_s: float = 1.0 / 60.0
    exposure_s: float = 1.0 / 60.0

    order: ClassVar[float] = 30.0

    def __post_init__(self) -> None:
        _positive(self, "scene_light", "reference_exposure_s")
        if not (np.isfinite(self.exposure_s) and self.exposure_s >= 0):
            raise SimEnvError(f"exposure_s must be >= 0 seconds, got {self.exposure_s}")

    @property
    def changes_image(self) -> bool:
        return self.scene_light != 1.0 or self.exposure_s != self.reference_exposure_s

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        x *= np.float32(self.scene_light * frame.exposure_s / self.reference_exposure_s)
        return x


@dataclass(frozen=True)
class Vignetting(CameraStage):
    """Vignetting: irradiance at the image corner farthest from the principal point relative to the principal point
    is ``vignette_corner`` (1 = none); the fall-off is cos^4-shaped (:func:`sim_envs.sensor.camera_sensor.vignette`)."""

    vignette_corner: float = 1.0

    order: ClassVar[float] = 40.0

    def __post_init__(self) -> None:
        if not 0 < self.vignette_corner <= 1:
            raise SimEnvError(f"vignette_corner must be in (0, 1] (1 = no vignetting), got {self.vignette_corner}")

    @property
    def changes_image(self) -> bool:
        return self.vignette_corner != 1.0

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        if frame.vignette is not None:
            x *= frame.vignette[..., None]
        return x


@dataclass(frozen=True)
class FullWell(CameraStage):
    """The sensor saturates at its full well (a linear signal of 1) before the noise is read."""

    order: ClassVar[float] = 50.0

    @property
    def changes_image(self) -> bool:
        return False  # renders are in [0, 1]: only a stage before it that brightens makes it clip

    def signal(self, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        np.minimum(x, np.float32(1.0), out=x)
        return x


_ENCODE_STEPS = 1 << 18  # linear steps of the encoding table (a step moves the output by < 0.02 levels)


@dataclass(frozen=True)
class Response(CameraStage):
    """The camera response function ``f`` and 8-bit quantisation. response: "srgb" (IEC 61966-2-1 encoding; what
    the renderer's bytes are read as, so the neutral choice) or "gamma" (``x ** (1 / response_gamma)``);
    response_gamma: the exponent of "gamma" (2.2: the common display gamma)."""

    response: ResponseCurve = "srgb"
    response_gamma: float = 2.2

    order: ClassVar[float] = 80.0

    def __post_init__(self) -> None:
        if self.response not in RESPONSES:
            raise UnknownNameError(f"unknown response {self.response!r}; valid: {', '.join(RESPONSES)}")
        _positive(self, "response_gamma")

    @property
    def changes_image(self) -> bool:
        return self.response != "srgb"

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Linear signal in [0, 1] (clipped) -> encoded value in [0, 1], float64."""
        x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
        if self.response == "srgb":
            return linear_to_srgb(x)
        return x ** (1.0 / self.response_gamma)

    def inverse(self) -> np.ndarray:
        """(256,) float64 ``G(k) = 255 * f^-1(k / 255)``: the linear signal of each 8-bit value, on the 0-255 scale
        of TUM monoVO's ``pcalib.txt`` (G(0) = 0, G(255) = 255)."""
        k = np.arange(256) / 255.0
        linear = srgb_to_linear(k) if self.response == "srgb" else k**self.response_gamma
        return 255.0 * linear

    def encode(self, x: np.ndarray) -> np.ndarray:
        """The response and 8-bit quantisation of a linear signal (clipped to [0, 1]; changed in place): uint8 of
        the same shape, ``rint(255 f(x))`` read from a table of 2^18 + 1 linear steps (x rounded to the nearest step
        first)."""
        t = np.clip(x, 0.0, 1.0)
        t *= np.float32(_ENCODE_STEPS)  # in place: the same float32 operations as rint(clip(x) * steps), fewer copies
        np.rint(t, out=t)
        return np.take(_encode_lut(self.response, float(self.response_gamma)), t.astype(np.int32))


@lru_cache(maxsize=8)
def _encode_lut(response: str, gamma: float) -> np.ndarray:
    curve = Response(response=response, response_gamma=gamma)  # type: ignore[arg-type]
    lut = np.rint(curve.apply(np.arange(_ENCODE_STEPS + 1) / _ENCODE_STEPS) * 255.0).astype(np.uint8)
    lut.setflags(write=False)
    return lut


@dataclass(frozen=True)
class SensorDepth(CameraStage):
    """A Kinect-like sensor depth (:func:`sim_envs.sensor.camera_sensor.kinect_depth`) beside the exact ground truth,
    which
    stays untouched. depth_noise: whether frames carry it."""

    depth_noise: bool = True

    order: ClassVar[float] = 90.0

    @property
    def changes_image(self) -> bool:
        return False

    def depth(self, depth: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        """The sensor depth of an exact planar depth (H, W) float32 metres, or None when off."""
        return kinect_depth(depth, rng) if self.depth_noise else None


# The stages whose parameters are CameraEffects fields of the same names, in chain order.
BUILTIN_STAGES: tuple[type[CameraStage], ...] = tuple(sorted(
    (Distortion, MotionBlur, RollingShutter, Exposure, Vignetting, FullWell, Noise, AutoExposure, Response,
     SensorDepth), key=lambda cls: cls.order))  # fmt: skip


# ---------------------------------------------------------------------------------------------------------- presets
FR1_NOISE_SCALE: float = 2.0  # the fr1 preset's shot and read noise, x ICL-NUIM's (fitted: see PRESET_STAGES["fr1"])
# Each camera preset as an ordered list of stages (chain order); stages left out keep their neutral defaults.
PRESET_STAGES: dict[str, tuple[CameraStage, ...]] = {
    # The renderer's image, byte for byte (what every sequence gave before camera effects existed).
    "clean": (),
    # A TUM / ICL-NUIM-like hand-held RGB-D camera (Kinect v1 class). Sources: noise, ICL-NUIM (real-cameras.md 4),
    # for a 640-px-wide sensor (ICL-NUIM's and the Kinect's resolution; at 320x240 it is the 2x2 area average, as
    # real frames are when loaded); shutter open about half the frame interval at 30 fps as the reference exposure
    # and a rolling-shutter readout of 0.05 of the frame time (BlenderProc's example, real-cameras.md 4); an sRGB
    # response (the 8-bit encoding of consumer cameras; ours). Calibrated on the first 100 frames of 7-Scenes
    # redkitchen against office0 / living0 (results/camera_calibration.md): ae_target (mean grey level 116),
    # exposure_jitter (frame-to-frame change of log mean grey level, std 0.008); vignette_corner 0.9 is a gentle value
    # within that measurement's uncertainty (corner/centre ratios of scene content alone differ by +-8 % between
    # rooms); ae_rate 0.25 (ours: a lag of a few frames). No lens distortion (7-Scenes gives none).
    "kinect": (
        MotionBlur(blur_subframes=3),
        RollingShutter(readout_s=0.05 / FPS_NOMINAL),
        Exposure(reference_exposure_s=0.5 / FPS_NOMINAL, exposure_s=0.5 / FPS_NOMINAL),
        Vignetting(vignette_corner=0.90),
        Noise(shot_noise=ICL_SHOT_NOISE, read_noise=ICL_READ_NOISE, sensor_width=640),
        AutoExposure(ae_target=0.20, ae_rate=0.25, ae_min_s=1e-3, ae_max_s=1.0 / FPS_NOMINAL, max_gain=2.0,
                     exposure_jitter=0.010),  # fmt: skip
        Response(response="srgb"),
        SensorDepth(),
    ),
    # TUM fr1 (a Kinect v1 on fr1/desk: fast hand-held motion, rolling shutter, motion blur, auto-exposure), as kinect
    # was made from the 7-Scenes kitchen. Fitted on the image statistics of fr1/desk's first 100 frames against the
    # first 100 frames of office_fr1motion / living_fr1motion (hand-held at fr1/desk's ground-truth motion
    # statistics), never on SLAM results (results/camera_calibration_fr1.md; `python -m
    # sim_envs.tools.cli_camera_calibration --real ../shared/data/real/rgbd_dataset_freiburg1_desk --sequences
    # office_fr1motion living_fr1motion --presets fr1 kinect clean --depth`): ae_target 0.34 (mean grey level 137
    # real, 137 / 136 simulated), exposure_jitter 0.026 (std of the frame-to-frame change of log mean grey level 0.020
    # real, 0.020 / 0.020), FR1_NOISE_SCALE (noise on flat regions 0.41 real, 0.37 / 0.38). From the camera's
    # published calibration: the TUM fr1 lens (SOURCE.md; the real folder is undistorted by the loader, so the
    # simulated images are too). Not measured (ours; no statistic of the calibration tool resolves them apart from
    # scene content): exposure up to the whole frame interval with 5 sub-frames (fr1/desk's strong blur), a
    # rolling-shutter readout of half the frame interval, and kinect's vignetting, ae_rate, response and sensor depth.
    "fr1": (
        Distortion(distortion=preset_distortion("tum_fr1")),
        MotionBlur(blur_subframes=5),
        RollingShutter(readout_s=0.5 / FPS_NOMINAL),
        Exposure(reference_exposure_s=0.5 / FPS_NOMINAL, exposure_s=0.5 / FPS_NOMINAL),
        Vignetting(vignette_corner=0.90),
        Noise(shot_noise=tuple(FR1_NOISE_SCALE * v for v in ICL_SHOT_NOISE),  # type: ignore[arg-type]
              read_noise=tuple(FR1_NOISE_SCALE * v for v in ICL_READ_NOISE),  # type: ignore[arg-type]
              sensor_width=640),  # fmt: skip
        AutoExposure(ae_target=0.34, ae_rate=0.25, ae_min_s=1e-3, ae_max_s=1.0 / FPS_NOMINAL, max_gain=2.0,
                     exposure_jitter=0.026),  # fmt: skip
        Response(response="srgb"),
        SensorDepth(),
    ),
    # TartanAir-like stress (ours): a dim room (a quarter of the light), so exposure runs at its longest (a whole
    # frame interval: strong blur) with up to 4x gain (noisier; ICL noise at the image's own resolution); a fast
    # controller (ae_rate 0.7) and 3 % exposure jitter (exposure changes from frame to frame); a readout of half
    # the frame interval; a gamma-2.2 response; strong vignetting; the TUM fr1 lens (reference-facts.md).
    "hard": (
        Distortion(distortion=preset_distortion("tum_fr1")),
        MotionBlur(blur_subframes=5),
        RollingShutter(readout_s=0.5 / FPS_NOMINAL),
        Exposure(scene_light=0.25, reference_exposure_s=0.5 / FPS_NOMINAL, exposure_s=1.0 / FPS_NOMINAL),
        Vignetting(vignette_corner=0.55),
        Noise(shot_noise=ICL_SHOT_NOISE, read_noise=ICL_READ_NOISE),
        AutoExposure(ae_target=0.18, ae_rate=0.7, ae_min_s=1e-3, ae_max_s=1.0 / FPS_NOMINAL, max_gain=4.0,
                     exposure_jitter=0.03),  # fmt: skip
        Response(response="gamma", response_gamma=2.2),
        SensorDepth(),
    ),
}
