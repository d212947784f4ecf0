"""The regression gate: compare a suite's figures with a committed baseline (:mod:`eval.bench.gate_baseline`: the
file, its tolerance rules and their checks), figure by figure, with tolerances measured from the figures' own spread.

What is gated (:func:`gate_metrics`): the figures a researcher gates on, per sequence and method, as the **median
over the cell's runs** (seeds): ATE RMSE, percentage of correct depth, tracked share, rotation error (RMSE) and the
number of frames scored (a run that stops producing its metrics is ``missing``); plus each method's suite averages
of the first four (``avg/<method>/<metric>``, over the sequences where the method has a value on all of them). Not
the min / max / std statistics of single runs: they move by chance. Rotation error twice: after the SE(3) fit and
after an orientation-only fit (:mod:`eval.metrics.trajectory_metrics`).

A metric's allowed change is its baseline's (:meth:`~eval.bench.gate_baseline.Baseline.allowed_change`).
``policy``: ``one-sided`` (default: only a change for the worse fails) or ``two-sided`` (a calibrated baseline's: a
change beyond the measured spread in either direction fails, since a tree whose results moved must come with an
updated baseline; e.g. a 1 deg heading bias can lower one sequence's rotation error by cancelling an error of the
method's own, and is still a change nobody intended).

Calibration (:func:`calibrate`, ``cnnslam bench quick --calibrate``) runs the suite
under a perturbation matrix (runs x thread counts x oneDNN on/off x the network's outputs perturbed in their last
bits, what another CPU does) and sets ``allowed = max(k * spread, rule floor)``, where ``spread`` is the larger of the
range of the metric's median over the matrix's configurations and the largest range of one run's value (one seed's)
over them: a figure that moves more than k times what floating point moved it is a regression. The run-level range
counts because a median of three runs moves as far as one run when the perturbation moves two of them: an ill-posed
figure (the rotation error after an SE(3) fit on a near-static start) can jump between two solutions in one seed
while the median stays put in the configurations the matrix tried. Its false-alarm rate is measured by holding
configurations out (:func:`holdout_false_alarms`). The result is made crossable
(:func:`~eval.bench.gate_baseline.cap_to_cross`).

Run file: a JSON object with a ``metrics`` object (a run record of :mod:`eval.metrics.results`, or anything shaped
so), a flat object of numbers, or a JSON list of run records (reduced to the gated figures by :func:`gate_metrics`).

Statuses: ``equal`` (within tolerance), ``improved``, ``regressed``, ``missing`` (in the baseline, not in the run,
or NaN in the run where the baseline has a number), ``new`` (in the run only; reported, not a failure). The gate
passes when nothing is ``regressed`` or ``missing``. Tracked -> lost is ``regressed`` whatever the tolerance: a
tracked share that was no failure in the baseline and is one in the run (:func:`lost`, by the one failure rule of
:func:`eval.metrics.results.failure_of`: never initialised, or below ``MIN_TRACKED_SHARE``).

The gate fails closed: before any run (:func:`check_gate`, called by ``cnnslam bench``) a missing, unreadable or
malformed baseline, or one of another suite or selection (:func:`check_selection`), is a
:class:`~eval.bench.gate_baseline.GateError` (an :class:`~eval.errors.InputError`: exit 2), unless the baseline is
being made (``--update-baseline``, ``--calibrate``); a baseline that goes missing during the runs fails the gate
(:func:`apply_gate`).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from enum import StrEnum
from pathlib import Path
from typing import Any

import pandas as pd

from eval.bench.gate_baseline import (
    CALIBRATION_K,
    DEFAULT_TOLERANCES,
    Baseline,
    GateError,
    Tolerance,
    as_float,
    cap_to_cross,
    figures_from_json,
    load_baseline,
    read_json_file,
    update_baseline,
)
from eval.metrics import catalogue
from eval.metrics.catalogue import TRACKED_SHARE
from eval.metrics.results import ResultsError, RunRecord, failure_of, share_text

# rotation twice: after the SE(3) fit (catches an error in the camera frame, which an orientation-only fit absorbs
# on short runs) and after the orientation-only fit (which no ill-posed position fit can decide)
GATED: tuple[str, ...] = catalogue.keys(gated=True)  # the catalogue's specs with gated=True
GATED_COUNTS: tuple[str, ...] = (catalogue.FRAMES.key,)  # gated too (a run without metrics is "missing"), not averaged
AVERAGE_PREFIX = "avg"


@dataclass(frozen=True)
class GateRow:
    metric: str
    baseline: float
    run: float
    delta: float
    allowed: float
    direction: str
    status: str


@dataclass(frozen=True)
class GateReport:
    """The comparison, row by row; ``passed`` when no row's status is in ``failing`` (one-sided: ``regressed``,
    ``missing``; two-sided: also ``improved``)."""

    rows: tuple[GateRow, ...] = field(default_factory=tuple)
    failing: tuple[str, ...] = ("regressed", "missing")

    @property
    def passed(self) -> bool:
        return not any(r.status in self.failing for r in self.rows)

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for r in self.rows:
            out[r.status] = out.get(r.status, 0) + 1
        return out

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame([asdict(r) for r in self.rows], columns=list(GateRow.__dataclass_fields__))


# --------------------------------------------------------------------------------------------------- comparison
def compare_metric(name: str, baseline: float, run: float | None, rule: Tolerance,
                   allowed: float | None = None) -> GateRow:
    """One metric's status (see the module docstring); ``allowed`` (calibrated) replaces the rule's allowance."""
    allowed = rule.allowed(baseline) if allowed is None else allowed
    if run is None or (math.isnan(run) and not math.isnan(baseline)):
        return GateRow(name, baseline, math.nan if run is None else run, math.nan, allowed, rule.direction, "missing")
    if math.isnan(baseline):
        status = "equal" if math.isnan(run) else "improved"
        return GateRow(name, baseline, run, math.nan, allowed, rule.direction, status)
    delta = run - baseline
    if lost(name, baseline, run):
        return GateRow(name, baseline, run, delta, allowed, rule.direction, "regressed")
    if rule.direction == "match":
        status = "regressed" if abs(delta) > allowed else "equal"
    else:
        worse = delta if rule.direction == "lower" else -delta
        status = "regressed" if worse > allowed else ("improved" if worse < -allowed else "equal")
    return GateRow(name, baseline, run, delta, allowed, rule.direction, status)


def lost(name: str, baseline: float, run: float) -> str | None:
    """Why a tracked share went from tracking to a failure (:func:`eval.metrics.results.failure_of`: never
    initialised, or below :data:`eval.metrics.results.MIN_TRACKED_SHARE`), e.g. ``"tracked 100 % -> never
    initialised"``; None when ``name`` is no tracked share, the baseline was a failure already, or the run is none.
    Such a change is a regression whatever the tolerance."""
    share = TRACKED_SHARE.key
    if name.rsplit("/", 1)[-1] != share or not (math.isfinite(baseline) and math.isfinite(run)):
        return None
    if failure_of({share: baseline}) is not None:
        return None
    why = failure_of({share: run})
    return None if why is None else f"tracked {share_text(baseline)} -> {why}"


def compare(baseline: Baseline, run_metrics: Mapping[str, float]) -> GateReport:
    """Compare every baseline metric with the run's; run-only metrics are listed as ``new``."""
    rows = [
        compare_metric(
            name,
            value,
            as_float(run_metrics[name]) if name in run_metrics else None,
            baseline.tolerance_for(name),
            baseline.allowed(name),
        )
        for name, value in baseline.metrics.items()
    ]
    for name, value in run_metrics.items():
        if name not in baseline.metrics:
            rule = baseline.tolerance_for(name)
            rows.append(GateRow(name, math.nan, as_float(value), math.nan, math.nan, rule.direction, "new"))
    failing = ("regressed", "missing", "improved") if baseline.policy == "two-sided" else ("regressed", "missing")
    return GateReport(tuple(rows), failing)


def format_report(report: GateReport, only_changes: bool = False) -> str:
    """The diff table as text, then one summary line."""
    frame = report.frame()
    if only_changes:
        frame = frame[frame["status"] != "equal"]
    lines = []
    if len(frame):
        shown = frame.copy()
        for col in ("baseline", "run", "delta", "allowed"):
            shown[col] = shown[col].map(lambda v: "-" if pd.isna(v) else f"{v:.6g}")
        lines.append(shown.to_string(index=False))
    for row in report.rows:
        why = lost(row.metric, row.baseline, row.run)
        if why:
            lines.append(f"tracked -> lost: {row.metric}: {why} (a regression whatever the tolerance)")
    counts = ", ".join(f"{n} {status}" for status, n in sorted(report.counts().items()))
    lines.append(f"{'PASS' if report.passed else 'FAIL'}: {len(report.rows)} metrics ({counts or 'none'})")
    if not report.passed and "improved" in report.failing and any(r.status == "improved" for r in report.rows):
        lines.append("two-sided gate: a figure moved beyond its measured spread for the better too; if the change "
                     "is intended, update the baseline (cnnslam bench quick --update-baseline) and commit it")
    return "\n".join(lines)


# -------------------------------------------------------------------------------------------------------- files
def suite_metrics(records: Iterable[RunRecord]) -> dict[str, float]:
    """Flatten run records to ``sequence/method/metric`` names, every metric (several runs of a pair: their median,
    NaN runs left out)."""
    values: dict[str, list[float]] = {}
    for rec in records:
        prefix = f"{rec.sequence}/{rec.method}/"
        for name, value in rec.metrics.items():
            values.setdefault(prefix + name, []).append(as_float(value))
    return {k: _median(v) for k, v in values.items()}


def gate_metrics(records: Iterable[RunRecord], gated: Sequence[str] = GATED) -> dict[str, float]:
    """The gated figures of a suite's run records (see the module docstring): per ``sequence/method/metric`` the
    median over the cell's runs of each metric in ``gated`` and of :data:`GATED_COUNTS`, and per method
    ``avg/<method>/<metric>``: the mean of its per-sequence medians, where it has one on every sequence of the
    records."""
    every = suite_metrics(records)
    wanted = set(gated) | set(GATED_COUNTS)
    out = {k: v for k, v in every.items() if k.rsplit("/", 1)[-1] in wanted}
    sequences = {k.split("/", 1)[0] for k in every}
    cells: dict[tuple[str, str], list[float]] = {}
    for key, value in out.items():
        if key.count("/") != 2:  # a method name with a '/' in it: no suite average
            continue
        _, method, metric = key.split("/")
        if metric in gated and not math.isnan(value):
            cells.setdefault((method, metric), []).append(value)
    for (method, metric), values in cells.items():
        if len(values) == len(sequences):
            out[f"{AVERAGE_PREFIX}/{method}/{metric}"] = math.fsum(values) / len(values)
    return out


def _median(values: Sequence[float]) -> float:
    """The median of the non-NaN values (NaN when there are none)."""
    finite = [v for v in values if not math.isnan(v)]
    return statistics.median(finite) if finite else math.nan


def metrics_from_json(data: Any, source: str = "<data>") -> dict[str, float]:
    """Metrics of a run file's content (see the module docstring for the accepted shapes)."""
    if isinstance(data, list):
        try:
            records = [RunRecord.from_json(r, f"{source}[{n}]") for n, r in enumerate(data)]
        except ResultsError as exc:
            raise GateError(f"{exc} (a JSON list must hold run records)") from exc
        return gate_metrics(records)
    if isinstance(data, dict):
        return figures_from_json(data["metrics"] if isinstance(data.get("metrics"), dict) else data, source)
    raise GateError(f"{source}: expected a JSON object of metrics or a list of run records")


def load_run_metrics(path: str | Path) -> dict[str, float]:
    """Read a run file's metrics (null -> NaN)."""
    return metrics_from_json(read_json_file(path), str(path))



# ---------------------------------------------------------------------------------------------- the gate, as a call
class GateAction(StrEnum):
    """What a benchmark does with its suite's baseline: ``COMPARE`` (the gate: a gated suite, or a baseline named),
    ``UPDATE`` (write the run's gated figures, refusing to drop any the baseline holds), ``REPLACE`` (write them,
    dropping what the run lacks), ``CALIBRATE`` (measure the tolerances, :mod:`eval.bench.calibrate`), ``OFF``."""

    COMPARE = "compare"
    UPDATE = "update"
    REPLACE = "replace"
    CALIBRATE = "calibrate"
    OFF = "off"


@dataclass(frozen=True)
class GateOutcome:
    """What the gate did: ``action``, the ``baseline`` file, the comparison's ``report`` (COMPARE), ``passed``
    (False: the command's exit status 1) and one line saying what happened."""

    action: GateAction
    baseline: Path
    passed: bool
    message: str
    report: GateReport | None = None


def apply_gate(records: Sequence[RunRecord], action: GateAction, baseline: str | Path, *, gated: bool,
               description: str, incomplete: str = "") -> GateOutcome | None:
    """Compare a suite's run records with its ``baseline`` or write them into it (``action``). COMPARE runs when the
    suite is ``gated`` or the baseline was named (then ``gated`` is True too); None when nothing was to be done.
    ``incomplete``: why the runs cannot make a baseline (failed runs, skipped methods; empty when they can).
    ``description``: the baseline's, when written."""
    path = Path(baseline)
    metrics = gate_metrics(records)
    if action in (GateAction.UPDATE, GateAction.REPLACE):
        if incomplete:
            return GateOutcome(action, path, False, f"not updating {path}: {incomplete}")
        try:
            new = update_baseline(path, metrics, description=description, replace_all=action is GateAction.REPLACE)
        except GateError as exc:
            return GateOutcome(action, path, False, str(exc))
        return GateOutcome(action, path, True, f"updated {path}: {len(metrics)} gated figures ({len(new.calibrated)} "
                           "with calibrated tolerances; recalibrate with --calibrate after a change of the methods' "
                           "spread)")  # fmt: skip
    if action is not GateAction.COMPARE or not gated:
        return None
    try:  # checked before the runs (check_gate); a file that went away or changed since fails the gate, closed
        baseline_file = load_baseline(path)
    except GateError as exc:
        return GateOutcome(action, path, False, f"gate not passed: {exc}")
    report = compare(baseline_file, metrics)
    return GateOutcome(action, path, report.passed, format_report(report, only_changes=True), report)


def check_selection(baseline: Baseline, cells: Iterable[tuple[str, str]], frames: int | None = None,
                    source: str = "baseline") -> None:
    """Refuse a baseline made of another selection than the runs about to be compared with it: the ``(sequence,
    method)`` ``cells`` the runs make must be the cells its figures hold (a cell it lacks would pass ungated as
    ``new``; one it holds and the runs lack would only fail after every run), and its ``frames`` figures must not
    exceed the ``frames`` asked for. :class:`GateError` naming an example and what to do."""
    planned = {f"{sequence}/{method}" for sequence, method in cells}
    methods = {method for _, method in cells}
    held, averaged = set(), set()
    for name in baseline.metrics:
        cell, _, _ = name.rpartition("/")
        if cell.startswith(f"{AVERAGE_PREFIX}/"):
            averaged.add(cell.partition("/")[2])
        else:
            held.add(cell)
    extra = sorted(held - planned) + sorted(f"{AVERAGE_PREFIX}/{m}" for m in averaged - methods)
    lacking = sorted(planned - held)
    if extra or lacking:
        what = (f"holds figures of {len(extra)} sequence/method cell(s) these runs do not make (e.g. {extra[0]})"
                if extra else f"lacks {len(lacking)} sequence/method cell(s) these runs make (e.g. {lacking[0]}), "
                "which would pass ungated")  # fmt: skip
        raise GateError(f"{source}: the baseline is of another suite or selection: it {what}; run the selection it "
                        "was made of, name your own --baseline (made with --update-baseline), or --no-gate")
    if frames is not None:
        longer = sorted(n for n, v in baseline.metrics.items() if n.endswith("/frames") and math.isfinite(v)
                        and v > frames)  # fmt: skip
        if longer:
            raise GateError(f"{source}: the baseline's runs scored {baseline.metrics[longer[0]]:g} frames "
                            f"({longer[0]}), these runs ask for {frames}: a baseline of another --frames")


def check_gate(action: GateAction, baseline: str | Path, *, gated: bool, cells: Iterable[tuple[str, str]],
               frames: int | None = None) -> None:
    """What :func:`apply_gate` will need, checked before any run, so that a gate fails closed: COMPARE (when
    ``gated``) needs a readable baseline of these runs' selection (:func:`load_baseline`,
    :func:`check_selection`); UPDATE and REPLACE need an existing baseline to be readable (a missing one is
    created). :class:`GateError` (an :class:`~eval.errors.InputError`) with one line otherwise."""
    path = Path(baseline)
    if action in (GateAction.UPDATE, GateAction.REPLACE):
        if path.exists():
            load_baseline(path, crossable=False)
        return
    if action is not GateAction.COMPARE or not gated:
        return
    if not path.is_file():
        raise GateError(f"no baseline at {path}" + (" (a folder)" if path.exists() else "") + "; make it with "
                        "--update-baseline (or --calibrate), name another with --baseline, or --no-gate")
    check_selection(load_baseline(path), cells, frames, str(path))


# -------------------------------------------------------------------------------------------------- calibration
def seed_figures(records: Iterable[RunRecord], gated: Sequence[str] = GATED) -> dict[str, dict[str, float]]:
    """The gated figures of each seed's runs alone: seed (as a string) -> :func:`gate_metrics` of the records whose
    ``metadata.seed`` is that seed (records without one form the seed ``"-"``)."""
    by_seed: dict[str, list[RunRecord]] = {}
    for record in records:
        by_seed.setdefault(str(record.metadata.get("seed", "-")), []).append(record)
    return {seed: gate_metrics(rs, gated) for seed, rs in sorted(by_seed.items())}


def calibrate(
    configurations: Mapping[str, Mapping[str, float]],
    reference: str,
    tolerances: Sequence[Tolerance] = DEFAULT_TOLERANCES,
    k: float = CALIBRATION_K,
    description: str = "",
    how: str = "",
    runs: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None,
) -> Baseline:
    """A baseline from the gated figures of the same suite run under several configurations (name -> figures of
    :func:`gate_metrics`): the metrics are ``reference``'s; each metric's ``spread`` is the range of its value over
    the configurations, or, where ``runs`` (name -> :func:`seed_figures`) is given and larger, the largest range of
    one seed's value over them; its allowed change is ``max(k * spread, the rule's floor)``; count metrics (direction
    ``match``) keep their rule. ``calibration`` records ``how``, ``k``, the configurations, the alarms each of them
    raises against the result (0 by construction) and the held-out false-alarm rate (:func:`holdout_false_alarms`)."""
    base = replace(_spread_baseline(configurations, reference, tolerances, k, runs), description=description)
    alarms = {name: _alarms(base, figures) for name, figures in configurations.items()}
    calibration = {
        **base.calibration,  # what cap_to_cross recorded
        "how": how,
        "k": k,
        "reference": reference,
        "configurations": sorted(configurations),
        "alarms_per_configuration": alarms,
        "holdout": holdout_false_alarms(configurations, reference, tolerances, k, runs),
    }
    return replace(base, calibration=calibration)


def _range(values: Iterable[float]) -> float:
    """max - min of the non-NaN values (0 when there are none)."""
    finite = [v for v in values if not math.isnan(v)]
    return max(finite) - min(finite) if finite else 0.0


def _spread_baseline(configurations: Mapping[str, Mapping[str, float]], reference: str,
                     tolerances: Sequence[Tolerance], k: float,
                     runs: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None) -> Baseline:
    """:func:`calibrate`'s metrics and allowed changes, without the record of how."""
    if reference not in configurations:
        raise GateError(f"the reference configuration {reference!r} is not among {sorted(configurations)}")
    base = Baseline({n: as_float(v) for n, v in configurations[reference].items()}, tuple(tolerances),
                    policy="two-sided")
    seeds = sorted({s for name in configurations for s in (runs or {}).get(name, {})})
    calibrated: dict[str, dict[str, float]] = {}
    for name, value in base.metrics.items():
        rule = base.tolerance_for(name)
        if rule.direction == "match" or math.isnan(value):
            continue
        median_spread = _range(as_float(c[name]) for c in configurations.values() if name in c)
        run_spread = max((_range(as_float(runs[c][s][name]) for c in configurations
                                 if s in runs.get(c, {}) and name in runs[c][s]) for s in seeds),
                         default=0.0) if runs else 0.0  # fmt: skip
        spread = max(median_spread, run_spread)
        calibrated[name] = {"spread": spread, "allowed": max(k * spread, rule.allowed(value))}
        if runs:
            calibrated[name].update(median_spread=median_spread, run_spread=run_spread)
    return cap_to_cross(replace(base, calibrated=calibrated), k)


def _alarms(baseline: Baseline, figures: Mapping[str, float]) -> int:
    report = compare(baseline, figures)
    return sum(r.status in report.failing for r in report.rows)


def holdout_false_alarms(
    configurations: Mapping[str, Mapping[str, float]],
    reference: str,
    tolerances: Sequence[Tolerance] = DEFAULT_TOLERANCES,
    k: float = CALIBRATION_K,
    runs: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None,
) -> dict[str, float]:
    """The false-alarm rate of calibration on data it has not seen: for each configuration other than
    ``reference``, calibrate without it (and without its runs) and compare it with that baseline. Returns ``alarms``
    (metrics that alarmed, summed), ``comparisons`` (metrics compared) and ``rate`` (their ratio), and
    ``runs_with_alarm`` (held-out configurations that would have failed the gate) over ``held_out`` configurations."""
    alarms = comparisons = failed = 0
    others = [c for c in configurations if c != reference]
    for held in others:
        rest = {c: v for c, v in configurations.items() if c != held}
        if len(rest) < 2:
            continue
        rest_runs = {c: v for c, v in runs.items() if c != held} if runs else None
        base = _spread_baseline(rest, reference, tolerances, k, rest_runs)
        bad = _alarms(base, configurations[held])
        alarms += bad
        comparisons += len(base.metrics)
        failed += bad > 0
    return {"alarms": alarms, "comparisons": comparisons, "rate": alarms / comparisons if comparisons else math.nan,
            "runs_with_alarm": failed, "held_out": len(others)}  # fmt: skip


