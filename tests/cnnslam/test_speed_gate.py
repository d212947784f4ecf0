"""The speed gate in CI: tracking and the whole system, in frames per machine unit, against
results/baselines/perf.json (eval.bench.perf.speed_regressions, allowed 1.5x slower).

The first test measures the figures exactly as ``cnnslam bench perf``'s slam probe does (a fresh process), the
second in this process with tracking slowed on purpose; in CPU time, the unit (a frozen reference workload timed in
the same process) carries the machine's speed, so the baseline made on one machine judges another.
"""

from __future__ import annotations

import time

import pytest

import cnnslam.system
from cnnslam.tools.bench_slam import benchmark
from eval.bench.perf import SPEED_GATED, load_probes, load_speed_baseline, run_probe, speed_regressions

pytestmark = pytest.mark.slow  # agent runs timed against a baseline: the full lane (make test), not make check


@pytest.fixture(scope="module")
def baseline():
    return load_speed_baseline()


def test_this_tree_is_not_slower_than_the_baseline(baseline) -> None:
    """Measured exactly as the baseline was: ``cnnslam bench perf``'s slam probe, a fresh process
    (:func:`eval.bench.perf.run_probe`); in this test's process the figures came out 1.1-1.2x lower on the same quiet
    machine (round 38: 0.121-0.153 against 0.147-0.178 frames per unit in the probe), a margin the gate cannot give
    away. Read as benchmarks are: the best of up to three measurements, 10 s apart. The unit, timed for 0.15 s, moves
    by up to 1.5x between timings in one quiet process here (0.64-0.99 ms in CPU time); a real slowdown fails all
    three (the next test injects one and is measured once)."""
    probes, _ = load_probes()
    probe = next(p for p in probes if p.name == "slam")
    failures: list[str] = []
    for attempt in range(3):
        if attempt:
            time.sleep(10.0)
        result = run_probe(probe, baseline.frames)
        assert result.ok, result.error
        figures = result.figures
        assert (figures["sequence"], figures["predictor"], figures["tracked_share"]) == (
            baseline.sequence, baseline.predictor, 1.0)
        failures = speed_regressions(figures, baseline)
        if not failures:
            break
    assert failures == []


def test_a_slowed_tracking_step_fails_the_gate(baseline, monkeypatch) -> None:
    real = cnnslam.system.track_frame

    def three_times_slower(*args, **kwargs):
        real(*args, **kwargs)
        real(*args, **kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(cnnslam.system, "track_frame", three_times_slower)
    figures = benchmark(baseline.sequence, baseline.frames, baseline.predictor)
    failures = speed_regressions(figures, baseline)
    assert any(f.startswith("tracking_frames_per_unit") for f in failures), failures


def test_the_gate_reads_units_and_ratios(baseline) -> None:
    """Known answers: exactly the allowed slowdown passes, just past it fails, another unit never compares."""
    at_limit = {k: baseline.figures[k] / baseline.max_slowdown for k in SPEED_GATED}
    assert speed_regressions({**at_limit, "unit_version": baseline.unit_version}, baseline) == []
    past = {k: v * 0.99 for k, v in at_limit.items()}
    assert len(speed_regressions({**past, "unit_version": baseline.unit_version}, baseline)) == len(SPEED_GATED)
    other = speed_regressions({**baseline.figures, "unit_version": "other/0"}, baseline)
    assert len(other) == 1 and "remake the baseline" in other[0]
