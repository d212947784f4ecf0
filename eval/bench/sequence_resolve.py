"""A sequence by name (:func:`resolve_sequence`): the text form of :mod:`eval.bench.sequence_ref` parsed back to a
:class:`~eval.bench.sequence_ref.SequenceRef` (a registered or rotation stress sequence, variant marks, a camera
preset, a folder path), and the local dataset list (``datasets.toml``, or the file ``$CNNSLAM_DATASETS`` names) that
names the real RGB-D folders this machine has (:func:`load_dataset_list`), each with its optional camera, size,
depth scale and second reference trajectory, checked before any run.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from eval.bench.sequence_ref import (
    ROTATION_NAME,
    SAFE_NAME,
    FolderSize,
    SequenceRef,
    folder_ref,
    folder_size,
    rotation_ref,
    sim_camera_presets,
)
from eval.errors import SuiteError
from sim_envs.camera import camera_presets
from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import PROCESSING_SIZE
from sim_envs.folders.formats import read_tum_trajectory
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
from sim_envs.sequences import list_sequences, split_variants

DATASETS_ENV = "CNNSLAM_DATASETS"  # a user's list of local dataset folders, instead of the repository's
DEFAULT_DATASETS_FILE = Path(__file__).resolve().parents[2] / "datasets.toml"


def resolve_sequence(name: str, *, check_references: bool = True) -> SequenceRef:
    """A sequence by name: a registered sequence; ``rot_<axes>_<speed>`` (axes yaw, pitch, roll joined by ``-``, or
    ``rpy``; speed in deg/s) for any rotation stress sequence; the path of an RGB-D folder (:func:`folder_ref`) when
    it has a ``/`` or starts with ``.`` or ``~``; a name of the dataset list (:func:`load_dataset_list`); an existing
    folder. The first that fits wins. A simulated sequence's name may end in ``@<camera preset>``
    (``office0@clean``): that sequence seen through that camera (:meth:`SequenceRef.with_camera_effects`); without
    one it is the renderer's image (``clean``). A simulated name may end in ``+lit`` before that (``office0+lit@hard``):
    the same room and trajectory with lamps, shadows and highlights (:meth:`SequenceRef.with_lighting`), and in
    ``+rich`` (``office0+rich``, ``office0+lit+rich@kinect``): the same room with clutter and texture detail
    (:meth:`SequenceRef.with_detail`); the marks may come in either order, the name is made ``+lit+rich``.
    ``check_references``: see :func:`load_dataset_list` (False: for the command that makes a missing reference)."""
    plain, sep, preset = name.rpartition("@")
    if sep and preset in sim_camera_presets() and plain:
        ref = resolve_sequence(plain)
        if ref.folder is None:
            return ref.with_camera_effects(preset)
    try:
        plain, marks = split_variants(name)
    except SimEnvError as exc:
        raise SuiteError(f"sequence {exc}") from None
    if marks:
        ref = resolve_sequence(plain)
        if ref.folder is None:
            return ref.with_lighting(marks.get("lighting", "flat")).with_detail(marks.get("detail", "standard"))
    if name in list_sequences():
        return SequenceRef(name, base=name)
    match = ROTATION_NAME.match(name)
    if match:
        axes = match["axes"]
        try:
            return rotation_ref(axes if axes == "rpy" else axes.replace("-", "+"), float(match["speed"]))
        except SimEnvError as exc:  # e.g. rot_yawn_30: a rotation name with a bad axis
            raise SuiteError(f"sequence {name!r}: {exc}") from None
    if "/" in name or os.sep in name or name.startswith((".", "~")):
        return folder_ref(name)
    datasets = load_dataset_list(check_references=check_references)
    if name in datasets:
        entry = datasets[name]
        if not entry.path.is_dir():
            raise SuiteError(f"dataset {name!r} of {dataset_list_file()}: {entry.path} is not a folder")
        return entry.ref()
    if Path(name).is_dir():
        return folder_ref(name)
    listed = f"; datasets of {dataset_list_file()}: {', '.join(datasets)}" if datasets else ""
    raise SuiteError(
        f"unknown sequence {name!r}; valid: {', '.join(list_sequences('test'))}, or rot_<axes>_<deg/s> "
        f"(e.g. rot_yaw_45, rot_yaw-pitch_20, rot_rpy_90){listed}, or the path of an RGB-D folder"
    )


def with_default_camera(name: str) -> SequenceRef:
    """:func:`resolve_sequence`, a simulated sequence named without a camera preset seen through the default camera
    (what the suites run: ``office0`` is ``office0@kinect``)."""
    ref = resolve_sequence(name)
    named_camera = name.rpartition("@")[2] in sim_camera_presets()
    if ref.folder is not None or named_camera or "camera_effects" in dict(ref.overrides):
        return ref
    return ref.with_camera_effects(DEFAULT_CAMERA_EFFECTS)


# ------------------------------------------------------------------------------------------- local dataset list
@dataclass(frozen=True)
class DatasetEntry:
    """A folder of the dataset list: ``name`` (its sequence name), ``path`` (absolute), and the optional
    ``camera`` (preset name or absolute camera file path), ``size`` and ``depth_scale`` of :class:`SequenceRef`;
    ``reference``: the absolute path of a second reference trajectory (TUM format, e.g. ``cnnslam reference``'s
    SfM one) that reports score the runs against too. It is a scoring input, not a run input: changing it reruns
    nothing."""

    name: str
    path: Path
    camera: str | None = None
    size: FolderSize = PROCESSING_SIZE
    depth_scale: float | None = None
    reference: Path | None = None

    def ref(self) -> SequenceRef:
        return SequenceRef(
            self.name, folder=str(self.path), camera=self.camera, size=self.size, depth_scale=self.depth_scale
        )


def dataset_list_file() -> Path:
    """The dataset list in use: the file named by ``$CNNSLAM_DATASETS``, else the repository's ``datasets.toml``."""
    named = os.environ.get(DATASETS_ENV)
    return Path(named).expanduser() if named else DEFAULT_DATASETS_FILE


def load_dataset_list(path: str | Path | None = None, *, check_references: bool = True) -> dict[str, DatasetEntry]:
    """The named local dataset folders of a TOML list (default :func:`dataset_list_file`), in file order.

    Format: a ``[datasets]`` table whose entries are ``name = "path"`` or ``[datasets.<name>]`` tables with
    ``path`` and optionally ``camera`` (preset name or camera file), ``size`` (``[width, height]`` or
    ``"native"``), ``depth_scale`` and ``reference`` (a second reference trajectory, TUM format: read here, so
    that a missing or malformed one is refused before any run; ``check_references=False`` leaves a missing one to
    be made, by ``cnnslam reference``, and still refuses one that is there but malformed). Relative paths are
    relative to the list file's
    folder; ``~`` is expanded. A missing default list is an empty list; a missing list named by
    ``$CNNSLAM_DATASETS`` is an error. Every error is one :class:`SuiteError` line naming the list file (and the
    entry).
    """
    explicit = path is not None or bool(os.environ.get(DATASETS_ENV))
    file = Path(path) if path is not None else dataset_list_file()
    if not file.is_file():
        if explicit:
            raise SuiteError(f"no dataset list at {file} (${DATASETS_ENV} or the given path)")
        return {}
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise SuiteError(f"{file}: not a readable TOML dataset list ({exc})") from None
    except UnicodeDecodeError as exc:
        raise SuiteError(f"{file}: not a text file (UTF-8 decoding failed at byte {exc.start})") from None
    table = data.get("datasets", {})
    if not isinstance(table, dict) or set(data) - {"datasets"}:
        raise SuiteError(f"{file}: expected only a [datasets] table (name = \"path\" or [datasets.<name>])")
    base = file.resolve().parent
    return {name: _dataset_entry(file, base, name, value, check_references) for name, value in table.items()}


def _dataset_entry(file: Path, base: Path, name: str, value: Any, check_references: bool = True) -> DatasetEntry:
    """One entry of the dataset list ``file`` (relative paths from ``base``); :class:`SuiteError` naming both.
    ``check_references``: a reference that is not there is an error (else only one that is there and malformed)."""
    entry = value if isinstance(value, dict) else {"path": value}
    unknown = sorted(set(entry) - {"path", "camera", "size", "depth_scale", "reference"})
    if unknown or not isinstance(entry.get("path"), str) or not entry["path"]:
        raise SuiteError(
            f"{file}: dataset {name!r} needs path = \"FOLDER\" (optional: camera, size, depth_scale, reference)"
            + (f"; unknown key(s) {', '.join(map(repr, unknown))}" if unknown else "")
        )
    if SAFE_NAME.search(name) or not name or name.startswith(".") or name in list_sequences("all"):
        raise SuiteError(f"{file}: dataset name {name!r} must use letters, digits, _.+- and not be a sequence's")
    for key in ("camera", "reference"):
        if key in entry and not (isinstance(entry[key], str) and entry[key]):
            raise SuiteError(f"{file}: dataset {name!r}: {key} = {entry[key]!r}; it must be a non-empty string "
                             f"({'a preset name or a camera file' if key == 'camera' else 'a TUM trajectory file'})")
    depth_scale = entry.get("depth_scale")
    if depth_scale is not None and (isinstance(depth_scale, bool) or not isinstance(depth_scale, int | float)
                                    or not (math.isfinite(depth_scale) and depth_scale > 0)):  # fmt: skip
        raise SuiteError(f"{file}: dataset {name!r}: depth_scale = {depth_scale!r}; it must be a positive number "
                         "(16-bit PNG value per metre)")  # fmt: skip
    try:
        size = folder_size(entry.get("size", PROCESSING_SIZE))
        folder = _resolve_path(base, entry["path"])
        camera = entry.get("camera")
        if camera is not None and camera not in camera_presets():
            camera = str(_resolve_path(base, camera))  # checked when the folder is loaded
        reference = _resolve_path(base, entry["reference"]) if "reference" in entry else None
    except SuiteError as exc:
        raise SuiteError(f"{file}: dataset {name!r}: {exc}") from None
    if reference is not None and (check_references or reference.exists()):
        _check_reference(file, name, reference)
    return DatasetEntry(name, folder, camera, size, None if depth_scale is None else float(depth_scale), reference)


def _resolve_path(base: Path, text: str) -> Path:
    """``text`` (``~`` expanded) relative to ``base``, absolute; :class:`SuiteError` when it cannot be."""
    try:
        return (base / Path(text).expanduser()).resolve()
    except (RuntimeError, OSError, ValueError) as exc:  # ~user of no user, a NUL, a loop of links
        raise SuiteError(f"path {text!r} cannot be resolved ({exc})") from None


def _check_reference(file: Path, name: str, reference: Path) -> None:
    """A dataset's second reference must be a readable TUM trajectory (scored against every run of the folder)."""
    try:
        stat = reference.stat()
    except OSError:
        stat = None
    if stat is None or not reference.is_file():
        raise SuiteError(f"{file}: dataset {name!r}: reference {reference} is not a file; make it (a TUM "
                         f"trajectory: `cnnslam reference {name} --out DIR` writes DIR/reference.tum) or remove the "
                         "entry's reference")  # fmt: skip
    problem = _trajectory_problem(str(reference), stat.st_size, stat.st_mtime_ns)
    if problem:
        raise SuiteError(f"{file}: dataset {name!r}: the reference is not a TUM trajectory: {problem}")


@lru_cache(maxsize=64)
def _trajectory_problem(path: str, size: int, mtime_ns: int) -> str | None:
    """Why the TUM trajectory file ``path`` (as it is at ``size``, ``mtime_ns``: the cache's key) cannot be read, or
    None when it can (a dataset list is read whenever a name is resolved; its references once per version)."""
    from sim_envs.errors import FormatError

    try:
        read_tum_trajectory(path)  # as the reports read it
    except FormatError as exc:
        return str(exc)
    return None
