"""RGB-D dataset folders: export any frame source as a TUM RGB-D folder; load TUM RGB-D and ICL-NUIM folders.

Exported folder (:func:`export_tum_rgbd`), readable by third-party SLAM systems (ORB-SLAM3, DSO, DROID-SLAM) and by
the TUM tools::

    rgb/<t>.png        8-bit RGB                         rgb.txt          "timestamp rgb/<t>.png"
    depth/<t>.png      16-bit, metres x 5000, 0 = none   depth.txt        "timestamp depth/<t>.png"
    labels/<t>.png     8-bit SemanticClass, 255 = none   groundtruth.txt  "timestamp tx ty tz qx qy qz qw"
    instances/<t>.png  16-bit, instance id + 1, 0 = none
    cnnslam.json       the side file: intrinsics (pixels, OpenCV convention, at the image size), depth scale,
                       what labels/ and instances/ hold, how many depth pixels were beyond the 16-bit range

``<t>`` is the timestamp with 6 decimals; the text files hold the exact timestamps. Depth is planar z; a depth
beyond 65535 / 5000 = 13.107 m cannot be stored and is written as 0 (no measurement), counted in the side file.

Loaded folders (:class:`RgbdFolder`, :func:`load_tum_rgbd_folder`) are frame sources:

- TUM RGB-D layout: ``rgb.txt``, ``depth.txt``, ``groundtruth.txt``. Each RGB image is associated with a depth image
  and then with a ground-truth pose by the TUM tools' greedy rule (max difference 0.02 s); RGB images without both
  are dropped. Frame i has the RGB image's timestamp and the associated ground-truth pose (not interpolated). A
  timestamp repeated in the ground truth keeps its last pose, as the TUM tools do (fr2/desk has one).
- ICL-NUIM "TUM-compatible" layout: ``associations.txt`` (``index depth/N.png index rgb/N.png``) and one
  ``*.gt.freiburg`` (or ``groundtruth.txt``) trajectory whose timestamps are the same frame indices. Indices are
  matched exactly (within 0.02) and frame k gets the timestamp k / 30 s (ICL-NUIM renders at 30 Hz).

Intrinsics, first found: the ``intrinsics`` argument (an :class:`Intrinsics` at the image size, or a preset name of
:func:`sim_envs.camera.preset`, scaled to the image size); the folder's ``cnnslam.json``; the folder name
(``freiburg1/2/3`` -> ``tum_fr1/2/3``); ``icl`` for the ICL layout. Otherwise an error lists the presets.

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

import json
import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from tqdm import tqdm

from sim_envs.camera import Intrinsics, camera_presets, preset
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
DEPTH_SCALE: float = 5000.0  # TUM RGB-D and ICL-NUIM: 16-bit PNG value 5000 = 1 m
ICL_FPS: float = 30.0
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
        raise SimEnvError(f"{folder} exists and is not empty; choose another folder or pass overwrite=True")
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
    has_labels = has_instances = False
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
    (folder / SIDE_FILE).write_text(json.dumps(side, indent=2) + "\n")
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
    K = intrinsics
    v, u = np.mgrid[0 : depth_a.shape[0] : stride, 0 : depth_a.shape[1] : stride]
    z = np.asarray(depth_a, dtype=np.float64)[v, u]
    ok = np.isfinite(z) & (z > 0)
    u, v, z = u[ok], v[ok], z[ok]
    points_a = np.stack([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z, np.ones_like(z)])
    points_b = (np.linalg.inv(T_world_b) @ T_world_a @ points_a)[:3]
    zb = points_b[2]
    front = zb > 1e-6
    ub = np.rint(K.fx * points_b[0, front] / zb[front] + K.cx).astype(np.int64)
    vb = np.rint(K.fy * points_b[1, front] / zb[front] + K.cy).astype(np.int64)
    zb = zb[front]
    inside = (ub >= 0) & (ub < depth_b.shape[1]) & (vb >= 0) & (vb < depth_b.shape[0])
    measured = np.asarray(depth_b, dtype=np.float64)[vb[inside], ub[inside]]
    valid = np.isfinite(measured) & (measured > 0)
    if not valid.any():
        return math.nan
    agree = np.abs(zb[inside][valid] - measured[valid]) < rel_tol * measured[valid]
    return float(agree.mean())


# ------------------------------------------------------------------------------------------------------------ load
class RgbdFolder:
    """A TUM RGB-D or ICL-NUIM (TUM-compatible) folder as a :class:`~sim_envs.source.FrameSource`.

    See the module docstring for layouts, intrinsics and the ICL pose convention. ``timestamps`` (N,) float64
    seconds; ``poses`` (N, 4, 4) float64 ``T_world_cam`` in the OpenCV camera convention. Frames are read from disk
    on each ``frame(i)`` call (nothing is cached).
    """

    def __init__(
        self,
        folder: str | Path,
        intrinsics: Intrinsics | str | None = None,
        *,
        pose_convention: PoseConvention | None = None,
        depth_scale: float | None = None,
        depth_is_ray_length: bool = False,
        max_difference: float = MAX_DIFFERENCE,
        name: str | None = None,
    ) -> None:
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise SimEnvError(f"{self.folder} is not a folder")
        self.name: str = name or self.folder.name
        side_path = self.folder / SIDE_FILE
        self.side: dict[str, Any] = _read_side_file(side_path) if side_path.exists() else {}
        self.layout = self._detect_layout()
        self.depth_scale = float(depth_scale or self.side.get("depth_scale", DEPTH_SCALE))
        self.depth_is_ray_length = bool(depth_is_ray_length)
        if self.layout == "tum":
            stamps, rgb_files, depth_files, raw_poses = self._index_tum(max_difference)
        else:
            stamps, rgb_files, depth_files, raw_poses = self._index_icl(max_difference)
        if not rgb_files:
            raise SimEnvError(f"{self.folder}: no RGB image has both a depth image and a ground-truth pose")
        self.timestamps: np.ndarray = stamps
        self._rgb_files = rgb_files
        self._depth_files = depth_files
        self.intrinsics: Intrinsics = self._resolve_intrinsics(intrinsics)
        self._raw_poses = raw_poses
        convention = pose_convention or ("auto" if self.layout == "icl" else "opencv")
        if convention not in POSE_CONVENTIONS:
            raise SimEnvError(f"pose_convention must be one of {POSE_CONVENTIONS}, got {convention!r}")
        self.pose_convention_scores: dict[str, float] = {}
        if convention == "auto":
            self.pose_convention_scores = self._score_conventions()
            convention = max(self.pose_convention_scores, key=lambda c: np.nan_to_num(self.pose_convention_scores[c]))
        self.pose_convention_used: str = convention
        self.poses: np.ndarray = convert_pose_convention(raw_poses, convention)
        self._labels = self._optional_folder("labels")
        self._instances = self._optional_folder("instances")

    # ---------------------------------------------------------------------------------------------- FrameSource
    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    def frame(self, index: int) -> Frame:
        """Load frame ``index``: RGB (H, W, 3) uint8, depth (H, W) float32 metres, pose, labels/instances if any."""
        i = self._check_index(index)
        rgb = cv2.cvtColor(_read_image(self._rgb_files[i], cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        depth = self.depth(i)
        if rgb.shape[:2] != depth.shape:
            raise SimEnvError(f"{self._rgb_files[i]}: RGB {rgb.shape[:2]} and depth {depth.shape} sizes differ")
        labels = instances = None
        if self._labels is not None:
            labels = _read_image(self._labels / self._rgb_files[i].name, cv2.IMREAD_UNCHANGED).astype(np.uint8)
        if self._instances is not None:
            raw = _read_image(self._instances / self._rgb_files[i].name, cv2.IMREAD_UNCHANGED)
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

    def depth(self, index: int) -> np.ndarray:
        """Depth of frame ``index`` alone: (H, W) float32 planar z metres, 0 = none."""
        i = self._check_index(index)
        raw = _read_image(self._depth_files[i], cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2:
            raise SimEnvError(f"{self._depth_files[i]}: a depth image must have one channel, got shape {raw.shape}")
        depth = raw.astype(np.float32) / np.float32(self.depth_scale)
        if self.depth_is_ray_length:
            depth = ray_length_to_z(depth, self.intrinsics)
        return depth

    def close(self) -> None:
        """Nothing is held open."""

    def __repr__(self) -> str:
        return f"RgbdFolder({str(self.folder)!r}, layout={self.layout!r}, frames={len(self)})"

    # -------------------------------------------------------------------------------------------------- helpers
    def _check_index(self, index: int) -> int:
        i = int(index)
        if not 0 <= i < len(self):
            raise SimEnvError(f"frame index {index} out of range 0..{len(self) - 1} of {self.folder}")
        return i

    def _detect_layout(self) -> str:
        if (self.folder / "rgb.txt").exists():
            return "tum"
        if (self.folder / "associations.txt").exists():
            return "icl"
        raise SimEnvError(
            f"{self.folder} is neither a TUM RGB-D folder (rgb.txt, depth.txt, groundtruth.txt) nor an ICL-NUIM "
            "TUM-compatible folder (associations.txt and a *.gt.freiburg trajectory)"
        )

    def _ground_truth_file(self) -> Path:
        for candidate in [self.folder / "groundtruth.txt", *sorted(self.folder.glob("*.gt.freiburg"))]:
            if candidate.exists():
                return candidate
        raise SimEnvError(f"{self.folder}: no ground truth (groundtruth.txt or *.gt.freiburg)")

    def _index_tum(self, max_difference: float):
        rgb_t, rgb_names = read_tum_image_list(self.folder / "rgb.txt")
        depth_path = self.folder / "depth.txt"
        if not depth_path.exists():
            raise SimEnvError(f"{self.folder}: rgb.txt but no depth.txt")
        depth_t, depth_names = read_tum_image_list(depth_path)
        gt_t, gt_T = read_tum_trajectory(self._ground_truth_file(), duplicate_timestamps="last")
        ri, di = associate_greedy(rgb_t, depth_t, max_difference)
        rj, gj = associate_greedy(rgb_t[ri], gt_t, max_difference)
        keep_rgb, keep_depth = ri[rj], di[rj]
        return (
            rgb_t[keep_rgb].copy(),
            [self.folder / rgb_names[k] for k in keep_rgb],
            [self.folder / depth_names[k] for k in keep_depth],
            gt_T[gj],
        )

    def _index_icl(self, max_difference: float):
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
        return (
            index[ai] / ICL_FPS,
            [self.folder / rows[k][1] for k in ai],
            [self.folder / rows[k][2] for k in ai],
            gt_T[gi],
        )

    def _image_size(self) -> tuple[int, int]:
        image = _read_image(self._rgb_files[0], cv2.IMREAD_UNCHANGED)
        return image.shape[1], image.shape[0]

    def _resolve_intrinsics(self, intrinsics: Intrinsics | str | None) -> Intrinsics:
        width, height = self._image_size()
        if isinstance(intrinsics, Intrinsics):
            chosen = intrinsics
        elif isinstance(intrinsics, str):
            chosen = preset(intrinsics, width, height)
        elif self.side.get("intrinsics"):
            k = self.side["intrinsics"]
            try:
                chosen = Intrinsics(
                    float(k["fx"]), float(k["fy"]), float(k["cx"]), float(k["cy"]), int(k["width"]), int(k["height"])
                )
            except (KeyError, TypeError, ValueError) as exc:
                raise FormatError(f"{self.folder / SIDE_FILE}: bad 'intrinsics' entry ({exc})") from exc
        else:
            guess = _preset_from_name(self.folder.name) or ("icl" if self.layout == "icl" else None)
            if guess is None:
                raise UnknownNameError(
                    f"{self.folder}: cannot tell the camera; pass intrinsics= an Intrinsics or a preset name "
                    f"({', '.join(camera_presets())}), or add a {SIDE_FILE}"
                )
            chosen = preset(guess, width, height)
        if (chosen.width, chosen.height) != (width, height):
            raise SimEnvError(
                f"{self.folder}: intrinsics for {chosen.width}x{chosen.height} but the images are {width}x{height}; "
                "use Intrinsics.scaled() or a preset name (scaled automatically)"
            )
        return chosen

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


def load_tum_rgbd_folder(folder: str | Path, intrinsics: Intrinsics | str | None = None, **kwargs: Any) -> RgbdFolder:
    """Load a TUM RGB-D (or ICL-NUIM TUM-compatible) folder as a frame source; see :class:`RgbdFolder`."""
    return RgbdFolder(folder, intrinsics, **kwargs)


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
    "RgbdFolder",
    "convert_pose_convention",
    "depth_consistency",
    "export_tum_rgbd",
    "load_tum_rgbd_folder",
    "ray_length_to_z",
)
