"""Camera files: read and write the camera (pinhole intrinsics and OpenCV lens distortion) of an RGB-D folder.

A folder's own camera file is the first of :data:`CAMERA_FILES` it holds (``camera.toml``, ``camera.yaml``,
``camera.yml``), read by :func:`read_camera_file`: TOML, or flat YAML (``key: value`` lines) read by the small reader
:func:`_read_flat_yaml` (PyYAML is not a dependency of the project; a camera file needs no more than flat keys).
:func:`camera_file_text` writes the TOML that :func:`read_camera_file` reads back exactly; :func:`camera_fields`
names a camera's fields as camera files and run records do. A 7-Scenes folder as andyzeng's tsdf-fusion ships it may
hold ``camera-intrinsics.txt`` (:data:`SEVEN_SCENES_INTRINSICS_FILE`, a 3x3 K, the depth camera's), read by
:func:`_read_intrinsics_matrix`. Which camera a loaded folder gets, in which order: :mod:`sim_envs.folders.datasets`.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from sim_envs.camera import DISTORTION_NAMES, CameraModel, Intrinsics, camera_model, camera_presets
from sim_envs.errors import FormatError

CAMERA_FILES: tuple[str, ...] = ("camera.toml", "camera.yaml", "camera.yml")  # a folder's own camera file
SEVEN_SCENES_INTRINSICS_FILE = "camera-intrinsics.txt"  # a 3x3 K, as andyzeng/tsdf-fusion ships 7-Scenes frames


def camera_fields(camera: CameraModel | Intrinsics) -> dict[str, float | int]:
    """A camera's fields as a camera file and run records name them: ``fx fy cx cy width height`` (pixels, OpenCV
    convention) and, for a :class:`CameraModel`, its distortion ``k1 k2 p1 p2 k3``."""
    if isinstance(camera, Intrinsics):
        return _intrinsics_dict(camera)
    return {**_intrinsics_dict(camera.intrinsics), **dict(zip(DISTORTION_NAMES, camera.distortion, strict=True))}


def camera_file_text(camera: CameraModel | Intrinsics, comment: str = "") -> str:
    """The text of a camera file (TOML) for ``camera``, which :func:`read_camera_file` reads back exactly;
    ``comment``: lines written first, as ``#`` comments."""
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"{k} = {int(v) if k in ('width', 'height') else float(v)!r}" for k, v in camera_fields(camera).items()]
    return "\n".join(lines) + "\n"


def read_camera_file(path: str | Path, width: int | None = None, height: int | None = None) -> CameraModel:
    """A camera file: TOML (``.toml``) or flat YAML (``key: value`` lines, ``.yaml`` / ``.yml``) with

    ``fx fy cx cy`` (pixels, OpenCV convention: y down, pixel centres at integers, so fy > 0) and optionally
    ``width height`` (the image size they are for; default: ``width`` x ``height`` given here) and the OpenCV
    distortion ``k1 k2 p1 p2 k3`` (default 0); or ``preset = "<name>"`` (a :func:`sim_envs.camera.preset` with its
    distortion, scaled to ``width`` x ``height`` when both are given, else 640x480).

    ``width`` x ``height``: the size of the images the camera is for. A file whose own ``width height`` differ from
    them is refused (:class:`FormatError`, both sizes named), not rescaled: fx fy cx cy of another resolution are a
    camera of other images. Every error is one :class:`FormatError` line naming the file.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
        data = tomllib.loads(text) if path.suffix == ".toml" else _read_flat_yaml(text, path)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise FormatError(f"{path}: not a readable camera file ({exc})") from exc
    except UnicodeDecodeError as exc:
        raise FormatError(f"{path}: not a text file (UTF-8 decoding failed at byte {exc.start})") from exc
    valid = ("preset", "fx", "fy", "cx", "cy", "width", "height", *DISTORTION_NAMES)
    unknown = sorted(set(data) - set(valid))
    if unknown:
        raise FormatError(f"{path}: unknown key(s) {', '.join(map(repr, unknown))}; valid: {', '.join(valid)}")
    if "preset" in data:
        if len(data) > 1:
            raise FormatError(f"{path}: give either preset or fx fy cx cy (and distortion), not both")
        name = data["preset"]
        if not isinstance(name, str) or name not in camera_presets():
            raise FormatError(f"{path}: unknown camera preset {name!r}; valid: {', '.join(camera_presets())}")
        return camera_model(name, width, height) if width and height else camera_model(name, 640, 480)
    missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
    if missing:
        raise FormatError(f"{path}: missing {', '.join(missing)} (pixels) or a preset name")
    numbers = {}
    for key in ("fx", "fy", "cx", "cy", *(n for n in DISTORTION_NAMES if n in data)):
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise FormatError(f"{path}: {key} = {value!r}; it must be a finite number")
        numbers[key] = float(value)
    size = []
    for key, given in (("width", width), ("height", height)):
        value = data.get(key, given)
        if value is None:
            raise FormatError(f"{path}: give width and height (the image size fx fy cx cy are for)")
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
                math.isfinite(value) and value > 0 and value == int(value)):  # fmt: skip
            raise FormatError(f"{path}: {key} = {value!r}; it must be a whole number of pixels > 0")
        size.append(int(value))
    if width and height and tuple(size) != (width, height):
        raise FormatError(
            f"{path}: the camera is for {size[0]}x{size[1]} images but the images are {width}x{height}; give the "
            "fx fy cx cy of these images (or leave width and height out: the images' size)"
        )
    try:
        K = Intrinsics(numbers["fx"], numbers["fy"], numbers["cx"], numbers["cy"], size[0], size[1])
        return CameraModel(K, tuple(numbers.get(n, 0.0) for n in DISTORTION_NAMES))  # type: ignore[arg-type]
    except ValueError as exc:
        raise FormatError(f"{path}: {exc}") from exc


def _read_intrinsics_matrix(path: Path, width: int, height: int) -> Intrinsics:
    """A 3x3 camera matrix in a text file (7-Scenes' ``camera-intrinsics.txt``), for images of width x height."""
    try:
        K = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as exc:
        raise FormatError(f"{path}: not a 3x3 matrix of numbers ({exc})") from exc
    if K.shape != (3, 3):
        raise FormatError(f"{path}: expected a 3x3 camera matrix, got shape {K.shape}")
    return Intrinsics(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), width, height)


def _read_flat_yaml(text: str, path: Path) -> dict[str, Any]:
    """``key: value`` lines (``#`` comments; numbers or plain strings): the YAML a camera file needs, no library."""
    data: dict[str, Any] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.split("#", 1)[0].rstrip()
        if not line.strip() or line.startswith(("%", "---")):
            continue
        key, sep, value = line.partition(":")
        value = value.strip().strip("\"'")
        if not sep or line[0].isspace() or not value:
            raise FormatError(f"{path}:{number}: expected a flat 'key: value' line (use TOML for anything else)")
        if key.strip() in data:
            raise FormatError(f"{path}:{number}: {key.strip()!r} given twice")
        try:
            data[key.strip()] = float(value) if key.strip() != "preset" else value
        except ValueError:
            raise FormatError(f"{path}:{number}: {value!r} is not a number") from None
    return data


def _intrinsics_dict(K: Intrinsics) -> dict[str, float | int]:
    return {"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width, "height": K.height}
