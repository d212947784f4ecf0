import json
from pathlib import Path

import numpy as np
import pytest

from cnnslam.cli import main

TUM = Path("/work/shared/data/tum")
FR2_GT, FR2_ORB = str(TUM / "fr2_desk_groundtruth.txt"), str(TUM / "fr2_desk_ORB.txt")
FR1_GT, FR1_EST = str(TUM / "freiburg1_xyz-groundtruth.txt"), str(TUM / "freiburg1_xyz-rgbdslam.txt")


def run_json(capsys, *args):
    assert main(["eval", *args, "--json"]) == 0
    out = capsys.readouterr().out
    assert len(out.strip().splitlines()) == 1  # exactly one JSON object
    return json.loads(out)


def test_json_reference_figures(capsys):
    d = run_json(capsys, FR2_GT, FR2_ORB, "--duplicates", "last")
    assert f"{d['rmse']:.6f}" == "0.008144" and d["pairs"] == 2223
    for key in ("mean", "median", "std", "min", "max"):
        assert isinstance(d[key], float)
    assert d["alignment"]["used"] == "se3" and d["association"] == {
        "rule": "tum",
        "max_difference": 0.02,
        "offset": 0.0,
        "pairs": 2223,
    }
    d = run_json(capsys, FR2_GT, FR2_ORB, "--duplicates", "last", "--association", "nearest", "--align", "sim3")
    assert f"{d['rmse']:.6f}" == "0.006187" and f"{d['scale']:.4f}" == "0.9970"
    d = run_json(capsys, FR1_GT, FR1_EST, "--align", "sim3")
    assert f"{d['rmse']:.6f}" == "0.013394" and f"{d['scale']:.4f}" == "1.0079" and d["pairs"] == 786
    d = run_json(capsys, FR1_GT, FR1_EST, "--rpe-delta", "10", "--rpe-unit", "frames")
    assert d["rpe"]["unit"] == "frames" and d["rpe"]["translation"]["pairs"] == 776


def test_text_report_and_plot(capsys, tmp_path):
    plot = tmp_path / "fig.png"
    assert main(["eval", FR1_GT, FR1_EST, "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "APE w.r.t. translation part (m)" in out and "      rmse  0.013473" in out
    assert "tum, max. difference 0.02 s, offset 0.0 s, 786 pairs" in out
    assert plot.stat().st_size > 10_000


def test_errors_name_the_file_and_line(capsys, tmp_path):
    assert main(["eval", FR2_GT, FR2_ORB]) == 1
    err = capsys.readouterr().err
    assert f"{FR2_GT}:10863:" in err and "--duplicates last" in err
    shifted = tmp_path / "shifted.txt"
    shifted.write_text("5.0 0 0 0 0 0 0 1\n6.0 0 0 0 0 0 0 1\n")
    assert main(["eval", FR1_GT, str(shifted)]) == 1
    assert "found 0 matching timestamps" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["eval", FR1_GT, FR1_EST, "--align", "affine"])


def test_kitti_files_and_degenerate_warning(capsys, tmp_path):
    from eval.trajectory import PoseTrajectory

    n = 30
    T = np.tile(np.eye(4), (n, 1, 1))
    angles = np.linspace(0, 1, n)
    T[:, 0, 0] = T[:, 2, 2] = np.cos(angles)
    T[:, 0, 2], T[:, 2, 0] = np.sin(angles), -np.sin(angles)  # pure rotation about y
    PoseTrajectory(np.arange(n) / 10, T).to_kitti_file(tmp_path / "gt.txt")
    PoseTrajectory(np.arange(n) / 10, T).to_kitti_file(tmp_path / "est.txt")
    assert main(["eval", str(tmp_path / "gt.txt"), str(tmp_path / "est.txt"), "--format", "kitti", "--json"]) == 0
    captured = capsys.readouterr()
    d = json.loads(captured.out)
    assert d["association"]["rule"] == "index" and d["alignment"]["used"] == "rotation_only"
    assert d["rmse"] == pytest.approx(0.0, abs=1e-9) and d["warnings"] and "rotation-only" in captured.err
