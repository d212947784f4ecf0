"""``python -m cnnslam.warmup``: compile the agents' numba kernels into numba's on-disk cache once, at install
(``make venv`` runs it), so that no run pays the JIT's time and memory.

A process that compiles the kernels keeps the JIT's memory: about 95 MiB on a 2-core AMD EPYC, measured with
``python -m cnnslam.bench_slam --memory`` (peak RSS after 1 000 frames 864 MiB with a cold cache against 765-772 MiB
warm; a 10 000-frame episode 1 522 MiB against 1 336 MiB). Numba keeps compiled kernels beside the sources
(``cnnslam/__pycache__``) and recompiles one whose source changed, so a stale cache costs time, never results.

Two parts, run side by side with ``--jobs 2`` (each in its own process, one math thread each):

- :func:`warm_up` runs the whole two-thread system, global model and ``finish`` included, over the first frames of
  office0 through the default camera: the kernels of tracking, refinement, key-frames, the pose graph and the model's
  fusion and re-placement are all called with the signatures a run uses (34 s with a cold cache on a 2-core Intel
  Xeon);
- :func:`warm_up_baselines` runs the baselines with kernels of their own (:data:`BASELINE_AGENTS`: ORB's features,
  map and bundle adjustment; REMODE's depth filter and smoothing; Laina's ICP) through ``sim_envs``' driver over the
  first frames of office0, as a suite runs them. Without it the first suite run of each compiled them: 22, 21 and
  6 s there (a 30-frame run of each in a fresh clone, against the same run again).

Side by side, the baselines of :data:`SYSTEM_SIDE_BASELINES` (Laina, whose global model is the system's) run in the
system's process after it, so that the two processes take about as long: on the 2-core EPYC with AVX-512 the
system's part took 17 s and the baselines' 34 s (ORB 12, REMODE 19 and Laina 9 s from a cold cache, one process).
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from slamcommon.threads import limit_threads

WARMUP_FRAMES = 150  # enough for several key-frames, pose-graph edges and a re-placement at finish
# (entry point, keyword arguments) of the baselines whose kernels the system's warm-up does not call; ORB first:
# the LSD-BS tracking inside REMODE then loads what the system's warm-up, beside it, has compiled meanwhile
BASELINE_AGENTS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("cnnslam.baselines.orb:OrbSlamAgent", {}),
    ("cnnslam.baselines.remode:RemodeAgent", {"threads": False}),
    ("cnnslam.baselines.laina:LainaAgent", {}),
)
BASELINE_FRAMES = 40  # ORB's map and bundle adjustment, REMODE's updates and (at finish) its smoothing
SYSTEM_SIDE_BASELINES: tuple[str, ...] = ("cnnslam.baselines.laina:LainaAgent",)  # (module docstring)


def warm_up(frames: int = WARMUP_FRAMES, sequence: str = "office0") -> dict[str, Any]:
    """Run the system over ``frames`` frames of ``sequence`` so that numba compiles (or loads) every kernel a run
    uses; returns the run's figures with how many signatures were compiled and how many came from the cache."""
    import numpy as np

    from cnnslam.bench_slam import memory_benchmark
    from cnnslam.depth_prediction import perturb_last_bits

    # the seeds > 0 of a suite perturb the network's outputs (and LSD-BS's first depth) in their last bits: the
    # kernel that does it, which a seed-0 run never calls, compiled here too (0.6 s cold)
    perturb_last_bits(np.ones(4, np.float32), np.random.default_rng(1))
    return memory_benchmark(sequence, frames, checkpoints=())  # its figures count the kernels


def warm_up_baselines(frames: int = BASELINE_FRAMES, sequence: str = "office0", camera: str = "kinect",
                      agents: tuple[tuple[str, dict[str, Any]], ...] = BASELINE_AGENTS) -> dict[str, Any]:
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


def _line(label: str, figures: dict[str, Any], seconds: float) -> str:
    return (f"numba warm-up ({label}): {figures['numba_signatures_compiled']} kernel signature(s) compiled, "
            f"{figures['numba_signatures_from_cache']} loaded from the cache, {seconds:.0f} s")


def _baselines_of(side_by_side: bool) -> dict[str, tuple[tuple[str, dict[str, Any]], ...]]:
    """The baselines each part warms up: one after another, all of them in the baselines' part; side by side, those
    of :data:`SYSTEM_SIDE_BASELINES` in the system's part, after it (module docstring), the others in the baselines'."""
    if not side_by_side:
        return {"system": (), "baselines": BASELINE_AGENTS}
    return {"system": tuple(a for a in BASELINE_AGENTS if a[0] in SYSTEM_SIDE_BASELINES),
            "baselines": tuple(a for a in BASELINE_AGENTS if a[0] not in SYSTEM_SIDE_BASELINES)}


def _timed(part: str, frames: int | None, agents: tuple[tuple[str, dict[str, Any]], ...]
           ) -> tuple[dict[str, Any], float]:
    """Run ``part`` ("system": the system, then the baselines ``agents`` if any; "baselines": ``agents``); returns
    the figures of its last call (the kernel counts are the process's) and the seconds it took."""
    start = time.perf_counter()
    if part == "system":
        figures = warm_up(WARMUP_FRAMES if frames is None else frames)
    if part == "baselines" or agents:
        figures = warm_up_baselines(BASELINE_FRAMES if frames is None else frames, agents=agents)
    return figures, time.perf_counter() - start


def _label(part: str, agents: tuple[tuple[str, dict[str, Any]], ...]) -> str:
    if part == "system" and agents:
        return "system, then " + ", ".join(entry.partition(":")[2] for entry, _ in agents)
    return part


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cnnslam.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=None,
                        help=f"frames to run (default {WARMUP_FRAMES} for the system, {BASELINE_FRAMES} for the "
                             "baselines)")
    parser.add_argument("--jobs", type=int, default=1, help="processes: 2 runs the two parts side by side")
    parser.add_argument("--parts", nargs="+", choices=("system", "baselines"), default=["system", "baselines"],
                        help="what to warm up (default both)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs must be >= 1, got {args.jobs}")
    side_by_side = args.jobs > 1 and len(args.parts) > 1
    agents = _baselines_of(side_by_side)
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
