"""The benchmark suites: which sequences, which methods, how many frames, what report and which gate; one
:class:`Suite` object each, registered in :data:`SUITES`.

Sequences are :class:`~eval.bench.sequence_ref.SequenceRef` values (their names, parsing and environments:
:mod:`eval.bench.sequence_ref`); methods are names of the method table (:mod:`eval.bench.methods`).

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
- ``perf``: throughput figures (:mod:`eval.bench.perf`), no agent runs;
- ``real``: every folder of the local dataset list x the paper's methods and the oracle, whole sequences;
- ``transfer``: the paper's methods on the simulated Table-1 analogues (per camera preset) and on the real folders,
  and whether the simulated rankings predict the real ones (:func:`transfer_parts`, :mod:`eval.reports.transfer`);
- ``quick``: a few short sequences x all methods, the CI regression baseline.

Sweep variants (:func:`sweep_sequences`), built with :func:`dataclasses.replace` on the base sequence's spec where
the spec has the parameter, and by :class:`sim_envs.sources.variants.VariantSequence` where it has not:

- texture density: ``SequenceSpec.texture_density`` (the room generator's share of textured surfaces);
- rotation share: the base trajectory with an extra pan (rotation about the camera's y axis) sweeping +-20 deg at a
  set angular speed; the x value is the measured share of the image motion due to rotation
  (:func:`eval.metrics.trajectory.rotation_share`);
- focal mismatch: the test camera's focal lengths set to ``ratio x`` the training camera's
  (:data:`sim_envs.sequences.TRAIN_CAMERA`, NYU) at the same resolution, principal point kept
  (:meth:`sim_envs.camera.Intrinsics.with_focal`); the field of view changes, the images are rendered with it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from enum import StrEnum
from pathlib import Path
from typing import Any, Literal

from eval.bench.methods import load_methods
from eval.bench.sequence_ref import (
    FolderSize,
    SequenceRef,
    motion_label,
    rotation_ref,
    sim_camera_presets,
    unique_refs,
    window_refs,
)
from eval.bench.sequence_resolve import dataset_list_file, load_dataset_list, with_default_camera
from eval.errors import SuiteError
from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import detect_layout
from sim_envs.motion.trajectories import ROTATION_AXES
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS, sweep_effects
from sim_envs.sequences import TABLE1_SEQUENCES, VARIANT_MARKS, split_variants


# --------------------------------------------------------------------------------------------------- the suites
class SuiteKind(StrEnum):
    """What a suite is made of: ``RUNS``, its own runs (one report of :data:`REPORT_LAYOUTS`); ``PERF``, throughput
    probes and no agent runs; ``TRANSFER``, ``LENGTHS``, ``PREPROCESSING``, several parts each run as a plain suite
    (:func:`transfer_parts`, :func:`length_parts`, :func:`preprocessing_parts`) with one report over all of them
    (the table of parts and writers: :data:`eval.bench.benchmark.KINDS`)."""

    RUNS = "runs"
    PERF = "perf"
    TRANSFER = "transfer"
    LENGTHS = "lengths"
    PREPROCESSING = "preprocessing"


# camera presets of the simulated part of the transfer suite (sim_envs.sensor.camera_effects), in report order:
# kinect was made from the 7-Scenes kitchen's image statistics, fr1 from TUM fr1/desk's (results/camera_calibration*.md)
SIM_CAMERA_PRESETS: tuple[str, ...] = ("clean", "kinect", "hard", "fr1")
# the paper's methods, the original ORB-SLAM3 beside our ORB baseline (thirdparty/, out of process), and the oracle:
# the methods whose table in eval/methods.toml says `table1 = true`, in the table's order (defined there only)
TABLE1_METHODS: tuple[str, ...] = tuple(name for name, method in load_methods().items() if method.table1)
# the transfer suite ranks the paper's methods; the oracle is fed ground truth and would win every ranking
TRANSFER_METHODS: tuple[str, ...] = tuple(m for m in TABLE1_METHODS if m != "oracle")
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


# the sweep's camera axes: each camera effect whose stage class declares sweep strengths, alone on the clean camera
# (sim_envs.sensor.camera_stages: a class's effect, sweep_strengths and axis_title; strength 1 = the kinect preset's
# value),
# in the classes' definition order. Live views of the stage classes: a new effect stage is a new axis.
class _SweepAxes(Mapping[str, Any]):
    """Axis name -> value: ``fixed``'s, then each camera effect's ``pick(stage class)`` (read at every access)."""

    def __init__(self, fixed: dict[str, Any], pick: Callable[[type], Any]) -> None:
        self._fixed, self._pick = fixed, pick

    def _now(self) -> dict[str, Any]:
        return {**self._fixed, **{name: self._pick(cls) for name, cls in sweep_effects().items()}}

    def __getitem__(self, axis: str) -> Any:
        return self._now()[axis]

    def __iter__(self) -> Iterator[str]:
        return iter(self._now())

    def __len__(self) -> int:
        return len(self._now())

    def __repr__(self) -> str:
        return repr(self._now())


CAMERA_EFFECT_STRENGTHS: Mapping[str, tuple[float, ...]] = _SweepAxes({}, lambda cls: cls.sweep_strengths)
SWEEP_AXES: Mapping[str, str] = _SweepAxes(
    {"texture": "texture density", "rotation": "share of rotation in the motion",
     "focal": "focal length, test / training camera"},
    lambda cls: cls.axis_title,
)  # fmt: skip


# the report layouts a suite may name (eval.reports.suite_reports writes each); "generic" is the plain per-metric table
REPORT_LAYOUTS: tuple[str, ...] = ("generic", "table1", "rotation", "ablation", "sweep", "quick", "depth_quality")
# the built-in suites' baselines, in the project's own results/ (found from the package, never from the working
# directory: a gate run from another folder compares with the same file)
BASELINE_DIR: Path = Path(__file__).resolve().parents[2] / "results" / "baselines"


@dataclass(frozen=True)
class Suite:
    """A suite: ``sequences`` x ``methods`` (names of the method table) x ``seeds`` (the runs of each cell, see
    ``eval/methods.toml`` for what a seed changes per method), each run on the first ``frames`` frames (None: whole
    sequences); ``alignment`` of the ATE (``slamcommon.alignment``; a method's own ``align`` wins); ``kind``: what
    the suite is made of (:class:`SuiteKind`); ``skipped``: ``(name, reason)`` of sequences it lists but cannot run
    here (a dataset folder that is missing).

    The suite also names what is made of its runs: ``report``, the layout of its report (:data:`REPORT_LAYOUTS`,
    written by :func:`eval.reports.suite_reports.write_report`); ``gated``: ``cnnslam bench`` compares its runs with
    its ``baseline`` file (default ``results/baselines/<name>.json``) unless told not to; ``real_folders``: its
    sequences are the folders of the local dataset list, read when the suite is asked for (:func:`get_suite`).
    Nothing else in the code switches on a suite's name."""

    name: str
    description: str
    sequences: tuple[SequenceRef, ...] = ()
    methods: tuple[str, ...] = ()
    frames: int | None = None
    seeds: tuple[int, ...] = tuple(range(DEFAULT_RUNS))
    alignment: str = "se3"
    kind: SuiteKind = SuiteKind.RUNS
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
        """The gate's baseline file of this suite (``baseline``, or ``results/baselines/<name>.json`` of the project,
        :data:`BASELINE_DIR`; a suite of one's own names its baseline, ``--baseline``)."""
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
        """The suite restricted or changed: ``sequences`` (names of the suite's, or any
        :func:`eval.bench.sequence_resolve.resolve_sequence` name or folder path), ``methods`` (any method names),
        ``frames`` (a number, or ``"all"``: whole sequences), ``seeds``, or ``runs`` N (seeds 0 .. N-1; not with
        ``seeds``);
        ``camera`` and ``size`` for
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
            refs = tuple(own[name] if name in own else with_default_camera(name) for name in named)
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
            sequences=unique_refs(refs),
            methods=tuple(methods) if methods else self.methods,
            frames=self.frames if frames is None else None if frames == "all" else int(frames),
            seeds=tuple(int(s) for s in seeds) if seeds else self.seeds,
            skipped=skipped,
        )

    @property
    def axis_titles(self) -> Mapping[str, str]:
        """The title of each sweep axis (:data:`SWEEP_AXES`, axis name -> title), as the sweep report shows it."""
        return SWEEP_AXES

    def second_references(self) -> dict[str, Path]:
        """Dataset name -> its second reference trajectory (a TUM file: the dataset list's ``reference``), for every
        entry of the dataset list that has one; the reports score the runs of such a sequence against it too.
        :class:`SuiteError` when the list cannot be read."""
        return {n: e.reference for n, e in load_dataset_list().items() if e.reference is not None}

    def selection_note(self) -> str:
        """How this suite's cells differ from the suite as defined (:func:`get_suite`), in words: the sequences and
        methods it leaves out or adds (any frames, seeds or alignment are the same cells); empty when it holds
        exactly the defined suite's sequences and methods, or when its name defines no suite."""
        try:
            defined = get_suite(self.name)
        except SuiteError:
            return ""
        notes = []
        for what, own, theirs in (("sequences", [s.name for s in self.sequences], [s.name for s in defined.sequences]),
                                  ("methods", list(self.methods), list(defined.methods))):  # fmt: skip
            if set(own) == set(theirs):
                continue
            kept = [n for n in own if n in theirs]
            added = [n for n in own if n not in theirs]
            if kept:
                notes.append(f"{len(kept)} of its {len(theirs)} {what} ({', '.join(kept)})")
            if added:
                notes.append(f"{what} not among its {len(theirs)}: {', '.join(added)}")
        return "; ".join(notes)

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
    (:data:`sim_envs.sensor.camera_effects.DEFAULT_CAMERA_EFFECTS`)."""
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
            "perf", "throughput: render fps, CNN ms/frame, tracking and whole-system fps, metrics time",
            kind=SuiteKind.PERF,
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
            kind=SuiteKind.TRANSFER,
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
            kind=SuiteKind.LENGTHS,
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
            kind=SuiteKind.PREPROCESSING,
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


def sim_domain(name: str) -> tuple[str, str, str]:
    """A simulated domain of the transfer report, ``<camera preset>`` with optional room variant marks
    (``kinect+lit``, ``kinect+rich``, ``kinect+lit+rich``: :data:`sim_envs.sequences.VARIANT_MARKS`), as ``(camera
    preset, lighting, detail)``; raises :class:`SuiteError` naming the valid ones."""
    marks = ", ".join(f"+{m}" for m in VARIANT_MARKS)
    error = SuiteError(f"unknown simulated domain {name!r}; valid: a camera preset ({', '.join(SIM_CAMERA_PRESETS)}), "
                       f"optionally with the room marks {marks}, each once (kinect+lit: lamps with shadows; "
                       "kinect+rich: clutter and texture detail)")  # fmt: skip
    try:
        rest, fields = split_variants(name)
    except SimEnvError:
        raise error from None
    if rest not in SIM_CAMERA_PRESETS:
        raise error
    return rest, fields.get("lighting", "flat"), fields.get("detail", "standard")


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
    if suite.kind is not SuiteKind.PREPROCESSING:
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
    if suite.kind is not SuiteKind.LENGTHS:
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
                   lengths: Sequence[int | None] | None = None, motions: Sequence[str | Path] = (),
                   sim_sequences: Sequence[str] | None = None) -> list[TransferPart]:
    """The suites the ``transfer`` suite is made of, compared like for like: for each length of ``lengths`` (default:
    the transfer suite's ``frames``, the bench length, then whole sequences; ``frames`` None: whole only), the
    ``table1`` suite on its first ``length`` frames through each simulated domain of ``presets`` (a camera preset,
    maybe with room marks ``+lit`` / ``+rich``, :func:`sim_domain`; domain ``sim:<preset>``), with the transfer
    suite's methods and seeds (its runs are ``make bench``'s and ``cnnslam bench table1``'s own); and the ``real``
    suite on the transfer suite's folder sequences: whole, or cut into non-overlapping windows of ``length`` frames
    (:func:`window_refs`), each window a sample of the real sequence's domain ``real:<name>``. ``motions``: TUM
    trajectory files (real hand-held motion) replayed in the same rooms (:meth:`SequenceRef.with_motion`), each a
    simulated domain ``sim:<preset>~<file stem>`` of its own beside the preset's, so that the motion's share of the
    gap to the real rankings can be told from the images'. Where a real folder gives w > 1 windows of a length, each
    simulated sequence's first w windows of that length are run too (domain ``win:<preset>``): the like-for-like
    null distribution of :func:`eval.reports.transfer.null_agreement` (one simulated recording, cut as the real one
    is, against the simulated domain). ``sim_sequences``: registered simulated sequences to run instead of the Table-1
    analogues (e.g. :data:`sim_envs.sequences.FR1_MOTION_SEQUENCES`, moving as TUM fr1/desk's camera does)."""
    if suite.kind is not SuiteKind.TRANSFER:
        raise SuiteError(f"suite {suite.name!r} is not a transfer suite")
    labels = [motion_label(m) for m in motions]
    if len(set(labels)) != len(labels):
        raise SuiteError(f"two motion files give the same name ({', '.join(labels)}): rename one")
    if lengths is None:
        lengths = (None,) if suite.frames is None else (suite.frames, None)
    table1 = SUITES["table1"]
    if sim_sequences is not None:
        table1 = replace(table1, sequences=tuple(_named(name) for name in sim_sequences))
    parts = []
    for length in lengths:
        refs, domains = [], []
        for ref in suite.sequences:
            windows = (ref,) if length is None else window_refs(ref, length)
            refs += windows
            domains += [(w.name, f"real:{ref.name}") for w in windows]
        per_recording = max((sum(1 for _, d in domains if d == f"real:{r.name}") for r in suite.sequences), default=0)
        for p in presets:
            camera, lighting, detail = sim_domain(p)
            sims = tuple(r.with_lighting(lighting).with_detail(detail).with_camera_effects(camera)
                         for r in table1.sequences)
            part = replace(table1, methods=suite.methods, seeds=suite.seeds, sequences=sims, frames=length)
            parts.append(TransferPart(length, part, tuple((r.name, f"sim:{p}") for r in sims)))
            if length is not None and per_recording > 1:  # the null, like for like: as many windows per recording
                wins = tuple(w for r in sims for w in window_refs(r, length)[:per_recording])
                part = replace(table1, methods=suite.methods, seeds=suite.seeds, sequences=wins, frames=length)
                parts.append(TransferPart(length, part, tuple((w.name, f"win:{p}") for w in wins)))
            for motion in motions:
                label = motion_label(motion)
                moved = tuple(r.with_motion(motion, label, frames=length) for r in sims)
                part = replace(table1, methods=suite.methods, seeds=suite.seeds, sequences=moved, frames=length)
                parts.append(TransferPart(length, part, tuple((r.name, f"sim:{p}~{label}") for r in moved)))
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
