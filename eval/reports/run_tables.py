"""Tables of a suite's report that summarise its runs rather than a metric per cell: what each method used (speed and
memory, as VSLAM-LAB and SLAMBench summarise them) and the relative error at several distances per sequence and
method (rpg_trajectory_evaluation's distances). Each is a frame (numbers) and its Markdown; the HTML report renders
the Markdown with the rest of the report. Failed runs (:func:`eval.metrics.results.failure_of`) count in the speed
and memory (they used them) but in no error: a relative-error cell is ``X (22 %)`` when at least half of its runs
failed, else over the runs that did not fail, with ``k/n failed``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from eval.metrics import catalogue
from eval.metrics.catalogue import TRACKED_SHARE, WALL_S
from eval.metrics.results import failure_of, failure_text
from eval.metrics.trajectory_metrics import RELATIVE_PATH_SHARES, RELATIVE_TOLERANCE
from eval.reports.inputs import SuiteRun
from eval.reports.run_data import missing_reasons

RESOURCE_COLUMNS: tuple[tuple[str, str, int], ...] = tuple(  # (resource figure, heading, decimals)
    (s.key, s.label_at(catalogue.RESOURCES), s.digits) for s in catalogue.shown_at(catalogue.RESOURCES))


def _cell(median: float, lo: float, hi: float, digits: int) -> str:
    """``median [min, max]`` with ``digits`` decimals, a bare median where the range is one value."""
    text = f"{median:.{digits}f}"
    return text if f"{lo:.{digits}f}" == f"{hi:.{digits}f}" else f"{text} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _spread_text(values: np.ndarray, digits: int) -> str:
    """:func:`_cell` of the finite values, ``-`` for none."""
    v = values[np.isfinite(values)]
    return _cell(float(np.median(v)), float(v.min()), float(v.max()), digits) if v.size else "-"


def resources_frame(run: SuiteRun) -> pd.DataFrame:
    """One row per method with finished runs (suite order): ``runs``, ``frames`` (median per run), then per
    resource figure of :data:`RESOURCE_COLUMNS` the ``median``, ``min``, ``max`` and
    ``count`` over its runs (columns ``<figure>_<stat>``), and ``wall_min_total`` (minutes, all its runs)."""
    rows = []
    for method in run.suite.methods:
        records = [r for r in run.records if r.method == method]
        if not records:
            continue
        row: dict[str, float | str] = {"method": method, "runs": len(records),
                                       "frames": float(np.median([r.metrics.get("frames", math.nan) for r in records]))}
        for name in (c[0] for c in RESOURCE_COLUMNS):
            v = np.array([r.resources.get(name, math.nan) for r in records], dtype=float)
            f = v[np.isfinite(v)]
            row.update({f"{name}_median": float(np.median(f)) if f.size else math.nan,
                        f"{name}_min": float(f.min()) if f.size else math.nan,
                        f"{name}_max": float(f.max()) if f.size else math.nan, f"{name}_count": int(f.size)})
        walls = np.array([r.resources.get(WALL_S.key, math.nan) for r in records], dtype=float)
        row["wall_min_total"] = float(np.nansum(walls) / 60.0) if np.isfinite(walls).any() else math.nan
        rows.append(row)
    return pd.DataFrame(rows)


def resources_markdown(run: SuiteRun) -> str:
    """The speed and memory table per method (median [min, max] over its runs); a figure a method has no value of
    says ``n/a`` and why. Empty when no run finished."""
    frame = resources_frame(run)
    if frame.empty:
        return ""
    heads = [h for _, h, _ in RESOURCE_COLUMNS]
    lines = ["## Speed and memory per method\n",
             "Per run, median [min, max] over the method's runs: wall time (the whole run: frames rendered or read, "
             "the agent, scoring, plots; runs two at a time share the machine), frames per second end to end "
             "(frames / wall time) and of the agent's step alone, and the peak resident memory of the process that ran "
             "it (a fresh worker per run; a system run in a process of its own, ORB-SLAM3, is not in it). An external "
             f"method's wall time and frames per second are its own (`{WALL_S.key}` of its `run.toml`), not the "
             "judge's scoring time. Every run's "
             "figures: `resources` of its record, `timing.json` of its folder. Failed runs count here: they used "
             "the time and memory.\n",
             "| method | runs | frames per run | " + " | ".join(heads) + " | all its runs [min] |",
             "|---|---:|---:|" + "---:|" * len(heads) + "---:|"]  # fmt: skip
    for row in frame.itertuples(index=False):
        data = row._asdict()
        cells = []
        for name, _, digits in RESOURCE_COLUMNS:
            values = np.array([r.resources.get(name, math.nan) for r in run.records if r.method == row.method])
            text = _spread_text(values.astype(float), digits)
            if text == "-":
                why = missing_reasons(run, name, [row.method]).get(row.method, "not recorded")
                text = "n/a (" + ("not recorded by the code that made these runs" if why == "no value on its runs"
                                  else why) + ")"  # fmt: skip
            cells.append(text)
        total = "-" if math.isnan(data["wall_min_total"]) else f"{data['wall_min_total']:.1f}"
        lines.append(f"| {row.method} | {row.runs} | {data['frames']:.0f} | " + " | ".join(cells) + f" | {total} |")
    return "\n".join(lines) + "\n"


def relative_error_frame(run: SuiteRun, shares: Sequence[int] = RELATIVE_PATH_SHARES) -> pd.DataFrame:
    """Long: one row per (sequence, method, share) with a value: ``distance_m`` and, over the cell's runs that did
    not fail, the median, min and max of the relative translation (``trans_*``, m) and rotation (``rot_*``, deg)
    error RMSE; ``runs`` and ``failed`` (its runs, those that failed: :func:`eval.metrics.results.failure_of`) and
    ``failure``: ``X (22 %)`` when at least half failed (its figures NaN), else empty."""
    rows = []
    for sequence in [s.name for s in run.suite.sequences]:
        for method in run.suite.methods:
            every = [r for r in run.records if r.sequence == sequence and r.method == method]
            lost = [r for r in every if failure_of(r.metrics) is not None]
            records = [r for r in every if failure_of(r.metrics) is None]
            failed_cell = bool(lost) and 2 * len(lost) >= len(every)
            count = {"runs": len(every), "failed": len(lost), "failure": ""}
            if failed_cell:
                share = float(np.median([r.metrics.get(TRACKED_SHARE.key, 0.0) for r in lost]))
                count["failure"] = failure_text(share if math.isfinite(share) else 0.0)
                records = []
            for share in shares:
                distance, translation, rotation = catalogue.relative_keys(share)
                if failed_cell:
                    if any(translation in r.metrics for r in lost):
                        d = np.array([r.metrics.get(distance, math.nan) for r in lost], dtype=float)
                        rows.append({"sequence": sequence, "method": method, "share": share,
                                     "distance_m": float(np.median(d[np.isfinite(d)])) if np.isfinite(d).any()
                                     else math.nan, **count})  # fmt: skip
                    continue
                t = np.array([r.metrics.get(translation, math.nan) for r in records], dtype=float)
                q = np.array([r.metrics.get(rotation, math.nan) for r in records], dtype=float)
                d = [r.metrics.get(distance, math.nan) for r in records]
                if not np.isfinite(t).any():
                    continue
                ft, fq = t[np.isfinite(t)], q[np.isfinite(q)]
                rows.append({"sequence": sequence, "method": method, "share": share,
                             "distance_m": float(np.nanmedian(np.asarray(d, dtype=float))),
                             "trans_median": float(np.median(ft)), "trans_min": float(ft.min()),
                             "trans_max": float(ft.max()),
                             "rot_median": float(np.median(fq)) if fq.size else math.nan,
                             "rot_min": float(fq.min()) if fq.size else math.nan,
                             "rot_max": float(fq.max()) if fq.size else math.nan, **count})  # fmt: skip
    return pd.DataFrame(rows)


def relative_error_markdown(run: SuiteRun, shares: Sequence[int] = RELATIVE_PATH_SHARES) -> str:
    """Two tables, relative translation error [m] and relative rotation error [deg], one row per sequence and method
    with a trajectory, one column per distance (``share`` % of the ground truth's path; the distances in metres in
    the row), median [min, max] over the cell's runs of each run's RMSE; empty without values."""
    frame = relative_error_frame(run, shares)
    if frame.empty:
        return ""
    lines = ["## Relative error at several distances\n",
             f"rpg_trajectory_evaluation's relative error: the RPE over every pair of poses whose ground-truth path "
             f"distance is {', '.join(f'{s}' for s in shares)} % of the sequence's path (within "
             f"{100 * RELATIVE_TOLERANCE:.0f} % of the distance; evo_rpe --delta D --delta_unit m --all_pairs "
             "--pairs_from_reference), after the run's ATE alignment; each run's RMSE, median [min, max] over the "
             "cell's runs. Boxplots over every pair: the per-sequence figures below.\n"]  # fmt: skip
    for kind, title, digits in (("trans", "Relative translation error [m]", 4), ("rot", "Relative rotation error "
                                                                                        "[deg]", 3)):  # fmt: skip
        lines += [f"**{title}**\n", "| sequence | method | distances [m] | " + " | ".join(f"{s} %" for s in shares)
                  + " |", "|---|---|---|" + "---:|" * len(shares)]  # fmt: skip
        for (sequence, method), cell in frame.groupby(["sequence", "method"], sort=False):
            by_share = cell.set_index("share")
            texts = []
            failure = str(cell["failure"].iloc[0])
            failed = int(cell["failed"].iloc[0])
            for s in shares:
                if failure:
                    texts.append(failure)
                    continue
                if s not in by_share.index or not np.isfinite(by_share.at[s, f"{kind}_median"]):
                    texts.append("-")
                    continue
                texts.append(_cell(*(by_share.at[s, f"{kind}_{k}"] for k in ("median", "min", "max")), digits)
                             + (f" ({failed}/{int(cell['runs'].iloc[0])} failed)" if failed else ""))  # fmt: skip
            distances = ", ".join("-" if not np.isfinite(d) else f"{d:g}" for d in cell["distance_m"])
            lines.append(f"| {sequence} | {method} | {distances} | " + " | ".join(texts) + " |")
        lines.append("")
    return "\n".join(lines) + "\n"
