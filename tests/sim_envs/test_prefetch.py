import multiprocessing
import os
import pickle
import threading
import time

import cv2
import numpy as np
import pytest

from sim_envs.camera import preset
from sim_envs.env import ReplayEnv
from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import _IMREAD_RGB, PREFETCH_WORKERS, RgbdFolder, _read_image
from sim_envs.folders.folder_exports import write_folder
from sim_envs.folders.prefetch import THREAD_PREFIX, Prefetcher
from sim_envs.frames import Frame
from slamcommon.agent_keys import T_WORLD_CAM, TRACKED

_OLDER: set[threading.Thread] = set()  # reading threads of other tests' unclosed folders (ended when collected)


def prefetch_threads() -> list[threading.Thread]:
    """The reading threads alive now that the current test started."""
    return [t for t in threading.enumerate() if t.name.startswith(THREAD_PREFIX) and t not in _OLDER]


@pytest.fixture(autouse=True)
def _older_threads():
    _OLDER.clear()
    _OLDER.update(t for t in threading.enumerate() if t.name.startswith(THREAD_PREFIX))


class NoiseSource:
    """Seeded noise images (so every resampling shows), depth with holes, moving poses: a folder-writing input."""

    def __init__(self, n: int = 8, width: int = 96, height: int = 72) -> None:
        self.name = "noise"
        self.intrinsics = preset("tum_fr1", width, height)
        self.timestamps = 1305031102.175 + np.arange(n) / 30.0
        self.poses = np.tile(np.eye(4), (n, 1, 1))
        self.poses[:, :3, 3] = np.linspace(0, 0.3, n)[:, None] * [1.0, 0.5, 0.2]

    def __len__(self) -> int:
        return len(self.timestamps)

    def frame(self, index: int) -> Frame:
        rng = np.random.default_rng(index)
        K = self.intrinsics
        rgb = rng.integers(0, 256, (K.height, K.width, 3), dtype=np.uint8)
        depth = rng.uniform(0.4, 5.0, (K.height, K.width)).astype(np.float32)
        depth[rng.random(depth.shape) < 0.1] = 0.0
        return Frame(index, float(self.timestamps[index]), rgb, depth, self.poses[index].copy())

    def close(self) -> None:
        pass


@pytest.fixture(scope="module")
def noise_folder(tmp_path_factory):
    """A TUM folder named as fr1 (distorted: delivered undistorted) without a camera file."""
    root = tmp_path_factory.mktemp("tum") / "rgbd_dataset_freiburg1_noise"
    return write_folder(NoiseSource(), root, "tum", camera_file=False)


def replay(source, ground_truth="pose"):
    """Every array an episode of ReplayEnv delivers (observation and info), in order."""
    env = ReplayEnv(source, ground_truth=ground_truth)
    out = []
    obs, info = env.reset()
    while True:
        out.append({**obs, **{k: v for k, v in info.items() if isinstance(v, np.ndarray)},
                    "index": info["frame_index"]})  # fmt: skip
        if len(out) == len(source):
            break
        obs, *_, info = env.step({T_WORLD_CAM: np.eye(4), TRACKED: 1})
    env.close()
    return out


def assert_same_bytes(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.keys() == y.keys()
        for key in x:
            x_arr, y_arr = np.asarray(x[key]), np.asarray(y[key])
            assert x_arr.dtype == y_arr.dtype and x_arr.shape == y_arr.shape, key
            assert x_arr.tobytes() == y_arr.tobytes(), key


@pytest.mark.parametrize("size", [(64, 48), None])
@pytest.mark.parametrize("ground_truth", ["pose", "full"])
def test_prefetching_delivers_the_same_bytes_as_reading_when_asked(noise_folder, size, ground_truth):
    plain = RgbdFolder(noise_folder, size=size, prefetch=0)
    ahead = RgbdFolder(noise_folder, size=size, prefetch=3)
    assert ahead.camera.distorted  # the undistortion runs in the threads
    want, got = replay(plain, ground_truth), replay(ahead, ground_truth)
    assert_same_bytes(got, want)
    assert [g["index"] for g in got] == list(range(len(plain)))
    if ground_truth == "full":
        assert "gt_depth" in got[0] and got[0]["gt_depth"].max() > 0
    for i in (0, 5, 2):  # frames out of order (key-frames after an episode): read when asked, the same bytes
        f, g = plain.frame(i), ahead.frame(i)
        for key in ("rgb", "depth", "T_world_cam"):
            assert getattr(f, key).tobytes() == getattr(g, key).tobytes()
        assert (f.index, f.timestamp) == (g.index, g.timestamp)
    ahead.close()


def converted_first(source: RgbdFolder, i: int) -> np.ndarray:
    """RGB of frame i converted as the reader did before it converted last: BGR -> RGB, then undistorted, resized."""
    bgr = cv2.imread(str(source.rgb_paths[i]), cv2.IMREAD_COLOR)
    return source._deliver(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), "rgb")


def test_rgb_is_the_same_bytes_as_decoding_to_bgr_and_converting_first(noise_folder, tmp_path):
    for size in [(64, 48), None]:
        source = RgbdFolder(noise_folder, size=size, prefetch=0)
        for i in (0, 3):
            assert source.rgb(i).tobytes() == converted_first(source, i).tobytes()
    rgb = cv2.GaussianBlur(NoiseSource(1).frame(0).rgb, (5, 5), 0)  # JPEG, grey and 16-bit PNG, RGBA PNG
    write_folder(NoiseSource(1), tmp_path / "jpg", "7scenes", image_format="jpg")
    for name, image in (("grey.png", rgb[..., 0]), ("deep.png", rgb.astype(np.uint16) * 257),
                        ("alpha.png", np.dstack([rgb, rgb[..., :1]]))):  # fmt: skip
        cv2.imwrite(str(tmp_path / name), image)
    for path in [*sorted((tmp_path / "jpg").glob("*.jpg")), *(tmp_path / n for n in ("grey.png", "deep.png",
                                                                                      "alpha.png"))]:
        bgr_first = cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        assert _read_image(path, _IMREAD_RGB).tobytes() == bgr_first.tobytes(), path.name


def test_the_real_fr1_desk_first_frames_are_the_same_bytes(shared_data):
    folder = shared_data("data/real/rgbd_dataset_freiburg1_desk", "rgb.txt", "depth.txt", "groundtruth.txt")
    plain = RgbdFolder(folder, prefetch=0)  # 640x480: the frames as the agent gets them at the images' own size
    ahead = RgbdFolder(folder, size=(320, 240), prefetch=4)
    small = RgbdFolder(folder, size=(320, 240), prefetch=0)
    for i in range(30):
        got = ahead.rgb(i)
        assert got.tobytes() == small.rgb(i).tobytes()
        if i % 10 == 0:
            assert got.tobytes() == converted_first(small, i).tobytes()
            assert plain.rgb(i).tobytes() == converted_first(plain, i).tobytes()
    assert ahead.prefetch_hits == 28
    ahead.close()
    for i in range(3):  # the full frame: depth and pose too
        f, g = small.frame(i), ahead.frame(i)
        assert (f.rgb.tobytes(), f.depth.tobytes(), f.T_world_cam.tobytes(), f.timestamp) == (
            g.rgb.tobytes(), g.depth.tobytes(), g.T_world_cam.tobytes(), g.timestamp)  # fmt: skip
    ahead.close()


def test_reads_ahead_in_order_after_two_consecutive_indices():
    calls: list[int] = []
    lock = threading.Lock()

    def read(i):
        with lock:
            calls.append(i)
        return i * 10

    p = Prefetcher(read, 20, ahead=3, workers=2)
    assert p.get(4) == 40 and p.pending == [] and not prefetch_threads()  # one index: nothing read ahead yet
    assert p.get(5) == 50 and p.pending == [6, 7, 8]
    assert [p.get(i) for i in range(6, 12)] == [60, 70, 80, 90, 100, 110]
    assert p.pending == [12, 13, 14] and p.hits == 6 and p.misses == 2
    assert p.get(2) == 20 and p.pending == [] and p.misses == 3  # a jump back: read now, reads ahead dropped
    assert p.get(3) == 30 and p.pending == [4, 5, 6]
    assert [p.get(i) for i in range(4, 20)] == [10 * i for i in range(4, 20)]
    assert p.pending == []  # never past the end
    p.close()
    with lock:
        assert calls.count(19) == 1 and max(calls) == 19


def test_close_stops_the_threads_and_episodes_do_not_leak_them(noise_folder):
    assert prefetch_threads() == []
    source = RgbdFolder(noise_folder, size=(64, 48), prefetch=2)
    env = ReplayEnv(source)
    for _ in range(3):  # three episodes on one env: one pool, reused
        obs, _ = env.reset()
        for _ in range(len(source) - 1):
            env.step({T_WORLD_CAM: np.eye(4), TRACKED: 1})
        assert 0 < len(prefetch_threads()) <= PREFETCH_WORKERS
    env.close()
    assert prefetch_threads() == []
    obs, _ = env.reset()  # reading again after close starts the threads again
    env.step({T_WORLD_CAM: np.eye(4), TRACKED: 1})
    env.step({T_WORLD_CAM: np.eye(4), TRACKED: 1})
    assert prefetch_threads()
    env.close()
    assert prefetch_threads() == []


def test_a_prefetching_folder_pickles_without_its_threads(noise_folder):
    source = RgbdFolder(noise_folder, size=(64, 48), prefetch=2)
    first = [source.rgb(i) for i in range(3)]
    copy = pickle.loads(pickle.dumps(source))
    assert copy.prefetch == 2 and copy.prefetch_hits == 0
    assert all(copy.rgb(i).tobytes() == first[i].tobytes() for i in range(3))
    source.close()
    copy.close()


def test_an_unreadable_frame_read_ahead_is_the_readers_own_error(noise_folder, tmp_path):
    import shutil

    folder = shutil.copytree(noise_folder, tmp_path / noise_folder.name)
    bad = sorted((folder / "rgb").glob("*.png"))[4]
    bad.write_bytes(b"not a png")
    source = RgbdFolder(folder, size=(64, 48), prefetch=3)
    source.rgb(2)
    source.rgb(3)  # frames 4, 5, 6 are read ahead: 4 fails in a thread
    time.sleep(0.05)
    with pytest.raises(SimEnvError) as caught:
        source.rgb(4)
    message = str(caught.value)
    assert "\n" not in message and str(bad) in message and "cannot read the image" in message
    assert source.rgb(5).shape == (48, 64, 3)  # the frames after it still come
    source.close()


def test_any_other_failure_read_ahead_is_one_line_naming_the_file():
    def read(i):
        if i == 3:
            raise ValueError("broken\nsecond line")
        return i

    p = Prefetcher(read, 10, ahead=2, label=lambda i: f"/data/{i}.png")
    p.get(1)
    p.get(2)
    with pytest.raises(SimEnvError, match=r"^cannot read /data/3.png \(frame 3\): ValueError: broken$"):
        p.get(3)
    p.close()
    with pytest.raises(SimEnvError, match="ahead >= 1 and workers >= 1"):
        Prefetcher(read, 10, ahead=0)


@pytest.mark.parametrize("bad", [-1, 1.5, True, "4"])
def test_a_bad_prefetch_depth_is_refused(noise_folder, bad):
    with pytest.raises(SimEnvError, match=r"prefetch must be a whole number of frames >= 0"):
        RgbdFolder(noise_folder, prefetch=bad)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_a_forked_child_reads_ahead_with_its_own_threads():
    p = Prefetcher(lambda i: i * 2, 50, ahead=3, workers=1)
    assert [p.get(i) for i in range(4)] == [0, 2, 4, 6] and p.pending == [4, 5, 6]
    ctx = multiprocessing.get_context("fork")
    results = ctx.Queue()
    child = ctx.Process(target=lambda: results.put([p.get(i) for i in range(4, 9)]))  # forked: not pickled
    child.start()  # the child inherits the pending reads, not the thread running them
    assert results.get(timeout=30) == [8, 10, 12, 14, 16]
    child.join(timeout=30)
    assert child.exitcode == 0
    assert [p.get(i) for i in range(4, 7)] == [8, 10, 12]
    p.close()
