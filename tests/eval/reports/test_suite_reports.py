"""What the suites leave under results/: Table 1 with the paper's numbers beside ours, rotation, sweep, long form."""

import html
import math
from pathlib import Path

import pandas as pd
import pytest

from eval.bench.run import RunSpec
from eval.bench.runner import RunOutcome, SuiteRun
from eval.bench.suites import get_suite
from eval.metrics.results import FAILURE_RULE, RunRecord
from eval.reports.report_parts import long_frame
from eval.reports.suite_reports import (
    ours_beside_paper,
    report_depth_quality,
    report_rotation,
    report_sweep,
    report_table1,
    sweep_points,
)
from eval.reports.tables import TABLE1_BLOCKS, table1

METHOD_NAMES = ("CNN-SLAM", "LSD", "REMODE", "oracle")


def fake_run(suite, values, skipped=None, failed=()):
    """A SuiteRun with records made of ``values``: (sequence, method) -> metrics dict (plus metadata)."""
    from eval.bench.methods import load_methods

    table = load_methods()
    specs, outcomes, records, timings = [], {}, [], {}
    for (sequence, method), metrics in values.items():
        ref = next(s for s in suite.sequences if s.name == sequence)
        spec = RunSpec(suite.name, ref, table[method], frames=suite.frames)
        specs.append(spec)
        status = "failed" if (sequence, method) in failed else "done"
        outcomes[spec.key] = RunOutcome(spec.key, status, Path("/runs") / spec.key,
                                        "Boom: it broke" if status == "failed" else None)  # fmt: skip
        if status == "done":
            meta = {"git_revision": "abc", "seed": 0, **metrics.pop("_meta", {})}
            records.append(RunRecord(sequence, method, method, metrics, metadata=meta, run=spec.key))
            timings[spec.key] = {"wall_s": 1.5}
    return SuiteRun(suite, Path("/runs"), tuple(specs), outcomes, skipped or {}, records, timings,
                    tuple(table[m] for m in suite.methods))  # fmt: skip


def table1_values():
    suite = get_suite("table1").select(["office0@clean", "living1@clean"], list(METHOD_NAMES))
    values = {}
    for k, seq in enumerate(("office0", "living1")):
        values[(seq, "CNN-SLAM")] = {"ate_rmse": 0.1 + k, "depth_percent_correct": 30.0 + k}
        values[(seq, "LSD")] = {"ate_rmse": 0.5, "depth_percent_correct": 1.0}
        values[(seq, "REMODE")] = {"depth_percent_correct": 5.0}
        values[(seq, "oracle")] = {"ate_rmse": 0.0, "depth_percent_correct": 100.0}
    return suite, values


def test_table1_quotes_the_paper_beside_ours(tmp_path):
    suite, values = table1_values()
    run = fake_run(suite, values, skipped={"ORB": "cannot import it"}, failed={("living1", "LSD")})
    paths = report_table1(run, tmp_path, "cnnslam bench table1")
    assert {p.name for p in paths} == {"table1.md", "table1.html", "table1.csv", "table1.tex", "table1_long.csv",
                                       "table1_stats.csv", "table1_runs.png"}  # no run folders: no other figure
    md = (tmp_path / "table1.md").read_text()
    # CNN-SLAM's ATE on office0: ours 0.100, the paper's 0.266; the Avg. of our two sequences (0.600) is no
    # nine-sequence average: the paper's 0.246 is not quoted beside it, and the report says what it holds
    assert "| office0 (ICL/office0) | 0.100 (0.266) |" in md
    assert "| Avg. | 0.600 |" in md and "(0.246)" not in md
    assert "**A selection from suite `table1`**: sequences not among its 9: office0, living1" in md
    assert "4 of its 8 methods (CNN-SLAM, LSD, REMODE, oracle)" in md
    assert "The suite as defined: the nine Table-1 analogue sequences" in md
    assert "| living1 (ICL/living1) | 1.100 (0.059) | - (0.480) | - | 0.000 |" in md  # failed LSD run: "-"
    assert "**ORB**: cannot import it" in md and "`table1/living1/LSD/seed0-framesall`: Boom: it broke" in md
    assert "cnnslam bench table1" in md
    csv = pd.read_csv(tmp_path / "table1.csv", header=[0, 1], index_col=0)
    assert csv.loc["Avg.", ("Perc. Correct Depth [%]", "CNN-SLAM")] == pytest.approx(30.5)
    assert math.isnan(csv.loc["office0", ("Abs. Trajectory Error [m]", "REMODE")])  # no ATE for REMODE
    assert "\\toprule" in (tmp_path / "table1.tex").read_text()
    long = pd.read_csv(tmp_path / "table1_long.csv")
    assert list(long.columns[:4]) == ["sequence", "method", "metric", "value"]
    assert {"seed", "git_revision", "wall_s", "run"} <= set(long.columns) and len(long) == 12  # 7 runs


def test_ours_beside_paper_without_a_paper_column():
    suite, values = table1_values()
    frame = long_frame(fake_run(suite, values))
    table = table1(frame, methods=list(METHOD_NAMES), sequences=["office0", "living1"])
    text = ours_beside_paper(table, TABLE1_BLOCKS[1][0], "depth_percent_correct", 1)
    assert "| office0 (ICL/office0) | 30.0 (19.4) | 1.0 (0.3) | 5.0 (4.5) | 100.0 |" in text


def test_rotation_report(tmp_path):
    suite = get_suite("rotation").select(["rot_yaw_15@clean", "rot_yaw_60@clean"], ["LSD", "oracle"])
    values = {
        ("rot_yaw_15", "LSD"): {"tracked_share": 0.9, "rot_deg_orient_rmse": 2.0, "rpe_rot_deg_rmse": 0.5,
                                 "depth_percent_correct": 3.0},
        ("rot_yaw_60", "LSD"): {"tracked_share": 0.2, "rot_deg_orient_rmse": 20.0, "rpe_rot_deg_rmse": 4.0,
                                 "depth_percent_correct": 0.5},
        ("rot_yaw_15", "oracle"): {"tracked_share": 1.0, "rot_deg_orient_rmse": 0.0, "rpe_rot_deg_rmse": 0.0,
                                    "depth_percent_correct": 100.0},
        ("rot_yaw_60", "oracle"): {"tracked_share": 1.0, "rot_deg_orient_rmse": 0.0, "rpe_rot_deg_rmse": 0.0,
                                    "depth_percent_correct": 100.0},
    }
    report_rotation(fake_run(suite, values), tmp_path, "cnnslam bench rotation")
    md = (tmp_path / "rotation.md").read_text()
    # the LSD run on rot_yaw_60 tracked 20 % of its frames: a failure, its mark in every block, never a figure; the
    # one on rot_yaw_15 tracked 90 %, the threshold: a figure with its share; LSD's Avg. covers 1 of 2 sequences
    assert "| rot_yaw_60 | X (20 %) | 1.000 | X (20 %) | 0.000 | X (20 %) | 0.000 | X (20 %) | 100.000 |" in md
    assert "| rot_yaw_15 | 0.900 (90 %) | 1.000 | 2.000 (90 %) | 0.000 | 0.500 (90 %) | 0.000 | 3.000 (90 %) |" in md
    assert "| Avg. | 0.900 (1/2) | 1.000 | 2.000 (1/2) | 0.000 | 0.500 (1/2) | 0.000 | 3.000 (1/2) | 100.000 |" in md
    assert "| LSD | 2 | 0 | 1 | 50% |" in md and "| oracle | 2 | 0 | 0 | 0% |" in md
    assert md.count(FAILURE_RULE) == 1  # the rule, stated once
    csv = (tmp_path / "rotation.csv").read_text()
    assert "rot_yaw_60,X (20 %),1,X (20 %),0,X (20 %),0,X (20 %),100" in csv and "20," not in csv
    tex = (tmp_path / "rotation.tex").read_text()
    assert "rot\\_yaw\\_60 & X (20 \\%) &" in tex and "20.000" not in tex
    stats = pd.read_csv(tmp_path / "rotation_stats.csv")
    failed = stats[(stats["sequence"] == "rot_yaw_60") & (stats["method"] == "LSD")]
    assert len(failed) == 4 and (failed["failure"] == "X (20 %)").all() and failed["median"].isna().all()
    assert (failed["failed_runs"] == 1).all() and (failed["runs"] == 0).all()
    page = (tmp_path / "rotation.html").read_text()
    assert '<span class="failure">X (20 %)</span>' in page and html.escape(FAILURE_RULE) in page
    assert "failure: tracked 20 % &lt; 90 %" in page  # the run itself says why
    assert (tmp_path / "rotation_long.csv").is_file() and (tmp_path / "rotation.tex").is_file()


def test_sweep_report_plots_each_axis(tmp_path):
    suite = get_suite("sweep").select(methods=["LSD"])
    values = {}
    for k, ref in enumerate(suite.sequences):
        meta = {"axis": ref.axis, "axis_value": ref.axis_value, "rotation_share": 0.4 + 0.01 * k}
        values[(ref.name, "LSD")] = {"ate_rmse": 0.1 * k, "depth_percent_correct": 2.0 * k, "_meta": meta}
    run = fake_run(suite, values)
    points = sweep_points(run)
    assert set(points["axis"]) == {"texture", "rotation", "focal", "noise", "blur", "exposure", "rolling_shutter",
                                   "distortion"} and len(points) == len(suite.sequences)
    pan = points[points["axis"] == "rotation"]
    assert pan["x"].tolist() == pytest.approx([0.44, 0.45, 0.46, 0.47])  # measured share, not the pan speed
    assert points[points["axis"] == "focal"]["x"].tolist() == [0.7, 0.85, 1.0, 1.2, 1.4]
    paths = report_sweep(run, tmp_path, "cnnslam bench sweep")
    assert (tmp_path / "sweep.png").read_bytes()[:4] == b"\x89PNG" and tmp_path / "sweep.png" in paths
    md = (tmp_path / "sweep.md").read_text()
    assert "### focal length, test / training camera" in md and "| 1.4 | 1.400 |" in md
    assert "### rolling shutter alone, readout in frame intervals" in md and "| 0.5 | 0.500 |" in md


def test_depth_quality_report_checks_the_targets(tmp_path):
    suite = get_suite("depth_quality").select(["office0@clean", "living0@clean"],
                                              ["CNN-SLAM", "raw-CNN", "dev-depth-10"])
    assert suite.frames is None  # whole sequences: the targets are per full sequence
    values = {
        ("office0", "CNN-SLAM"): {"ate_rmse": 0.19, "length_gt_m": 10.0, "scale_error": 0.04, "rot_deg_rmse": 5.0,
                                  "depth_percent_correct": 50.0},
        ("office0", "raw-CNN"): {"ate_rmse": 0.5, "length_gt_m": 10.0, "scale_error": 0.2, "rot_deg_rmse": 9.0,
                                 "depth_percent_correct": 45.0},
        ("living0", "CNN-SLAM"): {"ate_rmse": 0.5, "length_gt_m": 10.0, "scale_error": 0.4, "rot_deg_rmse": 9.0,
                                  "depth_percent_correct": 30.0},
        ("living0", "raw-CNN"): {"ate_rmse": 0.9, "length_gt_m": 10.0, "scale_error": 0.3, "rot_deg_rmse": 9.0,
                                 "depth_percent_correct": 35.0},
        ("living0", "dev-depth-10"): {"ate_rmse": 0.1, "length_gt_m": 10.0, "scale_error": 0.01,
                                      "rot_deg_rmse": 2.0, "depth_percent_correct": 80.0},
    }  # fmt: skip
    paths = report_depth_quality(fake_run(suite, values), tmp_path, "cnnslam bench depth_quality")
    assert {p.name for p in paths} >= {"depth_quality.md", "depth_quality.csv", "depth_quality.png"}
    md = (tmp_path / "depth_quality.md").read_text()
    assert "| office0 | yes | yes | yes |" in md and "| living0 | no | no | no |" in md
    assert "Met on 1 / 1 / 1 of 2 sequences" in md
    csv = pd.read_csv(tmp_path / "depth_quality.csv", header=[0, 1], index_col=0)
    assert csv.loc["office0", ("ATE / length [%]", "CNN-SLAM")] == pytest.approx(1.9)
    assert csv.loc["Avg.", ("Scale error [%]", "CNN-SLAM")] == pytest.approx(22.0)
    assert math.isnan(csv.loc["office0", ("ATE / length [%]", "dev-depth-10")])  # not run there
    assert (tmp_path / "depth_quality.png").read_bytes()[:4] == b"\x89PNG"


def test_reports_say_which_alignment_and_which_methods_were_fed_ground_truth(tmp_path):
    suite, values = table1_values()
    values[("office0", "CNN-SLAM")].update({"ate_alignment_fallback": 1.0, "ate_alignment_degenerate": 1.0,
                                            "ate_sim3_rmse": 0.05})  # fmt: skip
    values[("living1", "LSD")]["ate_alignment_degenerate"] = 1.0
    run = fake_run(suite, values)
    run.records[:] = [r.replace(uses_ground_truth=True) if r.method == "oracle" else r for r in run.records]
    report_table1(run, tmp_path, "cnnslam bench table1")
    md = (tmp_path / "table1.md").read_text()
    assert "- office0 / CNN-SLAM: rotation-only fallback (evo cannot fit: positions one point) in 1 of 1 runs" in md
    assert "- living1 / LSD: poorly conditioned fit" in md
    assert "- **oracle**: receives ground truth (declared by the agent)" in md
    assert "## Scale-aligned ATE, Sim(3) [m]" in md and "| office0 | 0.050 |" in md


def test_reports_name_the_camera_and_map_camera_sequences_to_the_paper():
    from eval.reports.report_parts import camera_sentence
    from eval.reports.suite_reports import paper_name

    assert paper_name("office0@kinect", "-") == paper_name("office0", "-") == "ICL/office0"
    assert paper_name("office0+lit@kinect", "-") == paper_name("office0+lit", "-") == "ICL/office0"
    assert paper_name("rot_yaw_30@kinect", "ours only") == "ours only"
    assert "**kinect**" in camera_sentence(get_suite("table1"))
    assert "**clean**" in camera_sentence(get_suite("table1").select(camera="clean"))
    assert "**hard, kinect**" in camera_sentence(get_suite("table1").select(["office0", "office1@hard"]))
    assert camera_sentence(get_suite("perf")) == ""  # no simulated sequence
    assert "Rooms lit" not in camera_sentence(get_suite("table1"))
    assert "1 of 2 simulated sequences" in camera_sentence(get_suite("table1").select(["office0", "office1+lit"]))


def test_the_papers_average_is_quoted_only_beside_an_average_over_its_nine_sequences():
    from eval.reports.suite_reports import PAPER_NAMES, ours_beside_paper
    from eval.reports.tables import AVG_LABEL

    title = "Abs. Trajectory Error [m]"
    nine = pd.DataFrame({(title, "CNN-SLAM"): [0.1] * 9 + [0.1]},
                        index=pd.Index([*PAPER_NAMES, AVG_LABEL], name="sequence"))  # fmt: skip
    assert "| Avg. | 0.100 (0.246) |" in ours_beside_paper(nine, title, "ate_rmse", 3)
    two = nine.loc[["office0", "living1", AVG_LABEL]]
    assert "| Avg. | 0.100 |" in ours_beside_paper(two, title, "ate_rmse", 3)


def test_a_sweep_cell_is_a_failure_or_the_median_of_the_runs_that_did_not_fail():
    from eval.reports.suite_reports import sweep_cells, sweep_markdown

    points = pd.DataFrame({"axis": "noise", "x": [1.0] * 3 + [2.0] * 3, "setting": [1.0] * 3 + [2.0] * 3,
                           "sequence": "office1@noise", "method": "ORB",
                           "ate_rmse": [0.1, 0.3, 9.0, 5.0, 6.0, 0.2],
                           "depth_percent_correct": [1.0, 3.0, 0.0, 0.0, 0.0, 2.0],
                           "tracked_share": [1.0, 0.95, 0.2, 0.5, 0.0, 1.0]})  # fmt: skip
    cells = sweep_cells(points)
    assert cells[(1.0, 1.0, "ORB", "ate_rmse")] == "0.200 (97 %, 1/3 failed)"  # 0.2 lost: median of 0.1 and 0.3
    assert cells[(2.0, 2.0, "ORB", "ate_rmse")] == "X (25 %)"  # 2 of 3 failed: median share of those two
    assert "| 2 | 2.000 | X (25 %) | X (25 %) |" in sweep_markdown(points)
