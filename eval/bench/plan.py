"""The benchmark's options and everything :func:`eval.bench.run_bench` checks before its first run: the options
(:class:`BenchOptions`, :class:`ExecutorOptions`), what each kind of suite is made of and how it is reported
(:data:`KINDS`), and :func:`prepare`, which checks a call's suite, methods, settings, sequences, numbers and output
folders and plans it (:class:`BenchPlan`), raising :class:`~eval.errors.InputError` with one line before anything
runs. :mod:`eval.bench.benchmark` runs the plan; the module docstring there lists the checks in order.
"""

from __future__ import annotations

import hashlib
import json
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from eval.bench.executors import EXECUTORS, Executor, ExecutorError, check_alarm, make_executor
from eval.bench.method_settings import apply_settings, parse_setting
from eval.bench.methods import Method, MethodError, entry_point_problem, load_methods
from eval.bench.regress import GateAction
from eval.bench.run import DONE_FILE
from eval.bench.run_store import run_folder
from eval.bench.runner import UNKNOWN_LENGTH, SuiteRun, plan_runs
from eval.bench.sequence_ref import check_frames, parse_image_size
from eval.bench.suites import (
    PREPROCESSING_CHOICES,
    SWEEP_LENGTHS,
    Suite,
    SuiteKind,
    get_suite,
    length_parts,
    preprocessing_parts,
    sim_domain,
    transfer_parts,
)
from eval.errors import InputError, SuiteError
from eval.reports.style import FIGURE_FORMATS
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
from slamcommon.errors import ProjectError
from slamcommon.output_paths import OutputPathError, check_output_folder

log = logging.getLogger("eval.bench.benchmark")  # the benchmark's progress lines (cnnslam bench prints them)


DEFAULT_JOBS = 2  # runs in parallel: one per core of the 2-core machines the suites are sized for
DEFAULT_RESULTS = Path("results")  # a suite as defined writes here (relative to the working folder, as --results is)
# the repository's committed tables: the folder beside the installed eval package (eval/bench/plan.py -> the
# repository root), resolved, so that no working folder or relative --results walks around the guard
COMMITTED_RESULTS = Path(__file__).resolve().parents[2] / "results"
# The default time limit of a run when none is given (--timeout): TIMEOUT_PER_FRAME_S seconds per frame of the
# longest run planned, at least TIMEOUT_MIN_S. Sized so that no committed run comes near it: the slowest measured
# per-frame time is COLMAP's, 0.38 s a frame (60 frames of office0 in 23 s, offline SfM that grows faster than its
# frames), 10x that is about 4 s; the whole-sequence runs of results/table1_long.csv take at most 0.075 s a frame
# (REMODE, 2-core EPYC, runs two at a time), 50x under it; the quick suite's short runs, where setting up dominates,
# at most 0.5 s a frame (results/quick_long.csv): tens of seconds, far under the 900 s floor.
TIMEOUT_PER_FRAME_S = 4.0
TIMEOUT_MIN_S = 900.0
Frames = int | Literal["all"] | None


# --------------------------------------------------------------------------------------------------- the options
@dataclass(frozen=True)
class ExecutorOptions:
    """Where runs execute (:mod:`eval.bench.executors`): ``kind`` local (a process pool), serial (this process) or
    ray; ``jobs`` at a time; ``address`` of a Ray cluster; ``reuse_workers`` (local: several runs per worker);
    ``timeout_s``: a run's time limit (None: none); ``threads``: math threads per local worker (None: the cores
    shared among the jobs)."""

    kind: str = "local"
    jobs: int = DEFAULT_JOBS
    address: str | None = None
    reuse_workers: bool = False
    timeout_s: float | None = None
    threads: int | None = None

    @property
    def is_default(self) -> bool:
        """The local pool at its default size: what ``--calibrate``'s matrix runs itself."""
        return self == ExecutorOptions(timeout_s=self.timeout_s)


@dataclass(frozen=True)
class BenchOptions:
    """How :func:`run_bench` runs a suite. Selection (None: the suite's): ``sequences`` (names of the suite's, any
    sequence name, dataset-list name or RGB-D folder path), ``frames`` (a number or ``"all"``), ``seeds`` or
    ``runs`` (seeds 0..N-1), ``lengths`` (lengths / transfer: numbers of frames, None = whole), ``motions``
    (transfer: TUM files replayed as simulated domains), ``sim_sequences`` (transfer: registered simulated sequences
    in place of the Table-1 analogues), ``camera`` (a simulated camera preset, a folder's
    calibration preset or camera file; transfer: comma-separated simulated domains), ``image_size`` (``WxH`` or
    ``native``) and ``undistort`` for folder sequences, ``align`` (the headline ATE's alignment), ``settings``
    (``(dotted key, value)`` into the chosen methods' configurations, or ``KEY=VALUE`` texts). Runs: ``executor``,
    ``renderer``, ``frame_cache``, ``check`` (build and step each method once before the suite), ``rerun``,
    ``report_only``, ``plots``, ``progress``, ``out`` (run folders). Results: ``results`` (None: ``results/`` for
    the suite as defined, else ``<out>/reports/<suite>-<digest>/``), ``command`` (the line the reports quote),
    ``figure_format`` (the report's figures: png, pdf or svg; :data:`eval.reports.style.FIGURE_FORMATS`).
    Gate: ``gate`` (:class:`~eval.bench.regress.GateAction`), ``baseline`` (None: the suite's). ``allow_skips``: a
    skipped method, external folder or listed sequence does not make the exit status 1."""

    sequences: tuple[str, ...] | None = None
    frames: Frames = None
    seeds: tuple[int, ...] | None = None
    runs: int | None = None
    lengths: tuple[int | None, ...] | None = None
    motions: tuple[Path, ...] = ()
    sim_sequences: tuple[str, ...] | None = None
    camera: str | None = None
    image_size: str | tuple[int, int] | None = None
    undistort: str | None = None
    align: str | None = None
    settings: tuple[tuple[str, Any] | str, ...] = ()
    executor: ExecutorOptions = field(default_factory=ExecutorOptions)
    renderer: str = "mujoco"
    frame_cache: bool = True
    check: bool = True
    rerun: bool = False
    report_only: bool = False
    plots: bool = True
    progress: bool = True
    out: Path = Path("runs")
    results: Path | None = None
    command: str | None = None
    figure_format: str = "png"
    gate: GateAction = GateAction.COMPARE
    baseline: Path | None = None
    allow_skips: bool = False


# --------------------------------------------------------------------------------- what did not run
@dataclass(frozen=True)
class Skip:
    """Something requested that did not run: ``what`` (method, sequence), its ``name`` and the ``reason``."""

    what: Literal["method", "sequence"]
    name: str
    reason: str



# ---------------------------------------------------------------------------------------- the parts of a suite
@dataclass(frozen=True)
class Part:
    """One suite a suite is made of: ``label`` (how the report and the log name it), the ``suite`` run as a plain
    suite, and ``detail``, what its report writer needs besides its runs (a transfer part, a length, a
    preprocessing choice's domains)."""

    label: str
    suite: Suite
    detail: Any = None


@dataclass(frozen=True)
class KindSpec:
    """How a kind of suite is run and reported: ``parts`` (the suite and the options -> its parts), ``report`` (the
    parts with their runs, the folder, the command -> the files written) and ``as_defined`` (whether the options
    leave the kind's own variants as defined: otherwise the report is a variant's, never the committed one); the
    report's last argument is the figure format."""

    parts: Callable[[Suite, BenchOptions], list[Part]]
    report: Callable[[list[tuple[Part, SuiteRun]], Path, str, str], list[Path]]
    as_defined: Callable[[BenchOptions], bool] = lambda options: True


def _lengths(options: BenchOptions) -> tuple[int | None, ...] | None:
    return None if options.lengths is None else tuple(options.lengths)


def _presets(options: BenchOptions) -> tuple[str, ...] | None:
    """The transfer suite's simulated domains when ``camera`` names only such (``clean,kinect+lit``), else None."""
    if options.camera is None:
        return None
    names = options.camera.split(",")
    try:
        for name in names:
            sim_domain(name)
    except SuiteError:
        return None
    return tuple(names)


def _plain_parts(suite: Suite, options: BenchOptions) -> list[Part]:
    return [Part(suite.name, suite)] if suite.sequences else []


def _plain_report(parts: list[tuple[Part, SuiteRun]], folder: Path, command: str, fmt: str) -> list[Path]:
    from eval.reports.suite_reports import write_report

    return write_report(parts[0][1], folder, command, fmt)


def _transfer_parts(suite: Suite, options: BenchOptions) -> list[Part]:
    planned = transfer_parts(suite, _presets(options) or (DEFAULT_CAMERA_EFFECTS,), _lengths(options),
                             motions=options.motions, sim_sequences=options.sim_sequences)  # fmt: skip
    return [Part(", ".join(dict.fromkeys(d for _, d in p.domains)), p.suite, p) for p in planned if p.suite.sequences]


def _transfer_report(parts: list[tuple[Part, SuiteRun]], folder: Path, command: str, fmt: str) -> list[Path]:
    from eval.reports.transfer_report import report_transfer

    return report_transfer([(part.detail, run) for part, run in parts], folder, command, fmt)


def _length_parts(suite: Suite, options: BenchOptions) -> list[Part]:
    lengths = _lengths(options) or SWEEP_LENGTHS
    return [Part(f"{'whole' if n is None else n} frames", s, n) for n, s in length_parts(suite, lengths)]


def _length_report(parts: list[tuple[Part, SuiteRun]], folder: Path, command: str, fmt: str) -> list[Path]:
    from eval.reports.lengths_report import report_lengths

    return report_lengths([(part.detail, run) for part, run in parts], folder, command, fmt)


def _preprocessing_parts(suite: Suite, options: BenchOptions) -> list[Part]:
    return [Part(choice, s, domains) for choice, s, domains in preprocessing_parts(suite) if s.sequences]


def _preprocessing_report(parts: list[tuple[Part, SuiteRun]], folder: Path, command: str, fmt: str) -> list[Path]:
    from eval.reports.sensitivity_report import report_preprocessing

    return report_preprocessing([(part.label, run, part.detail) for part, run in parts], PREPROCESSING_CHOICES, folder,
                                command, fmt)  # fmt: skip


# the one table of what each kind of suite is made of and how it is reported (PERF runs probes, no parts)
KINDS: dict[SuiteKind, KindSpec] = {
    SuiteKind.RUNS: KindSpec(_plain_parts, _plain_report),
    SuiteKind.TRANSFER: KindSpec(_transfer_parts, _transfer_report,
                                 lambda o: o.lengths is None and _presets(o) is None and not o.motions
                                 and o.sim_sequences is None),
    SuiteKind.LENGTHS: KindSpec(_length_parts, _length_report,
                                lambda o: o.lengths is None or set(o.lengths) == set(SWEEP_LENGTHS)),
    SuiteKind.PREPROCESSING: KindSpec(_preprocessing_parts, _preprocessing_report),
}


# ----------------------------------------------------------------------------------------------- the checks
@dataclass(frozen=True)
class BenchPlan:
    """A checked benchmark (:func:`prepare`): the selected suite, its parts, the methods by name (settings
    applied), where each setting went, the executor, the results folder, the command line (with the time limit of a
    run), what was skipped, and the time limit of a run (``--timeout`` or the default, :func:`_timeout`; None: none)."""

    suite: Suite
    parts: tuple[Part, ...]
    methods: dict[str, Method]
    settings: tuple[tuple[str, tuple[str, ...]], ...]
    executor: Executor | None
    results_dir: Path
    command: str
    skipped: tuple[Skip, ...]
    timeout_s: float | None = None


def prepare(suite: Suite | str, methods: Sequence[str | Method] | None = None,
            options: BenchOptions = BenchOptions(), table: Mapping[str, Method] | None = None) -> BenchPlan:
    """Check everything :func:`run_bench` can check before its first run (module docstring, step 1) and plan it;
    :class:`~eval.errors.InputError` with one line naming the bad value and what is valid. ``table``: the method
    table names are looked up in (default ``eval/methods.toml``); ``Method`` objects are used as given."""
    try:
        return _prepare(suite, methods, options, table)
    except InputError:
        raise
    except ProjectError as exc:  # a bad value found while planning (a camera file, an executor, ...): bad input
        raise InputError(str(exc)) from exc


def _prepare(suite: Suite | str, methods: Sequence[str | Method] | None, options: BenchOptions,
             table: Mapping[str, Method] | None) -> BenchPlan:
    suite = get_suite(suite) if isinstance(suite, str) else suite
    _check_options(suite, options)
    chosen = _chosen_methods(suite, methods, table)
    _check_entry_points(chosen, methods is not None, options.allow_skips)
    settings = tuple(parse_setting(s) if isinstance(s, str) else tuple(s) for s in options.settings)
    resolved, applied = apply_settings(list(chosen.values()), settings) if settings else (chosen, {})
    camera = None if _presets(options) is not None and suite.kind is SuiteKind.TRANSFER else options.camera
    selected = suite.select(options.sequences, list(resolved), options.frames, options.seeds, options.runs,
                            camera=camera, size=parse_image_size(options.image_size), undistort=options.undistort)
    if options.align is not None:
        selected = replace(selected, alignment=options.align)
    lengths: dict[str, int] = {}
    for ref in selected.sequences:  # a folder's camera (file, preset, side file) and index read now, not in a run
        if ref.folder is not None:
            source = ref.make_source()
            try:
                lengths[ref.name] = len(source)
            finally:
                source.close()
    if suite.kind is not SuiteKind.PERF:  # "the first N frames" must be what every run reads
        check_frames(selected.sequences, selected.frames, lengths)
    parts = () if suite.kind is SuiteKind.PERF else tuple(KINDS[suite.kind].parts(selected, options))
    command = options.command or command_line(selected.name, options)
    builtin = load_methods()
    as_defined = (selected.is_default and not settings and all(builtin.get(n) == m for n, m in resolved.items())
                  and (suite.kind is SuiteKind.PERF or KINDS[suite.kind].as_defined(options)))  # fmt: skip
    results_dir = _results_dir(selected, options, command, as_defined)
    _check_outputs(selected, parts, resolved, options, results_dir)
    timeout = _timeout(selected, parts, options, lengths)
    if timeout is not None and "--timeout" not in command.split():  # the limit, given or the default, stated in
        command += f" --timeout {timeout:g}"  # the command the reports quote (their provenance)
    if timeout is not None and options.executor.timeout_s is None:
        log.info("%s: a run is stopped after %g s (the default: %g s a frame of the longest run, %d frames, at "
                 "least %g s; --timeout sets another)", selected.name, timeout, TIMEOUT_PER_FRAME_S,
                 _longest_run(parts, lengths), TIMEOUT_MIN_S)  # fmt: skip
    skipped = tuple(Skip("sequence", name, reason) for name, reason in selected.skipped)
    plan_options = replace(options, executor=replace(options.executor, timeout_s=timeout))
    return BenchPlan(selected, parts, dict(resolved), tuple(applied.items()),
                     _executor(selected, resolved, plan_options), results_dir, command, skipped, timeout)


def _check_entry_points(chosen: Mapping[str, Method], named: bool, allow_skips: bool) -> None:
    """Every chosen agent's module imported and its class found before any run
    (:func:`eval.bench.methods.entry_point_problem`). A broken definition (a module that is not there, a misspelt
    class, a module that raises) is refused. A method whose module needs a package this machine lacks (an optional
    third-party system) is refused when the caller ``named`` the methods, unless ``allow_skips``; in a suite's own
    selection (or allowed) it is left to the suite's check, which skips it with the reason."""
    for method in chosen.values():
        problem = entry_point_problem(method)
        if problem is None:
            continue
        if not problem.optional:
            raise MethodError(problem.reason)
        if named and not allow_skips:
            raise MethodError(f"method {method.name!r} cannot run here ({problem.reason}): leave it out of "
                              "--methods, install what it needs, or pass --allow-skips to skip it")  # fmt: skip


def check_writable(folder: str | Path, flag: str) -> None:
    """Refuse a folder the benchmark could not write into (a file where the folder or one of its parents should be,
    a folder this user may not write), by trying (:func:`slamcommon.output_paths.check_output_folder`):
    :class:`~eval.errors.InputError` naming ``flag`` (the option that gave it) and the folder."""
    try:
        check_output_folder(folder, flag)
    except OutputPathError as exc:
        raise InputError(str(exc)) from None


def _check_outputs(suite: Suite, parts: Sequence[Part], methods: Mapping[str, Method], options: BenchOptions,
                   results_dir: Path) -> None:
    """The folders the call writes, checked before any run: the results folder (:func:`check_writable`), and the
    runs' folder ``out`` (written by every run; ``--report-only``: it must hold finished runs of this selection,
    else there is nothing to report)."""
    if suite.kind is SuiteKind.PERF:
        check_writable(options.results or DEFAULT_RESULTS, "--results")
        return
    if options.report_only:
        out = Path(options.out)
        if not out.is_dir():
            raise InputError(f"--out {out}: no such folder; --report-only writes the tables from the finished runs "
                             "of an --out folder that a run of the suite wrote")  # fmt: skip
        folders = [run_folder(out, spec) for part in parts
                   for spec in plan_runs(part.suite, [methods[m] for m in part.suite.methods if m in methods])]
        if not any((folder / DONE_FILE).is_file() for folder in folders):
            example = f" (e.g. {folders[0]})" if folders else ""
            raise InputError(f"--out {out}: no finished run of suite {suite.name} for this selection: none of its "
                             f"{len(folders)} run folders holds a {DONE_FILE}{example}; --report-only reports "
                             "finished runs only (run the suite first, or name the --out that holds them)")
    else:
        check_writable(options.out, "--out")
    check_writable(results_dir, "--results")


def _longest_run(parts: Sequence[Part], lengths: Mapping[str, int]) -> int:
    """The most frames any planned run reads: its part's frames, or its sequence's length (a folder's as read, a
    simulated one's from its definition)."""
    longest = 0
    for part in parts:
        for ref in part.suite.sequences:
            n = lengths.get(ref.name, UNKNOWN_LENGTH) if ref.folder is not None else \
                max(0, int(ref.spec().n_frames) - int(ref.start))
            longest = max(longest, n if part.suite.frames is None else min(n, int(part.suite.frames)))
    return longest


def _timeout(suite: Suite, parts: Sequence[Part], options: BenchOptions, lengths: Mapping[str, int]) -> float | None:
    """A run's time limit: ``--timeout`` when given; else :data:`TIMEOUT_PER_FRAME_S` per frame of the longest run
    planned, at least :data:`TIMEOUT_MIN_S`; None for ``perf`` (probes, no runs) and for the serial executor where
    it cannot stop a run (no SIGALRM, or called from a thread other than the main one:
    :func:`eval.bench.executors.check_alarm`)."""
    given = options.executor.timeout_s
    if given is not None:
        return float(given)
    if suite.kind is SuiteKind.PERF:
        return None
    if options.executor.kind == "serial" and options.gate is not GateAction.CALIBRATE:
        try:
            check_alarm()
        except ExecutorError:
            return None
    return max(TIMEOUT_MIN_S, TIMEOUT_PER_FRAME_S * _longest_run(parts, lengths))


def _check_sim_sequences(kind: SuiteKind, names: tuple[str, ...]) -> None:
    """``--sim-sequences``: the transfer suite's only, each a registered simulated sequence, at least one."""
    from sim_envs.sequences import registered_names

    if kind is not SuiteKind.TRANSFER:
        raise SuiteError("--sim-sequences applies to the transfer suite (the simulated sequences it ranks the methods "
                         "on)")  # fmt: skip
    known = registered_names()
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise SuiteError(f"--sim-sequences takes registered simulated sequences (cnnslam bench --list, sim_envs/"
                         f"sequences.py; e.g. office_fr1motion living_fr1motion), got {', '.join(bad) or 'none'}")


def _check_options(suite: Suite, options: BenchOptions) -> None:
    """The options that belong to some suites only, and the numbers that must be in range."""
    kind = suite.kind
    if options.motions and kind is not SuiteKind.TRANSFER:
        raise SuiteError("--motion applies to the transfer suite (a recorded motion as a simulated domain)")
    if options.sim_sequences is not None:
        _check_sim_sequences(kind, options.sim_sequences)
    if options.lengths is not None and kind not in (SuiteKind.LENGTHS, SuiteKind.TRANSFER):
        raise SuiteError("--lengths applies to the lengths and transfer suites; other suites take --frames")
    if options.lengths is not None and options.frames is not None:
        raise SuiteError("give --lengths or --frames, not both")
    bad = [s for s in options.seeds or () if not (isinstance(s, int) and s >= 0)]
    if bad:
        raise SuiteError(f"--seeds takes whole numbers >= 0 (a run's seed), got {', '.join(map(str, bad))}")
    frames = options.frames
    if frames is not None and frames != "all" and not (_whole(frames) and frames >= 2):
        raise SuiteError(f"--frames takes a number of frames >= 2 (the first N of each sequence) or 'all', got "
                         f"{frames!r}")  # fmt: skip
    bad_lengths = [n for n in options.lengths or () if n is not None and not (_whole(n) and n >= 2)]
    if bad_lengths:
        raise SuiteError(f"--lengths takes numbers of frames >= 2 or 'all', got {', '.join(map(repr, bad_lengths))}")
    if options.runs is not None and not (_whole(options.runs) and options.runs >= 1):
        raise SuiteError(f"--runs takes a number of runs per cell >= 1 (seeds 0..N-1), got {options.runs!r}")
    if not (_whole(options.executor.jobs) and options.executor.jobs >= 1):
        raise SuiteError(f"--jobs takes a number of runs in parallel >= 1, got {options.executor.jobs!r}")
    timeout = options.executor.timeout_s
    if timeout is not None and not timeout > 0:
        raise SuiteError(f"--timeout must be a number of seconds > 0, got {timeout}")
    if options.executor.kind not in EXECUTORS:
        raise SuiteError(f"unknown executor {options.executor.kind!r}; valid executors: {', '.join(EXECUTORS)}")
    if options.figure_format not in FIGURE_FORMATS:
        raise SuiteError(f"unknown figure format {options.figure_format!r}; valid formats: {', '.join(FIGURE_FORMATS)}")
    if options.gate is GateAction.CALIBRATE and not options.executor.is_default:
        raise SuiteError("--calibrate runs its matrix's own local pools (2 runs at a time, then 1 with 2 threads; "
                         "eval/bench/calibrate.py): --executor, --jobs and --reuse-workers do not apply")


def _whole(value: object) -> bool:
    """Whether ``value`` is a whole number (an int, not a bool)."""
    return isinstance(value, int) and not isinstance(value, bool)


def _chosen_methods(suite: Suite, methods: Sequence[str | Method] | None,
                    table: Mapping[str, Method] | None) -> dict[str, Method]:
    """The methods to run by name: ``methods`` (names looked up in ``table``, Method objects as given) or the
    suite's; an unknown name or an external folder that is not there is an :class:`InputError`."""
    table = load_methods() if table is None else table
    wanted = list(suite.methods) if methods is None else list(methods)
    names = [m for m in wanted if isinstance(m, str)]
    unknown = [n for n in names if n not in table]
    if unknown:
        raise SuiteError(f"unknown method(s) {', '.join(unknown)}; valid methods: {', '.join(table)}")
    chosen = {m.name if isinstance(m, Method) else m: m if isinstance(m, Method) else table[m] for m in wanted}
    chosen.update({m.name: m for m in table.values() if m.kind == "external" and m.name not in chosen})
    missing = [m for m in chosen.values() if m.kind == "external" and not Path(m.folder or "").is_dir()]
    if missing:
        raise SuiteError("; ".join(f"--external {m.name}={m.folder}: no such folder" for m in missing)
                         + "; an external method's folder holds its output (cnnslam bench --help shows the layout)")
    return chosen


def _results_dir(suite: Suite, options: BenchOptions, command: str, as_defined: bool) -> Path:
    """Where the report goes: ``options.results``; else ``results/`` for the suite as defined; else a folder named
    after the selection under ``<out>/reports/``. A selection of other sequences or methods than the suite's never
    writes into the committed ``results/`` (it would overwrite the whole table with part of it): neither the
    repository's own (:data:`COMMITTED_RESULTS`, however ``--results`` reaches it: paths compared resolved) nor
    ``results/`` under the working folder, where the suite as defined writes; except a folder below them that holds
    this suite's result made by this very command (:func:`made_here`: a committed variant such as
    ``results/camera_clean/``, remade in place by ``cnnslam results make``)."""
    if options.results is None:
        if as_defined:
            return DEFAULT_RESULTS
        return Path(options.out) / "reports" / f"{suite.name}-{hashlib.sha256(command.encode()).hexdigest()[:8]}"
    target = Path(options.results).resolve()
    note = suite.selection_note()
    guarded = (COMMITTED_RESULTS, DEFAULT_RESULTS.resolve())  # the repository's, and where the suite writes here
    if note and any(committed in target.parents for committed in guarded) and made_here(target, suite.name, command):
        return Path(options.results)  # a committed variant remade in its own folder by the command that made it
    if note and any(target == committed or committed in target.parents for committed in guarded):
        raise SuiteError(f"--results {options.results}: the committed results hold suite {suite.name} as defined, "
                         f"and this selection is {note}: leave --results out (it writes under {options.out}/reports/) "
                         "or name a folder outside results/")  # fmt: skip
    return Path(options.results)


def made_here(folder: Path, suite: str, command: str) -> bool:
    """Whether ``folder`` holds ``suite``'s result made by ``command`` (as a report quotes it, without the
    ``--timeout`` the planner adds): its manifest records that command, or its report ``<suite>.md`` quotes it
    ("Made by `...`")."""
    bare = _without_timeout(command)
    manifest = Path(folder) / f"{suite}.provenance.json"
    if manifest.is_file():
        try:
            recorded = json.loads(manifest.read_text()).get("command")
        except (OSError, ValueError, AttributeError):
            recorded = None
        if isinstance(recorded, str) and _without_timeout(recorded) == bare:
            return True
    report = Path(folder) / f"{suite}.md"
    try:
        return report.is_file() and f"Made by `{bare}`" in report.read_text()
    except OSError:
        return False


def _without_timeout(command: str) -> str:
    words = command.split()
    if "--timeout" in words:
        i = words.index("--timeout")
        words = words[:i] + words[i + 2:]
    return " ".join(words)


def _executor(suite: Suite, methods: Mapping[str, Method], options: BenchOptions) -> Executor | None:
    """The executor of the runs (None for ``perf`` and ``--calibrate``, which run their own)."""
    if suite.kind is SuiteKind.PERF or options.gate is GateAction.CALIBRATE:
        return None
    ex = options.executor
    # the fork server imports the agents' modules once, the modules they import late (their method's preload) and
    # the plots' module; each run still gets a fresh worker forked from it
    preload = [m.entry_point.partition(":")[0] for m in methods.values() if m.entry_point]
    preload += [name for m in methods.values() for name in m.preload]
    if options.plots:
        preload.append("eval.reports.plots")
    return make_executor(ex.kind, ex.jobs, ex.address, fresh_workers=not ex.reuse_workers, preload=preload,
                         threads=ex.threads,
                         **({"timeout_s": ex.timeout_s} if ex.timeout_s is not None else {}))  # fmt: skip


def command_line(suite: str, options: BenchOptions, methods: Sequence[str] = ()) -> str:
    """A ``cnnslam bench`` line for the options that shape the results (what a report quotes when its caller gives
    none)."""
    words = ["cnnslam", "bench", suite]
    for flag, value in (("--frames", options.frames), ("--runs", options.runs), ("--align", options.align),
                        ("--camera", options.camera), ("--undistort", options.undistort),
                        ("--image-size", options.image_size)):  # fmt: skip
        if value is not None:
            words += [flag, str(value)]
    lengths = None if options.lengths is None else ["all" if n is None else n for n in options.lengths]
    for flag, values in (("--sequences", options.sequences), ("--methods", methods), ("--seeds", options.seeds),
                         ("--lengths", lengths), ("--motion", options.motions),
                         ("--sim-sequences", options.sim_sequences)):  # fmt: skip
        if values:
            words += [flag, *map(str, values)]
    return " ".join(words)
