"""Real RGB-D folders wherever a sequence name goes: folder references (names, fingerprints), the dataset list and
the ``real`` suite, runs on folders (the source's description in the run record; RGB-only: no depth metric), and
``cnnslam bench`` with folder paths, ``--camera`` and ``--image-size``. The folders are written at test time
(``sim_envs.folders.datasets.write_folder``) from a few synthetic frames."""

import json
from pathlib import Path

import numpy as np
import pytest

from cnnslam.cli import main
from eval.bench.methods import external_method, load_methods
from eval.bench.runner import run_suite
from eval.bench.sequence_ref import REPLAY_ENV_ID, SequenceRef, folder_ref
from eval.bench.sequence_resolve import DATASETS_ENV, DEFAULT_DATASETS_FILE, load_dataset_list, resolve_sequence
from eval.bench.suites import get_suite
from eval.errors import SuiteError
from sim_envs.camera import preset
from sim_envs.folders.datasets import write_folder
from sim_envs.folders.formats import write_tum_trajectory
from sim_envs.frames import Frame
from sim_envs.sources.simsource import FrameListSource

METHODS = load_methods()
SMALL = ["--frames", "5", "--runs", "1", "--executor", "serial", "--no-plots", "--no-progress"]


def tiny_source(n: int = 6) -> FrameListSource:
    """Random-textured 64x48 frames in front of a plane 2 m away, moving sideways at 30 Hz."""
    rng = np.random.default_rng(3)
    frames = []
    for k in range(n):
        T = np.eye(4)
        T[0, 3] = 0.02 * k
        rgb = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
        frames.append(Frame(k, k / 30.0, rgb, np.full((48, 64), 2.0, np.float32), T))
    return FrameListSource("tiny", preset("icl", 64, 48), frames)


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    root = tmp_path_factory.mktemp("real")
    return {layout: write_folder(tiny_source(), root / f"seq_{layout}", layout) for layout in ("7scenes", "rgb_only")}


def test_a_folder_with_a_frame_cache_keeps_its_prepared_images(folders, tmp_path):
    ref = resolve_sequence(str(folders["7scenes"]))
    assert ref.make_source().prepared_images is None
    first = ref.make_source(frame_cache=tmp_path)
    store = first.prepared_images
    assert store is not None and store.folder.parent == tmp_path / "prepared"
    want = [first.rgb(i).tobytes() for i in range(len(first))]
    first.close()
    again = ref.make_source(frame_cache=tmp_path)
    assert [again.rgb(i).tobytes() for i in range(len(again))] == want
    assert again.prepared_images.reads == len(want)
    again.close()

def test_a_folder_is_a_sequence(folders, tmp_path):
    ref = resolve_sequence(str(folders["7scenes"]))
    assert ref == folder_ref(folders["7scenes"]) and ref.name == "seq_7scenes" and ref.env_id == REPLAY_ENV_ID
    assert not ref.registered and ref.size == (320, 240) and ref.folder == str(folders["7scenes"].resolve())
    source = ref.make_source()
    assert source.size == (320, 240) and len(source) == 6
    np.testing.assert_allclose(source.intrinsics.as_array(), preset("icl", 320, 240).as_array())
    described = ref.describe()
    assert described["folder"] == ref.folder and described["content"]["files"] == 19  # 6 x 3 files, camera.toml
    assert described["size"] == [320, 240] and described["loader"].startswith("cnnslam-rgbd-folder/")
    native = ref.with_folder_options(size="native")
    assert native.make_source().size == (64, 48) and native.describe() != described
    with pytest.raises(SuiteError, match="no spec overrides"):
        SequenceRef("x", folder="/tmp", overrides={"n_frames": 3})
    with pytest.raises(SuiteError, match="exactly one of base"):
        SequenceRef("x", base="office0", folder="/tmp")
    with pytest.raises(SuiteError, match="not a simulated sequence"):
        ref.spec()


def test_folder_names_are_their_own_and_unique(tmp_path):
    for own in ("my seq (1)", "office 0", "b\u00fcro_k\u00fcche", "\u5ba2\u5385 2"):  # spaces, any letters: as is
        folder = write_folder(tiny_source(2), tmp_path / own, "7scenes")
        assert folder_ref(folder).name == own == resolve_sequence(str(folder)).name
    for taken in ("office0", "office0+lit", "office0@kinect", "rot_yaw_30", "office1~fr1_desk"):
        clash = write_folder(tiny_source(2), tmp_path / taken, "7scenes")
        assert folder_ref(clash).name.startswith(f"{taken}-")  # never taken for a simulated sequence's runs
    hidden = write_folder(tiny_source(2), tmp_path / ".seq\tone", "7scenes")
    assert folder_ref(hidden).name == "seq_one"  # no leading dot (a hidden run folder), nothing unprintable
    a = write_folder(tiny_source(2), tmp_path / "a" / "rgbd", "7scenes")
    b = write_folder(tiny_source(2), tmp_path / "b" / "rgbd", "7scenes")
    suite = get_suite("table1").select([str(a), str(b), str(a)], ["oracle"])
    names = [s.name for s in suite.sequences]
    assert len(names) == 2 and len(set(names)) == 2 and all(n.startswith("rgbd-") for n in names)


def test_an_external_system_is_looked_up_under_the_folder_s_own_name(tmp_path):
    """``--external NAME=OUT`` finds OUT/office 0/trajectory.txt for the folder "office 0" (not OUT/office_0)."""
    folder = write_folder(tiny_source(6), tmp_path / "data" / "office 0", "7scenes")
    source = folder_ref(folder).make_source()
    out = tmp_path / "orb"
    (out / "office 0").mkdir(parents=True)
    write_tum_trajectory(out / "office 0" / "trajectory.txt", source.timestamps, source.poses)
    table = {**METHODS, "orb": external_method("orb", out)}
    suite = get_suite("table1").select([str(folder)], ["orb"], frames=5, runs=1, size="native")
    run = run_suite(suite, table, tmp_path / "runs", plots=False, progress=False)
    assert not run.failed, [o.error for o in run.failed]
    (record,) = run.records
    assert record.sequence == "office 0" and record.metrics["ate_rmse"] == pytest.approx(0.0, abs=1e-6)


def test_a_changed_folder_changes_the_fingerprint(tmp_path):
    folder = write_folder(tiny_source(3), tmp_path / "seq", "7scenes")
    ref = folder_ref(folder)
    before = ref.describe()
    pose = folder / "frame-000001.pose.txt"
    pose.write_text(pose.read_text().replace("2.000000000000000042e-02", "3.000000000000000042e-02"))
    assert ref.describe()["content"] != before["content"]


def test_unknown_names_and_paths_are_one_line_errors(tmp_path):
    with pytest.raises(SuiteError, match="or the path of an RGB-D folder") as err:
        resolve_sequence("office9")
    assert "\n" not in str(err.value)
    with pytest.raises(SuiteError, match="is not a folder"):
        resolve_sequence(str(tmp_path / "missing"))
    with pytest.raises(SuiteError, match="not an RGB-D folder of a known layout; expected one of: TUM RGB-D"):
        resolve_sequence(str(tmp_path))
    with pytest.raises(SuiteError, match="neither a preset"):
        folder_ref(write_folder(tiny_source(2), tmp_path / "seq", "7scenes"), camera="tum_fr9")


def test_the_dataset_list_and_the_real_suite(folders, tmp_path, monkeypatch):
    camera = tmp_path / "cams" / "mine.toml"
    camera.parent.mkdir()
    camera.write_text("fx = 60\nfy = 60\ncx = 31.5\ncy = 23.5\nwidth = 64\nheight = 48\n")
    listing = tmp_path / "lists" / "datasets.toml"
    listing.parent.mkdir()
    listing.write_text(
        f'[datasets]\nseven = "{folders["7scenes"]}"\ngone = "../nowhere"\n'
        f'[datasets.rgbonly]\npath = "{folders["rgb_only"]}"\ncamera = "../cams/mine.toml"\nsize = "native"\n'
    )
    monkeypatch.setenv(DATASETS_ENV, str(listing))
    entries = load_dataset_list()
    assert list(entries) == ["seven", "gone", "rgbonly"]
    assert entries["gone"].path == (tmp_path / "nowhere").resolve()  # relative to the list's folder
    assert entries["rgbonly"].camera == str(camera.resolve()) and entries["rgbonly"].size == "native"
    suite = get_suite("real")
    assert [s.name for s in suite.sequences] == ["seven", "rgbonly"] and suite.frames is None
    assert [name for name, _ in suite.skipped] == ["gone"] and suite.is_default
    assert suite.methods == get_suite("table1").methods
    assert resolve_sequence("seven") == suite.sequences[0]  # list names work wherever a sequence name goes
    assert suite.sequences[1].make_source().intrinsics.fx == 60
    only = suite.select(["rgbonly"])
    assert [s.name for s in only.sequences] == ["rgbonly"] and not only.skipped and not only.is_default
    listing.write_text('[datasets]\n"bad name" = "x"\n')
    with pytest.raises(SuiteError, match="dataset name 'bad name'"):
        get_suite("real")
    listing.write_text('[datasets.x]\npath = "x"\nzoom = 2\n')
    with pytest.raises(SuiteError, match="unknown key.*zoom"):
        get_suite("real")
    monkeypatch.setenv(DATASETS_ENV, str(tmp_path / "none.toml"))
    with pytest.raises(SuiteError, match="no dataset list at"):
        get_suite("real")


@pytest.mark.parametrize(("reference", "message"), [
    (None, r"reference .*missing.tum is not a file; make it \(a TUM trajectory: `cnnslam reference seven --out "
           r"DIR` writes DIR/reference.tum\) or remove the entry's reference"),
    ("0.0 0 0 0 0 0 0 1\nnot a pose\n", r"the reference is not a TUM trajectory: .*ref.tum:2: "
                                         r"expected 8 columns"),
    ("", "the reference is not a TUM trajectory: .*ref.tum: no poses found"),
    ("1.0 0 0 0 0 0 0 1\n0.5 0 0 0 0 0 0 1\n", "ref.tum:2: timestamp 0.5 is smaller than"),
])  # fmt: skip
def test_a_dataset_reference_that_is_missing_or_malformed_is_refused_before_any_run(folders, tmp_path, monkeypatch,
                                                                                   capsys, reference, message):
    """A list entry's ``reference`` is read with the list: missing or not a TUM trajectory, the list is refused
    (SuiteError naming the list, the dataset and the reference), and ``cnnslam bench`` exits 2 before any run."""
    listing = tmp_path / "datasets.toml"
    name = "missing.tum" if reference is None else "ref.tum"
    if reference is not None:
        (tmp_path / name).write_text(reference)
    listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\nreference = "{name}"\n')
    monkeypatch.setenv(DATASETS_ENV, str(listing))
    with pytest.raises(SuiteError, match=f"datasets.toml: dataset 'seven': .*{message}") as err:
        load_dataset_list()
    assert "\n" not in str(err.value)
    assert bench(tmp_path, "table1", "--sequences", "seven", "--methods", "oracle", *SMALL) == 2
    err = capsys.readouterr().err
    assert "datasets.toml: dataset 'seven': " in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "runs").exists()
    for bad in ("1", "[]", '""'):  # not a path
        listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\nreference = {bad}\n')
        with pytest.raises(SuiteError, match="datasets.toml: dataset 'seven': reference = .*; it must be a non-empty"):
            load_dataset_list()
    (tmp_path / "ok.tum").write_text("0.0 0 0 0 0 0 0 1\n0.1 0.01 0 0 0 0 0 1\n")
    listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\nreference = "ok.tum"\n')
    assert load_dataset_list()["seven"].reference == (tmp_path / "ok.tum").resolve()


def test_more_frames_than_a_sequence_has_is_refused_before_any_run(folders, tmp_path, capsys):
    """``--frames 99999`` on a 6-frame folder (or a simulated sequence) is exit 2, naming the sequence and its
    length: a report would have said "the first 99999 frames" of runs that read 6."""
    path = str(folders["7scenes"])
    assert bench(tmp_path, "table1", "--sequences", path, "--methods", "oracle", *SMALL[2:], "--frames", "99999") == 2
    err = capsys.readouterr().err
    assert "--frames 99999: sequence 'seq_7scenes' has 6 frames; give --frames 6 or less, or --frames all" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "runs").exists()
    assert bench(tmp_path, "table1", "--sequences", path, "office0", "--methods", "oracle", *SMALL[2:],
                 "--frames", "7") == 2  # fmt: skip
    assert "sequence 'seq_7scenes' has 6 frames; give --frames 6" in capsys.readouterr().err
    assert bench(tmp_path, "table1", "--sequences", "office0", "--methods", "oracle", *SMALL[2:], "--frames",
                 "99999") == 2  # fmt: skip
    assert "--frames 99999: sequence 'office0@kinect' has" in capsys.readouterr().err
    assert bench(tmp_path, "table1", "--sequences", path, "--methods", "oracle", *SMALL[2:], "--frames", "6") == 0


def test_a_camera_file_for_other_images_is_refused_before_any_run(tmp_path, capsys):
    """A folder whose camera.toml is for 640x480 images while its images are 64x48: exit 2 naming the file and
    both sizes, before any run (it was rescaled silently, fx 600 -> 60)."""
    folder = write_folder(tiny_source(3), tmp_path / "seq", "7scenes")
    (folder / "camera.toml").write_text("fx = 600.0\nfy = 600.0\ncx = 319.5\ncy = 239.5\nwidth = 640\nheight = 480\n")
    assert bench(tmp_path, "table1", "--sequences", str(folder), "--methods", "oracle", *SMALL[2:], "--frames",
                 "3") == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "camera.toml: the camera is for 640x480 images but the images are 64x48" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "runs").exists()


def test_the_shipped_list_names_the_two_shared_real_folders(monkeypatch):
    monkeypatch.delenv(DATASETS_ENV, raising=False)
    entries = load_dataset_list()
    repository = Path(__file__).resolve().parents[2]
    assert DEFAULT_DATASETS_FILE == repository / "datasets.toml"
    shared = (repository / ".." / "shared" / "data" / "real").resolve()
    assert entries["7scenes_redkitchen"].path == shared / "7scenes_redkitchen"
    assert entries["fr1_desk"].path == shared / "rgbd_dataset_freiburg1_desk"
    suite = get_suite("real")  # a clone without ../shared: the folders are skipped, not an error
    assert [s.name for s in suite.sequences] + [n for n, _ in suite.skipped] == ["7scenes_redkitchen", "fr1_desk"]


def test_runs_on_folders_record_the_source_and_skip_depth_without_depth(folders, tmp_path):
    suite = get_suite("table1").select([str(folders["7scenes"]), str(folders["rgb_only"])], ["oracle"], frames=5,
                                       runs=1, size="native")  # fmt: skip
    run = run_suite(suite, METHODS, tmp_path / "runs", plots=True, progress=False)
    assert not run.failed, [o.error for o in run.failed]
    seven, rgb_only = run.records
    source = seven.metadata["source"]
    assert source["layout"] == "7scenes" and source["original_size"] == [64, 48] and source["depth_scale"] == 1000
    assert seven.metadata["sequence_definition"]["folder"] == str(folders["7scenes"].resolve())
    assert seven.metrics["ate_rmse"] == pytest.approx(0.0, abs=1e-9)
    assert seven.metrics["depth_percent_correct"] == pytest.approx(100.0)  # ground truth depth, in mm
    assert rgb_only.metadata["source"]["has_depth"] is False
    assert not any(k.startswith("depth_") for k in rgb_only.metrics)  # skipped, not crashed
    assert any("depth metric skipped" in w for w in rgb_only.warnings)
    folder = tmp_path / "runs" / "table1" / "seq_rgb_only" / "oracle" / "seed0-frames5"
    assert (folder / "trajectory.png").is_file() and not (folder / "depth.png").exists()


def bench(tmp_path, *args):
    return main(["bench", *args, "--out", str(tmp_path / "runs"), "--results", str(tmp_path / "results")])


def test_bench_with_a_folder_path(folders, tmp_path, capsys):
    path = str(folders["7scenes"])
    assert bench(tmp_path, "table1", "--sequences", path, "--methods", "oracle", "--image-size", "32x24", *SMALL) == 0
    out = capsys.readouterr().out
    assert "1 runs (1 run now" in out
    assert "| seq_7scenes (ours only) |" in (tmp_path / "results" / "table1.md").read_text()
    record = json.loads((tmp_path / "runs" / "table1" / "seq_7scenes" / "oracle" / "seed0-frames5" /
                         "metrics.json").read_text())  # fmt: skip
    assert record["metadata"]["source"]["size"] == [32, 24]
    assert any(c.startswith("resized 64x48 -> 32x24") for c in record["metadata"]["source"]["conversions"])
    assert bench(tmp_path, "table1", "--sequences", path, "--methods", "oracle", "--frames", "all", *SMALL[2:]) == 0
    assert (tmp_path / "runs" / "table1" / "seq_7scenes" / "oracle" / "seed0-framesall" / "metrics.json").is_file()
    capsys.readouterr()
    assert bench(tmp_path, "table1", "--sequences", str(tmp_path / "nope"), *SMALL) == 2
    err = capsys.readouterr().err
    assert "is not a folder" in err and len(err.strip().splitlines()) == 1
    assert bench(tmp_path, "table1", "--sequences", "office0", "--camera", "tum_fr1", *SMALL) == 2
    assert "applies to folder sequences only" in capsys.readouterr().err
    assert bench(tmp_path, "table1", "--sequences", "office0", "--camera", "kinectt", *SMALL) == 2
    err = capsys.readouterr().err
    assert "unknown camera preset 'kinectt'" in err and "kinect" in err and len(err.strip().splitlines()) == 1
    assert bench(tmp_path, "table1", "--sequences", path, "--image-size", "big", *SMALL) == 2
    assert "--image-size must be WIDTHxHEIGHT" in capsys.readouterr().err


def test_bench_real_reports_missing_folders(folders, tmp_path, monkeypatch, capsys):
    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets]\nseven = "{folders["7scenes"]}"\ngone = "{tmp_path / "gone"}"\n')
    monkeypatch.setenv(DATASETS_ENV, str(listing))
    args = ["real", "--methods", "oracle", *SMALL]
    assert bench(tmp_path, *args) == 1
    captured = capsys.readouterr()
    assert "skipped sequence gone" in captured.out and "--allow-skips" in captured.err
    assert "Sequences skipped" in (tmp_path / "results" / "real.md").read_text()
    assert bench(tmp_path, *args, "--allow-skips") == 0
    listing.write_text(f'[datasets]\ngone = "{tmp_path / "gone"}"\n')
    assert bench(tmp_path, *args) == 1
    assert "no sequence to run here" in capsys.readouterr().err
    assert bench(tmp_path, *args, "--allow-skips") == 0
    assert main(["bench", "--list"]) == 0
    assert "missing here: gone" in capsys.readouterr().out


def status(results: Path) -> tuple[int, str]:
    """``cnnslam results status --json --results RESULTS real``: the exit status and the result's why."""
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["results", "status", "--json", "--results", str(results), "real"])
    return code, json.loads(out.getvalue())[0]["why"]


def test_a_second_reference_scores_every_run_in_the_report(folders, tmp_path, monkeypatch):
    """Known answer: the reference is the ground truth with every translation doubled (a similarity), so against
    it the oracle and the ground truth both have Sim(3) ATE 0 and a scale error of |1/2 - 1| = 50 %. The reference
    is one of the result's inputs: editing it makes the result stale."""
    from eval.bench import provenance
    from sim_envs.folders.formats import read_tum_trajectory, write_tum_trajectory

    monkeypatch.setattr(provenance, "tree_state", lambda root=None: provenance.TreeState("0123456789ab", ()))

    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\nreference = "refs/seven.tum"\n')
    monkeypatch.setenv(DATASETS_ENV, str(listing))
    args = ["real", "--methods", "oracle", *SMALL]
    assert bench(tmp_path, *args) == 2 and not (tmp_path / "runs").exists()  # listed, not made: refused
    assert load_dataset_list(check_references=False)["seven"].reference == (tmp_path / "refs" / "seven.tum").resolve()
    assert resolve_sequence("seven", check_references=False).folder == str(folders["7scenes"].resolve())
    listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\n')
    assert bench(tmp_path, *args) == 0
    stamps, T = read_tum_trajectory(tmp_path / "runs" / "real" / "seven" / "oracle" / "seed0-frames5" /
                                    "groundtruth.tum")  # fmt: skip
    T = T.copy()
    T[:, :3, 3] *= 2.0
    (tmp_path / "refs").mkdir()
    write_tum_trajectory(tmp_path / "refs" / "seven.tum", stamps, T)
    listing.write_text(f'[datasets.seven]\npath = "{folders["7scenes"]}"\nreference = "refs/seven.tum"\n')
    assert load_dataset_list()["seven"].reference == (tmp_path / "refs" / "seven.tum").resolve()
    assert bench(tmp_path, *args) == 0  # the runs are reused: a reference is a scoring input, not a run input
    assert status(tmp_path / "results") == (0, "all 1 runs' fingerprints equal")
    write_tum_trajectory(tmp_path / "refs" / "seven.tum", stamps, T * 1.0001)  # the report's figures change with it
    assert status(tmp_path / "results") == (1, f"scoring inputs changed: {tmp_path / 'refs' / 'seven.tum'}")
    write_tum_trajectory(tmp_path / "refs" / "seven.tum", stamps, T)
    report = (tmp_path / "results" / "real.md").read_text()
    section = report.split("## Against a second reference")[1].split("![every run")[0]
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in section.splitlines() if line.startswith("| ") and "---" not in line}  # fmt: skip
    for name, runs in (("(the folder's ground truth)", "-"), ("oracle", "1")):
        assert rows[name][0] == runs
        assert float(rows[name][2]) == pytest.approx(0.0, abs=1e-6)  # Sim(3) ATE
        assert float(rows[name][3]) == pytest.approx(50.0, abs=1e-3)  # scale error [%]
    assert float(rows["oracle"][1]) > 0.01  # SE(3) ATE: the doubled path does not fit without scale
    # a method scored without a trajectory of its own (REMODE, on LSD-BS's poses) gets no row of its own
    scored = tmp_path / "runs" / "real" / "seven" / "oracle" / "seed0-frames5" / "metrics.json"
    record = json.loads(scored.read_text())
    record["metrics"].pop("ate_rmse")
    scored.write_text(json.dumps(record))
    assert bench(tmp_path, *args, "--report-only") == 0
    section = (tmp_path / "results" / "real.md").read_text().split("## Against a second reference")[1]
    section = section.split("\n## ")[0].split("![every run")[0]
    assert "(the folder's ground truth)" in section and "| oracle |" not in section
