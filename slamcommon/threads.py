"""How many threads a process's math libraries may use: set by the judge's pool workers (:mod:`eval.bench.executors`)
and the agent's install-time warm-up (:mod:`cnnslam.tools.warmup`) alike."""

from __future__ import annotations

import os

# the BLAS libraries' thread counts (numpy's linear algebra; read once, when numpy loads its BLAS) ...
BLAS_THREAD_VARIABLES: tuple[str, ...] = ("MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")
# ... and every math library's: OpenMP (torch) and numba's too
THREAD_VARIABLES: tuple[str, ...] = ("OMP_NUM_THREADS", *BLAS_THREAD_VARIABLES, "NUMBA_NUM_THREADS")
# Mesa's software rasteriser (llvmpipe, the offscreen renderer's OpenGL without a GPU; read when a process opens its
# first GL display): its count of rasteriser threads beside the calling one, 0 = rasterise on the calling thread.
# One thread a process is 0, not 1: with 1 the caller hands every frame to one worker and waits (rendering office2 in
# one process on the 2-core EPYC: 20.1 ms a frame unset or 1, 17.4 ms with 0; two processes side by side 23.3 ->
# 22.7 ms; the same bytes)
RASTERISER_THREAD_VARIABLE = "LP_NUM_THREADS"


def thread_environment(threads: int) -> dict[str, str]:
    """The environment variables that limit a process's math libraries and its software rasteriser to ``threads``
    threads (set them before the libraries load)."""
    threads = int(threads)
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    env = dict.fromkeys(THREAD_VARIABLES, str(threads))
    env[RASTERISER_THREAD_VARIABLE] = "0" if threads == 1 else str(threads)
    return env


def limit_threads(threads: int) -> None:
    """Limit this process's math libraries (and its software rasteriser, :func:`thread_environment`) to ``threads``
    threads (call before they are imported: a pool's initializer). OpenCV, when already imported, is limited
    directly."""
    os.environ.update(thread_environment(threads))
    try:
        import cv2

        cv2.setNumThreads(int(threads))
    except ImportError:  # OpenCV is a dependency; without it there is nothing to limit
        pass
