"""``cnnslam generate rotation``: names, measured speeds, export as TUM RGB-D folders, prefix-consistent lengths."""

import json

import numpy as np
import pytest

from cnnslam.cli import main
from eval.bench.sequence_resolve import resolve_sequence
from eval.commands.cli_generate import rotation_refs
from eval.errors import EvalError
from sim_envs.folders.formats import read_tum_image_list, read_tum_trajectory


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
    assert main(["generate", "rotation", "--speeds", "fast"]) == 2
    assert "comma-separated numbers" in capsys.readouterr().err
    assert main(["generate", "rotation", "--axes", "sideways"]) == 2
    assert "bad rotation axes" in capsys.readouterr().err
    with pytest.raises(EvalError, match="--frames 1: must be >= 2"):
        rotation_refs(["yaw"], [30.0], 1)


def _refuse_writes(*args, **kwargs):
    raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize(("options", "named", "valid"), [
    (["--frames", "0"], "--frames 0", "must be >= 2"),
    (["--frames", "-5"], "--frames -5", "must be >= 2"),
    (["--axes", "sideways"], "--axes 'sideways': bad rotation axes 'sideways'", "yaw, pitch, roll"),
    (["--axes", ","], "--axes ','", "no axes; give e.g. yaw"),
    (["--axes", "rpy,yaw+pitch+roll", "--speeds", "15"], "give rot_rpy_15@kinect more than once", "once"),
    (["--speeds", "0"], "--speeds '0'", "positive numbers of deg/s"),
    (["--speeds", "fast"], "--speeds 'fast'", "comma-separated numbers of deg/s"),
    (["--speeds", "15,15"], "--speeds '15,15'", "given twice"),
    (["--export", "{tmp}/file"], "--export {tmp}/file: a file, not a folder", "name a folder"),
    (["--export", "{tmp}/file/sub"], "--export {tmp}/file/sub: {tmp}/file is a file", "under a folder"),
    (["--export", "READ_ONLY"], "--export {tmp}/new: cannot write in", "Permission denied"),
    (["--export", "{tmp}/full", "--axes", "yaw", "--speeds", "15"],
     "--export {tmp}/full: {tmp}/full/rot_yaw_15@kinect exists and is not empty", "--overwrite"),
])
def test_bad_arguments_exit_2_in_one_line_before_anything_renders(tmp_path, monkeypatch, capsys, options, named,
                                                                   valid):
    """Bad frames, axes (unknown, none, one sequence twice), speeds (not numbers, not positive, repeated), an
    --export that cannot be written or holds a non-empty sequence folder: exit 2 and one line, nothing rendered
    (not even the table's header) and nothing written."""
    import slamcommon.output_paths as output_paths

    if "READ_ONLY" in options:  # as the check sees a folder it may not write (root may write anywhere)
        monkeypatch.setattr(output_paths.tempfile, "NamedTemporaryFile", _refuse_writes)
        options = [o.replace("READ_ONLY", "{tmp}/new") for o in options]
    (tmp_path / "file").write_text("x")
    (tmp_path / "full" / "rot_yaw_15@kinect").mkdir(parents=True)
    (tmp_path / "full" / "rot_yaw_15@kinect" / "kept").write_text("x")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    options = [o.replace("{tmp}", str(tmp_path)) for o in options]
    assert main(["generate", "rotation", "--no-progress", *options]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cnnslam generate: error: "), captured.err
    assert named.replace("{tmp}", str(tmp_path)) in lines[0] and valid in lines[0] and captured.out == ""
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_generated_sequences_take_the_suites_camera_and_names():
    (kinect,) = rotation_refs(["yaw"], [30.0], 20, "kinect")
    assert kinect.name == "rot_yaw_30@kinect" and kinect.spec().camera_effects == "kinect"
    assert kinect.spec().n_frames == 20
    assert resolve_sequence("rot_yaw_30@kinect").make_source().poses[:20] == pytest.approx(kinect.make_source().poses)
