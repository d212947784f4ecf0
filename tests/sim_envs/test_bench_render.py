"""The render benchmark's camera figures (figures only: nothing about speed is asserted)."""

from __future__ import annotations

import json

import pytest

from sim_envs.tools.bench_render import camera_throughput, main


def test_camera_throughput_late_in_a_sequence():
    fps = camera_throughput("office0", frames=2, width=64, height=48, variants={"kinect": "kinect"}, first=5)
    assert set(fps) == {"kinect"} and fps["kinect"] > 0
    with pytest.raises(ValueError, match="first must be >= 0"):
        camera_throughput("office0", frames=2, width=64, height=48, variants={"kinect": "kinect"}, first=-1)


def test_the_late_probe_prints_one_json_object_of_the_presets(capsys):
    assert main(["--cameras", "--first", "3", "--frames", "2", "--width", "64", "--height", "48", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert set(figures) == {"kinect_fps", "hard_fps"} and all(v > 0 for v in figures.values())
