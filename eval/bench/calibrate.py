"""Measure how much a suite's gated figures move on an unchanged tree, and turn that into the gate's tolerances.

"Deterministic", as this project means it:

- **same machine, same configuration: same bytes.** A run's ``metrics.json`` is a function of its fingerprint
  (method, inputs, agent source, sequence, seed, frames) on one machine with one thread count and math back-end;
- **another CPU, thread count or math back-end: within the calibrated tolerance.** The network's float32 outputs
  differ there in their last bits and the SLAM system amplifies that; the gate allows each gated figure
  ``max(k x spread, floor)`` (:func:`eval.bench.regress.calibrate`), where ``spread`` is what this module measures: how
  far each gated figure's median, and each single run's value, moved over the matrix.

The perturbation matrix (:data:`MATRIX`) runs the suite, with all its runs per cell, once per configuration:

- ``reference``: 2 runs at a time, one math thread per run (how CI runs the gate);
- ``threads2``: 1 run at a time, two math threads per run (other reduction orders in torch, OpenCV, numba);
- ``onednn-off``: torch's oneDNN kernels off for the network (predictor option ``onednn = false``: another math
  back-end);
- ``another-cpu``: the network's outputs perturbed in their last bits in every run, seed 0 included (predictor
  option ``jitter_seed_fallback``: what another CPU does to them; see ``cnnslam/depthnet/predict.py``);
- ``another-isa``: every numeric library of the stack on an older instruction set than this CPU's (:data:`OLDER_ISA`:
  OpenBLAS's Sandy Bridge kernels, numpy's and OpenCV's dispatch without AVX2/FMA, numba compiling for a generic
  x86-64, torch's ATen kernels without vectorisation and oneDNN up to SSE4.1). Another CPU changes the bytes of the
  methods without a network too (LSD, LSD-BS: their reductions and BLAS calls); this configuration makes this
  machine do the same. Measured: the quick suite's LSD-BS and LSD figures moved as much under it on an AMD EPYC
  (AVX2) as between that machine and an Intel Xeon (AVX-512) (docs/benchmarks.md, "Which machine").

An allowed change that could never be crossed inside its metric's bounds is made crossable
(:func:`eval.bench.gate_baseline.cap_to_cross`), so every gated figure can fail: where the figure's own noise
(k x spread) reaches its bound (a rotation error of 51.9 deg moving by 60.7 deg: 3 x 60.7 > the 128 deg left to 180)
no tolerance both absorbs that noise and can fail, and the figure is left out of the gate, listed; where a rule's floor
does (a correct depth of 0.1 % under the 0.3-point floor), the allowance is capped to
:data:`eval.bench.gate_baseline.CROSSABLE_SHARE` of the room between the figure and its worst value.

Other machines: ``--calibrate`` also writes this machine's reference figures to ``<baseline dir>/machines/<suite>/``
(:func:`machine_record`), and folds every such record of another machine into the spread as one more configuration
(``machine:<label>``) when it was made from the same runs: the same run fingerprints (agents, inputs, sequences,
seeds), so an intended change of results leaves the older records out (reported) until they are made again there.
The matrix emulates another CPU; a record measures one.

A configuration's predictor options are merged into the ``predictor_options`` keyword of every method whose seed
reaches the network (``predictor_options.jitter_seed`` among its seed targets): they become part of its method
definition and so of every run's fingerprint. The instruction-set configuration is the numeric libraries' own
environment variables (which CPU the stack believes it runs on, not a parameter of ours); they reach the runs because
the local executor's workers are spawned from this process. Each configuration's runs go to their own folder
(``<out>/calibrate/<name>/``). ``cnnslam bench quick --calibrate`` runs this and writes the baseline.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval.bench.environment import machine_description
from eval.bench.executors import LocalExecutor
from eval.bench.gate_baseline import CALIBRATION_K, CROSSABLE_SHARE, Baseline
from eval.bench.method_settings import with_predictor_options
from eval.bench.regress import calibrate, gate_metrics, seed_figures
from eval.bench.runner import SuiteRun, run_suite
from eval.bench.suites import Suite
from eval.metrics.results import RunRecord, json_ready


@dataclass(frozen=True)
class Perturbation:
    """One configuration of the matrix: ``jobs`` runs at a time (math threads per run = cores / jobs), the numeric
    libraries' environment variables set for the runs, and ``predictor_options`` given to every method whose seed
    reaches the network (explicit: part of its runs' fingerprints)."""

    name: str
    jobs: int
    env: dict[str, str] = field(default_factory=dict)
    description: str = ""
    predictor_options: dict[str, Any] = field(default_factory=dict)

    def methods(self, methods: Mapping[str, Any]) -> dict[str, Any]:
        """``methods`` with :attr:`predictor_options` merged into the network methods' ``predictor_options``."""
        if not self.predictor_options:
            return dict(methods)
        return {name: (with_predictor_options(m, self.predictor_options)
                       if "predictor_options.jitter_seed" in getattr(m, "seed_targets", ()) else m)
                for name, m in methods.items()}


# Environment variables read by the libraries at import: each selects an older code path than the CPU offers.
OLDER_ISA: dict[str, str] = {
    "OPENBLAS_CORETYPE": "Sandybridge",
    "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
    "OPENCV_CPU_DISABLE": "AVX2,FMA3",
    "NUMBA_CPU_NAME": "generic",
    "ATEN_CPU_CAPABILITY": "default",
    "ONEDNN_MAX_CPU_ISA": "SSE41",
}

MATRIX: tuple[Perturbation, ...] = (
    Perturbation("reference", 2, {}, "2 runs at a time, 1 math thread per run (as CI runs the gate)"),
    Perturbation("threads2", 1, {}, "1 run at a time, 2 math threads per run"),
    Perturbation("onednn-off", 2, {}, "torch's oneDNN kernels off", {"onednn": False}),
    Perturbation("another-cpu", 2, {},
                 "the network's outputs perturbed in their last bits (2 ulp) in every run, seed 0 included",
                 {"jitter_seed_fallback": 1009}),
    Perturbation("another-isa", 2, OLDER_ISA,
                 "every numeric library on an older instruction set (BLAS, numpy, OpenCV, numba, torch, oneDNN)"),
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
                      progress: bool = True, renderer: str = "mujoco", timeout_s: float | None = None) -> SuiteRun:
    """The suite's runs under one configuration of the matrix, in ``out_root / config.name``, rendered with
    ``renderer``, each stopped after ``timeout_s`` seconds (None: no limit)."""
    with environment(config.env):
        return run_suite(suite, config.methods(methods), Path(out_root) / config.name,
                         executor=LocalExecutor(jobs=config.jobs, timeout_s=timeout_s), renderer=renderer,
                         plots=False, progress=progress)  # fmt: skip


def measure(
    suite: Suite,
    methods: Mapping[str, Any],
    out_root: str | Path,
    matrix: Sequence[Perturbation] = MATRIX,
    progress: bool = True,
    on_config: Callable[[Perturbation, SuiteRun], None] | None = None,
    renderer: str = "mujoco",
    timeout_s: float | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """The run records of ``suite`` under every configuration of ``matrix`` (configuration name -> records); runs
    already finished in a configuration's folder are reused. ``renderer`` and ``timeout_s``: as for every run of
    the suite; the pools are the configurations' own (their job counts are part of the matrix)."""
    records: dict[str, list[RunRecord]] = {}
    for config in matrix:
        run = run_configuration(suite, methods, Path(out_root) / "calibrate", config, progress, renderer, timeout_s)
        if on_config is not None:
            on_config(config, run)
        records[config.name] = list(run.records)
    return records


def run_fingerprints(records: Sequence[RunRecord]) -> list[str]:
    """The sorted fingerprints of a configuration's runs: what two machines must share for their figures to be
    compared (the same agents, inputs, sequences, seeds and frames)."""
    return sorted({str(r.metadata["fingerprint"]) for r in records})


def machine_record(suite: Suite, records: Sequence[RunRecord], revision: str = "") -> dict[str, Any]:
    """This machine's reference figures of ``suite`` (:func:`gate_metrics` of the reference configuration's run
    records), with the machine (:func:`eval.bench.environment.machine_description`), the run fingerprints and the git
    revision: what another machine's calibration folds in (:func:`load_machine_records`)."""
    return {
        "schema": "cnnslam-machine-figures/1",
        "suite": suite.name,
        "environment": machine_description(),
        "revision": revision,
        "fingerprints": run_fingerprints(records),
        "metrics": gate_metrics(records),
    }


def machine_file_name(environment: Mapping[str, Any]) -> str:
    """A file name for a machine's record: its CPU, widest ISA and core count, lower case, [a-z0-9-] only."""
    isa = (environment.get("isa") or ["x86"])[0]
    text = f"{environment.get('cpu', 'cpu')}-{isa}-{environment.get('cores', 0)}cores"
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") + ".json"


def save_machine_record(record: Mapping[str, Any], folder: str | Path) -> Path:
    """Write ``record`` as ``folder / machine_file_name(...)`` (strict JSON: NaN as null); returns the path."""
    path = Path(folder) / machine_file_name(record["environment"])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(json_ready(record), indent=1, sort_keys=True, allow_nan=False) + "\n")
    return path


def load_machine_records(folder: str | Path, suite: str, fingerprints: Sequence[str],
                         exclude: str | None = None) -> tuple[dict[str, dict[str, float]], list[str]]:
    """Other machines' figures of ``suite`` in ``folder`` (``*.json`` of :func:`machine_record`) that were made
    from runs with exactly these ``fingerprints``: ({"machine:<file stem>": figures}, [why each other record was
    left out]). ``exclude``: a file name to skip (this machine's own record)."""
    usable: dict[str, dict[str, float]] = {}
    left_out: list[str] = []
    wanted = sorted(fingerprints)
    for path in sorted(Path(folder).glob("*.json")) if Path(folder).is_dir() else []:
        if path.name == exclude:
            continue
        try:
            record = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            left_out.append(f"{path.name}: unreadable ({exc})")
            continue
        if record.get("suite") != suite:
            left_out.append(f"{path.name}: suite {record.get('suite')!r}, not {suite!r}")
        elif sorted(record.get("fingerprints", [])) != wanted:
            left_out.append(f"{path.name}: made from other runs (revision {record.get('revision') or '?'}); "
                            f"run cnnslam bench {suite} --calibrate on that machine again")
        else:
            usable[f"machine:{path.stem}"] = {k: math.nan if v is None else float(v)
                                             for k, v in record["metrics"].items()}
    return usable, left_out


def calibrated_baseline(suite: Suite, records: Mapping[str, Sequence[RunRecord]], description: str,
                        matrix: Sequence[Perturbation] = MATRIX, k: float = CALIBRATION_K,
                        machines: Mapping[str, Mapping[str, float]] | None = None) -> Baseline:
    """The baseline of the configurations' run records (:func:`measure`): the reference configuration's gated
    figures, tolerances from how far the medians and the single runs moved over the matrix and, where given, how
    far other machines' reference figures (``machines``, :func:`load_machine_records`) lie from them."""
    machines = dict(machines or {})
    how = (
        f"cnnslam bench {suite.name} --calibrate: {len(suite.seeds)} runs per cell (seeds "
        f"{', '.join(map(str, suite.seeds))}), gated figure = median over the runs; spread = the larger of the range "
        "of each gated figure and the largest range of one seed's value over the configurations: "
        + "; ".join(f"{c.name}: {c.description}" for c in matrix)
        + "".join(f"; {name}: its reference figures, measured there" for name in sorted(machines))
        + f"; allowed change = max({k:g} x spread, the rule's floor), capped to {CROSSABLE_SHARE:g} of the room "
        "between the figure and its metric's worst value where it could never be crossed (listed in capped_to_cross); "
        f"a figure whose {k:g} x spread alone reaches that worst value is left out of the gate (ungated_as_noise)"
    )
    figures = {name: gate_metrics(rs) for name, rs in records.items()}
    clash = set(machines) & set(figures)
    if clash:
        raise ValueError(f"machine records named like configurations of the matrix: {sorted(clash)}")
    figures.update(machines)
    runs = {name: seed_figures(rs) for name, rs in records.items()}
    return calibrate(figures, matrix[0].name, k=k, description=description, how=how, runs=runs)


@dataclass(frozen=True)
class Calibration:
    """What :func:`calibrate_suite` made: each configuration's runs (name -> :class:`SuiteRun`), the runs that failed
    (one line each; then no baseline is written), the ``baseline`` written to ``baseline_path`` (None when runs
    failed), this machine's record file, the other machines' records left out and why, and one summary line."""

    runs: dict[str, SuiteRun]
    failed: tuple[str, ...]
    baseline_path: Path
    baseline: Baseline | None = None
    machine_file: Path | None = None
    left_out: tuple[str, ...] = ()
    summary: str = ""


def calibrate_suite(suite: Suite, methods: Mapping[str, Any], out_root: str | Path, baseline_path: str | Path,
                    description: str, *, renderer: str = "mujoco", timeout_s: float | None = None,
                    progress: bool = True, revision: str = "") -> Calibration:
    """``--calibrate`` as a call: the suite under every configuration of :data:`MATRIX` (:func:`measure`), this
    machine's reference figures recorded in ``<baseline dir>/machines/<suite>/``, and the baseline with tolerances
    from the spread over the matrix and the other machines' records of the same runs written to ``baseline_path``
    (:func:`calibrated_baseline`). Nothing is written when a run failed."""
    from eval.bench.gate_baseline import save_baseline

    runs: dict[str, SuiteRun] = {}
    failed: list[str] = []

    def note(config: Perturbation, run: SuiteRun) -> None:
        runs[config.name] = run
        failed.extend(f"{config.name}: {o.key}: {o.error}" for o in run.failed)

    records = measure(suite, methods, out_root, progress=progress, on_config=note, renderer=renderer,
                      timeout_s=timeout_s)  # fmt: skip
    path = Path(baseline_path)
    if failed:
        return Calibration(runs, tuple(failed), path, summary=f"not writing a baseline: {len(failed)} run(s) failed")
    own = save_machine_record(machine_record(suite, records[MATRIX[0].name], revision), path.parent / "machines" /
                              suite.name)  # fmt: skip
    machines, left_out = load_machine_records(own.parent, suite.name, run_fingerprints(records[MATRIX[0].name]),
                                              exclude=own.name)  # fmt: skip
    baseline = calibrated_baseline(suite, records, description, MATRIX, machines=machines)
    save_baseline(baseline, path)
    holdout = baseline.calibration["holdout"]
    summary = (f"wrote {path}: {len(baseline.metrics)} gated figures, {len(baseline.calibrated)} calibrated; held-out "
               f"false alarms {holdout['alarms']} of {holdout['comparisons']} comparisons "
               f"({holdout['runs_with_alarm']} of {holdout['held_out']} held-out configurations would fail); other "
               f"machines folded in: {', '.join(sorted(machines)) or 'none'}; this machine's figures: {own}")
    return Calibration(runs, (), path, baseline, own, tuple(left_out), summary)
