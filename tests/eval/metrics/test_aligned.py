"""The aligned trajectory files, the relative error at several distances and the ATE, tested against evo itself:
evo reads each aligned file, its APE on it (no alignment) is ours, its RPE over the same path distances is ours."""

import numpy as np
import pytest

from eval.metrics.aligned import ALIGNED_FILES, aligned_alignments, aligned_files, aligned_tum_text
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import RELATIVE_TOLERANCE, error_statistics, evaluate_trajectory
from sim_envs.folders.formats import write_tum_trajectory


@pytest.fixture(scope="module")
def fr1_xyz_scored(tum_dir):
    """RGBD-SLAM's estimate of TUM fr1/xyz scored with SE(3) alignment (TUM association, 0.02 s)."""
    gt = PoseTrajectory.from_tum_file(tum_dir / "freiburg1_xyz-groundtruth.txt")
    est = PoseTrajectory.from_tum_file(tum_dir / "freiburg1_xyz-rgbdslam.txt")
    return evaluate_trajectory(gt, est, alignment="se3")


def test_a_monocular_run_keeps_sim3_too():
    assert aligned_alignments("mono") == ("se3", "sim3") and aligned_alignments(None) == ("se3", "sim3")
    assert aligned_alignments("rgbd") == ("se3",)


def test_the_files_hold_the_aligned_estimate(fr1_xyz_scored, tmp_path):
    m = fr1_xyz_scored
    files = aligned_files(m, ("se3", "sim3"), "RGBD-SLAM on fr1/xyz")
    assert set(files) == {ALIGNED_FILES["se3"], ALIGNED_FILES["sim3"]}
    assert files[ALIGNED_FILES["se3"]].startswith("# RGBD-SLAM on fr1/xyz\n# aligned onto the ground truth: SE(3)")
    for alignment, name in ALIGNED_FILES.items():
        (tmp_path / name).write_text(files[name])
        back = PoseTrajectory.from_tum_file(tmp_path / name)
        assert np.array_equal(back.timestamps, m.est.timestamps)  # the estimate's own times
        np.testing.assert_allclose(back.positions, m.aligned(alignment).positions, atol=1e-9)
    # the run's own alignment is the SE(3) one: the same poses as est_aligned
    np.testing.assert_allclose(m.aligned("se3").T_world_cam, m.est_aligned.T_world_cam)
    assert "scale" in aligned_tum_text(m, "sim3").splitlines()[0]


def test_evo_reads_each_file_and_scores_it_as_we_do(fr1_xyz_scored, tmp_path, evo):
    m = fr1_xyz_scored
    gt = tmp_path / "groundtruth.tum"  # the associated ground truth at the estimate's times: evo pairs the same poses
    write_tum_trajectory(gt, m.est.timestamps, m.gt.T_world_cam)
    raw = tmp_path / "estimate.tum"
    write_tum_trajectory(raw, m.est.timestamps, m.est.T_world_cam)
    for name, text in aligned_files(m, ("se3", "sim3")).items():
        (tmp_path / name).write_text(text)
        assert "786 poses" in evo("evo_traj", "tum", str(tmp_path / name))["stdout"]  # evo reads every pose
    se3 = evo("evo_ape", "tum", str(gt), str(tmp_path / ALIGNED_FILES["se3"]))  # already aligned: no -a
    sim3 = evo("evo_ape", "tum", str(gt), str(tmp_path / ALIGNED_FILES["sim3"]))
    assert se3["stats"]["rmse"] == pytest.approx(m.ate_se3_rmse, abs=1e-8)
    assert sim3["stats"]["rmse"] == pytest.approx(m.ate_sim3_rmse, abs=1e-8)
    assert evo("evo_ape", "tum", str(gt), str(raw), "-as")["stats"]["rmse"] == pytest.approx(m.ate_sim3_rmse,
                                                                                             abs=1e-8)


def test_evo_rpe_over_the_same_path_distances_is_ours(fr1_xyz_scored, tmp_path, evo):
    """rpg's relative error at 10-50 % of the path = evo_rpe --delta D --delta_unit m --all_pairs
    --pairs_from_reference --delta_tol 0.2 on the aligned estimate."""
    m = fr1_xyz_scored
    gt, aligned = tmp_path / "groundtruth.tum", tmp_path / "aligned.tum"
    write_tum_trajectory(gt, m.est.timestamps, m.gt.T_world_cam)  # at the estimate's times, as above
    aligned.write_text(aligned_tum_text(m, "se3"))
    # ours from the files as written (9 decimals), so that both pick their pairs on the same numbers
    back = evaluate_trajectory(PoseTrajectory.from_tum_file(gt), PoseTrajectory.from_tum_file(aligned),
                               alignment="none", association="index")  # fmt: skip
    assert [r.share for r in back.relative] == [10, 20, 30, 40, 50]
    for rel in back.relative[::2]:
        assert rel.translation.size > 100  # fr1/xyz: a 7 m path
        common = ["tum", str(gt), str(aligned), "--delta", repr(rel.distance_m), "--delta_unit", "m", "--all_pairs",
                  "--pairs_from_reference", "--delta_tol", str(RELATIVE_TOLERANCE)]
        trans = evo("evo_rpe", *common)["stats"]
        rot = evo("evo_rpe", *common, "--pose_relation", "angle_deg")["stats"]
        assert trans["rmse"] == pytest.approx(error_statistics(rel.translation).rmse, rel=1e-9)
        assert rot["rmse"] == pytest.approx(error_statistics(rel.rotation_deg).rmse, rel=1e-7, abs=1e-9)
        assert back.flat_metrics()[f"rpe_trans_rmse_p{rel.share}"] == pytest.approx(trans["rmse"], rel=1e-9)
