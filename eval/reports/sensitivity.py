"""Does a preprocessing choice decide a verdict? (``cnnslam bench preprocessing``)

On real images the way a folder's files become the frames an agent sees (how a distorted lens is undistorted, the
image size, whether depth is registered to the colour camera) can decide a method's fate: a baseline that tracks
7 % of a real sequence's frames with one undistortion may track 92 % with another. The preprocessing suite runs
each folder under the loader's defaults and under every choice that applies to it
(:data:`eval.bench.suites.PREPROCESSING_CHOICES`); per folder, choice and metric:

- **scores and ranks** (:func:`choice_ranks`): as :mod:`eval.reports.transfer` makes them (the median over each cell's
  runs; rank 1 best in the metric's direction), over the methods scored under every choice of the folder;
- **agreement with the defaults** (:func:`choice_agreement`): Kendall's tau-b and Spearman's rho of the choice's
  ranking against the default's, and whether the ranking is the same;
- **changed verdicts** (:func:`changed_verdicts`): a method whose rank moves, or whose tracked share moves by more
  than :data:`TRACKED_SHARE_CHANGE` (it tracks under one choice and is lost under another).

The numeric core does no I/O; :mod:`eval.reports.sensitivity_report` writes ``preprocessing.{md,csv}``.
"""

from __future__ import annotations

import pandas as pd

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.metrics.catalogue import TRACKED_SHARE
from eval.reports.transfer import (
    TRANSFER_METRICS,
    TransferMetric,
    domain_scores,
    rank_methods,
    ranking_agreement,
    transfer_metrics,
)

DEFAULT = "default"
TRACKED_SHARE_CHANGE = 0.2  # a change of the share of frames tracked that changes a verdict (20 points; ours)
SENSITIVITY_METRICS: tuple[TransferMetric, ...] = (*TRANSFER_METRICS, *transfer_metrics(catalogue.SENSITIVITY))


def choice_order(choices: list[str]) -> list[str]:
    """The default first, then the other choices in name order."""
    return sorted(set(choices), key=lambda c: (c != DEFAULT, c))


def choice_ranks(frame: pd.DataFrame, metrics: tuple[TransferMetric, ...] = SENSITIVITY_METRICS) -> pd.DataFrame:
    """Score and rank per (folder, choice, metric, method) from a long frame of runs with ``folder`` and ``choice``
    columns besides :func:`eval.reports.transfer.domain_scores`' columns; ranked per folder over the methods scored
    under every one of its choices. Columns: folder, choice, metric, method, score, sequences, runs, rank."""
    if missing := {"folder", "choice"} - set(frame.columns):
        raise EvalError(f"a preprocessing frame needs columns 'folder' and 'choice'; missing {sorted(missing)}")
    parts = []
    for folder, sub in frame.groupby("folder", sort=True):
        scores = domain_scores(sub.assign(domain=sub["choice"]), metrics)
        ranks = rank_methods(scores, metrics, domains=choice_order(list(scores["domain"].unique())))
        parts.append(ranks.rename(columns={"domain": "choice"}).assign(folder=folder))
    if not parts:
        return pd.DataFrame(columns=["folder", "choice", "metric", "method", "score", "sequences", "runs", "rank"])
    out = pd.concat(parts, ignore_index=True)
    return out[["folder", "choice", "metric", "method", "score", "sequences", "runs", "rank"]]


def choice_agreement(ranks: pd.DataFrame) -> pd.DataFrame:
    """Per (folder, metric, choice): n, Kendall's tau-b, Spearman's rho of the choice's ranking against the
    default's, and ``same`` (identical ranks). Columns: folder, metric, choice, n, kendall, spearman, same."""
    parts = [ranking_agreement(sub, "choice", DEFAULT, choice_order).assign(folder=folder)
             for folder, sub in ranks.groupby("folder", sort=True)]  # fmt: skip
    if not parts:
        return pd.DataFrame(columns=["folder", "metric", "choice", "n", "kendall", "spearman", "same"])
    return pd.concat(parts, ignore_index=True)[["folder", "metric", "choice", "n", "kendall", "spearman", "same"]]


def changed_verdicts(ranks: pd.DataFrame) -> pd.DataFrame:
    """The verdicts a choice changes: per folder, choice other than the default, metric and method, a rank other
    than under the default, or (tracked share) a score that differs by more than :data:`TRACKED_SHARE_CHANGE`.
    Columns: folder, choice, metric, method, default_score, score, default_rank, rank."""
    base = ranks[ranks["choice"] == DEFAULT][["folder", "metric", "method", "score", "rank"]]
    other = ranks[ranks["choice"] != DEFAULT].merge(base, on=["folder", "metric", "method"],
                                                     suffixes=("", "_default"))  # fmt: skip
    moved = other["rank"] != other["rank_default"]
    tracked = other["metric"] == TRACKED_SHARE.key
    moved = (moved & ~tracked) | (tracked & ((other["score"] - other["score_default"]).abs() > TRACKED_SHARE_CHANGE))
    out = other[moved].rename(columns={"score_default": "default_score", "rank_default": "default_rank"})
    return out[["folder", "choice", "metric", "method", "default_score", "score", "default_rank", "rank"]].reset_index(
        drop=True)
