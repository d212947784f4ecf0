"""Timestamp association of an estimated trajectory with ground truth.

Three rules, and every :class:`Association` says which one it used and with which max difference and offset:

- ``"tum"`` (the default): the TUM RGB-D tools' ``associate.py``: every pair with
  ``|t_gt - (t_est + offset)| < max_difference`` is a candidate, candidates are sorted by difference and taken
  greedily, one to one (:func:`matching_greedy`: the pairs of :func:`sim_envs.formats.associate_greedy`, vectorised);
- ``"nearest"``: evo's ``sync.associate_trajectories``: each stamp of the SHORTER trajectory takes the nearest stamp
  of the longer one when ``|difference| <= max_difference`` (first on ties); a stamp of the longer one may be used
  twice;
- ``"index"``: pose i with pose i (the two trajectories come from the same run, as the driver's do); the max
  difference is still checked.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from eval.errors import EvalError
from eval.metrics.trajectory import PoseTrajectory

DEFAULT_MAX_DIFFERENCE: float = 0.02  # seconds, the TUM tools' default (evo's is 0.01)


class AssociationError(EvalError):
    """No (or not enough) timestamps match, or an unknown rule."""


class AssociationRule(StrEnum):
    """How estimated poses are matched to ground-truth poses (see the module docstring)."""

    TUM = "tum"
    NEAREST = "nearest"
    INDEX = "index"


def parse_rule(rule: str | AssociationRule) -> AssociationRule:
    """Validate an association rule name once."""
    try:
        return AssociationRule(rule)
    except ValueError:
        valid = ", ".join(r.value for r in AssociationRule)
        raise AssociationError(f"unknown association rule {rule!r}; valid rules: {valid}") from None


@dataclass(frozen=True, eq=False)
class Association:
    """Matched index pairs. ``gt_indices``, ``est_indices``: (M,) int64 into the ground truth and the estimate."""

    rule: AssociationRule
    max_difference: float  # seconds
    offset: float  # seconds added to the estimate's timestamps
    gt_indices: np.ndarray
    est_indices: np.ndarray

    def __len__(self) -> int:
        return int(self.gt_indices.shape[0])

    def describe(self) -> dict:
        """JSON-ready summary: rule, max_difference, offset, pairs."""
        return {
            "rule": self.rule.value,
            "max_difference": self.max_difference,
            "offset": self.offset,
            "pairs": len(self),
        }


def matching_nearest(
    stamps_short: np.ndarray, stamps_long: np.ndarray, max_difference: float
) -> tuple[np.ndarray, np.ndarray]:
    """For each short stamp, the index of the nearest long stamp (lower index on ties) if within max_difference.

    Both arrays sorted increasing. Returns (indices into short, indices into long).
    """
    short = np.asarray(stamps_short, dtype=np.float64)
    long = np.asarray(stamps_long, dtype=np.float64)
    if short.size == 0 or long.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    right = np.clip(np.searchsorted(long, short, side="left"), 0, long.size - 1)
    left = np.clip(right - 1, 0, long.size - 1)
    d_left, d_right = np.abs(long[left] - short), np.abs(long[right] - short)
    nearest = np.where(d_left <= d_right, left, right)
    diff = np.minimum(d_left, d_right)
    keep = np.flatnonzero(diff <= max_difference)
    return keep, nearest[keep]


def greedy_candidates(
    stamps_first: np.ndarray, stamps_second: np.ndarray, max_difference: float, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair (i, j) with ``|first[i] - (second[j] + offset)| < max_difference`` (the TUM tools' candidates),
    ordered by i, then j. Both arrays sorted increasing. Returns (i, j, difference): int64, int64 and float64 arrays
    (K,). Work: O((N1 + N2) log N) plus the candidates."""
    a = np.asarray(stamps_first, dtype=np.float64).reshape(-1)
    b = np.asarray(stamps_second, dtype=np.float64).reshape(-1)
    shifted = b + offset
    lo = np.searchsorted(shifted, a - max_difference, side="left")
    hi = np.searchsorted(shifted, a + max_difference, side="right")
    counts = hi - lo
    i = np.repeat(np.arange(a.size, dtype=np.int64), counts)
    j = np.arange(counts.sum(), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(lo, counts)
    diff = np.abs(a[i] - (b[j] + offset))
    keep = diff < max_difference
    return i[keep], j[keep], diff[keep]


def locally_first(i: np.ndarray, j: np.ndarray, difference: np.ndarray, n_first: int, n_second: int) -> np.ndarray:
    """(K,) bool: the candidates (ordered by i, then j, as :func:`greedy_candidates` gives them) that come first in
    the TUM tools' order, ``(difference, first[i], second[j])``, among all candidates of their i and of their j.

    Among candidates of one i that order is by difference, then j; among those of one j, by difference, then i
    (both stamp lists increase), so no sort is needed: per-stamp minima of the difference, then the lowest index.
    """
    k = i.size
    if k == 0:
        return np.zeros(0, dtype=bool)
    new_i = np.empty(k, dtype=bool)
    new_i[0] = True
    np.not_equal(i[1:], i[:-1], out=new_i[1:])
    starts = np.flatnonzero(new_i)
    least_i = np.repeat(np.minimum.reduceat(difference, starts), np.diff(np.append(starts, k)))
    at_least_i = np.flatnonzero(difference == least_i)  # candidates of least difference for their i, by i then j
    first_i = np.zeros(k, dtype=bool)
    first_i[at_least_i[np.append(True, i[at_least_i[1:]] != i[at_least_i[:-1]])]] = True
    least_j = np.full(n_second, np.inf)
    np.minimum.at(least_j, j, difference)
    at_least_j = difference == least_j[j]
    lowest_i = np.full(n_second, n_first, dtype=np.int64)
    np.minimum.at(lowest_i, j[at_least_j], i[at_least_j])
    return first_i & at_least_j & (i == lowest_i[j])


def matching_greedy(
    stamps_first: np.ndarray, stamps_second: np.ndarray, max_difference: float, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The TUM tools' association (``associate.py``): greedy one-to-one matching of two sorted timestamp lists.

    Their rule: the candidates of :func:`greedy_candidates`, sorted by ``(difference, first[i], second[j])``, taken
    in that order while neither stamp is used yet. Here: the same pairs as that sequential pass (and as
    :func:`sim_envs.formats.associate_greedy`), found in vectorised rounds. The order is a strict total order, so a
    candidate that comes first among all candidates of both its stamps (:func:`locally_first`) is taken by the
    sequential pass, and dropping the candidates that share a stamp with it leaves the pass over the rest unchanged.
    Each round takes every such candidate at once; when a round takes less than a tenth of what is left (a chain of
    near-equal differences, where every round takes few), the rest are sorted and taken one by one. Returns index
    arrays (M,) into ``stamps_first`` and ``stamps_second``, sorted by the first.
    """
    a = np.asarray(stamps_first, dtype=np.float64).reshape(-1)
    b = np.asarray(stamps_second, dtype=np.float64).reshape(-1)
    i, j, diff = greedy_candidates(a, b, max_difference, offset)
    taken_i: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    taken_j: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    while i.size:
        first = locally_first(i, j, diff, a.size, b.size)
        taken_i.append(i[first])
        taken_j.append(j[first])
        used_i = np.zeros(a.size, dtype=bool)
        used_j = np.zeros(b.size, dtype=bool)
        used_i[i[first]] = True
        used_j[j[first]] = True
        free = ~(used_i[i] | used_j[j])
        i, j, diff = i[free], j[free], diff[free]
        if i.size and np.count_nonzero(first) * 10 < i.size:
            seq_i, seq_j = _greedy_in_order(a, b, i, j, diff)
            taken_i.append(seq_i)
            taken_j.append(seq_j)
            break
    first_arr, second_arr = np.concatenate(taken_i), np.concatenate(taken_j)
    sort = np.argsort(first_arr, kind="stable")
    return first_arr[sort], second_arr[sort]


def _greedy_in_order(
    a: np.ndarray, b: np.ndarray, i: np.ndarray, j: np.ndarray, diff: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The TUM tools' sequential pass over candidates (i, j) with differences ``diff``."""
    order = np.lexsort((b[j], a[i], diff))
    used_a, used_b = [False] * a.size, [False] * b.size
    first, second = [], []
    for ii, jj in zip(i[order].tolist(), j[order].tolist(), strict=True):
        if not used_a[ii] and not used_b[jj]:
            used_a[ii] = used_b[jj] = True
            first.append(ii)
            second.append(jj)
    return np.asarray(first, dtype=np.int64), np.asarray(second, dtype=np.int64)


def associate(
    gt: PoseTrajectory,
    est: PoseTrajectory,
    rule: str | AssociationRule = AssociationRule.TUM,
    max_difference: float = DEFAULT_MAX_DIFFERENCE,
    offset: float = 0.0,
    min_pairs: int = 1,
) -> Association:
    """Match the estimate's timestamps (shifted by ``offset``) to the ground truth's with ``rule``.

    Raises :class:`AssociationError` when fewer than ``min_pairs`` pairs are found, naming the time ranges.
    """
    rule = parse_rule(rule)
    if not (max_difference > 0 and np.isfinite(max_difference)):
        raise AssociationError(f"max_difference must be a positive number of seconds, got {max_difference!r}")
    if not np.isfinite(offset):
        raise AssociationError(f"offset must be a finite number of seconds, got {offset!r}")
    t_gt, t_est = gt.timestamps, est.timestamps
    for name, t in (("ground truth", t_gt), ("estimate", t_est)):
        if t.size > 1 and rule != AssociationRule.INDEX and np.any(np.diff(t) <= 0):
            raise AssociationError(f"the {name}'s timestamps must strictly increase to associate by time")
    if rule == AssociationRule.TUM:
        gi, ei = matching_greedy(t_gt, t_est, max_difference, offset)
    elif rule == AssociationRule.NEAREST:
        if t_est.size > t_gt.size:  # evo: each stamp of the shorter trajectory takes its nearest in the longer
            gi, ei = matching_nearest(t_gt, t_est + offset, max_difference)
        else:
            ei, gi = matching_nearest(t_est + offset, t_gt, max_difference)
    else:
        if t_gt.size != t_est.size:
            raise AssociationError(
                f"rule 'index' pairs pose i with pose i, but the ground truth has {t_gt.size} poses and the "
                f"estimate {t_est.size}; use rule 'tum' or 'nearest'"
            )
        idx = np.arange(t_gt.size)
        ok = np.abs(t_gt - (t_est + offset)) <= max_difference
        gi, ei = idx[ok], idx[ok]
    result = Association(rule, float(max_difference), float(offset), gi.astype(np.int64), ei.astype(np.int64))
    if len(result) < min_pairs:
        raise AssociationError(
            f"found {len(result)} matching timestamps (need {min_pairs}) between the ground truth "
            f"[{_span(t_gt)}] and the estimate [{_span(t_est)}] with rule {rule.value!r}, max. difference "
            f"{max_difference} s and offset {offset} s; check the files, or raise --max-diff / set --offset"
        )
    return result


def associated_pair(gt: PoseTrajectory, est: PoseTrajectory, association: Association):
    """The matched poses: (ground truth subset, estimate subset), both of length M, pair k = k."""
    return gt.subset(association.gt_indices), est.subset(association.est_indices)


def _span(t: np.ndarray) -> str:
    return f"{t[0]:.6f} .. {t[-1]:.6f} s, {t.size} poses" if t.size else "no poses"
