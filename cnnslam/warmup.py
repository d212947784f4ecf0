"""``python -m cnnslam.warmup``: compile the agent's numba kernels into numba's on-disk cache once, at install
(``make venv`` runs it), so that no run pays the JIT's time and memory.

A process that compiles the kernels keeps the JIT's memory: about 95 MiB on a 2-core AMD EPYC, measured with
``python -m cnnslam.bench_slam --memory`` (peak RSS after 1 000 frames 864 MiB with a cold cache against 765-772 MiB
warm; a 10 000-frame episode 1 522 MiB against 1 336 MiB). Numba keeps compiled kernels beside the sources
(``cnnslam/__pycache__``) and recompiles one whose source changed, so a stale cache costs time, never results.

The warm-up runs the whole two-thread system, global model and ``finish`` included, over the first frames of
office0 through the default camera: the kernels of tracking, refinement, key-frames, the pose graph and the model's
fusion and re-placement are all called with the signatures a run uses.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from cnnslam.bench_slam import memory_benchmark

WARMUP_FRAMES = 150  # enough for several key-frames, pose-graph edges and a re-placement at finish


def warm_up(frames: int = WARMUP_FRAMES, sequence: str = "office0") -> dict[str, Any]:
    """Run the system over ``frames`` frames of ``sequence`` so that numba compiles (or loads) every kernel a run
    uses; returns the run's figures with how many signatures were compiled and how many came from the cache."""
    return memory_benchmark(sequence, frames, checkpoints=())  # its figures count the kernels


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m cnnslam.warmup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=WARMUP_FRAMES, help=f"frames to run (default {WARMUP_FRAMES})")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    figures = warm_up(args.frames)
    print(f"numba warm-up: {figures['numba_signatures_compiled']} kernel signature(s) compiled, "
          f"{figures['numba_signatures_from_cache']} loaded from the cache, {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
