"""RGB-D folder layouts: detect a folder's layout and index its frames (timestamp, RGB file, depth file, pose).

A layout is one registered :class:`FolderLayout` (its ``name``, ``description``, ``detect(folder) -> bool`` and
``index(folder, max_difference) -> FolderIndex``): a new layout is one subclass here plus :func:`register_layout`.
:func:`detect_layout` names the layout of a folder (the first registered layout, by ``priority``, that detects it; a
key of :data:`LAYOUTS`); :func:`index_folder` lists the frames that have what they need, associating RGB images,
depth images and poses by time (or frame number). The file formats they read are :mod:`slamcommon.formats` (through
:mod:`sim_envs.folders.formats`, which raises the world's errors). The layouts registered here:

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
  depth. Frames have an all-zero depth map (0 = no measurement, :attr:`sim_envs.folders.datasets.RgbdFolder.has_depth`
  False), so no depth metric can be computed (the benchmark runner skips it).

Also here: each layout's depth scale and frame rate, the side file ``cnnslam.json`` (:data:`SIDE_FILE`) that
:func:`sim_envs.folders.folder_exports.export_tum_rgbd` writes and :func:`_read_side_file` reads, and
:func:`folder_fingerprint`, a content fingerprint of a folder that is cheap to compute (for run records). Reading
the frames themselves: :class:`sim_envs.folders.datasets.RgbdFolder`.
"""

from __future__ import annotations

import hashlib
import json
import os
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np

from sim_envs.errors import FormatError, SimEnvError, UnknownNameError
from sim_envs.folders.formats import (
    associate_greedy,
    read_icl_associations,
    read_pose_matrix,
    read_tum_image_list,
    read_tum_trajectory,
    world_errors,
)
from slamcommon.formats.icl import ICL_FPS
from slamcommon.formats.seven_scenes import (  # noqa: F401 (POSE_ROTATION_TOL, SEVEN_SCENES_INVALID_DEPTH: re-exported)
    POSE_ROTATION_TOL,
    SEVEN_SCENES_COLOUR,
    SEVEN_SCENES_DEPTH_SCALE,
    SEVEN_SCENES_FPS,
    SEVEN_SCENES_INVALID_DEPTH,
)

SIDE_FILE = "cnnslam.json"
SIDE_FORMAT = "cnnslam-tum-rgbd/1"
DEPTH_SCALE: float = 5000.0  # TUM RGB-D and ICL-NUIM: 16-bit PNG value 5000 = 1 m
Layout = Literal["tum", "icl", "7scenes", "7scenes_split", "rgb_only"]  # the built-in layouts' names
_LAYOUT_DEPTH_SCALE: dict[str, float] = {"7scenes": SEVEN_SCENES_DEPTH_SCALE, "7scenes_split": SEVEN_SCENES_DEPTH_SCALE}
_SEVEN_SCENES_COLOUR = SEVEN_SCENES_COLOUR
MAX_DIFFERENCE: float = 0.02  # seconds, the TUM tools' default association tolerance


@dataclass(frozen=True)
class FolderIndex:
    """What a layout's files say: per kept frame its timestamp (s), RGB file, depth file (None: no depth), pose."""

    timestamps: np.ndarray  # (N,) float64 seconds, increasing
    rgb_files: list[Path]  # N
    depth_files: list[Path] | None  # N, or None for a layout without depth
    poses: np.ndarray  # (N, 4, 4) float64 T_world_cam (ground truth)
    dropped: int  # frames listed but not kept (no depth or no pose)
    timing: str  # where the timestamps come from


_Index = FolderIndex  # the name it had


# ------------------------------------------------------------------------------------------------------- registry
class FolderLayout(ABC):
    """One layout of an RGB-D folder on disk. Subclasses set ``name`` (a key of :data:`LAYOUTS`), ``description``
    (one line: the files that make it), ``priority`` (detection order, lower first: a layout whose files another
    layout's folder may also hold goes first) and implement :meth:`detect` and :meth:`index`."""

    name: ClassVar[str]
    description: ClassVar[str]
    priority: ClassVar[int] = 100

    @abstractmethod
    def detect(self, folder: Path) -> bool:
        """Whether ``folder`` (an existing folder) has this layout's files."""

    @abstractmethod
    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        """The frames of ``folder`` that have an RGB image, a depth image (unless the layout has none) and a pose;
        ``max_difference``: seconds, the tolerance of an association by time or frame index. Bad files raise a
        ``FormatError`` naming the file and line."""


_REGISTRY: dict[str, FolderLayout] = {}


def register_layout(layout: FolderLayout | type[FolderLayout]) -> Any:
    """Register a layout (an instance, or a class, then instantiated; usable as a class decorator) under its
    ``name``; returns its argument. :class:`SimEnvError` when the name is taken."""
    instance = layout() if isinstance(layout, type) else layout
    if instance.name in _REGISTRY:
        raise SimEnvError(f"layout {instance.name!r} is registered already; taken names: {', '.join(_REGISTRY)}")
    _REGISTRY[instance.name] = instance
    return layout


def unregister_layout(name: str) -> FolderLayout:
    """Remove the layout ``name`` from the registry (for tests that register their own); returns it."""
    folder_layout(name)
    return _REGISTRY.pop(name)


def folder_layout(name: str) -> FolderLayout:
    """The registered layout ``name``; :class:`UnknownNameError` listing the registered names."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise UnknownNameError(f"unknown layout {name!r}; valid layouts: {', '.join(_REGISTRY)}") from None


class _Descriptions(Mapping[str, str]):
    """{layout name: description} of the registered layouts, in registration order (a live view)."""

    def __getitem__(self, name: str) -> str:
        return _REGISTRY[name].description

    def __iter__(self) -> Iterator[str]:
        return iter(list(_REGISTRY))

    def __len__(self) -> int:
        return len(_REGISTRY)

    def __repr__(self) -> str:
        return repr(dict(self))


LAYOUTS: Mapping[str, str] = _Descriptions()


def detect_layout(folder: str | Path) -> str:
    """The layout of an RGB-D folder, a key of :data:`LAYOUTS`: the first registered layout, by ``priority`` (then
    registration order), whose ``detect`` accepts it; :class:`SimEnvError` (one line, listing the layouts) when none
    does. 7-Scenes file names win over TUM index files beside them."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SimEnvError(f"{folder} is not a folder")
    for layout in sorted(_REGISTRY.values(), key=lambda layout: layout.priority):
        if layout.detect(folder):
            return layout.name
    raise SimEnvError(
        f"{folder}: not an RGB-D folder of a known layout; expected one of: {'; '.join(LAYOUTS.values())}"
    )


def index_folder(folder: str | Path, layout: str, max_difference: float = MAX_DIFFERENCE) -> FolderIndex:
    """The frames of ``folder`` in ``layout`` (a key of :data:`LAYOUTS`, as :func:`detect_layout` names it) that have
    an RGB image, a depth image (unless the layout has none) and a pose; ``max_difference``: seconds, the tolerance of
    the association by time (TUM, RGB-only) or by frame index (ICL-NUIM). A shared format error comes out as the
    world's :class:`FormatError`."""
    return world_errors(folder_layout(layout).index)(Path(folder), max_difference)


# ----------------------------------------------------------------------------------------------- built-in layouts
def _ground_truth_file(folder: Path) -> Path:
    for candidate in [folder / "groundtruth.txt", *sorted(folder.glob("*.gt.freiburg"))]:
        if candidate.exists():
            return candidate
    raise SimEnvError(f"{folder}: no ground truth (groundtruth.txt or *.gt.freiburg)")


@register_layout
class TumLayout(FolderLayout):
    """TUM RGB-D: RGB images associated with depth images, then with ground-truth poses, by time."""

    name = "tum"
    description = "TUM RGB-D (rgb.txt, depth.txt, groundtruth.txt)"
    priority = 30

    def detect(self, folder: Path) -> bool:
        return (folder / "rgb.txt").is_file() and (folder / "depth.txt").is_file()

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        rgb_t, rgb_names = read_tum_image_list(folder / "rgb.txt")
        depth_t, depth_names = read_tum_image_list(folder / "depth.txt")
        gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
        ri, di = associate_greedy(rgb_t, depth_t, max_difference)
        rj, gj = associate_greedy(rgb_t[ri], gt_t, max_difference)
        keep_rgb, keep_depth = ri[rj], di[rj]
        return FolderIndex(
            rgb_t[keep_rgb].copy(),
            [folder / rgb_names[k] for k in keep_rgb],
            [folder / depth_names[k] for k in keep_depth],
            gt_T[gj],
            len(rgb_t) - len(keep_rgb),
            "rgb.txt",
        )


@register_layout
class IclLayout(FolderLayout):
    """ICL-NUIM TUM-compatible: frame indices matched with the trajectory's stamps (the same indices)."""

    name = "icl"
    description = "ICL-NUIM TUM-compatible (associations.txt, *.gt.freiburg)"
    priority = 40

    def detect(self, folder: Path) -> bool:
        return (folder / "associations.txt").is_file()

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        index, rgb_names, depth_names = read_icl_associations(folder / "associations.txt")
        gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
        ai, gi = associate_greedy(index, gt_t, max_difference)
        return FolderIndex(
            index[ai] / ICL_FPS,
            [folder / rgb_names[k] for k in ai],
            [folder / depth_names[k] for k in ai],
            gt_T[gi],
            len(index) - len(ai),
            f"frame index / {ICL_FPS:g} s",
        )


@register_layout
class SevenScenesLayout(FolderLayout):
    """7-Scenes as it ships: colour, depth and pose files of each frame in one folder."""

    name = "7scenes"
    description = "7-Scenes (frame-XXXXXX.color.png|jpg, .depth.png in mm, .pose.txt in one folder)"
    priority = 10

    def detect(self, folder: Path) -> bool:
        return _has_seven_scenes_colour(folder)

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        return _index_seven_scenes(folder, folder, folder)


@register_layout
class SevenScenesSplitLayout(FolderLayout):
    """7-Scenes files split into ``rgb/``, ``depth/`` and ``poses/``."""

    name = "7scenes_split"
    description = "7-Scenes split (rgb/, depth/, poses/ holding the 7-Scenes files)"
    priority = 20

    def detect(self, folder: Path) -> bool:
        return (folder / "poses").is_dir() and _has_seven_scenes_colour(folder / "rgb")

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        return _index_seven_scenes(folder / "rgb", folder / "depth", folder / "poses")


@register_layout
class RgbOnlyLayout(FolderLayout):
    """TUM files without depth: RGB images associated with ground-truth poses by time; no depth files."""

    name = "rgb_only"
    description = "RGB only (rgb.txt, groundtruth.txt, no depth.txt)"
    priority = 30

    def detect(self, folder: Path) -> bool:
        return (folder / "rgb.txt").is_file() and not (folder / "depth.txt").is_file()

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        rgb_t, rgb_names = read_tum_image_list(folder / "rgb.txt")
        gt_t, gt_T = read_tum_trajectory(_ground_truth_file(folder), duplicate_timestamps="last")
        ri, gi = associate_greedy(rgb_t, gt_t, max_difference)
        return FolderIndex(
            rgb_t[ri].copy(), [folder / rgb_names[k] for k in ri], None, gt_T[gi], len(rgb_t) - len(ri), "rgb.txt"
        )


def _index_seven_scenes(colour_dir: Path, depth_dir: Path, pose_dir: Path) -> FolderIndex:
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
    return FolderIndex(
        np.asarray(stamps, dtype=np.float64),
        rgb_files,
        depth_files,
        np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4),
        dropped,
        f"frame number / {SEVEN_SCENES_FPS:g} s",
    )


def _has_seven_scenes_colour(folder: Path) -> bool:
    return folder.is_dir() and any(_SEVEN_SCENES_COLOUR.match(p.name) for p in folder.glob("frame-*.color.*"))


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
