"""``python -m cnnslam.warmup``: compile the agents' numba kernels into numba's on-disk cache once, at install
(``make venv`` runs it), so that no run pays the JIT's time and memory.

A process that compiles the kernels keeps the JIT's memory: about 95 MiB on a 2-core AMD EPYC, measured with
``python -m cnnslam.bench_slam --memory`` (peak RSS after 1 000 frames 864 MiB with a cold cache against 765-772 MiB
warm; a 10 000-frame episode 1 522 MiB against 1 336 MiB). Numba keeps compiled kernels beside the sources
(``cnnslam/__pycache__``) and recompiles one whose source changed, so a stale cache costs time, never results.

Its parts (``--parts``; all by default), split between ``--jobs`` processes of one math thread each by their usual
time (:func:`split_parts`: with 2, the system and Laina in one, ORB then REMODE in the other, so that the LSD-BS
tracking inside REMODE loads the kernels the system's part has compiled meanwhile):

- ``system`` (:func:`warm_up`) runs the whole two-thread system, global model and ``finish`` included, over the
  first frames of office0 through the default camera: the kernels of tracking, refinement, key-frames, the pose graph
  and the model's fusion and re-placement are all called with the signatures a run uses (38 s with a cold cache on a
  2-core Intel Xeon);
- ``orb``, ``remode``, ``laina`` (:func:`warm_up_baselines`) run the baselines with kernels of their own (ORB's
  features, map and bundle adjustment; REMODE's depth filter and smoothing; Laina's ICP) through ``sim_envs``'
  driver over the first frames of office0, as a suite runs them. Without them the first suite run of each compiled
  them: 22, 21 and 6 s there (a 30-frame run of each in a fresh clone, against the same run again).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

WARMUP_FRAMES = 150  # enough for several key-frames, pose-graph edges and a re-placement at finish
# the baselines whose kernels the system's warm-up does not call: part name -> (entry point, keyword arguments)
BASELINE_AGENTS: dict[str, tuple[str, dict[str, Any]]] = {
    "orb": ("cnnslam.baselines.orb:OrbSlamAgent", {}),
    "remode": ("cnnslam.baselines.remode:RemodeAgent", {"threads": False}),
    "laina": ("cnnslam.baselines.laina:LainaAgent", {}),
}
BASELINE_FRAMES = 40  # ORB's map and bundle adjustment, REMODE's updates and (at finish) its smoothing
PARTS = ("system", *BASELINE_AGENTS)
# about how long each part takes with a cold cache (s, 2-core Intel Xeon, one part a process): how --jobs splits them
PART_SECONDS = {"system": 38.0, "orb": 27.0, "remode": 27.0, "laina": 10.0}
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def warm_up(frames: int = WARMUP_FRAMES, sequence: str = "office0") -> dict[str, Any]:
    """Run the system over ``frames`` frames of ``sequence`` so that numba compiles (or loads) every kernel a run
    uses; returns the run's figures with how many signatures were compiled and how many came from the cache."""
    from cnnslam.bench_slam import memory_benchmark

    return memory_benchmark(sequence, frames, checkpoints=())  # its figures count the kernels


def warm_up_baselines(frames: int = BASELINE_FRAMES, sequence: str = "office0", camera: str = "kinect",
                      agents: tuple[tuple[str, dict[str, Any]], ...] = tuple(BASELINE_AGENTS.values()),
                      ) -> dict[str, Any]:
    """Run each of ``agents`` ("module:Class", keyword arguments) over the first ``frames`` frames of ``sequence``
    through ``camera``, as a suite runs an agent (``sim_envs.driver.run_episode`` on a ``ReplayEnv``; the frames
    rendered once, into a temporary frame cache), so that numba compiles (or loads) their kernels. Returns the
    seconds each agent took, and how many signatures of the loaded ``cnnslam`` kernels were compiled and loaded."""
    import importlib
    import tempfile

    from cnnslam.bench_slam import numba_cache_counts
    from sim_envs.driver import run_episode
    from sim_envs.env import ReplayEnv
    from sim_envs.frame_cache import CachedFrames
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.simsource import SimulatedSequence

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


def split_parts(parts: list[str] | tuple[str, ...], jobs: int) -> list[list[str]]:
    """``parts`` in at most ``jobs`` groups of about equal time (:data:`PART_SECONDS`; the longest first, each to
    the group with the least so far), each group's parts in :data:`PARTS` order."""
    groups: list[list[str]] = [[] for _ in range(max(1, min(int(jobs), len(parts))))]
    totals = [0.0] * len(groups)
    for part in sorted(parts, key=lambda p: -PART_SECONDS.get(p, 0.0)):
        k = totals.index(min(totals))
        groups[k].append(part)
        totals[k] += PART_SECONDS.get(part, 0.0)
    return [sorted(g, key=PARTS.index) for g in groups if g]


def _run_group(group: list[str], frames: int | None) -> str:
    """Warm up the parts of ``group`` in this process; one line saying what was compiled, loaded and how long."""
    start = time.perf_counter()
    seconds: dict[str, float] = {}
    figures: dict[str, Any] = {}
    if "system" in group:
        figures = warm_up(WARMUP_FRAMES if frames is None else frames)
        seconds["system"] = time.perf_counter() - start
    agents = [BASELINE_AGENTS[p] for p in group if p != "system"]
    if agents:
        figures = warm_up_baselines(BASELINE_FRAMES if frames is None else frames, agents=tuple(agents))
        for part in group:
            if part != "system":
                seconds[part] = figures[f"seconds_{BASELINE_AGENTS[part][0].partition(':')[2]}"]
    each = ", ".join(f"{p} {seconds[p]:.0f} s" for p in group)
    return (f"numba warm-up ({each}): {figures['numba_signatures_compiled']} kernel signature(s) compiled, "
            f"{figures['numba_signatures_from_cache']} loaded from the cache, {time.perf_counter() - start:.0f} s")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cnnslam.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=None,
                        help=f"frames to run (default {WARMUP_FRAMES} for the system, {BASELINE_FRAMES} for the "
                             "baselines)")
    parser.add_argument("--jobs", type=int, default=1,
                        help="processes: the parts split between them by their usual time (default 1)")
    parser.add_argument("--parts", nargs="+", choices=PARTS, default=list(PARTS),
                        help="what to warm up (default all: the system and each baseline)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    groups = split_parts(list(dict.fromkeys(args.parts)), args.jobs)
    if len(groups) == 1:
        print(_run_group(groups[0], args.frames), flush=True)
        return 0
    saved = {name: os.environ.get(name) for name in _THREAD_VARIABLES}
    os.environ.update({name: "1" for name in _THREAD_VARIABLES})  # the spawned children's math libraries
    try:
        with ProcessPoolExecutor(len(groups), mp_context=multiprocessing.get_context("spawn")) as pool:
            for line in pool.map(_run_group, groups, [args.frames] * len(groups)):
                print(line, flush=True)
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
