"""``cnnslam generate rotation``: names, measured speeds, export as TUM RGB-D folders, prefix-consistent lengths."""

import json

import numpy as np
import pytest

from cnnslam.cli import main
from eval.bench.sequence_ref import resolve_sequence
from eval.commands.cli_generate import rotation_refs
from eval.errors import EvalError
from sim_envs.formats import read_tum_image_list, read_tum_trajectory


def test_help(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["generate", "--help"])
    assert exit_info.value.code == 0
    assert "--axes" in capsys.readouterr().out


def test_generate_and_export(tmp_path, capsys):
    out = tmp_path / "rot"
    code = main(["generate", "rotation", "--axes", "yaw,yaw+pitch", "--speeds", "45", "--frames", "5",
                 "--export", str(out), "--no-progress", "--camera", "clean"])  # fmt: skip
    assert code == 0
    printed = capsys.readouterr().out
    assert "rot_yaw_45" in printed and "rot_yaw-pitch_45" in printed
    row = next(line for line in printed.splitlines() if line.startswith("rot_yaw_45 "))
    assert row.split()[-2:] == ["45.0,", "45.0"]  # measured angular speed (median, max), deg/s
    manifest = json.loads((out / "sequences.json").read_text())
    assert [m["name"] for m in manifest] == ["rot_yaw_45", "rot_yaw-pitch_45"]
    assert manifest[0]["spec"]["n_frames"] == 5 and manifest[0]["spec"]["trajectory"] == "rotation"
    stamps, names = read_tum_image_list(out / "rot_yaw_45" / "rgb.txt")
    assert len(names) == 5 and (out / "rot_yaw_45" / names[0]).is_file()
    _, T = read_tum_trajectory(out / "rot_yaw_45" / "groundtruth.txt")
    assert np.ptp(T[:, :3, 3], axis=0).max() < 1e-9  # pure rotation: the optical centre does not move


def test_a_generated_length_is_a_prefix_of_the_registered_sequence():
    (short,) = rotation_refs(["yaw"], [30.0], 20)
    assert short.name == "rot_yaw_30" and short.spec().n_frames == 20
    registered = resolve_sequence("rot_yaw_30").make_source()
    np.testing.assert_allclose(short.make_source().poses, registered.poses[:20], atol=1e-12)


def test_bad_arguments(capsys):
    with pytest.raises(SystemExit):
        main(["generate", "rotation", "--speeds", "fast"])
    assert "comma-separated numbers" in capsys.readouterr().err
    assert main(["generate", "rotation", "--axes", "sideways"]) == 1
    assert "bad rotation axes" in capsys.readouterr().err
    with pytest.raises(EvalError, match="frames must be >= 2"):
        rotation_refs(["yaw"], [30.0], 1)


def test_generated_sequences_take_the_suites_camera_and_names():
    (kinect,) = rotation_refs(["yaw"], [30.0], 20, "kinect")
    assert kinect.name == "rot_yaw_30@kinect" and kinect.spec().camera_effects == "kinect"
    assert kinect.spec().n_frames == 20
    assert resolve_sequence("rot_yaw_30@kinect").make_source().poses[:20] == pytest.approx(kinect.make_source().poses)
