"""The regression gate's baseline file: its tolerance rules, the range of each gated figure, and reading,
checking, capping, writing and updating it. The comparison of a run with it is :mod:`eval.bench.regress`.

Baseline file (JSON, committed under ``results/baselines/``)::

    {"schema": "cnnslam-baseline/2",
     "metrics": {"office0/CNN-SLAM/<key>": 0.0056, ...},
     "tolerances": [{"pattern": "*<key>", "direction": "lower", "abs": 0.0005, "rel": 0.02}, ...],
     "calibrated": {"office0/CNN-SLAM/<key>": {"spread": 0.0003, "allowed": 0.0009}, ...},
     "calibration": {"how": "...", "configurations": [...], "k": 3.0, "false_alarms": ..., ...}}

``<key>``: a metric's key (:mod:`eval.metrics.catalogue`; a run's ``metrics.json`` holds them by these keys).

A metric's allowed change (:meth:`Baseline.allowed_change`) is ``calibrated[metric]["allowed"]`` when the baseline
has it, else its rule's ``max(abs, rel * |baseline|)``. ``policy``: ``one-sided`` (default: only a change for the
worse fails) or ``two-sided`` (a calibrated baseline's: a change beyond the measured spread in either direction
fails).

Rules: ``tolerances`` is optional (then :data:`DEFAULT_TOLERANCES` apply); the first rule whose ``pattern``
(:func:`fnmatch.fnmatchcase`) matches a metric name is used, and a metric that no rule matches gets
:data:`FALLBACK_TOLERANCE`. ``direction``: ``lower`` (lower is better), ``higher`` (higher is better) or ``match``
(any change beyond the tolerance fails, for counts).

A gate that cannot fail is refused when the baseline is loaded (:func:`check_tolerances`, :class:`GateError`): a
rule that can never match (an earlier rule matches every name it does, :func:`dead_rules`), a baseline of another
schema or with no figures, and a figure whose allowed change reaches its metric's bound (:data:`METRIC_BOUNDS`:
degrees 0..180, shares 0..1, percent 0..100, metres and counts >= 0; :func:`uncrossable`), e.g. a rotation error of
51.9 deg +- 182 deg. The writers of a baseline (calibration, updates) make it crossable (:func:`cap_to_cross`): a
figure whose own measured noise (k x its spread) reaches the bound is left out of the gate (listed in the calibration
record's ``ungated_as_noise``); otherwise the allowance is capped to :data:`CROSSABLE_SHARE` of the figure's room to
fail (listed in ``capped_to_cross``).

Updating a baseline (after an intended change): ``cnnslam regress BASELINE.json RUN.json --update`` rewrites the
baseline's metrics with the run's, keeping its tolerances (writing the defaults out when it had none), then the
change is reviewed and committed like code. Python: :func:`update_baseline`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any, Literal

from eval.errors import InputError
from eval.metrics import catalogue
from eval.metrics.results import json_ready

BASELINE_SCHEMA = "cnnslam-baseline/2"
BASELINE_SCHEMAS: tuple[str, ...] = ("cnnslam-baseline/1", BASELINE_SCHEMA)  # what load_baseline reads
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



def load_baseline(path: str | Path, crossable: bool = True) -> Baseline:
    """Read a baseline file; raises :class:`GateError` naming the file and the problem: unreadable, not JSON, of
    another schema, no figures, malformed tolerances or calibration, or a gate that cannot fail
    (:func:`check_tolerances`)."""
    data = read_json_file(path)
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
            raise GateError(f"{path}: a tolerance's pattern is a text (fnmatch), e.g. '*{catalogue.ATE_RMSE.key}'")
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
    baseline = Baseline(figures_from_json(data["metrics"], str(path)), tolerances, str(data.get("description", "")),
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


def figures_from_json(data: Mapping[str, Any], source: str = "<data>") -> dict[str, float]:
    """A flat JSON object of figures (name -> number or null) as ``name -> float`` (null -> NaN); :class:`GateError`
    naming ``source`` and the first value that is not a number."""
    out = {}
    for name, value in data.items():
        if isinstance(value, bool) or (value is not None and not isinstance(value, int | float)):
            raise GateError(f"{source}: metric {name!r} is {value!r}, not a number")
        out[str(name)] = as_float(value)
    return out


def read_json_file(path: str | Path) -> Any:
    """The content of the JSON file ``path``; :class:`GateError` naming it when it cannot be read or parsed."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except OSError as exc:
        raise GateError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise GateError(f"{path}:{exc.lineno}: not valid JSON: {exc.msg}") from exc


def as_float(value: Any) -> float:
    """A JSON number as a float, null (None) as NaN."""
    return math.nan if value is None else float(value)
