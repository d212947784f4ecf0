"""RGB-D dataset folders: export any frame source as a TUM RGB-D folder; load real RGB-D folders as frame sources.

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
:func:`write_folder` writes a source in any of the layouts below (small fixtures for tests, inputs for other tools).

Loaded folders (:class:`RgbdFolder`; :func:`load_rgbd_folder` at the processing resolution) are frame sources. The
layout is detected (:func:`detect_layout`, :data:`LAYOUTS`):

- ``tum``, TUM RGB-D: ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``. Each RGB image is associated with a depth
  image and then with a ground-truth pose by the TUM tools' greedy rule (max difference 0.02 s); RGB images without
  both are dropped. Frame i has the RGB image's timestamp and the associated ground-truth pose (not interpolated). A
  timestamp repeated in the ground truth keeps its last pose, as the TUM tools do (fr2/desk has one).
- ``icl``, ICL-NUIM "TUM-compatible": ``associations.txt`` (``index depth/N.png index rgb/N.png``) and one
  ``*.gt.freiburg`` (or ``groundtruth.txt``) trajectory whose timestamps are the same frame indices. Indices are
  matched exactly (within 0.02) and frame k gets the timestamp k / 30 s (ICL-NUIM renders at 30 Hz).
- ``7scenes``, Microsoft 7-Scenes as it ships: ``frame-XXXXXX.color.png`` (or ``.jpg``), ``frame-XXXXXX.depth.png``
  (16-bit millimetres; 0 and 65535 = no measurement) and ``frame-XXXXXX.pose.txt`` (4x4 camera-to-world, metres) in
  one folder. There are no timestamps: frame XXXXXX is at XXXXXX / 30 s. The rotation of each pose is projected
  onto SO(3) (:func:`read_pose_matrix`). A frame without its depth or pose file, or with a non-finite pose, is
  dropped.
- ``7scenes_split``: the same files split into ``rgb/``, ``depth/`` and ``poses/`` (as
  ``../shared/data/real/7scenes_redkitchen``). TUM-style index files beside them are not needed and not read: the
  frames and poses come from the 7-Scenes files, exactly as in the flat layout.
- ``rgb_only``: ``rgb.txt`` and ``groundtruth.txt`` (or ``*.gt.freiburg``) without ``depth.txt``: a camera without
  depth. Frames have an all-zero depth map (0 = no measurement, :attr:`RgbdFolder.has_depth` False), so no depth
  metric can be computed (the benchmark runner skips it).

Depth scale (PNG value per metre), first found: the ``depth_scale`` argument; the side file's ``depth_scale``; the
layout's (7-Scenes: 1000); TUM's 5000.

Camera (intrinsics and lens distortion, :class:`~sim_envs.camera.CameraModel`), first found: the ``camera``
argument (an :class:`Intrinsics` or :class:`CameraModel` at the image size, a preset name of
:func:`sim_envs.camera.preset` with the preset's distortion, or the path of a camera file); the folder's camera file
(:data:`CAMERA_FILES`, see :func:`read_camera_file`); the side file's ``intrinsics`` (and ``distortion``); for
7-Scenes layouts the ``7scenes_rgb`` preset (below); the folder name (``freiburg1/2/3`` -> ``tum_fr1/2/3``: fr1 and
fr2 with their published distortion, fr3 without); ``icl`` for the ICL layout. Otherwise an error lists the
presets. Presets are scaled to the images' size.

7-Scenes' depth maps and KinectFusion poses are the depth camera's, its colour camera another, unregistered one
(7-Scenes gives one intrinsic set, fx = fy = 585, the depth camera's; ``camera-intrinsics.txt`` of andyzeng's
tsdf-fusion is that one). A 7-Scenes folder whose camera is not given (no argument, camera file or side file) is
therefore delivered as its colour camera, as the relocalisation setups ACE and DSAC* register it: intrinsics the
``7scenes_rgb`` preset (525 px), each depth map registered to it (:func:`register_depth`, from the depth camera of
``camera-intrinsics.txt`` or the ``7scenes`` preset, with the Kinect's depth-to-colour baseline
:data:`SEVEN_SCENES_T_COLOUR_DEPTH`), and each pose moved to it (``T_world_depth T_colour_depth^-1``). A camera
given names the colour camera and takes the depth maps and poses as its own, unchanged.

What the agent receives is always an undistorted pinhole image, because the agent contract (``reset(intrinsics,
image_size)``) has only pinhole intrinsics: a distorted camera's images are undistorted with
``cv2.initUndistortRectifyMap`` + ``cv2.remap`` at the original resolution, with the new camera matrix of
``cv2.getOptimalNewCameraMatrix`` at alpha = 0 (:meth:`sim_envs.camera.CameraModel.rectified`: cropped to what the
lens saw, a focal length a few per cent longer than K's, as LSD-SLAM's and DSO's undistorters do, so that no border
without image, fixed in the image, gives direct tracking a static edge); RGB is interpolated bilinearly, depth,
labels and instances take the nearest pixel (depth registered to the RGB image shares its pixel grid; see below for
why nearest).

Then each frame is resized to ``size`` (width, height; :data:`PROCESSING_SIZE` = 320x240, the paper's, for
:func:`load_rgbd_folder`; ``None`` keeps the original): intrinsics f' = f s and c' = (c + 0.5) s - 0.5 per axis
(pixel centres at integers, OpenCV); RGB by area averaging (``cv2.INTER_AREA``: each output pixel averages the input
pixels it covers, so no aliasing); depth, labels and instances by nearest neighbour (``cv2.INTER_NEAREST_EXACT``,
the input pixel under the output pixel's centre) because averaging depth across an object's edge makes depths of
no surface (flying pixels) and averaging with 0 (no measurement) pulls depth towards the camera, and an average of
class or instance ids means nothing. :meth:`RgbdFolder.describe` records the layout, original and processing size,
camera, depth scale and each conversion, for the run record.

ICL-NUIM's official K has fy = -480: its camera's y axis points up (image rows still run top to bottom in the
PNGs). In this project's OpenCV convention (y down) the same camera has fy = +480, and nothing is done to the
images. A pose given for a y-up camera converts as T_cv = S T S with S = diag(1, -1, 1, 1): the camera's y axis is
flipped, and the world's y axis with it so that rotations stay proper (det +1); depth is unchanged. Whether the
poses of a given ICL-NUIM release need this is decided from the data (``pose_convention="auto"``, the default for
the ICL layout): each candidate ("opencv" = as written, "icl" = S T S) is scored by :func:`depth_consistency` (the
depth of one frame, moved into another by the candidate's relative pose, must agree with that frame's depth) on a
few frame pairs, and the better one is used; ``pose_convention_used`` and ``pose_convention_scores`` say what
happened. ICL-NUIM depth PNGs are planar z scaled by 5000; pass ``depth_is_ray_length=True`` for folders made from
the raw POV-Ray depth (Euclidean ray length), converted by z = d / sqrt(((u-cx)/fx)^2 + ((v-cy)/fy)^2 + 1).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from tqdm import tqdm

from sim_envs.camera import (
    DEFAULT_HEIGHT,
    DEFAULT_WIDTH,
    DISTORTION_NAMES,
    UNDISTORT_MODES,
    CameraModel,
    Intrinsics,
    camera_model,
    camera_presets,
)
from sim_envs.errors import FormatError, SimEnvError, UnknownNameError
from sim_envs.formats import (
    associate_greedy,
    read_tum_image_list,
    read_tum_trajectory,
    write_tum_image_list,
    write_tum_trajectory,
)
from sim_envs.frames import NO_INSTANCE, NO_LABEL, Frame, SemanticClass
from sim_envs.source import FrameSource

SIDE_FILE = "cnnslam.json"
SIDE_FORMAT = "cnnslam-tum-rgbd/1"
CAMERA_FILES: tuple[str, ...] = ("camera.toml", "camera.yaml", "camera.yml")  # a folder's own camera file
SEVEN_SCENES_INTRINSICS_FILE = "camera-intrinsics.txt"  # a 3x3 K, as andyzeng/tsdf-fusion ships 7-Scenes frames
DEPTH_SCALE: float = 5000.0  # TUM RGB-D and ICL-NUIM: 16-bit PNG value 5000 = 1 m
SEVEN_SCENES_DEPTH_SCALE: float = 1000.0  # 7-Scenes: millimetres
SEVEN_SCENES_INVALID_DEPTH = 65535  # 7-Scenes marks no measurement by 0 and by 65535
ICL_FPS: float = 30.0
SEVEN_SCENES_FPS: float = 30.0  # 7-Scenes has no timestamps; the Kinect's nominal rate
PROCESSING_SIZE: tuple[int, int] = (DEFAULT_WIDTH, DEFAULT_HEIGHT)  # (width, height): the paper's 320x240
LOADER_VERSION = "cnnslam-rgbd-folder/5"  # recorded in descriptions; bump when a conversion changes its output
# 7-Scenes' depth camera -> colour camera (X_colour = T X_depth, metres): the Kinect's 2.6 cm baseline between
# them, the translation of the LIRIS Kinect calibration (projet.liris.cnrs.fr/voir/activities-dataset/
# kinect-calibration.html) with which the relocalisation setups ACE and DSAC* register 7-Scenes. Its 0.65 deg
# rotation is another Kinect's and is left out: on redkitchen's frames the depth edges fall on the colour edges far
# better without it (sim_envs.camera_calibration.depth_edge_alignment over 20 frames: 2.57 without, 1.41 with,
# 1.30 unregistered; with the translation, 525 px beats 510 and 540: 2.57 vs 1.81 and 2.07).
SEVEN_SCENES_T_COLOUR_DEPTH = np.array([
    [1.0, 0.0, 0.0, -2.5558943178152542e-02],
    [0.0, 1.0, 0.0, 1.0109636268061706e-04],
    [0.0, 0.0, 1.0, 2.0318321729487039e-03],
    [0.0, 0.0, 0.0, 1.0],
])  # fmt: skip
SEVEN_SCENES_T_COLOUR_DEPTH.setflags(write=False)
SEVEN_SCENES_COLOUR_SOURCE = "preset 7scenes_rgb (layout: 7-Scenes' colour camera)"
Layout = Literal["tum", "icl", "7scenes", "7scenes_split", "rgb_only"]
LAYOUTS: dict[str, str] = {
    "tum": "TUM RGB-D (rgb.txt, depth.txt, groundtruth.txt)",
    "icl": "ICL-NUIM TUM-compatible (associations.txt, *.gt.freiburg)",
    "7scenes": "7-Scenes (frame-XXXXXX.color.png|jpg, .depth.png in mm, .pose.txt in one folder)",
    "7scenes_split": "7-Scenes split (rgb/, depth/, poses/ holding the 7-Scenes files)",
    "rgb_only": "RGB only (rgb.txt, groundtruth.txt, no depth.txt)",
}
_LAYOUT_DEPTH_SCALE: dict[str, float] = {"7scenes": SEVEN_SCENES_DEPTH_SCALE, "7scenes_split": SEVEN_SCENES_DEPTH_SCALE}
_SEVEN_SCENES_COLOUR = re.compile(r"^(frame-(\d+))\.color\.(png|jpg)$")
MAX_DIFFERENCE: float = 0.02  # seconds, the TUM tools' default association tolerance
PoseConvention = Literal["opencv", "icl", "auto"]
POSE_CONVENTIONS: tuple[str, ...] = ("opencv", "icl", "auto")
_FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])


# ---------------------------------------------------------------------------------------------------------- export
def _stamp_name(t: float) -> str:
    return f"{t:.6f}.png"


def _write_png(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image):
        raise SimEnvError(f"cannot write the image {path}")


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

    Refuses a non-empty ``folder`` unless ``overwrite``. Shows a tqdm progress bar unless ``progress`` is False.
    Returns the folder.
    """
    folder = Path(folder)
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise SimEnvError(f"{folder} exists and is not empty; choose another folder or allow overwriting it "
                           "(overwrite=True; --overwrite on the command line)")
    n = len(source) if max_frames is None else min(int(max_frames), len(source))
    if n <= 0:
        raise SimEnvError(f"nothing to export: the source {source.name!r} has no frames (max_frames={max_frames})")
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

    ``source``: a :class:`sim_envs.simsource.SimulatedSequence` (anything with ``camera_effects``, ``intrinsics``,
    ``timestamps`` and ``exposures()``). Files:

    - ``times.txt``: ``index timestamp exposure_ms`` per frame (monoVO's layout; the exposure is the effective one,
      exposure time x analogue gain, in milliseconds, so that irradiance = G(pixel) / (V * exposure));
    - ``pcalib.txt``: the inverse response G, 256 values on one line (G(0) = 0, G(255) = 255; linear signal on the
      0-255 scale);
    - ``vignette.png``: 16-bit vignette V (65535 = 1) on the pixel grid of the exported images (undistorted like
      them when the lens is distorted);
    - ``camera.toml``: the camera of the exported images (``rgb/``): pinhole intrinsics at the image size and zero
      distortion, since delivered images are undistorted (:mod:`sim_envs.simsource`: the crop of
      :meth:`sim_envs.camera.CameraModel.rectified` when the lens is distorted);
    - ``camera_raw.toml``: the lens, for raw sensor images (``SimulatedSequence.raw_rgb``): the rendered camera's
      intrinsics and the OpenCV distortion ``k1 k2 p1 p2 k3``. Both camera files are readable by
      :func:`read_camera_file`.
    """
    from sim_envs.camera_effects import inverse_response, sensor_geometry, undistort_image

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
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise SimEnvError(f"{folder} exists and is not empty; choose another folder or allow overwriting it "
                           "(overwrite=True; --overwrite on the command line)")
    n = len(source) if max_frames is None else min(int(max_frames), len(source))
    if n <= 0:
        raise SimEnvError(f"nothing to write: the source {source.name!r} has no frames (max_frames={max_frames})")
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


# ------------------------------------------------------------------------------------------------------ consistency
def depth_consistency(
    depth_a: np.ndarray,
    T_world_a: np.ndarray,
    depth_b: np.ndarray,
    T_world_b: np.ndarray,
    intrinsics: Intrinsics,
    rel_tol: float = 0.05,
    stride: int = 2,
) -> float:
    """Share (0..1) of frame a's depth pixels that, moved into frame b by the poses, land on a depth of b agreeing
    within ``rel_tol`` (relative). Only pixels landing inside b on a valid depth count; NaN if none does.

    depth_*: (H, W) planar z metres (0 = none); T_world_*: (4, 4) camera-to-world; every ``stride``-th pixel is used.
    """
    v, u = np.mgrid[0 : depth_a.shape[0] : stride, 0 : depth_a.shape[1] : stride]
    z = np.asarray(depth_a, dtype=np.float64)[v, u]
    ok = np.isfinite(z) & (z > 0)
    ub, vb, zb = move_pixels(u[ok], v[ok], z[ok], intrinsics, np.linalg.inv(T_world_b) @ T_world_a, intrinsics,
                             depth_b.shape)  # fmt: skip
    measured = np.asarray(depth_b, dtype=np.float64)[vb, ub]
    valid = np.isfinite(measured) & (measured > 0)
    if not valid.any():
        return math.nan
    agree = np.abs(zb[valid] - measured[valid]) < rel_tol * measured[valid]
    return float(agree.mean())


def move_pixels(u: np.ndarray, v: np.ndarray, z: np.ndarray, K_from: Intrinsics, T_to_from: np.ndarray,
                K_to: Intrinsics, shape_to: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Pixels (u, v) with planar depth z (1-D arrays, metres) of a camera ``K_from``, back-projected, moved by
    ``T_to_from`` (4, 4; OpenCV axes) and projected with ``K_to`` to their nearest pixel: (u', v', z') int64, int64,
    float64 of those that land in front of the camera and inside an image of ``shape_to`` (height, width, ...)."""
    points = np.stack([(u - K_from.cx) / K_from.fx * z, (v - K_from.cy) / K_from.fy * z, z, np.ones_like(z)])
    moved = (np.asarray(T_to_from, dtype=np.float64) @ points)[:3]
    zt = moved[2]
    front = zt > 1e-6
    ut = np.rint(K_to.fx * moved[0, front] / zt[front] + K_to.cx).astype(np.int64)
    vt = np.rint(K_to.fy * moved[1, front] / zt[front] + K_to.cy).astype(np.int64)
    zt = zt[front]
    inside = (ut >= 0) & (ut < shape_to[1]) & (vt >= 0) & (vt < shape_to[0])
    return ut[inside], vt[inside], zt[inside]


# ------------------------------------------------------------------------------------------------------------ load
CameraLike = Intrinsics | CameraModel | str | os.PathLike[str] | None


@dataclass(frozen=True)
class _Index:
    """What a layout's files say: per kept frame its timestamp (s), RGB file, depth file (None: no depth), pose."""

    timestamps: np.ndarray
    rgb_files: list[Path]
    depth_files: list[Path] | None
    poses: np.ndarray
    dropped: int  # frames listed but not kept (no depth or no pose)
    timing: str  # where the timestamps come from


def detect_layout(folder: str | Path) -> str:
    """The layout of an RGB-D folder, a key of :data:`LAYOUTS`; :class:`SimEnvError` (one line, listing the layouts)
    when none matches. 7-Scenes file names win over TUM index files beside them."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SimEnvError(f"{folder} is not a folder")
    if _has_seven_scenes_colour(folder):
        return "7scenes"
    if (folder / "poses").is_dir() and _has_seven_scenes_colour(folder / "rgb"):
        return "7scenes_split"
    if (folder / "rgb.txt").is_file():
        return "tum" if (folder / "depth.txt").is_file() else "rgb_only"
    if (folder / "associations.txt").is_file():
        return "icl"
    raise SimEnvError(
        f"{folder}: not an RGB-D folder of a known layout; expected one of: {'; '.join(LAYOUTS.values())}"
    )


@dataclass(frozen=True)
class DepthRig:
    """A depth camera beside the colour camera, whose depth maps and poses the loader moves to the colour camera.

    depth_intrinsics: the depth camera's pinhole K at the depth images' size; T_colour_depth: (4, 4) maps depth-camera
    coordinates to colour-camera coordinates (OpenCV axes, metres); source: where both came from (for the record).
    """

    depth_intrinsics: Intrinsics
    T_colour_depth: np.ndarray
    source: str


def register_depth(depth: np.ndarray, depth_intrinsics: Intrinsics, colour_intrinsics: Intrinsics,
                   T_colour_depth: np.ndarray) -> np.ndarray:  # fmt: skip
    """A depth camera's (H, W) planar z map (metres, 0 = none) seen from the colour camera: each measured pixel is
    back-projected with ``depth_intrinsics``, moved by ``T_colour_depth`` and projected with ``colour_intrinsics``
    to its nearest pixel, the nearest surface winning where several land on one pixel (a z-buffer). Returns
    (colour height, colour width) float32 planar z in the colour camera, 0 where no measurement lands."""
    d = np.asarray(depth, dtype=np.float64)
    Kd, Kc = depth_intrinsics, colour_intrinsics
    if d.shape != (Kd.height, Kd.width):
        raise SimEnvError(f"depth of shape {d.shape} for a depth camera of {Kd.width}x{Kd.height}")
    v, u = np.nonzero(d > 0)
    uc, vc, zc = move_pixels(u, v, d[v, u], Kd, T_colour_depth, Kc, (Kc.height, Kc.width))
    out = np.full(Kc.height * Kc.width, np.inf)
    np.minimum.at(out, vc * Kc.width + uc, zc)
    out[~np.isfinite(out)] = 0.0
    return out.reshape(Kc.height, Kc.width).astype(np.float32)


class RgbdFolder:
    """A real (or exported) RGB-D folder as a :class:`~sim_envs.source.FrameSource`.

    Layouts, depth scale, camera, undistortion and resizing: see the module docstring. ``size``: (width, height) of
    the delivered frames (None: the images' own). ``timestamps`` (N,) float64 seconds; ``poses`` (N, 4, 4) float64
    ``T_world_cam`` in the OpenCV camera convention; ``intrinsics``: the pinhole camera of the delivered
    (undistorted, resized) frames; ``camera``: the folder's camera model at its original resolution;
    ``has_depth``: False for an RGB-only folder. Frames are read from disk on each ``frame(i)`` call (nothing is
    cached).
    """

    def __init__(
        self,
        folder: str | Path,
        camera: CameraLike = None,
        *,
        size: tuple[int, int] | None = None,
        pose_convention: PoseConvention | None = None,
        depth_scale: float | None = None,
        depth_is_ray_length: bool = False,
        max_difference: float = MAX_DIFFERENCE,
        name: str | None = None,
        undistort: str = "crop",
    ) -> None:
        if undistort not in UNDISTORT_MODES:
            raise SimEnvError(f"unknown undistortion {undistort!r}; valid: {', '.join(UNDISTORT_MODES)} (crop: to "
                              "what the lens saw, the default; full: the whole frame with K and a black border; "
                              "none: the distorted images as they are)")  # fmt: skip
        self.undistort: str = undistort
        self.folder = Path(folder)
        self.layout: str = detect_layout(self.folder)
        self.name: str = name or self.folder.name
        side_path = self.folder / SIDE_FILE
        self.side: dict[str, Any] = _read_side_file(side_path) if side_path.exists() else {}
        self.depth_scale, self.depth_scale_source = self._resolve_depth_scale(depth_scale)
        self.depth_is_ray_length = bool(depth_is_ray_length)
        index = self._index(max_difference)
        if not index.rgb_files:
            raise SimEnvError(f"{self.folder}: no RGB image has both a depth image and a ground-truth pose")
        self.timestamps: np.ndarray = index.timestamps
        self._rgb_files = index.rgb_files
        self._depth_files = index.depth_files
        self._index_info = index
        self.has_depth: bool = index.depth_files is not None
        self.original_size: tuple[int, int] = self._image_size()
        self.camera, self.camera_source = self._resolve_camera(camera)
        self.depth_rig: DepthRig | None = self._resolve_depth_rig()
        self.native_intrinsics: Intrinsics = self.camera.rectified(undistort)  # the undistorted images' camera
        self.size: tuple[int, int] = check_size(size) if size is not None else self.original_size
        self.intrinsics: Intrinsics = self.native_intrinsics.scaled(*self.size)
        self._maps: tuple[np.ndarray, np.ndarray] | None = None  # undistortion maps, made on first use
        self._raw_poses = index.poses
        convention = pose_convention or ("auto" if self.layout == "icl" else "opencv")
        if convention not in POSE_CONVENTIONS:
            raise SimEnvError(f"pose_convention must be one of {POSE_CONVENTIONS}, got {convention!r}")
        self.pose_convention_scores: dict[str, float] = {}
        if convention == "auto":
            self.pose_convention_scores = self._score_conventions()
            convention = max(self.pose_convention_scores, key=lambda c: np.nan_to_num(self.pose_convention_scores[c]))
        self.pose_convention_used: str = convention
        self.poses: np.ndarray = convert_pose_convention(index.poses, convention)
        if self.depth_rig is not None:  # the depth camera's poses -> the colour camera's: T_wc = T_wd T_dc
            self.poses = self.poses @ np.linalg.inv(self.depth_rig.T_colour_depth)
        self._labels = self._optional_folder("labels")
        self._instances = self._optional_folder("instances")

    # ---------------------------------------------------------------------------------------------- FrameSource
    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    @property
    def rgb_paths(self) -> list[Path]:
        """The colour image files as they are on disk (before undistortion and resizing), one per frame."""
        return list(self._rgb_files)

    def frame(self, index: int) -> Frame:
        """Frame ``index`` as delivered: RGB (H, W, 3) uint8, depth (H, W) float32 planar z metres (0 = none; all 0
        without depth), pose, and labels / instances where the side file names them."""
        i = self._check_index(index)
        rgb = self.rgb(i)
        depth = self.depth(i)
        labels = instances = None
        if self._labels is not None:
            raw = _read_image(self._labels / self._rgb_files[i].name, cv2.IMREAD_UNCHANGED).astype(np.uint8)
            labels = self._deliver(raw, "labels")
        if self._instances is not None:
            raw = self._deliver(_read_image(self._instances / self._rgb_files[i].name, cv2.IMREAD_UNCHANGED), "ids")
            instances = raw.astype(np.int32) - 1
            instances[raw == 0] = NO_INSTANCE
        return Frame(
            index=i,
            timestamp=float(self.timestamps[i]),
            rgb=rgb,
            depth=depth,
            T_world_cam=self.poses[i].copy(),
            labels=labels,
            instances=instances,
        )

    def rgb(self, index: int) -> np.ndarray:
        """RGB of frame ``index`` alone, as delivered: (H, W, 3) uint8 (the environment's fast path)."""
        i = self._check_index(index)
        image = _read_image(self._rgb_files[i], cv2.IMREAD_COLOR)
        if image.shape[:2] != self.original_size[::-1]:
            raise SimEnvError(
                f"{self._rgb_files[i]}: image of {image.shape[1]}x{image.shape[0]}, but the folder's first image is "
                f"{self.original_size[0]}x{self.original_size[1]}"
            )
        return self._deliver(cv2.cvtColor(image, cv2.COLOR_BGR2RGB), "rgb")

    def depth(self, index: int) -> np.ndarray:
        """Depth of frame ``index`` alone, as delivered: (H, W) float32 planar z metres, 0 = none (all 0 for a
        folder without depth)."""
        i = self._check_index(index)
        if self._depth_files is None:
            return np.zeros(self.size[::-1], dtype=np.float32)
        raw = _read_image(self._depth_files[i], cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2:
            raise SimEnvError(f"{self._depth_files[i]}: a depth image must have one channel, got shape {raw.shape}")
        if raw.shape != self.original_size[::-1]:
            raise SimEnvError(
                f"{self._depth_files[i]}: RGB {self.original_size[::-1]} and depth {raw.shape} sizes differ"
            )
        depth = raw.astype(np.float32) / np.float32(self.depth_scale)
        if self.layout in _LAYOUT_DEPTH_SCALE:
            depth[raw == SEVEN_SCENES_INVALID_DEPTH] = 0.0
        if self.depth_is_ray_length:
            depth = ray_length_to_z(depth, self.native_intrinsics)
        if self.depth_rig is not None:
            rig = self.depth_rig
            depth = register_depth(depth, rig.depth_intrinsics, self.camera.intrinsics, rig.T_colour_depth)
        return self._deliver(depth, "depth")

    def close(self) -> None:
        """Nothing is held open."""

    def describe(self) -> dict[str, Any]:
        """JSON-ready account of what was read and how it was converted (for the run record): layout, original and
        delivered size, camera (and where it came from), depth scale, frames kept and dropped, conversions."""
        K0, K = self.native_intrinsics, self.intrinsics
        return {
            "loader": LOADER_VERSION,
            "folder": str(self.folder.resolve()),
            "layout": self.layout,
            "layout_description": LAYOUTS[self.layout],
            "frames": len(self),
            "frames_dropped": self._index_info.dropped,
            "timestamps": self._index_info.timing,
            "original_size": list(self.original_size),
            "size": list(self.size),
            "camera_source": self.camera_source,
            "camera": camera_fields(self.camera),
            "depth_registration": None if self.depth_rig is None else {
                "depth_intrinsics": _intrinsics_dict(self.depth_rig.depth_intrinsics),
                "T_colour_depth": np.asarray(self.depth_rig.T_colour_depth).tolist(),
                "source": self.depth_rig.source,
            },
            "undistort": self.undistort,
            "undistorted_intrinsics": _intrinsics_dict(K0),
            "intrinsics": _intrinsics_dict(K),
            "has_depth": self.has_depth,
            "depth_scale": self.depth_scale if self.has_depth else None,
            "depth_scale_source": self.depth_scale_source if self.has_depth else None,
            "pose_convention": self.pose_convention_used,
            "conversions": self.conversions(),
        }

    def conversions(self) -> list[str]:
        """The conversions from the folder's files to the delivered frames, in the order they are applied."""
        steps = []
        if self.has_depth:
            invalid = f"0 and {SEVEN_SCENES_INVALID_DEPTH}" if self.layout in _LAYOUT_DEPTH_SCALE else "0"
            steps.append(f"depth: 16-bit PNG value / {self.depth_scale:g} = metres; {invalid} = no measurement")
            if self.depth_is_ray_length:
                steps.append("depth: Euclidean ray length -> planar z")
        else:
            steps.append("depth: none in the folder (frames get all-zero depth; no depth metric)")
        if self.depth_rig is not None:
            Kd = self.depth_rig.depth_intrinsics
            steps.append(
                f"depth: registered from the depth camera (fx {Kd.fx:g}, fy {Kd.fy:g}, cx {Kd.cx:g}, cy {Kd.cy:g}) "
                "to the colour camera: back-projected, moved by T_colour_depth, projected to the nearest pixel, "
                "nearest surface wins"
            )
        if self.layout in _LAYOUT_DEPTH_SCALE:
            steps.append("poses: 4x4 camera-to-world matrices, rotation projected onto SO(3) (SVD)")
            if self.depth_rig is not None:
                steps.append("poses: the depth camera's -> the colour camera's, T_world_colour = T_world_depth "
                             "T_colour_depth^-1")  # fmt: skip
            steps.append(f"timestamps: frame number / {SEVEN_SCENES_FPS:g} s (7-Scenes has none)")
        if self.pose_convention_used == "icl":
            steps.append("poses: ICL-NUIM y-up camera converted to OpenCV, T = S T S, S = diag(1, -1, 1, 1)")
        if self.camera.distorted and self.undistort == "none":
            steps.append("not undistorted (undistort='none'): the distorted images delivered as pinhole ones with K")
        elif self.camera.distorted and self.undistort == "full":
            coeffs = " ".join(f"{n}={c:g}" for n, c in zip(DISTORTION_NAMES, self.camera.distortion, strict=True))
            steps.append(f"undistorted ({coeffs}, OpenCV model) onto the whole frame with K (undistort='full'): "
                         "cv2.initUndistortRectifyMap + cv2.remap, the border the lens never saw black, no depth, "
                         "no label; RGB bilinear, depth/labels nearest")  # fmt: skip
        elif self.camera.distorted:
            K, K0 = self.camera.intrinsics, self.native_intrinsics
            coeffs = " ".join(f"{n}={c:g}" for n, c in zip(DISTORTION_NAMES, self.camera.distortion, strict=True))
            steps.append(
                f"undistorted ({coeffs}, OpenCV model): cv2.initUndistortRectifyMap + cv2.remap, new camera matrix "
                f"cv2.getOptimalNewCameraMatrix alpha=0 (fx {K.fx:g} -> {K0.fx:.2f}, fy {K.fy:g} -> {K0.fy:.2f}, "
                f"cx {K.cx:g} -> {K0.cx:.2f}, cy {K.cy:g} -> {K0.cy:.2f}); RGB bilinear, depth/labels nearest"
            )
        if self.size != self.original_size:
            (w0, h0), (w, h) = self.original_size, self.size
            steps.append(
                f"resized {w0}x{h0} -> {w}x{h}: RGB area averaging, depth/labels nearest neighbour; intrinsics "
                "f' = f s, c' = (c + 0.5) s - 0.5"
            )
        return steps

    def __repr__(self) -> str:
        return f"RgbdFolder({str(self.folder)!r}, layout={self.layout!r}, frames={len(self)}, size={self.size})"

    # -------------------------------------------------------------------------------------------------- helpers
    def _check_index(self, index: int) -> int:
        i = int(index)
        if not 0 <= i < len(self):
            raise SimEnvError(f"frame index {index} out of range 0..{len(self) - 1} of {self.folder}")
        return i

    def _deliver(self, image: np.ndarray, kind: Literal["rgb", "depth", "labels", "ids"]) -> np.ndarray:
        """An image at the original resolution -> undistorted (if the camera is distorted) and resized to
        ``size``. RGB: bilinear remap, area-averaged resize; depth, labels, instance ids: nearest neighbour."""
        if self.camera.distorted and self.undistort != "none":
            if self._maps is None:
                self._maps = self.camera.undistort_maps(self.undistort)
            interpolation = cv2.INTER_LINEAR if kind == "rgb" else cv2.INTER_NEAREST
            if self.undistort == "crop":  # every position inside the image
                image = cv2.remap(image, *self._maps, interpolation, borderMode=cv2.BORDER_REPLICATE)
            else:  # the border the lens never saw: black, no depth, no label, no instance
                fill = {"rgb": 0, "depth": 0, "labels": NO_LABEL, "ids": 0}[kind]  # ids: as stored, 0 = none
                image = cv2.remap(image, *self._maps, interpolation, borderMode=cv2.BORDER_CONSTANT, borderValue=fill)
        if self.size != self.original_size:
            interpolation = cv2.INTER_AREA if kind == "rgb" else cv2.INTER_NEAREST_EXACT
            image = cv2.resize(image, self.size, interpolation=interpolation)
        return image

    def _resolve_depth_scale(self, depth_scale: float | None) -> tuple[float, str]:
        if depth_scale is not None:
            value, source = depth_scale, "argument"
        elif "depth_scale" in self.side:
            value, source = self.side["depth_scale"], SIDE_FILE
        elif self.layout in _LAYOUT_DEPTH_SCALE:
            value, source = _LAYOUT_DEPTH_SCALE[self.layout], f"layout {self.layout}"
        else:
            value, source = DEPTH_SCALE, "default (TUM: 5000 = 1 m)"
        try:
            value = float(value)
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise SimEnvError(f"{self.folder}: depth_scale must be a positive number (from {source}), got {value!r}")
        return value, source

    def _ground_truth_file(self) -> Path:
        for candidate in [self.folder / "groundtruth.txt", *sorted(self.folder.glob("*.gt.freiburg"))]:
            if candidate.exists():
                return candidate
        raise SimEnvError(f"{self.folder}: no ground truth (groundtruth.txt or *.gt.freiburg)")

    def _index(self, max_difference: float) -> _Index:
        if self.layout == "tum":
            return self._index_tum(max_difference)
        if self.layout == "icl":
            return self._index_icl(max_difference)
        if self.layout == "rgb_only":
            return self._index_rgb_only(max_difference)
        if self.layout == "7scenes":
            return _index_seven_scenes(self.folder, self.folder, self.folder)
        return _index_seven_scenes(self.folder / "rgb", self.folder / "depth", self.folder / "poses")

    def _index_tum(self, max_difference: float) -> _Index:
        rgb_t, rgb_names = read_tum_image_list(self.folder / "rgb.txt")
        depth_t, depth_names = read_tum_image_list(self.folder / "depth.txt")
        gt_t, gt_T = read_tum_trajectory(self._ground_truth_file(), duplicate_timestamps="last")
        ri, di = associate_greedy(rgb_t, depth_t, max_difference)
        rj, gj = associate_greedy(rgb_t[ri], gt_t, max_difference)
        keep_rgb, keep_depth = ri[rj], di[rj]
        return _Index(
            rgb_t[keep_rgb].copy(),
            [self.folder / rgb_names[k] for k in keep_rgb],
            [self.folder / depth_names[k] for k in keep_depth],
            gt_T[gj],
            len(rgb_t) - len(keep_rgb),
            "rgb.txt",
        )

    def _index_rgb_only(self, max_difference: float) -> _Index:
        rgb_t, rgb_names = read_tum_image_list(self.folder / "rgb.txt")
        gt_t, gt_T = read_tum_trajectory(self._ground_truth_file(), duplicate_timestamps="last")
        ri, gi = associate_greedy(rgb_t, gt_t, max_difference)
        return _Index(
            rgb_t[ri].copy(), [self.folder / rgb_names[k] for k in ri], None, gt_T[gi], len(rgb_t) - len(ri), "rgb.txt"
        )

    def _index_icl(self, max_difference: float) -> _Index:
        path = self.folder / "associations.txt"
        rows = []
        for number, line in enumerate(path.read_text().splitlines(), start=1):
            fields = line.split("#", 1)[0].split()
            if not fields:
                continue
            if len(fields) != 4:
                raise FormatError(
                    f"{path}:{number}: expected 4 columns (index depth/N.png index rgb/N.png), found {len(fields)}"
                )
            try:
                rows.append((float(fields[2]), fields[3], fields[1]))
            except ValueError:
                raise FormatError(f"{path}:{number}: {fields[2]!r} is not a number (the RGB frame index)") from None
        if not rows:
            raise FormatError(f"{path}: no entries")
        rows.sort()
        index = np.array([r[0] for r in rows])
        gt_t, gt_T = read_tum_trajectory(self._ground_truth_file(), duplicate_timestamps="last")
        ai, gi = associate_greedy(index, gt_t, max_difference)
        return _Index(
            index[ai] / ICL_FPS,
            [self.folder / rows[k][1] for k in ai],
            [self.folder / rows[k][2] for k in ai],
            gt_T[gi],
            len(rows) - len(ai),
            f"frame index / {ICL_FPS:g} s",
        )

    def _image_size(self) -> tuple[int, int]:
        image = _read_image(self._rgb_files[0], cv2.IMREAD_UNCHANGED)
        return image.shape[1], image.shape[0]

    def _resolve_camera(self, camera: CameraLike) -> tuple[CameraModel, str]:
        """The camera model at the images' size and where it came from (see the module docstring for the order)."""
        width, height = self.original_size
        if isinstance(camera, CameraModel | Intrinsics):
            model = camera if isinstance(camera, CameraModel) else CameraModel(camera)
            K = model.intrinsics
            if (K.width, K.height) != (width, height):
                raise SimEnvError(
                    f"{self.folder}: intrinsics for {K.width}x{K.height} but the images are {width}x{height}; "
                    "use Intrinsics.scaled() or a preset name (scaled automatically)"
                )
            return model, "argument"
        if camera is not None:
            text = os.fspath(camera)
            if text in camera_presets():
                return camera_model(text, width, height), f"preset {text}"
            if Path(text).is_file():
                return read_camera_file(text, width, height), f"camera file {Path(text).resolve()}"
            raise UnknownNameError(
                f"camera {text!r} is neither a preset ({', '.join(camera_presets())}) nor a camera file"
            )
        own = next((self.folder / n for n in CAMERA_FILES if (self.folder / n).is_file()), None)
        if own is not None:
            return read_camera_file(own, width, height), f"camera file {own.name}"
        if self.side.get("intrinsics"):
            return self._side_camera(width, height), SIDE_FILE
        if self.layout in _LAYOUT_DEPTH_SCALE:  # its colour camera; depth and poses are the depth camera's
            return camera_model("7scenes_rgb", width, height), SEVEN_SCENES_COLOUR_SOURCE
        guess = _preset_from_name(self.folder.name)
        if guess is not None:
            return camera_model(guess, width, height), f"preset {guess} (folder name)"
        if self.layout == "icl":
            return camera_model("icl", width, height), "preset icl (layout)"
        raise UnknownNameError(
            f"{self.folder}: cannot tell the camera; pass a camera preset ({', '.join(camera_presets())}) or a "
            f"camera file, or put a {CAMERA_FILES[0]} in the folder"
        )

    def _resolve_depth_rig(self) -> DepthRig | None:
        """7-Scenes with its own colour camera (no camera given): its depth camera (``camera-intrinsics.txt``, else
        the ``7scenes`` preset) and the published depth-to-colour calibration; None otherwise (the depth maps and
        poses are taken as the colour camera's)."""
        if self.camera_source != SEVEN_SCENES_COLOUR_SOURCE or not self.has_depth:
            return None
        width, height = self.original_size
        path = self.folder / SEVEN_SCENES_INTRINSICS_FILE
        if path.is_file():
            K, source = _read_intrinsics_matrix(path, width, height), SEVEN_SCENES_INTRINSICS_FILE
        else:
            K, source = camera_model("7scenes", width, height).intrinsics, "preset 7scenes"
        note = "depth-to-colour: the Kinect's baseline (the LIRIS calibration's translation, as ACE and DSAC* use)"
        return DepthRig(K, SEVEN_SCENES_T_COLOUR_DEPTH, f"depth camera {source}; {note}")

    def _side_camera(self, width: int, height: int) -> CameraModel:
        k = self.side["intrinsics"]
        try:
            K = Intrinsics(
                float(k["fx"]), float(k["fy"]), float(k["cx"]), float(k["cy"]), int(k["width"]), int(k["height"])
            )
            model = CameraModel(K, tuple(self.side.get("distortion") or (0.0,) * len(DISTORTION_NAMES)))
        except (KeyError, TypeError, ValueError) as exc:
            raise FormatError(f"{self.folder / SIDE_FILE}: bad 'intrinsics' or 'distortion' entry ({exc})") from exc
        if (K.width, K.height) != (width, height):
            raise SimEnvError(
                f"{self.folder / SIDE_FILE}: intrinsics for {K.width}x{K.height} but the images are {width}x{height}"
            )
        return model

    def _optional_folder(self, key: str) -> Path | None:
        entry = self.side.get(key)
        if not entry:
            return None
        path = self.folder / str(entry.get("folder", key))
        return path if path.is_dir() else None

    def _score_conventions(self) -> dict[str, float]:
        """Mean :func:`depth_consistency` of each candidate convention over up to 3 frame pairs with motion."""
        pairs = _moving_pairs(self._raw_poses)
        depths = {i: self.depth(i) for pair in pairs for i in pair}
        scores = {}
        for convention in ("opencv", "icl"):
            poses = convert_pose_convention(self._raw_poses[[i for p in pairs for i in p]], convention)
            values = [
                depth_consistency(depths[i], poses[2 * k], depths[j], poses[2 * k + 1], self.intrinsics)
                for k, (i, j) in enumerate(pairs)
            ]
            finite = [v for v in values if np.isfinite(v)]
            scores[convention] = float(np.mean(finite)) if finite else math.nan
        return scores


def load_rgbd_folder(
    folder: str | Path, camera: CameraLike = None, *, size: tuple[int, int] | None = PROCESSING_SIZE, **kwargs: Any
) -> RgbdFolder:
    """An RGB-D folder of any layout as a frame source delivered at ``size`` (default 320x240, the paper's
    processing resolution; None: the images' own); see :class:`RgbdFolder`."""
    return RgbdFolder(folder, camera, size=size, **kwargs)


def load_tum_rgbd_folder(folder: str | Path, camera: CameraLike = None, **kwargs: Any) -> RgbdFolder:
    """Load an RGB-D folder (TUM RGB-D, ICL-NUIM, 7-Scenes, RGB-only) at its own resolution; see :class:`RgbdFolder`."""
    return RgbdFolder(folder, camera, **kwargs)


def read_pose_matrix(path: str | Path) -> np.ndarray:
    """A 7-Scenes ``frame-XXXXXX.pose.txt`` (4 rows of 4 numbers, camera-to-world, metres) -> (4, 4) float64
    ``T_world_cam``, the rotation block replaced by the nearest rotation (SVD, U V^T): 7-Scenes' KinectFusion
    matrices are orthonormal only to about 4e-4. A matrix with a non-finite entry (no pose) comes back all NaN."""
    path = Path(path)
    try:
        M = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except (OSError, ValueError) as exc:
        raise FormatError(f"{path}: not a 4x4 matrix of numbers ({exc})") from exc
    if M.shape != (4, 4):
        raise FormatError(f"{path}: expected 4 rows of 4 numbers (a 4x4 camera-to-world matrix), got {M.shape}")
    if not np.isfinite(M).all():
        return np.full((4, 4), np.nan)
    if not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
        raise FormatError(f"{path}: the last row of a pose must be 0 0 0 1, got {M[3].tolist()}")
    U, _, Vt = np.linalg.svd(M[:3, :3])
    R = U @ Vt
    if np.linalg.det(R) < 0:
        raise FormatError(f"{path}: the 3x3 block is a reflection (det < 0), not a rotation")
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = M[:3, 3]
    return T


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


def folder_fingerprint(folder: str | Path, extra_files: Sequence[str | Path] = ()) -> dict[str, Any]:
    """A content fingerprint of an RGB-D folder that is cheap to compute: SHA-256 over the content of its text
    files (index files, trajectories, 7-Scenes poses, side and camera files: what says which frame is where and
    which pose it has) and the name and size of every other file (the images), in the folder and its immediate
    sub-folders, plus the content of ``extra_files`` (a camera file elsewhere). Modification times are left out, so
    a copied folder keeps its fingerprint. Returns ``{"sha256", "files", "bytes"}``."""
    root = Path(folder)
    entries = []
    for path in sorted(_fingerprint_files(root)):
        stat = path.stat()
        entries.append((path.relative_to(root).as_posix(), stat.st_size, stat.st_mtime_ns, path))
    extra = [Path(p) for p in extra_files]
    key = (str(root.resolve()), tuple(e[:3] for e in entries), tuple(str(p) for p in extra))
    cached = _FINGERPRINTS.get(key)
    if cached is not None:
        return dict(cached)
    digest = hashlib.sha256()
    total = 0
    for rel, size, _, path in entries:
        digest.update(f"{rel}\0{size}\0".encode())
        if path.suffix.lower() in _TEXT_SUFFIXES:
            digest.update(path.read_bytes())
        total += size
    for path in extra:
        digest.update(f"extra\0{path.name}\0".encode() + path.read_bytes())
    result = {"sha256": digest.hexdigest(), "files": len(entries), "bytes": total}
    _FINGERPRINTS[key] = result  # the listing (with mtimes) is the key: a changed file is hashed again
    return dict(result)


_TEXT_SUFFIXES = frozenset({".txt", ".json", ".toml", ".yaml", ".yml", ".freiburg", ".csv"})
_FINGERPRINTS: dict[tuple, dict[str, Any]] = {}


def _fingerprint_files(root: Path) -> list[Path]:
    files = []
    for entry in os.scandir(root):
        if entry.name.startswith("."):
            continue
        if entry.is_file():
            files.append(Path(entry.path))
        elif entry.is_dir():
            files += [Path(e.path) for e in os.scandir(entry.path) if e.is_file() and not e.name.startswith(".")]
    return files


def _index_seven_scenes(colour_dir: Path, depth_dir: Path, pose_dir: Path) -> _Index:
    """7-Scenes frames: every ``frame-XXXXXX.color.png|jpg`` with its ``.depth.png`` and a finite ``.pose.txt``."""
    colour: dict[int, Path] = {}
    for path in colour_dir.iterdir():
        match = _SEVEN_SCENES_COLOUR.match(path.name)
        if match and not (int(match[2]) in colour and colour[int(match[2])].suffix == ".png"):
            colour[int(match[2])] = path  # PNG wins over a JPEG of the same frame
    stamps, rgb_files, depth_files, poses = [], [], [], []
    dropped = 0
    for number in sorted(colour):
        prefix = _SEVEN_SCENES_COLOUR.match(colour[number].name)[1]  # type: ignore[index]
        depth, pose = depth_dir / f"{prefix}.depth.png", pose_dir / f"{prefix}.pose.txt"
        T = read_pose_matrix(pose) if depth.is_file() and pose.is_file() else None
        if T is None or not np.isfinite(T).all():
            dropped += 1
            continue
        stamps.append(number / SEVEN_SCENES_FPS)
        rgb_files.append(colour[number])
        depth_files.append(depth)
        poses.append(T)
    return _Index(
        np.asarray(stamps, dtype=np.float64),
        rgb_files,
        depth_files,
        np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4),
        dropped,
        f"frame number / {SEVEN_SCENES_FPS:g} s",
    )


def _has_seven_scenes_colour(folder: Path) -> bool:
    return folder.is_dir() and any(_SEVEN_SCENES_COLOUR.match(p.name) for p in folder.glob("frame-*.color.*"))


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


def check_size(size: Sequence[int]) -> tuple[int, int]:
    """``size`` as a (width, height) pair of positive pixel counts; :class:`SimEnvError` otherwise."""
    try:
        width, height = (int(v) for v in size)
    except (TypeError, ValueError):
        raise SimEnvError(f"size must be (width, height) in pixels, got {size!r}") from None
    if width <= 0 or height <= 0:
        raise SimEnvError(f"size must be positive, got {width}x{height}")
    return width, height


def _intrinsics_dict(K: Intrinsics) -> dict[str, float | int]:
    return {"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width, "height": K.height}


def convert_pose_convention(T_world_cam: np.ndarray, convention: str) -> np.ndarray:
    """Poses (N, 4, 4) as written in a folder -> OpenCV-convention poses: "opencv" unchanged, "icl" S T S with
    S = diag(1, -1, 1, 1) (camera and world y axes flipped; S is its own inverse, so this also converts back)."""
    T = np.asarray(T_world_cam, dtype=np.float64)
    if convention == "opencv":
        return T.copy()
    if convention == "icl":
        return _FLIP_Y @ T @ _FLIP_Y
    raise SimEnvError(f"unknown pose convention {convention!r}; valid: opencv, icl")


def ray_length_to_z(distance: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """Euclidean ray length (H, W) -> planar z (H, W): z = d / sqrt(((u-cx)/fx)^2 + ((v-cy)/fy)^2 + 1)."""
    K = intrinsics
    v, u = np.mgrid[0 : distance.shape[0], 0 : distance.shape[1]]
    scale = np.sqrt(((u - K.cx) / K.fx) ** 2 + ((v - K.cy) / K.fy) ** 2 + 1.0)
    return (distance / scale).astype(np.float32)


def _moving_pairs(T: np.ndarray, n_pairs: int = 3, min_translation: float = 0.05, min_angle_deg: float = 3.0):
    """Up to ``n_pairs`` frame pairs (i, j), j > i, with enough motion between them to tell conventions apart."""
    n = T.shape[0]
    pairs: list[tuple[int, int]] = []
    for start in np.linspace(0, max(n - 2, 0), n_pairs).astype(int):
        i = int(start)
        for j in range(i + 1, min(n, i + 60)):
            R = T[i, :3, :3].T @ T[j, :3, :3]
            angle = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
            if np.linalg.norm(T[j, :3, 3] - T[i, :3, 3]) >= min_translation or angle >= min_angle_deg:
                pairs.append((i, j))
                break
    if not pairs and n > 1:
        pairs.append((0, n - 1))
    return pairs


def _preset_from_name(name: str) -> str | None:
    match = re.search(r"freiburg([123])", name)
    return f"tum_fr{match.group(1)}" if match else None


def _read_side_file(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise FormatError(f"{path}: not a readable JSON side file: {exc}") from exc
    if not isinstance(data, dict):
        raise FormatError(f"{path}: the side file must hold a JSON object")
    return data


def _read_image(path: Path, flags: int) -> np.ndarray:
    image = cv2.imread(str(path), flags)
    if image is None:
        raise SimEnvError(f"cannot read the image {path} (missing or not an image)")
    return image


__all__: Sequence[str] = (
    "CAMERA_FILES",
    "LAYOUTS",
    "PROCESSING_SIZE",
    "RgbdFolder",
    "convert_pose_convention",
    "depth_consistency",
    "detect_layout",
    "export_photometric_calibration",
    "export_tum_rgbd",
    "folder_fingerprint",
    "load_rgbd_folder",
    "load_tum_rgbd_folder",
    "ray_length_to_z",
    "read_camera_file",
    "read_pose_matrix",
    "write_folder",
)
