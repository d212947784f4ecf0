"""The TUM RGB-D tools' timestamp association (``associate.py``): greedy one-to-one matching of two timestamp lists,
used by the world to pair a folder's RGB images, depth images and poses and by the judge to pair an estimate with
its ground truth (``eval.metrics.association`` adds its other rules)."""

from __future__ import annotations

import numpy as np

from slamcommon.errors import FormatError


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


def associate_greedy(
    stamps_first: np.ndarray, stamps_second: np.ndarray, max_difference: float = 0.02, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The TUM tools' association (``associate.py``): greedy one-to-one matching of two sorted timestamp lists.

    Their rule: the candidates of :func:`greedy_candidates` (``|a - (b + offset)| < max_difference``, seconds),
    sorted by ``(difference, first[i], second[j])``, taken in that order while neither stamp is used yet. Here: the
    same pairs as that sequential pass (:func:`greedy_in_order`), found in vectorised rounds. The order is a strict
    total order, so a candidate that comes first among all candidates of both its stamps (:func:`locally_first`) is
    taken by the sequential pass, and dropping the candidates that share a stamp with it leaves the pass over the
    rest unchanged. Each round takes every such candidate at once; when a round takes less than a tenth of what is
    left (a chain of near-equal differences, where every round takes few), the rest are sorted and taken one by one.
    Returns index arrays (M,) int64 into ``stamps_first`` and ``stamps_second``, sorted by the first. Both lists must
    be sorted increasing. :class:`FormatError` when ``max_difference`` is not a positive number.
    """
    if not (max_difference > 0 and np.isfinite(max_difference)):
        raise FormatError(f"max_difference must be a positive number of seconds, got {max_difference!r}")
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
            seq_i, seq_j = greedy_in_order(a, b, i, j, diff)
            taken_i.append(seq_i)
            taken_j.append(seq_j)
            break
    first_arr, second_arr = np.concatenate(taken_i), np.concatenate(taken_j)
    sort = np.argsort(first_arr, kind="stable")
    return first_arr[sort], second_arr[sort]


def greedy_in_order(
    a: np.ndarray, b: np.ndarray, i: np.ndarray, j: np.ndarray, diff: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The TUM tools' sequential pass over candidates (i, j) of stamps ``a``, ``b`` with differences ``diff``: sorted
    by ``(diff, a[i], b[j])``, each taken while neither stamp is used. Returns the taken (i, j), int64, in
    that order."""
    order = np.lexsort((b[j], a[i], diff))
    used_a, used_b = [False] * a.size, [False] * b.size
    first, second = [], []
    for ii, jj in zip(i[order].tolist(), j[order].tolist(), strict=True):
        if not used_a[ii] and not used_b[jj]:
            used_a[ii] = used_b[jj] = True
            first.append(ii)
            second.append(jj)
    return np.asarray(first, dtype=np.int64), np.asarray(second, dtype=np.int64)
