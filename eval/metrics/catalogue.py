"""The metric catalogue: one :class:`MetricSpec` per figure a run record, a report or the gate knows, as data.

Each spec gives a metric's flat name (its ``key`` in a run record's ``metrics``, :mod:`eval.metrics.results`), its
label and unit, which way is better, its metric group (what a method declares it reports,
:mod:`eval.bench.methods`), how many decimals a figure is written with, the gate's default allowed change and its
floor (:mod:`eval.bench.regress`: ``max(abs, rel x |baseline|)``), the range the figure can take, and where it is
shown (:class:`Shown`: a table's column block or a plot's panel, at a position, under a label). The record, the gate,
the tables (Markdown, CSV, LaTeX, HTML), the plots and ``cnnslam eval`` read it; none spells a metric key itself.
evo keeps the same knowledge as data (``PoseRelation``, ``StatisticsType``, ``Unit``).

A **family** is a spec whose key is an ``fnmatch`` pattern (``rpe_*``): it covers the names no exact spec has (the
statistics of an error, the per-share relative errors, the per-class IoU). :func:`spec_of` finds a name's spec: the
exact one, else the first family in :data:`FAMILIES` that matches. The gate's rules (:func:`gate_rules`, first match
wins) and bounds (:func:`bound_rules`) are derived from the same order: exact specs first, then the families; no
rule shadows a later one.

A new metric: compute it where its kind is computed (a trajectory figure in
:meth:`eval.metrics.trajectory_metrics.TrajectoryMetrics.flat_metrics`, a key-frame figure in
:func:`eval.metrics.results.evaluate_episode`, reading its key from its spec here) and add its spec to
:data:`CATALOGUE` (with ``gated=True`` to gate it and a :class:`Shown` per table or plot that shows it). Nothing else
names it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from fnmatch import fnmatchcase
from typing import Literal

from eval.errors import EvalError
from slamcommon import agent_keys

Better = Literal["lower", "higher", "match"]
Group = Literal["trajectory", "depth", "semantic", "map"]
Kind = Literal["metric", "timing", "resource", "report"]
GROUPS: tuple[str, ...] = ("trajectory", "depth", "semantic", "map")
UNBOUNDED: tuple[float, float] = (-math.inf, math.inf)
NON_NEGATIVE: tuple[float, float] = (0.0, math.inf)
SHARE: tuple[float, float] = (0.0, 1.0)  # a share of frames, pixels or points; a 0/1 flag
PERCENT: tuple[float, float] = (0.0, 100.0)
ANGLE: tuple[float, float] = (0.0, 180.0)  # degrees between two orientations

# Where a figure is shown (Shown.place): the suites' tables (eval.reports.suite_reports), the HTML report's facts of
# one run and the resources table (eval.reports.html_report, eval.reports.run_tables), the rankings compared across
# domains, lengths and settings (eval.reports.transfer, eval.reports.sensitivity) and the plots' panels.
TABLE1, ROTATION, SIM3, MAP, QUICK, SWEEP, DEPTH_QUALITY = (
    "table1", "rotation", "sim3", "map", "quick", "sweep", "depth_quality")
RUN_FACTS, RESOURCES, TRANSFER, SENSITIVITY, DECISIVE = "run_facts", "resources", "transfer", "sensitivity", "decisive"
RUNS_FIGURE, SWEEP_FIGURE, SECOND_REFERENCE = "runs_figure", "sweep_figure", "second_reference"


@dataclass(frozen=True)
class Shown:
    """One place a metric is shown: ``place`` (a table's block list or a plot, the names above), ``at`` (its
    position there, 0 first), ``label`` (the heading or axis label there; empty: the spec's :attr:`label`) and
    ``factor`` (the figure is multiplied by it there: 100 shows a share as percent)."""

    place: str
    at: int
    label: str = ""
    factor: float = 1.0


@dataclass(frozen=True)
class MetricSpec:
    """What the judge knows of one metric (or, with a pattern as ``key``, of a family of them).

    key: the flat name in a run record (``fnmatch`` pattern for a family); label: its heading; unit: ``"m"``,
    ``"deg"``, ``"%"`` (percent, 0..100), ``""`` (a share, a ratio or a flag), ``"count"``, ``"s"``, ``"ms"``,
    ``"1/s"`` or ``"MiB"``; better: ``"lower"``, ``"higher"``, ``"match"`` (a count that should not change) or None
    (neither: a scale, a length); group: the metric group a method declares (None: kept by every method or none);
    digits: decimals of a figure in the HTML report; tolerance: the gate's default ``(abs, rel)`` allowed change, its
    floor when calibrated (None: the gate's fallback); bounds: ``(low, high)``, the range the figure can take; gated:
    compared by the quick gate; kind: ``metric`` (in ``metrics.json``, the same bytes run after run), ``timing``
    (measured wall-clock figures of the step, kept apart), ``resource`` (a run's measured use, ``timing.json``) or
    ``report`` (derived by a report from other metrics); resource: also one of a run's resource figures;
    shown: where it is shown (:class:`Shown`)."""

    key: str
    label: str
    unit: str = ""
    better: Better | None = None
    group: Group | None = None
    digits: int = 3
    tolerance: tuple[float, float] | None = None
    bounds: tuple[float, float] = UNBOUNDED
    gated: bool = False
    kind: Kind = "metric"
    resource: bool = False
    shown: tuple[Shown, ...] = field(default_factory=tuple)

    @property
    def is_family(self) -> bool:
        """True when :attr:`key` is a pattern covering many names."""
        return any(c in self.key for c in "*?[")

    @property
    def higher_is_better(self) -> bool:
        """True when higher values are better."""
        return self.better == "higher"

    @property
    def table_direction(self) -> str | None:
        """``"lower"`` or ``"higher"`` when a table can mark a best value, None otherwise (a count, a scale)."""
        return self.better if self.better in ("lower", "higher") else None

    @property
    def gate_direction(self) -> Better:
        """The gate's direction: :attr:`better`, or ``"lower"`` (the gate's fallback) when neither way is better."""
        return self.better or "lower"

    @property
    def unit_suffix(self) -> str:
        """The unit as written after a figure (``" m"``, ``" %"``; empty for a share or a count)."""
        return f" {self.unit}" if self.unit and self.unit not in ("count", "1/s") else ""

    def label_at(self, place: str) -> str:
        """The label this metric is shown under at ``place`` (:attr:`label` unless the place gives its own)."""
        return next((s.label or self.label for s in self.shown if s.place == place), self.label)

    def factor_at(self, place: str) -> float:
        """What the figure is multiplied by where it is shown at ``place`` (1 unless the place says otherwise)."""
        return next((s.factor for s in self.shown if s.place == place), 1.0)


def _shown(*places: tuple) -> tuple[Shown, ...]:
    return tuple(Shown(*p) for p in places)


_ATE_LABEL = "Abs. Trajectory Error [m]"
_DEPTH_LABEL = "Perc. Correct Depth [%]"
_ERR = (0.002, 0.10)  # an error statistic's floor (metres or degrees): 2 mm, 10 %
_FINE = (0.02, 0.03)  # the gated rotation errors (deg)
_DEPTH_RATE = (1.0, 0.05)  # a percentage of pixels
_DEPTH_ERR = (0.005, 0.05)
_SEM = (0.01, 0.02)

# ------------------------------------------------------------------------------------------------------ trajectory
ATE_RMSE = MetricSpec("ate_rmse", _ATE_LABEL, "m", "lower", "trajectory", 4, (0.0005, 0.03), NON_NEGATIVE, gated=True,
                      shown=_shown((TABLE1, 0), (QUICK, 0), (SWEEP, 0), (RUN_FACTS, 0, "ATE (headline)"),
                                   (RUNS_FIGURE, 0, "ATE RMSE, SE(3) [m]"), (SWEEP_FIGURE, 0, "ATE RMSE [m]")))
ATE_SE3_RMSE = MetricSpec("ate_se3_rmse", "ATE, SE(3) [m]", "m", "lower", "trajectory", 4, _ERR, NON_NEGATIVE,
                          shown=_shown((RUN_FACTS, 1, "ATE SE(3)"), (TRANSFER, 0), (DECISIVE, 0),
                                       (SECOND_REFERENCE, 0, "SE(3) ATE [m]")))
ATE_SIM3_RMSE = MetricSpec("ate_sim3_rmse", "ATE, Sim(3) [m]", "m", "lower", "trajectory", 4, _ERR, NON_NEGATIVE,
                           shown=_shown((SIM3, 0, "ATE after Sim(3) alignment [m]"),
                                        (QUICK, 2, "ATE after Sim(3) alignment [m]"), (RUN_FACTS, 2, "ATE Sim(3)"),
                                        (TRANSFER, 1), (SECOND_REFERENCE, 1, "Sim(3) ATE [m]")))
ATE_MAX = MetricSpec("ate_max", "ATE, max [m]", "m", "lower", "trajectory", 4, _ERR, NON_NEGATIVE)
ATE_PAIRS = MetricSpec("ate_pairs", "pose pairs scored", "count", "match", "trajectory", 0, (0.0, 0.0), NON_NEGATIVE)
ATE_ALIGNMENT_DEGENERATE = MetricSpec("ate_alignment_degenerate", "alignment degenerate (0/1)", "", "lower",
                                      "trajectory", 0, _ERR, SHARE)
ATE_ALIGNMENT_FALLBACK = MetricSpec("ate_alignment_fallback", "alignment fell back (0/1)", "", "lower", "trajectory",
                                    0, _ERR, SHARE)
RPE_ROT_DEG_RMSE = MetricSpec("rpe_rot_deg_rmse", "RPE rotation, 1 s [deg]", "deg", "lower", "trajectory", 2, _FINE,
                              ANGLE, shown=_shown((ROTATION, 2)))
RPE_ROT_DEG_PAIRS = MetricSpec("rpe_rot_deg_pairs", "RPE pairs", "count", "match", "trajectory", 0, (0.0, 0.0),
                               NON_NEGATIVE)
RPE_TRANS_RMSE = MetricSpec("rpe_trans_rmse", "RPE translation, 1 s [m]", "m", "lower", "trajectory", 4, _ERR,
                            NON_NEGATIVE)
RPE_TRANS_PAIRS = MetricSpec("rpe_trans_pairs", "RPE pairs", "count", "match", "trajectory", 0, (0.0, 0.0),
                             NON_NEGATIVE)
ROT_DEG_ORIENT_RMSE = MetricSpec("rot_deg_orient_rmse", "Rotation error, orientation-aligned [deg]", "deg", "lower",
                                 "trajectory", 2, _FINE, ANGLE, gated=True,
                                 shown=_shown((ROTATION, 1), (RUN_FACTS, 4, "rotation, orientation-aligned"),
                                              (TRANSFER, 2, "rotation error, orientation-aligned [deg]"),
                                              (SECOND_REFERENCE, 3, "rotation, orientation-aligned [deg]")))
ROT_DEG_RMSE = MetricSpec("rot_deg_rmse", "Rotation error [deg]", "deg", "lower", "trajectory", 2, _FINE, ANGLE,
                          gated=True, shown=_shown((DEPTH_QUALITY, 3)))
ROT_DEG_PAIRS = MetricSpec("rot_deg_pairs", "rotation pairs", "count", "match", "trajectory", 0, (0.0, 0.0),
                           NON_NEGATIVE)
SCALE = MetricSpec("scale", "Sim(3) scale", "", "match", "trajectory", 4, (0.02, 0.0), NON_NEGATIVE)
SCALE_ERROR = MetricSpec("scale_error", "scale error", "", "lower", "trajectory", 3, (0.01, 0.10), NON_NEGATIVE,
                         shown=_shown((RUN_FACTS, 3), (SECOND_REFERENCE, 2, "scale error [%]", 100.0)))
LENGTH_GT_M = MetricSpec("length_gt_m", "ground-truth path length [m]", "m", "match", "trajectory", 3, (0.0, 0.10),
                         NON_NEGATIVE)
LENGTH_EST_M = MetricSpec("length_est_m", "estimated path length [m]", "m", "match", "trajectory", 3, (0.0, 0.10),
                          NON_NEGATIVE)
TRACKED_SHARE = MetricSpec(agent_keys.TRACKED_SHARE, "Tracked share", "", "higher", "trajectory", 3, (0.005, 0.0),
                           SHARE, gated=True,
                           shown=_shown((ROTATION, 0), (QUICK, 3), (SWEEP, 2), (RUN_FACTS, 5, "tracked share"),
                                        (SENSITIVITY, 4, "tracked share")))
# the depth_quality report's columns, derived there from the record's figures
ATE_PERCENT_LENGTH = MetricSpec("ate_percent_length", "ATE / length [%]", "%", "lower", "trajectory", 2, _ERR,
                                NON_NEGATIVE, kind="report", shown=_shown((DEPTH_QUALITY, 0)))
SCALE_ERROR_PERCENT = MetricSpec("scale_error_percent", "Scale error [%]", "%", "lower", "trajectory", 2, None,
                                 NON_NEGATIVE, kind="report", shown=_shown((DEPTH_QUALITY, 1)))

# ----------------------------------------------------------------------------------------------------------- depth
DEPTH_PERCENT_CORRECT = MetricSpec("depth_percent_correct", _DEPTH_LABEL, "%", "higher", "depth", 2, (0.3, 0.0),
                                   PERCENT, gated=True,
                                   shown=_shown((TABLE1, 1), (ROTATION, 3), (QUICK, 1), (SWEEP, 1), (DEPTH_QUALITY, 2),
                                                (RUN_FACTS, 6, "correct depth"), (TRANSFER, 3, "correct depth [%]"),
                                                (DECISIVE, 1), (RUNS_FIGURE, 1, "correct depth [%]"),
                                                (SWEEP_FIGURE, 1, "correct depth [%]")))
DEPTH_PERCENT_CORRECT_MEAN = MetricSpec("depth_percent_correct_mean", "correct depth, mean over key-frames [%]", "%",
                                        "higher", "depth", 2, _DEPTH_RATE, PERCENT)
DEPTH_DENSITY = MetricSpec("depth_density", "depth density [%]", "%", "higher", "depth", 2, _DEPTH_RATE, PERCENT)
DEPTH_ABS_REL = MetricSpec("depth_abs_rel", "depth abs. rel. error", "", "lower", "depth", 3, _DEPTH_ERR, NON_NEGATIVE)
DEPTH_RMSE = MetricSpec("depth_rmse", "depth RMSE [m]", "m", "lower", "depth", 3, _DEPTH_ERR, NON_NEGATIVE)
DEPTH_DELTA_1_25 = MetricSpec("depth_delta_1_25", "depth within 1.25x [%]", "%", "higher", "depth", 2, _DEPTH_RATE,
                              PERCENT)
DEPTH_KEYFRAMES = MetricSpec("depth_keyframes", "key-frames scored", "count", "match", "depth", 0, (2.0, 0.0),
                             NON_NEGATIVE)

# -------------------------------------------------------------------------------------------------------- semantic
SEMANTIC_PIXEL_ACCURACY = MetricSpec("semantic_pixel_accuracy", "label pixel accuracy", "", "higher", "semantic", 3,
                                     _SEM, SHARE)
SEMANTIC_MEAN_IOU = MetricSpec("semantic_mean_iou", "label mean IoU", "", "higher", "semantic", 3, _SEM, SHARE)

# ------------------------------------------------------------------------------------------------------------- map
MAP_ACCURACY_MEDIAN = MetricSpec("map_accuracy_median", "Map accuracy, median [m]", "m", "lower", "map", 3,
                                 (0.005, 0.05), NON_NEGATIVE, gated=True,
                                 shown=_shown((MAP, 0), (QUICK, 4), (RUN_FACTS, 7, "map accuracy, median")))
MAP_ACCURACY_WITHIN = MetricSpec("map_accuracy_within", "Map accuracy within 5 cm", "", "higher", "map", 3,
                                 (0.01, 0.03), SHARE)
MAP_COMPLETENESS_MEDIAN = MetricSpec("map_completeness_median", "Map completeness, median [m]", "m", "lower", "map", 3,
                                     (0.005, 0.05), NON_NEGATIVE)
MAP_COMPLETENESS_WITHIN = MetricSpec("map_completeness_within", "Map completeness within 5 cm", "", "higher", "map",
                                     3, (0.01, 0.03), SHARE, gated=True, shown=_shown((MAP, 1), (QUICK, 5)))
MAP_LABEL_ACCURACY = MetricSpec("map_label_accuracy", "Map label accuracy", "", "higher", "map", 3, (0.01, 0.02),
                                SHARE, gated=True, shown=_shown((MAP, 2), (QUICK, 6)))
MAP_POINTS = MetricSpec("map_points", "map points", "count", "match", "map", 0, (0.0, 0.10), NON_NEGATIVE)

# ------------------------------------------------------------------------------------------ counts, speed, resources
FRAMES = MetricSpec(agent_keys.FRAMES, "frames", "count", "match", None, 0, (0.0, 0.0), NON_NEGATIVE)
STEP_MS_MEAN = MetricSpec("step_ms_mean", "step time, mean [ms]", "ms", "lower", None, 1, (0.0, 0.50), NON_NEGATIVE,
                          kind="timing")
STEP_MS_MEDIAN = MetricSpec("step_ms_median", "step time, median [ms]", "ms", "lower", None, 1, (0.0, 0.50),
                            NON_NEGATIVE, kind="timing")
STEP_MS_MAX = MetricSpec("step_ms_max", "step time, max [ms]", "ms", "lower", None, 1, (0.0, 0.50), NON_NEGATIVE,
                         kind="timing")
WALL_S = MetricSpec("wall_s", "wall time per run [s]", "s", "lower", None, 1, kind="resource", resource=True,
                    shown=_shown((RUN_FACTS, 8, "wall time"), (RESOURCES, 0)))
FPS_END_TO_END = MetricSpec("fps_end_to_end", "frames per second, end to end", "1/s", "higher", None, 1,
                            kind="resource", resource=True,
                            shown=_shown((RUN_FACTS, 9), (RESOURCES, 1)))
FPS = MetricSpec("fps", "frames per second, the agent's step", "1/s", "higher", None, 1, (0.0, 0.33), NON_NEGATIVE,
                 kind="timing", resource=True,
                 shown=_shown((RUN_FACTS, 10, "frames per second, agent's step"), (RESOURCES, 2)))
PEAK_RSS_MIB = MetricSpec("peak_rss_mib", "peak memory [MiB]", "MiB", "lower", None, 0, kind="resource",
                          resource=True, shown=_shown((RUN_FACTS, 11, "peak memory"), (RESOURCES, 3)))
METHOD_WALL_S = MetricSpec("method_wall_s", "the system's own run time [s]", "s", None, None, 1, kind="resource",
                           resource=True)
MAP_SCORING_S = MetricSpec("map_scoring_s", "map scoring time [s]", "s", None, "map", 2, None, NON_NEGATIVE,
                           kind="timing")

# The exact specs, in the gate's order (no rule may shadow a later one: a name ending in another's key goes first).
CATALOGUE: tuple[MetricSpec, ...] = (
    ATE_RMSE, ATE_SE3_RMSE, ATE_SIM3_RMSE, ATE_MAX, ATE_PAIRS, ATE_ALIGNMENT_DEGENERATE, ATE_ALIGNMENT_FALLBACK,
    RPE_ROT_DEG_RMSE, RPE_ROT_DEG_PAIRS, RPE_TRANS_RMSE, RPE_TRANS_PAIRS,
    ROT_DEG_ORIENT_RMSE, ROT_DEG_RMSE, ROT_DEG_PAIRS,
    SCALE_ERROR_PERCENT, SCALE_ERROR, SCALE, LENGTH_GT_M, LENGTH_EST_M, TRACKED_SHARE, ATE_PERCENT_LENGTH,
    DEPTH_PERCENT_CORRECT, DEPTH_PERCENT_CORRECT_MEAN, DEPTH_DENSITY, DEPTH_ABS_REL, DEPTH_RMSE, DEPTH_DELTA_1_25,
    DEPTH_KEYFRAMES,
    SEMANTIC_PIXEL_ACCURACY, SEMANTIC_MEAN_IOU,
    MAP_ACCURACY_MEDIAN, MAP_ACCURACY_WITHIN, MAP_COMPLETENESS_MEDIAN, MAP_COMPLETENESS_WITHIN, MAP_LABEL_ACCURACY,
    MAP_POINTS,
    FRAMES, STEP_MS_MEAN, STEP_MS_MEDIAN, STEP_MS_MAX, WALL_S, FPS_END_TO_END, FPS, PEAK_RSS_MIB, METHOD_WALL_S,
    MAP_SCORING_S,
)
# The families, first match wins: the statistics of each error (evo's StatisticsType: rmse, mean, median, std, min,
# max), the relative errors per share of the path (``_p<share>``) and the per-class IoU (``semantic_iou_<class>``).
FAMILIES: tuple[MetricSpec, ...] = (
    MetricSpec("ate_*", "ATE statistic [m]", "m", "lower", "trajectory", 4, _ERR, NON_NEGATIVE),
    MetricSpec("rpe_rot_deg_*", "RPE rotation statistic [deg]", "deg", "lower", "trajectory", 2, _ERR, ANGLE),
    MetricSpec("rpe_dist_m_*", "relative-error distance [m]", "m", None, "trajectory", 2, _ERR, NON_NEGATIVE),
    MetricSpec("rpe_*", "RPE translation statistic [m]", "m", "lower", "trajectory", 4, _ERR, NON_NEGATIVE),
    MetricSpec("rot_deg_*", "rotation error statistic [deg]", "deg", "lower", "trajectory", 2, (0.1, 0.10), ANGLE),
    MetricSpec("length_*", "path length [m]", "m", "match", "trajectory", 3, (0.0, 0.10), NON_NEGATIVE),
    MetricSpec("scale*", "scale figure", "", None, "trajectory", 3),
    MetricSpec("depth_*", "depth figure", "", None, "depth", 3),
    MetricSpec("semantic_*", "label figure", "", "higher", "semantic", 3, _SEM, SHARE),
    MetricSpec("map_*", "map figure", "", None, "map", 3, None, NON_NEGATIVE),
)
_BY_KEY: dict[str, MetricSpec] = {s.key: s for s in CATALOGUE}
# The relative errors at a share of the path (rpg_trajectory_evaluation's distances; families above): the distance
# (m), the translation RMSE (m) and the rotation RMSE (deg) at ``share`` percent
RELATIVE_TEMPLATES: tuple[str, str, str] = ("rpe_dist_m_p{share}", "rpe_trans_rmse_p{share}",
                                            "rpe_rot_deg_rmse_p{share}")


def relative_keys(share: int) -> tuple[str, str, str]:
    """The keys ``(distance, translation RMSE, rotation RMSE)`` of the relative errors at ``share`` % of the path."""
    distance, translation, rotation = (t.format(share=share) for t in RELATIVE_TEMPLATES)
    return distance, translation, rotation


class CatalogueError(EvalError):
    """A catalogue that contradicts itself (a key twice, a family given as an exact spec)."""


def check_catalogue(specs: Iterable[MetricSpec] = CATALOGUE, families: Iterable[MetricSpec] = FAMILIES) -> None:
    """Raise :class:`CatalogueError` naming the first problem: a key spelled twice, a pattern among the exact specs
    or an exact key among the families, a group outside :data:`GROUPS`, bounds with low > high, or a place given
    twice the same position."""
    specs, families = tuple(specs), tuple(families)
    seen: set[str] = set()
    for spec in (*specs, *families):
        if spec.key in seen:
            raise CatalogueError(f"metric {spec.key!r} is in the catalogue twice")
        seen.add(spec.key)
        if spec.group is not None and spec.group not in GROUPS:
            raise CatalogueError(f"metric {spec.key!r}: group {spec.group!r} is none of {', '.join(GROUPS)}")
        if spec.bounds[0] > spec.bounds[1]:
            raise CatalogueError(f"metric {spec.key!r}: bounds {spec.bounds} have low > high")
    for spec in specs:
        if spec.is_family:
            raise CatalogueError(f"exact spec {spec.key!r} is a pattern: put it among the families")
    for spec in families:
        if not spec.is_family:
            raise CatalogueError(f"family {spec.key!r} is no pattern: put it among the exact specs")
    taken: set[tuple[str, int]] = set()
    for spec in specs:
        for shown in spec.shown:
            if (shown.place, shown.at) in taken:
                raise CatalogueError(f"metric {spec.key!r}: position {shown.at} of {shown.place!r} is taken")
            taken.add((shown.place, shown.at))


def spec_of(name: str, specs: Iterable[MetricSpec] | None = None,
            families: Iterable[MetricSpec] = FAMILIES) -> MetricSpec | None:
    """The spec of a flat metric name: its exact spec, else the first family matching it; None when neither does.
    ``specs``: another catalogue (default :data:`CATALOGUE`)."""
    exact = _BY_KEY.get(name) if specs is None else next((s for s in specs if s.key == name), None)
    if exact is not None:
        return exact
    return next((f for f in families if fnmatchcase(name, f.key)), None)


def spec(key: str) -> MetricSpec:
    """The exact spec of ``key``; :class:`KeyError` naming the valid keys when the catalogue has none."""
    try:
        return _BY_KEY[key]
    except KeyError:
        raise KeyError(f"no metric {key!r} in the catalogue; known: {', '.join(_BY_KEY)}") from None


def group_of(name: str) -> str | None:
    """The metric group of a flat name (None: a figure of no group, kept by every method or by none)."""
    found = spec_of(name)
    return None if found is None else found.group


def better_direction(name: str) -> str | None:
    """``"lower"`` or ``"higher"``: which values of a metric are better; None for neither (a count, a scale)."""
    found = spec_of(name)
    return None if found is None else found.table_direction


def shown_at(place: str, specs: Iterable[MetricSpec] = CATALOGUE) -> tuple[MetricSpec, ...]:
    """The specs shown at ``place``, in their order there."""
    found = [(s, shown.at) for s in specs for shown in s.shown if shown.place == place]
    return tuple(s for s, _ in sorted(found, key=lambda pair: pair[1]))


def blocks(place: str, specs: Iterable[MetricSpec] = CATALOGUE) -> tuple[tuple[str, str], ...]:
    """A table's column blocks at ``place``: ``(label, key)`` pairs in their order."""
    return tuple((s.label_at(place), s.key) for s in shown_at(place, specs))


def keys(kind: str | None = None, *, gated: bool | None = None, resource: bool | None = None,
         specs: Iterable[MetricSpec] = CATALOGUE) -> tuple[str, ...]:
    """The exact keys, in catalogue order, of the given ``kind`` and flags (None: any)."""
    return tuple(s.key for s in specs if (kind is None or s.kind == kind) and (gated is None or s.gated == gated)
                 and (resource is None or s.resource == resource))  # fmt: skip


def gate_rules(specs: Iterable[MetricSpec] = CATALOGUE,
               families: Iterable[MetricSpec] = FAMILIES) -> tuple[tuple[str, str, float, float], ...]:
    """The gate's default tolerance rules: ``(pattern, direction, abs, rel)`` for every spec with a tolerance, exact
    specs first, then the families (first match wins; a pattern ``*key`` also matches the ``sequence/method/``
    and ``avg/method/`` names of the gate)."""
    return tuple((f"*{s.key}", s.gate_direction, float(s.tolerance[0]), float(s.tolerance[1]))
                 for s in (*specs, *families) if s.tolerance is not None)  # fmt: skip


def bound_rules(specs: Iterable[MetricSpec] = CATALOGUE,
                families: Iterable[MetricSpec] = FAMILIES) -> tuple[tuple[str, float, float], ...]:
    """The gate's metric bounds: ``(pattern, low, high)`` for every spec with a bound, in :func:`gate_rules`' order."""
    return tuple((f"*{s.key}", s.bounds[0], s.bounds[1]) for s in (*specs, *families) if s.bounds != UNBOUNDED)
