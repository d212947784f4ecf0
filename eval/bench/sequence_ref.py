"""A benchmark sequence as a typed value: :class:`SequenceRef` (a registered simulated sequence, a rotation stress
sequence, a variant of either, or a real RGB-D folder), its one canonical text form (the name results and run
folders carry: ``office0@kinect``, ``office0+lit@hard``, ``office1~fr1_desk@kinect``, ``rot_yaw_30``, a folder's
name), the refs of a folder (:func:`folder_ref`) and of a rotation (:func:`rotation_ref`), windows of a sequence and
the checks of a frame count. A name is resolved to its ref by :mod:`eval.bench.sequence_resolve`.

A simulated sequence is made as a Gymnasium environment by its id (``sim_envs/<name>-v0``) when registered as is,
else as a :class:`~sim_envs.sources.simsource.SimulatedSequence` replayed by ``sim_envs/Replay-v0``.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from eval.errors import SuiteError
from sim_envs.camera import UNDISTORT_MODES, camera_presets
from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import (
    LOADER_VERSION,
    PROCESSING_SIZE,
    RgbdFolder,
    check_size,
    detect_layout,
    folder_fingerprint,
)
from sim_envs.folders.formats import read_tum_trajectory
from sim_envs.motion.trajectories import parse_axes
from sim_envs.scenes.scene import DETAILS, LIGHTINGS
from sim_envs.sequences import (
    SequenceSpec,
    get_sequence,
    gym_id,
    list_sequences,
    rotation_stress_spec,
    split_variants,
)
from sim_envs.source import WINDOW_VERSION, FrameWindow
from sim_envs.sources.frame_cache import CachedFrames, cache_key
from sim_envs.sources.simsource import SimulatedSequence
from sim_envs.sources.variants import VariantSequence

REPLAY_ENV_ID = "sim_envs/Replay-v0"
ROTATION_NAME = re.compile(r"^rot_(?P<axes>[a-z]+(-[a-z]+)*)_(?P<speed>\d+(\.\d+)?)$")
SAFE_NAME = re.compile(r"[^A-Za-z0-9_.+-]")  # what a folder's name may keep in a sequence (and run folder) name
FolderSize = tuple[int, int] | Literal["native"]
# the room variants a simulated sequence name may mark, in name order: field -> (default, valid values)
ROOM_MARKS: dict[str, tuple[str, tuple[str, ...]]] = {"lighting": ("flat", LIGHTINGS), "detail": ("standard", DETAILS)}





def sim_camera_presets() -> list[str]:
    """The camera-effects presets a simulated sequence can be seen through (``--camera`` of simulated sequences);
    disjoint from the calibration presets of real folders (:func:`sim_envs.camera.camera_presets`)."""
    from sim_envs.sensor.camera_effects import camera_effect_presets

    return camera_effect_presets()


# ------------------------------------------------------------------------------------------------ the sequences
@dataclass(frozen=True)
class SequenceRef:
    """A sequence of a suite: a registered one, a rotation stress sequence, a variant of either, or an RGB-D folder.

    name: shown in results (and the run folder's name); base: a registered sequence name; rotation: ``(axes,
    speed_deg_s)`` of :func:`sim_envs.sequences.rotation_stress_spec` (instead of ``base``); overrides:
    :class:`SequenceSpec` fields to replace, as sorted ``(field, value)`` pairs (a mapping is accepted);
    focal_ratio / added_pan_deg_s: see :class:`VariantSequence`; axis / axis_value: the sweep axis and its nominal
    value, for plots. folder (instead of ``base`` or ``rotation``): the absolute path of a real RGB-D folder
    (:class:`sim_envs.folders.datasets.RgbdFolder`), with ``camera`` (a preset name or the path of a camera file; None:
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
        object.__setattr__(self, "size", folder_size(self.size))
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
        simulated source keeps the frames it rendered (:class:`sim_envs.sources.frame_cache.CachedFrames`; same
        bytes) and a folder its delivered RGB images, in ``prepared/`` (:mod:`sim_envs.folders.prepared`; same
        bytes)."""
        if self.start:  # the whole sequence's source (its frames cached as the whole's), windowed
            whole = replace(self, start=0).make_source(renderer, frame_cache)
            return FrameWindow(whole, self.start, name=self.name)
        if self.folder is not None:
            size = None if self.size == "native" else self.size
            prepared = None if frame_cache is None else Path(frame_cache) / "prepared"
            return RgbdFolder(self.folder, self.camera, size=size, depth_scale=self.depth_scale, name=self.name,
                              undistort=self.undistort, prepared=prepared)  # fmt: skip
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
        and a content fingerprint (:func:`sim_envs.folders.datasets.folder_fingerprint`), so a changed folder reruns."""
        if self.folder is not None:
            camera_file = [self.camera] if self.camera and Path(self.camera).is_file() else []
            return {
                "name": self.name,
                "env_id": self.env_id,
                # absent at 0: earlier runs keep their fingerprint; a window names its reader's version (2: the
                # images of frame start + i; 1, unnamed, read frame i's images with start + i's poses)
                **({"start": self.start, "window": WINDOW_VERSION} if self.start else {}),
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
            **({"start": self.start, "window": WINDOW_VERSION} if self.start else {}),
            **({"motion_sha256": _file_sha256(dict(self.overrides)["trajectory_params"])}
               if dict(self.overrides).get("trajectory") == "replay" else {}),  # fmt: skip
        }

    def with_camera_effects(self, preset: str) -> SequenceRef:
        """This simulated sequence seen through the camera-effects preset ``preset``
        (:func:`sim_envs.sensor.camera_effects.camera_effect_presets`), named ``<name>@<preset>`` (its own run folders);
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
        """This simulated sequence in the same room lit otherwise (:data:`sim_envs.scenes.scene.LIGHTINGS`; ``lit``:
        :mod:`sim_envs.scenes.lighting`), named ``<name>+<lighting>`` before any ``+<detail>`` and ``@<camera preset>``
        (its
        own run folders); ``flat`` is the plain name. The trajectory is the same."""
        return self._with_room_mark("lighting", lighting, "light")

    def with_detail(self, detail: str) -> SequenceRef:
        """This simulated sequence in the same room at another detail level (:data:`sim_envs.scenes.scene.DETAILS`;
        ``rich``: clutter and texture detail, :mod:`sim_envs.scenes.scenegen`), named ``<name>+<detail>`` after any
        ``+<lighting>`` and before any ``@<camera preset>`` (its own run folders); ``standard`` is the plain name. The
        trajectory is the same."""
        return self._with_room_mark("detail", detail, "detail")

    def _with_room_mark(self, field: str, value: str, what: str) -> SequenceRef:
        """The room variant ``field`` (:data:`ROOM_MARKS`) set to ``value``; the name printed in the one canonical
        form ``<base>+<lighting>+<detail>@<preset>``, each mark only when it is not the default."""
        if self.folder is not None:
            raise SuiteError(f"sequence {self.name!r} is a folder: its {what} is the real room's")
        default, valid = ROOM_MARKS[field]
        if value not in valid:
            raise SuiteError(f"unknown {field} {value!r}; valid: {', '.join(valid)}")
        overrides = dict(self.overrides)
        base, at, preset = self._camera_suffix()
        marks = {f: overrides.get(f, d) for f, (d, _) in ROOM_MARKS.items()}
        for f, (d, _) in reversed(ROOM_MARKS.items()):  # strip the marks the name carries, last first
            if marks[f] != d and base.endswith(f"+{marks[f]}"):
                base = base[: -len(marks[f]) - 1]
        marks[field] = value
        overrides.pop(field, None)
        if value != default:
            overrides[field] = value
        suffix = "".join(f"+{marks[f]}" for f, (d, _) in ROOM_MARKS.items() if marks[f] != d)
        return replace(self, name=f"{base}{suffix}{at}{preset}", overrides=tuple(overrides.items()))

    def with_motion(self, file: str | Path, label: str | None = None, frames: int | None = None) -> SequenceRef:
        """This simulated sequence's room with a recorded camera motion replayed in it instead of its own
        trajectory (the ``replay`` kind of :mod:`sim_envs.motion.trajectories`: a TUM trajectory ``file``, e.g. real
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
            size=folder_size(size) if size is not None else self.size,
            undistort=undistort if undistort is not None else self.undistort,
        )


def motion_label(path: str | Path) -> str:
    """The name a recorded motion gives its sequences and domain: the file's stem, or its folder's name for a TUM
    RGB-D ``groundtruth.txt`` (every sequence's is called that), made file-safe."""
    path = Path(path)
    stem = path.parent.name if path.stem == "groundtruth" else path.stem
    return SAFE_NAME.sub("_", stem.removeprefix("rgbd_dataset_"))


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
    """An RGB-D folder as a sequence (see :class:`SequenceRef`). Its name: ``name``, else the folder's own name as
    it is (spaces and any letters included: the name of its run folders, and of the folder an external system's
    output for it is looked up in), with only what no name can hold changed: leading dots dropped, characters
    that do not print replaced by ``_``; a short hash of the path appended when the name would be taken for a
    simulated sequence (``office0``, ``rot_yaw_30``, ``office0+lit``, ``office0@kinect``). :class:`SuiteError`
    (one line) when it is not a folder of a known layout."""
    try:
        folder = Path(path).expanduser().resolve()
        detect_layout(folder)
    except (SimEnvError, RuntimeError, OSError) as exc:
        raise SuiteError(f"sequence {os.fspath(path)!r}: {exc}") from None
    if name is None:
        name = "".join(c if c.isprintable() else "_" for c in folder.name).lstrip(".") or "folder"
        if _names_a_simulated_sequence(name):
            name = f"{name}-{_path_tag(folder)}"
    return SequenceRef(
        name,
        folder=str(folder),
        camera=_camera_argument(camera) if camera is not None else None,
        size=size,
        depth_scale=depth_scale,
    )


def _names_a_simulated_sequence(name: str) -> bool:
    """True when ``name`` is, or could be, a simulated sequence's: a registered or rotation stress sequence's name,
    alone or with variant marks (``+lit``), a camera preset (``@kinect``) or a recorded motion (``~fr1_desk``)."""
    plain, at, preset = name.rpartition("@")
    plain = plain if at and preset in sim_camera_presets() else name
    plain = plain.partition("~")[0]
    try:
        plain, _ = split_variants(plain)
    except SimEnvError:
        return False
    return plain in list_sequences("all") or bool(ROTATION_NAME.match(plain))


def parse_image_size(text: str | tuple[int, int] | None) -> FolderSize | None:
    """An image size as options give it: ``"WxH"`` (``"320x240"``), ``"native"``, a ``(W, H)`` pair, or None (the
    default); :class:`SuiteError` naming the text otherwise."""
    if text is None or text == "native" or isinstance(text, tuple):
        return folder_size(text) if isinstance(text, tuple) else text
    try:
        width, height = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise SuiteError(f"--image-size must be WIDTHxHEIGHT (e.g. 320x240) or native, got {text!r}") from None
    return folder_size((width, height))


def folder_size(size: Any) -> FolderSize:
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


def unique_refs(refs: Sequence[SequenceRef]) -> tuple[SequenceRef, ...]:
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


def sequence_length(ref: SequenceRef) -> int:
    """The number of frames of ``ref`` from its first frame: a folder's as its index reads now (the frames that have
    what they need), a simulated sequence's from its definition."""
    if ref.folder is None:
        return max(0, int(ref.spec().n_frames) - int(ref.start))
    source = ref.make_source()
    try:
        return len(source)
    finally:
        source.close()


def check_frames(refs: Sequence[SequenceRef], frames: int | None, lengths: Mapping[str, int] | None = None) -> None:
    """Every sequence of ``refs`` has at least ``frames`` frames (None: whole sequences, nothing to check), so that
    "the first N frames" is what each run reads; :class:`SuiteError` naming the shortest and what is valid
    otherwise. ``lengths``: sequence name -> frames, where already known (:func:`sequence_length` for the rest)."""
    if frames is None:
        return
    known = dict(lengths or {})
    short = [(n, ref.name) for ref in refs
             if (n := known[ref.name] if ref.name in known else sequence_length(ref)) < frames]
    if short:
        n, name = min(short)
        more = f" (and {len(short) - 1} more sequence(s) shorter than {frames})" if len(short) > 1 else ""
        raise SuiteError(f"--frames {frames}: sequence {name!r} has {n} frames{more}; give --frames {n} or less, or "
                         "--frames all (each sequence whole)")  # fmt: skip


def rotation_ref(axes: str, speed_deg_s: float) -> SequenceRef:
    """The rotation stress sequence ``rot_<axes>_<speed>`` (registered ones are used as registered)."""
    names = parse_axes(axes)
    label = "rpy" if names == ("yaw", "pitch", "roll") else "-".join(names)
    name = f"rot_{label}_{float(speed_deg_s):g}"
    if name in list_sequences():
        return SequenceRef(name, base=name)
    return SequenceRef(name, rotation=("+".join(names), float(speed_deg_s)))
