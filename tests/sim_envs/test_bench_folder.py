import pytest

from sim_envs.folders.datasets import RgbdFolder
from sim_envs.folders.folder_exports import write_folder
from sim_envs.tools.bench_folder import drop_from_page_cache, main, replay_folder
from tests.sim_envs.test_prefetch import NoiseSource


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("bench") / "rgbd_dataset_freiburg1_bench"
    return write_folder(NoiseSource(6), root, "tum", camera_file=False)


def test_the_benchmark_prints_one_row_per_depth_with_equal_digests(folder, capsys):
    assert main([str(folder), "--frames", "5", "--prefetch", "0", "3", "--digest", "--cold", "--size", "48x36"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "cold" in lines[0] and "size 48x36" in lines[0]
    rows = [line.split() for line in lines[2:]]
    assert [r[0] for r in rows] == ["0", "3"] and all(r[1] == "5" for r in rows)
    assert rows[0][-1] == rows[1][-1]  # the same bytes delivered with and without reading ahead
    assert rows[0][-3] == "0" and int(rows[1][-3]) == 3  # hits: frames 2, 3, 4 came from reads ahead
    assert rows[0][-2] == rows[1][-2] == "0"  # no prepared images


def test_prepared_images_are_read_back_on_the_second_row(folder, tmp_path, capsys):
    args = [str(folder), "--prefetch", "2", "2", "--digest", "--prepared", str(tmp_path / "prep"), "--size", "48x36"]
    assert main(args) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[2:]]
    assert [r[-2] for r in rows] == ["0", "6"] and rows[0][-1] == rows[1][-1]


def test_replay_figures_and_the_full_reader(folder):
    plain = replay_folder(folder, prefetch=0, reader="frame", size=None, digest=True)
    ahead = replay_folder(folder, prefetch=2, reader="frame", size=None, digest=True)
    assert plain.frames == ahead.frames == len(RgbdFolder(folder, prefetch=0)) == 6
    assert plain.digest == ahead.digest and ahead.hits == 4
    assert plain.fps > 0 and plain.ms_per_frame > 0 and plain.cpu_seconds >= 0


def test_bad_input_is_one_line_and_exit_status_2(folder, tmp_path, capsys):
    assert main([str(tmp_path), "--frames", "2"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("bench_folder: error: ") and err.count("\n") == 1
    assert main([str(folder), "--frames", "0"]) == 2
    assert "--frames must be >= 1, got 0" in capsys.readouterr().err
    assert main([str(folder), "--prefetch", "2", "-1"]) == 2
    assert "--prefetch depths must be >= 0 (0: no reading ahead), got -1" in capsys.readouterr().err
    with pytest.raises(SystemExit) as caught:
        main([str(folder), "--size", "big"])
    assert caught.value.code == 2 and "WIDTHxHEIGHT" in capsys.readouterr().err


def test_drop_from_page_cache_leaves_the_files(folder):
    paths = sorted((folder / "rgb").glob("*.png"))
    before = [p.read_bytes() for p in paths]
    drop_from_page_cache(paths)
    assert [p.read_bytes() for p in paths] == before
