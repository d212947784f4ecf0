"""The machine-speed unit: a frozen reference workload timed in the same process as a speed figure, so that
figures from machines of other speeds, or under other loads, compare: a frames-per-second figure times the unit's
seconds is frames per unit, the currency of the speed gates (``eval.bench.perf.speed_regressions`` for CNN-SLAM's
benchmark, ``eval.bench.suite_speed`` for every run of a suite). Defined once here, where the agent's benchmark
(``cnnslam.tools.bench_slam``) and the judge's runs (``eval.bench.run``) both time it.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np
from numba import njit

T = TypeVar("T")

# ------------------------------------------------------------------------------------------- the machine-speed unit
# A fixed workload timed in the same process as the figures, so that fps from machines of other speeds, or under
# other loads, can be compared: a figure times the unit's seconds is frames per unit (the speed gate's currency,
# eval.bench.perf.speed_regressions). The workload is frozen: it calls nothing of the project (a change to tracking must
# not move the unit), and editing it invalidates results/baselines/perf.json (bump UNIT_VERSION, remake the baseline).
# Its mix is tracking's: a rigid warp, bilinear samples of an interleaved float32 image, divisions, a square root and
# the 21 products of a 6x6 normal equation per point, in a numba loop.
# /2: timed in the calling thread's CPU time (time.thread_time) and summarised by the median: the process's CPU time
# (/1) also counts the library thread pools spinning after a run (torch's OpenMP workers after the network), which
# moved the gate's figures with no change to the code (measurements: results/perf_history.md).

UNIT_VERSION = "warp-bilinear-6x6/2"
_UNIT_POINTS = 20000


@njit(cache=True, nogil=True, fastmath=True)
def _unit_kernel(image: np.ndarray, points: np.ndarray, rounds: int) -> float:  # pragma: no cover - numba
    h, w = image.shape[0], image.shape[1]
    total = 0.0
    for k in range(rounds):
        c, s = np.cos(0.01 * k), np.sin(0.01 * k)
        H = np.zeros((6, 6))
        g = np.zeros(3)
        J = np.zeros(6)
        for i in range(points.shape[0]):
            x = c * points[i, 0] - s * points[i, 2] + 0.01 * k
            y = points[i, 1]
            z = s * points[i, 0] + c * points[i, 2]
            iz = 1.0 / z
            u = 250.0 * x * iz + 160.0
            v = 250.0 * y * iz + 120.0
            if not (u > 1.0 and v > 1.0 and u < w - 2.0 and v < h - 2.0):
                continue
            iu, iv = int(u), int(v)
            au, av = u - iu, v - iv
            for ch in range(3):
                g[ch] = ((1.0 - au) * (1.0 - av) * image[iv, iu, ch] + au * (1.0 - av) * image[iv, iu + 1, ch]
                         + (1.0 - au) * av * image[iv + 1, iu, ch] + au * av * image[iv + 1, iu + 1, ch])
            wgt = 1.0 / np.sqrt(16.0 + g[0] * g[0] * 1e-3)
            J[0], J[1], J[2] = g[1] * iz, g[2] * iz, -(g[1] * x + g[2] * y) * iz * iz
            J[3], J[4], J[5] = g[1] * y, g[2] * x, g[0] * iz
            for a in range(6):
                for b in range(a, 6):
                    H[a, b] += wgt * J[a] * J[b]
        total += H[0, 0] + H[5, 5]
    return total


_UNIT_DATA: tuple[np.ndarray, np.ndarray] | None = None


def machine_unit_seconds(clock: Callable[[], float] = time.perf_counter) -> float:
    """Seconds of one unit of the frozen reference workload (20 000 points warped, sampled and accumulated), timed
    in this process by ``clock`` (default wall time; ``time.process_time``: this process's CPU time); compiled and
    warmed on first use."""
    global _UNIT_DATA
    if _UNIT_DATA is None:
        rng = np.random.default_rng(0)
        image = rng.uniform(0.0, 255.0, (240, 320, 3)).astype(np.float32)
        points = np.column_stack([rng.uniform(-1.2, 1.2, _UNIT_POINTS), rng.uniform(-0.9, 0.9, _UNIT_POINTS),
                                  rng.uniform(1.0, 4.0, _UNIT_POINTS)]).astype(np.float32)
        _UNIT_DATA = (image, points)
        _unit_kernel(image, points, 1)
    t0 = clock()
    _unit_kernel(*_UNIT_DATA, 1)
    return clock() - t0


def units_around(run: Callable[[], T], repeats: int = 60,
                 clock: Callable[[], float] = time.thread_time) -> tuple[T, float]:
    """``run()``'s value and the median machine unit, timed by ``clock`` (default this thread's CPU time, which
    neither other processes nor this process's other threads inflate), over ``repeats`` back-to-back timings just
    before it and as many just after (about 0.1 s in all)."""
    before = [machine_unit_seconds(clock) for _ in range(repeats)]
    value = run()
    after = [machine_unit_seconds(clock) for _ in range(repeats)]
    return value, unit_summary(before + after)


def unit_summary(timings: list[float]) -> float:
    """The unit's seconds from repeated timings: their median (a timing a cache-hungry neighbour or an interrupt
    lengthened does not move it)."""
    return float(np.median(timings))
