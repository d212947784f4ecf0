import numpy as np
import pytest

import sim_envs.folders.formats
import slamcommon.formats.association as association
from eval.metrics.association import (
    AssociationError,
    AssociationRule,
    associate,
    associated_pair,
    matching_greedy,
    matching_nearest,
)
from eval.metrics.trajectory import PoseTrajectory
from slamcommon.formats.association import associate_greedy, greedy_candidates, greedy_in_order, locally_first


def traj(stamps):
    stamps = np.asarray(stamps, dtype=float)
    T = np.tile(np.eye(4), (stamps.size, 1, 1))
    T[:, 0, 3] = stamps  # x = time, to see which pose was taken
    return PoseTrajectory(stamps, T)


def test_tum_rule_is_one_to_one_and_nearest_is_not():
    gt = traj([0.0, 0.01, 0.02, 1.0])
    est = traj([0.012, 1.004])
    tum = associate(gt, est, "tum", max_difference=0.02)
    assert tum.gt_indices.tolist() == [1, 3] and tum.est_indices.tolist() == [0, 1]
    # evo: each stamp of the shorter trajectory (est) takes its nearest stamp of the longer one
    near = associate(gt, est, "nearest", max_difference=0.02)
    assert near.gt_indices.tolist() == [1, 3] and near.est_indices.tolist() == [0, 1]
    est2 = traj([0.0085, 0.011, 5.0])
    gt2 = traj([0.0, 0.01, 1.0, 2.0])
    assert associate(gt2, est2, "nearest").gt_indices.tolist() == [1, 1]  # gt pose used twice
    tum2 = associate(gt2, est2, "tum")  # one to one: 0.0085 falls back to the next free stamp within 0.02
    assert tum2.gt_indices.tolist() == [0, 1] and tum2.est_indices.tolist() == [0, 1]
    assert tum.describe() == {"rule": "tum", "max_difference": 0.02, "offset": 0.0, "pairs": 2}


def test_offset_is_added_to_the_estimate():
    gt = traj([10.0, 11.0, 12.0])
    est = traj([0.001, 1.0, 2.0])
    a = associate(gt, est, "tum", offset=10.0)
    assert len(a) == 3 and a.offset == 10.0
    assert len(associate(gt, est, "nearest", offset=10.0)) == 3
    with pytest.raises(AssociationError, match="found 0 matching timestamps"):
        associate(gt, est, "tum")


def test_nearest_ties_take_the_lower_index_and_respect_max_difference():
    short, long = matching_nearest(np.array([0.5, 3.0]), np.array([0.0, 1.0, 2.0]), 0.5)
    assert short.tolist() == [0] and long.tolist() == [0]


def test_index_rule_and_errors():
    gt, est = traj([0.0, 1.0, 2.0]), traj([0.0, 1.0, 2.5])
    a = associate(gt, est, AssociationRule.INDEX)
    assert a.gt_indices.tolist() == [0, 1]
    with pytest.raises(AssociationError, match="valid rules: tum, nearest, index"):
        associate(gt, est, "closest")
    with pytest.raises(AssociationError, match="has 3 poses and the estimate 2"):
        associate(gt, traj([0.0, 1.0]), "index")
    with pytest.raises(AssociationError, match="positive"):
        associate(gt, est, "tum", max_difference=-1)
    g, e = associated_pair(gt, est, a)
    assert len(g) == len(e) == 2


def test_reference_pair_counts_on_real_files(tum_dir):
    gt = PoseTrajectory.from_tum_file(tum_dir / "fr2_desk_groundtruth.txt", duplicate_timestamps="last")
    est = PoseTrajectory.from_tum_file(tum_dir / "fr2_desk_ORB.txt")
    assert len(associate(gt, est, "tum")) == 2223
    assert len(associate(gt, est, "nearest")) == 2225  # evo's rule reuses ground-truth poses


def brute_force_tum(first, second, max_difference, offset=0.0):
    """The TUM tools' associate.py, literally: every pair within max_difference, sorted by (difference, a, b), taken
    greedily one to one; returned sorted by the first stamp's index."""
    candidates = sorted(
        (abs(a - (b + offset)), a, b, i, j)
        for i, a in enumerate(first)
        for j, b in enumerate(second)
        if abs(a - (b + offset)) < max_difference
    )
    used_i, used_j, pairs = set(), set(), []
    for _, _, _, i, j in candidates:
        if i not in used_i and j not in used_j:
            used_i.add(i)
            used_j.add(j)
            pairs.append((i, j))
    pairs.sort()
    return [i for i, _ in pairs], [j for _, j in pairs]


def random_stamps(rng, n, rate, jitter):
    t = np.cumsum(rng.uniform(1.0 / rate - jitter, 1.0 / rate + jitter, n))
    return np.round(t, int(rng.integers(2, 5)))  # rounded: equal differences (ties) happen


@pytest.mark.parametrize("seed", range(40))
def test_greedy_matching_gives_the_brute_force_pairs(seed):
    rng = np.random.default_rng(seed)
    first = np.unique(random_stamps(rng, int(rng.integers(1, 80)), 30.0, 0.02))
    second = np.unique(random_stamps(rng, int(rng.integers(1, 80)), float(rng.choice([10.0, 30.0, 100.0])), 0.005))
    max_difference = float(rng.choice([0.005, 0.01, 0.02, 0.05, 0.2]))
    offset = float(rng.choice([0.0, 0.01, -0.013]))
    gi, ei = matching_greedy(first, second, max_difference, offset)
    assert (gi.tolist(), ei.tolist()) == brute_force_tum(first.tolist(), second.tolist(), max_difference, offset)
    ri, rj = greedy_in_order(first, second, *greedy_candidates(first, second, max_difference, offset))  # one pass
    order = np.argsort(ri, kind="stable")
    assert np.array_equal(gi, ri[order]) and np.array_equal(ei, rj[order]) and gi.dtype == ei.dtype == np.int64


def test_the_judge_and_the_world_share_one_association():
    """eval.metrics.association and sim_envs.folders.formats use slamcommon's; the world raises its own error type."""
    assert matching_greedy is associate_greedy
    assert sim_envs.folders.formats.associate_greedy.__wrapped__ is associate_greedy
    with pytest.raises(sim_envs.folders.formats.FormatError, match="max_difference"):
        sim_envs.folders.formats.associate_greedy(np.zeros(2), np.zeros(2), 0.0)


def test_greedy_matching_on_a_chain_of_equal_differences_finishes_in_order(monkeypatch):
    """b = a + 0.5: every stamp has two candidates exactly 0.5 away and only the chain's start is first for both of
    its stamps, so a round takes one pair and the rest are taken one by one in the TUM order."""
    calls = []
    in_order = association.greedy_in_order
    monkeypatch.setattr(association, "greedy_in_order", lambda *a: calls.append(len(a[2])) or in_order(*a))
    first = np.arange(60.0)
    second = first + 0.5
    gi, ei = matching_greedy(first, second, 0.6)
    assert calls == [117]  # of 119 candidates: (0, 0) taken in the first round, (1, 0) dropped with it
    assert (gi.tolist(), ei.tolist()) == brute_force_tum(first.tolist(), second.tolist(), 0.6)
    assert gi.tolist() == ei.tolist() == list(range(60))  # ties go to the smaller stamps: (0.5, a, b) order
    assert matching_greedy(first, np.zeros(0), 0.6)[0].size == 0  # no candidates


def test_candidates_and_locally_first():
    i, j, d = greedy_candidates(np.array([0.0, 1.0, 2.0]), np.array([0.125, 0.9375, 1.25, 1.875]), 0.3)
    assert i.tolist() == [0, 1, 1, 2] and j.tolist() == [0, 1, 2, 3] and d.tolist() == [0.125, 0.0625, 0.25, 0.125]
    assert locally_first(i, j, d, 3, 4).tolist() == [True, True, False, True]
    # equal differences: the smaller stamp of the other list comes first, on either side
    i, j, d = greedy_candidates(np.array([1.0]), np.array([0.75, 1.25]), 0.3)
    assert locally_first(i, j, d, 1, 2).tolist() == [True, False]
    i, j, d = greedy_candidates(np.array([0.75, 1.25]), np.array([1.0]), 0.3)
    assert locally_first(i, j, d, 2, 1).tolist() == [True, False]
