"""Sim-to-real transfer of a benchmark's verdicts: do the simulated sequences rank the methods as real ones do?

The question every user of a synthetic benchmark should ask (``cnnslam bench transfer``). Runs are grouped into
**domains**: the simulated Table-1 analogues under one camera preset (``sim:clean``, ``sim:kinect``, ...), and each
real RGB-D folder (``real:<name>``). Per domain, metric and method:

- **score** (:func:`domain_scores`): the median over a cell's runs (its seeds), then the mean over the domain's
  sequences (the Avg. row of Table 1); a method missing a sequence of the domain gets no score there;
- **rank** (:func:`rank_methods`): 1 = best, in the metric's direction (:data:`TRANSFER_METRICS`), ties share the
  mean rank (``scipy.stats.rankdata``), over the methods that have a score in every domain compared;
- **agreement** (:func:`rank_correlations`): Spearman's rho and Kendall's tau-b (``scipy.stats``) between each
  simulated domain's ranks and each real domain's, with the number of methods n and the two-sided p-values (with
  n = 5 methods, scipy's p is below 0.05 only for rho >= 0.9: read the figures as agreement, not significance);
- **which camera predicts real data best** (:func:`best_predictor`): the simulated domain with the highest mean
  Spearman rho over the metrics and real domains.

Methods fed ground truth (the oracle) are left out of the rankings: they win by construction. The numeric core
does no I/O; :mod:`eval.reports` writes ``transfer.{md,csv,png}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from eval.errors import EvalError

SIM_PREFIX, REAL_PREFIX = "sim:", "real:"


@dataclass(frozen=True)
class TransferMetric:
    """A metric whose ranking is compared: its long-frame name, a label, and whether higher is better."""

    name: str
    label: str
    higher_is_better: bool


TRANSFER_METRICS: tuple[TransferMetric, ...] = (
    TransferMetric("ate_se3_rmse", "ATE, SE(3) [m]", False),
    TransferMetric("ate_sim3_rmse", "ATE, Sim(3) [m]", False),
    TransferMetric("rot_deg_orient_rmse", "rotation error, orientation-aligned [deg]", False),
    TransferMetric("depth_percent_correct", "correct depth [%]", True),
)


def domain_scores(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS) -> pd.DataFrame:
    """Scores per (domain, metric, method) from a long frame of runs.

    frame: columns ``domain``, ``sequence``, ``method``, ``metric``, ``value`` (one row per run and metric, as
    :func:`eval.results.runs_frame` gives, plus the domain). Returns columns domain, metric, method, score,
    sequences (how many the score averages), runs: the median over each cell's runs, then the mean over the
    domain's sequences; a method lacking a finite value on one of the domain's sequences gets no row.
    """
    need = {"domain", "sequence", "method", "metric", "value"}
    if missing := need - set(frame.columns):
        raise EvalError(f"a transfer frame needs columns {sorted(need)}; missing {sorted(missing)}")
    names = [m.name for m in metrics]
    sub = frame[frame["metric"].isin(names)]
    cells = (sub.groupby(["domain", "metric", "method", "sequence"])["value"]
             .agg(median="median", runs="count").reset_index())  # fmt: skip
    cells = cells[np.isfinite(cells["median"])]
    n_seq = sub.groupby("domain")["sequence"].nunique()
    out = cells.groupby(["domain", "metric", "method"]).agg(
        score=("median", "mean"), sequences=("sequence", "nunique"), runs=("runs", "sum")
    ).reset_index()
    out = out[out["sequences"] == out["domain"].map(n_seq)]
    return out.sort_values(["metric", "domain", "method"], ignore_index=True)


def rank_methods(scores: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS,
                 domains: Sequence[str] | None = None) -> pd.DataFrame:
    """``scores`` (:func:`domain_scores`) with a ``rank`` column: 1 = best in each (domain, metric), ties sharing
    their mean rank, over the methods scored in every one of ``domains`` (default: all domains) for that metric,
    so that every domain ranks the same set. Rows of other methods are dropped."""
    direction = {m.name: m.higher_is_better for m in metrics}
    domains = list(domains) if domains is not None else sorted(scores["domain"].unique())
    parts = []
    for metric, group in scores[scores["domain"].isin(domains)].groupby("metric"):
        per_method = group.groupby("method")["domain"].nunique()
        common = set(per_method[per_method == len(domains)].index)
        group = group[group["method"].isin(common)].copy()
        sign = -1.0 if direction.get(str(metric), False) else 1.0
        group["rank"] = group.groupby("domain")["score"].transform(lambda s, k=sign: stats.rankdata(k * s.to_numpy()))
        parts.append(group)
    if not parts:
        return scores.iloc[0:0].assign(rank=pd.Series(dtype=float))
    return pd.concat(parts, ignore_index=True).sort_values(["metric", "domain", "rank"], ignore_index=True)


def _correlation(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float]:
    """Spearman rho and p, Kendall tau-b and p of two rankings (NaN where undefined, e.g. a constant ranking)."""
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return math.nan, math.nan, math.nan, math.nan
    rho, p_rho = stats.spearmanr(a, b)
    tau, p_tau = stats.kendalltau(a, b)
    return float(rho), float(p_rho), float(tau), float(p_tau)


def rank_correlations(ranks: pd.DataFrame) -> pd.DataFrame:
    """Spearman and Kendall agreement between every simulated domain (``sim:...``) and every real one (``real:...``)
    per metric, over the methods both rank. Columns: sim, real, metric, n (methods), spearman, spearman_p, kendall,
    kendall_p, methods (comma-separated)."""
    rows = []
    sims = sorted(d for d in ranks["domain"].unique() if d.startswith(SIM_PREFIX))
    reals = sorted(d for d in ranks["domain"].unique() if d.startswith(REAL_PREFIX))
    for metric, group in ranks.groupby("metric", sort=True):
        wide = group.pivot_table(index="method", columns="domain", values="rank")
        for sim in sims:
            for real in reals:
                if sim not in wide or real not in wide:
                    continue
                both = wide[[sim, real]].dropna()
                rho, p_rho, tau, p_tau = _correlation(both[sim].to_numpy(), both[real].to_numpy())
                rows.append({"sim": sim, "real": real, "metric": metric, "n": len(both), "spearman": rho,
                             "spearman_p": p_rho, "kendall": tau, "kendall_p": p_tau,
                             "methods": ", ".join(both.index)})  # fmt: skip
    return pd.DataFrame(rows, columns=["sim", "real", "metric", "n", "spearman", "spearman_p", "kendall",
                                       "kendall_p", "methods"])  # fmt: skip


def best_predictor(correlations: pd.DataFrame) -> tuple[str, float] | None:
    """The simulated domain whose rankings agree best with the real ones: ``(domain, mean Spearman rho over
    metrics and real domains)``, or None when no correlation is defined."""
    finite = correlations[np.isfinite(correlations["spearman"].astype(float))]
    if finite.empty:
        return None
    mean = finite.groupby("sim")["spearman"].mean().sort_values(ascending=False, kind="stable")
    return str(mean.index[0]), float(mean.iloc[0])
