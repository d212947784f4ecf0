"""``python -m cnnslam.tools.warmup``: compile the agents' numba kernels into numba's on-disk cache once, at install
(``make venv`` runs it), so that no run pays the JIT's time and memory.

A process that compiles the kernels keeps the JIT's memory: about 95 MiB on a 2-core AMD EPYC, measured with
``python -m cnnslam.tools.bench_slam --memory`` (peak RSS after 1 000 frames 864 MiB with a cold cache against 765-772
MiB
warm; a 10 000-frame episode 1 522 MiB against 1 336 MiB). Numba keeps compiled kernels beside the sources
(``cnnslam/__pycache__``) and recompiles one whose source changed, so a stale cache costs time, never results.

Two parts, run side by side with ``--jobs 2`` (each in its own process, one math thread each):

- :func:`warm_up` runs the whole two-thread system, global model and ``finish`` included, over the first frames of
  office0 through the default camera: the kernels of tracking, refinement, key-frames, the pose graph and the model's
  fusion and re-placement are all called with the signatures a run uses (34 s with a cold cache on a 2-core Intel
  Xeon);
- :func:`warm_up_baselines` runs the baselines with kernels of their own through ``sim_envs``' driver over the
  first frames of office0, as a suite runs them. Without it the first suite run of each compiled them: 22, 21 and
  6 s there for ORB (features, map, bundle adjustment), REMODE (depth filter, smoothing) and Laina (ICP) (a 30-frame
  run of each in a fresh clone, against the same run again).

Which baselines, built how, comes from the method table's data (:func:`warmup_agents`): every table of
``eval/methods.toml`` with a ``warmup`` field, its ``entry_point`` built with its ``kwargs``; ``warmup = "system"``
(Laina, whose global model is the system's) runs in the system's process after it when the two parts run side by
side, so that the two processes take about as long (on the 2-core EPYC with AVX-512 the system's part took 17 s and
the baselines' 34 s: ORB 12, REMODE 19 and Laina 9 s from a cold cache, one process); ``"baselines"`` in the
baselines' process. The table is read as a file: the agents' package never imports the judge's.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from cnnslam.errors import CnnSlamError
from slamcommon.threads import limit_threads

WARMUP_FRAMES = 150  # enough for several key-frames, pose-graph edges and a re-placement at finish
BASELINE_FRAMES = 40  # ORB's map and bundle adjustment, REMODE's updates and (at finish) its smoothing
# the method table (data beside the judge's code, read as TOML): which agents the warm-up runs (module docstring)
METHODS_FILE: Path = Path(__file__).resolve().parents[2] / "eval" / "methods.toml"
WARMUP_PARTS: tuple[str, ...] = ("system", "baselines")  # the values of a table's `warmup` field
AgentSpec = tuple[str, dict[str, Any]]  # ("module:Class", keyword arguments)


def warmup_agents(path: str | Path = METHODS_FILE) -> dict[str, tuple[AgentSpec, ...]]:
    """``{part: (("module:Class", kwargs), ...)}`` for each part of :data:`WARMUP_PARTS`: the tables of the method
    table at ``path`` with a ``warmup`` field naming that part, in the file's order, each as its ``entry_point`` and
    ``kwargs``. :class:`CnnSlamError` (one line) for a file that cannot be read or a bad ``warmup`` value."""
    path = Path(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8")).get("methods", {})
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise CnnSlamError(f"cannot read the method table {path} ({type(exc).__name__}: {exc}); "
                           "--method-file names another") from None
    parts: dict[str, list[AgentSpec]] = {part: [] for part in WARMUP_PARTS}
    for name, entry in table.items():
        part = entry.get("warmup") if isinstance(entry, dict) else None
        if part is None:
            continue
        if part not in WARMUP_PARTS or not isinstance(entry.get("entry_point"), str):
            raise CnnSlamError(f"{path}: methods.{name}.warmup = {part!r} needs an entry_point and one of "
                               f"{', '.join(WARMUP_PARTS)}")
        parts[part].append((entry["entry_point"], dict(entry.get("kwargs", {}))))
    return {part: tuple(agents) for part, agents in parts.items()}


def warm_up(frames: int = WARMUP_FRAMES, sequence: str = "office0") -> dict[str, Any]:
    """Run the system over ``frames`` frames of ``sequence`` so that numba compiles (or loads) every kernel a run
    uses; returns the run's figures with how many signatures were compiled and how many came from the cache."""
    import numpy as np

    from cnnslam.depth.depth_prediction import perturb_last_bits
    from cnnslam.tools.bench_slam import memory_benchmark

    # the seeds > 0 of a suite perturb the network's outputs (and LSD-BS's first depth) in their last bits: the
    # kernel that does it, which a seed-0 run never calls, compiled here too (0.6 s cold)
    perturb_last_bits(np.ones(4, np.float32), np.random.default_rng(1))
    return memory_benchmark(sequence, frames, checkpoints=())  # its figures count the kernels


def warm_up_baselines(frames: int = BASELINE_FRAMES, sequence: str = "office0", camera: str = "kinect",
                      agents: tuple[AgentSpec, ...] | None = None) -> dict[str, Any]:
    """Run each of ``agents`` ("module:Class", keyword arguments; None: every agent of :func:`warmup_agents`) over
    the first ``frames`` frames of ``sequence`` through ``camera``, as a suite runs an agent
    (``sim_envs.driver.run_episode`` on a ``ReplayEnv``; the frames rendered once, into a temporary frame cache), so
    that numba compiles (or loads) their kernels. Returns the seconds each agent took, and how many signatures of the
    loaded ``cnnslam`` kernels were compiled and loaded."""
    import importlib
    import tempfile

    from cnnslam.tools.bench_slam import numba_cache_counts
    from sim_envs.driver import run_episode
    from sim_envs.env import ReplayEnv
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.frame_cache import CachedFrames
    from sim_envs.sources.simsource import SimulatedSequence

    if agents is None:
        agents = tuple(a for part in warmup_agents().values() for a in part)
    figures: dict[str, Any] = {"frames": int(frames)}
    spec = with_camera(get_sequence(sequence), camera)
    with tempfile.TemporaryDirectory(prefix="cnnslam-warmup-") as folder, SimulatedSequence(spec) as live:
        source = CachedFrames(live, folder)
        for entry_point, kwargs in agents:
            start = time.perf_counter()
            module, _, name = entry_point.partition(":")
            agent = getattr(importlib.import_module(module), name)(**kwargs)
            run_episode(ReplayEnv(source), agent, max_frames=int(frames), progress=False)
            figures[f"seconds_{name}"] = time.perf_counter() - start
    figures.update(numba_cache_counts())
    return figures


def _line(label: str, figures: dict[str, Any], seconds: float) -> str:
    return (f"numba warm-up ({label}): {figures['numba_signatures_compiled']} kernel signature(s) compiled, "
            f"{figures['numba_signatures_from_cache']} loaded from the cache, {seconds:.0f} s")


def _baselines_of(side_by_side: bool, path: str | Path = METHODS_FILE) -> dict[str, tuple[AgentSpec, ...]]:
    """The baselines each part warms up (:func:`warmup_agents` of ``path``): one after another, all of them in the
    baselines' part (the system's first, then the others, in the table's order); side by side, those of
    ``warmup = "system"`` in the system's part, after it (module docstring), the others in the baselines'."""
    parts = warmup_agents(path)
    if not side_by_side:
        return {"system": (), "baselines": parts["system"] + parts["baselines"]}
    return parts


def _timed(part: str, frames: int | None, agents: tuple[AgentSpec, ...]) -> tuple[dict[str, Any], float]:
    """Run ``part`` ("system": the system, then the baselines ``agents`` if any; "baselines": ``agents``); returns
    the figures of its last call (the kernel counts are the process's) and the seconds it took."""
    start = time.perf_counter()
    if part == "system":
        figures = warm_up(WARMUP_FRAMES if frames is None else frames)
    if part == "baselines" or agents:
        figures = warm_up_baselines(BASELINE_FRAMES if frames is None else frames, agents=agents)
    return figures, time.perf_counter() - start


def _label(part: str, agents: tuple[AgentSpec, ...]) -> str:
    if part == "system" and agents:
        return "system, then " + ", ".join(entry.partition(":")[2] for entry, _ in agents)
    return part


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cnnslam.tools.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=None,
                        help=f"frames to run (default {WARMUP_FRAMES} for the system, {BASELINE_FRAMES} for the "
                             "baselines)")
    parser.add_argument("--jobs", type=int, default=1, help="processes: 2 runs the two parts side by side")
    parser.add_argument("--parts", nargs="+", choices=("system", "baselines"), default=["system", "baselines"],
                        help="what to warm up (default both)")
    parser.add_argument("--method-file", default=str(METHODS_FILE),
                        help="the method table whose `warmup` entries name the baselines (default eval/methods.toml)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    side_by_side = args.jobs > 1 and len(args.parts) > 1
    try:
        agents = _baselines_of(side_by_side, args.method_file)
    except CnnSlamError as exc:
        parser.error(str(exc))
    if not side_by_side:
        for part in args.parts:
            figures, seconds = _timed(part, args.frames, agents[part])
            print(_line(_label(part, agents[part]), figures, seconds), flush=True)
        return 0
    with ProcessPoolExecutor(min(args.jobs, len(args.parts)), mp_context=multiprocessing.get_context("spawn"),
                             initializer=limit_threads, initargs=(1,)) as pool:  # one math thread a process
        futures = [(part, pool.submit(_timed, part, args.frames, agents[part])) for part in args.parts]
        for part, future in futures:
            figures, seconds = future.result()
            print(_line(_label(part, agents[part]), figures, seconds), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
