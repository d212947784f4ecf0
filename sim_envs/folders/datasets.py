"""RGB-D dataset folders as frame sources: load a real (or exported) RGB-D folder and convert its frames.

Four modules do the rest, and this one re-exports the names other code imports from it:
:mod:`sim_envs.folders.folder_layouts` (layouts, their detection and indexing, the side file, folder fingerprints),
:mod:`sim_envs.folders.camera_files` (reading and writing camera files), :mod:`sim_envs.folders.depth_registration`
(depth maps
moved between cameras; depth checked against poses) and :mod:`sim_envs.folders.folder_exports` (any frame source
written as
a TUM RGB-D folder, :func:`export_tum_rgbd`, or a folder of any layout, :func:`write_folder`).

Loaded folders (:class:`RgbdFolder`; :func:`load_rgbd_folder` at the processing resolution) are frame sources. The
layout is detected (:func:`detect_layout`, :data:`LAYOUTS`: TUM RGB-D, ICL-NUIM, 7-Scenes flat or split, RGB only)
and the frames indexed (timestamps, files, poses) as :mod:`sim_envs.folders.folder_layouts` describes.

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

import math
import numbers
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

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
from sim_envs.folders.camera_files import (
    CAMERA_FILES,
    SEVEN_SCENES_INTRINSICS_FILE,
    _intrinsics_dict,
    _read_intrinsics_matrix,
    camera_fields,
    camera_file_text,
    read_camera_file,
)
from sim_envs.folders.depth_registration import SEVEN_SCENES_T_COLOUR_DEPTH, DepthRig, depth_consistency, register_depth
from sim_envs.folders.folder_exports import export_photometric_calibration, export_tum_rgbd, write_folder
from sim_envs.folders.folder_layouts import (
    _LAYOUT_DEPTH_SCALE,
    DEPTH_SCALE,
    LAYOUTS,
    MAX_DIFFERENCE,
    SEVEN_SCENES_FPS,
    SEVEN_SCENES_INVALID_DEPTH,
    SIDE_FILE,
    _read_side_file,
    detect_layout,
    folder_fingerprint,
    index_folder,
    read_pose_matrix,
)
from sim_envs.folders.prefetch import Prefetcher
from sim_envs.folders.prepared import PreparedImages, prepared_key
from sim_envs.frames import NO_INSTANCE, NO_LABEL, Frame

PROCESSING_SIZE: tuple[int, int] = (DEFAULT_WIDTH, DEFAULT_HEIGHT)  # (width, height): the paper's 320x240
LOADER_VERSION = "cnnslam-rgbd-folder/5"  # recorded in descriptions; bump when a conversion changes its output
SEVEN_SCENES_COLOUR_SOURCE = "preset 7scenes_rgb (layout: 7-Scenes' colour camera)"
PoseConvention = Literal["opencv", "icl", "auto"]
POSE_CONVENTIONS: tuple[str, ...] = ("opencv", "icl", "auto")
_FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])
PREFETCH_AHEAD = 6  # frames read ahead of a run of consecutive reads (0: none); see sim_envs.folders.prefetch
PREFETCH_WORKERS = 3  # threads reading ahead: the 2 cores a run is given, and one more for a thread waiting on disk
_IMREAD_RGB: int = getattr(cv2, "IMREAD_COLOR_RGB", cv2.IMREAD_COLOR)  # OpenCV >= 4.10 decodes to RGB itself

CameraLike = Intrinsics | CameraModel | str | os.PathLike[str] | None


class RgbdFolder:
    """A real (or exported) RGB-D folder as a :class:`~sim_envs.source.FrameSource`.

    Layouts, depth scale, camera, undistortion and resizing: see the module docstring. ``size``: (width, height) of
    the delivered frames (None: the images' own). ``timestamps`` (N,) float64 seconds; ``poses`` (N, 4, 4) float64
    ``T_world_cam`` in the OpenCV camera convention; ``intrinsics``: the pinhole camera of the delivered
    (undistorted, resized) frames; ``camera``: the folder's camera model at its original resolution;
    ``has_depth``: False for an RGB-only folder. Frames are read from disk on each ``frame(i)`` / ``rgb(i)`` call
    (nothing is cached); ``prefetch`` (default :data:`PREFETCH_AHEAD`; 0: off): once ``frame`` or ``rgb`` is asked
    for two consecutive indices, the next ``prefetch`` frames are read ahead on :data:`PREFETCH_WORKERS` threads
    (:class:`~sim_envs.folders.prefetch.Prefetcher`: the same bytes, handed back in the order asked; :meth:`close`
    stops the threads). ``prepared``: a folder under which the delivered RGB images are kept once converted and read
    back by later runs that convert the same way (:class:`~sim_envs.folders.prepared.PreparedImages`: the same
    bytes; ``prepared_images`` is the store, None without one).
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
        prefetch: int = PREFETCH_AHEAD,
        prepared: str | os.PathLike[str] | None = None,
    ) -> None:
        if isinstance(prefetch, bool) or not isinstance(prefetch, numbers.Integral) or prefetch < 0:
            raise SimEnvError(f"prefetch must be a whole number of frames >= 0 (0: no reading ahead), got {prefetch!r}")
        self.prefetch: int = int(prefetch)
        self._prefetchers: dict[str, Prefetcher[Any]] = {}
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
        index = index_folder(self.folder, self.layout, max_difference)
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
        self.prepared_images: PreparedImages | None = None
        if prepared is not None:
            key = prepared_key(self.describe(), folder_fingerprint(self.folder))
            self.prepared_images = PreparedImages(Path(prepared) / key, (self.size[1], self.size[0], 3))

    # ---------------------------------------------------------------------------------------------- FrameSource
    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    @property
    def rgb_paths(self) -> list[Path]:
        """The colour image files as they are on disk (before undistortion and resizing), one per frame."""
        return list(self._rgb_files)

    @property
    def depth_paths(self) -> list[Path]:
        """The depth image files as they are on disk, one per frame (empty for a folder without depth)."""
        return list(self._depth_files or [])

    @property
    def prefetch_hits(self) -> int:
        """Frames handed back from a read ahead since the threads last started (see ``prefetch``)."""
        return sum(p.hits for p in self._prefetchers.values())

    def frame(self, index: int) -> Frame:
        """Frame ``index`` as delivered: RGB (H, W, 3) uint8, depth (H, W) float32 planar z metres (0 = none; all 0
        without depth), pose, and labels / instances where the side file names them."""
        i = self._check_index(index)
        if self.prefetch:
            return self._prefetched("frame", self._read_frame).get(i)
        return self._read_frame(i)

    def _read_frame(self, i: int) -> Frame:
        rgb = self._read_rgb(i)
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
        if self.prefetch:
            return self._prefetched("rgb", self._read_rgb).get(i)
        return self._read_rgb(i)

    def _read_rgb(self, i: int) -> np.ndarray:
        store = self.prepared_images
        if store is None:
            return self._convert_rgb(i)
        image = store.load(i, self._rgb_files[i])
        if image is None:
            image = self._convert_rgb(i)
            store.store(i, self._rgb_files[i], image)
        return image

    def _convert_rgb(self, i: int) -> np.ndarray:
        # decoded straight to RGB: the bytes of decoding to BGR and swapping the channels, without the swap
        image = _read_image(self._rgb_files[i], _IMREAD_RGB)
        if image.shape[:2] != self.original_size[::-1]:
            raise SimEnvError(
                f"{self._rgb_files[i]}: image of {image.shape[1]}x{image.shape[0]}, but the folder's first image is "
                f"{self.original_size[0]}x{self.original_size[1]}"
            )
        if _IMREAD_RGB == cv2.IMREAD_COLOR:  # an OpenCV without IMREAD_COLOR_RGB: swap after undistortion and
            # resizing, which treat each channel alone (the same bytes as swapping first, on fewer pixels)
            return cv2.cvtColor(self._deliver(image, "rgb"), cv2.COLOR_BGR2RGB)
        return self._deliver(image, "rgb")

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
        """Stop the threads reading ahead (no file is held open); reading again starts them again."""
        prefetchers, self._prefetchers = list(self._prefetchers.values()), {}
        for prefetcher in prefetchers:
            prefetcher.close()

    def __getstate__(self) -> dict[str, Any]:
        """Picklable state (for worker processes): without the threads reading ahead."""
        state = dict(self.__dict__)
        state["_prefetchers"] = {}
        return state

    def _prefetched(self, kind: str, read: Any) -> Prefetcher[Any]:
        """The prefetcher of the per-frame reader ``kind`` ("rgb" or "frame"), made on first use."""
        prefetcher = self._prefetchers.get(kind)
        if prefetcher is None:
            prefetcher = Prefetcher(read, len(self), ahead=self.prefetch, workers=PREFETCH_WORKERS,
                                    label=lambda i: str(self._rgb_files[i]))  # fmt: skip
            self._prefetchers[kind] = prefetcher
        return prefetcher

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


def check_size(size: Sequence[int]) -> tuple[int, int]:
    """``size`` as a (width, height) pair of positive whole pixel counts (ints, or floats of whole values);
    :class:`SimEnvError` otherwise."""
    try:
        width, height = size
        whole = all(isinstance(v, numbers.Real) and not isinstance(v, bool) and float(v) == int(v)
                    for v in (width, height))  # fmt: skip
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole:
        raise SimEnvError(f"size must be (width, height) in whole pixels, got {size!r}")
    width, height = int(width), int(height)
    if width <= 0 or height <= 0:
        raise SimEnvError(f"size must be positive, got {width}x{height}")
    return width, height


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


def _read_image(path: Path, flags: int) -> np.ndarray:
    image = cv2.imread(str(path), flags)
    if image is None:
        raise SimEnvError(f"cannot read the image {path} (missing or not an image)")
    return image


# this module's public names and those it re-exports from camera_files, depth_registration, folder_exports and
# folder_layouts (other code imports them from here)
__all__: Sequence[str] = (
    "CAMERA_FILES",
    "LAYOUTS",
    "LOADER_VERSION",
    "PROCESSING_SIZE",
    "SEVEN_SCENES_COLOUR_SOURCE",
    "SEVEN_SCENES_T_COLOUR_DEPTH",
    "SIDE_FILE",
    "RgbdFolder",
    "camera_fields",
    "camera_file_text",
    "check_size",
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
    "register_depth",
    "write_folder",
)
