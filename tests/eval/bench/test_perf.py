"""The perf suite: parsing each probe's output, running probes as subprocesses, perf.{md,json}."""

import json
import sys

import pytest

from eval.bench.perf import (
    PerfError,
    Probe,
    load_probes,
    parse_json_stdout,
    parse_metrics_text,
    parse_render_table,
    run_perf,
)

RENDER_OUTPUT = """\
render throughput at 320x240, 200 frames per row (frames per second)
style      renderer   outputs         fps
# office seed 0: 113 primitives, 61 instances; generated in 1.11 s with physics, 0.20 s without
office     mujoco     rgb+depth     118.1
office     pyrender   all            42.0
"""
METRICS_OUTPUT = """\
poses: 100000, associated pairs: 100000
TUM association:                      25.5 ms
SE(3) alignment + ATE + RPE(1 s):     61.0 ms
evaluate_trajectory (all):           180.25 ms
"""


def test_parsers_read_the_figures_and_skip_the_rest():
    assert parse_render_table(RENDER_OUTPUT) == {"office/mujoco/rgb+depth_fps": 118.1, "office/pyrender/all_fps": 42.0}
    assert parse_metrics_text(METRICS_OUTPUT) == {
        "poses": 100000,
        "tum_association_ms": 25.5,
        "se_3_alignment_ate_rpe_1_s_ms": 61.0,
        "evaluate_trajectory_all_ms": 180.25,
    }
    printed = 'warming up...\n{\n  "tracking_fps": 51.5,\n  "stages": {"a": 1}\n}\n'
    assert parse_json_stdout(printed) == {"tracking_fps": 51.5, "stages": {"a": 1}}
    assert parse_json_stdout("no json here {") == {} and parse_render_table("nothing") == {}


def test_the_default_probes():
    probes, frames = load_probes()
    by_name = {p.name: p for p in probes}
    assert set(by_name) == {"render", "cameras", "cameras_late", "cameras_lit", "cnn", "slam", "metrics", "suite"}
    assert frames > 0
    assert tuple(by_name["cameras_lit"].args[:3]) == ("--cameras", "--lighting", "lit")
    assert tuple(by_name["cameras_late"].args[:3]) == ("--cameras", "--first", "900")
    assert "--cameras" in by_name["cameras"].args and by_name["cameras"].output == "json_stdout"
    assert by_name["render"].module == "sim_envs.tools.bench_render" and by_name["render"].output == "render_table"
    assert by_name["cnn"].output == "json_file" and "{json}" in by_name["cnn"].args
    assert by_name["slam"].output == "json_stdout" and "--json" in by_name["slam"].args
    assert by_name["metrics"].module == "eval.metrics.bench_metrics" and by_name["metrics"].output == "metrics_text"
    assert by_name["suite"].module == "eval.commands.cli_profile" and "--json" in by_name["suite"].args
    with pytest.raises(PerfError, match="output must be one of"):
        Probe("x", "x", "json.tool", output="xml")


def test_run_perf_keeps_the_good_probes_and_reports_the_bad(tmp_path):
    data = tmp_path / "in.json"
    data.write_text('{"fps": 12.5}')
    probes = [
        Probe("metrics", "metrics on 2000 poses", "eval.metrics.bench_metrics", ("{frames}",), "metrics_text"),
        Probe("stdout", "a JSON object printed", "json.tool", (str(data),), "json_stdout"),
        Probe("file", "a JSON file written", "json.tool", (str(data), "{json}"), "json_file"),
        Probe("broken", "a module that does not exist", "no_such_module_here", (), "json_stdout"),
        Probe("silent", "prints no figure", "json.tool", (str(data),), "metrics_text"),
    ]
    report = run_perf(tmp_path / "results", frames=2000, probes=probes, progress=False)
    status = {p.name: p.ok for p in report.probes}
    assert status == {"metrics": True, "stdout": True, "file": True, "broken": False, "silent": False}
    figures = {p.name: p.figures for p in report.probes}
    assert figures["metrics"]["poses"] == 2000 and figures["metrics"]["evaluate_trajectory_all_ms"] > 0
    assert figures["stdout"] == {"fps": 12.5} == figures["file"]
    stored = json.loads((tmp_path / "results" / "perf.json").read_text())
    assert stored["probes"]["broken"]["error"].startswith("exit status 1")
    assert stored["probes"]["metrics"]["command"][:3] == [sys.executable, "-m", "eval.metrics.bench_metrics"]
    assert stored["machine"]["cores_available"] >= 1
    md = (tmp_path / "results" / "perf.md").read_text()
    assert "## metrics on 2000 poses" in md and "| poses | 2000 |" in md
    assert "**failed**: no figures found in the output (metrics_text)" in md
    manifest = json.loads((tmp_path / "results" / "perf.provenance.json").read_text())  # what it measured
    assert manifest["outputs"] == ["perf.json", "perf.md"] and manifest["command"] == "cnnslam bench perf --frames 2000"
    assert {"eval.bench.perf", "eval.metrics.bench_metrics", "json.tool"} <= set(manifest["code"]["modules"])
    assert manifest["wall_s"] > 0


def test_speed_baseline_is_the_median_of_its_runs_and_the_gate_judges_against_it(tmp_path):
    from eval.bench.perf import PerfError, load_speed_baseline, speed_baseline_from_runs, speed_gate

    runs = [{"unit_version": "u/1", "tracking_frames_per_unit": t, "whole_system_frames_per_unit": w,
             "sequence": "office0", "frames": 100, "predictor": "network"}
            for t, w in ((0.03, 0.02), (0.05, 0.01), (0.04, 0.03))]
    baseline = speed_baseline_from_runs(runs, sequence="office0", frames=100, predictor="network")
    assert baseline.figures == {"tracking_frames_per_unit": 0.04, "whole_system_frames_per_unit": 0.02}
    path = tmp_path / "perf.json"
    path.write_text(json.dumps(baseline.to_dict()))
    assert load_speed_baseline(path) == baseline
    slow = {**runs[0], "tracking_frames_per_unit": 0.02}  # 2x slower tracking
    record = speed_gate(slow, path)
    assert record["figures"]["tracking_frames_per_unit"]["slowdown"] == 2.0
    assert len(record["failures"]) == 1 and record["failures"][0].startswith("tracking_frames_per_unit")
    assert "differ from the baseline" in speed_gate({**runs[0], "frames": 50}, path)["error"]
    assert "cannot read" in speed_gate(runs[0], tmp_path / "none.json")["error"]
    with pytest.raises(PerfError, match="different or missing machine units"):
        speed_baseline_from_runs([runs[0], {**runs[1], "unit_version": "u/2"}], sequence="s", frames=1, predictor="p")
