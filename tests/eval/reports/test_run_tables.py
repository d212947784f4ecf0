"""The speed and memory table per method and the relative-error tables, from the runs' records."""

import pytest

from eval.reports.run_tables import relative_error_frame, relative_error_markdown, resources_frame, resources_markdown


def test_speed_and_memory_per_method(folder_run):
    frame = resources_frame(folder_run).set_index("method")
    assert list(frame.index) == ["CNN-SLAM", "LSD", "REMODE", "oracle"]  # ORB skipped: no runs
    assert frame.at["LSD", "runs"] == 3 and frame.at["CNN-SLAM", "runs"] == 4
    assert frame.at["CNN-SLAM", "wall_s_median"] == 2.5 and frame.at["CNN-SLAM", "wall_s_max"] == 3.0
    assert frame.at["CNN-SLAM", "fps_end_to_end_min"] == pytest.approx(20.0)
    assert frame.at["oracle", "peak_rss_mib_median"] == 300.0
    assert frame.at["CNN-SLAM", "wall_min_total"] == pytest.approx(10.0 / 60)
    md = resources_markdown(folder_run)
    assert "| CNN-SLAM | 4 | 60 | 2.5 [2.0, 3.0] | 25.0 [20.0, 30.0] | 40.0 | 700 | 0.2 |" in md


def test_a_run_from_before_peak_memory_was_recorded_says_so(folder_run):
    from dataclasses import replace

    old = replace(folder_run, records=[r.replace(resources={k: v for k, v in r.resources.items()
                                                            if k != "peak_rss_mib"}) for r in folder_run.records])
    assert "n/a (not recorded by the code that made these runs)" in resources_markdown(old)


def test_relative_error_per_sequence_method_and_distance(folder_run):
    frame = relative_error_frame(folder_run)
    assert set(frame["method"]) == {"CNN-SLAM", "LSD", "oracle"} and set(frame["share"]) == {10, 20, 30, 40, 50}
    lsd = frame[(frame.sequence == "office0") & (frame.method == "LSD")].set_index("share")
    assert lsd.at[50, "trans_median"] > lsd.at[10, "trans_median"] > 0.05  # 20 % too large: grows with distance
    oracle = frame[frame.method == "oracle"]
    assert (oracle["trans_max"] < 1e-6).all()
    md = relative_error_markdown(folder_run)
    assert "**Relative translation error [m]**" in md and "**Relative rotation error [deg]**" in md
    assert "| office0 | oracle | 0.32, 0.63, 0.95, 1.3, 1.6 | 0.0000 |" in md


def test_a_failed_cell_has_no_relative_error(folder_run):
    from dataclasses import replace

    def lose(record, share):
        return record.replace(metrics={**record.metrics, "tracked_share": share})

    # LSD on office0 (two runs): both lost; CNN-SLAM on office0: one of two never initialised, half: a failed cell
    lost = {("office0", "LSD"): 0.22, ("office0", "CNN-SLAM"): 0.0}
    first = {}
    records = []
    for r in folder_run.records:
        key = (r.sequence, r.method)
        if key == ("office0", "CNN-SLAM") and key in first:
            records.append(r)
            continue
        first[key] = True
        records.append(lose(r, lost[key]) if key in lost else r)
    run = replace(folder_run, records=records)
    frame = relative_error_frame(run)
    cnn = frame[(frame.sequence == "office0") & (frame.method == "CNN-SLAM")]
    assert (cnn["failed"] == 1).all() and (cnn["runs"] == 2).all() and cnn["trans_median"].isna().all()
    living = frame[(frame.sequence == "living1") & (frame.method == "CNN-SLAM")]
    assert (living["failed"] == 0).all() and living["trans_median"].notna().all()
    md = relative_error_markdown(run)
    row = next(line for line in md.splitlines() if line.startswith("| office0 | LSD |"))
    assert row.count("X (22 %)") == 5 and "0.0" not in row.split("|", 4)[4]
    assert next(line for line in md.splitlines() if line.startswith("| office0 | CNN-SLAM |")).count("X (0 %)") == 5
