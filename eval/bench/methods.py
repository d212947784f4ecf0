"""The method table: what each benchmark method is (an agent entry point with keyword arguments, or a folder of a
third-party system's output), which metric groups apply to it, and a check that it can run here.

The table itself is data, :file:`eval/methods.toml` (the judge names agents by ``"module:Class"`` strings and never
imports the agents' package; see that file for the fields). A user adds a method by adding a table there or by
passing another file of the same shape (:func:`load_methods`).

Two kinds of method:

- ``agent``: an agent of :mod:`sim_envs.agent` run in the environment of each sequence by :mod:`eval.bench.run`;
- ``external``: a third-party SLAM system that ran on an exported sequence (``cnnslam export``, ``cnnslam generate
  rotation --export``) and wrote, per sequence, a TUM trajectory and optionally depth maps into a folder
  (:func:`external_method`; layout in :data:`EXTERNAL_LAYOUT`). Its output is scored exactly like an agent's.

Metric groups (:data:`METRIC_GROUPS`): ``trajectory`` (ATE, rotation error, RPE, scale, path lengths, tracked share),
``depth`` (percentage of correct depth, density, AbsRel, RMSE, delta < 1.25, key-frame count), ``semantic`` (pixel
accuracy, IoU), ``map`` (the global model's accuracy, completeness and fused-label accuracy,
:mod:`eval.metrics.map_metrics`; for agents that hand back a model). ``frames`` is always kept. A method without the
``trajectory`` group (REMODE, which runs on LSD-BS poses) gets no ATE column, as in the paper's Table 1.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from eval.bench.fingerprint import agent_modules, source_sha256  # source_sha256: beside the closures it hashes
from eval.errors import InputError
from eval.metrics import catalogue
from eval.metrics.runs import GROUP_ABSENT, METRIC_GROUPS, metric_group  # noqa: F401  (the judge's groups)
from slamcommon.alignment import AlignmentMethod

MethodKind = Literal["agent", "external"]
METHOD_KINDS: tuple[str, ...] = get_args(MethodKind)
# what a method's agent is given (Method.input): "harness" = the frames as the suite delivers them (a folder's
# undistorted by the harness and resized to the suite's size, 320x240 by default); "native" = a folder's frames at
# the images' own size, not undistorted, the lens distortion handed to the agent (sim_envs.agent's
# takes_distortion), which undistorts them itself; a simulated sequence as rendered either way (pinhole, its size)
MethodInput = Literal["harness", "native"]
METHOD_INPUTS: tuple[str, ...] = get_args(MethodInput)
METHODS_FILE: Path = Path(__file__).resolve().parents[1] / "methods.toml"  # eval/methods.toml, data beside code

ALWAYS_KEPT: tuple[str, ...] = (catalogue.FRAMES.key,)
# wall-clock figures: kept apart from the metrics (not deterministic, never compared by the gate)
TIMING_METRICS: tuple[str, ...] = catalogue.keys("timing")

_OWN = catalogue.WALL_S.key  # the external layout's run.toml key: the run's wall seconds
EXTERNAL_LAYOUT = f"""\
FOLDER/<sequence>/trajectory.txt     TUM trajectory (timestamp tx ty tz qx qy qz qw), the exported timestamps
FOLDER/<sequence>.txt                (alternative to the above)
FOLDER/<sequence>/depth/<t>.png      optional key-frame depth, 16-bit PNG, 5000 = 1 m (TUM), t = the timestamp
FOLDER/<sequence>/depth/<t>.npy      optional key-frame depth, (H, W) float32 metres, 0 = no estimate
FOLDER/<sequence>/run.toml           optional: {_OWN} = the system's own run time on the sequence (seconds)
FOLDER/method.toml                   optional: sensor = "mono" | "rgbd" | "stereo"; uses_ground_truth = ["depth",
                                     "scale", "poses"] (what it was fed); align = "se3" | "sim3" (its ATE)"""

_FILE_SAFE = re.compile(r"[^A-Za-z0-9._+-]+")


DEFAULT_COST_MS = 30.0  # a method's scheduling cost when its table gives none (ms per frame, about CNN-SLAM's)


class MethodError(InputError):
    """A method definition or choice that cannot be used (a bad table, an unknown name, a setting its configuration
    does not take)."""


@dataclass(frozen=True)
class Method:
    """One benchmark method.

    name: shown in results; kind: "agent" or "external"; entry_point: ``"module:Class"`` (agents); kwargs: the
    agent's keyword arguments as sorted ``(name, value)`` pairs (a mapping is accepted); seed: where a run's seed
    goes (see :meth:`agent_kwargs`): one target or a tuple of targets (a list is accepted), None when the agent takes
    none; metrics: metric groups reported; paper: the
    method's column in the paper's Table 1, if any; description: one line; folder: the output folder (external);
    inputs: files the agent reads whose contents determine its results (network weights, vocabularies): their
    SHA-256 enters a run's fingerprint (:meth:`input_hashes`), so a finished run is not reused after they change.
    An input is ``"package:path/inside/it"`` (found without importing the package) or a file path. align: the
    trajectory alignment of the method's headline ATE (``se3``, ``sim3``, ...; None: the suite's); sensor: ``mono``,
    ``rgbd`` or ``stereo``; uses_ground_truth: what ground truth an external system declares it used (``depth``,
    ``scale``, ``poses``). cost: about how many milliseconds a frame of the method takes in a suite on a 2-core
    machine, for scheduling only (a suite starts its longest runs first, :func:`eval.bench.runner.run_order`); not
    part of a run's fingerprint. preload: modules a run of the method imports late (the network's, and torch with it)
    that a suite's fork server imports once ahead of the runs (:mod:`eval.bench.executors`), so that no run pays
    the import (1-2 s); names, never imported by the judge itself; not part of a run's fingerprint. table1: whether
    the Table-1 suite (and the suites built on its methods) runs the method (:data:`eval.bench.suites.TABLE1_METHODS`,
    in the table's order). warmup: which part of the agents' install-time numba warm-up runs it (``"baselines"`` or
    ``"system"``; the agents' package reads it from the table file, the judge does nothing with it). input: what the
    agent is given (:data:`METHOD_INPUTS`: ``harness``, the suite's frames, or ``native``, a folder's frames at
    their own size with their lens distortion, :meth:`given_sequence`).
    """

    name: str
    kind: MethodKind = "agent"
    entry_point: str | None = None
    kwargs: tuple[tuple[str, Any], ...] = ()
    seed: str | tuple[str, ...] | None = None
    metrics: tuple[str, ...] = ("trajectory", "depth")
    paper: str | None = None
    description: str = ""
    folder: str | None = None
    inputs: tuple[str, ...] = ()
    align: str | None = None
    sensor: str = "mono"
    uses_ground_truth: tuple[str, ...] = ()
    cost: float = DEFAULT_COST_MS
    preload: tuple[str, ...] = ()
    table1: bool = False
    warmup: str | None = None
    input: MethodInput = "harness"

    def __post_init__(self) -> None:
        if self.input not in METHOD_INPUTS:
            raise MethodError(f"method {self.name!r}: input must be one of {', '.join(METHOD_INPUTS)} (harness: the "
                              "suite's frames; native: a folder's own size and lens, undistorted by the method), got "
                              f"{self.input!r}")
        if self.input != "harness" and self.kind == "external":
            raise MethodError(f"method {self.name!r}: input = {self.input!r} is for agents; an external system's "
                              "output was made from whatever it read")
        if not isinstance(self.table1, bool) or not isinstance(self.warmup, str | None):
            raise MethodError(f"method {self.name!r}: table1 is true or false and warmup a string, got "
                              f"{self.table1!r} and {self.warmup!r}")
        object.__setattr__(self, "preload", tuple(str(m) for m in self.preload))
        bad_modules = [m for m in self.preload if not re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*", m)]
        if bad_modules:
            raise MethodError(f"method {self.name!r}: preload names modules ('package.module'), got {bad_modules}")
        if isinstance(self.cost, bool) or not isinstance(self.cost, int | float) or not self.cost > 0:
            raise MethodError(f"method {self.name!r}: cost must be a positive number of milliseconds per frame, "
                              f"got {self.cost!r}")
        object.__setattr__(self, "cost", float(self.cost))
        kwargs = self.kwargs
        items = kwargs.items() if isinstance(kwargs, Mapping) else kwargs
        object.__setattr__(self, "kwargs", tuple(sorted((str(k), _freeze(v)) for k, v in items)))
        object.__setattr__(self, "metrics", tuple(self.metrics))
        object.__setattr__(self, "inputs", tuple(str(i) for i in self.inputs))
        if isinstance(self.seed, list | tuple):
            object.__setattr__(self, "seed", tuple(str(t) for t in self.seed) or None)
        object.__setattr__(self, "uses_ground_truth", tuple(str(g) for g in self.uses_ground_truth))
        if self.sensor not in SENSORS:
            raise MethodError(f"method {self.name!r}: sensor must be one of {SENSORS}, got {self.sensor!r}")
        bad_gt = [g for g in self.uses_ground_truth if g not in GROUND_TRUTH_KINDS]
        if bad_gt:
            raise MethodError(f"method {self.name!r}: uses_ground_truth {bad_gt} not among {GROUND_TRUTH_KINDS}")
        if self.align is not None and self.align not in ALIGNMENTS:
            raise MethodError(f"method {self.name!r}: align must be one of {ALIGNMENTS}, got {self.align!r}")
        if not self.name or _FILE_SAFE.sub("", self.name) == "":
            raise MethodError(f"a method needs a name with at least one letter or digit, got {self.name!r}")
        if self.kind not in METHOD_KINDS:
            raise MethodError(f"method {self.name!r}: kind must be one of {METHOD_KINDS}, got {self.kind!r}")
        bad = [g for g in self.metrics if g not in METRIC_GROUPS]
        if bad or not self.metrics:
            raise MethodError(
                f"method {self.name!r}: unknown metric group(s) {bad or '(none given)'}; "
                f"valid: {', '.join(METRIC_GROUPS)}"
            )
        if self.kind == "agent":
            module, sep, attr = (self.entry_point or "").partition(":")
            if not (module and sep and attr):
                raise MethodError(
                    f"method {self.name!r}: entry_point must look like 'package.module:Class', got {self.entry_point!r}"
                )
        elif not self.folder:
            raise MethodError(f"external method {self.name!r} needs the folder holding its output")
        for target in self.seed_targets:
            if not re.fullmatch(r"[A-Za-z_]\w*(\.[^.\s]+(\.[^.\s]+)*)?", target):
                raise MethodError(f"method {self.name!r}: a seed target is 'keyword' or 'keyword.key', got {target!r}")

    @property
    def seed_targets(self) -> tuple[str, ...]:
        """Where a run's seed goes, as a tuple (empty: the agent takes none)."""
        if self.seed is None:
            return ()
        return (self.seed,) if isinstance(self.seed, str) else tuple(self.seed)

    @property
    def slug(self) -> str:
        """The name made safe for a folder name."""
        return _FILE_SAFE.sub("_", self.name).strip("_")

    def agent_kwargs(self, seed: int | None = None) -> dict[str, Any]:
        """The agent's keyword arguments, with ``seed`` put where each of :attr:`seed_targets` says
        (``"config.system.seed"``: ``kwargs["config"]["system.seed"] = seed``, merged into a config dict already
        given)."""
        kwargs = {k: thaw(v) for k, v in self.kwargs}
        if seed is None:
            return kwargs
        for target in self.seed_targets:
            keyword, _, key = target.partition(".")
            if not key:
                kwargs[keyword] = int(seed)
                continue
            inner = kwargs.get(keyword) or {}
            if not isinstance(inner, dict):
                raise MethodError(f"method {self.name!r}: seed goes into {keyword!r}, which is {inner!r}, not a dict")
            kwargs[keyword] = {**inner, key: int(seed)}
        return kwargs

    def given_sequence(self, ref: Any) -> Any:
        """The sequence as this method's agent is given it: ``ref`` (an :class:`eval.bench.sequence_ref.SequenceRef`)
        itself, or with ``input = "native"`` a folder sequence at the images' own size and not undistorted (same
        name: its runs stay in the suite's cells)."""
        if self.input == "native" and getattr(ref, "folder", None) is not None:
            return replace(ref, size="native", undistort="none")
        return ref

    def input_hashes(self) -> dict[str, str]:
        """``{input: sha256 hex}`` of :attr:`inputs` (see :func:`resolve_input`)."""
        return {name: _file_sha256(resolve_input(name, self.name)) for name in self.inputs}

    def source_hashes(self) -> dict[str, str]:
        """``{top-level package: sha256 hex}`` of the agent's own source: for each module the agent is built from
        (its entry point's, and that of every ``"module:Class"`` string among its keyword arguments: a wrapping agent
        names the agent it wraps), the files of its import closure (:func:`source_sha256`), keyed by the module's
        top-level package. Editing a file the agent imports thus redoes its runs; editing another method's files does
        not. External methods: none (their output files are read afresh every run)."""
        tops: dict[str, list[str]] = {}
        for module in agent_modules(self):
            tops.setdefault(module.split(".")[0], []).append(module)
        out = {}
        for top, modules in tops.items():
            digests = [d for m in modules if (d := source_sha256(m)) is not None]
            if digests:
                out[top] = digests[0] if len(digests) == 1 else hashlib.sha256("".join(digests).encode()).hexdigest()
        return out

    def keeps(self, metric: str) -> bool:
        """Whether the metric (a flat name of :mod:`eval.metrics.results`) belongs to one of the method's groups."""
        if metric in ALWAYS_KEPT:
            return True
        return metric_group(metric) in self.metrics

    def select_metrics(self, metrics: Mapping[str, float]) -> dict[str, float]:
        """The metrics that apply to this method (its groups), timing figures left out."""
        return {k: v for k, v in metrics.items() if k not in TIMING_METRICS and self.keeps(k)}

    def describe(self) -> dict[str, Any]:
        """JSON-ready description (for run metadata and listings)."""
        return {
            "name": self.name,
            "kind": self.kind,
            "entry_point": self.entry_point,
            "kwargs": {k: thaw(v) for k, v in self.kwargs},
            "seed": self.seed,
            "metrics": list(self.metrics),
            "paper": self.paper,
            "folder": self.folder,
            "inputs": list(self.inputs),
            "align": self.align,
            "sensor": self.sensor,
            "uses_ground_truth": list(self.uses_ground_truth),
            **({"input": self.input} if self.input != "harness" else {}),  # harness: as before the field
        }


def resolve_input(name: str, method: str = "?") -> Path:
    """The file of a method input: ``"package:relative/path"`` inside a top-level package's folder (located with
    :func:`importlib.util.find_spec`, which does not import it), else ``name`` as a path. Raises
    :class:`MethodError` when it is not a readable file."""
    package, sep, rel = name.partition(":")
    path = Path(name)
    if sep and package.isidentifier() and rel:
        spec = importlib.util.find_spec(package)
        roots = list(spec.submodule_search_locations or []) if spec else []
        if not roots:
            raise MethodError(f"method {method!r}: input {name!r} names package {package!r}, which is not installed")
        path = Path(roots[0]) / rel
    if not path.is_file():
        raise MethodError(
            f"method {method!r}: input {name!r} is not a file ({path}); inputs are 'package:path' or a file path"
        )
    return path


_HASHES: dict[tuple[str, int, int], str] = {}


def _file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, remembered per (path, size, mtime) so a suite hashes its weights once."""
    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _HASHES:
        _HASHES[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _HASHES[key]


def _freeze(value: Any) -> Any:
    """Dicts become sorted pair tuples and lists tuples, so a method stays hashable."""
    if isinstance(value, Mapping):
        return ("__dict__", tuple(sorted((str(k), _freeze(v)) for k, v in value.items())))
    if isinstance(value, list | tuple):
        return tuple(_freeze(v) for v in value)
    return value


def thaw(value: Any) -> Any:
    if isinstance(value, tuple) and len(value) == 2 and value[0] == "__dict__":
        return {k: thaw(v) for k, v in value[1]}
    if isinstance(value, tuple):
        return [thaw(v) for v in value]
    return value


# ------------------------------------------------------------------------------------------------------ the table
_FIELDS = {"entry_point", "kwargs", "seed", "metrics", "paper", "description", "kind", "folder", "inputs", "align",
           "sensor", "uses_ground_truth", "cost", "preload", "table1", "warmup", "input"}
_STRING_FIELDS = ("entry_point", "paper", "description", "kind", "folder", "align", "sensor", "input")
_LIST_FIELDS = ("metrics", "inputs", "uses_ground_truth", "preload")
_FIELD_KINDS = {**dict.fromkeys(_STRING_FIELDS, "a string"), **dict.fromkeys(_LIST_FIELDS, "a list of strings"),
                "seed": "a string or a list of strings", "kwargs": "a table", "cost": "a number",
                "table1": "true or false", "warmup": "a string"}  # fmt: skip


def _strings(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


_FIELD_TYPES: dict[str, Any] = {
    **dict.fromkeys(_STRING_FIELDS, lambda v: isinstance(v, str)),
    **dict.fromkeys(_LIST_FIELDS, _strings),
    "seed": lambda v: isinstance(v, str) or _strings(v),
    "kwargs": lambda v: isinstance(v, Mapping),
    "cost": lambda v: isinstance(v, int | float) and not isinstance(v, bool),
    "table1": lambda v: isinstance(v, bool),
    "warmup": lambda v: isinstance(v, str),
}  # what the value of each field of a method table must be (checked before the Method is made)
SENSORS: tuple[str, ...] = ("mono", "rgbd", "stereo")
GROUND_TRUTH_KINDS: tuple[str, ...] = ("depth", "scale", "poses")
ALIGNMENTS: tuple[str, ...] = tuple(m.value for m in AlignmentMethod)
EXTERNAL_SIDE_FILE = "method.toml"  # FOLDER/method.toml: what an external system declares about itself
RUN_SIDE_FILE = "run.toml"  # FOLDER/<sequence>/run.toml: its own run time in seconds (EXTERNAL_LAYOUT)


def parse_methods(data: Mapping[str, Any], source: str = "<methods>") -> dict[str, Method]:
    """Methods of a parsed table (``{"methods": {name: {...}}}``), in file order."""
    table = data.get("methods")
    if not isinstance(table, Mapping) or not table:
        raise MethodError(f"{source}: expected a non-empty [methods.<name>] table")
    methods: dict[str, Method] = {}
    for name, entry in table.items():
        if not isinstance(entry, Mapping):
            raise MethodError(f"{source}: methods.{name} must be a table")
        unknown = sorted(set(entry) - _FIELDS)
        if unknown:
            raise MethodError(f"{source}: methods.{name} has unknown field(s) {unknown}; valid: {sorted(_FIELDS)}")
        for key, value in entry.items():
            if not _FIELD_TYPES[key](value):
                raise MethodError(f"{source}: methods.{name}.{key} = {value!r}; {key} is {_FIELD_KINDS[key]}")
        try:
            methods[name] = Method(name=name, **dict(entry))
        except MethodError as exc:
            raise MethodError(f"{source}: {exc}") from exc
        except (TypeError, ValueError) as exc:  # a value of the wrong type for its field
            raise MethodError(f"{source}: methods.{name}: {exc}") from exc
    return methods


def load_methods(path: str | Path | None = None) -> dict[str, Method]:
    """The method table of ``path`` (default :data:`METHODS_FILE`), name -> :class:`Method`, in file order."""
    path = Path(path) if path is not None else METHODS_FILE
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise MethodError(f"{path}: cannot read the method table: {exc.strerror or exc}") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MethodError(f"{path}: not valid TOML: {exc}") from exc
    return parse_methods(data, str(path))


def merge_methods(base: Mapping[str, Method], extra: Mapping[str, Method], source: str = "<methods>",
                  override: bool = False) -> dict[str, Method]:
    """``base`` plus ``extra``; a name of ``extra`` already in ``base`` is an error unless ``override`` (a user's
    method silently replacing a built-in one would sit beside the paper's numbers under the built-in's name)."""
    clash = [name for name in extra if name in base]
    if clash and not override:
        raise MethodError(
            f"{source} redefines the method(s) {', '.join(clash)} of the built-in table; give them other names, or "
            "pass --override to replace the built-in definitions"
        )
    return {**base, **extra}


def get_method(name: str, table: Mapping[str, Method] | None = None) -> Method:
    """A method by name; :class:`MethodError` listing the valid names otherwise."""
    table = load_methods() if table is None else table
    try:
        return table[name]
    except KeyError:
        raise MethodError(f"unknown method {name!r}; valid methods: {', '.join(table)}") from None


def external_method(name: str, folder: str | Path, metrics: Sequence[str] = ("trajectory", "depth")) -> Method:
    """A third-party system's output in ``folder`` (layout: :data:`EXTERNAL_LAYOUT`) as a method named ``name``.

    ``folder/method.toml`` (optional) declares what the system is: ``sensor`` (mono / rgbd / stereo),
    ``uses_ground_truth`` (a list of depth / scale / poses), ``align`` (the ATE alignment its headline figure takes,
    e.g. ``sim3`` for a monocular system without metric scale), ``description``."""
    side: dict[str, Any] = {}
    path = Path(folder) / EXTERNAL_SIDE_FILE
    if path.is_file():
        try:
            side = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise MethodError(f"{path}: not valid TOML: {exc}") from exc
        unknown = sorted(set(side) - {"sensor", "uses_ground_truth", "align", "description"})
        if unknown:
            raise MethodError(f"{path}: unknown field(s) {unknown}; valid: align, description, sensor, "
                              "uses_ground_truth")
        used = side.get("uses_ground_truth", [])
        if not (isinstance(used, list) and all(isinstance(g, str) for g in used)) or not all(
                isinstance(side.get(k, ""), str) for k in ("sensor", "align", "description")):  # fmt: skip
            raise MethodError(f"{path}: sensor, align and description are strings, uses_ground_truth a list of "
                              f"them; got {side!r}")  # fmt: skip
    try:
        return Method(
            name=name,
            kind="external",
            folder=str(Path(folder).resolve()),
            metrics=tuple(metrics),
            description=str(side.get("description", f"external system, output read from {folder}")),
            align=side.get("align"),
            sensor=side.get("sensor", "mono"),
            uses_ground_truth=tuple(side.get("uses_ground_truth", ())),
        )
    except MethodError as exc:
        raise MethodError(f"{path}: {exc}" if side else str(exc)) from exc


def parse_external(text: str) -> Method:
    """``NAME=FOLDER`` (the ``--external`` option) as an external method."""
    name, sep, folder = text.partition("=")
    if not sep or not name.strip() or not folder.strip():
        raise MethodError(f"--external takes NAME=FOLDER, got {text!r}")
    return external_method(name.strip(), folder.strip())


def method_table(method_file: str | Path | None = None, externals: Sequence[str] = (),
                 override: bool = False) -> dict[str, Method]:
    """The methods a benchmark may name: the built-in table (:data:`METHODS_FILE`), plus the methods of
    ``method_file`` and the ``NAME=FOLDER`` ``externals`` (:func:`parse_external`); a name of the built-in table
    redefined is an error unless ``override`` (:func:`merge_methods`)."""
    table = load_methods()
    if method_file is not None:
        table = merge_methods(table, load_methods(method_file), str(method_file), override)
    added = {m.name: m for m in (parse_external(text) for text in externals)}
    return merge_methods(table, added, "--external", override)


# ------------------------------------------------------------------------------------------------ availability
@dataclass(frozen=True)
class EntryPointProblem:
    """Why an agent method's entry point cannot be loaded (:func:`entry_point_problem`): ``reason`` (one line) and
    whether it is ``optional``: the method's own module is there but imports a package this machine lacks (a
    third-party system whose package is not installed: ORB-SLAM3 without ``pyorbslam3``, Open3D), as opposed to a
    broken definition (its module not found, a misspelt class, a module that raises on import)."""

    reason: str
    optional: bool


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def entry_point_problem(method: Method) -> EntryPointProblem | None:
    """None when the agent method's module imports and has its class (external methods: always None); else what is
    wrong, without building the agent. A :class:`ModuleNotFoundError` for the entry point's own module (or a package
    above it) is a broken definition (a typo in ``"module:Class"``, or its folder not on the Python path), as is a
    missing attribute (with the module's names closest to it) and any other exception raised on import; an
    ImportError for anything else is a package this machine lacks (``optional``)."""
    if method.kind != "agent":
        return None
    entry = method.entry_point or ""
    module_name, _, attr = entry.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if missing and (module_name == missing or module_name.startswith(missing + ".")):
            return EntryPointProblem(f"method {method.name!r}: no module {module_name!r} to import (entry point "
                                     f"{entry!r}): check its spelling and that its folder is on the Python path "
                                     "(PYTHONPATH)", optional=False)  # fmt: skip
        return EntryPointProblem(f"cannot import {module_name!r}: {type(exc).__name__}: {_one_line(exc)}", True)
    except ImportError as exc:
        return EntryPointProblem(f"cannot import {module_name!r}: {type(exc).__name__}: {_one_line(exc)}", True)
    except Exception as exc:  # noqa: BLE001 - a module that raises on import is a broken method, named with its error
        return EntryPointProblem(f"method {method.name!r}: importing {module_name!r} raises {type(exc).__name__}: "
                                 f"{_one_line(exc)}", optional=False)  # fmt: skip
    if getattr(module, attr, None) is None:
        import difflib

        names = [n for n in dir(module) if not n.startswith("_")]
        close = difflib.get_close_matches(attr, names, n=3)
        hint = f"did you mean {' or '.join(repr(f'{module_name}:{c}') for c in close)}?" if close else \
            f"its names: {', '.join(n for n in names if n[:1].isupper())[:200] or '(none)'}"
        return EntryPointProblem(f"method {method.name!r}: module {module_name!r} has no {attr!r} (entry point "
                                 f"{entry!r}); {hint}", optional=False)  # fmt: skip
    return None


def check_available(method: Method, build: bool = True) -> str | None:
    """None when the method can run here, else a one-line reason.

    Agents: the entry point's module imports and has the attribute; with ``build``, the agent is also built with
    its keyword arguments, reset for a 320x240 camera and stepped once on a synthetic image (:func:`_smoke_test`:
    this loads a network's weights, so a missing weights file is found before any run starts); its ``inputs`` are
    readable files. Only what this machine lacks makes a reason (an ImportError or OSError: a module, a library, a
    file): an agent that is there and raises anything else is no method that "cannot run here" but a broken one,
    and its runs fail, each with its error, in the report's failure table. External: the folder exists.
    """
    if method.kind == "external":
        folder = Path(method.folder or "")
        return None if folder.is_dir() else f"the output folder {folder} does not exist"
    module_name, _, attr = (method.entry_point or "").partition(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001 - any import failure makes the method unavailable, with its reason
        return f"cannot import {module_name!r}: {type(exc).__name__}: {exc}"
    factory = getattr(module, attr, None)
    if factory is None:
        return f"module {module_name!r} has no attribute {attr!r}"
    try:
        method.input_hashes()  # a missing input file is a reason to skip, not a crash while planning the runs
    except MethodError as exc:
        return str(exc)
    if not build:
        return None
    try:
        _smoke_test(factory(**method.agent_kwargs(0)))
    except (ImportError, OSError) as exc:  # a module, library or file this machine lacks: it cannot run here
        return f"cannot run {method.entry_point} with {method.agent_kwargs(0)}: {type(exc).__name__}: {exc}"
    except Exception:  # noqa: BLE001 - an agent that runs here and fails: its runs fail, each with its error
        return None
    return None


def _smoke_test(agent: Any) -> None:
    """Reset ``agent`` for a 320x240 camera, step it once on a fixed random image (with a plausible ``info`` for an
    agent that declares ``uses_ground_truth``), then let it finish. Raises whatever the agent raises."""
    h, w = 240, 320
    intrinsics = np.array([0.75 * w, 0.75 * w, (w - 1) / 2, (h - 1) / 2])
    rng = np.random.default_rng(0)
    observation = {
        "rgb": rng.integers(0, 256, (h, w, 3), dtype=np.uint8),
        "timestamp": np.zeros(1),
        "intrinsics": intrinsics.copy(),
    }
    agent.reset(intrinsics.copy(), (h, w))
    if getattr(agent, "uses_ground_truth", False):
        info = {
            "frame_index": 0,
            "timestamp": 0.0,
            "gt_T_world_cam": np.eye(4),
            "gt_depth": np.full((h, w), 2.0, dtype=np.float32),
            "gt_labels": np.zeros((h, w), dtype=np.uint8),
        }
        agent.step(observation, info)
    else:
        agent.step(observation)
    agent.finish()


@dataclass(frozen=True)
class MethodCheck:
    """Which of a suite's methods can run (``available``) and why the others cannot (``skipped``: name -> reason)."""

    available: tuple[Method, ...]
    skipped: dict[str, str] = field(default_factory=dict)


def check_methods(methods: Sequence[Method], build: bool = True) -> MethodCheck:
    """Split ``methods`` into those that can run and those skipped (with the reason)."""
    ok: list[Method] = []
    skipped: dict[str, str] = {}
    for method in methods:
        reason = check_available(method, build)
        if reason is None:
            ok.append(method)
        else:
            skipped[method.name] = reason
    return MethodCheck(tuple(ok), skipped)
