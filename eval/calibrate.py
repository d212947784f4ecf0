"""Measure how much a suite's gated figures move on an unchanged tree, and turn that into the gate's tolerances.

"Deterministic", as this project means it:

- **same machine, same configuration: same bytes.** A run's ``metrics.json`` is a function of its fingerprint
  (method, inputs, agent source, sequence, seed, frames) on one machine with one thread count and math back-end;
- **another CPU, thread count or math back-end: within the calibrated tolerance.** The network's float32 outputs
  differ there in their last bits and the SLAM system amplifies that; the gate allows each gated figure
  ``max(k x spread, floor)`` (:func:`eval.regress.calibrate`), where ``spread`` is what this module measures: how
  far each gated figure's median, and each single run's value, moved over the matrix.

The perturbation matrix (:data:`MATRIX`) runs the suite, with all its runs per cell, once per configuration:

- ``reference``: 2 runs at a time, one math thread per run (how CI runs the gate);
- ``threads2``: 1 run at a time, two math threads per run (other reduction orders in torch, OpenCV, numba);
- ``onednn-off``: torch's oneDNN kernels off (``CNNSLAM_ONEDNN=0``: another math back-end);
- ``another-cpu``: the network's outputs perturbed in their last bits in every run, seed 0 included
  (``CNNSLAM_NET_JITTER``: what another CPU does to them; see ``cnnslam/depthnet/predict.py``).

The environment variables reach the runs because the local executor's workers are spawned from this process. Each
configuration's runs go to their own folder (``<out>/calibrate/<name>/``): the fingerprint does not cover the
environment, so they must not share one. ``cnnslam bench quick --calibrate`` runs this and writes the baseline.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval.executors import LocalExecutor
from eval.regress import CALIBRATION_K, Baseline, calibrate, gate_metrics, seed_figures
from eval.runner import SuiteRun, run_suite
from eval.suites import Suite


@dataclass(frozen=True)
class Perturbation:
    """One configuration of the matrix: ``jobs`` runs at a time (math threads per run = cores / jobs) and
    environment variables set for the runs."""

    name: str
    jobs: int
    env: dict[str, str] = field(default_factory=dict)
    description: str = ""


MATRIX: tuple[Perturbation, ...] = (
    Perturbation("reference", 2, {}, "2 runs at a time, 1 math thread per run (as CI runs the gate)"),
    Perturbation("threads2", 1, {}, "1 run at a time, 2 math threads per run"),
    Perturbation("onednn-off", 2, {"CNNSLAM_ONEDNN": "0"}, "torch's oneDNN kernels off"),
    Perturbation("another-cpu", 2, {"CNNSLAM_NET_JITTER": "1009"},
                 "the network's outputs perturbed in their last bits (2 ulp) in every run, seed 0 included"),
)  # fmt: skip


@contextmanager
def environment(env: Mapping[str, str]) -> Iterator[None]:
    """Set ``env`` in this process (and so in the workers it spawns) for the duration; restore afterwards."""
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def run_configuration(suite: Suite, methods: Mapping[str, Any], out_root: Path, config: Perturbation,
                      progress: bool = True) -> SuiteRun:
    """The suite's runs under one configuration of the matrix, in ``out_root / config.name``."""
    with environment(config.env):
        return run_suite(suite, methods, Path(out_root) / config.name, executor=LocalExecutor(jobs=config.jobs),
                         plots=False, progress=progress)  # fmt: skip


def measure(
    suite: Suite,
    methods: Mapping[str, Any],
    out_root: str | Path,
    matrix: Sequence[Perturbation] = MATRIX,
    progress: bool = True,
    on_config: Callable[[Perturbation, SuiteRun], None] | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """The run records of ``suite`` under every configuration of ``matrix`` (configuration name -> records); runs
    already finished in a configuration's folder are reused."""
    records: dict[str, list[dict[str, Any]]] = {}
    for config in matrix:
        run = run_configuration(suite, methods, Path(out_root) / "calibrate", config, progress)
        if on_config is not None:
            on_config(config, run)
        records[config.name] = list(run.records)
    return records


def calibrated_baseline(suite: Suite, records: Mapping[str, Sequence[Mapping[str, Any]]], description: str,
                        matrix: Sequence[Perturbation] = MATRIX, k: float = CALIBRATION_K) -> Baseline:
    """The baseline of the configurations' run records (:func:`measure`): the reference configuration's gated
    figures, tolerances from how far the medians and the single runs moved over the matrix."""
    how = (
        f"cnnslam bench {suite.name} --calibrate: {len(suite.seeds)} runs per cell (seeds "
        f"{', '.join(map(str, suite.seeds))}), gated figure = median over the runs; spread = the larger of the range "
        "of each gated figure and the largest range of one seed's value over the configurations: "
        + "; ".join(f"{c.name}: {c.description}" for c in matrix)
        + f"; allowed change = max({k:g} x spread, the rule's floor)"
    )
    figures = {name: gate_metrics(rs) for name, rs in records.items()}
    runs = {name: seed_figures(rs) for name, rs in records.items()}
    return calibrate(figures, matrix[0].name, k=k, description=description, how=how, runs=runs)
