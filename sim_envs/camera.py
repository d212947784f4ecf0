"""Pinhole camera intrinsics, lens distortion, presets of the usual RGB-D datasets, and resolution scaling.

Conventions (used everywhere in this project):
- camera frame: x right, y down, z forward (OpenCV); pixel (u, v) = (column, row), pixel centres at integers;
- images are H x W; depth is metric planar z in metres;
- poses are ``T_world_cam`` 4x4 (camera-to-world).

Lens distortion (:class:`CameraModel`) is OpenCV's radial-tangential model with the five coefficients in OpenCV's
order ``k1 k2 p1 p2 k3``, applied to normalised image coordinates (x, y) = ((u - cx) / fx, (v - cy) / fy): the
coefficients do not change with the image resolution, only the intrinsics do.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from sim_envs.errors import SimEnvError, UnknownNameError


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of ``width`` x ``height``. fx may differ from fy; cx, cy anywhere."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise SimEnvError(f"image size must be positive, got {self.width}x{self.height}")
        if not (np.isfinite([self.fx, self.fy, self.cx, self.cy]).all() and self.fx > 0 and self.fy > 0):
            raise SimEnvError(
                f"focal lengths must be finite and positive (OpenCV convention, y down), got fx={self.fx}, "
                f"fy={self.fy}; a dataset with a negative fy (ICL-NUIM) is converted when it is loaded"
            )

    @property
    def K(self) -> np.ndarray:
        """The 3x3 intrinsic matrix, float64."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def as_array(self) -> np.ndarray:
        """``[fx, fy, cx, cy]`` as float64, the form agents receive in observations."""
        return np.array([self.fx, self.fy, self.cx, self.cy], dtype=np.float64)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera at another resolution, keeping pixel-centre conventions exact.

        f' = f * s and c' = (c + 0.5) * s - 0.5 per axis, with s = new size / old size.
        """
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            fx=self.fx * sx,
            fy=self.fy * sy,
            cx=(self.cx + 0.5) * sx - 0.5,
            cy=(self.cy + 0.5) * sy - 0.5,
            width=int(width),
            height=int(height),
        )

    def with_focal(self, fx: float, fy: float) -> Intrinsics:
        """The same camera with other focal lengths (for focal-mismatch experiments)."""
        return replace(self, fx=float(fx), fy=float(fy))

    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view in degrees (for a centred principal point)."""
        return (
            float(np.degrees(2 * np.arctan(self.width / (2 * self.fx)))),
            float(np.degrees(2 * np.arctan(self.height / (2 * self.fy)))),
        )


# Native 640x480 values (../shared/notes/reference-facts.md). ICL-NUIM's official K has fy = -480 because its raw
# renders flip y; in this project's OpenCV convention the same camera has fy = +480.
_NATIVE: dict[str, Intrinsics] = {
    "icl": Intrinsics(481.20, 480.00, 319.50, 239.50, 640, 480),
    "tum_fr1": Intrinsics(517.3, 516.5, 318.6, 255.3, 640, 480),
    "tum_fr2": Intrinsics(520.9, 521.0, 325.1, 249.7, 640, 480),
    "tum_fr3": Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480),
    "tum_default": Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480),
    "nyu": Intrinsics(518.8579, 519.4696, 325.5824, 253.7362, 640, 480),
    "7scenes": Intrinsics(585.0, 585.0, 320.0, 240.0, 640, 480),  # the one set 7-Scenes gives: its depth camera's
    # 7-Scenes' colour camera: focal length 525 px, principal point at the centre, as the relocalisation setups
    # that register 7-Scenes to its colour camera use it (DSAC*, ACE: datasets/setup_7scenes.py)
    "7scenes_rgb": Intrinsics(525.0, 525.0, 320.0, 240.0, 640, 480),
}
# TUM fr1 and fr2 RGB images are distorted (OpenCV order k1 k2 p1 p2 k3, reference-facts.md); fr3's are not.
_DISTORTION: dict[str, tuple[float, float, float, float, float]] = {
    "tum_fr1": (0.2624, -0.9531, -0.0054, 0.0026, 1.1633),
    "tum_fr2": (0.2312, -0.7849, -0.0033, -0.0001, 0.9172),
}
DISTORTION_NAMES: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3")
NO_DISTORTION: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

DEFAULT_WIDTH, DEFAULT_HEIGHT = 320, 240  # the paper runs everything but the CNN at 320x240


def camera_presets() -> list[str]:
    """Names accepted by :func:`preset`."""
    return sorted(_NATIVE)


def preset(name: str, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT) -> Intrinsics:
    """Intrinsics of a named dataset camera scaled to ``width`` x ``height`` (default 320x240)."""
    try:
        native = _NATIVE[name]
    except KeyError:
        valid = ", ".join(camera_presets())
        raise UnknownNameError(f"unknown camera preset {name!r}; valid presets: {valid}") from None
    return native.scaled(width, height)


def preset_distortion(name: str) -> tuple[float, float, float, float, float]:
    """The lens distortion ``(k1, k2, p1, p2, k3)`` of a named camera (zeros for an undistorted one)."""
    if name not in _NATIVE:
        valid = ", ".join(camera_presets())
        raise UnknownNameError(f"unknown camera preset {name!r}; valid presets: {valid}")
    return _DISTORTION.get(name, NO_DISTORTION)


# how a distorted camera's images are delivered as pinhole ones (CameraModel.rectified): cropped to what the lens saw
# (the default, LSD-SLAM's and DSO's choice), the whole frame with K and a black border, or not undistorted at all
UNDISTORT_MODES: tuple[str, ...] = ("crop", "full", "none")


@dataclass(frozen=True)
class CameraModel:
    """A pinhole camera with OpenCV radial-tangential lens distortion.

    ``intrinsics``: the pinhole part at the image size; ``distortion``: ``(k1, k2, p1, p2, k3)`` in OpenCV's order
    (all zeros: an undistorted pinhole camera). A pixel (u, v) of the distorted image sees the ray whose normalised
    coordinates (x, y) distort to ((u - cx) / fx, (v - cy) / fy) under OpenCV's model.
    """

    intrinsics: Intrinsics
    distortion: tuple[float, float, float, float, float] = field(default=NO_DISTORTION)

    def __post_init__(self) -> None:
        coeffs = tuple(float(c) for c in self.distortion)
        if len(coeffs) != len(DISTORTION_NAMES) or not np.isfinite(coeffs).all():
            raise SimEnvError(
                f"distortion must be 5 finite numbers (OpenCV order k1 k2 p1 p2 k3), got {self.distortion!r}"
            )
        object.__setattr__(self, "distortion", coeffs)

    @property
    def distorted(self) -> bool:
        """True when any distortion coefficient is not zero."""
        return any(c != 0.0 for c in self.distortion)

    def scaled(self, width: int, height: int) -> CameraModel:
        """The same camera at another resolution: intrinsics scaled (:meth:`Intrinsics.scaled`), distortion kept
        (it acts on normalised coordinates)."""
        return CameraModel(self.intrinsics.scaled(width, height), self.distortion)

    def rectified(self, mode: str = "crop") -> Intrinsics:
        """The pinhole camera this camera's images are delivered in once undistorted (``mode`` ``crop``, the
        default): at the same image size, the new camera matrix of ``cv2.getOptimalNewCameraMatrix`` with alpha = 0,
        so that every pixel of the undistorted image sees through the lens (a slight zoom: 7 % for TUM fr1's lens),
        as LSD-SLAM's and DSO's undistorters crop. Keeping K instead (``full``: the whole frame, with a border the
        lens never saw, black and fixed in the image, whose edge direct tracking may read as a static feature) or not
        undistorting at all (``none``: the distorted images taken as pinhole ones with K) are the other choices of
        :data:`UNDISTORT_MODES`; both deliver K. This camera's own intrinsics when it has no distortion."""
        if mode not in UNDISTORT_MODES:
            raise SimEnvError(f"unknown undistortion {mode!r}; valid: {', '.join(UNDISTORT_MODES)}")
        if not self.distorted or mode != "crop":
            return self.intrinsics
        import cv2  # lazily: the camera model itself needs only numpy

        K = self.intrinsics
        size = (K.width, K.height)
        new, _ = cv2.getOptimalNewCameraMatrix(K.K, np.asarray(self.distortion, dtype=np.float64), size, 0.0, size)
        return Intrinsics(float(new[0, 0]), float(new[1, 1]), float(new[0, 2]), float(new[1, 2]), K.width, K.height)

    def undistort_maps(self, mode: str = "crop") -> tuple[np.ndarray, np.ndarray]:
        """Maps for ``cv2.remap`` that turn a distorted image into the pinhole image of :meth:`rectified` (``mode``).

        Returns ``(map_u, map_v)``, each (H, W) float32: for pixel (u, v) of the undistorted image, the position in
        the distorted image to read (``cv2.initUndistortRectifyMap`` with no rectification and new camera matrix =
        :meth:`rectified`; with ``crop`` every position lies inside the distorted image, with ``full`` those of the
        border fall outside). Identity maps when not distorted.
        """
        import cv2

        K = self.intrinsics
        map_u, map_v = cv2.initUndistortRectifyMap(
            K.K, np.asarray(self.distortion, dtype=np.float64), None, self.rectified(mode).K, (K.width, K.height),
            cv2.CV_32FC1,
        )  # fmt: skip
        return map_u, map_v


def pinhole_maps(source: Intrinsics, target: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Maps for ``cv2.remap`` that resample a pinhole image of ``source`` onto the pixel grid of ``target`` (the same
    centre of projection and orientation: only the intrinsics differ, so planar depth z carries over unchanged).
    Returns ``(map_u, map_v)``, each (target.height, target.width) float32: for each target pixel, the source
    position that sees the same ray."""
    v, u = np.mgrid[0 : target.height, 0 : target.width].astype(np.float64)
    map_u = (u - target.cx) * (source.fx / target.fx) + source.cx
    map_v = (v - target.cy) * (source.fy / target.fy) + source.cy
    return map_u.astype(np.float32), map_v.astype(np.float32)


def camera_model(name: str, width: int = DEFAULT_WIDTH, height: int = DEFAULT_HEIGHT) -> CameraModel:
    """A named dataset camera with its lens distortion, its intrinsics scaled to ``width`` x ``height``."""
    return CameraModel(preset(name, width, height), preset_distortion(name))
