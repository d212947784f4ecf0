"""Where a suite's time goes, per method: the stages of its runs (:data:`eval.bench.run.STAGES`, from each run's
``timing.json``) summed over the method's runs, in milliseconds per frame, beside its frames per second end to end.

:func:`measure` (the command: ``python -m eval.commands.cli_profile [--sequences office0@kinect] [--frames 100]
[--methods ...] [--jobs 1] [--threads 1] [--json]``) renders the sequences into a fresh frame cache (timed: the
rendering a suite does once, ahead of its runs), runs each method once as a Table-1 suite would
(``eval.bench.run_bench``, fresh worker processes, plots on; by default the Table-1 suite's own methods,
:data:`eval.bench.suites.TABLE1_METHODS`, a method this machine cannot run, an optional third-party system, skipped
with its reason as the suite skips it), and the command prints the table (Markdown, or one
JSON object with ``--json``: the perf suite's ``suite`` probe, ``eval/perf.toml``, shown in ``results/perf.md``).
One job at a time by default, so that runs do not slow each other down, with one math thread per run as in a 2-job
suite on 2 cores (``make bench``; ``--threads``); the figures depend on the machine and its load, and are measured,
never asserted.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eval.bench.perf import format_table  # noqa: F401  (defined in perf, whose table probes print it)
from eval.bench.run import STAGES
from eval.metrics.catalogue import WALL_S

DEFAULT_SEQUENCES = ("office0@kinect",)
DEFAULT_FRAMES = 100


@dataclass(frozen=True)
class MethodProfile:
    """One method's runs: how many, their frames, their wall seconds and the seconds of each stage (summed)."""

    method: str
    runs: int
    frames: int
    seconds: float  # wall-clock, summed over the runs
    stages: dict[str, float]

    @property
    def fps(self) -> float:
        """Frames per second end to end (frames over the runs' wall time)."""
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def ms_per_frame(self, stage: str) -> float:
        """Milliseconds per frame spent in ``stage`` (0 when the runs had none)."""
        return 1e3 * self.stages.get(stage, 0.0) / self.frames if self.frames else 0.0


def profile_runs(runs: Iterable[tuple[str, int, Mapping[str, Any]]]) -> list[MethodProfile]:
    """Per method, in first-seen order: ``runs`` are (method, frames, timing.json content) of finished runs; a run
    without stages (made before they were recorded) counts in frames and wall time only."""
    acc: dict[str, dict[str, Any]] = {}
    for method, frames, timing in runs:
        a = acc.setdefault(method, {"runs": 0, "frames": 0, "seconds": 0.0, "stages": dict.fromkeys(STAGES, 0.0)})
        a["runs"] += 1
        a["frames"] += int(frames)
        a["seconds"] += float(timing.get(WALL_S.key) or 0.0)
        for stage, seconds in (timing.get("stages") or {}).items():
            a["stages"][stage] = a["stages"].get(stage, 0.0) + float(seconds)
    return [MethodProfile(m, a["runs"], a["frames"], a["seconds"], a["stages"]) for m, a in acc.items()]


def suite_profile(suite_run: Any) -> list[MethodProfile]:
    """The profile of a :class:`eval.bench.runner.SuiteRun`'s finished runs (its records and timings)."""
    return profile_runs((r.method, int(r.metrics.get("frames", 0)), suite_run.timings.get(r.run or "", {}))
                        for r in suite_run.records)


def profile_table(profiles: Sequence[MethodProfile]) -> dict[str, Any]:
    """JSON-ready: ``columns`` (method, runs, frames, fps, the wall seconds under the key of
    :data:`eval.metrics.catalogue.WALL_S`, then each stage in ms per frame) and ``rows``."""
    columns = ["method", "runs", "frames", "fps", WALL_S.key, *(f"{s}_ms" for s in STAGES)]
    rows = [[p.method, p.runs, p.frames, round(p.fps, 2), round(p.seconds, 2),
             *(round(p.ms_per_frame(s), 2) for s in STAGES)] for p in profiles]
    return {"columns": columns, "rows": rows}


def measure(sequences: Sequence[str] = DEFAULT_SEQUENCES, frames: int = DEFAULT_FRAMES,
            methods: Sequence[str] | None = None, jobs: int = 1, threads: int = 1) -> dict[str, Any]:
    """Render ``sequences`` (first ``frames`` frames) into a fresh frame cache, run each of ``methods`` (None: the
    Table-1 suite's, those this machine cannot run skipped) once on each as the Table-1 suite does (``jobs`` at a
    time, ``threads`` math threads each), and return :func:`profile_table` with the rendering's milliseconds per
    frame, the suite's wall seconds, the machine's load and the methods skipped (their names, comma-separated)."""
    import os

    from eval.bench import BenchOptions, run_bench
    from eval.bench.benchmark import ExecutorOptions
    from eval.bench.regress import GateAction
    from eval.bench.run import FRAME_CACHE_DIR, FramesJob, render_frames
    from eval.bench.sequence_resolve import resolve_sequence

    with tempfile.TemporaryDirectory(prefix="cnnslam-profile-") as tmp:
        out = Path(tmp)
        t0 = time.perf_counter()
        for name in sequences:
            render_frames(FramesJob(resolve_sequence(name), frames, "mujoco", str(out / FRAME_CACHE_DIR)))
        render_s = time.perf_counter() - t0
        options = BenchOptions(sequences=tuple(sequences), frames=frames, runs=1, out=out, results=out / "reports",
                               gate=GateAction.OFF, progress=False,
                               executor=ExecutorOptions(jobs=jobs, threads=threads))
        t1 = time.perf_counter()
        outcome = run_bench("table1", None if methods is None else list(methods), options)
        suite_s = time.perf_counter() - t1
        profiles = [p for _, part in outcome.parts for p in suite_profile(part)]
    return {**profile_table(profiles), "sequences": list(sequences), "frames": frames, "jobs": jobs, "threads": threads,
            "rendering_ms_per_frame": round(1e3 * render_s / max(1, frames * len(sequences)), 2),
            "suite_wall_s": round(suite_s, 1), "failed_runs": len(outcome.failed),
            "skipped_methods": ", ".join(s.name for s in outcome.skipped if s.what == "method"),
            "load_average_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None}
