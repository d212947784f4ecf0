"""Export RGB-D folders: any frame source as a TUM RGB-D folder, or as a folder of any layout the loader reads.

Exported folder (:func:`export_tum_rgbd`), readable by third-party SLAM systems (ORB-SLAM3, DSO, DROID-SLAM) and by
the TUM tools::

    rgb/<t>.png        8-bit RGB                         rgb.txt          "timestamp rgb/<t>.png"
    depth/<t>.png      16-bit, metres x 5000, 0 = none   depth.txt        "timestamp depth/<t>.png"
    labels/<t>.png     8-bit SemanticClass, 255 = none   groundtruth.txt  "timestamp tx ty tz qx qy qz qw"
    instances/<t>.png  16-bit, instance id + 1, 0 = none
    cnnslam.json       the side file: intrinsics (pixels, OpenCV convention, at the image size), depth scale,
                       what labels/ and instances/ hold, how many depth pixels were beyond the 16-bit range

A sequence seen through a simulated camera (``camera_effects`` other than clean) also gets ``depth_sensor/`` (the
camera's noisy depth, when it has depth noise; ``depth/`` stays the exact ground truth) and its photometric
calibration as the TUM monoVO dataset ships it (:func:`export_photometric_calibration`: ``times.txt``,
``pcalib.txt``, ``vignette.png``, ``camera.toml``, ``camera_raw.toml``).

``<t>`` is the timestamp with 6 decimals; the text files hold the exact timestamps. Depth is planar z; a depth
beyond 65535 / 5000 = 13.107 m cannot be stored and is written as 0 (no measurement), counted in the side file.
:func:`write_folder` writes a source in any of the layouts of :mod:`sim_envs.folders.folder_layouts` (small fixtures for
tests, inputs for other tools), the way that dataset ships it.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from tqdm import tqdm

from sim_envs.camera import CameraModel
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.folders.camera_files import CAMERA_FILES, camera_file_text
from sim_envs.folders.folder_layouts import (
    _LAYOUT_DEPTH_SCALE,
    DEPTH_SCALE,
    LAYOUTS,
    SEVEN_SCENES_FPS,
    SEVEN_SCENES_INVALID_DEPTH,
    SIDE_FILE,
    SIDE_FORMAT,
)
from sim_envs.folders.formats import write_tum_image_list, write_tum_trajectory
from sim_envs.frames import NO_LABEL, SemanticClass
from sim_envs.source import FrameSource


def _stamp_name(t: float) -> str:
    return f"{t:.6f}.png"


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise SimEnvError(f"cannot write the image {path}")


def _frames_to_write(source: Any, folder: Path, overwrite: bool, max_frames: int | None, verb: str) -> int:
    """How many frames of ``source`` a writer writes into ``folder`` (its first ``max_frames``); refuses a non-empty
    folder unless ``overwrite``, and a source with nothing to write."""
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise SimEnvError(f"{folder} exists and is not empty; choose another folder or allow overwriting it "
                          "(overwrite=True; --overwrite on the command line)")
    n = len(source) if max_frames is None else min(int(max_frames), len(source))
    if n <= 0:
        raise SimEnvError(f"nothing to {verb}: the source {source.name!r} has no frames (max_frames={max_frames})")
    return n


def export_tum_rgbd(
    source: FrameSource,
    folder: str | Path,
    *,
    overwrite: bool = False,
    progress: bool = True,
    max_frames: int | None = None,
    depth_scale: float = DEPTH_SCALE,
) -> Path:
    """Write ``source`` (its first ``max_frames`` frames) as a TUM RGB-D folder with the ``cnnslam.json`` side file.

    Refuses a path that is a file, and a non-empty ``folder`` unless ``overwrite`` (then it writes into it). A new
    folder is written as a hidden temporary folder beside it and renamed into place at the end, so an export that
    is stopped (Ctrl-C, an error) leaves no partial folder in the way of the next one. Shows a tqdm progress bar
    unless ``progress`` is False. Returns the folder.
    """
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise SimEnvError(f"{folder} is a file; an export writes a folder: name a folder that does not exist yet")
    _frames_to_write(source, folder, overwrite, max_frames, "export")
    if folder.is_dir() and any(folder.iterdir()):  # --overwrite into what is there: in place
        return _export_tum_rgbd(source, folder, progress, max_frames, depth_scale)
    folder.parent.mkdir(parents=True, exist_ok=True)
    partial = folder.parent / f".{folder.name}.partial-{os.getpid()}"
    shutil.rmtree(partial, ignore_errors=True)
    try:
        _export_tum_rgbd(source, partial, progress, max_frames, depth_scale)
        if folder.is_dir():  # an empty folder given: the export takes its place
            folder.rmdir()
        os.rename(partial, folder)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    return folder


def _export_tum_rgbd(source: FrameSource, folder: Path, progress: bool, max_frames: int | None,
                     depth_scale: float) -> Path:
    """:func:`export_tum_rgbd`'s writing, into ``folder`` as it is."""
    n = _frames_to_write(source, folder, True, max_frames, "export")
    stamps = np.asarray(source.timestamps, dtype=np.float64)[:n]
    names = [_stamp_name(t) for t in stamps]
    if len(set(names)) != n:
        raise SimEnvError("two timestamps agree to the microsecond; TUM file names (6 decimals) would collide")
    for sub in ("rgb", "depth"):
        (folder / sub).mkdir(parents=True, exist_ok=True)
    max_value = np.iinfo(np.uint16).max
    clipped = 0
    has_labels = has_instances = has_sensor_depth = False
    poses = np.empty((n, 4, 4))
    for i in tqdm(range(n), desc=f"export {source.name}", unit="frame", disable=not progress):
        frame = source.frame(i)
        poses[i] = frame.T_world_cam
        _write_png(folder / "rgb" / names[i], cv2.cvtColor(np.ascontiguousarray(frame.rgb), cv2.COLOR_RGB2BGR))
        depth = np.nan_to_num(np.asarray(frame.depth, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        scaled = np.rint(np.clip(depth, 0.0, None) * depth_scale)
        over = scaled > max_value
        clipped += int(over.sum())
        _write_png(folder / "depth" / names[i], np.where(over, 0, scaled).astype(np.uint16))
        if frame.labels is not None:
            (folder / "labels").mkdir(exist_ok=True)
            _write_png(folder / "labels" / names[i], np.asarray(frame.labels, dtype=np.uint8))
            has_labels = True
        if frame.instances is not None:
            ids = np.asarray(frame.instances, dtype=np.int64) + 1  # NO_INSTANCE (-1) -> 0
            if ids.min() < 0 or ids.max() > max_value:
                raise SimEnvError(f"frame {i}: instance ids must lie in -1..{max_value - 1} to fit a 16-bit PNG")
            (folder / "instances").mkdir(exist_ok=True)
            _write_png(folder / "instances" / names[i], ids.astype(np.uint16))
            has_instances = True
        sensor_depth = getattr(frame, "sensor_depth", None)
        if sensor_depth is not None:
            (folder / "depth_sensor").mkdir(exist_ok=True)
            sensor = np.rint(np.clip(np.nan_to_num(sensor_depth, nan=0.0), 0.0, None) * depth_scale)
            _write_png(folder / "depth_sensor" / names[i], np.where(sensor > max_value, 0, sensor).astype(np.uint16))
            has_sensor_depth = True
    title = f"generated by cnnslam from {source.name!r}"
    write_tum_image_list(folder / "rgb.txt", stamps, [f"rgb/{s}" for s in names], f"color images, {title}")
    write_tum_image_list(folder / "depth.txt", stamps, [f"depth/{s}" for s in names], f"depth maps, {title}")
    write_tum_trajectory(folder / "groundtruth.txt", stamps, poses, header=f"ground truth trajectory, {title}")
    K = source.intrinsics
    side: dict[str, Any] = {
        "format": SIDE_FORMAT,
        "name": source.name,
        "frames": n,
        "intrinsics": {"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width, "height": K.height},
        "camera_convention": "OpenCV: x right, y down, z forward; pixel centres at integers; poses T_world_cam",
        "depth_scale": depth_scale,
        "depth": "planar z in metres = PNG value / depth_scale; 0 = no measurement",
        "depth_clipped_pixels": clipped,
        "labels": None,
        "instances": None,
    }
    if has_labels:
        side["labels"] = {
            "folder": "labels",
            "classes": {str(c.value): c.name.lower() for c in SemanticClass},
            "no_label": NO_LABEL,
        }
    if has_instances:
        side["instances"] = {"folder": "instances", "encoding": "16-bit PNG value = instance id + 1; 0 = none"}
    if has_sensor_depth:
        side["sensor_depth"] = {"folder": "depth_sensor", "encoding": "as depth/, a simulated sensor's noisy depth"}
    effects = getattr(source, "camera_effects", None)
    if effects is not None and effects.any:
        side["camera_effects"] = effects.describe()
        side["photometric_calibration"] = sorted(export_photometric_calibration(source, folder, max_frames=n))
    (folder / SIDE_FILE).write_text(json.dumps(side, indent=2) + "\n")
    return folder


PHOTOMETRIC_FILES: tuple[str, ...] = ("times.txt", "pcalib.txt", "vignette.png", "camera.toml", "camera_raw.toml")


def export_photometric_calibration(source: Any, folder: str | Path, *, max_frames: int | None = None) -> list[str]:
    """Write a simulated sequence's photometric calibration the way the TUM monoVO dataset ships its own (Engel,
    Usenko, Cremers 2016), and its lens, into ``folder``; returns the file names written.

    ``source``: a :class:`sim_envs.sources.simsource.SimulatedSequence` (anything with ``camera_effects``,
    ``intrinsics``,
    ``timestamps`` and ``exposures()``). Files:

    - ``times.txt``: ``index timestamp exposure_ms`` per frame (monoVO's layout; the exposure is the effective one,
      exposure time x analogue gain, in milliseconds, so that irradiance = G(pixel) / (V * exposure));
    - ``pcalib.txt``: the inverse response G, 256 values on one line (G(0) = 0, G(255) = 255; linear signal on the
      0-255 scale);
    - ``vignette.png``: 16-bit vignette V (65535 = 1) on the pixel grid of the exported images (undistorted like
      them when the lens is distorted);
    - ``camera.toml``: the camera of the exported images (``rgb/``): pinhole intrinsics at the image size and zero
      distortion, since delivered images are undistorted (:mod:`sim_envs.sources.simsource`: the crop of
      :meth:`sim_envs.camera.CameraModel.rectified` when the lens is distorted);
    - ``camera_raw.toml``: the lens, for raw sensor images (``SimulatedSequence.raw_rgb``): the rendered camera's
      intrinsics and the OpenCV distortion ``k1 k2 p1 p2 k3``. Both camera files are readable by
      :func:`sim_envs.folders.camera_files.read_camera_file`.
    """
    from sim_envs.sensor.camera_effects import inverse_response, sensor_geometry, undistort_image

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    effects = source.camera_effects
    n = len(source) if max_frames is None else min(int(max_frames), len(source))
    exposure, gain = source.exposures(n - 1)
    stamps = np.asarray(source.timestamps, dtype=np.float64)[:n]
    effective_ms = exposure * gain * 1000.0
    lines = [f"{i:05d} {t:.6f} {e:.6f}" for i, (t, e) in enumerate(zip(stamps, effective_ms, strict=True))]
    (folder / "times.txt").write_text("\n".join(lines) + "\n")
    (folder / "pcalib.txt").write_text(" ".join(f"{g:.6f}" for g in inverse_response(effects)) + "\n")
    K = getattr(source, "sensor_intrinsics", source.intrinsics)  # the rendered camera (raw sensor images)
    geometry = sensor_geometry(K, effects)
    V = geometry.vignette if geometry.vignette is not None else np.ones((K.height, K.width), np.float32)
    V = undistort_image(V, geometry)
    _write_png(folder / "vignette.png", np.rint(np.clip(V, 0.0, 1.0) * 65535).astype(np.uint16))
    pinhole = "the exported rgb/ images: pinhole (undistorted; OpenCV convention, pixel centres at integers)"
    (folder / "camera.toml").write_text(camera_file_text(source.intrinsics, pinhole))
    raw = "the raw sensor images (SimulatedSequence.raw_rgb): OpenCV radial-tangential distortion k1 k2 p1 p2 k3"
    (folder / "camera_raw.toml").write_text(camera_file_text(CameraModel(K, effects.distortion), raw))
    return list(PHOTOMETRIC_FILES)


def write_folder(
    source: FrameSource,
    folder: str | Path,
    layout: str,
    *,
    max_frames: int | None = None,
    depth_scale: float | None = None,
    image_format: Literal["png", "jpg"] = "png",
    camera_file: bool = True,
    overwrite: bool = False,
) -> Path:
    """Write the first ``max_frames`` frames of ``source`` as a folder of ``layout`` (a key of :data:`LAYOUTS`), the
    way that dataset ships it (no ``cnnslam.json``): small real-format fixtures for tests, inputs for other tools.

    - ``tum``: ``rgb/<t>.png``, ``depth/<t>.png``, ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``;
    - ``icl``: ``rgb/<k>.png``, ``depth/<k>.png``, ``associations.txt``, ``traj.gt.freiburg`` (timestamps = frame
      number k; poses as the source has them, OpenCV convention);
    - ``7scenes``: ``frame-XXXXXX.color.<png|jpg>``, ``frame-XXXXXX.depth.png`` (millimetres),
      ``frame-XXXXXX.pose.txt`` in one folder, XXXXXX = frame number;
    - ``7scenes_split``: the same files in ``rgb/``, ``depth/``, ``poses/`` with ``rgb.txt``, ``depth.txt`` and
      ``groundtruth.txt`` beside them (timestamps k / 30 s), as ``../shared/data/real/7scenes_redkitchen``;
    - ``rgb_only``: ``rgb/<t>.png``, ``rgb.txt``, ``groundtruth.txt``.

    Depth is written as 16-bit PNG x ``depth_scale`` (default: the layout's, 1000 for 7-Scenes, else 5000); a depth
    that does not fit (for 7-Scenes: that would read as 65535, its "invalid") is written as 0. ``camera_file``: also
    write ``camera.toml`` with the source's intrinsics. ``image_format``: of the 7-Scenes colour images. Layouts
    without timestamps (ICL, 7-Scenes) number the frames 0, 1, ...: the loader gives frame k the time k / 30 s.
    """
    if layout not in LAYOUTS:
        raise UnknownNameError(f"unknown layout {layout!r}; valid layouts: {', '.join(LAYOUTS)}")
    if image_format not in ("png", "jpg"):
        raise SimEnvError(f"image_format must be png or jpg, got {image_format!r}")
    folder = Path(folder)
    n = _frames_to_write(source, folder, overwrite, max_frames, "write")
    scale = float(depth_scale or _LAYOUT_DEPTH_SCALE.get(layout, DEPTH_SCALE))
    limit = SEVEN_SCENES_INVALID_DEPTH - 1 if layout in _LAYOUT_DEPTH_SCALE else np.iinfo(np.uint16).max
    stamps = np.asarray(source.timestamps, dtype=np.float64)[:n]
    seven = layout.startswith("7scenes")
    flat = layout == "7scenes"  # 7-Scenes as it ships: every file in one folder
    dirs = {"rgb": "" if flat else "rgb/", "depth": "" if flat else "depth/", "pose": "" if flat else "poses/"}
    rows: dict[str, list[str]] = {"rgb": [], "depth": [], "assoc": []}
    poses = np.empty((n, 4, 4))
    for i in range(n):
        frame = source.frame(i)
        poses[i] = frame.T_world_cam
        if seven:
            names = {"rgb": f"frame-{i:06d}.color.{image_format}", "depth": f"frame-{i:06d}.depth.png"}
        elif layout == "icl":
            names = {"rgb": f"{i}.png", "depth": f"{i}.png"}
        else:
            names = dict.fromkeys(("rgb", "depth"), _stamp_name(stamps[i]))
        rgb_rel, depth_rel = dirs["rgb"] + names["rgb"], dirs["depth"] + names["depth"]
        (folder / rgb_rel).parent.mkdir(parents=True, exist_ok=True)
        _write_png(folder / rgb_rel, cv2.cvtColor(np.ascontiguousarray(frame.rgb), cv2.COLOR_RGB2BGR))
        rows["rgb"].append(rgb_rel)
        if layout != "rgb_only":
            depth = np.nan_to_num(np.asarray(frame.depth, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
            scaled = np.rint(np.clip(depth, 0.0, None) * scale)
            (folder / depth_rel).parent.mkdir(parents=True, exist_ok=True)
            _write_png(folder / depth_rel, np.where(scaled > limit, 0, scaled).astype(np.uint16))
            rows["depth"].append(depth_rel)
            rows["assoc"].append(f"{i} {depth_rel} {i} {rgb_rel}")
        if seven:
            pose_rel = dirs["pose"] + f"frame-{i:06d}.pose.txt"
            (folder / pose_rel).parent.mkdir(parents=True, exist_ok=True)
            np.savetxt(folder / pose_rel, frame.T_world_cam, fmt="%.18e")
    title = f"written by cnnslam from {source.name!r} as layout {layout}"
    if layout == "icl":
        (folder / "associations.txt").write_text("\n".join(rows["assoc"]) + "\n")
        write_tum_trajectory(folder / "traj.gt.freiburg", np.arange(n, dtype=np.float64), poses, header=title)
    elif layout != "7scenes":
        times = np.arange(n) / SEVEN_SCENES_FPS if seven else stamps
        write_tum_image_list(folder / "rgb.txt", times, rows["rgb"], f"color images, {title}")
        if layout != "rgb_only":
            write_tum_image_list(folder / "depth.txt", times, rows["depth"], f"depth maps, {title}")
        write_tum_trajectory(folder / "groundtruth.txt", times, poses, header=f"ground truth trajectory, {title}")
    if camera_file:
        K = source.intrinsics
        (folder / CAMERA_FILES[0]).write_text(
            f"# camera of {source.name!r}: pixels, OpenCV convention, for {K.width}x{K.height} images\n"
            f"fx = {K.fx!r}\nfy = {K.fy!r}\ncx = {K.cx!r}\ncy = {K.cy!r}\nwidth = {K.width}\nheight = {K.height}\n"
        )
    return folder
