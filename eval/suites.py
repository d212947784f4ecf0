"""The benchmark suites: which sequences, which methods, how many frames, and how each sequence's environment is made.

A suite names its environments the way a user would: a registered sequence by its Gymnasium id
(``sim_envs/<name>-v0``), anything else (a rotation stress sequence at another speed, a variant of the sweep) as a
:class:`~sim_envs.simsource.SimulatedSequence` replayed by ``sim_envs/Replay-v0``. Methods are names of the method
table (:mod:`eval.methods`).

Suites (:data:`SUITES`):

- ``table1``: the nine Table-1 analogue sequences x the paper's methods and the oracle (CNN-SLAM Table 1);
- ``rotation``: pure-rotation stress sequences (yaw, pitch, roll, all three) at 15, 30 and 60 deg/s: tracked share,
  rotation error, percentage of correct depth (the paper's Sec. 4.2, made quantitative);
- ``ablation``: raw CNN depth vs focal-adjusted vs adjusted and refined (the paper's Fig. 3);
- ``sweep``: one difficulty axis at a time on one hand-held sequence: texture density, share of rotation in the
  motion, focal-length mismatch between the network's training camera and the test camera;
- ``depth_quality``: the six office and living sequences at full length: CNN-SLAM with the network against the raw
  CNN (the issue's targets: ATE / path length, scale error, correct depth), and CNN-SLAM on development depth of
  three known accuracies (ground truth degraded like a CNN's) in the network's place: how accurate key-frame depth
  must be for those targets;
- ``perf``: throughput figures (:mod:`eval.perf`), no agent runs;
- ``real``: every folder of the local dataset list x the paper's methods and the oracle, whole sequences;
- ``transfer``: the paper's methods on the simulated Table-1 analogues (per camera preset) and on the real folders,
  and whether the simulated rankings predict the real ones (:func:`transfer_parts`, :mod:`eval.transfer`);
- ``quick``: a few short sequences x all methods, the CI regression baseline.

Sweep variants (:func:`sweep_sequences`), built with :func:`dataclasses.replace` on the base sequence's spec where
the spec has the parameter, and by :class:`VariantSequence` where it has not:

- texture density: ``SequenceSpec.texture_density`` (the room generator's share of textured surfaces);
- rotation share: the base trajectory with an extra pan (rotation about the camera's y axis) sweeping +-20 deg at a
  set angular speed; the x value is the measured share of the image motion due to rotation
  (:func:`rotation_share`);
- focal mismatch: the test camera's focal lengths set to ``ratio x`` the training camera's
  (:data:`sim_envs.sequences.TRAIN_CAMERA`, NYU) at the same resolution, principal point kept
  (:meth:`sim_envs.camera.Intrinsics.with_focal`); the field of view changes, the images are rendered with it.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import numpy as np
from scipy.spatial.transform import Rotation

from eval.errors import EvalError
from sim_envs.camera import UNDISTORT_MODES, camera_presets, preset
from sim_envs.camera_effects import DEFAULT_CAMERA_EFFECTS
from sim_envs.datasets import (
    LOADER_VERSION,
    PROCESSING_SIZE,
    RgbdFolder,
    check_size,
    detect_layout,
    folder_fingerprint,
)
from sim_envs.errors import SimEnvError
from sim_envs.formats import read_tum_trajectory
from sim_envs.frame_cache import CachedFrames, cache_key
from sim_envs.scene import DETAILS, LIGHTINGS
from sim_envs.sequences import (
    TABLE1_SEQUENCES,
    TRAIN_CAMERA,
    SequenceSpec,
    get_sequence,
    gym_id,
    list_sequences,
    rotation_stress_spec,
    split_variant,
)
from sim_envs.simsource import SimulatedSequence
from sim_envs.source import FrameWindow
from sim_envs.trajectories import ROTATION_AXES, Trajectory, parse_axes, sweep_angles

REPLAY_ENV_ID = "sim_envs/Replay-v0"
NOMINAL_DEPTH_M = 2.0  # scene depth that weighs translation against rotation in rotation_share (ours: indoor rooms)
ADDED_PAN_AMPLITUDE_DEG = 20.0  # amplitude of the sweep's extra pan (ours: keeps the view on the room's content)
_ROTATION_NAME = re.compile(r"^rot_(?P<axes>[a-z]+(-[a-z]+)*)_(?P<speed>\d+(\.\d+)?)$")
_SAFE_NAME = re.compile(r"[^A-Za-z0-9_.+-]")  # what a folder's name may keep in a sequence (and run folder) name
DATASETS_ENV = "CNNSLAM_DATASETS"  # a user's list of local dataset folders, instead of the repository's
DEFAULT_DATASETS_FILE = Path(__file__).resolve().parent.parent / "datasets.toml"
FolderSize = tuple[int, int] | Literal["native"]


class SuiteError(EvalError):
    """An unknown suite, sequence or method selection."""


# ------------------------------------------------------------------------------------------------ the sequences
class VariantSequence(SimulatedSequence):
    """A simulated sequence with what :class:`~sim_envs.sequences.SequenceSpec` cannot express: other focal lengths
    (``focal_ratio`` x the training camera's, at the spec's resolution) and an extra pan sweeping
    +-:data:`ADDED_PAN_AMPLITUDE_DEG` at ``added_pan_deg_s`` deg/s about the camera's y axis (down in the image).

    Rendering, ground truth and determinism are :class:`SimulatedSequence`'s: the renderer is built from
    ``self.intrinsics`` and ``self.poses``, both set here before the first frame.
    """

    def __init__(
        self,
        spec: SequenceSpec,
        renderer: str = "mujoco",
        *,
        name: str | None = None,
        focal_ratio: float | None = None,
        added_pan_deg_s: float = 0.0,
    ) -> None:
        super().__init__(spec, renderer)
        self.name = name or spec.name
        if focal_ratio is not None:
            if not (math.isfinite(focal_ratio) and focal_ratio > 0):
                raise SuiteError(f"focal_ratio must be a positive number, got {focal_ratio!r}")
            train = preset(TRAIN_CAMERA, spec.width, spec.height)
            self.intrinsics = self.intrinsics.with_focal(focal_ratio * train.fx, focal_ratio * train.fy)
        if not (math.isfinite(added_pan_deg_s) and added_pan_deg_s >= 0):
            raise SuiteError(f"added_pan_deg_s must be a number >= 0, got {added_pan_deg_s!r}")
        self.added_pan_deg_s = float(added_pan_deg_s)
        self._panned: Trajectory | None = None

    @property
    def trajectory(self) -> Trajectory:
        """The spec's trajectory, with the extra pan when one is set (computed once)."""
        base = super().trajectory
        if self.added_pan_deg_s == 0.0:
            return base
        if self._panned is None:
            angles = sweep_angles(
                base.timestamps, np.radians(ADDED_PAN_AMPLITUDE_DEG), np.radians(self.added_pan_deg_s)
            )
            pan = np.tile(np.eye(4), (len(base), 1, 1))
            pan[:, :3, :3] = Rotation.from_euler("y", angles[:, None]).as_matrix()
            self._panned = Trajectory(base.timestamps, base.T_world_cam @ pan, kind=f"{base.kind}+pan")
        return self._panned


@dataclass(frozen=True)
class SequenceRef:
    """A sequence of a suite: a registered one, a rotation stress sequence, a variant of either, or an RGB-D folder.

    name: shown in results (and the run folder's name); base: a registered sequence name; rotation: ``(axes,
    speed_deg_s)`` of :func:`sim_envs.sequences.rotation_stress_spec` (instead of ``base``); overrides:
    :class:`SequenceSpec` fields to replace, as sorted ``(field, value)`` pairs (a mapping is accepted);
    focal_ratio / added_pan_deg_s: see :class:`VariantSequence`; axis / axis_value: the sweep axis and its nominal
    value, for plots. folder (instead of ``base`` or ``rotation``): the absolute path of a real RGB-D folder
    (:class:`sim_envs.datasets.RgbdFolder`), with ``camera`` (a preset name or the path of a camera file; None:
    detected), ``size`` ((width, height) of the delivered frames, default 320x240, or ``"native"``),
    ``depth_scale`` (None: detected) and ``undistort`` (how a distorted lens is undistorted:
    :data:`sim_envs.camera.UNDISTORT_MODES`, default ``crop``). start: the sequence's first frame (0: its
    beginning); a run's ``frames`` count from there: a window of a longer sequence (:func:`window_refs`).
    """

    name: str
    base: str | None = None
    rotation: tuple[str, float] | None = None
    overrides: tuple[tuple[str, Any], ...] = ()
    focal_ratio: float | None = None
    added_pan_deg_s: float = 0.0
    axis: str | None = None
    axis_value: float | None = None
    folder: str | None = None
    camera: str | None = None
    size: FolderSize = PROCESSING_SIZE
    depth_scale: float | None = None
    start: int = 0
    undistort: str = "crop"

    def __post_init__(self) -> None:
        items = self.overrides.items() if isinstance(self.overrides, Mapping) else self.overrides
        object.__setattr__(self, "overrides", tuple(sorted((str(k), v) for k, v in items)))
        if sum(v is not None for v in (self.base, self.rotation, self.folder)) != 1:
            raise SuiteError(
                f"sequence {self.name!r}: give exactly one of base (a registered name), rotation or folder"
            )
        bad = sorted(set(dict(self.overrides)) - set(SequenceSpec.__dataclass_fields__))
        if bad:
            raise SuiteError(f"sequence {self.name!r}: {bad} are not SequenceSpec fields")
        if not self.name or "/" in self.name or self.name.startswith("."):
            raise SuiteError(f"a sequence name must be non-empty, without '/', not starting with '.': {self.name!r}")
        object.__setattr__(self, "size", _folder_size(self.size))
        if isinstance(self.start, bool) or not isinstance(self.start, int) or self.start < 0:
            raise SuiteError(f"sequence {self.name!r}: start must be a frame index >= 0, got {self.start!r}")
        if self.folder is not None and (self.overrides or self.focal_ratio is not None or self.added_pan_deg_s):
            raise SuiteError(f"sequence {self.name!r}: a folder sequence has no spec overrides or variants")
        if self.undistort not in UNDISTORT_MODES or (self.undistort != "crop" and self.folder is None):
            raise SuiteError(f"sequence {self.name!r}: undistort must be one of {', '.join(UNDISTORT_MODES)}, and "
                             "other than crop only for a folder sequence")  # fmt: skip

    @property
    def registered(self) -> bool:
        """True when this is a registered sequence as it is (made by its own Gymnasium id)."""
        return (
            self.base is not None
            and self.name == self.base
            and not self.overrides
            and self.focal_ratio is None
            and self.added_pan_deg_s == 0.0
            and self.start == 0
        )

    @property
    def env_id(self) -> str:
        """The Gymnasium id the environment is made with."""
        return gym_id(self.name) if self.registered else REPLAY_ENV_ID

    def spec(self) -> SequenceSpec:
        """The sequence's spec (a registered one, or built, with the overrides applied; named ``name``)."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is the folder {self.folder}, not a simulated sequence")
        if self.base is not None:
            spec = get_sequence(self.base)
        else:
            axes, speed = self.rotation  # type: ignore[misc]
            spec = rotation_stress_spec(axes, float(speed))
        return replace(spec, name=self.name, **dict(self.overrides)) if not self.registered else spec

    def make_source(self, renderer: str = "mujoco", frame_cache: str | Path | None = None) -> Any:
        """The frame source (lazy: nothing is rendered or generated until used; a folder's frames are read from
        disk when asked for). ``renderer`` does not apply to a folder. ``frame_cache``: a folder under which a
        simulated source keeps the frames it rendered (:class:`sim_envs.frame_cache.CachedFrames`; same bytes)."""
        if self.start:  # the whole sequence's source (its frames cached as the whole's), windowed
            whole = replace(self, start=0).make_source(renderer, frame_cache)
            return FrameWindow(whole, self.start, name=self.name)
        if self.folder is not None:
            size = None if self.size == "native" else self.size
            return RgbdFolder(self.folder, self.camera, size=size, depth_scale=self.depth_scale, name=self.name,
                              undistort=self.undistort)  # fmt: skip
        if self.focal_ratio is None and self.added_pan_deg_s == 0.0:
            source = SimulatedSequence(self.spec(), renderer=renderer)
        else:
            source = VariantSequence(self.spec(), renderer, name=self.name, focal_ratio=self.focal_ratio,
                                     added_pan_deg_s=self.added_pan_deg_s)  # fmt: skip
        if frame_cache is None:
            return source
        return CachedFrames(source, Path(frame_cache) / cache_key(self.describe(), renderer))

    def make_env(self, max_frames: int | None = None, renderer: str = "mujoco",
                 frame_cache: str | Path | None = None) -> Any:
        """The Gymnasium environment: ``sim_envs/<name>-v0`` when registered as is (never cached), else
        ``sim_envs/Replay-v0`` replaying :meth:`make_source` (with ``frame_cache``)."""
        import gymnasium

        import sim_envs  # noqa: F401 - registers the environments

        if self.registered:
            return gymnasium.make(self.env_id, renderer=renderer, max_frames=max_frames)
        return gymnasium.make(REPLAY_ENV_ID, source=self.make_source(renderer, frame_cache), max_frames=max_frames)

    def describe(self) -> dict[str, Any]:
        """JSON-ready definition (run metadata; part of a run's fingerprint). A folder's includes its resolved path
        and a content fingerprint (:func:`sim_envs.datasets.folder_fingerprint`), so a changed folder reruns."""
        if self.folder is not None:
            camera_file = [self.camera] if self.camera and Path(self.camera).is_file() else []
            return {
                "name": self.name,
                "env_id": self.env_id,
                **({"start": self.start} if self.start else {}),  # absent at 0: earlier runs keep their fingerprint
                "folder": self.folder,
                "camera": self.camera,
                "size": self.size if self.size == "native" else list(self.size),
                "depth_scale": self.depth_scale,
                **({"undistort": self.undistort} if self.undistort != "crop" else {}),  # crop: as before the option
                "loader": LOADER_VERSION,
                "content": folder_fingerprint(self.folder, camera_file) if Path(self.folder).is_dir() else None,
            }
        return {
            "name": self.name,
            "env_id": self.env_id,
            "base": self.base,
            "rotation": list(self.rotation) if self.rotation else None,
            "overrides": {k: v for k, v in self.overrides},
            "focal_ratio": self.focal_ratio,
            "added_pan_deg_s": self.added_pan_deg_s,
            "axis": self.axis,
            "axis_value": self.axis_value,
            **({"start": self.start} if self.start else {}),
            **({"motion_sha256": _file_sha256(dict(self.overrides)["trajectory_params"])}
               if dict(self.overrides).get("trajectory") == "replay" else {}),  # fmt: skip
        }

    def with_camera_effects(self, preset: str) -> SequenceRef:
        """This simulated sequence seen through the camera-effects preset ``preset``
        (:func:`sim_envs.camera_effects.camera_effect_presets`), named ``<name>@<preset>`` (its own run folders);
        ``clean`` (the renderer's bytes) is the plain ``<name>``. A preset the sequence already has is replaced."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is a folder: its images come from a real camera")
        if dict(self.overrides).get("camera_effects", "clean") not in sim_camera_presets():
            return self  # a camera of its own (one effect alone, the sweep's camera axes): not a preset's to replace
        if preset not in sim_camera_presets():
            raise SuiteError(f"unknown camera preset {preset!r}; camera-effects presets of simulated sequences: "
                             f"{', '.join(sim_camera_presets())}")  # fmt: skip
        overrides = dict(self.overrides)
        name = self.name
        if overrides.get("camera_effects") in sim_camera_presets() and name.endswith(f"@{overrides['camera_effects']}"):
            name = name[: -len(overrides.pop("camera_effects")) - 1]  # seen through another preset: replaced
        if preset != "clean":
            overrides["camera_effects"] = preset
            name = f"{name}@{preset}"
        return replace(self, name=name, overrides=tuple(overrides.items()))

    def _camera_suffix(self) -> tuple[str, str, str]:
        """The name split as ``(base, "@", preset)`` when it ends in its camera preset's ``@<preset>``, else
        ``(name, "", "")``: where a variant's mark (``+lit``, ``~<motion>``) goes, before the camera."""
        base, at, preset = self.name.rpartition("@")
        if at and preset == dict(self.overrides).get("camera_effects"):
            return base, at, preset
        return self.name, "", ""

    def with_lighting(self, lighting: str) -> SequenceRef:
        """This simulated sequence in the same room lit otherwise (:data:`sim_envs.scene.LIGHTINGS`; ``lit``:
        :mod:`sim_envs.lighting`), named ``<name>+<lighting>`` before any ``@<camera preset>`` (its own run folders);
        ``flat`` is the plain name. The trajectory is the same."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is a folder: its light is the real room's")
        if lighting not in LIGHTINGS:
            raise SuiteError(f"unknown lighting {lighting!r}; valid: {', '.join(LIGHTINGS)}")
        overrides = dict(self.overrides)
        base, at, preset = self._camera_suffix()
        detail = overrides.get("detail", "standard")  # a +<detail> mark stays last: office0+lit+rich
        tail = f"+{detail}" if detail != "standard" and base.endswith(f"+{detail}") else ""
        base = base[: len(base) - len(tail)]
        old = overrides.pop("lighting", "flat")
        if old != "flat" and base.endswith(f"+{old}"):
            base = base[: -len(old) - 1]
        if lighting != "flat":
            overrides["lighting"] = lighting
            base = f"{base}+{lighting}"
        return replace(self, name=f"{base}{tail}{at}{preset}", overrides=tuple(overrides.items()))

    def with_detail(self, detail: str) -> SequenceRef:
        """This simulated sequence in the same room at another detail level (:data:`sim_envs.scene.DETAILS`;
        ``rich``: clutter and texture detail, :mod:`sim_envs.scenegen`), named ``<name>+<detail>`` after any
        ``+<lighting>`` and before any ``@<camera preset>`` (its own run folders); ``standard`` is the plain name. The
        trajectory is the same."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is a folder: its detail is the real room's")
        if detail not in DETAILS:
            raise SuiteError(f"unknown detail {detail!r}; valid: {', '.join(DETAILS)}")
        overrides = dict(self.overrides)
        base, at, preset = self._camera_suffix()
        old = overrides.pop("detail", "standard")
        if old != "standard" and base.endswith(f"+{old}"):
            base = base[: -len(old) - 1]
        if detail != "standard":
            overrides["detail"] = detail
            base = f"{base}+{detail}"
        return replace(self, name=f"{base}{at}{preset}", overrides=tuple(overrides.items()))

    def with_motion(self, file: str | Path, label: str | None = None, frames: int | None = None) -> SequenceRef:
        """This simulated sequence's room with a recorded camera motion replayed in it instead of its own
        trajectory (the ``replay`` kind of :mod:`sim_envs.trajectories`: a TUM trajectory ``file``, e.g. real
        hand-held motion), named ``<name>~<label>`` before any ``@<camera preset>`` (label: :func:`motion_label`).
        The room and camera are the sequence's; its length too, cut to what the recording covers and to ``frames``
        (the frames a suite will run: the whole replayed path must fit the room's free space, so a path longer than
        the run would only make a room refuse it). The run's fingerprint holds the file's SHA-256
        (:meth:`describe`), so an edited recording reruns."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is a folder: its motion is the real camera's")
        path = Path(file).expanduser().resolve()
        if not path.is_file():
            raise SuiteError(f"motion file {path} is not a file (a TUM trajectory: timestamp tx ty tz qx qy qz qw)")
        try:
            stamps, _ = read_tum_trajectory(path, duplicate_timestamps="first")
        except SimEnvError as exc:
            raise SuiteError(f"motion file: {exc}") from None
        spec = self.spec()
        n_frames = min(spec.n_frames, int(math.floor((stamps[-1] - stamps[0]) * spec.fps + 1e-9)) + 1,
                       spec.n_frames if frames is None else int(frames))
        if n_frames < 2:
            raise SuiteError(f"motion file {path} covers {stamps[-1] - stamps[0]:.3f} s: too short to replay")
        overrides = dict(self.overrides)
        base, at, preset = self._camera_suffix()
        overrides.update(trajectory="replay", trajectory_params=(("file", str(path)),), n_frames=n_frames)
        name = f"{base}~{label or motion_label(path)}{at}{preset}"
        return replace(self, name=name, overrides=tuple(overrides.items()))

    def with_folder_options(self, camera: str | None = None, size: FolderSize | None = None,
                            undistort: str | None = None) -> SequenceRef:
        """This folder sequence with another camera (preset name or camera file), delivered size and/or
        undistortion (:data:`sim_envs.camera.UNDISTORT_MODES`; other than ``crop`` the name gets
        ``~undistort_<mode>``, its own run folders, as the preprocessing suite's)."""
        if self.folder is None:
            raise SuiteError(f"sequence {self.name!r} is not a folder: --camera, --image-size and --undistort do not "
                             "apply")  # fmt: skip
        if undistort is not None and undistort not in UNDISTORT_MODES:
            raise SuiteError(f"unknown undistortion {undistort!r}; valid: {', '.join(UNDISTORT_MODES)}")
        name = self.name
        if undistort is not None and undistort != self.undistort:  # named as the preprocessing suite names it
            name = name.removesuffix(f"~undistort_{self.undistort}")
            name += "" if undistort == "crop" else f"~undistort_{undistort}"
        return replace(
            self,
            name=name,
            camera=_camera_argument(camera) if camera is not None else self.camera,
            size=_folder_size(size) if size is not None else self.size,
            undistort=undistort if undistort is not None else self.undistort,
        )


def motion_label(path: str | Path) -> str:
    """The name a recorded motion gives its sequences and domain: the file's stem, or its folder's name for a TUM
    RGB-D ``groundtruth.txt`` (every sequence's is called that), made file-safe."""
    path = Path(path)
    stem = path.parent.name if path.stem == "groundtruth" else path.stem
    return _SAFE_NAME.sub("_", stem.removeprefix("rgbd_dataset_"))


def _file_sha256(params: Any) -> str | None:
    """SHA-256 of the ``file`` of a replay trajectory's parameters (None when it cannot be read); read once per
    version of the file (``describe`` is called for every fingerprint, cache key and record)."""
    try:
        path = Path(dict(params)["file"])
        stat = path.stat()
    except (OSError, KeyError, TypeError):
        return None
    return _sha256_of(str(path), stat.st_size, stat.st_mtime_ns)


@lru_cache(maxsize=64)
def _sha256_of(path: str, size: int, mtime_ns: int) -> str | None:
    """SHA-256 of the file ``path`` as it is at (``size``, ``mtime_ns``), the cache's key."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return None


def folder_ref(
    path: str | os.PathLike[str],
    *,
    camera: str | None = None,
    size: FolderSize = PROCESSING_SIZE,
    depth_scale: float | None = None,
    name: str | None = None,
) -> SequenceRef:
    """An RGB-D folder as a sequence (see :class:`SequenceRef`). Its name: ``name``, else the folder's name with
    characters other than letters, digits and ``_.+-`` replaced by ``_``, and a short hash of the path appended
    when that would be taken for a simulated sequence. :class:`SuiteError` (one line) when it is not a folder of a
    known layout."""
    folder = Path(path).expanduser().resolve()
    try:
        detect_layout(folder)
    except SimEnvError as exc:
        raise SuiteError(f"sequence {os.fspath(path)!r}: {exc}") from None
    if name is None:
        name = _SAFE_NAME.sub("_", folder.name).lstrip(".") or "folder"
        if name in list_sequences("all") or _ROTATION_NAME.match(name):
            name = f"{name}-{_path_tag(folder)}"
    return SequenceRef(
        name,
        folder=str(folder),
        camera=_camera_argument(camera) if camera is not None else None,
        size=size,
        depth_scale=depth_scale,
    )


def _folder_size(size: Any) -> FolderSize:
    if size == "native":
        return "native"
    try:
        return check_size(size)
    except SimEnvError as exc:
        raise SuiteError(f"an image size is WIDTHxHEIGHT in pixels or 'native': {exc}") from None


def _camera_argument(camera: str, base: Path | None = None) -> str:
    """A camera preset name as it is, or a camera file's absolute path (relative to ``base``, default the cwd)."""
    if camera in camera_presets():
        return camera
    path = (base or Path.cwd()) / Path(camera).expanduser()
    if not path.is_file():
        raise SuiteError(
            f"camera {camera!r} is neither a preset ({', '.join(camera_presets())}) nor a camera file (TOML/YAML)"
        )
    return str(path.resolve())


def _path_tag(folder: str | Path) -> str:
    return hashlib.sha256(str(folder).encode()).hexdigest()[:6]


def _unique(refs: Sequence[SequenceRef]) -> tuple[SequenceRef, ...]:
    """The refs in order, a repeated one once, and folders whose names clash given a short hash of their path."""
    out: list[SequenceRef] = []
    for ref in refs:
        if ref not in out:
            out.append(ref)
    names = [r.name for r in out]
    return tuple(
        replace(r, name=f"{r.name}-{_path_tag(r.folder)}") if r.folder is not None and names.count(r.name) > 1 else r
        for r in out
    )


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


def load_dataset_list(path: str | Path | None = None) -> dict[str, DatasetEntry]:
    """The named local dataset folders of a TOML list (default :func:`dataset_list_file`), in file order.

    Format: a ``[datasets]`` table whose entries are ``name = "path"`` or ``[datasets.<name>]`` tables with
    ``path`` and optionally ``camera`` (preset name or camera file), ``size`` (``[width, height]`` or
    ``"native"``), ``depth_scale`` and ``reference`` (a second reference trajectory). Relative paths are
    relative to the list file's folder; ``~`` is expanded.
    A missing default list is an empty list; a missing list named by ``$CNNSLAM_DATASETS`` is an error.
    """
    explicit = path is not None or bool(os.environ.get(DATASETS_ENV))
    file = Path(path) if path is not None else dataset_list_file()
    if not file.is_file():
        if explicit:
            raise SuiteError(f"no dataset list at {file} (${DATASETS_ENV} or the given path)")
        return {}
    try:
        data = tomllib.loads(file.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise SuiteError(f"{file}: not a readable TOML dataset list ({exc})") from None
    table = data.get("datasets", {})
    if not isinstance(table, dict) or set(data) - {"datasets"}:
        raise SuiteError(f"{file}: expected only a [datasets] table (name = \"path\" or [datasets.<name>])")
    base = file.resolve().parent
    entries = {}
    for name, value in table.items():
        entry = value if isinstance(value, dict) else {"path": value}
        unknown = sorted(set(entry) - {"path", "camera", "size", "depth_scale", "reference"})
        if unknown or not isinstance(entry.get("path"), str):
            raise SuiteError(
                f"{file}: dataset {name!r} needs path = \"FOLDER\" (optional: camera, size, depth_scale, reference)"
                + (f"; unknown key(s) {', '.join(unknown)}" if unknown else "")
            )
        if _SAFE_NAME.search(name) or name.startswith(".") or name in list_sequences("all"):
            raise SuiteError(f"{file}: dataset name {name!r} must use letters, digits, _.+- and not be a sequence's")
        camera = entry.get("camera")
        if camera is not None and camera not in camera_presets():
            camera = str((base / Path(camera).expanduser()).resolve())  # checked when the folder is loaded
        entries[name] = DatasetEntry(
            name,
            (base / Path(entry["path"]).expanduser()).resolve(),
            camera,
            _folder_size(entry.get("size", PROCESSING_SIZE)),
            float(entry["depth_scale"]) if entry.get("depth_scale") is not None else None,
            (base / Path(str(entry["reference"])).expanduser()).resolve() if entry.get("reference") else None,
        )
    return entries


def window_refs(ref: SequenceRef, length: int, total: int | None = None) -> tuple[SequenceRef, ...]:
    """``ref`` cut into non-overlapping windows of ``length`` frames from its first frame (a short remainder is
    left out): each a sequence of its own, named ``<name>.from<start>`` (the first keeps ``ref``'s name: it is
    ``ref`` on its first ``length`` frames, the same runs), run on its first ``length`` frames (the suite's
    ``frames``). ``total``: the sequence's number of frames (default: its source's, read now). A sequence shorter
    than ``length`` gives no window."""
    if length < 2:
        raise SuiteError(f"a window needs >= 2 frames, got {length}")
    if ref.start:
        raise SuiteError(f"sequence {ref.name!r} is already a window (from frame {ref.start})")
    if total is None:
        source = ref.make_source()
        try:
            total = len(source)
        finally:
            source.close()
    return tuple(replace(ref, name=f"{ref.name}.from{start}", start=start) if start else ref
                 for start in range(0, int(total) - int(length) + 1, int(length)))  # fmt: skip


def rotation_ref(axes: str, speed_deg_s: float) -> SequenceRef:
    """The rotation stress sequence ``rot_<axes>_<speed>`` (registered ones are used as registered)."""
    names = parse_axes(axes)
    label = "rpy" if names == ("yaw", "pitch", "roll") else "-".join(names)
    name = f"rot_{label}_{float(speed_deg_s):g}"
    if name in list_sequences():
        return SequenceRef(name, base=name)
    return SequenceRef(name, rotation=("+".join(names), float(speed_deg_s)))


def resolve_sequence(name: str) -> SequenceRef:
    """A sequence by name: a registered sequence; ``rot_<axes>_<speed>`` (axes yaw, pitch, roll joined by ``-``, or
    ``rpy``; speed in deg/s) for any rotation stress sequence; the path of an RGB-D folder (:func:`folder_ref`) when
    it has a ``/`` or starts with ``.`` or ``~``; a name of the dataset list (:func:`load_dataset_list`); an existing
    folder. The first that fits wins. A simulated sequence's name may end in ``@<camera preset>``
    (``office0@clean``): that sequence seen through that camera (:meth:`SequenceRef.with_camera_effects`); without
    one it is the renderer's image (``clean``). A simulated name may end in ``+lit`` before that (``office0+lit@hard``):
    the same room and trajectory with lamps, shadows and highlights (:meth:`SequenceRef.with_lighting`), and in
    ``+rich`` (``office0+rich``, ``office0+lit+rich@kinect``): the same room with clutter and texture detail
    (:meth:`SequenceRef.with_detail`); the marks may come in either order, the name is made ``+lit+rich``."""
    plain, sep, preset = name.rpartition("@")
    if sep and preset in sim_camera_presets() and plain:
        ref = resolve_sequence(plain)
        if ref.folder is None:
            return ref.with_camera_effects(preset)
    variant = split_variant(name)
    if variant is not None:
        plain, field, value = variant
        ref = resolve_sequence(plain)
        if ref.folder is None:
            return ref.with_lighting(value) if field == "lighting" else ref.with_detail(value)
    if name in list_sequences():
        return SequenceRef(name, base=name)
    match = _ROTATION_NAME.match(name)
    if match:
        axes = match["axes"]
        try:
            return rotation_ref(axes if axes == "rpy" else axes.replace("-", "+"), float(match["speed"]))
        except SimEnvError as exc:  # e.g. rot_yawn_30: a rotation name with a bad axis
            raise SuiteError(f"sequence {name!r}: {exc}") from None
    if "/" in name or os.sep in name or name.startswith((".", "~")):
        return folder_ref(name)
    datasets = load_dataset_list()
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


def _with_default_camera(name: str) -> SequenceRef:
    """:func:`resolve_sequence`, a simulated sequence named without a camera preset seen through the default camera
    (what the suites run: ``office0`` is ``office0@kinect``)."""
    ref = resolve_sequence(name)
    named_camera = name.rpartition("@")[2] in sim_camera_presets()
    if ref.folder is not None or named_camera or "camera_effects" in dict(ref.overrides):
        return ref
    return ref.with_camera_effects(DEFAULT_CAMERA_EFFECTS)


def rotation_share(T_world_cam: np.ndarray, depth_m: float = NOMINAL_DEPTH_M) -> float:
    """Share (0..1) of the image motion along a trajectory that is due to rotation.

    Per frame step, a rotation by angle a moves the image by about f * a pixels and a translation t by about
    f * |t| / d for a scene at depth d; the share is sum(a) / (sum(a) + sum(|t|) / d) over the steps.
    T_world_cam: (N, 4, 4); depth_m: the scene depth d in metres. NaN for a trajectory that does not move.
    """
    T = np.asarray(T_world_cam, dtype=np.float64)
    if T.shape[0] < 2:
        return math.nan
    rel = np.einsum("nji,njk->nik", T[:-1, :3, :3], T[1:, :3, :3])
    angles = Rotation.from_matrix(rel).magnitude()
    shifts = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1) / float(depth_m)
    total = float(angles.sum() + shifts.sum())
    return float(angles.sum() / total) if total > 0 else math.nan


# --------------------------------------------------------------------------------------------------- the suites
SuiteKind = Literal["runs", "perf", "transfer", "lengths", "preprocessing"]

# the paper's methods, the original ORB-SLAM3 beside our ORB baseline (thirdparty/, out of process), and the oracle
TABLE1_METHODS: tuple[str, ...] = ("CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE", "ORB-SLAM3", "oracle")
# the transfer suite ranks the paper's methods; the oracle is fed ground truth and would win every ranking
TRANSFER_METHODS: tuple[str, ...] = tuple(m for m in TABLE1_METHODS if m != "oracle")
# camera presets of the simulated part of the transfer suite (sim_envs.camera_effects), in report order
SIM_CAMERA_PRESETS: tuple[str, ...] = ("clean", "kinect", "hard")


def sim_camera_presets() -> list[str]:
    """The camera-effects presets a simulated sequence can be seen through (``--camera`` of simulated sequences);
    disjoint from the calibration presets of real folders (:func:`sim_envs.camera.camera_presets`)."""
    from sim_envs.camera_effects import camera_effect_presets

    return camera_effect_presets()
ABLATION_METHODS: tuple[str, ...] = ("raw-CNN", "focal-adjusted", "adjusted+refined")
# the gate's methods: deterministic ones (ORB-SLAM3's threads make its runs differ: not gated)
QUICK_METHODS: tuple[str, ...] = ("CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE", "oracle", "constant-pose")
DEPTH_QUALITY_METHODS: tuple[str, ...] = ("CNN-SLAM", "raw-CNN", "dev-depth-5", "dev-depth-10", "dev-depth-20")
DEPTH_QUALITY_SEQUENCES: tuple[str, ...] = tuple(s for s in TABLE1_SEQUENCES if s.startswith(("office", "living")))
# the rotation suite's axes: each of the world's rotation axes alone, then all three together ("rpy")
ROTATION_SUITE_AXES: tuple[str, ...] = (*ROTATION_AXES, "rpy")
ROTATION_SPEEDS: tuple[float, ...] = (15.0, 30.0, 60.0)
SWEEP_BASE = "office1"
DEFAULT_RUNS = 3  # runs per cell (seeds 0, 1, 2): a median and a spread, as the field reports (DPVO: median of 5)
# the short length: the ablation, the transfer suite's short comparison (against real windows of this length) and
# the preprocessing suite run it. Not the verdict's length: the length sweep (cnnslam bench lengths,
# results/lengths.md) found no length short of whole sequences that ranks the Table-1 methods as whole sequences do,
# so the table1 suite and `make bench` run whole sequences, the paper's protocol.
BENCH_FRAMES = 200
TEXTURE_DENSITIES: tuple[float, ...] = (1.0, 0.6, 0.3, 0.1)
ADDED_PAN_SPEEDS: tuple[float, ...] = (0.0, 15.0, 30.0, 60.0)
FOCAL_RATIOS: tuple[float, ...] = (0.7, 0.85, 1.0, 1.2, 1.4)
# the sweep's camera axes: each effect alone on the clean camera (sim_envs.camera_effects.SINGLE_EFFECTS), strength 1
# = the kinect preset's value
CAMERA_EFFECT_STRENGTHS: dict[str, tuple[float, ...]] = {
    "noise": (1.0, 2.0, 4.0),
    "blur": (0.5, 1.0, 2.0),
    "exposure": (1.0, 3.0, 6.0),
    "rolling_shutter": (0.1, 0.5, 1.0),
    "distortion": (0.5, 1.0, 2.0),
}
SWEEP_AXES: dict[str, str] = {
    "texture": "texture density",
    "rotation": "share of rotation in the motion",
    "focal": "focal length, test / training camera",
    "noise": "camera noise alone, x ICL-NUIM's",
    "blur": "motion blur alone, exposure x half a frame interval",
    "exposure": "auto-exposure alone, exposure jitter x kinect's",
    "rolling_shutter": "rolling shutter alone, readout in frame intervals",
    "distortion": "lens distortion alone, x TUM fr1's",
}


# the report layouts a suite may name (eval.reports writes each); "generic" is the plain per-metric table
REPORT_LAYOUTS: tuple[str, ...] = ("generic", "table1", "rotation", "ablation", "sweep", "quick", "depth_quality")
BASELINE_DIR: Path = Path("results") / "baselines"  # relative to the working directory, as --results is


@dataclass(frozen=True)
class Suite:
    """A suite: ``sequences`` x ``methods`` (names of the method table) x ``seeds`` (the runs of each cell, see
    ``eval/methods.toml`` for what a seed changes per method), each run on the first ``frames`` frames (None: whole
    sequences); ``alignment`` of the ATE (``slamcommon.alignment``; a method's own ``align`` wins); ``kind`` "perf" for
    the throughput suite, which runs no agents; ``skipped``: ``(name, reason)`` of sequences it lists but cannot
    run here (a dataset folder that is missing).

    The suite also names what is made of its runs: ``report``, the layout of its report (:data:`REPORT_LAYOUTS`,
    written by :func:`eval.reports.write_report`); ``gated``: ``cnnslam bench`` compares its runs with its
    ``baseline`` file (default ``results/baselines/<name>.json``) unless told not to; ``real_folders``: its
    sequences are the folders of the local dataset list, read when the suite is asked for (:func:`get_suite`).
    Nothing else in the code switches on a suite's name."""

    name: str
    description: str
    sequences: tuple[SequenceRef, ...] = ()
    methods: tuple[str, ...] = ()
    frames: int | None = None
    seeds: tuple[int, ...] = tuple(range(DEFAULT_RUNS))
    alignment: str = "se3"
    kind: SuiteKind = "runs"
    skipped: tuple[tuple[str, str], ...] = ()
    report: str = "generic"
    gated: bool = False
    baseline: str | None = None
    real_folders: bool = False

    def __post_init__(self) -> None:
        if self.report not in REPORT_LAYOUTS:
            raise SuiteError(f"suite {self.name!r}: report must be one of {', '.join(REPORT_LAYOUTS)}, got "
                             f"{self.report!r}")  # fmt: skip

    @property
    def baseline_path(self) -> Path:
        """The gate's baseline file of this suite (``baseline``, or ``results/baselines/<name>.json``)."""
        return Path(self.baseline) if self.baseline is not None else BASELINE_DIR / f"{self.name}.json"

    def select(
        self,
        sequences: Sequence[str] | None = None,
        methods: Sequence[str] | None = None,
        frames: int | Literal["all"] | None = None,
        seeds: Sequence[int] | None = None,
        runs: int | None = None,
        camera: str | None = None,
        size: FolderSize | None = None,
        undistort: str | None = None,
    ) -> Suite:
        """The suite restricted or changed: ``sequences`` (names of the suite's, or any :func:`resolve_sequence`
        name or folder path), ``methods`` (any method names), ``frames`` (a number, or ``"all"``: whole
        sequences), ``seeds``, or ``runs`` N (seeds 0 .. N-1; not with ``seeds``); ``camera`` and ``size`` for
        every folder sequence (:meth:`SequenceRef.with_folder_options`). Sequences named explicitly drop the suite's
        skipped ones not among them."""
        if runs is not None:
            if seeds:
                raise SuiteError("give --runs or --seeds, not both")
            if int(runs) < 1:
                raise SuiteError(f"--runs must be >= 1, got {runs}")
            seeds = range(int(runs))
        if seeds is not None and len(set(seeds)) != len(list(seeds)):
            raise SuiteError(f"seeds must be distinct, got {list(seeds)}")
        refs, skipped = self.sequences, self.skipped
        if sequences:
            own = {s.name: s for s in self.sequences}
            missing = dict(self.skipped)
            named = [name for name in sequences if name not in missing]
            refs = tuple(own[name] if name in own else _with_default_camera(name) for name in named)
            skipped = tuple((name, missing[name]) for name in sequences if name in missing)
        if camera is not None and camera in sim_camera_presets():  # what the simulated camera does to its images
            if not any(r.folder is None for r in refs):
                raise SuiteError(f"--camera {camera} is a simulated camera's preset, and no simulated sequence is "
                                 "selected (a folder's camera is a calibration preset or file)")  # fmt: skip
            refs = tuple(r.with_camera_effects(camera) if r.folder is None else r for r in refs)
            camera = None
        if camera is not None or size is not None or undistort is not None:
            if not any(r.folder is not None for r in refs):
                if undistort is not None:
                    raise SuiteError("--undistort applies to folder sequences, and none is selected (a simulated "
                                     "camera's lens is undistorted by its camera preset)")  # fmt: skip
                if camera is not None:  # most likely a misspelt preset
                    raise SuiteError(f"unknown camera preset {camera!r} for simulated sequences; valid presets: "
                                     f"{', '.join(sim_camera_presets())} (a calibration preset or camera file applies "
                                     "to folder sequences only)")  # fmt: skip
                raise SuiteError("--image-size applies to folder sequences, and none is selected (simulated sequences "
                                 "render at their own size)")  # fmt: skip
            refs = tuple(r.with_folder_options(camera, size, undistort) if r.folder is not None else r for r in refs)
        if frames is not None and frames != "all" and int(frames) < 2:
            raise SuiteError(f"--frames must be >= 2, got {frames}")
        return replace(
            self,
            sequences=_unique(refs),
            methods=tuple(methods) if methods else self.methods,
            frames=self.frames if frames is None else None if frames == "all" else int(frames),
            seeds=tuple(int(s) for s in seeds) if seeds else self.seeds,
            skipped=skipped,
        )

    @property
    def is_default(self) -> bool:
        """True when this is the suite exactly as defined (not a subset or variant): only then does it write the
        committed results under ``results/``. The ``real`` suite is defined by the dataset list as it is now."""
        try:
            return get_suite(self.name) == self
        except SuiteError:
            return False


def sweep_sequences(base: str = SWEEP_BASE) -> tuple[SequenceRef, ...]:
    """The sweep's variants of ``base``, one axis at a time (see the module docstring)."""
    refs = [
        SequenceRef(f"{base}@texture{d:g}", base=base, overrides={"texture_density": d}, axis="texture", axis_value=d)
        for d in TEXTURE_DENSITIES
    ]
    refs += [
        SequenceRef(f"{base}@pan{s:g}", base=base, added_pan_deg_s=s, axis="rotation", axis_value=s)
        for s in ADDED_PAN_SPEEDS
    ]
    refs += [
        SequenceRef(f"{base}@focal{r:g}", base=base, focal_ratio=r, axis="focal", axis_value=r) for r in FOCAL_RATIOS
    ]
    refs = [r.with_camera_effects(DEFAULT_CAMERA_EFFECTS) for r in refs]
    refs += [  # one camera effect alone, on the clean camera
        SequenceRef(f"{base}@{effect}{s:g}", base=base, overrides={"camera_effects": f"{effect}:{s:g}"}, axis=effect,
                    axis_value=s)
        for effect, strengths in CAMERA_EFFECT_STRENGTHS.items() for s in strengths
    ]  # fmt: skip
    return tuple(refs)


def _named(name: str) -> SequenceRef:
    """A registered sequence as suites run it: through the world's default camera
    (:data:`sim_envs.camera_effects.DEFAULT_CAMERA_EFFECTS`)."""
    return SequenceRef(name, base=name).with_camera_effects(DEFAULT_CAMERA_EFFECTS)


def _suites() -> dict[str, Suite]:
    table1 = tuple(_named(name) for name in TABLE1_SEQUENCES)
    return {
        "table1": Suite(
            "table1",
            "the nine Table-1 analogue sequences, whole as the paper runs them, x the paper's methods and the oracle "
            "(CNN-SLAM Table 1; make bench runs it at the bench length)",
            table1,
            TABLE1_METHODS,
            frames=None,
            report="table1",
        ),
        "rotation": Suite(
            "rotation",
            "pure-rotation stress sequences (yaw, pitch, roll, all three at 15, 30, 60 deg/s): tracked share, "
            "rotation error, correct depth (the paper's Sec. 4.2)",
            tuple(rotation_ref(a, s).with_camera_effects(DEFAULT_CAMERA_EFFECTS) for a in ROTATION_SUITE_AXES
                  for s in ROTATION_SPEEDS),
            TABLE1_METHODS,
            frames=150,
            report="rotation",
        ),
        "ablation": Suite(
            "ablation",
            "raw CNN depth vs focal-adjusted vs adjusted + refined, ATE and correct depth (the paper's Fig. 3)",
            table1,
            ABLATION_METHODS,
            frames=BENCH_FRAMES,
            report="ablation",
        ),
        "sweep": Suite(
            "sweep",
            f"one difficulty axis at a time on {SWEEP_BASE}: texture density, share of rotation, focal mismatch, and "
            "each camera effect alone (noise, blur, auto-exposure, rolling shutter, distortion)",
            sweep_sequences(),
            tuple(m for m in TABLE1_METHODS if m != "oracle"),
            frames=150,
            report="sweep",
        ),
        "depth_quality": Suite(
            "depth_quality",
            "full-length office and living sequences: CNN-SLAM against the raw CNN, and CNN-SLAM on development "
            "depth of known accuracy (ATE / length, scale error, correct depth)",
            tuple(_named(name) for name in DEPTH_QUALITY_SEQUENCES),
            DEPTH_QUALITY_METHODS,
            frames=None,
            report="depth_quality",
        ),
        "perf": Suite(
            "perf", "throughput: render fps, CNN ms/frame, tracking and whole-system fps, metrics time", kind="perf"
        ),
        "real": Suite(
            "real",
            "every folder of the local dataset list (datasets.toml, or the file $CNNSLAM_DATASETS names) x the "
            "paper's methods and the oracle, whole sequences",
            (),
            TABLE1_METHODS,
            frames=None,
            real_folders=True,
        ),
        "transfer": Suite(
            "transfer",
            "sim-to-real transfer, like for like: the paper's methods on the simulated Table-1 analogues through "
            "the default camera and on every folder of the local dataset list, whole sequence against whole "
            "sequence and bench length against real windows of the bench length; per metric, the methods' "
            "rankings side by side, their rank correlation (Spearman, Kendall) and its bootstrap interval",
            (),
            TRANSFER_METHODS,
            frames=BENCH_FRAMES,
            kind="transfer",
            real_folders=True,
        ),
        "lengths": Suite(
            "lengths",
            "the length sweep: the Table-1 suite on the first 200, 400 and 800 frames and on whole sequences; per "
            "metric, each length's ranking of the paper's methods against the whole sequences' (Kendall's tau), "
            "where each method's rank settles, and the shortest length that ranks as whole sequences do",
            table1,
            TRANSFER_METHODS,
            frames=None,
            kind="lengths",
        ),
        "preprocessing": Suite(
            "preprocessing",
            "preprocessing that decides nothing unseen: the paper's methods on every folder of the local dataset "
            "list, first 200 frames, under each preprocessing choice that applies (undistortion cropped / full "
            "frame / none, the images' own size, depth unregistered); per folder and metric, each choice's ranking "
            "against the default's, and the verdicts that change",
            (),
            TRANSFER_METHODS,
            frames=BENCH_FRAMES,
            kind="preprocessing",
            real_folders=True,
        ),
        "quick": Suite(
            "quick",
            "a few short sequences x all methods: the CI regression baseline (results/baselines/quick.json)",
            tuple(_named(name) for name in ("office0", "tum_nostructure_near", "rot_yaw_30")),
            QUICK_METHODS,
            frames=60,
            report="quick",
            gated=True,
        ),
    }


SUITES: dict[str, Suite] = _suites()


def get_suite(name: str) -> Suite:
    """A suite by name (``real``: built from the dataset list now, :func:`real_suite`); :class:`SuiteError`
    listing the valid names otherwise."""
    try:
        suite = SUITES[name]
    except KeyError:
        raise SuiteError(f"unknown suite {name!r}; valid suites: {', '.join(SUITES)}") from None
    return with_real_folders(suite) if suite.real_folders else suite


def sim_domain(name: str) -> tuple[str, str]:
    """A simulated domain of the transfer report, ``<camera preset>`` or ``<camera preset>+<lighting>``
    (``kinect+lit``), as ``(camera preset, lighting)``; raises :class:`SuiteError` naming the valid ones."""
    camera, _, lighting = name.partition("+")
    if camera not in SIM_CAMERA_PRESETS or (lighting or "flat") not in LIGHTINGS:
        raise SuiteError(
            f"unknown simulated domain {name!r}; valid: a camera preset ({', '.join(SIM_CAMERA_PRESETS)}), "
            f"optionally with +lit (kinect+lit: the rooms lit by lamps with shadows)"
        )
    return camera, lighting or "flat"


@dataclass(frozen=True)
class PreprocessingChoice:
    """A way of turning a folder's files into the frames an agent sees, other than the loader's default: ``name``
    (the report's and the run folders' ``<folder>~<name>``), what it does, and the :class:`SequenceRef` fields it
    sets; ``applies``: which folders it changes anything for (``distorted``: a camera with lens distortion;
    ``registered``: depth registered to the colour camera, 7-Scenes; ``resized``: images not already at the
    processing size)."""

    name: str
    description: str
    fields: tuple[tuple[str, Any], ...]
    applies: Literal["distorted", "registered", "resized"]


PREPROCESSING_CHOICES: tuple[PreprocessingChoice, ...] = (
    PreprocessingChoice("undistort_full", "undistorted onto the whole frame with K, black border",
                        (("undistort", "full"),), "distorted"),  # fmt: skip
    PreprocessingChoice("undistort_none", "not undistorted: the distorted images as pinhole ones with K",
                        (("undistort", "none"),), "distorted"),  # fmt: skip
    PreprocessingChoice("native_size", "the images' own size instead of 320x240", (("size", "native"),), "resized"),
    PreprocessingChoice("unregistered_depth", "7-Scenes: the depth camera's intrinsics (585 px) taken as the colour "
                        "camera's, depth maps and poses as they are (no registration)", (("camera", "7scenes"),),
                        "registered"),  # fmt: skip
)
DEFAULT_PREPROCESSING = "default"  # the loader's defaults: cropped undistortion, 320x240, depth registered


def preprocessing_parts(suite: Suite) -> list[tuple[str, Suite, tuple[tuple[str, str], ...]]]:
    """The suites the ``preprocessing`` suite is made of, as ``(choice, suite, domains)``: the ``real`` suite on the
    preprocessing suite's folders as the loader delivers them by default (choice ``default``), then, per choice of
    :data:`PREPROCESSING_CHOICES`, on the folders it applies to, named ``<folder>~<choice>``; ``domains``: each
    sequence's folder (the name the default gives it). Frames, methods and seeds are the preprocessing suite's."""
    if suite.kind != "preprocessing":
        raise SuiteError(f"suite {suite.name!r} is not a preprocessing suite")
    base = replace(SUITES["real"], methods=suite.methods, frames=suite.frames, seeds=suite.seeds, skipped=suite.skipped)
    folders = [r for r in suite.sequences if r.folder is not None]
    parts = [(DEFAULT_PREPROCESSING, replace(base, sequences=tuple(folders)), tuple((r.name, r.name) for r in folders))]
    traits = {r.name: _folder_traits(r) for r in folders}
    for choice in PREPROCESSING_CHOICES:
        chosen = [r for r in folders if choice.applies in traits[r.name]]
        refs = tuple(replace(r, name=f"{r.name}~{choice.name}", **dict(choice.fields)) for r in chosen)
        if refs:
            domains = tuple((c.name, r.name) for c, r in zip(refs, chosen, strict=True))
            parts.append((choice.name, replace(base, sequences=refs), domains))
    return parts


def _folder_traits(ref: SequenceRef) -> set[str]:
    """Which preprocessing choices change anything for this folder (see :class:`PreprocessingChoice`)."""
    source = ref.make_source()
    try:
        traits = set()
        if source.camera.distorted:
            traits.add("distorted")
        if source.depth_rig is not None:
            traits.add("registered")
        if ref.size != "native" and tuple(source.original_size) != tuple(ref.size):
            traits.add("resized")
        return traits
    finally:
        source.close()


SWEEP_LENGTHS: tuple[int | None, ...] = (200, 400, 800, None)  # the length sweep's lengths (None: whole sequences)


def length_parts(suite: Suite, lengths: Sequence[int | None] = SWEEP_LENGTHS) -> list[tuple[int | None, Suite]]:
    """The suites the ``lengths`` suite is made of: for each of ``lengths`` (frames; None: whole sequences), the
    ``table1`` suite on the lengths suite's sequences, methods and seeds, on the first ``length`` frames (its runs
    are ``make bench``'s and ``cnnslam bench table1``'s own)."""
    if suite.kind != "lengths":
        raise SuiteError(f"suite {suite.name!r} is not a length sweep")
    bad = [n for n in lengths if n is not None and int(n) < 2]
    if bad or not lengths:
        raise SuiteError(f"lengths must be numbers of frames >= 2 or 'all', got {list(lengths)}")
    table1 = SUITES["table1"]
    ordered = sorted(set(lengths), key=lambda n: (n is None, n or 0))
    return [(n, replace(table1, sequences=suite.sequences, methods=suite.methods, seeds=suite.seeds, frames=n))
            for n in ordered]  # fmt: skip


@dataclass(frozen=True)
class TransferPart:
    """One suite the ``transfer`` suite runs: ``suite`` (named ``table1`` or ``real``, so its runs are those suites'
    own), the ``length`` its samples have (frames; None: whole sequences) and the transfer ``domain`` of each of its
    sequences, as ``(sequence name, domain)`` pairs."""

    length: int | None
    suite: Suite
    domains: tuple[tuple[str, str], ...]

    def domain_of(self, sequence: str) -> str:
        return dict(self.domains)[sequence]


def transfer_parts(suite: Suite, presets: Sequence[str] = (DEFAULT_CAMERA_EFFECTS,),
                   lengths: Sequence[int | None] | None = None,
                   motions: Sequence[str | Path] = ()) -> list[TransferPart]:
    """The suites the ``transfer`` suite is made of, compared like for like: for each length of ``lengths``
    (default: the transfer suite's ``frames``, the bench length, then whole sequences; ``frames`` None: whole
    only), the ``table1`` suite on its first ``length`` frames through each simulated domain of ``presets`` (a
    camera preset, or one with ``+lit``, :func:`sim_domain`; domain ``sim:<preset>``), with the transfer suite's
    methods and seeds (its runs are ``make bench``'s and ``cnnslam bench table1``'s own); and the ``real`` suite on
    the transfer suite's folder sequences: whole, or cut into non-overlapping windows of ``length`` frames
    (:func:`window_refs`), each window a sample of the real sequence's domain ``real:<name>``. ``motions``: TUM
    trajectory files (real hand-held motion) replayed in the same rooms (:meth:`SequenceRef.with_motion`), each a
    simulated domain ``sim:<preset>~<file stem>`` of its own beside the preset's, so that the motion's share of the
    gap to the real rankings can be told from the images'."""
    if suite.kind != "transfer":
        raise SuiteError(f"suite {suite.name!r} is not a transfer suite")
    labels = [motion_label(m) for m in motions]
    if len(set(labels)) != len(labels):
        raise SuiteError(f"two motion files give the same name ({', '.join(labels)}): rename one")
    if lengths is None:
        lengths = (None,) if suite.frames is None else (suite.frames, None)
    table1 = SUITES["table1"]
    parts = []
    for length in lengths:
        for p in presets:
            camera, lighting = sim_domain(p)
            refs = tuple(r.with_lighting(lighting).with_camera_effects(camera) for r in table1.sequences)
            part = replace(table1, methods=suite.methods, seeds=suite.seeds, sequences=refs, frames=length)
            parts.append(TransferPart(length, part, tuple((r.name, f"sim:{p}") for r in refs)))
            for motion in motions:
                label = motion_label(motion)
                moved = tuple(r.with_motion(motion, label, frames=length) for r in refs)
                part = replace(table1, methods=suite.methods, seeds=suite.seeds, sequences=moved, frames=length)
                parts.append(TransferPart(length, part, tuple((r.name, f"sim:{p}~{label}") for r in moved)))
        refs, domains = [], []
        for ref in suite.sequences:
            windows = (ref,) if length is None else window_refs(ref, length)
            refs += windows
            domains += [(w.name, f"real:{ref.name}") for w in windows]
        real = replace(SUITES["real"], sequences=tuple(refs), skipped=suite.skipped, methods=suite.methods,
                       frames=length, seeds=suite.seeds)  # fmt: skip
        parts.append(TransferPart(length, real, tuple(domains)))
    return parts


def real_suite(path: str | Path | None = None) -> Suite:
    """The ``real`` suite with the folders of the dataset list at ``path`` (default :func:`dataset_list_file`)."""
    return with_real_folders(SUITES["real"], path)


def with_real_folders(suite: Suite, path: str | Path | None = None) -> Suite:
    """``suite`` with every folder of the dataset list (:func:`load_dataset_list`; ``path`` default
    :func:`dataset_list_file`) that is there and of a known layout as its sequences; the others are its ``skipped``
    sequences, with the reason."""
    file = Path(path) if path is not None else dataset_list_file()
    refs, skipped = [], []
    for entry in load_dataset_list(path).values():
        if not entry.path.is_dir():
            skipped.append((entry.name, f"{entry.path} (listed in {file}) is not a folder here"))
            continue
        try:
            detect_layout(entry.path)
        except SimEnvError as exc:
            skipped.append((entry.name, str(exc)))
            continue
        refs.append(entry.ref())
    return replace(suite, sequences=tuple(refs), skipped=tuple(skipped))
