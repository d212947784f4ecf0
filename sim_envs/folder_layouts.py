"""RGB-D folder layouts: detect a folder's layout and index its frames (timestamp, RGB file, depth file, pose).

:func:`detect_layout` names the layout (a key of :data:`LAYOUTS`); :func:`index_folder` lists the frames that have
what they need, associating RGB images, depth images and poses by time (or frame number):

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
  depth. Frames have an all-zero depth map (0 = no measurement, :attr:`sim_envs.datasets.RgbdFolder.has_depth`
  False), so no depth metric can be computed (the benchmark runner skips it).

Also here: each layout's depth scale and frame rate, the side file ``cnnslam.json`` (:data:`SIDE_FILE`) that
:func:`sim_envs.folder_exports.export_tum_rgbd` writes and :func:`_read_side_file` reads, and
:func:`folder_fingerprint`, a content fingerprint of a folder that is cheap to compute (for run records). Reading
the frames themselves: :class:`sim_envs.datasets.RgbdFolder`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from sim_envs.errors import FormatError, SimEnvError
from sim_envs.formats import _data_lines, associate_greedy, read_tum_image_list, read_tum_trajectory

SIDE_FILE = "cnnslam.json"
SIDE_FORMAT = "cnnslam-tum-rgbd/1"
DEPTH_SCALE: float = 5000.0  # TUM RGB-D and ICL-NUIM: 16-bit PNG value 5000 = 1 m
SEVEN_SCENES_DEPTH_SCALE: float = 1000.0  # 7-Scenes: millimetres
SEVEN_SCENES_INVALID_DEPTH = 65535  # 7-Scenes marks no measurement by 0 and by 65535
ICL_FPS: float = 30.0
SEVEN_SCENES_FPS: float = 30.0  # 7-Scenes has no timestamps; the Kinect's nominal rate
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
POSE_ROTATION_TOL: float = 1e-2  # max |R - nearest rotation| of a 7-Scenes pose (ours: its matrices are within 4e-4)


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


def index_folder(folder: str | Path, layout: str, max_difference: float = MAX_DIFFERENCE) -> _Index:
    """The frames of ``folder`` in ``layout`` (a key of :data:`LAYOUTS`, as :func:`detect_layout` names it) that have
    an RGB image, a depth image (unless the layout has none) and a pose; ``max_difference``: seconds, the tolerance of
    the association by time (TUM, RGB-only) or by frame index (ICL-NUIM)."""
    folder = Path(folder)
    if layout == "tum":
        return _index_tum(folder, max_difference)
    if layout == "icl":
        return _index_icl(folder, max_difference)
    if layout == "rgb_only":
        return _index_rgb_only(folder, max_difference)
    if layout == "7scenes":
        return _index_seven_scenes(folder, folder, folder)
    return _index_seven_scenes(folder / "rgb", folder / "depth", folder / "poses")


def _ground_truth_file(folder: Path) -> Path:
    for candidate in [folder / "groundtruth.txt", *sorted(folder.glob("*.gt.freiburg"))]:
        if candidate.exists():
            return candidate
    raise SimEnvError(f"{folder}: no ground truth (groundtruth.txt or *.gt.freiburg)")


def _index_tum(folder: Path, max_difference: float) -> _Index:
    rgb_t, rgb_names = read_tum_image_list(folder / "rgb.txt")
    depth_t, depth_names = read_tum_image_list(folder / "depth.txt")
    gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
    ri, di = associate_greedy(rgb_t, depth_t, max_difference)
    rj, gj = associate_greedy(rgb_t[ri], gt_t, max_difference)
    keep_rgb, keep_depth = ri[rj], di[rj]
    return _Index(
        rgb_t[keep_rgb].copy(),
        [folder / rgb_names[k] for k in keep_rgb],
        [folder / depth_names[k] for k in keep_depth],
        gt_T[gj],
        len(rgb_t) - len(keep_rgb),
        "rgb.txt",
    )


def _index_rgb_only(folder: Path, max_difference: float) -> _Index:
    rgb_t, rgb_names = read_tum_image_list(folder / "rgb.txt")
    gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
    ri, gi = associate_greedy(rgb_t, gt_t, max_difference)
    return _Index(
        rgb_t[ri].copy(), [folder / rgb_names[k] for k in ri], None, gt_T[gi], len(rgb_t) - len(ri), "rgb.txt"
    )


def _index_icl(folder: Path, max_difference: float) -> _Index:
    path = folder / "associations.txt"
    rows = []
    layout = "index depth/N.png index rgb/N.png"
    for number, fields in _data_lines(path):
        if len(fields) != 4:
            raise FormatError(
                f"{path}:{number}: expected 4 columns ({layout}), found {len(fields)}: {' '.join(fields)!r}"
            )
        for column in (1, 3):
            try:
                value = float(fields[column - 1])
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise FormatError(f"{path}:{number}: column {column} is {fields[column - 1]!r}, not a frame index "
                                  f"(a finite number); valid lines are '{layout}'")  # fmt: skip
        rows.append((float(fields[2]), fields[3], fields[1]))
    if not rows:
        raise FormatError(f"{path}: no entries; expected lines '{layout}'")
    rows.sort()
    index = np.array([r[0] for r in rows])
    gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
    ai, gi = associate_greedy(index, gt_t, max_difference)
    return _Index(
        index[ai] / ICL_FPS,
        [folder / rows[k][1] for k in ai],
        [folder / rows[k][2] for k in ai],
        gt_T[gi],
        len(rows) - len(ai),
        f"frame index / {ICL_FPS:g} s",
    )


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


def read_pose_matrix(path: str | Path) -> np.ndarray:
    """A 7-Scenes ``frame-XXXXXX.pose.txt`` (4 rows of 4 numbers, camera-to-world, metres) -> (4, 4) float64
    ``T_world_cam``, the rotation block replaced by the nearest rotation (SVD, U V^T): 7-Scenes' KinectFusion
    matrices are orthonormal only to about 4e-4. A matrix with a non-finite entry (no pose) comes back all NaN.
    :class:`FormatError` (one line naming the file) for anything else that is not a pose: not 4 rows of 4 numbers,
    a last row other than 0 0 0 1, a reflection, a block farther than :data:`POSE_ROTATION_TOL` from a rotation."""
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
    deviation = float(np.abs(M[:3, :3] - R).max())
    if deviation > POSE_ROTATION_TOL:
        raise FormatError(f"{path}: the 3x3 block is {deviation:.3g} away from the nearest rotation; a pose needs a "
                          f"rotation (orthonormal to within {POSE_ROTATION_TOL:g}, det +1)")  # fmt: skip
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = M[:3, 3]
    return T


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


def _read_side_file(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise FormatError(f"{path}: not a readable JSON side file: {exc}") from exc
    if not isinstance(data, dict):
        raise FormatError(f"{path}: the side file must hold a JSON object")
    return data
