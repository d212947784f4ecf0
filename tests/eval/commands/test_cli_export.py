import numpy as np
import pytest

import eval.commands.cli_export as cli_export
from cnnslam.cli import main
from sim_envs.camera import preset
from sim_envs.folders.datasets import RgbdFolder
from sim_envs.frames import Frame

NO_WORLD = "sim_envs.sequences cannot be imported (core dependencies: pip install -c constraints.txt -e '.[dev]')"


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
    assert main(["export", "tiny", str(out), "--no-progress"]) == 2  # not empty: refused before anything renders
    assert "not empty" in capsys.readouterr().err


def test_export_command_unknown_sequence(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences", reason=NO_WORLD)
    assert main(["export", "no-such-sequence", str(tmp_path / "x"), "--no-progress"]) == 2
    assert "no-such-sequence" in capsys.readouterr().err


def test_export_command_unknown_camera_effects(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences", reason=NO_WORLD)
    assert main(["export", "office0", str(tmp_path / "x"), "--no-progress", "--camera-effects", "fancy"]) == 2
    assert "clean, fr1, hard, kinect" in capsys.readouterr().err


def test_export_command_lighting(tmp_path, capsys):
    pytest.importorskip("sim_envs.sequences", reason=NO_WORLD)
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
    from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

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
    from sim_envs.folders.datasets import export_tum_rgbd

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


class CountingSource(TinySource):
    """TinySource that counts the frames it renders."""

    rendered = 0

    def frame(self, i):
        CountingSource.rendered += 1
        return super().frame(i)


def _refuse_writes(*args, **kwargs):
    raise PermissionError(13, "Permission denied")


@pytest.mark.parametrize(("folder", "options", "named", "valid"), [
    ("new", ["--frames", "0"], "--frames 0", "must be >= 1"),
    ("new", ["--frames", "-2"], "--frames -2", "must be >= 1"),
    ("new", ["--frames", "5"], "--frames 5: tiny has 4 frames", "give 1..4"),
    ("file", [], "{tmp}/file is a file", "name a folder that does not exist yet"),
    ("file/sub", [], "{tmp}/file/sub: {tmp}/file is a file, not a folder", "name a path under a folder"),
    ("full", [], "{tmp}/full exists and is not empty", "--overwrite"),
    ("READ_ONLY", [], "{tmp}/new: cannot write in {tmp}/new (Permission denied)", "name a path this user can"),
])
def test_bad_arguments_exit_2_in_one_line_before_anything_renders(tmp_path, monkeypatch, capsys, folder, options,
                                                                   named, valid):
    """A --frames outside 1..the sequence's length, a file where the folder goes (or where one of its folders goes),
    a non-empty folder without --overwrite, a folder this user cannot write: exit 2 and one line naming the value
    and what is valid, before any frame renders; nothing is written."""
    import slamcommon.output_paths as output_paths

    source = CountingSource()
    CountingSource.rendered = 0
    monkeypatch.setattr(cli_export, "open_sequence", lambda name, renderer, effects="clean", lighting="flat": source)
    if folder == "READ_ONLY":  # as the check sees a folder it may not write (root may write anywhere)
        monkeypatch.setattr(output_paths.tempfile, "NamedTemporaryFile", _refuse_writes)
        folder = "new"
    (tmp_path / "file").write_text("x")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "kept").write_text("x")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    assert main(["export", "tiny", str(tmp_path / folder), "--no-progress", *options]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cnnslam export: error: "), captured.err
    assert named.format(tmp=tmp_path) in lines[0] and valid in lines[0]
    assert CountingSource.rendered == 0 and captured.out == ""
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
