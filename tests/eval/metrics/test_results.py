import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.metrics.results import evaluate_episode, json_ready, load_run, load_runs, runs_frame, save_run
from sim_envs.agent import KeyframeDepth
from sim_envs.camera import preset
from sim_envs.frames import Frame


def gt_frame(t, depth, labels=None):
    h, w = depth.shape
    return Frame(0, t, np.zeros((h, w, 3), np.uint8), depth, np.eye(4), labels)


def episode(n=40, seed=0):
    """A stand-in for the driver's EpisodeResult: perfect poses shifted by 5 cm in x, 3 of 4 frames tracked."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 30.0
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(np.outer(np.linspace(0, 0.5, n), [0, 1, 0])).as_matrix()
    T[:, :3, 3] = np.stack([np.sin(t), np.cos(t), 0.2 * t], axis=1)
    T_est = T.copy()
    T_est[:, 0, 3] += np.where(np.arange(n) % 2, 0.05, -0.05)  # +-5 cm: ATE = 5 cm whatever the alignment
    gt_depth = np.full((6, 8), 2.0, dtype=np.float32)
    gt_depth[0, 0] = 0.0  # one pixel without ground truth
    est_a = gt_depth * 1.05  # all correct
    est_b = gt_depth.copy()
    est_b[:3] = 0.0  # half missing
    labels = np.zeros((6, 8), np.uint8)
    labels[3:] = 1
    return SimpleNamespace(
        sequence="office0",
        agent="my_pkg.agent:Slam",
        intrinsics=preset("icl", 8, 6),
        timestamps=t,
        T_world_cam_est=T_est,
        tracked=np.arange(n) % 4 != 0,
        T_world_cam_gt=T,
        keyframes=[
            KeyframeDepth(t[0], est_a, T_est[0], labels=labels),
            KeyframeDepth(t[20], est_b, T_est[20]),
            KeyframeDepth(t[30], est_a[::2, ::2], T_est[30]),  # half resolution: resized, with a warning
            KeyframeDepth(99.0, est_a, T_est[0]),  # no ground truth frame: skipped, with a warning
        ],
        keyframe_gt=[gt_frame(t[0], gt_depth, labels), gt_frame(t[20], gt_depth), gt_frame(t[30], gt_depth)],
        step_seconds=np.full(n, 0.02) + rng.uniform(0, 1e-3, n),
        uses_ground_truth=False,
        extras={},
    )


def test_evaluate_episode_known_answers():
    rec = evaluate_episode(episode(), method="CNN-SLAM", metadata={"seed": 3})
    m = rec.metrics
    assert rec.sequence == "office0" and rec.method == "CNN-SLAM" and rec.agent == "my_pkg.agent:Slam"
    assert rec.association["rule"] == "index" and rec.alignment["used"] == "se3"
    assert m["ate_rmse"] == pytest.approx(0.05, abs=1e-3) and m["ate_pairs"] == 40 and m["frames"] == 40
    assert m["tracked_share"] == pytest.approx(0.75)
    assert m["depth_keyframes"] == 3
    # 47 valid ground-truth pixels per key-frame; estimated (all correct): 47; 24 (rows 3-5); 44 (the half-size
    # map, upsampled by nearest neighbour, spreads its hole at (0, 0) over a 2x2 block: 3 more pixels missing)
    assert m["depth_percent_correct"] == pytest.approx(100 * (47 + 24 + 44) / (3 * 47))
    assert m["depth_percent_correct_mean"] == pytest.approx(100 * (47 / 47 + 24 / 47 + 44 / 47) / 3)
    assert m["depth_density"] == pytest.approx(m["depth_percent_correct"])
    assert m["depth_abs_rel"] == pytest.approx((47 * 0.05 + 24 * 0.0 + 44 * 0.05) / (47 + 24 + 44), rel=1e-5)
    assert m["semantic_pixel_accuracy"] == 1.0 and m["semantic_mean_iou"] == 1.0
    assert m["step_ms_mean"] == pytest.approx(20.5, abs=0.5) and m["fps"] == pytest.approx(1000 / m["step_ms_mean"])
    assert any("resized" in w for w in rec.warnings) and any("no ground-truth frame" in w for w in rec.warnings)
    assert len(rec.keyframes) == 3 and rec.metadata == {"seed": 3}
    json.dumps(json_ready(rec.to_json()), allow_nan=False)  # strict JSON


def test_the_record_says_which_alignment_was_used_and_reports_both_ates():
    rec = evaluate_episode(episode())
    m, a = rec.metrics, rec.alignment
    assert a["used"] == "se3" and a["title"].startswith("SE(3) Umeyama") and a["degenerate"] is False
    assert a["sim3"]["used"] == "sim3" and rec.rpe == {"delta": 1.0, "unit": "s"}
    assert m["ate_se3_rmse"] == m["ate_rmse"] and m["ate_sim3_rmse"] <= m["ate_rmse"]
    assert m["ate_alignment_degenerate"] == 0.0 and m["ate_alignment_fallback"] == 0.0
    assert m["rot_deg_orient_rmse"] == pytest.approx(0.0, abs=1e-9)  # only positions are off
    assert all(isinstance(v, float) for v in m.values())  # the flat metrics stay numbers only
    # a pure rotation on the spot: the fallback (evo refuses), flagged in the record and the flat metrics
    still = episode()
    still.T_world_cam_gt = still.T_world_cam_gt.copy()
    still.T_world_cam_gt[:, :3, 3] = [1.0, 2.0, 1.5]
    still.T_world_cam_est = still.T_world_cam_gt.copy()
    rec = evaluate_episode(still)
    assert rec.alignment["used"] == "rotation_only" and rec.alignment["fallback"] is True
    assert rec.metrics["ate_alignment_fallback"] == 1.0 and rec.metrics["ate_alignment_degenerate"] == 1.0
    assert any("rotation-only" in w for w in rec.warnings) and math.isnan(rec.metrics["scale"])


def test_save_load_and_long_form(tmp_path):
    rec = evaluate_episode(episode(), method="CNN-SLAM", metadata={"seed": 3})
    rec = rec.replace(metrics={**rec.metrics, "semantic_iou_small_structure": math.nan})
    path = save_run(rec, tmp_path / "runs" / "a.json")
    assert "NaN" not in path.read_text()
    back = load_run(path)
    assert math.isnan(back.metrics["semantic_iou_small_structure"])
    assert back.metrics["ate_rmse"] == rec.metrics["ate_rmse"]
    other = rec.replace(sequence="office1", method="LSD")
    save_run(other, tmp_path / "runs" / "b.json")
    frame = load_runs([tmp_path / "runs"])
    assert list(frame.columns[:5]) == ["sequence", "method", "metric", "value", "run"]
    assert {"agent", "uses_ground_truth", "alignment", "alignment_used", "association", "seed"} <= set(frame.columns)
    assert len(frame) == 2 * len(rec.metrics)
    sel = frame[(frame.sequence == "office1") & (frame.metric == "ate_rmse")]
    assert sel["method"].tolist() == ["LSD"] and sel["value"].iloc[0] == pytest.approx(rec.metrics["ate_rmse"])
    assert runs_frame([]).empty


def test_load_run_rejects_bad_files(tmp_path):
    from eval.metrics.results import ResultsError

    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(ResultsError, match="x.json"):
        load_run(tmp_path / "x.json")
    (tmp_path / "y.json").write_text('{"metrics": {}}')
    with pytest.raises(ResultsError, match="'sequence'"):
        load_run(tmp_path / "y.json")


def test_a_run_record_is_typed_frozen_and_round_trips_in_a_fixed_key_order():
    import dataclasses

    from eval.metrics.results import ResultsError, RunRecord

    rec = evaluate_episode(episode(), method="CNN-SLAM", metadata={"seed": 3})
    with pytest.raises(dataclasses.FrozenInstanceError):
        rec.method = "LSD"  # type: ignore[misc]
    out = rec.replace(sensor="mono", run="table1/office0/CNN-SLAM/seed3").to_json()
    assert list(out) == ["schema", "sequence", "method", "agent", "uses_ground_truth", "alignment", "association",
                         "rpe", "warnings", "metrics", "keyframes", "metadata", "sensor"]  # the run key stays out
    written = json.loads(json.dumps(json_ready(out)))
    back = RunRecord.from_json(written, "mem")
    assert json_ready(back.to_json()) == written and back.sensor == "mono" and back.run is None
    assert rec.with_warning("w").warnings[-1] == "w" and "w" not in rec.warnings
    with pytest.raises(ResultsError, match="mem: a run record needs 'sequence'"):
        RunRecord.from_json({"metrics": {}}, "mem")


def test_a_run_folders_record_holds_what_the_run_used_and_metrics_json_stays_the_same_bytes(tmp_path):
    """resources come from timing.json beside metrics.json (measured figures differ from run to run); the record's
    JSON leaves them out, so the same run still writes the same metrics.json."""
    import json

    from eval.metrics.results import RESOURCE_FIGURES, resources_of

    rec = evaluate_episode(episode(), method="CNN-SLAM")
    path = save_run(rec, tmp_path / "run" / "metrics.json")
    written = path.read_bytes()
    (tmp_path / "run" / "timing.json").write_text(json.dumps(
        {"wall_s": 4.0, "fps": 50.0, "peak_rss_mib": 812.5, "step_ms_mean": 20.0,
         "environment": {"cpu": "x"}}))  # fmt: skip
    back = load_run(path)
    frames = rec.metrics["frames"]
    # fps_end_to_end from frames and wall time: a timing.json from before it was written
    assert back.resources == {"wall_s": 4.0, "fps": 50.0, "peak_rss_mib": 812.5, "fps_end_to_end": frames / 4.0}
    assert set(back.resources) <= set(RESOURCE_FIGURES)
    assert "resources" not in back.to_json() and save_run(back, path).read_bytes() == written
    frame = runs_frame([back])
    assert frame.loc[frame.metric == "peak_rss_mib", "value"].tolist() == [812.5]
    assert resources_of({"wall_s": True, "fps_end_to_end": 9.0}) == {"fps_end_to_end": 9.0}  # no bools
    assert load_run(tmp_path / "run" / "metrics.json").resources["peak_rss_mib"] == 812.5


# ------------------------------------------------------------------------------------------------- failures
def test_the_failure_threshold_is_a_share_and_the_rule_states_it():
    from eval.metrics.results import FAILURE_MARK, FAILURE_RULE, MIN_TRACKED_SHARE

    assert 0.0 < MIN_TRACKED_SHARE < 1.0
    assert f"{round(100 * MIN_TRACKED_SHARE)} %" in FAILURE_RULE and FAILURE_MARK in FAILURE_RULE


def test_a_run_that_tracked_nothing_or_scored_no_pose_is_a_failure():
    from eval.metrics.results import failure_of, is_failure

    assert failure_of({"tracked_share": 0.0, "ate_rmse": 0.003}) == "never initialised"
    assert failure_of({"tracked_share": 1.0, "ate_pairs": 0.0}) == "never initialised"
    assert is_failure({"tracked_share": 0.0}) and not is_failure({"tracked_share": 1.0, "ate_pairs": 40.0})
    assert failure_of({"depth_percent_correct": 12.0}) is None  # a record with no trajectory figures is no failure
    assert failure_of({"tracked_share": math.nan}) is None


def test_the_threshold_is_exact_just_below_is_a_failure_just_above_is_not():
    from eval.metrics.results import MIN_TRACKED_SHARE, failure_of, failure_text, share_text

    below = failure_of({"tracked_share": MIN_TRACKED_SHARE - 1e-4})
    threshold = f"{round(100 * MIN_TRACKED_SHARE)} %"
    assert below is not None and below.startswith("tracked ") and below.endswith(f"< {threshold}")
    assert failure_of({"tracked_share": MIN_TRACKED_SHARE}) is None
    assert failure_of({"tracked_share": MIN_TRACKED_SHARE + 1e-4}) is None
    assert failure_of({"tracked_share": 0.22}) == f"tracked 22 % < {threshold}"
    assert share_text(0.896) == "89 %" and share_text(1.0) == "100 %" and share_text(0.07) == "7 %"
    assert failure_text(0.22) == "X (22 %)"


def test_an_sfm_run_registering_no_image_is_a_failure_not_its_identity_poses():
    """COLMAP registering 0 of N images hands back identity poses, none tracked (thirdparty.colmap_sfm): its record
    scores a small ATE over identity poses, and the rule makes it a failure (tracked share 0)."""
    from eval.metrics.results import failure_of

    ep = episode()
    n = len(ep.timestamps)
    ep.T_world_cam_est = np.tile(np.eye(4), (n, 1, 1))
    ep.tracked = np.zeros(n, dtype=bool)
    rec = evaluate_episode(ep, method="COLMAP")
    assert rec.metrics["tracked_share"] == 0.0 and math.isfinite(rec.metrics["ate_rmse"])
    assert failure_of(rec.metrics) == "never initialised"
    assert failure_of(evaluate_episode(episode()).metrics) == "tracked 75 % < 90 %"  # 3 of 4 frames tracked
