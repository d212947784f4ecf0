"""Tests of the speed benchmark: it runs, returns every figure, prints them (speed itself is not asserted)."""

from __future__ import annotations

import json

from cnnslam.tools.bench_slam import benchmark, format_figures, main


def test_benchmark_reports_every_figure() -> None:
    figures = benchmark("office0", n_frames=12, predictor="degraded_ground_truth")
    assert figures["frames"] == 12 and figures["resolution"] == "320x240"
    for key in ("tracking_fps", "whole_system_fps", "single_thread_fps", "refinement_ms_per_frame",
                "whole_system_fps_without_model", "fusion_ms_per_keyframe"):
        assert figures[key] > 0, key
    assert figures["tracked_share"] == 1.0
    # the gated figures are in CPU time: the frame thread's CPU in tracking cannot exceed the wall time it took
    # (one thread; the numba kernels are serial), and both are positive
    tracking_wall_ms = 1000 / figures["tracking_fps"]
    assert 0 < figures["tracking_cpu_ms_per_frame"] <= tracking_wall_ms * 1.001 + 0.01
    assert figures["whole_system_cpu_s"] > 0 and figures["tracking_frames_per_unit"] > 0
    text = format_figures(figures)
    assert "tracking_fps" in text and "whole_system_fps" in text


def test_command_line_prints_json(capsys) -> None:
    assert main(["--frames", "8", "--predictor", "degraded_ground_truth", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["frames"] == 8 and figures["predictor"] == "degraded_ground_truth"
