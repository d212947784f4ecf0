"""A simulated camera that behaves like a real one: response curve, vignetting, auto-exposure, linear-domain noise,
motion blur over the exposure, rolling shutter, lens distortion, 8-bit quantisation, and Kinect-like depth noise.

The camera is a chain of stages, one class per effect (:mod:`sim_envs.sensor.camera_stages`, whose docstring gives the
order
of image formation); :class:`CameraEffects` is the frozen configuration of one camera, made from an ordered list of
stages (:meth:`CameraEffects.from_stages`), every part switchable. Named presets (:func:`camera_effect_presets`,
:func:`camera_effects_preset`, :data:`sim_envs.sensor.camera_stages.PRESET_STAGES`): ``clean`` (the renderer's image as
it
is), ``kinect`` (a TUM / ICL-NUIM-like hand-held RGB-D camera) and ``hard`` (low light, strong blur, long
rolling-shutter readout, fast exposure changes, TUM fr1 lens distortion); one effect alone at a strength,
``"<effect>:<s>"`` (:func:`single_effect`, :data:`SINGLE_EFFECTS`: the stage classes that name an ``effect``).

:func:`sensor_image` forms one frame: the renders at the sub-frame times, each warped by the stages' ``warp`` hooks
(the lens), combined over the rows' exposure windows (blur, rolling shutter), then the linear signal through the
stages' ``signal`` hooks (exposure, vignetting, saturation, noise, gain), the response and 8-bit quantisation, and the
``encoded`` hooks.

Auto-exposure (:func:`auto_exposure`) is a first-order controller on the mean linear brightness of the previous
frames, so exposure lags behind changes of scene brightness; frame i's exposure depends on the brightness of
frames 0..i-1 only, which makes it a deterministic function of the sequence and i (the sequence computes the
brightness of every frame up to i on cheap low-resolution renders and caches it).

Ground truth (depth, labels, instances) is never touched: it stays the exact pinhole render at the frame's pose.
:func:`kinect_depth` makes a separate, noisy "sensor depth" (simkinect) for users who want one. All randomness comes
from a ``numpy.random.Generator`` passed in.

Conventions: images H x W, uint8 RGB (H, W, 3); linear images float32 in [0, 1]; depth metric planar z; camera x
right, y down, z forward; poses ``T_world_cam``; times in seconds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np

from sim_envs.camera import CameraModel, Intrinsics, pinhole_maps
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.sensor.camera_sensor import (  # noqa: F401  (re-exported: the camera's public names live here)
    FPS_NOMINAL,
    ICL_READ_NOISE,
    ICL_SHOT_NOISE,
    KINECT_BASELINE_M,
    KINECT_FOCAL_PX,
    KINECT_SHIFT_STD_PX,
    KINECT_SUBPIXEL,
    decode_render,
    distortion_maps,
    kinect_depth,
    linear_to_srgb,
    row_times,
    row_weights,
    srgb_to_linear,
    vignette,
)
from sim_envs.sensor.camera_stages import (  # noqa: F401  (re-exported)
    BUILTIN_STAGES,
    PRESET_STAGES,
    RESPONSES,
    SINGLE_EFFECTS,
    AutoExposure,
    CameraStage,
    Distortion,
    Exposure,
    FrameContext,
    FullWell,
    MotionBlur,
    Noise,
    ResponseCurve,
    RollingShutter,
    SensorDepth,
    Vignetting,
    effect_stage,
    sweep_effects,
)
from sim_envs.sensor.camera_stages import Response as ResponseStage

Response = ResponseCurve  # the response kinds ("srgb", "gamma"), as the fields name them


@dataclass(frozen=True)
class CameraEffects:
    """What a simulated camera does to the rendered image. Every default is off: ``CameraEffects()`` is the clean
    camera (the renderer's bytes). Frozen and hashable; :meth:`describe` gives a JSON-ready dict.

    name: a label (the preset's name; "custom" for a hand-made one), recorded with runs. The other fields are the
    built-in stages' parameters, under the same names (each documented and checked on its class in
    :mod:`sim_envs.sensor.camera_stages`):

    - :class:`~sim_envs.sensor.camera_stages.Response`: response ("srgb" or "gamma"), response_gamma;
    - :class:`~sim_envs.sensor.camera_stages.Vignetting`: vignette_corner (1 = none);
    - :class:`~sim_envs.sensor.camera_stages.Exposure`: scene_light, reference_exposure_s, exposure_s;
    - :class:`~sim_envs.sensor.camera_stages.AutoExposure`: auto_exposure (default off), ae_target, ae_rate, ae_min_s,
      ae_max_s, max_gain, exposure_jitter;
    - :class:`~sim_envs.sensor.camera_stages.Noise`: shot_noise, read_noise (per channel R, G, B), sensor_width;
    - :class:`~sim_envs.sensor.camera_stages.MotionBlur`: blur_subframes (1 = one render: no blur, no rolling shutter);
    - :class:`~sim_envs.sensor.camera_stages.RollingShutter`: readout_s (0 = global shutter);
    - :class:`~sim_envs.sensor.camera_stages.Distortion`: distortion, OpenCV ``(k1, k2, p1, p2, k3)`` (zeros: none);
    - :class:`~sim_envs.sensor.camera_stages.SensorDepth`: depth_noise (default off), a Kinect-like sensor depth
      (:func:`kinect_depth`) besides the exact ground truth.

    extra_stages: the camera's other stages (stage classes without fields here), run in chain order with the
    built-in ones (:attr:`stages`).
    """

    name: str = "custom"
    response: ResponseCurve = ResponseStage.response
    response_gamma: float = ResponseStage.response_gamma
    vignette_corner: float = Vignetting.vignette_corner
    scene_light: float = Exposure.scene_light
    reference_exposure_s: float = Exposure.reference_exposure_s
    exposure_s: float = Exposure.exposure_s
    auto_exposure: bool = False
    ae_target: float = AutoExposure.ae_target
    ae_rate: float = AutoExposure.ae_rate
    ae_min_s: float = AutoExposure.ae_min_s
    ae_max_s: float = AutoExposure.ae_max_s
    max_gain: float = AutoExposure.max_gain
    exposure_jitter: float = AutoExposure.exposure_jitter
    shot_noise: tuple[float, float, float] = Noise.shot_noise
    read_noise: tuple[float, float, float] = Noise.read_noise
    sensor_width: int | None = Noise.sensor_width
    blur_subframes: int = MotionBlur.blur_subframes
    readout_s: float = RollingShutter.readout_s
    distortion: tuple[float, float, float, float, float] = Distortion.distortion
    depth_noise: bool = False
    extra_stages: tuple[CameraStage, ...] = field(default=())

    def __post_init__(self) -> None:
        chain: list[CameraStage] = []
        for cls in BUILTIN_STAGES:  # each stage checks and normalises its own parameters
            stage = cls(**{f.name: getattr(self, f.name) for f in dataclasses.fields(cls)})  # type: ignore[call-arg]
            for key, value in stage.params().items():
                object.__setattr__(self, key, value)
            chain.append(stage)
        extra = tuple(self.extra_stages)
        for stage in extra:
            if not isinstance(stage, CameraStage) or type(stage) in BUILTIN_STAGES:
                raise SimEnvError(f"extra_stages takes camera stages other than the built-in ones "
                                  f"({', '.join(c.__name__ for c in BUILTIN_STAGES)}), got {stage!r}")  # fmt: skip
        object.__setattr__(self, "extra_stages", extra)
        object.__setattr__(self, "_chain", tuple(sorted(chain + list(extra), key=lambda s: s.order)))

    @classmethod
    def from_stages(cls, name: str, stages: Iterable[CameraStage]) -> CameraEffects:
        """The camera named ``name`` made of ``stages`` (each class at most once; the built-in ones not given keep
        their neutral defaults). :class:`SimEnvError` for a stage given twice."""
        values: dict[str, Any] = {}
        extra: list[CameraStage] = []
        seen: set[type] = set()
        for stage in stages:
            if type(stage) in seen:
                raise SimEnvError(f"camera {name!r}: stage {type(stage).__name__} given twice")
            seen.add(type(stage))
            if type(stage) in BUILTIN_STAGES:
                values.update(stage.params())
            else:
                extra.append(stage)
        return cls(name=name, extra_stages=tuple(extra), **values)

    @property
    def stages(self) -> tuple[CameraStage, ...]:
        """The camera's chain: every built-in stage (neutral ones included) and the extra stages, in chain order."""
        return self._chain  # type: ignore[attr-defined, no-any-return]

    def stage(self, cls: type[Any]) -> Any:
        """The camera's stage of class ``cls`` (None if it has none)."""
        return next((s for s in self.stages if type(s) is cls), None)

    @property
    def any(self) -> bool:
        """Whether this camera changes the renderer's image at all (False: the clean camera, same bytes)."""
        return any(s.changes_image for s in self.stages)

    @property
    def photometric(self) -> bool:
        """Whether the pixel values go through exposure, vignetting, noise or a non-neutral response."""
        return any(s.changes_image for s in self.stages if s.photometric)

    @property
    def distorted(self) -> bool:
        """Whether the lens has distortion."""
        return any(c != 0.0 for c in self.distortion)

    def describe(self) -> dict[str, Any]:
        """JSON-ready parameters (lists for tuples), e.g. for run records and fingerprints; ``extra_stages`` (each
        stage's :meth:`~sim_envs.sensor.camera_stages.CameraStage.describe`) only when there are some."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.name != "extra_stages"}
        out = {k: list(v) if isinstance(v, tuple) else v for k, v in out.items()}
        if self.extra_stages:
            out["extra_stages"] = [s.describe() for s in self.extra_stages]
        return out


# --------------------------------------------------------------------------------------------------------- presets
# The camera every command that renders a simulated sequence sees it through unless told otherwise (bench, generate,
# export, train validate): a hand-held RGB-D camera calibrated on real Kinect frames (results/camera_calibration.md).
DEFAULT_CAMERA_EFFECTS = "kinect"

_PRESETS: dict[str, CameraEffects] = {name: CameraEffects.from_stages(name, stages)
                                      for name, stages in PRESET_STAGES.items()}  # fmt: skip


def camera_effect_presets() -> list[str]:
    """Names of the whole-camera presets of :func:`camera_effects_preset`: ``clean``, ``hard``, ``kinect``."""
    return sorted(_PRESETS)


def single_effect(effect: str, strength: float) -> CameraEffects:
    """The clean camera with one effect of :data:`SINGLE_EFFECTS` at ``strength`` (>= 0; 0 = the clean camera's
    bytes), named ``"<effect>:<strength>"``: the stages of the effect's class (:meth:`CameraStage.alone`).
    :class:`SimEnvError` for an unknown effect or a bad strength."""
    cls = effect_stage(effect)
    s = float(strength)
    if not (np.isfinite(s) and s >= 0):
        raise SimEnvError(f"camera effect {effect!r}: strength must be a finite number >= 0, got {strength!r}")
    if s > cls.max_strength:
        raise SimEnvError(f"camera effect {effect!r}: strength is at most {cls.max_strength:g} "
                          f"({cls.max_strength_means}), got {s:g}")  # fmt: skip
    name = f"{effect}:{s:g}"
    if s == 0:
        return replace(_PRESETS["clean"], name=name)
    return CameraEffects.from_stages(name, cls.alone(s))


def camera_effects_preset(name: str) -> CameraEffects:
    """The camera-effects preset ``name`` (:func:`camera_effect_presets`) or one effect alone, ``"<effect>:<s>"``
    (:func:`single_effect`); :class:`UnknownNameError` listing the valid names otherwise."""
    if name in _PRESETS:
        return _PRESETS[name]
    effect, sep, strength = str(name).partition(":")
    if sep and effect in SINGLE_EFFECTS:
        try:
            value = float(strength)
        except ValueError:
            raise SimEnvError(f"camera effect {name!r}: the strength after ':' must be a number") from None
        return single_effect(effect, value)
    valid = ", ".join(camera_effect_presets())
    raise UnknownNameError(f"unknown camera-effects preset {name!r}; valid presets: {valid}, or one effect alone as "
                           f"EFFECT:STRENGTH with EFFECT one of {', '.join(SINGLE_EFFECTS)}") from None  # fmt: skip


def resolve_camera_effects(value: str | CameraEffects | None) -> CameraEffects:
    """A preset name, a :class:`CameraEffects` or None (clean) as a :class:`CameraEffects`."""
    if value is None:
        return _PRESETS["clean"]
    if isinstance(value, CameraEffects):
        return value
    return camera_effects_preset(str(value))


def with_options(effects: CameraEffects, **changes: Any) -> CameraEffects:
    """``effects`` with some fields replaced and named "<name>+<field>=<value>,..." (for sweeps of one effect)."""
    label = ",".join(f"{k}={v}" for k, v in sorted(changes.items()))
    return replace(effects, name=f"{effects.name}+{label}", **changes)


# ------------------------------------------------------------------------------------- the stages, as functions
def apply_response(x: np.ndarray, effects: CameraEffects) -> np.ndarray:
    """The camera response ``f``: linear signal in [0, 1] (clipped) -> encoded value in [0, 1], float64."""
    return effects.stage(ResponseStage).apply(x)  # type: ignore[no-any-return]


def inverse_response(effects: CameraEffects) -> np.ndarray:
    """(256,) float64 ``G(k) = 255 * f^-1(k / 255)``: the linear signal of each 8-bit value, on the 0-255 scale of
    TUM monoVO's ``pcalib.txt`` (G(0) = 0, G(255) = 255)."""
    return effects.stage(ResponseStage).inverse()  # type: ignore[no-any-return]


def encode(x: np.ndarray, effects: CameraEffects) -> np.ndarray:
    """The camera response and 8-bit quantisation of a linear signal (clipped to [0, 1]): uint8 of the same shape,
    ``rint(255 f(x))`` read from a table of 2^18 + 1 linear steps (x rounded to the nearest step first)."""
    return effects.stage(ResponseStage).encode(x)  # type: ignore[no-any-return]


def subframe_times(effects: CameraEffects, exposure_s: float, height: int) -> np.ndarray:
    """(K,) float64 render times relative to the frame's timestamp (:meth:`MotionBlur.times` under the camera's
    rolling-shutter readout)."""
    return effects.stage(MotionBlur).times(effects.readout_s, exposure_s, height)  # type: ignore[no-any-return]


def auto_exposure(
    brightness: np.ndarray, effects: CameraEffects, jitter: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame exposure time (s) and analogue gain from each frame's mean linear brightness at the reference
    exposure (``brightness``, (N,): mean of ``L * V * scene_light``). Returns two (N,) float64 arrays.

    Off: ``exposure_s`` and gain 1 for every frame. On: the effective exposure E = exposure * gain follows
    ``E_{i+1} = E_i * (ae_target / m_i) ** ae_rate`` with ``m_i = brightness_i * E_i / reference_exposure_s`` the
    brightness frame i was measured at (a first-order controller in log space: lag of about 1 / ae_rate frames);
    E_0 is the settled value of frame 0 (the camera ran before recording started). E is clamped to
    [ae_min_s, ae_max_s * max_gain]; the exposure takes it up to ae_max_s, the gain the rest. Frame i's values
    depend on frames 0..i-1 only (and on its own jitter).

    jitter: (N,) standard normal draws, one per frame; the frame's effective exposure is multiplied by
    ``exp(exposure_jitter * jitter_i)`` (the gain takes the factor, or the exposure when the gain is 1 and the
    factor < 1), and the controller measures the frame as exposed. None or exposure_jitter 0: no jitter.
    """
    b = np.maximum(np.asarray(brightness, dtype=np.float64), 1e-6)
    n = b.shape[0]
    factor = np.ones(n)
    if jitter is not None and effects.exposure_jitter > 0:
        factor = np.exp(effects.exposure_jitter * np.asarray(jitter, dtype=np.float64)[:n])
    if not effects.auto_exposure:
        E = effects.exposure_s * factor
    else:
        lo, hi = effects.ae_min_s, effects.ae_max_s * effects.max_gain
        E = np.empty(n)
        settled = np.clip(effects.reference_exposure_s * effects.ae_target / b[0], lo, hi) if n else 0.0
        for i in range(n):
            E[i] = settled * factor[i]
            measured = b[i] * E[i] / effects.reference_exposure_s
            settled = np.clip(settled * (effects.ae_target / measured) ** effects.ae_rate, lo, hi)
    exposure = np.minimum(E, max(effects.ae_max_s, effects.exposure_s))
    return exposure, E / np.where(exposure > 0, exposure, 1.0)


def mean_brightness(rgb: np.ndarray, effects: CameraEffects, vignette_map: np.ndarray | None = None) -> float:
    """Mean linear brightness of a render at the reference exposure: mean of ``L * V * scene_light`` over pixels
    and channels (``vignette_map`` (H, W) at the render's size; None: no vignetting)."""
    linear = decode_render(rgb)
    if vignette_map is not None:
        linear = linear * vignette_map[..., None]
    return float(linear.mean()) * effects.scene_light


def noise_draws(shape: tuple[int, ...], effects: CameraEffects, rng: np.random.Generator) -> np.ndarray | None:
    """The (H, W, 3) float32 standard normal draws :func:`linear_noise` makes from ``rng`` for an image of
    ``shape``, or None when the camera has no noise (no draw). Drawn ahead, they let the draw run beside the
    renders: ``linear_noise(x, effects, rng)`` equals ``linear_noise(x, effects, normals=noise_draws(...))``."""
    return effects.stage(Noise).draws(shape, rng)  # type: ignore[no-any-return]


def linear_noise(x: np.ndarray, effects: CameraEffects, rng: np.random.Generator | None = None, *,
                 normals: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``x`` (H, W, 3) linear sensor signal plus the camera's shot and read noise (:meth:`Noise.apply`)."""
    return effects.stage(Noise).apply(x, rng, normals=normals)  # type: ignore[no-any-return]


# ---------------------------------------------------------------------------------------------- the sensor image
def expose(linear: np.ndarray, effects: CameraEffects, exposure_s: float, gain: float,
           rng: np.random.Generator | None, vignette_map: np.ndarray | None = None, *,
           normals: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Linear radiance (H, W, 3) float -> (H, W, 3) uint8 camera image: the stages' ``signal`` hooks in chain order
    (exposure and scene light, vignetting, saturation, noise from ``normals`` when given else from ``rng``, gain),
    the response and 8-bit quantisation, then their ``encoded`` hooks."""
    frame = FrameContext(float(exposure_s), float(gain), rng, normals, vignette_map)
    x = np.array(linear, dtype=np.float32)  # a copy: the stages work in place
    for stage in effects.stages:
        x = stage.signal(x, frame)
    rgb = encode(x, effects)
    for stage in effects.stages:
        rgb = stage.encoded(rgb, frame)
    return rgb


@dataclass(frozen=True)
class SensorGeometry:
    """Precomputed maps of a camera at one image size: vignette (H, W) float32 or None, distortion maps (map_u,
    map_v) or None, undistortion maps (to the pinhole camera ``delivered``, for the agent's images) or None, and
    ``ground_truth`` maps (the exact pinhole renders resampled onto ``delivered``'s grid) or None; ``delivered``: the
    intrinsics of the delivered images (:meth:`sim_envs.camera.CameraModel.rectified`: the rendered camera's own when
    the lens has no distortion)."""

    vignette: np.ndarray | None
    distort: tuple[np.ndarray, np.ndarray] | None
    undistort: tuple[np.ndarray, np.ndarray] | None
    delivered: Intrinsics | None = None
    ground_truth: tuple[np.ndarray, np.ndarray] | None = None


def sensor_geometry(intrinsics: Intrinsics, effects: CameraEffects) -> SensorGeometry:
    """The vignette and distortion maps of ``effects`` at ``intrinsics``' size (computed once per sequence)."""
    vig = vignette(intrinsics, effects.vignette_corner) if effects.vignette_corner != 1.0 else None
    if not effects.distorted:
        return SensorGeometry(vig, None, None, intrinsics)
    model = CameraModel(intrinsics, effects.distortion)
    delivered = model.rectified()
    ground_truth = pinhole_maps(intrinsics, delivered)
    if (ground_truth[0].min() < -0.5 or ground_truth[0].max() > intrinsics.width - 0.5
            or ground_truth[1].min() < -0.5 or ground_truth[1].max() > intrinsics.height - 0.5):  # fmt: skip
        raise SimEnvError(
            f"lens distortion {effects.distortion} sees wider than the rendered pinhole camera (barrel distortion, "
            "k1 < 0): the simulated camera supports lenses whose undistorted view lies inside the render "
            "(pincushion-like, k1 >= 0, as the TUM fr1 and fr2 calibrations)"
        )
    return SensorGeometry(vig, distortion_maps(intrinsics, effects.distortion), model.undistort_maps(), delivered,
                          ground_truth)  # fmt: skip


def sensor_image(
    render_rgb: Callable[[np.ndarray], np.ndarray],
    pose_at: Callable[[np.ndarray], np.ndarray],
    t: float,
    effects: CameraEffects,
    intrinsics: Intrinsics,
    rng: np.random.Generator,
    *,
    exposure_s: float | None = None,
    gain: float = 1.0,
    geometry: SensorGeometry | None = None,
    own_render: np.ndarray | None = None,
    normals: Callable[[], np.ndarray | None] | None = None,
) -> np.ndarray:
    """The raw (H, W, 3) uint8 sensor image of the frame at time ``t`` (seconds): distorted when the lens is.

    render_rgb: a pinhole render of ``intrinsics`` at a ``T_world_cam`` (4, 4) -> (H, W, 3) uint8; pose_at: times
    (M,) -> (M, 4, 4) ``T_world_cam``; exposure_s: this frame's exposure (None: ``effects.exposure_s``); gain: its
    analogue gain; geometry: :func:`sensor_geometry` (computed here when None); own_render: the render at ``t``
    if already made (used for the time-0 sub-frame). Randomness (noise) from ``rng`` only, or, when ``normals`` is
    given, from what it returns (called after the renders: e.g. a future's ``result`` of :func:`noise_draws` from
    ``rng``, drawn beside the renders, with the same bytes).
    """
    exposure = effects.exposure_s if exposure_s is None else float(exposure_s)
    geometry = geometry or sensor_geometry(intrinsics, effects)
    frame = FrameContext(exposure, float(gain), rng, None, geometry.vignette, geometry.distort)
    times = subframe_times(effects, exposure, intrinsics.height)
    renders = []
    for dt, T in zip(times, pose_at(t + times), strict=True):
        linear = decode_render(own_render if (dt == 0.0 and own_render is not None) else render_rgb(T))
        for stage in effects.stages:
            linear = stage.warp(linear, frame)
        renders.append(linear)
    linear = effects.stage(MotionBlur).combine(renders, times, effects.readout_s, exposure)
    drawn = normals() if normals is not None else None
    return expose(linear, effects, exposure, gain, None if drawn is not None else rng, geometry.vignette,
                  normals=drawn)  # fmt: skip


def undistort_image(rgb: np.ndarray, geometry: SensorGeometry) -> np.ndarray:
    """A distorted sensor image resampled to the pinhole image of ``geometry.delivered`` (bilinear), as
    :class:`sim_envs.folders.datasets.RgbdFolder` does with a real distorted camera; the image itself when the lens has
    no
    distortion."""
    if geometry.undistort is None:
        return rgb
    return cv2.remap(rgb, *geometry.undistort, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def ground_truth_on_delivered_grid(image: np.ndarray, geometry: SensorGeometry) -> np.ndarray:
    """An exact pinhole render (depth, labels or instance ids) resampled onto the delivered images' grid by nearest
    neighbour (no depth of no surface, no averaged ids); the image itself when the lens has no distortion."""
    if geometry.ground_truth is None:
        return image
    return cv2.remap(image, *geometry.ground_truth, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
