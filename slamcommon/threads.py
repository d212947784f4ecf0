"""How many threads a process's math libraries may use: set by the judge's pool workers (:mod:`eval.bench.executors`)
and the agent's install-time warm-up (:mod:`cnnslam.warmup`) alike."""

from __future__ import annotations

import os

# the BLAS libraries' thread counts (numpy's linear algebra; read once, when numpy loads its BLAS) ...
BLAS_THREAD_VARIABLES: tuple[str, ...] = ("MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")
# ... and every math library's: OpenMP (torch) and numba's too
THREAD_VARIABLES: tuple[str, ...] = ("OMP_NUM_THREADS", *BLAS_THREAD_VARIABLES, "NUMBA_NUM_THREADS")


def limit_threads(threads: int) -> None:
    """Limit this process's math libraries to ``threads`` threads (call before they are imported: a pool's
    initializer). OpenCV, when already imported, is limited directly."""
    for name in THREAD_VARIABLES:
        os.environ[name] = str(int(threads))
    try:
        import cv2

        cv2.setNumThreads(int(threads))
    except ImportError:  # OpenCV is a dependency; without it there is nothing to limit
        pass
