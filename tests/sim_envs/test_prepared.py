import os

import numpy as np
import pytest

from sim_envs.folders.datasets import RgbdFolder
from sim_envs.folders.folder_exports import write_folder
from sim_envs.folders.prepared import PreparedImages, prepared_key
from tests.sim_envs.test_prefetch import NoiseSource


@pytest.fixture()
def folder(tmp_path):
    return write_folder(NoiseSource(5), tmp_path / "rgbd_dataset_freiburg1_prep", "tum", camera_file=False)


@pytest.mark.parametrize("prefetch", [0, 2])
def test_prepared_images_are_the_same_bytes_and_read_back(folder, tmp_path, prefetch):
    plain = RgbdFolder(folder, size=(64, 48), prefetch=0)
    want = [plain.rgb(i) for i in range(len(plain))]
    first = RgbdFolder(folder, size=(64, 48), prefetch=prefetch, prepared=tmp_path / "prep")
    assert [first.rgb(i).tobytes() for i in range(len(first))] == [w.tobytes() for w in want]
    first.close()
    store = first.prepared_images
    assert store is not None and store.writes == len(want) and store.reads == 0
    assert sorted(p.name for p in store.folder.iterdir()) == [f"{i:06d}.rgb" for i in range(len(want))]
    second = RgbdFolder(folder, size=(64, 48), prefetch=prefetch, prepared=tmp_path / "prep")
    got = [second.rgb(i) for i in range(len(second))]
    second.close()
    assert second.prepared_images.folder == store.folder and second.prepared_images.reads == len(want)
    assert second.prepared_images.writes == 0
    for g, w in zip(got, want, strict=True):
        assert g.dtype == np.uint8 and g.shape == w.shape and g.tobytes() == w.tobytes() and g.flags.writeable
    full = second.frame(2)  # the full frame carries the same RGB
    assert full.rgb.tobytes() == want[2].tobytes()


def test_another_conversion_or_folder_content_is_another_store(folder, tmp_path):
    a = RgbdFolder(folder, size=(64, 48), prepared=tmp_path)
    b = RgbdFolder(folder, size=(48, 36), prepared=tmp_path)
    c = RgbdFolder(folder, size=(64, 48), undistort="full", prepared=tmp_path)
    assert len({a.prepared_images.folder, b.prepared_images.folder, c.prepared_images.folder}) == 3
    assert b.prepared_images.shape == (36, 48, 3)
    described, content = a.describe(), {"sha256": "x"}
    assert prepared_key(described, content) != prepared_key(described, {"sha256": "y"})


def test_an_edited_or_damaged_image_is_converted_again(folder, tmp_path):
    RgbdFolder(folder, size=(64, 48), prefetch=0, prepared=tmp_path).rgb(1)
    source = RgbdFolder(folder, size=(64, 48), prefetch=0, prepared=tmp_path)
    store = source.prepared_images
    path = source.rgb_paths[1]
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))  # the image file changed since
    assert store.load(1, path) is None
    want = RgbdFolder(folder, size=(64, 48), prefetch=0).rgb(1)
    assert source.rgb(1).tobytes() == want.tobytes() and store.writes == 1
    store.path(1).write_bytes(store.path(1).read_bytes()[:100])  # cut short
    assert source.rgb(1).tobytes() == want.tobytes() and store.writes == 2 and store.reads == 0
    assert source.rgb(1).tobytes() == want.tobytes() and store.reads == 1


def test_a_store_that_cannot_be_written_still_delivers(folder, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    store = PreparedImages(blocker / "sub", (48, 64, 3))
    image = np.zeros((48, 64, 3), np.uint8)
    store.store(0, folder / "rgb.txt", image)
    assert store.writes == 0 and store.load(0, folder / "rgb.txt") is None
    assert not list(tmp_path.glob("**/.tmp-*"))
