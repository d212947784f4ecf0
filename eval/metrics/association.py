"""Timestamp association of an estimated trajectory with ground truth.

Three rules, and every :class:`Association` says which one it used and with which max difference and offset:

- ``"tum"`` (the default): the TUM RGB-D tools' ``associate.py``: every pair with
  ``|t_gt - (t_est + offset)| < max_difference`` is a candidate, candidates are sorted by difference and taken
  greedily, one to one (:func:`slamcommon.formats.associate_greedy`, which the world uses too);
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
from slamcommon.formats.association import (  # noqa: F401 (re-exports)
    associate_greedy,
    greedy_candidates,
    greedy_in_order,
    locally_first,
)

# The TUM tools' association lives in slamcommon.formats.association (shared with the world); these names are kept
# for users who import them from here.
matching_greedy = associate_greedy
_greedy_in_order = greedy_in_order

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
        gi, ei = associate_greedy(t_gt, t_est, max_difference, offset)
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
