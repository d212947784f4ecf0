"""The machine unit (slamcommon.machine_unit): timed in the calling thread's CPU time, so that the process's other
threads working or spinning (a thread pool after a network call) do not move it; round 38's CI failed when the unit,
then timed in the process's CPU time, read 2x in a quiet process with spinning threads."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from numba import njit

from slamcommon.machine_unit import machine_unit_seconds, unit_summary, units_around


@njit(nogil=True, cache=True)
def _spin_chunk(n: int) -> float:  # pragma: no cover - numba
    """About a millisecond of busy work without the GIL (a thread pool's worker spinning)."""
    total = 0.0
    for i in range(n):
        total += np.sqrt(i + total * 1e-12)
    return total


def _spin_until(stop: threading.Event) -> None:
    while not stop.is_set():
        _spin_chunk(500_000)


def test_the_unit_is_timed_in_this_thread_only() -> None:
    """The same unit with another thread of the process busy beside it: not inflated (in the process's CPU time
    it counts both threads: about twice as long where the other thread has a core)."""
    machine_unit_seconds(time.thread_time)  # compiled and warmed
    _spin_chunk(10)
    _, quiet = units_around(lambda: None, repeats=40)
    stop = threading.Event()
    worker = threading.Thread(target=_spin_until, args=(stop,))
    worker.start()
    try:
        time.sleep(0.05)
        p0, t0 = time.process_time(), time.thread_time()
        _, busy = units_around(lambda: None, repeats=40)
        other = (time.process_time() - p0) / max(time.thread_time() - t0, 1e-9) - 1.0
    finally:
        stop.set()
        worker.join()
    if other < 0.5:
        pytest.skip(f"the other thread got {other:.0%} of a core beside the unit (a loaded machine): nothing to test")
    assert busy < 1.4 * quiet, (busy, quiet, other)


def test_the_summary_is_the_median() -> None:
    """Known answer: one timing a neighbour lengthened does not move the unit."""
    assert unit_summary([1.0, 1.0, 1.1, 0.9, 50.0]) == 1.0
    value, unit = units_around(lambda: 42, repeats=3)
    assert value == 42 and unit > 0
