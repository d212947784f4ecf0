"""Suites and runs: the method table, sequences, suites, one run and its folder, a suite's runs on an executor, the
regression gate and its calibration, throughput (see :mod:`eval` for the modules), and the benchmark as one library
call, :func:`run_bench` (:mod:`eval.bench.benchmark`; ``cnnslam bench`` is a thin shell around it)::

    from eval.bench import BenchOptions, run_bench

    outcome = run_bench("table1", ["CNN-SLAM", "LSD"], BenchOptions(sequences=("office0",), frames=300))
"""

from typing import Any

_API = ("BenchOptions", "BenchOutcome", "ExecutorOptions", "GateAction", "RunRow", "Skip", "prepare", "run_bench")


def __getattr__(name: str) -> Any:
    """The benchmark call and its types, imported on first use (the package's modules import without them)."""
    if name in _API:
        from eval.bench import benchmark

        return getattr(benchmark, name)
    raise AttributeError(f"module 'eval.bench' has no attribute {name!r}")


__all__ = list(_API)
