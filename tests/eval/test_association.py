from pathlib import Path

import numpy as np
import pytest

from eval.association import AssociationError, AssociationRule, associate, associated_pair, matching_nearest
from eval.trajectory import PoseTrajectory

TUM = Path("/work/shared/data/tum")


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


def test_reference_pair_counts_on_real_files():
    gt = PoseTrajectory.from_tum_file(TUM / "fr2_desk_groundtruth.txt", duplicate_timestamps="last")
    est = PoseTrajectory.from_tum_file(TUM / "fr2_desk_ORB.txt")
    assert len(associate(gt, est, "tum")) == 2223
    assert len(associate(gt, est, "nearest")) == 2225  # evo's rule reuses ground-truth poses
