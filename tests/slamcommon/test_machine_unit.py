"""The machine unit (slamcommon.machine_unit): summarised by the median of its timings, so that a timing a
neighbour or a clock tick lengthened does not move it (round 38's CI failure: the mean of process-CPU timings picked
up the process's spinning thread pools)."""

from __future__ import annotations

import time

from slamcommon.machine_unit import unit_summary, units_around


def test_the_summary_is_the_median() -> None:
    """Known answer: one timing a neighbour lengthened does not move the unit."""
    assert unit_summary([1.0, 1.0, 1.1, 0.9, 50.0]) == 1.0


def test_units_around_returns_the_runs_value_and_the_median_of_its_clock() -> None:
    """Known answer with a fake clock: each timing lasts the next step of the clock's sequence."""
    steps = iter([0.0, 1.0, 1.0, 3.0, 3.0, 4.0, 4.0, 104.0])  # timings 1, 2 before; 1, 100 after
    value, unit = units_around(lambda: 42, repeats=2, clock=lambda: next(steps))
    assert value == 42 and unit == 1.5
    assert units_around.__defaults__[-1] is time.thread_time  # the calling thread's CPU time by default
