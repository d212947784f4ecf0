"""``cnnslam reference``: every argument it cannot use is refused with exit 2 and one line naming the value and what
is valid, before COLMAP starts and before anything is written (the command end to end, on a rendered folder, is in
tests/eval/metrics/test_sfm_reference.py)."""

from __future__ import annotations

import numpy as np
import pytest

import eval.commands.cli_reference as cli_reference
from cnnslam.cli import main
from sim_envs.camera import preset
from sim_envs.frames import Frame


class FourFrames:
    """A 4-frame source of random 32 x 24 images (the TUM fr3 camera scaled down: fx 26.77 != fy 26.96)."""

    name = "four"

    def __init__(self):
        self.intrinsics = preset("tum_fr3", 32, 24)
        self.timestamps = np.arange(4) / 30.0
        self.poses = np.tile(np.eye(4), (4, 1, 1))
        self.poses[:, 0, 3] = np.arange(4) * 0.1

    def __len__(self):
        return 4

    def frame(self, i):
        rng = np.random.default_rng(i)
        rgb = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
        depth = rng.uniform(0.5, 5.0, (24, 32)).astype(np.float32)
        return Frame(i, float(self.timestamps[i]), rgb, depth, self.poses[i])


def _refuse_writes(*args, **kwargs):
    raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize(("arguments", "named", "valid"), [
    (["{tmp}/missing"], "{tmp}/missing is not a folder", "sequence"),
    (["{tmp}/file"], "{tmp}/file is not a folder", "sequence"),
    (["{tmp}/empty"], "{tmp}/empty: not an RGB-D folder of a known layout", "TUM RGB-D (rgb.txt"),
    (["office0"], "'office0' is a simulated sequence", "give a real RGB-D folder"),
    (["{tmp}/rgbd", "--step", "0"], "--step 0", "must be >= 1"),
    (["{tmp}/rgbd", "--overlap", "0"], "--overlap 0", "must be >= 1"),
    (["{tmp}/rgbd", "--first", "-1"], "--first -1", "must be >= 0"),
    (["{tmp}/rgbd", "--frames", "2"], "--frames 2", "at least 3 images"),
    (["{tmp}/rgbd", "--rpe-delta", "0"], "--rpe-delta 0", "positive number of seconds"),
    (["{tmp}/rgbd", "--first", "3"], "--first 3 --step 2 select 1 of the folder's 4 images", "at least 3"),
    (["{tmp}/rgbd", "--step", "2"], "--first 0 --step 2 select 2 of the folder's 4 images", "at least 3"),
    (["{tmp}/rgbd", "--step", "1", "--fixed-camera", "--camera-model", "SIMPLE_RADIAL"],
     "--fixed-camera --camera-model SIMPLE_RADIAL: the stated camera (fx 26.77, fy 26.96, distortion 0, 0, 0, 0, 0)",
     "needs --camera-model OPENCV"),
    (["{tmp}/rgbd", "--step", "1", "--out", "{tmp}/file"], "--out {tmp}/file: a file, not a folder", "name a folder"),
    (["{tmp}/rgbd", "--step", "1", "--out", "READ_ONLY"], "--out {tmp}/new: cannot write in", "Permission denied"),
    (["{tmp}/rgbd", "--step", "1", "--workdir", "{tmp}/file/w"], "--workdir {tmp}/file/w: {tmp}/file is a file",
     "under a folder"),
])
def test_bad_arguments_exit_2_in_one_line_before_colmap_starts(tmp_path, monkeypatch, capsys, arguments, named,
                                                                valid):
    """Options out of range, a folder that is missing, a file or of no known layout, a simulated sequence, a
    selection of fewer than 3 images, a stated camera the fixed model cannot hold, an output that cannot be
    written: exit 2, one line, COLMAP never called, nothing written."""
    import slamcommon.output_paths as output_paths
    from sim_envs.folders.datasets import export_tum_rgbd

    def no_colmap(*args, **kwargs):
        raise AssertionError("COLMAP ran")

    monkeypatch.setattr(cli_reference, "reconstruct", no_colmap)
    export_tum_rgbd(FourFrames(), tmp_path / "rgbd", progress=False)
    (tmp_path / "file").write_text("x")
    (tmp_path / "empty").mkdir()
    if "READ_ONLY" in arguments:  # as the check sees a folder it may not write (root may write anywhere)
        monkeypatch.setattr(output_paths.tempfile, "NamedTemporaryFile", _refuse_writes)
        arguments = [a.replace("READ_ONLY", "{tmp}/new") for a in arguments]
    monkeypatch.chdir(tmp_path)  # the default --out (results/reference/<name>) lands here, if anywhere
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    arguments = [a.replace("{tmp}", str(tmp_path)) for a in arguments]
    assert main(["reference", *arguments]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cnnslam reference: error: "), captured.err
    assert named.replace("{tmp}", str(tmp_path)) in lines[0] and valid in lines[0] and captured.out == ""
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
