"""The regression gate: compare a run's metrics with a committed baseline, metric by metric, with tolerances.

Baseline file (JSON, committed under ``results/``)::

    {"schema": "cnnslam-baseline/1",
     "metrics": {"office0/cnnslam/ate_rmse": 0.121, ...},
     "tolerances": [{"pattern": "*ate_rmse", "direction": "lower", "abs": 0.005, "rel": 0.10}, ...]}

``tolerances`` is optional (then :data:`DEFAULT_TOLERANCES` apply); the first rule whose ``pattern``
(:func:`fnmatch.fnmatchcase`) matches a metric name is used, and a metric that no rule matches gets
:data:`FALLBACK_TOLERANCE`. ``direction``: ``lower`` (lower is better), ``higher`` (higher is better) or ``match``
(any change beyond the tolerance fails, for counts). The allowed change is max(abs, rel * |baseline|).

Run file: a JSON object with a ``metrics`` object (a run record of :mod:`eval.results`, or anything shaped so), a
flat object of numbers, or a JSON list of run records (flattened to ``sequence/method/metric`` names by
:func:`suite_metrics`).

Statuses: ``equal`` (within tolerance), ``improved``, ``regressed``, ``missing`` (in the baseline, not in the run,
or NaN in the run where the baseline has a number), ``new`` (in the run only; reported, not a failure). The gate
passes when nothing is ``regressed`` or ``missing``.

Updating a baseline (after an intended change): ``cnnslam regress BASELINE.json RUN.json --update`` rewrites the
baseline's metrics with the run's, keeping its tolerances (writing the defaults out when it had none), then the
change is reviewed and committed like code. Python: :func:`update_baseline`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any, Literal

import pandas as pd

from eval.errors import EvalError
from eval.results import json_ready

BASELINE_SCHEMA = "cnnslam-baseline/1"
Direction = Literal["lower", "higher", "match"]
DIRECTIONS: tuple[str, ...] = ("lower", "higher", "match")


class GateError(EvalError):
    """A baseline or run file that cannot be used."""


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


DEFAULT_TOLERANCES: tuple[Tolerance, ...] = (
    Tolerance("*pairs", "match"),
    Tolerance("*frames", "match"),
    Tolerance("*keyframes", "match", abs=2.0),
    Tolerance("*ate_*", "lower", abs=0.002, rel=0.10),
    Tolerance("*rpe_*", "lower", abs=0.002, rel=0.10),
    Tolerance("*rot_deg_*", "lower", abs=0.1, rel=0.10),
    Tolerance("*scale_error", "lower", abs=0.01, rel=0.10),
    Tolerance("*length_*", "match", rel=0.10),
    Tolerance("*scale", "match", abs=0.02),
    Tolerance("*percent_correct*", "higher", abs=1.0, rel=0.05),
    Tolerance("*density", "higher", abs=1.0, rel=0.05),
    Tolerance("*delta_1_25", "higher", abs=1.0, rel=0.05),
    Tolerance("*abs_rel", "lower", abs=0.005, rel=0.05),
    Tolerance("*depth_rmse", "lower", abs=0.005, rel=0.05),
    Tolerance("*tracked_share", "higher", abs=0.02),
    Tolerance("*semantic_*", "higher", abs=0.01, rel=0.02),
    Tolerance("*step_ms_*", "lower", rel=0.50),
    Tolerance("*fps", "higher", rel=0.33),
)
FALLBACK_TOLERANCE = Tolerance("*", "lower", rel=0.05)


@dataclass(frozen=True)
class Baseline:
    """Baseline metrics and the tolerance rules that apply to them."""

    metrics: dict[str, float]
    tolerances: tuple[Tolerance, ...] = DEFAULT_TOLERANCES
    description: str = ""

    def tolerance_for(self, metric: str) -> Tolerance:
        for rule in self.tolerances:
            if fnmatchcase(metric, rule.pattern):
                return rule
        return FALLBACK_TOLERANCE


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
    """The comparison, row by row; ``passed`` when no row is ``regressed`` or ``missing``."""

    rows: tuple[GateRow, ...] = field(default_factory=tuple)

    @property
    def passed(self) -> bool:
        return not any(r.status in ("regressed", "missing") for r in self.rows)

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for r in self.rows:
            out[r.status] = out.get(r.status, 0) + 1
        return out

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame([asdict(r) for r in self.rows], columns=list(GateRow.__dataclass_fields__))


# --------------------------------------------------------------------------------------------------- comparison
def compare_metric(name: str, baseline: float, run: float | None, rule: Tolerance) -> GateRow:
    """One metric's status (see the module docstring)."""
    allowed = rule.allowed(baseline)
    if run is None or (math.isnan(run) and not math.isnan(baseline)):
        return GateRow(name, baseline, math.nan if run is None else run, math.nan, allowed, rule.direction, "missing")
    if math.isnan(baseline):
        status = "equal" if math.isnan(run) else "improved"
        return GateRow(name, baseline, run, math.nan, allowed, rule.direction, status)
    delta = run - baseline
    if rule.direction == "match":
        status = "regressed" if abs(delta) > allowed else "equal"
    else:
        worse = delta if rule.direction == "lower" else -delta
        status = "regressed" if worse > allowed else ("improved" if worse < -allowed else "equal")
    return GateRow(name, baseline, run, delta, allowed, rule.direction, status)


def compare(baseline: Baseline, run_metrics: Mapping[str, float]) -> GateReport:
    """Compare every baseline metric with the run's; run-only metrics are listed as ``new``."""
    rows = [
        compare_metric(
            name, value, _as_float(run_metrics[name]) if name in run_metrics else None, baseline.tolerance_for(name)
        )
        for name, value in baseline.metrics.items()
    ]
    for name, value in run_metrics.items():
        if name not in baseline.metrics:
            rule = baseline.tolerance_for(name)
            rows.append(GateRow(name, math.nan, _as_float(value), math.nan, math.nan, rule.direction, "new"))
    return GateReport(tuple(rows))


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
    counts = ", ".join(f"{n} {status}" for status, n in sorted(report.counts().items()))
    lines.append(f"{'PASS' if report.passed else 'FAIL'}: {len(report.rows)} metrics ({counts or 'none'})")
    return "\n".join(lines)


# -------------------------------------------------------------------------------------------------------- files
def suite_metrics(records: Iterable[Mapping[str, Any]]) -> dict[str, float]:
    """Flatten run records to ``sequence/method/metric`` names (several runs of a pair: their mean)."""
    sums: dict[str, list[float]] = {}
    for rec in records:
        prefix = f"{rec['sequence']}/{rec.get('method') or rec.get('agent')}/"
        for name, value in rec["metrics"].items():
            sums.setdefault(prefix + name, []).append(_as_float(value))
    return {k: math.fsum(v) / len(v) for k, v in sums.items()}


def metrics_from_json(data: Any, source: str = "<data>") -> dict[str, float]:
    """Metrics of a run file's content (see the module docstring for the accepted shapes)."""
    if isinstance(data, list):
        if not all(isinstance(r, dict) and isinstance(r.get("metrics"), dict) and "sequence" in r for r in data):
            raise GateError(f"{source}: a JSON list must hold run records (objects with 'sequence' and 'metrics')")
        return suite_metrics(data)
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


def load_baseline(path: str | Path) -> Baseline:
    """Read a baseline file; raises :class:`GateError` naming the file and the problem."""
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("metrics"), dict):
        raise GateError(f"{path}: a baseline is a JSON object with a 'metrics' object (schema {BASELINE_SCHEMA})")
    rules = data.get("tolerances")
    if rules is None:
        tolerances = DEFAULT_TOLERANCES
    else:
        try:
            tolerances = tuple(Tolerance(**rule) for rule in rules)
        except TypeError as exc:
            raise GateError(f"{path}: each tolerance is {{'pattern', 'direction', 'abs', 'rel'}}; {exc}") from exc
    return Baseline(metrics_from_json(data["metrics"], str(path)), tolerances, str(data.get("description", "")))


def baseline_to_json(baseline: Baseline) -> dict[str, Any]:
    return json_ready(
        {
            "schema": BASELINE_SCHEMA,
            "description": baseline.description,
            "metrics": dict(sorted(baseline.metrics.items())),
            "tolerances": [asdict(t) for t in baseline.tolerances],
        }
    )


def save_baseline(baseline: Baseline, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(baseline_to_json(baseline), indent=2, allow_nan=False) + "\n")
    return path


def update_baseline(
    path: str | Path, run_metrics: Mapping[str, float], tolerances: Sequence[Tolerance] | None = None
) -> Baseline:
    """Replace the baseline's metrics by the run's (keeping its tolerances, or ``tolerances``); write and return it.

    A missing baseline file is created with the default tolerances.
    """
    path = Path(path)
    old = load_baseline(path) if path.exists() else None
    rules = tuple(tolerances) if tolerances is not None else (old.tolerances if old else DEFAULT_TOLERANCES)
    new = Baseline(dict(run_metrics), rules, old.description if old else "")
    save_baseline(new, path)
    return new


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
