import numpy as np
import pytest

import eval.commands.cli_export as cli_export
from cnnslam.cli import main
from sim_envs.camera import preset
from sim_envs.datasets import RgbdFolder
from sim_envs.frames import Frame


class TinySource:
    """A 4-frame source of random images (the exporter needs nothing else)."""

    def __init__(self):
        self.name = "tiny"
        self.intrinsics = preset("tum_fr3", 32, 24)
        self.timestamps = np.arange(4) / 30.0
        self.poses = np.tile(np.eye(4), (4, 1, 1))
        self.poses[:, 0, 3] = np.arange(4) * 0.1
        self.closed = False

    def __len__(self):
        return 4

    def frame(self, i):
        rng = np.random.default_rng(i)
        rgb = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
        depth = rng.uniform(0.5, 5.0, (24, 32)).astype(np.float32)
        return Frame(i, float(self.timestamps[i]), rgb, depth, self.poses[i])

    def close(self):
        self.closed = True


def test_export_command_writes_a_loadable_folder(tmp_path, monkeypatch, capsys):
    source = TinySource()
    monkeypatch.setattr(cli_export, "open_sequence", lambda name, renderer, effects="clean", lighting="flat": source)
    out = tmp_path / "tiny"
    assert main(["export", "tiny", str(out), "--no-progress", "--frames", "3"]) == 0
    assert "exported tiny" in capsys.readouterr().out and source.closed
    loaded = RgbdFolder(out)
    assert len(loaded) == 3 and loaded.intrinsics == source.intrinsics
    np.testing.assert_array_equal(loaded.frame(2).rgb, source.frame(2).rgb)
    np.testing.assert_allclose(loaded.poses, source.poses[:3], atol=1e-9)
    assert loaded.frame(0).labels is None
    assert main(["export", "tiny", str(out), "--no-progress"]) == 1  # not empty
    assert "not empty" in capsys.readouterr().err


def test_export_command_unknown_sequence(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences")
    assert main(["export", "no-such-sequence", str(tmp_path / "x"), "--no-progress"]) == 2
    assert "no-such-sequence" in capsys.readouterr().err


def test_export_command_unknown_camera_effects(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences")
    assert main(["export", "office0", str(tmp_path / "x"), "--no-progress", "--camera-effects", "fancy"]) == 2
    assert "clean, hard, kinect" in capsys.readouterr().err


def test_export_command_lighting(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences")
    assert main(["export", "office0", str(tmp_path / "x"), "--no-progress", "--lighting", "dim"]) == 2
    assert "lighting must be one of flat, lit" in capsys.readouterr().err
    assert main(["export", "office0", str(tmp_path / "y"), "--no-progress", "--lighting", "lit", "--renderer",
                 "pyrender"]) == 2  # fmt: skip
    assert "mujoco renderer only" in capsys.readouterr().err
    assert cli_export.open_sequence("office0", "mujoco", "kinect", "lit").spec.lighting == "lit"


def test_the_readmes_through_files_recipe_works_as_written(tmp_path, monkeypatch, capsys):
    """README, "Through files": ``cnnslam export office0 data/office0``, a system writes OUT/office0/trajectory.txt
    from the exported images, ``cnnslam bench table1 --external MySLAM=OUT`` scores it (here at 12 frames, one
    sequence, the external method alone). The export shows the images the suite scores (the default camera)."""
    from sim_envs.camera_effects import DEFAULT_CAMERA_EFFECTS
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.simsource import SimulatedSequence

    monkeypatch.chdir(tmp_path)
    assert main(["export", "office0", "data/office0", "--frames", "12", "--no-progress"]) == 0
    folder = RgbdFolder(tmp_path / "data" / "office0")
    with SimulatedSequence(with_camera(get_sequence("office0"), DEFAULT_CAMERA_EFFECTS)) as scored:
        assert np.array_equal(folder.frame(0).rgb, scored.frame(0).rgb)
    # "run your system": a perfect one, answering the exported ground truth at the exported time stamps
    (tmp_path / "OUT" / "office0").mkdir(parents=True)
    (tmp_path / "OUT" / "office0" / "trajectory.txt").write_text(
        (tmp_path / "data" / "office0" / "groundtruth.txt").read_text())
    capsys.readouterr()
    code = main(["bench", "table1", "--external", "MySLAM=OUT", "--methods", "MySLAM", "--sequences", "office0",
                 "--frames", "12", "--runs", "1", "--no-plots", "--no-progress", "--results", "res"])
    out = capsys.readouterr().out
    assert code == 0, out
    table = (tmp_path / "res" / "table1.md").read_text()
    assert "0 failed" in out and "| office0@kinect (ICL/office0) | 0.000 |" in table


def test_a_file_in_the_folders_place_is_one_line(tmp_path, capsys):
    (tmp_path / "EXISTING_FILE").write_text("x")
    assert main(["export", "office0", str(tmp_path / "EXISTING_FILE"), "--frames", "2", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "is a file; an export writes a folder" in err and len(err.strip().splitlines()) == 1


def test_an_interrupted_export_leaves_nothing_in_the_way(tmp_path):
    """Ctrl-C during an export: the temporary folder goes, no partial folder blocks the rerun, which then works."""
    from sim_envs.datasets import export_tum_rgbd

    class Interrupted(TinySource):
        def frame(self, i):
            if i == 2:
                raise KeyboardInterrupt
            return super().frame(i)

    with pytest.raises(KeyboardInterrupt):
        export_tum_rgbd(Interrupted(), tmp_path / "out", progress=False)
    assert list(tmp_path.iterdir()) == []
    assert export_tum_rgbd(TinySource(), tmp_path / "out", progress=False) == tmp_path / "out"
    assert [p.name for p in tmp_path.iterdir()] == ["out"] and len(RgbdFolder(tmp_path / "out")) == 4
