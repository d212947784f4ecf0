"""The suite profile: per method, every stage of its runs in ms per frame, summing to its wall time; the perf
suite's probe prints it as a table that perf.md shows as one."""

from __future__ import annotations

import json

import pytest

from eval.bench.methods import load_methods
from eval.bench.perf import PerfReport, ProbeResult, format_perf_markdown, parse_json_stdout
from eval.bench.profile import profile_runs, profile_table, suite_profile
from eval.bench.run import STAGES
from eval.bench.runner import run_suite
from eval.bench.suites import get_suite
from eval.commands.cli_profile import main


def test_known_answers() -> None:
    timing = {"wall_s": 2.0, "stages": {"agent": 1.0, "frames": 0.5, "other": 0.5}}
    [p] = profile_runs([("m", 10, timing), ("m", 30, {**timing, "wall_s": 2.0}), ("m", 10, {"wall_s": 1.0})])
    assert (p.runs, p.frames, p.seconds, p.fps) == (3, 50, 5.0, 10.0)
    assert p.ms_per_frame("agent") == pytest.approx(40.0) and p.ms_per_frame("plots") == 0.0
    table = profile_table([p])
    assert table["columns"][:5] == ["method", "runs", "frames", "fps", "wall_s"] and len(table["rows"]) == 1
    assert len(table["rows"][0]) == 5 + len(STAGES)


def test_a_tiny_suite_has_every_stage_and_they_sum_to_its_wall_time(tmp_path) -> None:
    suite = get_suite("table1").select(["office0@kinect"], ["oracle", "constant-pose"], frames=5, runs=1)
    done = run_suite(suite, load_methods(), tmp_path, plots=True, progress=False, check=False, revision="r")
    profiles = suite_profile(done)
    assert [p.method for p in profiles] == ["oracle", "constant-pose"]
    for p in profiles:
        assert p.runs == 1 and p.frames == 5 and p.fps > 0
        assert p.stages["agent"] > 0 and p.stages["plots"] > 0 and p.stages["trajectory_metrics"] > 0
        assert sum(p.ms_per_frame(s) for s in STAGES) == pytest.approx(1e3 * p.seconds / p.frames, rel=1e-6)


@pytest.mark.slow
def test_the_probe_prints_a_table_perf_md_shows(capsys) -> None:
    assert main(["--sequences", "office0@kinect", "--frames", "3", "--methods", "oracle", "--json"]) == 0
    figures = parse_json_stdout(capsys.readouterr().out)
    assert figures["columns"][0] == "method" and [r[0] for r in figures["rows"]] == ["oracle"]
    assert figures["rendering_ms_per_frame"] > 0 and figures["failed_runs"] == 0
    probe = ProbeResult("suite", "suite profile", ["python", "-m", "eval.commands.cli_profile"], True, figures)
    text = format_perf_markdown(PerfReport([probe], {"cores_available": 2}, "r"))
    assert "| method | runs | frames | fps | wall_s | setup_ms |" in text and "| oracle | 1 | 3 |" in text
    json.dumps(figures)


def test_the_default_methods_are_the_table1_suites_defined_once_in_the_method_table(monkeypatch, capsys) -> None:
    import eval.bench
    import eval.bench.profile as profile
    import eval.bench.run
    from eval.bench.benchmark import Skip
    from eval.bench.suites import TABLE1_METHODS

    # the Table-1 list is the method table's `table1 = true` methods, in its order, and nowhere else
    assert TABLE1_METHODS == tuple(name for name, m in load_methods().items() if m.table1)
    assert {"CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE", "oracle"} <= set(TABLE1_METHODS)
    assert get_suite("table1").methods == TABLE1_METHODS and not hasattr(profile, "TABLE1_METHODS")
    calls = []

    class Outcome:
        parts: tuple = ()
        failed: tuple = ()
        skipped = (Skip("method", "ORB-SLAM3", "no pyorbslam3"), Skip("sequence", "x", "absent"))

    monkeypatch.setattr(eval.bench.run, "render_frames", lambda job: None)
    monkeypatch.setattr(eval.bench, "run_bench", lambda suite, methods, options: calls.append((suite, methods))
                        or Outcome())
    assert main(["--frames", "3"]) == 0
    assert calls == [("table1", None)]  # None: the suite's own methods, a method that cannot run here skipped
    assert "skipped (cannot run here): ORB-SLAM3" in capsys.readouterr().out
    assert main(["--frames", "3", "--methods", "oracle", "--json"]) == 0 and calls[-1] == ("table1", ["oracle"])
    assert json.loads(capsys.readouterr().out)["skipped_methods"] == "ORB-SLAM3"
