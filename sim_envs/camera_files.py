"""Camera files: read and write the camera (pinhole intrinsics and OpenCV lens distortion) of an RGB-D folder.

A folder's own camera file is the first of :data:`CAMERA_FILES` it holds (``camera.toml``, ``camera.yaml``,
``camera.yml``), read by :func:`read_camera_file`: TOML, or flat YAML (``key: value`` lines) read by the small reader
:func:`_read_flat_yaml` (PyYAML is not a dependency of the project; a camera file needs no more than flat keys).
:func:`camera_file_text` writes the TOML that :func:`read_camera_file` reads back exactly; :func:`camera_fields`
names a camera's fields as camera files and run records do. A 7-Scenes folder as andyzeng's tsdf-fusion ships it may
hold ``camera-intrinsics.txt`` (:data:`SEVEN_SCENES_INTRINSICS_FILE`, a 3x3 K, the depth camera's), read by
:func:`_read_intrinsics_matrix`. Which camera a loaded folder gets, in which order: :mod:`sim_envs.datasets`.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from sim_envs.camera import DISTORTION_NAMES, CameraModel, Intrinsics, camera_model
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
    distortion). The camera is scaled to ``width`` x ``height`` when both are given.
    """
    path = Path(path)
    try:
        text = path.read_text()
        data = tomllib.loads(text) if path.suffix == ".toml" else _read_flat_yaml(text, path)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise FormatError(f"{path}: not a readable camera file ({exc})") from exc
    valid = ("preset", "fx", "fy", "cx", "cy", "width", "height", *DISTORTION_NAMES)
    unknown = sorted(set(data) - set(valid))
    if unknown:
        raise FormatError(f"{path}: unknown key(s) {', '.join(unknown)}; valid: {', '.join(valid)}")
    if "preset" in data:
        if len(data) > 1:
            raise FormatError(f"{path}: give either preset or fx fy cx cy (and distortion), not both")
        name = str(data["preset"])
        return camera_model(name, width, height) if width and height else camera_model(name, 640, 480)
    missing = [k for k in ("fx", "fy", "cx", "cy") if k not in data]
    if missing:
        raise FormatError(f"{path}: missing {', '.join(missing)} (pixels) or a preset name")
    w, h = data.get("width", width), data.get("height", height)
    if not w or not h:
        raise FormatError(f"{path}: give width and height (the image size fx fy cx cy are for)")
    try:
        K = Intrinsics(float(data["fx"]), float(data["fy"]), float(data["cx"]), float(data["cy"]), int(w), int(h))
        model = CameraModel(K, tuple(float(data.get(n, 0.0)) for n in DISTORTION_NAMES))  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise FormatError(f"{path}: {exc}") from exc
    if width and height and (K.width, K.height) != (width, height):
        model = model.scaled(width, height)
    return model


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
        try:
            data[key.strip()] = float(value) if key.strip() != "preset" else value
        except ValueError:
            raise FormatError(f"{path}:{number}: {value!r} is not a number") from None
    return data


def _intrinsics_dict(K: Intrinsics) -> dict[str, float | int]:
    return {"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width, "height": K.height}
