"""Run folders read for the reports: each run's trajectory scored from its TUM files as its record scores it, the
ATE band over runs, the median run, and why a method has no value."""

import numpy as np
import pytest

from eval.reports.run_data import RunTrack, ate_bands, median_track, missing_reasons, suite_tracks


def test_tracks_are_the_runs_as_their_records_score_them(folder_run):
    tracks = suite_tracks(folder_run)
    assert set(tracks) == {"office0", "living1"}
    assert set(tracks["office0"]) == {"CNN-SLAM", "LSD", "oracle"}  # REMODE: no trajectory of its own
    assert [t.seed for t in tracks["living1"]["LSD"]] == [0]  # its seed 1 failed
    records = {r.run: r for r in folder_run.records}
    for by_method in tracks.values():
        for runs in by_method.values():
            for track in runs:
                assert track.rmse == pytest.approx(records[track.key].metrics["ate_rmse"], abs=1e-9)
                assert track.est.shape == track.gt.shape == (60, 3) and track.alignment == "se3"
                rel = track.relative[0]
                assert rel.share == 10 and rel.distance_m == pytest.approx(records[track.key].metrics["rpe_dist_m_p10"])


def _track(seed, stamps, ate):
    n = len(stamps)
    return RunTrack(f"k{seed}", "M", seed, np.asarray(stamps, float), np.zeros((n, 3)), np.zeros((n, 3)),
                    np.asarray(ate, float), float(np.sqrt(np.mean(np.square(ate)))), (), "se3")


def test_the_band_is_the_median_min_and_max_over_runs_where_they_have_poses():
    stamps = np.array([0.0, 0.1, 0.2])
    runs = [_track(0, stamps, [1, 2, 3]), _track(1, stamps, [3, 2, 1]), _track(2, stamps[1:], [5, 5])]
    median, lo, hi = ate_bands(runs, stamps)
    assert median.tolist() == [2.0, 2.0, 3.0] and lo.tolist() == [1.0, 2.0, 1.0] and hi.tolist() == [3.0, 5.0, 5.0]
    assert median_track(runs).seed == 1  # ATE RMSE 2.16 (seed 0), 2.16 (seed 1), 5: the middle one, ties by seed
    assert median_track(runs[:2] + runs[2:][:0]).seed == 0  # two runs: the lower of the two middle ones


def test_why_a_method_has_no_value(folder_run):
    ate = missing_reasons(folder_run, "ate_rmse")
    assert ate == {"REMODE": "no trajectory of its own", "ORB": "skipped: cannot import pyorb here"}
    assert missing_reasons(folder_run, "map_accuracy_median", ["CNN-SLAM", "LSD"]) == {
        "CNN-SLAM": "no value on its runs", "LSD": "no global model"}
    assert missing_reasons(folder_run, "ate_rmse", ["LSD"], sequence="living1") == {}  # one of two runs finished
