"""The regression gate: compare a suite's figures with a committed baseline, figure by figure, with tolerances
measured from the figures' own spread.

What is gated (:func:`gate_metrics`): the figures a researcher gates on, per sequence and method, as the **median
over the cell's runs** (seeds): ATE RMSE, percentage of correct depth, tracked share, rotation error (RMSE) and the
number of frames scored (a run that stops producing its metrics is ``missing``); plus each method's suite averages
of the first four (``avg/<method>/<metric>``, over the sequences where the method has a value on all of them). Not
the min / max / std statistics of single runs: they move by chance. Rotation error twice: after the SE(3) fit and
after an orientation-only fit (:mod:`eval.metrics.trajectory_metrics`).

Baseline file (JSON, committed under ``results/baselines/``)::

    {"schema": "cnnslam-baseline/2",
     "metrics": {"office0/CNN-SLAM/ate_rmse": 0.0056, ...},
     "tolerances": [{"pattern": "*ate_rmse", "direction": "lower", "abs": 0.0005, "rel": 0.02}, ...],
     "calibrated": {"office0/CNN-SLAM/ate_rmse": {"spread": 0.0003, "allowed": 0.0009}, ...},
     "calibration": {"how": "...", "configurations": [...], "k": 3.0, "false_alarms": ..., ...}}

A metric's allowed change is ``calibrated[metric]["allowed"]`` when the baseline has it, else its rule's
``max(abs, rel * |baseline|)``. ``policy``: ``one-sided`` (default: only a change for the worse fails) or
``two-sided`` (a calibrated baseline's: a change beyond the measured spread in either direction fails, since a tree
whose results moved must come with an updated baseline; e.g. a 1 deg heading bias can lower one sequence's rotation
error by cancelling an error of the method's own, and is still a change nobody intended).

Calibration (:func:`calibrate`, ``cnnslam bench quick --calibrate``) runs the suite
under a perturbation matrix (runs x thread counts x oneDNN on/off x the network's outputs perturbed in their last
bits, what another CPU does) and sets ``allowed = max(k * spread, rule floor)``, where ``spread`` is the larger of the
range of the metric's median over the matrix's configurations and the largest range of one run's value (one seed's)
over them: a figure that moves more than k times what floating point moved it is a regression. The run-level range
counts because a median of three runs moves as far as one run when the perturbation moves two of them: an ill-posed
figure (the rotation error after an SE(3) fit on a near-static start) can jump between two solutions in one seed
while the median stays put in the configurations the matrix tried. Its false-alarm rate is measured by holding
configurations out (:func:`holdout_false_alarms`).

Rules: ``tolerances`` is optional (then :data:`DEFAULT_TOLERANCES` apply); the first rule whose ``pattern``
(:func:`fnmatch.fnmatchcase`) matches a metric name is used, and a metric that no rule matches gets
:data:`FALLBACK_TOLERANCE`. ``direction``: ``lower`` (lower is better), ``higher`` (higher is better) or ``match``
(any change beyond the tolerance fails, for counts). The allowed change is max(abs, rel * |baseline|).

A gate that cannot fail is refused when the baseline is loaded (:func:`check_tolerances`, :class:`GateError`): a
rule that can never match (an earlier rule matches every name it does), a baseline of another schema or with no
figures, and a figure whose allowed change reaches its metric's bound (:data:`METRIC_BOUNDS`: degrees 0..180,
shares 0..1, percent 0..100, metres and counts >= 0), e.g. a rotation error of 51.9 deg +- 182 deg. The writers of a
baseline (calibration, updates) make it crossable (:func:`cap_to_cross`): a figure whose own measured noise (k x
its spread) reaches the bound is left out of the gate (no tolerance both absorbs that noise and can fail; listed in
the calibration record's ``ungated_as_noise``); otherwise the allowance is capped to :data:`CROSSABLE_SHARE` of the
figure's room to fail (listed in ``capped_to_cross``).

Run file: a JSON object with a ``metrics`` object (a run record of :mod:`eval.metrics.results`, or anything shaped
so), a flat object of numbers, or a JSON list of run records (reduced to the gated figures by :func:`gate_metrics`).

Statuses: ``equal`` (within tolerance), ``improved``, ``regressed``, ``missing`` (in the baseline, not in the run,
or NaN in the run where the baseline has a number), ``new`` (in the run only; reported, not a failure). The gate
passes when nothing is ``regressed`` or ``missing``. Tracked -> lost is ``regressed`` whatever the tolerance: a
tracked share that was no failure in the baseline and is one in the run (:func:`lost`, by the one failure rule of
:func:`eval.metrics.results.failure_of`: never initialised, or below ``MIN_TRACKED_SHARE``).

The gate fails closed: before any run (:func:`check_gate`, called by ``cnnslam bench``) a missing, unreadable or
malformed baseline, or one of another suite or selection (:func:`check_selection`), is a :class:`GateError` (an
:class:`~eval.errors.InputError`: exit 2), unless the baseline is being made (``--update-baseline``,
``--calibrate``); a baseline that goes missing during the runs fails the gate (:func:`apply_gate`).

Updating a baseline (after an intended change): ``cnnslam regress BASELINE.json RUN.json --update`` rewrites the
baseline's metrics with the run's, keeping its tolerances (writing the defaults out when it had none), then the
change is reviewed and committed like code. Python: :func:`update_baseline`.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from enum import StrEnum
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any, Literal

import pandas as pd

from eval.errors import InputError
from eval.metrics import catalogue
from eval.metrics.catalogue import TRACKED_SHARE
from eval.metrics.results import ResultsError, RunRecord, failure_of, json_ready, share_text

BASELINE_SCHEMA = "cnnslam-baseline/2"
BASELINE_SCHEMAS: tuple[str, ...] = ("cnnslam-baseline/1", BASELINE_SCHEMA)  # what load_baseline reads
# rotation twice: after the SE(3) fit (catches an error in the camera frame, which an orientation-only fit absorbs
# on short runs) and after the orientation-only fit (which no ill-posed position fit can decide)
GATED: tuple[str, ...] = catalogue.keys(gated=True)  # the catalogue's specs with gated=True
GATED_COUNTS: tuple[str, ...] = (catalogue.FRAMES.key,)  # gated too (a run without metrics is "missing"), not averaged
AVERAGE_PREFIX = "avg"
ADDED_KEY = "added_after_calibration"  # the baseline's figures written by update_baseline(only_new=True)
# the baseline's figures given new values by update_baseline(merge=True): like the added ones, in no machine record
# made before (the records keep their old values until --calibrate is run again on their machines)
REWRITTEN_KEY = "rewritten_after_calibration"
CALIBRATION_K = 3.0  # allowed change = k x the spread measured over the perturbation matrix (ours: see calibrate)
Direction = Literal["lower", "higher", "match"]
Policy = Literal["one-sided", "two-sided"]
POLICIES: tuple[str, ...] = ("one-sided", "two-sided")
DIRECTIONS: tuple[str, ...] = ("lower", "higher", "match")


class GateError(InputError):
    """A baseline or run file that cannot be used (missing, unreadable, malformed, of another suite or selection, a
    tolerance that cannot fail), or an update that is refused: bad input, one line naming it."""


@dataclass(frozen=True)
class Tolerance:
    """How much a metric may move, and which way is better."""

    pattern: str
    direction: Direction = "lower"
    abs: float = 0.0  # allowed change in the metric's units
    rel: float = 0.0  # allowed change as a fraction of |baseline|

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise GateError(
                f"tolerance {self.pattern!r}: direction must be one of {DIRECTIONS}, got {self.direction!r}"
            )
        for name in ("abs", "rel"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise GateError(f"tolerance {self.pattern!r}: {name} must be a finite number >= 0, got {value!r}")

    def allowed(self, baseline: float) -> float:
        return max(self.abs, self.rel * abs(baseline)) if math.isfinite(baseline) else self.abs


# Floors of the allowed change: a calibrated metric may never be held tighter than these (the figure's own rounding
# and a margin for configurations the matrix did not try); uncalibrated metrics get them as their tolerance.
DEFAULT_TOLERANCES: tuple[Tolerance, ...] = tuple(  # each metric's (abs, rel): its catalogue spec's tolerance
    Tolerance(pattern, direction, abs=low, rel=rel) for pattern, direction, low, rel in catalogue.gate_rules())
FALLBACK_TOLERANCE = Tolerance("*", "lower", rel=0.05)

# The range each metric can take (first matching pattern wins; a metric no pattern matches is unbounded): a
# tolerance must leave the figure room to fail inside it (:func:`uncrossable`).
METRIC_BOUNDS: tuple[tuple[str, float, float], ...] = catalogue.bound_rules()  # each spec's bounds, same order
# A tolerance that cannot be crossed is capped to this share of the room between the figure and its worst value
# (ours: the worst tenth of that room still fails), by the writers of a baseline (calibration, --update-baseline);
# a file read with one is refused.
CROSSABLE_SHARE = 0.9
CAPPED_KEY = "capped_to_cross"  # the calibration record's list of the figures whose allowed change was capped
UNGATED_KEY = "ungated_as_noise"  # the figures left out of the gate: their measured noise leaves no room to fail


def metric_bounds(metric: str) -> tuple[float, float]:
    """The range ``(low, high)`` of a gated figure by its name (:data:`METRIC_BOUNDS`; ``(-inf, inf)`` when none
    matches)."""
    for pattern, low, high in METRIC_BOUNDS:
        if fnmatchcase(metric, pattern):
            return low, high
    return -math.inf, math.inf


def room_to_fail(metric: str, value: float, direction: str) -> float:
    """How far ``value`` can move the worse way inside the metric's bounds (``match``: the larger of the two
    ways); inf when unbounded that way, 0 when the figure already sits at its worst value."""
    low, high = metric_bounds(metric)
    up, down = max(high - value, 0.0), max(value - low, 0.0)
    return up if direction == "lower" else down if direction == "higher" else max(up, down)


def uncrossable(metric: str, value: float, direction: str, allowed: float) -> bool:
    """True when a figure ``value`` with an allowed change ``allowed`` can never fail the gate: the change the
    worse way that the tolerance allows reaches the metric's bound. A figure already at its worst value (a share of
    0, a rotation error of 180 deg) cannot get worse under any tolerance, so its tolerance is not judged."""
    if not math.isfinite(value):
        return False
    room = room_to_fail(metric, value, direction)
    return 0.0 < room <= allowed


def dead_rules(tolerances: Sequence[Tolerance]) -> list[tuple[Tolerance, Tolerance]]:
    """``(dead, earlier)`` pairs: rules that can never match because an earlier rule matches every name they match
    (the first matching rule wins). Found when the earlier pattern's only wildcard is ``*`` and it matches the later
    pattern's text: then every name the later one matches, the earlier one does too."""
    out = []
    for n, rule in enumerate(tolerances):
        for earlier in tolerances[:n]:
            if not any(c in earlier.pattern for c in "?[") and fnmatchcase(rule.pattern, earlier.pattern):
                out.append((rule, earlier))
                break
    return out


@dataclass(frozen=True)
class Baseline:
    """Baseline metrics, the tolerance rules that apply to them, and the per-metric allowed changes measured by
    calibration (``calibrated``: metric -> {"spread", "allowed"}) with how they were measured (``calibration``)."""

    metrics: dict[str, float]
    tolerances: tuple[Tolerance, ...] = DEFAULT_TOLERANCES
    description: str = ""
    calibrated: dict[str, dict[str, float]] = field(default_factory=dict)
    calibration: dict[str, Any] = field(default_factory=dict)
    policy: Policy = "one-sided"

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise GateError(f"baseline policy must be one of {POLICIES}, got {self.policy!r}")

    def tolerance_for(self, metric: str) -> Tolerance:
        for rule in self.tolerances:
            if fnmatchcase(metric, rule.pattern):
                return rule
        return FALLBACK_TOLERANCE

    def allowed(self, metric: str) -> float | None:
        """The calibrated allowed change of ``metric``, None when it was not calibrated."""
        entry = self.calibrated.get(metric)
        return None if entry is None else float(entry["allowed"])

    def allowed_change(self, metric: str) -> float:
        """The change of ``metric`` the gate allows: its calibrated one, else its rule's for its figure."""
        calibrated = self.allowed(metric)
        return self.tolerance_for(metric).allowed(self.metrics[metric]) if calibrated is None else calibrated


def check_tolerances(baseline: Baseline, source: str = "baseline", crossable: bool = True) -> None:
    """Refuse a baseline whose gate cannot fail somewhere: a rule that can never match (:func:`dead_rules`), or
    (``crossable``) a figure whose allowed change reaches its metric's bound (:func:`uncrossable`).
    :class:`GateError` names the rule, the figure and the bounds."""
    for rule, earlier in dead_rules(baseline.tolerances):
        raise GateError(f"{source}: tolerance rule {rule.pattern!r} can never match: the earlier rule "
                        f"{earlier.pattern!r} matches every name it does (the first matching rule wins); remove it")
    for metric, value in baseline.metrics.items() if crossable else ():
        rule = baseline.tolerance_for(metric)
        allowed = baseline.allowed_change(metric)
        if uncrossable(metric, value, rule.direction, allowed):
            low, high = metric_bounds(metric)
            how = "its calibrated allowed change" if baseline.allowed(metric) is not None else f"rule {rule.pattern!r}"
            raise GateError(f"{source}: {metric} = {value:.6g} +- {allowed:.6g} ({how}, {rule.direction} is better) "
                            f"can never fail inside the metric's bounds {low:g}..{high:g}; allow less than "
                            f"{room_to_fail(metric, value, rule.direction):.6g}")  # fmt: skip


def cap_to_cross(baseline: Baseline, k: float | None = None) -> Baseline:
    """``baseline`` with every allowed change that cannot be crossed (:func:`uncrossable`) made crossable, figures
    untouched. Where the figure's own measured noise leaves no room to fail (``k`` x its calibrated ``spread`` reaches
    its metric's bound; ``k``: the calibration's, default :data:`CALIBRATION_K`), no tolerance both absorbs that
    noise and can fail: the figure is left out of the gate and listed with its value, spread and room
    (:data:`UNGATED_KEY`). Otherwise (a rule's floor above a figure near its bound) the allowance is capped to
    :data:`CROSSABLE_SHARE` of the figure's room to fail, as a calibrated entry (``capped_from``: the allowance it
    replaced), and listed (:data:`CAPPED_KEY`)."""
    k = float(baseline.calibration.get("k", CALIBRATION_K)) if k is None else k
    metrics, calibrated = dict(baseline.metrics), dict(baseline.calibrated)
    capped, noisy = [], {}
    for metric, value in baseline.metrics.items():
        direction = baseline.tolerance_for(metric).direction
        allowed = baseline.allowed_change(metric)
        if not uncrossable(metric, value, direction, allowed):
            continue
        room = room_to_fail(metric, value, direction)
        spread = calibrated.get(metric, {}).get("spread")
        if isinstance(spread, int | float) and math.isfinite(spread) and k * spread >= room:
            noisy[metric] = {"value": value, "spread": float(spread), "room": room}
            del metrics[metric]
            calibrated.pop(metric)
            continue
        entry = dict(calibrated.get(metric, {}))
        entry.update(allowed=CROSSABLE_SHARE * room, capped_from=allowed)
        calibrated[metric] = entry
        capped.append(metric)
    if not capped and not noisy:
        return baseline
    calibration = dict(baseline.calibration)
    if capped:
        _list_in(calibration, CAPPED_KEY, capped)
    if noisy:
        calibration[UNGATED_KEY] = dict(sorted({**calibration.get(UNGATED_KEY, {}), **noisy}.items()))
    return replace(baseline, metrics=metrics, calibrated=calibrated, calibration=calibration)


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
            _as_float(run_metrics[name]) if name in run_metrics else None,
            baseline.tolerance_for(name),
            baseline.allowed(name),
        )
        for name, value in baseline.metrics.items()
    ]
    for name, value in run_metrics.items():
        if name not in baseline.metrics:
            rule = baseline.tolerance_for(name)
            rows.append(GateRow(name, math.nan, _as_float(value), math.nan, math.nan, rule.direction, "new"))
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
            values.setdefault(prefix + name, []).append(_as_float(value))
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
        metrics = data["metrics"] if isinstance(data.get("metrics"), dict) else data
        out = {}
        for name, value in metrics.items():
            if isinstance(value, bool) or (value is not None and not isinstance(value, int | float)):
                raise GateError(f"{source}: metric {name!r} is {value!r}, not a number")
            out[str(name)] = _as_float(value)
        return out
    raise GateError(f"{source}: expected a JSON object of metrics or a list of run records")


def load_run_metrics(path: str | Path) -> dict[str, float]:
    """Read a run file's metrics (null -> NaN)."""
    return metrics_from_json(_read_json(path), str(path))


def load_baseline(path: str | Path, crossable: bool = True) -> Baseline:
    """Read a baseline file; raises :class:`GateError` naming the file and the problem: unreadable, not JSON, of
    another schema, no figures, malformed tolerances or calibration, or a gate that cannot fail
    (:func:`check_tolerances`)."""
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("metrics"), dict):
        raise GateError(f"{path}: a baseline is a JSON object with a 'metrics' object (schema {BASELINE_SCHEMA})")
    schema = data.get("schema", BASELINE_SCHEMA)
    if schema not in BASELINE_SCHEMAS:
        raise GateError(f"{path}: schema {schema!r} is not a baseline's; valid: {', '.join(BASELINE_SCHEMAS)}")
    if not data["metrics"]:
        raise GateError(f"{path}: the baseline holds no figures, so it gates nothing; make it with "
                        "--update-baseline (cnnslam bench) or --update (cnnslam regress)")
    rules = data.get("tolerances")
    if rules is None:
        tolerances = DEFAULT_TOLERANCES
    else:
        try:
            if not isinstance(rules, list):
                raise TypeError(f"'tolerances' is a list, got {type(rules).__name__}")
            tolerances = tuple(Tolerance(**rule) for rule in rules)
        except TypeError as exc:
            raise GateError(f"{path}: each tolerance is {{'pattern', 'direction', 'abs', 'rel'}}; {exc}") from exc
        if any(not isinstance(t.pattern, str) for t in tolerances):
            raise GateError(f"{path}: a tolerance's pattern is a text (fnmatch), e.g. '*ate_rmse'")
    calibrated = {} if data.get("calibrated") is None else data["calibrated"]
    if not isinstance(calibrated, dict) or not all(
        isinstance(v, dict) and isinstance(v.get("allowed"), int | float) and not isinstance(v["allowed"], bool)
        and math.isfinite(v["allowed"]) and v["allowed"] >= 0 for v in calibrated.values()
    ):
        raise GateError(f"{path}: 'calibrated' maps metric names to {{'spread', 'allowed'}} objects (allowed: a "
                        "finite number >= 0)")
    calibration = {} if data.get("calibration") is None else data["calibration"]
    if not isinstance(calibration, dict):
        raise GateError(f"{path}: 'calibration' is an object (how the tolerances were measured)")
    baseline = Baseline(metrics_from_json(data["metrics"], str(path)), tolerances, str(data.get("description", "")),
                        {k: dict(v) for k, v in calibrated.items()}, dict(calibration),
                        data.get("policy", "one-sided"))  # fmt: skip
    check_tolerances(baseline, str(path), crossable)
    return baseline


def baseline_to_json(baseline: Baseline) -> dict[str, Any]:
    return json_ready(
        {
            "schema": BASELINE_SCHEMA,
            "description": baseline.description,
            "metrics": dict(sorted(baseline.metrics.items())),
            "tolerances": [asdict(t) for t in baseline.tolerances],
            "policy": baseline.policy,
            "calibrated": dict(sorted(baseline.calibrated.items())),
            "calibration": baseline.calibration,
        }
    )


def save_baseline(baseline: Baseline, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(baseline_to_json(baseline), indent=2, allow_nan=False) + "\n")
    return path


def _list_in(calibration: dict[str, Any], key: str, names: Iterable[str]) -> None:
    """Add ``names`` to the calibration record's sorted list ``key`` (figures written after the calibration)."""
    calibration[key] = sorted({*calibration.get(key, []), *names})


def update_baseline(
    path: str | Path, run_metrics: Mapping[str, float], tolerances: Sequence[Tolerance] | None = None,
    description: str | None = None, only_new: bool = False, replace_all: bool = False, merge: bool = False,
) -> Baseline:
    """Replace the baseline's metrics by the run's, keeping everything else it holds (tolerances, policy,
    calibrated tolerances and their record), or ``tolerances`` / ``description`` where given; write and return it.
    The one way a baseline's figures are rewritten (``cnnslam regress --update``, ``cnnslam bench
    --update-baseline``). A missing baseline file is created with the default tolerances.

    ``only_new``: add the run's figures the baseline does not hold yet (a newly gated metric) and keep every figure
    it holds as it is (their calibration was measured around them, on the machines of its record); the default
    tolerance rules that its rules leave reachable are appended to them, so the new figures get theirs.

    ``merge``: replace the figures the run holds and keep those it lacks (a run of one changed method: its figures
    are rewritten, the other methods' stay as measured, with their calibration); the calibration record lists the
    figures it gave new values (``rewritten_after_calibration``: no machine record holds them until ``--calibrate``
    runs again) and the ones it added.

    An update that would drop gated figures (the baseline holds figures the run lacks: another selection of
    sequences or methods) is refused with :class:`GateError`, unless ``replace_all`` (``--replace``) or ``merge``: a
    gate whose figures silently shrink to another run's no longer gates what it did.
    """
    if sum((only_new, replace_all, merge)) > 1:
        raise GateError("only one of only_new (--only-new), replace_all (--replace) and merge (--merge) at a time")
    path = Path(path)
    old = load_baseline(path, crossable=False) if path.exists() else Baseline({})
    dropped = sorted(set(old.metrics) - set(run_metrics))
    if dropped and not (only_new or replace_all or merge):
        raise GateError(f"not updating {path}: the run lacks {len(dropped)} of its {len(old.metrics)} gated figures "
                        f"(e.g. {dropped[0]}), which the update would drop; --replace to replace them by the run's "
                        f"{len(run_metrics)}, --merge to rewrite only the run's figures, --only-new to add the run's "
                        "new figures only")  # fmt: skip
    if only_new:
        added = {k: v for k, v in run_metrics.items() if k not in old.metrics}
        rules = old.tolerances
        for default in DEFAULT_TOLERANCES:  # those an earlier rule leaves reachable (never a rule that cannot match)
            if not dead_rules((*rules, default)):
                rules = (*rules, default)
        # the calibration record says which figures came after it (and so are in no machine record made before)
        calibration = dict(old.calibration)
        _list_in(calibration, ADDED_KEY, added)
        new = replace(old, metrics={**old.metrics, **added}, tolerances=rules, calibration=calibration)
    elif merge:
        calibration = dict(old.calibration)
        added = [k for k in run_metrics if k not in old.metrics]
        changed = [k for k, v in run_metrics.items() if k in old.metrics and old.metrics[k] != v]
        if added:
            _list_in(calibration, ADDED_KEY, added)
        if changed:
            _list_in(calibration, REWRITTEN_KEY, changed)
        new = replace(old, metrics={**old.metrics, **run_metrics}, calibration=calibration)
    else:
        new = replace(old, metrics=dict(run_metrics))
    if tolerances is not None:
        new = replace(new, tolerances=tuple(tolerances))
    if description is not None:
        new = replace(new, description=description)
    new = cap_to_cross(new)  # a figure now near its bound keeps a tolerance it can still cross
    save_baseline(new, path)
    return new


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
    base = Baseline({n: _as_float(v) for n, v in configurations[reference].items()}, tuple(tolerances),
                    policy="two-sided")
    seeds = sorted({s for name in configurations for s in (runs or {}).get(name, {})})
    calibrated: dict[str, dict[str, float]] = {}
    for name, value in base.metrics.items():
        rule = base.tolerance_for(name)
        if rule.direction == "match" or math.isnan(value):
            continue
        median_spread = _range(_as_float(c[name]) for c in configurations.values() if name in c)
        run_spread = max((_range(_as_float(runs[c][s][name]) for c in configurations
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


def _read_json(path: str | Path) -> Any:
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except OSError as exc:
        raise GateError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise GateError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from exc


def _as_float(value: Any) -> float:
    return math.nan if value is None else float(value)
