"""A suite run: the suite's runs planned (:func:`plan_runs`), executed on an executor (:mod:`eval.bench.executors`)
with progress, stored (:mod:`eval.bench.run_store`), reused when finished earlier with the same fingerprint, and
collected as a :class:`SuiteRun` (the records of the finished runs, how each run ended) for the reports. One run is
:mod:`eval.bench.run`; every kind of suite runs through :func:`eval.bench.run_bench`."""

from __future__ import annotations

import json
import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

from tqdm import tqdm

from eval.bench.executors import Executor, SerialExecutor
from eval.bench.methods import Method, check_methods
from eval.bench.run import (
    DONE_FILE,
    FRAME_CACHE_DIR,
    FramesJob,
    RunResult,
    RunSpec,
    RunStatus,
    execute_run,
    render_frames,
)
from eval.bench.run_store import complete_run, remove_stale_temporaries, reuse_finished, run_folder, store_result
from eval.bench.sequence_ref import SequenceRef
from eval.bench.suites import Suite, SuiteKind
from eval.errors import RunnerError
from eval.metrics.results import RunRecord, load_run
from eval.metrics.runs import suite_records_json  # noqa: F401  (the judge's; its name kept here)
from slamcommon.provenance import tree_state

logger = logging.getLogger(__name__)


# -------------------------------------------------------------------------------------------------- a suite run
@dataclass(frozen=True)
class RunOutcome:
    """How one run of a suite ended: "done" (ran now), "cached" (finished earlier), "failed" (with its error), or
    "not_run" (``--report-only`` and no finished run there: neither a result nor a failure)."""

    key: str
    status: RunStatus
    folder: Path
    error: str | None = None
    seconds: float | None = None  # wall-clock seconds of a run made now


@dataclass(frozen=True)
class SuiteRun:
    """A suite's runs: the plan, how each ended, the methods skipped (name -> reason) and the run records of the
    finished runs (in plan order), each with its run key; ``timings``: key -> timing.json content."""

    suite: Suite
    out_root: Path
    specs: tuple[RunSpec, ...]
    outcomes: dict[str, RunOutcome]
    skipped_methods: dict[str, str]
    records: list[RunRecord]
    timings: dict[str, dict[str, Any]]
    methods: tuple[Method, ...] = ()

    @property
    def failed(self) -> list[RunOutcome]:
        return [o for o in self.outcomes.values() if o.status == "failed"]

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for o in self.outcomes.values():
            out[o.status] = out.get(o.status, 0) + 1
        return out


def git_revision(root: str | Path | None = None) -> str | None:
    """The 12-digit revision of the repository holding ``root`` (default: this package), ``-dirty`` appended when a
    tracked file outside ``results/`` is changed and not committed (:func:`slamcommon.provenance.tree_state`, as the
    provenance manifests judge it), or None outside a repository."""
    root = Path(root) if root is not None else Path(__file__).resolve().parent
    state = tree_state(root)
    if state.revision is None:
        return None
    return state.revision + ("-dirty" if state.dirty else "")


def plan_runs(
    suite: Suite,
    methods: Sequence[Method],
    *,
    renderer: str = "mujoco",
    plots: bool = True,
    revision: str | None = None,
) -> list[RunSpec]:
    """Every run of the suite: sequences x methods x seeds, in that nesting order; a method's own ``align`` wins
    over the suite's alignment.

    A method that takes no seed (no ``seed`` in its table: exact given its inputs, such as the oracle, constant-pose
    or a scored external folder) runs once per cell, with the suite's first seed: its other runs would be
    byte-for-byte copies (``tests/eval/bench/test_runner.py`` checks that they are), and its cell is that one run.
    """
    return [
        RunSpec(suite.name, ref, method, seed, suite.frames, method.align or suite.alignment, renderer, plots,
                revision)
        for ref in suite.sequences
        for method in methods
        for seed in (suite.seeds if method.seed_targets else suite.seeds[:1])
    ]


UNKNOWN_LENGTH = 1000  # frames assumed for a run of a whole sequence whose length is not known before it runs


def run_frames(spec: RunSpec) -> int:
    """How many frames ``spec`` runs: its ``frames``, else its sequence's length (a simulated sequence's; a folder's
    is not read: :data:`UNKNOWN_LENGTH`)."""
    ref = spec.sequence
    length = UNKNOWN_LENGTH
    if ref.folder is None:
        length = max(0, int(ref.spec().n_frames) - int(ref.start))
    return length if spec.frames is None else min(length, int(spec.frames))


def run_order(specs: Sequence[RunSpec]) -> list[RunSpec]:
    """The runs longest first (frames x the method's cost per frame, :attr:`eval.bench.methods.Method.cost`), plan
    order among equals: the longest-processing-time rule, so that the last runs to start are short ones and no core
    waits alone on a long run at the end of a suite."""
    return sorted(specs, key=lambda s: -run_frames(s) * s.method.cost)


def frames_jobs(specs: Sequence[RunSpec], cache: str | Path) -> list[FramesJob]:
    """One job per simulated sequence the runs read (the most frames any of them reads), longest first: rendered
    ahead of the runs (:func:`eval.bench.run.render_frames`, queued before them: :func:`suite_task`), each sequence
    once, where the first run of each sequence used to render it while the others waited for nothing (and the last
    sequences' first runs ran long)."""
    longest: dict[Any, tuple[SequenceRef, int | None]] = {}
    for spec in specs:
        ref = spec.sequence
        if ref.folder is not None or ref.registered:  # a folder is read from disk; a registered one is never cached
            continue
        whole = replace(ref, start=0)  # a window reads the whole sequence's cached frames
        frames = None if spec.frames is None else int(spec.frames) + int(ref.start)
        key = (whole.name, json.dumps(whole.describe(), sort_keys=True, default=str), spec.renderer)
        _, known = longest.get(key, (whole, 0))
        longest[key] = (whole, None if frames is None or known is None else max(frames, known))
    jobs = [FramesJob(ref, frames, key[2], str(cache)) for key, (ref, frames) in longest.items()]
    return sorted(jobs, key=lambda j: -(int(j.sequence.spec().n_frames) if j.frames is None else j.frames))


def run_suite(
    suite: Suite,
    methods: Mapping[str, Method],
    out_root: str | Path,
    *,
    executor: Executor | None = None,
    renderer: str = "mujoco",
    plots: bool = True,
    progress: bool = True,
    check: bool = True,
    revision: str | None = None,
    on_result: Callable[[RunOutcome], None] | None = None,
    rerun: bool = False,
    report_only: bool = False,
    frame_cache: bool = True,
) -> SuiteRun:
    """Run every unfinished run of ``suite`` (its methods looked up in ``methods``) and gather the records.

    Methods that cannot run here (:func:`eval.bench.methods.check_methods`; ``check=False`` only checks the import)
    are skipped and reported, not failed. Finished runs (same fingerprint) are not run again. ``executor``:
    default :class:`~eval.bench.executors.SerialExecutor`. ``revision``: recorded in every run (default: the git
    revision).
    ``rerun``: run every run again, finished or not. ``report_only``: run nothing; take every run folder that holds
    a ``metrics.json``, whatever code made it (each record names its git revision), and report the others failed
    "not_run" (neither failed nor in the tables; the reports list them): for rewriting tables after a change of the
    report code, without rerunning. A finished run an earlier judge wrote gets what it lacks of this one's files and
    trajectory figures (:func:`eval.bench.run_store.complete_run`: aligned trajectories, relative errors). Ctrl-C
    (KeyboardInterrupt) stops the executor and propagates;
    the runs finished before it are stored. ``frame_cache``: simulated frames rendered once per sequence, on the
    executor ahead of the runs (:func:`frames_jobs`; one queue with the runs, :func:`suite_task`), and read back by
    every run, under ``out_root/.frames`` (:mod:`sim_envs.sources.frame_cache`; the same bytes). The runs start longest
    first (:func:`run_order`).
    """
    unknown = [m for m in suite.methods if m not in methods]
    if unknown:
        raise RunnerError(f"suite {suite.name!r}: unknown method(s) {unknown}; valid methods: {', '.join(methods)}")
    if suite.kind is not SuiteKind.RUNS:
        raise RunnerError(f"suite {suite.name!r} is made of parts or runs no agents (kind {suite.kind.value!r}): "
                          "eval.bench.benchmark.run_bench runs every kind")
    out_root = Path(out_root)
    executor = executor or SerialExecutor()
    revision = revision if revision is not None else git_revision()
    checked = check_methods([methods[m] for m in suite.methods], build=check)
    specs = plan_runs(suite, checked.available, renderer=renderer, plots=plots, revision=revision)
    remove_stale_temporaries([run_folder(out_root, s).parent for s in specs])
    outcomes: dict[str, RunOutcome] = {}
    todo = []
    for spec in specs:
        folder = run_folder(out_root, spec)
        if report_only:
            done = (folder / DONE_FILE).is_file()
            outcomes[spec.key] = RunOutcome(spec.key, "cached" if done else "not_run", folder,
                                            None if done else "not run (--report-only runs nothing)")  # fmt: skip
            continue
        spec = replace(spec, known_fingerprint=spec.fingerprint())  # once a run: the check, the worker, the index
        if not rerun and reuse_finished(out_root, spec):  # its own folder, or another suite's run of it
            outcomes[spec.key] = RunOutcome(spec.key, "cached", folder)
        else:
            cache = str(out_root / FRAME_CACHE_DIR) if frame_cache else None
            todo.append(replace(spec, frame_cache=cache))
    renders = frames_jobs(todo, out_root / FRAME_CACHE_DIR) if frame_cache and todo else []
    todo = run_order(todo)
    serial = isinstance(executor, SerialExecutor)
    fn = partial(suite_task, progress=progress and serial)
    with (tqdm(total=len(renders), desc="rendering", unit="sequence", disable=not progress or not renders) as drawn,
          tqdm(total=len(todo), desc=f"{suite.name} runs", unit="run", disable=not progress) as bar):
        for item, result in executor.map(fn, [*renders, *todo]):
            if isinstance(item, FramesJob):
                if isinstance(result, BaseException):
                    logger.warning("rendering %s ahead of its runs failed (%s: %s); its runs render it themselves",
                                   item.key, type(result).__name__, result)
                drawn.update(1)
                if drawn.n == len(renders):
                    drawn.close()  # its time is the rendering's, not the runs' that go on beside it
                continue
            spec = item
            if isinstance(result, BaseException):
                result = RunResult(spec, "failed", error=f"{type(result).__name__}: {result}")
            folder = store_result(out_root, result)
            outcome = RunOutcome(spec.key, result.status, folder, result.error, result.seconds)
            outcomes[spec.key] = outcome
            if on_result is not None:
                on_result(outcome)
            bar.update(1)
            failed = sum(o.status == "failed" for o in outcomes.values())
            if failed:
                bar.set_postfix(failed=failed)
    records, timings = [], {}
    for spec in specs:
        outcome = outcomes[spec.key]
        if outcome.status in ("failed", "not_run"):
            continue
        record = load_run(outcome.folder / DONE_FILE).replace(run=spec.key)
        records.append(complete_run(outcome.folder, spec, record) if outcome.status == "cached" else record)
        timing_path = outcome.folder / "timing.json"
        timings[spec.key] = json.loads(timing_path.read_text()) if timing_path.is_file() else {}
    ordered = {s.key: outcomes[s.key] for s in specs}
    return SuiteRun(suite, out_root, tuple(specs), ordered, checked.skipped, records, timings, checked.available)


def suite_task(item: FramesJob | RunSpec, progress: bool = False) -> int | RunResult:
    """One task of a suite on its executor: a sequence rendered into the frame cache (a :class:`FramesJob`:
    :func:`eval.bench.run.render_frames`, frames rendered) or a run (:func:`eval.bench.run.execute_run`).

    :func:`run_suite` hands the executor the rendering jobs (longest first) and then the runs (longest first) as one
    queue, so that a core that has no sequence left to render starts a run of a sequence already rendered instead of
    waiting for the last one (a run of a sequence still rendering waits for it: ``CachedFrames.filling``). A failed
    rendering job is logged and left to its runs, which render what they miss themselves (and fail with the error)."""
    if isinstance(item, FramesJob):
        return render_frames(item)
    return execute_run(item, progress=progress)
