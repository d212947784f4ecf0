"""How long must a benchmark run be for its verdict to be the whole sequences' verdict? (``cnnslam bench lengths``)

A monocular method's scale drift grows with the path it has travelled: over the first 200 frames it hardly shows,
over a whole sequence (the paper's protocol) it decides the ranking. The length sweep runs the Table-1 suite on the
first N frames of every sequence for several N and whole sequences, and per length and metric:

- **scores and ranks** (:func:`length_ranks`): as :mod:`eval.reports.transfer` makes them, one "domain" per length (the
  median over each cell's runs, the mean over the sequences; rank 1 best in the metric's direction, ties sharing
  their mean rank), over the methods scored at every length;
- **agreement with the whole sequences** (:func:`length_agreement`): Kendall's tau-b and Spearman's rho between a
  length's ranking and the whole-sequence one, with n (methods), and whether the two rankings are the same;
- **where each method's rank settles** (:func:`settling_lengths`): the shortest length from which the method's rank
  equals its whole-sequence rank at every longer length;
- **the bench length** (:func:`shortest_agreeing_length`): the shortest length from which every ranking equals the
  whole sequences' on the decisive metrics (Table 1's: SE(3) ATE and correct depth).

Methods fed ground truth (the oracle) are left out by the suite's default methods: they win by construction. The
numeric core does no I/O; :mod:`eval.reports.lengths_report` writes ``lengths.{md,csv,png}``.
"""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.reports.transfer import TRANSFER_METRICS, TransferMetric, domain_scores, rank_methods, ranking_agreement

WHOLE = "whole"
# the metrics the bench length must rank as whole sequences do: the paper's Table 1 (trajectory and depth)
DECISIVE_METRICS: tuple[str, ...] = tuple(s.key for s in catalogue.shown_at(catalogue.DECISIVE))


def length_label(frames: int | None) -> str:
    """A length as the report names it: the number of frames, or ``whole``."""
    return WHOLE if frames is None else str(int(frames))


def length_order(labels: Sequence[str]) -> list[str]:
    """Length labels from shortest to longest (``whole`` last)."""
    return sorted(set(labels), key=lambda x: (x == WHOLE, int(x) if x != WHOLE else 0))


def length_ranks(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS) -> pd.DataFrame:
    """Score and rank per (length, metric, method) from a long frame of runs with a ``length`` column (labels of
    :func:`length_label`) besides :func:`eval.reports.transfer.domain_scores`' columns. Returns columns length, metric,
    method, score, sequences, runs, rank; ranked over the methods scored at every length (per metric)."""
    if "length" not in frame.columns:
        raise EvalError("a length frame needs a 'length' column")
    scores = domain_scores(frame.assign(domain=frame["length"].astype(str)), metrics)
    ranks = rank_methods(scores, metrics, domains=length_order(scores["domain"].unique()))
    return ranks.rename(columns={"domain": "length"})


def length_agreement(ranks: pd.DataFrame, reference: str = WHOLE) -> pd.DataFrame:
    """Per (metric, length): n (methods ranked), Kendall's tau-b and Spearman's rho of the length's ranking against
    the ``reference`` length's (NaN where undefined: fewer than 3 methods, or all tied), and ``same``: the two
    rankings are identical. Columns: metric, length, n, kendall, spearman, same."""
    return ranking_agreement(ranks, "length", reference, length_order)


def settling_lengths(ranks: pd.DataFrame, reference: str = WHOLE) -> pd.DataFrame:
    """Per (metric, method): its rank at each length (columns named by length, shortest first), its rank at the
    ``reference`` length, and ``settles_at``: the shortest length from which its rank equals the reference rank at
    every longer length (the reference itself when it differs at the length just before)."""
    rows = []
    for metric, group in ranks.groupby("metric", sort=False):
        wide = group.pivot_table(index="method", columns="length", values="rank")
        if reference not in wide:
            continue
        order = length_order(wide.columns)
        for method, row in wide[order].iterrows():
            settles = reference
            for length in reversed(order):
                if row[length] != row[reference]:
                    break
                settles = length
            rows.append({"metric": metric, "method": method, **{f"rank_{k}": row[k] for k in order},
                         "settles_at": settles})  # fmt: skip
    return pd.DataFrame(rows)


def shortest_agreeing_length(agreement: pd.DataFrame, metrics: Sequence[str] = DECISIVE_METRICS) -> str | None:
    """The shortest length from which the ranking is the same as the reference's on every one of ``metrics`` at
    that length and every longer one (a length that agrees while a longer one does not is a coincidence, not a
    settled verdict); None when not even the longest does (a metric missing from ``agreement`` disagrees)."""
    found = None
    for length in reversed(length_order(agreement["length"].unique())):
        rows = agreement[agreement["length"] == length].set_index("metric")
        if not all(m in rows.index and bool(rows.loc[m, "same"]) for m in metrics):
            break
        found = length
    return found
