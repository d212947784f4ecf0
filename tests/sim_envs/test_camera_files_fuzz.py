"""Property-based test of :func:`sim_envs.folders.camera_files.read_camera_file` (``fuzz_reader``: tests/conftest.py):
mutated valid camera files (TOML and flat YAML) for 640x480 images give a camera of that size, or one
:class:`FormatError` line naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_envs.camera import CameraModel
from sim_envs.folders.camera_files import read_camera_file

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

CAMERA_SEEDS = (  # (file name, text)
    ("camera.toml", "# Kinect\nfx = 525.0\nfy = 525.0\ncx = 319.5\ncy = 239.5\nwidth = 640\nheight = 480\n"),
    ("camera.toml", "fx = 517.3\nfy = 516.5\ncx = 318.6\ncy = 255.3\nk1 = 0.2624\nk2 = -0.9531\np1 = -0.0054\n"
     "p2 = 0.0026\nk3 = 1.1633\n"),
    ("camera.toml", 'preset = "tum_fr1"\n'),
    ("camera.yaml", "# ICL-NUIM, y down\nfx: 481.2\nfy: 480.0\ncx: 319.5\ncy: 239.5\nwidth: 640\nheight: 480\n"),
    ("camera.yml", "%YAML 1.2\n---\nfx: 585\nfy: 585\ncx: 320\ncy: 240\nk1: 0.0\n"),
)


def _check_camera(model: CameraModel) -> None:
    K = model.intrinsics
    assert isinstance(model, CameraModel) and (K.width, K.height) == (640, 480)
    assert np.isfinite([K.fx, K.fy, K.cx, K.cy]).all() and K.fx > 0 and K.fy > 0
    assert len(model.distortion) == 5 and np.isfinite(model.distortion).all()


def test_camera_file_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(lambda i: tmp_path / CAMERA_SEEDS[i][0], [text for _, text in CAMERA_SEEDS],
                         lambda p: read_camera_file(p, 640, 480), _check_camera)  # fmt: skip
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
