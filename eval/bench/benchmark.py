"""The benchmark as a library call: ``run_bench(suite, methods, options) -> BenchOutcome``.

``cnnslam bench`` is a thin shell around it (arguments -> :class:`BenchOptions` -> :func:`run_bench` -> a summary),
as evo's ``main_ape.ape(...)`` returns a result its command line prints::

    from eval.bench import BenchOptions, run_bench

    outcome = run_bench("table1", ["CNN-SLAM", "LSD"], BenchOptions(sequences=("office0",), frames=300))
    print(outcome.exit_status, [(r.key, r.status, r.coverage) for r in outcome.runs], outcome.reports)

What it does, in this order:

1. **Checks everything it can before the first run** (:func:`eval.bench.plan.prepare`): the suite and the options
   that belong to it, the numbers (frames and lengths >= 2, runs and jobs >= 1, a time limit > 0), the methods (names
   of the method table, ``Method`` objects as given, an external folder that is not there, every agent's module
   imported and its class found: :func:`eval.bench.plan._check_entry_points` says which are refused and which
   skipped), ``settings`` (keys that no chosen method's configuration has, values of the wrong type or range:
   :func:`eval.bench.method_settings.apply_settings`), seeds, sequence names, every folder sequence's camera (a camera
   file that does not parse or has ``fx = -5``), the output folders (``out`` and the results folder writable,
   :func:`check_writable`; ``report_only``: ``out`` holds finished runs of the selection), the results folder (a
   selection other than the suite's never writes into the committed ``results/``, :data:`COMMITTED_RESULTS`), the
   executor, and a run's time limit (given, or :func:`eval.bench.plan._timeout`'s default, quoted in the reports'
   command). Anything wrong raises :class:`~eval.errors.InputError` with one line naming the value and what is valid;
   nothing has run.
2. **Runs every part of the suite** (:data:`KINDS`): a plain suite is one part; ``transfer``, ``lengths`` and
   ``preprocessing`` are several parts, each run as a plain suite (so their runs are those suites' own), with one
   report over all of them; ``perf`` runs throughput probes instead. A run that breaks (an agent that raises, no
   poses or one pose to score, a method that cannot import what it needs at run time) is a failed run, stored as
   such and never reused as finished.
3. **Writes the report** and, for a plain suite, **the gate** (:func:`eval.bench.regress.apply_gate`:
   compare, update, replace) or the calibration (:func:`eval.bench.calibrate.calibrate_suite`).
4. **Returns** a frozen :class:`BenchOutcome`: every run with its status and coverage, the report's files, the
   gate's outcome, what was skipped and why, and the exit status a command gives it (0: every requested run
   finished, nothing skipped unless allowed, the gate passed; 1 otherwise). Ctrl-C propagates
   (KeyboardInterrupt) with the finished runs stored.

No printing: progress goes to the ``eval.bench.benchmark`` logger (INFO) and tqdm's bars (``progress``).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from eval.bench.methods import Method
from eval.bench.plan import (  # the options and the checks before any run; their names kept here too
    COMMITTED_RESULTS,
    DEFAULT_JOBS,
    DEFAULT_RESULTS,
    KINDS,
    TIMEOUT_MIN_S,
    TIMEOUT_PER_FRAME_S,
    BenchOptions,
    BenchPlan,
    ExecutorOptions,
    Frames,
    KindSpec,
    Part,
    Skip,
    check_writable,
    command_line,
    prepare,
)
from eval.bench.regress import GateAction, GateOutcome, apply_gate, check_gate
from eval.bench.runner import RunOutcome, SuiteRun, git_revision, run_suite
from eval.bench.sequence_resolve import dataset_list_file
from eval.bench.suites import SUITES, Suite, SuiteKind, get_suite
from eval.errors import SuiteError
from eval.metrics.results import coverage

__all__ = ["COMMITTED_RESULTS", "DEFAULT_JOBS", "DEFAULT_RESULTS", "KINDS", "TIMEOUT_MIN_S", "TIMEOUT_PER_FRAME_S",
           "BenchOptions", "BenchOutcome", "BenchPlan", "ExecutorOptions", "Frames", "KindSpec", "Part", "RunRow",
           "Skip", "baseline_description", "check_writable", "command_line", "describe_suites", "prepare",
           "run_bench", "run_rows"]

log = logging.getLogger(__name__)
DEFAULT_OPTIONS = BenchOptions()  # run_bench's options when none are given (frozen: shared safely)

# --------------------------------------------------------------------------------------------------- the outcome
@dataclass(frozen=True)
class RunRow:
    """One run as the outcome lists it: its ``key`` (its folder under ``out``), the ``part`` it belongs to,
    sequence, method, seed, ``status`` (done, cached, failed, not_run), ``error`` (failed), and ``coverage``:
    ``(poses scored, frames)`` when its trajectory covers less than its sequence (None: whole, or not scored)."""

    key: str
    part: str
    sequence: str
    method: str
    seed: int
    status: str
    error: str | None = None
    coverage: tuple[int, int] | None = None


@dataclass(frozen=True)
class BenchOutcome:
    """What :func:`run_bench` did (module docstring): the suite, the command the reports quote, every part's
    :class:`~eval.bench.runner.SuiteRun` (label -> run), every run, the report's files and folder, the gate's
    outcome (None: no gate), what was skipped, which methods each setting went to, and the exit status (0 or 1)."""

    suite: str
    command: str
    parts: tuple[tuple[str, SuiteRun], ...]
    runs: tuple[RunRow, ...]
    reports: tuple[Path, ...]
    results_dir: Path | None
    gate: GateOutcome | None
    skipped: tuple[Skip, ...]
    settings: tuple[tuple[str, tuple[str, ...]], ...]
    exit_status: int
    notes: tuple[str, ...] = ()

    @property
    def failed(self) -> tuple[RunRow, ...]:
        """The runs that failed (crashed, timed out, broke)."""
        return tuple(r for r in self.runs if r.status == "failed")

    def counts(self) -> dict[str, int]:
        """How many runs ended how (status -> count)."""
        out: dict[str, int] = {}
        for r in self.runs:
            out[r.status] = out.get(r.status, 0) + 1
        return out


# --------------------------------------------------------------------------------------------------- the call
def run_bench(suite: Suite | str, methods: Sequence[str | Method] | None = None,
              options: BenchOptions = DEFAULT_OPTIONS, table: Mapping[str, Method] | None = None) -> BenchOutcome:
    """Run a benchmark suite and write its report (module docstring). ``suite``: a name of :data:`SUITES` or a
    :class:`Suite`; ``methods``: names of ``table`` (default ``eval/methods.toml``;
    :func:`eval.bench.methods.method_table` adds a method file and ``--external`` folders, whose methods always run)
    or ``Method`` objects (None: the suite's); ``options``: :class:`BenchOptions`. Raises
    :class:`~eval.errors.InputError` before any run for bad input; KeyboardInterrupt after storing the runs finished
    so far."""
    plan = prepare(suite, methods, options, table)
    _check_gate(plan, options)
    if plan.suite.kind is SuiteKind.PERF:
        return _perf(plan, options)
    if options.gate is GateAction.CALIBRATE:
        return _calibrate(plan, options)
    done: list[tuple[Part, SuiteRun]] = []
    for part in plan.parts:
        if len(plan.parts) > 1:
            frames = "whole sequences" if part.suite.frames is None else f"{part.suite.frames} frames"
            log.info("%s: %s: suite %s, %d sequence(s), %s", plan.suite.name, part.label, part.suite.name,
                     len(part.suite.sequences), frames)  # fmt: skip
        done.append((part, _run_part(part.suite, plan, options)))
    notes = []
    reports: list[Path] = []
    if done:
        reports = KINDS[plan.suite.kind].report(done, plan.results_dir, plan.command, options.figure_format)
        from eval.bench.provenance import write_manifest  # where the report came from: `cnnslam results status`

        reports = [*reports, write_manifest(plan.results_dir, plan.suite.name, plan.command, options, plan.methods,
                                            [run for _, run in done])]  # fmt: skip
    else:
        notes.append(f"suite {plan.suite.name} has no sequence to run here ({len(plan.suite.skipped)} skipped; the "
                     f"dataset list is {dataset_list_file()})")  # fmt: skip
    gate = None
    if plan.suite.kind is SuiteKind.RUNS and done:
        run = done[0][1]
        incomplete = (f"{len(run.failed)} run(s) failed, {len(run.skipped_methods)} method(s) skipped"
                      if run.failed or run.skipped_methods else "")  # fmt: skip
        gate = apply_gate(run.records, options.gate, options.baseline or plan.suite.baseline_path,
                          gated=plan.suite.gated or options.baseline is not None,
                          description=baseline_description(plan.suite), incomplete=incomplete)  # fmt: skip
    return _outcome(plan, options, done, reports, gate, notes)


def _check_gate(plan: BenchPlan, options: BenchOptions) -> None:
    """The gate's baseline, checked before any run so that the gate fails closed
    (:func:`eval.bench.regress.check_gate`: COMPARE needs a readable baseline of this selection; an update, a
    readable one or none); a ``baseline`` named for a suite that has no gate of runs is refused too."""
    kind = plan.suite.kind
    if kind is not SuiteKind.RUNS:
        if options.baseline is not None and options.gate is GateAction.COMPARE:
            raise SuiteError(f"--baseline {options.baseline}: suite {plan.suite.name} ({kind.value}) has no gate of "
                             "runs to compare; the gate compares suites of runs such as quick")  # fmt: skip
        return
    if options.gate is GateAction.CALIBRATE:  # writes the baseline
        return
    check_gate(options.gate, options.baseline or plan.suite.baseline_path,
               gated=plan.suite.gated or options.baseline is not None,
               cells=[(s.name, m) for s in plan.suite.sequences for m in plan.methods],
               frames=plan.suite.frames)  # fmt: skip


def _run_part(suite: Suite, plan: BenchPlan, options: BenchOptions) -> SuiteRun:
    return run_suite(suite, plan.methods, options.out, executor=plan.executor, renderer=options.renderer,
                     plots=options.plots, progress=options.progress, check=options.check, rerun=options.rerun,
                     report_only=options.report_only, frame_cache=options.frame_cache)  # fmt: skip


def _outcome(plan: BenchPlan, options: BenchOptions, done: list[tuple[Part, SuiteRun]], reports: list[Path],
             gate: GateOutcome | None, notes: list[str]) -> BenchOutcome:
    """The outcome of the parts' runs, and its exit status (module docstring)."""
    rows = tuple(row for part, run in done for row in run_rows(part.label, run))
    skipped = list(plan.skipped)
    for _, run in done:
        skipped += [Skip("method", n, r) for n, r in run.skipped_methods.items() if Skip("method", n, r) not in skipped]
    failed = any(r.status == "failed" for r in rows)
    # no sequence here at all (a real-folder suite without its folders): a plain suite may allow that; a suite that
    # compares against the real folders has nothing to compare
    empty = not plan.suite.sequences and not (options.allow_skips and plan.suite.skipped
                                              and plan.suite.kind is SuiteKind.RUNS)  # fmt: skip
    status = 1 if failed or (skipped and not options.allow_skips) or empty or (gate and not gate.passed) else 0
    return BenchOutcome(plan.suite.name, plan.command, tuple((p.label, r) for p, r in done), rows, tuple(reports),
                        plan.results_dir if reports else None, gate, tuple(skipped), plan.settings, status,
                        tuple(notes))  # fmt: skip


def run_rows(label: str, run: SuiteRun) -> list[RunRow]:
    """Every planned run of a part as a :class:`RunRow` (coverage read from its record)."""
    records = {r.run: r for r in run.records}
    rows = []
    for spec in run.specs:
        outcome: RunOutcome = run.outcomes[spec.key]
        record = records.get(spec.key)
        rows.append(RunRow(spec.key, label, spec.sequence.name, spec.method.name, spec.seed, outcome.status,
                           outcome.error, coverage(record.metrics) if record is not None else None))  # fmt: skip
    return rows


def baseline_description(suite: Suite) -> str:
    """The description a baseline written from ``suite`` carries."""
    frames = "all" if suite.frames is None else suite.frames
    return (f"cnnslam bench {suite.name}: {frames} frames, {len(suite.seeds)} runs per cell, sequences "
            f"{', '.join(s.name for s in suite.sequences)}; methods {', '.join(suite.methods)}")  # fmt: skip


def _perf(plan: BenchPlan, options: BenchOptions) -> BenchOutcome:
    """The ``perf`` suite: throughput probes (:func:`eval.bench.perf.run_perf`), their report and speed gate."""
    from eval.bench.perf import SPEED_BASELINE, run_perf

    results = options.results or DEFAULT_RESULTS
    frames = None if options.frames == "all" else options.frames
    report = run_perf(results, frames=frames, progress=options.progress,
                      update_speed_baseline=options.gate in (GateAction.UPDATE, GateAction.REPLACE))  # fmt: skip
    verdict = report.speed_gate or {}
    message = (f"speed gate not judged: {verdict['error']}" if verdict.get("error") else
               "speed gate: " + ("; ".join(verdict.get("failures") or []) or "passed"))  # fmt: skip
    gate = GateOutcome(options.gate, Path(str(verdict.get("baseline", SPEED_BASELINE))), bool(report.ok), message)
    return BenchOutcome(plan.suite.name, plan.command, (), (), (results / "perf.md", results / "perf.json"), results,
                        gate, (), (), 0 if report.ok else 1)  # fmt: skip


def _calibrate(plan: BenchPlan, options: BenchOptions) -> BenchOutcome:
    """``GateAction.CALIBRATE``: the suite under the perturbation matrix, its baseline, and its report from the
    reference configuration's runs (:func:`eval.bench.calibrate.calibrate_suite`)."""
    from eval.bench.calibrate import MATRIX, calibrate_suite

    done = calibrate_suite(plan.suite, plan.methods, options.out, options.baseline or plan.suite.baseline_path,
                           baseline_description(plan.suite), renderer=options.renderer,
                           timeout_s=plan.timeout_s, progress=options.progress,
                           revision=git_revision() or "")  # fmt: skip
    parts = [(Part(name, run.suite), run) for name, run in done.runs.items()]
    reports: list[Path] = []
    if done.baseline is not None:
        reference = [(p, r) for p, r in parts if p.label == MATRIX[0].name]
        reports = KINDS[SuiteKind.RUNS].report(reference, plan.results_dir, plan.command, options.figure_format)
    gate = GateOutcome(GateAction.CALIBRATE, done.baseline_path, done.baseline is not None,
                       "; ".join([done.summary, *(f"left out of the calibration: {w}" for w in done.left_out)]))
    notes = [f"report from the {MATRIX[0].name} configuration's runs", *done.failed]
    return _outcome(plan, options, parts, reports, gate, notes)


def describe_suites(table: Mapping[str, Method]) -> str:
    """The suites (their sequences, frames and methods; a real-folder suite read from the dataset list now) and the
    method table, as text (``cnnslam bench --list``)."""
    lines = ["suites:"]
    for suite in SUITES.values():
        lines.append(f"  {suite.name:<9} {suite.description}")
        if suite.kind is not SuiteKind.RUNS:
            continue
        if suite.real_folders:
            try:
                suite = get_suite(suite.name)
            except SuiteError as exc:
                lines.append(f"            {exc}")
        frames = "all" if suite.frames is None else suite.frames
        lines.append(f"            frames {frames}; sequences: {', '.join(s.name for s in suite.sequences)}")
        if suite.skipped:
            lines.append(f"            missing here: {', '.join(name for name, _ in suite.skipped)}")
        lines.append(f"            methods: {', '.join(suite.methods)}")
    lines.append("methods:")
    for m in table.values():
        lines.append(f"  {m.name:<17} {m.entry_point or m.folder}  {dict(m.agent_kwargs())}  [{', '.join(m.metrics)}]")
    return "\n".join(lines)
