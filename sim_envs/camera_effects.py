"""A simulated camera that behaves like a real one: response curve, vignetting, auto-exposure, linear-domain noise,
motion blur over the exposure, rolling shutter, lens distortion, 8-bit quantisation, and Kinect-like depth noise.

Everything a camera does is in one frozen dataclass, :class:`CameraEffects`, every part switchable; named presets
(:func:`camera_effect_presets`, :func:`camera_effects_preset`): ``clean`` (the renderer's image as it is), ``kinect``
(a TUM / ICL-NUIM-like hand-held RGB-D camera) and ``hard`` (low light, strong blur, long rolling-shutter readout,
fast exposure changes, TUM fr1 lens distortion).

Image formation of one frame (:func:`sensor_image`), in this order:

1. the renderer's uint8 RGB is read as sRGB-encoded scene radiance and decoded to linear values in [0, 1]
   (:func:`srgb_to_linear`); renders are made at the sub-frame times of :func:`subframe_times`;
2. lens distortion (OpenCV radial-tangential, ``distortion``) resamples each linear render onto the sensor grid with
   ``cv2.remap`` (:func:`distortion_maps`; pixels seeing rays outside the pinhole render are 0);
3. motion blur and rolling shutter: sensor row r integrates a box of width ``exposure_s`` centred on
   ``t + readout_s * (r / (H - 1) - 1/2)`` (the middle row is exposed around the frame's timestamp, whose pose is the
   ground truth); the box is integrated over the renders by linear interpolation in time (:func:`row_weights`);
4. vignetting (a radial fall-off ``V``, :func:`vignette`), scene light, exposure: the sensor signal is
   ``x = L * V * scene_light * exposure_s / reference_exposure_s`` (at the reference exposure, full light and no
   vignetting a pixel gets the renderer's value back);
5. shot and read noise in the linear domain (ICL-NUIM model: std ``sqrt(x) * shot_noise`` and ``read_noise`` per
   channel), then the analogue gain;
6. the camera response function ``f`` (:func:`apply_response`), then 8-bit quantisation.

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
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any, Literal

import cv2
import numpy as np

from sim_envs.camera import NO_DISTORTION, CameraModel, Intrinsics, pinhole_maps, preset_distortion
from sim_envs.errors import SimEnvError, UnknownNameError

Response = Literal["srgb", "gamma"]
RESPONSES: tuple[str, ...] = ("srgb", "gamma")
FPS_NOMINAL: float = 30.0  # Kinect v1 / TUM RGB-D / ICL-NUIM frame rate

# ICL-NUIM RGB noise as reimplemented in ShudaLi/rgbd_simulation (../shared/notes/real-cameras.md, section 4):
# per channel (R, G, B), on linear intensities in [0, 1].
ICL_SHOT_NOISE: tuple[float, float, float] = (0.0104, 0.0066, 0.0106)
ICL_READ_NOISE: tuple[float, float, float] = (0.0045, 0.0038, 0.0050)
# simkinect (ankurhanda/simkinect, part of ICL-NUIM): the Kinect's IR camera focal length, projector baseline,
# disparity quantisation and lateral jitter.
KINECT_FOCAL_PX: float = 480.0
KINECT_BASELINE_M: float = 0.075
KINECT_SUBPIXEL: float = 8.0  # disparity quantised to 1/8 px
KINECT_SHIFT_STD_PX: float = 0.5


@dataclass(frozen=True)
class CameraEffects:
    """What a simulated camera does to the rendered image. Every default is off: ``CameraEffects()`` is the clean
    camera (the renderer's bytes). Frozen and hashable; :meth:`describe` gives a JSON-ready dict.

    name: a label (the preset's name; "custom" for a hand-made one), recorded with runs.

    Photometric:
    response: the camera response function applied to the linear signal: "srgb" (IEC 61966-2-1 encoding; what the
    renderer's bytes are read as, so the neutral choice) or "gamma" (``x ** (1 / response_gamma)``);
    response_gamma: the exponent of "gamma" (2.2: the common display gamma);
    vignette_corner: irradiance at the image corner farthest from the principal point relative to the principal
    point, 1 = no vignetting; the fall-off is cos^4-shaped, ``V(rho) = 1 / (1 + a rho^2)^2`` with rho the distance
    from the principal point over the corner's (:func:`vignette`);
    scene_light: scale of the scene's irradiance (1 = as rendered; < 1 a darker room);
    reference_exposure_s: the exposure at which, with scene_light 1, gain 1 and no vignetting, a pixel keeps the
    renderer's value;
    exposure_s: the exposure time when auto-exposure is off (and the first frame's guess when it is on);
    auto_exposure: whether a first-order controller sets each frame's exposure (:func:`auto_exposure`);
    ae_target: the mean linear brightness the controller aims at;
    ae_rate: the fraction of the log-brightness error corrected per frame (1 = no lag; 0.2 = a time constant of
    about 5 frames);
    ae_min_s, ae_max_s: exposure limits in seconds (the longest exposure is at most a frame interval);
    max_gain: the analogue gain the controller may add once the exposure is at ``ae_max_s`` (it amplifies noise);
    exposure_jitter: std of a per-frame log-normal factor on the effective exposure (exposure x gain), drawn from
    the frame's own generator, that the controller sees and corrects like any brightness change (real auto-exposure
    hunts; 0 = off).

    Noise (linear domain, per channel R, G, B, on intensities in [0, 1], before the gain):
    shot_noise: std ``sqrt(x) * shot_noise``; read_noise: std ``read_noise``; sensor_width: the width in pixels of
    the sensor these stds are for (None: the image's own): an image narrower than the sensor is the sensor's image
    area-averaged, as the folder loader does to real frames (``cv2.INTER_AREA``), so both stds are scaled by
    ``width / sensor_width`` (the mean of (sensor_width / width)^2 independent pixels).

    Geometry of the exposure:
    blur_subframes: renders per frame spread over the union of the rows' exposure windows (1 = one render at the
    frame's pose: no blur and no rolling shutter, whatever the exposure);
    readout_s: rolling-shutter readout, seconds from the first row's exposure to the last row's (0 = global shutter);
    distortion: OpenCV radial-tangential ``(k1, k2, p1, p2, k3)`` of the lens (zeros: none).

    Depth:
    depth_noise: whether frames carry a Kinect-like sensor depth (:func:`kinect_depth`) besides the exact ground
    truth (which stays untouched).
    """

    name: str = "custom"
    response: Response = "srgb"
    response_gamma: float = 2.2
    vignette_corner: float = 1.0
    scene_light: float = 1.0
    reference_exposure_s: float = 1.0 / 60.0
    exposure_s: float = 1.0 / 60.0
    auto_exposure: bool = False
    ae_target: float = 0.18
    ae_rate: float = 0.25
    ae_min_s: float = 1e-4
    ae_max_s: float = 1.0 / FPS_NOMINAL
    max_gain: float = 1.0
    exposure_jitter: float = 0.0
    shot_noise: tuple[float, float, float] = (0.0, 0.0, 0.0)
    read_noise: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sensor_width: int | None = None
    blur_subframes: int = 1
    readout_s: float = 0.0
    distortion: tuple[float, float, float, float, float] = field(default=NO_DISTORTION)
    depth_noise: bool = False

    def __post_init__(self) -> None:
        for key in ("shot_noise", "read_noise"):
            value = tuple(float(v) for v in getattr(self, key))
            if len(value) != 3 or not all(np.isfinite(v) and v >= 0 for v in value):
                raise SimEnvError(f"{key} must be 3 numbers >= 0 (R, G, B), got {getattr(self, key)!r}")
            object.__setattr__(self, key, value)
        object.__setattr__(self, "distortion", CameraModel(Intrinsics(1, 1, 0, 0, 1, 1), self.distortion).distortion)
        if self.response not in RESPONSES:
            raise UnknownNameError(f"unknown response {self.response!r}; valid: {', '.join(RESPONSES)}")
        positive = ("response_gamma", "scene_light", "reference_exposure_s", "ae_target", "ae_min_s", "ae_max_s")
        for key in positive:
            if not (np.isfinite(getattr(self, key)) and getattr(self, key) > 0):
                raise SimEnvError(f"{key} must be a number > 0, got {getattr(self, key)!r}")
        if not 0 < self.vignette_corner <= 1:
            raise SimEnvError(f"vignette_corner must be in (0, 1] (1 = no vignetting), got {self.vignette_corner}")
        if not (np.isfinite(self.exposure_s) and self.exposure_s >= 0):
            raise SimEnvError(f"exposure_s must be >= 0 seconds, got {self.exposure_s}")
        if not 0 < self.ae_rate <= 1:
            raise SimEnvError(f"ae_rate must be in (0, 1], got {self.ae_rate}")
        if self.ae_min_s > self.ae_max_s:
            raise SimEnvError(f"ae_min_s ({self.ae_min_s}) must not exceed ae_max_s ({self.ae_max_s})")
        if not (np.isfinite(self.max_gain) and self.max_gain >= 1):
            raise SimEnvError(f"max_gain must be >= 1, got {self.max_gain}")
        if not (np.isfinite(self.exposure_jitter) and self.exposure_jitter >= 0):
            raise SimEnvError(f"exposure_jitter must be >= 0, got {self.exposure_jitter}")
        if self.sensor_width is not None and int(self.sensor_width) < 1:
            raise SimEnvError(f"sensor_width must be a positive number of pixels or None, got {self.sensor_width}")
        if int(self.blur_subframes) != self.blur_subframes or self.blur_subframes < 1:
            raise SimEnvError(f"blur_subframes must be an integer >= 1 (1 = one render), got {self.blur_subframes}")
        if not (np.isfinite(self.readout_s) and self.readout_s >= 0):
            raise SimEnvError(f"readout_s must be >= 0 seconds, got {self.readout_s}")

    @property
    def any(self) -> bool:
        """Whether this camera changes the renderer's image at all (False: the clean camera, same bytes)."""
        return self.photometric or self.blur_subframes > 1 or any(c != 0.0 for c in self.distortion)

    @property
    def photometric(self) -> bool:
        """Whether the pixel values go through exposure, vignetting, noise or a non-neutral response."""
        return (
            self.response != "srgb"
            or self.vignette_corner != 1.0
            or self.scene_light != 1.0
            or self.auto_exposure
            or self.exposure_jitter > 0
            or self.exposure_s != self.reference_exposure_s
            or any(self.shot_noise)
            or any(self.read_noise)
        )

    @property
    def distorted(self) -> bool:
        """Whether the lens has distortion."""
        return any(c != 0.0 for c in self.distortion)

    def describe(self) -> dict[str, Any]:
        """JSON-ready parameters (lists for tuples), e.g. for run records and fingerprints."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


# --------------------------------------------------------------------------------------------------------- presets
# The camera every command that renders a simulated sequence sees it through unless told otherwise (bench, generate,
# export, train validate): a hand-held RGB-D camera calibrated on real Kinect frames (results/camera_calibration.md).
DEFAULT_CAMERA_EFFECTS = "kinect"

_PRESETS: dict[str, CameraEffects] = {
    # The renderer's image, byte for byte (what every sequence gave before camera effects existed).
    "clean": CameraEffects(name="clean"),
    # A TUM / ICL-NUIM-like hand-held RGB-D camera (Kinect v1 class). Sources: noise, ICL-NUIM (real-cameras.md 4),
    # for a 640-px-wide sensor (ICL-NUIM's and the Kinect's resolution; at 320x240 it is the 2x2 area average, as
    # real frames are when loaded); shutter open about half the frame interval at 30 fps as the reference exposure
    # and a rolling-shutter readout of 0.05 of the frame time (BlenderProc's example, real-cameras.md 4); an sRGB
    # response (the 8-bit encoding of consumer cameras; ours). Calibrated on the first 100 frames of 7-Scenes
    # redkitchen against office0 / living0 (results/camera_calibration.md): ae_target (mean grey level 116),
    # exposure_jitter (frame-to-frame change of log mean grey level, std 0.008); vignette_corner 0.9 is a gentle value
    # within that measurement's uncertainty (corner/centre ratios of scene content alone differ by +-8 % between
    # rooms); ae_rate 0.25 (ours: a lag of a few frames). No lens distortion (7-Scenes gives none).
    "kinect": CameraEffects(
        name="kinect",
        response="srgb",
        vignette_corner=0.90,
        reference_exposure_s=0.5 / FPS_NOMINAL,
        exposure_s=0.5 / FPS_NOMINAL,
        auto_exposure=True,
        ae_target=0.20,
        ae_rate=0.25,
        ae_min_s=1e-3,
        ae_max_s=1.0 / FPS_NOMINAL,
        max_gain=2.0,
        exposure_jitter=0.010,
        shot_noise=ICL_SHOT_NOISE,
        read_noise=ICL_READ_NOISE,
        sensor_width=640,
        blur_subframes=3,
        readout_s=0.05 / FPS_NOMINAL,
        depth_noise=True,
    ),
    # TartanAir-like stress (ours): a dim room (a quarter of the light), so exposure runs at its longest (a whole
    # frame interval: strong blur) with up to 4x gain (noisier; ICL noise at the image's own resolution); a fast
    # controller (ae_rate 0.7) and 3 % exposure jitter (exposure changes from frame to frame); a readout of half
    # the frame interval; a gamma-2.2 response; strong vignetting; the TUM fr1 lens (reference-facts.md).
    "hard": CameraEffects(
        name="hard",
        response="gamma",
        response_gamma=2.2,
        vignette_corner=0.55,
        scene_light=0.25,
        reference_exposure_s=0.5 / FPS_NOMINAL,
        exposure_s=1.0 / FPS_NOMINAL,
        auto_exposure=True,
        ae_target=0.18,
        ae_rate=0.7,
        ae_min_s=1e-3,
        ae_max_s=1.0 / FPS_NOMINAL,
        max_gain=4.0,
        exposure_jitter=0.03,
        shot_noise=ICL_SHOT_NOISE,
        read_noise=ICL_READ_NOISE,
        blur_subframes=5,
        readout_s=0.5 / FPS_NOMINAL,
        distortion=preset_distortion("tum_fr1"),
        depth_noise=True,
    ),
}


def camera_effect_presets() -> list[str]:
    """Names of the whole-camera presets of :func:`camera_effects_preset`: ``clean``, ``hard``, ``kinect``."""
    return sorted(_PRESETS)


# One camera effect alone on the clean camera, at a strength (the sweep's camera axes): the effect's name and what
# strength s means. s = 1 is the kinect preset's value where it has one.
SINGLE_EFFECTS: dict[str, str] = {
    "noise": "shot + read noise, s x ICL-NUIM's (640-px sensor, as kinect)",
    "blur": "motion blur, exposure s x half the frame interval (kinect's; 2 = the whole interval), global shutter",
    "exposure": "auto-exposure with kinect's lag, per-frame exposure jitter s x kinect's (1 %)",
    "rolling_shutter": "rolling-shutter readout of s frame intervals (kinect: 0.05, hard: 0.5), 1 ms exposure",
    "distortion": "lens distortion s x TUM fr1's coefficients, undistorted for the agent",
}


def single_effect(effect: str, strength: float) -> CameraEffects:
    """The clean camera with one effect of :data:`SINGLE_EFFECTS` at ``strength`` (>= 0; 0 = the clean camera's
    bytes), named ``"<effect>:<strength>"``. :class:`SimEnvError` for an unknown effect or a bad strength."""
    if effect not in SINGLE_EFFECTS:
        raise UnknownNameError(f"unknown camera effect {effect!r}; valid effects: {', '.join(SINGLE_EFFECTS)}")
    s = float(strength)
    if not (np.isfinite(s) and s >= 0):
        raise SimEnvError(f"camera effect {effect!r}: strength must be a finite number >= 0, got {strength!r}")
    if effect == "blur" and s > 2:
        raise SimEnvError(f"camera effect 'blur': strength is at most 2 (an exposure of the whole frame interval), "
                          f"got {s:g}")  # fmt: skip
    name, kinect = f"{effect}:{s:g}", _PRESETS["kinect"]
    if s == 0:
        return replace(_PRESETS["clean"], name=name)
    if effect == "noise":
        return CameraEffects(name=name, shot_noise=tuple(s * v for v in kinect.shot_noise),  # type: ignore[arg-type]
                             read_noise=tuple(s * v for v in kinect.read_noise),  # type: ignore[arg-type]
                             sensor_width=kinect.sensor_width)  # fmt: skip
    if effect == "blur":
        exposure = s * 0.5 / FPS_NOMINAL  # the brightness stays the renderer's: reference exposure = exposure
        return CameraEffects(name=name, exposure_s=exposure, reference_exposure_s=exposure, blur_subframes=5)
    if effect == "exposure":
        return replace(kinect, name=name, vignette_corner=1.0, shot_noise=(0.0,) * 3, read_noise=(0.0,) * 3,
                       sensor_width=None, blur_subframes=1, readout_s=0.0, depth_noise=False,
                       exposure_jitter=s * kinect.exposure_jitter)  # fmt: skip
    if effect == "rolling_shutter":
        return CameraEffects(name=name, exposure_s=1e-3, reference_exposure_s=1e-3, readout_s=s / FPS_NOMINAL,
                             blur_subframes=max(3, int(np.ceil(8 * s))))  # fmt: skip
    return CameraEffects(name=name, distortion=tuple(s * c for c in preset_distortion("tum_fr1")))  # type: ignore[arg-type]


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


# ------------------------------------------------------------------------------------------------ response curves
def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1] to linear intensities in [0, 1] (same shape, float)."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding of linear intensities in [0, 1] to values in [0, 1] (same shape, float)."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def apply_response(x: np.ndarray, effects: CameraEffects) -> np.ndarray:
    """The camera response ``f``: linear signal in [0, 1] (clipped) -> encoded value in [0, 1], float64."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    if effects.response == "srgb":
        return linear_to_srgb(x)
    return x ** (1.0 / effects.response_gamma)


def inverse_response(effects: CameraEffects) -> np.ndarray:
    """(256,) float64 ``G(k) = 255 * f^-1(k / 255)``: the linear signal of each 8-bit value, on the 0-255 scale of
    TUM monoVO's ``pcalib.txt`` (G(0) = 0, G(255) = 255)."""
    k = np.arange(256) / 255.0
    linear = srgb_to_linear(k) if effects.response == "srgb" else k**effects.response_gamma
    return 255.0 * linear


_ENCODE_STEPS = 1 << 18  # linear steps of the encoding table (a step moves the output by < 0.02 levels)


@lru_cache(maxsize=8)
def _encode_lut(response: str, gamma: float) -> np.ndarray:
    fx = CameraEffects(response=response, response_gamma=gamma)  # type: ignore[arg-type]
    lut = np.rint(apply_response(np.arange(_ENCODE_STEPS + 1) / _ENCODE_STEPS, fx) * 255.0).astype(np.uint8)
    lut.setflags(write=False)
    return lut


def encode(x: np.ndarray, effects: CameraEffects) -> np.ndarray:
    """The camera response and 8-bit quantisation of a linear signal (clipped to [0, 1]): uint8 of the same shape,
    ``rint(255 f(x))`` read from a table of 2^18 + 1 linear steps (x rounded to the nearest step first)."""
    t = np.clip(x, 0.0, 1.0)
    t *= np.float32(_ENCODE_STEPS)  # in place: the same float32 operations as rint(clip(x) * steps), fewer copies
    np.rint(t, out=t)
    return np.take(_encode_lut(effects.response, float(effects.response_gamma)), t.astype(np.int32))


@lru_cache(maxsize=4)
def _decode_lut() -> np.ndarray:
    lut = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    lut.setflags(write=False)
    return lut


def decode_render(rgb: np.ndarray) -> np.ndarray:
    """A renderer's (H, W, 3) uint8 image read as sRGB: (H, W, 3) float32 linear radiance in [0, 1]."""
    return cv2.LUT(np.asarray(rgb, dtype=np.uint8), _decode_lut().reshape(256, 1))  # = lut[rgb], 10x faster


# ------------------------------------------------------------------------------------------------------ vignetting
def vignette(intrinsics: Intrinsics, corner: float) -> np.ndarray:
    """(H, W) float32 relative irradiance, 1 at the principal point and ``corner`` at the farthest image corner.

    cos^4-shaped fall-off ``V(rho) = 1 / (1 + a rho^2)^2`` (the cos^4 law of a thin lens, whose tan(theta) grows
    linearly with the distance from the principal point), rho = distance / the farthest corner's distance, and
    ``a = corner^(-1/2) - 1`` so that V(1) = corner.
    """
    K = intrinsics
    u = np.arange(K.width, dtype=np.float64) - K.cx
    v = np.arange(K.height, dtype=np.float64) - K.cy
    r2 = u[None, :] ** 2 + v[:, None] ** 2
    corners = [(x - K.cx) ** 2 + (y - K.cy) ** 2 for x in (-0.5, K.width - 0.5) for y in (-0.5, K.height - 0.5)]
    a = corner**-0.5 - 1.0
    return (1.0 / (1.0 + a * r2 / max(corners)) ** 2).astype(np.float32)


# ------------------------------------------------------------------------------------------------------ distortion
def distortion_maps(intrinsics: Intrinsics, distortion: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` that turn a pinhole render into the distorted image of the same K.

    For each pixel (u, v) of the distorted image: the pinhole pixel ``K undistort(K^-1 (u, v))`` to read, computed
    with ``cv2.undistortPoints`` (OpenCV radial-tangential model, iterative inverse). Returns ``(map_u, map_v)``,
    each (H, W) float32. Back to a pinhole image: :meth:`sim_envs.camera.CameraModel.undistort_maps`.
    """
    K = intrinsics
    u, v = np.meshgrid(np.arange(K.width, dtype=np.float64), np.arange(K.height, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
    und = cv2.undistortPoints(pts, K.K, np.asarray(distortion, dtype=np.float64), P=K.K)
    und = und.reshape(K.height, K.width, 2).astype(np.float32)
    return np.ascontiguousarray(und[..., 0]), np.ascontiguousarray(und[..., 1])


# ------------------------------------------------------------------------------------ exposure timing over the rows
def row_times(height: int, readout_s: float) -> np.ndarray:
    """(H,) float64 centre of each sensor row's exposure relative to the frame's timestamp:
    ``readout_s * (r / (H - 1) - 1/2)`` (the middle row at the timestamp, rows read top to bottom)."""
    if height < 2 or readout_s == 0:
        return np.zeros(height)
    return readout_s * (np.arange(height) / (height - 1) - 0.5)


def subframe_times(effects: CameraEffects, exposure_s: float, height: int) -> np.ndarray:
    """(K,) float64 render times relative to the frame's timestamp: ``blur_subframes`` times evenly spread over
    ``[-(readout_s + exposure_s) / 2, +(readout_s + exposure_s) / 2]`` (just ``[0]`` for one sub-frame or a zero
    window). With an odd count the middle time is 0, so the frame's own render is one of them."""
    k = int(effects.blur_subframes)
    half = 0.5 * (effects.readout_s * (height > 1) + exposure_s)
    if k == 1 or half == 0:
        return np.zeros(1)
    return np.linspace(-half, half, k)


def row_weights(times: np.ndarray, row_centres: np.ndarray, exposure_s: float, samples: int = 32) -> np.ndarray:
    """(K, H) float32 weights of the K renders at ``times`` for each row: the mean over the row's exposure box
    (width ``exposure_s`` around ``row_centres``) of the linear-interpolation basis functions of ``times`` (a box
    filter through a piecewise-linear signal in time). Each column sums to 1; times outside ``times``' span are
    clamped to it. ``samples`` quadrature points per row."""
    times = np.asarray(times, dtype=np.float64)
    n = times.shape[0]
    if n == 1:
        return np.ones((1, row_centres.shape[0]), dtype=np.float32)
    offsets = (np.arange(samples) + 0.5) / samples - 0.5 if exposure_s > 0 else np.zeros(1)
    tau = row_centres[:, None] + exposure_s * offsets[None, :]  # (H, S)
    pos = np.interp(tau, times, np.arange(n, dtype=np.float64))  # fractional index in the render list
    lo = np.clip(np.floor(pos).astype(int), 0, n - 2)
    frac = pos - lo
    weights = np.zeros((n, row_centres.shape[0]))
    rows = np.broadcast_to(np.arange(row_centres.shape[0])[:, None], tau.shape)
    np.add.at(weights, (lo, rows), 1.0 - frac)
    np.add.at(weights, (lo + 1, rows), frac)
    return (weights / tau.shape[1]).astype(np.float32)


# --------------------------------------------------------------------------------------------------- auto-exposure
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


# ---------------------------------------------------------------------------------------------- the sensor image
def noise_draws(shape: tuple[int, ...], effects: CameraEffects, rng: np.random.Generator) -> np.ndarray | None:
    """The (H, W, 3) float32 standard normal draws :func:`linear_noise` makes from ``rng`` for an image of
    ``shape``, or None when the camera has no noise (no draw). Drawn ahead, they let the draw run beside the
    renders: ``linear_noise(x, effects, rng)`` equals ``linear_noise(x, effects, normals=noise_draws(...))``."""
    if not (any(effects.shot_noise) or any(effects.read_noise)):
        return None
    return rng.standard_normal(shape, dtype=np.float32)


def linear_noise(x: np.ndarray, effects: CameraEffects, rng: np.random.Generator | None = None, *,
                 normals: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """``x`` (H, W, 3) linear sensor signal plus shot noise (std ``sqrt(x) * shot_noise``) and read noise (std
    ``read_noise``) per channel, both scaled by ``width / sensor_width`` (at most 1) when ``sensor_width`` is set,
    as float32; no draw when both are zero. The standard normal draws come from ``normals`` when given
    (:func:`noise_draws`), else from ``rng``."""
    if not (any(effects.shot_noise) or any(effects.read_noise)):
        return x
    if normals is None:
        if rng is None:
            raise ValueError("linear_noise needs rng or normals (the camera has noise)")
        normals = noise_draws(x.shape, effects, rng)
    scale = 1.0 if effects.sensor_width is None else min(1.0, x.shape[1] / effects.sensor_width)
    shot = np.asarray(effects.shot_noise, dtype=np.float32) * np.float32(scale)
    read = np.asarray(effects.read_noise, dtype=np.float32) * np.float32(scale)
    std = np.maximum(x, 0.0)  # std = sqrt(max(x, 0) shot^2 + read^2), computed in place (the same float32 steps)
    std *= shot**2
    std += read**2
    np.sqrt(std, out=std)
    std *= normals
    std += x
    return std


def expose(linear: np.ndarray, effects: CameraEffects, exposure_s: float, gain: float,
           rng: np.random.Generator | None, vignette_map: np.ndarray | None = None, *,
           normals: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """Linear radiance (H, W, 3) float -> (H, W, 3) uint8 camera image: vignetting, scene light and exposure, noise
    (from ``normals`` when given, else from ``rng``: :func:`linear_noise`), gain, response, 8-bit quantisation
    (steps 4-6 of the module docstring)."""
    scale = effects.scene_light * exposure_s / effects.reference_exposure_s
    x = np.asarray(linear, dtype=np.float32) * np.float32(scale)  # a new array: the steps below work in place
    if vignette_map is not None:
        x *= vignette_map[..., None]
    np.minimum(x, np.float32(1.0), out=x)  # the sensor saturates (full well) before the noise is read
    x = linear_noise(x, effects, rng, normals=normals)
    x *= np.float32(gain)
    return encode(x, effects)


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
    H = intrinsics.height
    times = subframe_times(effects, exposure, H)
    poses = pose_at(t + times)
    renders = []
    for dt, T in zip(times, poses, strict=True):
        rgb = own_render if (dt == 0.0 and own_render is not None) else render_rgb(T)
        linear = decode_render(rgb)
        if geometry.distort is not None:
            linear = cv2.remap(linear, *geometry.distort, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        renders.append(linear)
    if len(renders) == 1:
        linear = renders[0]
    else:
        weights = row_weights(times, row_times(H, effects.readout_s), exposure)
        linear = np.einsum("kh,khwc->hwc", weights, np.stack(renders), optimize=True)
    drawn = normals() if normals is not None else None
    return expose(linear, effects, exposure, gain, None if drawn is not None else rng, geometry.vignette,
                  normals=drawn)  # fmt: skip


def undistort_image(rgb: np.ndarray, geometry: SensorGeometry) -> np.ndarray:
    """A distorted sensor image resampled to the pinhole image of ``geometry.delivered`` (bilinear), as
    :class:`sim_envs.datasets.RgbdFolder` does with a real distorted camera; the image itself when the lens has no
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


# ----------------------------------------------------------------------------------------------------- depth noise
def kinect_depth(
    depth: np.ndarray,
    rng: np.random.Generator,
    *,
    focal_px: float = KINECT_FOCAL_PX,
    baseline_m: float = KINECT_BASELINE_M,
    shift_std_px: float = KINECT_SHIFT_STD_PX,
    edge_disparity_px: float = 0.5,
) -> np.ndarray:
    """A Kinect-like sensor depth from exact planar depth (H, W) float32 metres (0 = none), after simkinect
    (ankurhanda/simkinect, ICL-NUIM): (H, W) float32 metres, 0 = no measurement. A new array; ``depth`` is not
    changed.

    1. lateral jitter: the depth is resampled at positions shifted by N(0, ``shift_std_px``) per pixel and axis
       (bilinear, as simkinect's ``add_gaussian_shifts``);
    2. disparity ``focal_px * baseline_m / z`` quantised to 1/8 px;
    3. holes at depth edges: where the disparity over a pixel's 3x3 neighbourhood spans more than
       ``edge_disparity_px`` (simkinect uses a 9x9 dot-pattern filter, whose pattern image is not shipped here;
       this keeps its effect of dropping measurements across depth discontinuities), and where there was no depth;
    4. simkinect's final step ``35130 / round(35130 / z_cm + N(0, 1/6) + 0.5)`` with z in centimetres.
    """
    depth = np.asarray(depth, dtype=np.float32)
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    shifts = rng.normal(0.0, shift_std_px, size=(2, h, w)).astype(np.float32)
    map_u = np.clip(u + shifts[0], 0, w - 1)
    map_v = np.clip(v + shifts[1], 0, h - 1)
    jittered = cv2.remap(depth, map_u, map_v, cv2.INTER_LINEAR)
    valid = jittered > 0
    disp = np.where(valid, focal_px * baseline_m / np.where(valid, jittered, 1.0), 0.0)
    disp = np.round(disp * KINECT_SUBPIXEL) / KINECT_SUBPIXEL
    kernel = np.ones((3, 3), np.uint8)
    spread = cv2.dilate(disp.astype(np.float32), kernel) - cv2.erode(disp.astype(np.float32), kernel)
    valid &= (spread <= edge_disparity_px) & (disp > 0)
    z = np.where(valid, focal_px * baseline_m / np.where(valid, disp, 1.0), 0.0)
    z_cm = np.round(z * 100.0)
    noisy = rng.normal(0.0, 1.0 / 6.0, size=(h, w))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 35130.0 / np.round(35130.0 / z_cm + noisy + 0.5) / 100.0
    return np.where(valid & (z_cm > 0) & np.isfinite(out), out, 0.0).astype(np.float32)
