"""The frame cache: a frame read back is the frame rendered, field for field and byte for byte; the folder's name
changes with the source, the renderer and the numeric environment."""

from __future__ import annotations

import numpy as np

from sim_envs.render.gl import gl_platform
from sim_envs.sequences import get_sequence, with_camera
from sim_envs.sources import frame_cache
from sim_envs.sources.frame_cache import CachedFrames, cache_key, world_source_hash
from sim_envs.sources.simsource import SimulatedSequence


def _same(a, b) -> bool:
    fields = ("index", "timestamp", "rgb", "depth", "T_world_cam", "labels", "instances", "sensor_depth")
    for name in fields:
        x, y = getattr(a, name), getattr(b, name)
        if x is None or y is None:
            if x is not y:
                return False
        elif not (np.asarray(x).dtype == np.asarray(y).dtype and np.array_equal(x, y)):
            return False
    return True


def test_frames_read_back_are_the_rendered_ones(tmp_path) -> None:
    spec = with_camera(get_sequence("office0"), "kinect")  # noise, sensor depth: every field filled
    with SimulatedSequence(spec) as plain:
        expected = [plain.frame(i) for i in (0, 7)]
    cached = CachedFrames(SimulatedSequence(spec), tmp_path / "office0")
    try:
        first = [cached.frame(i) for i in (0, 7)]  # rendered and stored
        again = [cached.frame(i) for i in (0, 7)]  # read back
        assert len(cached) == spec.n_frames and cached.name == spec.name
        assert sorted(p.name for p in (tmp_path / "office0").iterdir()) == ["000000.frame", "000007.frame"]
        for e, f, a in zip(expected, first, again, strict=True):
            assert _same(e, f) and _same(e, a) and a.sensor_depth is not None
        rgb = cached.rgb(7)  # the image alone, from the same file
        assert rgb.dtype == np.uint8 and np.array_equal(rgb, expected[1].rgb) and rgb.flags.writeable
        assert (cached.reads, cached.renders) == (3, 2)
        size = sum(p.stat().st_size for p in (tmp_path / "office0").iterdir())
        assert size < 0.4 * 2 * sum(x.nbytes for x in (expected[0].rgb, expected[0].depth, expected[0].labels,
                                                        expected[0].instances, expected[0].sensor_depth))
        (tmp_path / "office0" / "000007.frame").write_bytes(b"broken")  # an interrupted copy is rendered again
        assert _same(cached.frame(7), expected[1]) and cached.renders == 3
        (tmp_path / "office0" / "000007.frame").write_bytes(b"")
        assert np.array_equal(cached.rgb(7), expected[1].rgb) and cached.renders == 4
    finally:
        cached.close()


def test_the_key_follows_source_renderer_and_environment(monkeypatch) -> None:
    a = cache_key({"name": "office0"}, "mujoco")
    assert a == cache_key({"name": "office0"}, "mujoco") and len(world_source_hash()) == 16
    assert a != cache_key({"name": "office1"}, "mujoco") and a != cache_key({"name": "office0"}, "pyrender")
    monkeypatch.setenv("NPY_DISABLE_CPU_FEATURES", "AVX512F")
    assert cache_key({"name": "office0"}, "mujoco") != a
    monkeypatch.delenv("NPY_DISABLE_CPU_FEATURES")
    monkeypatch.setattr(frame_cache, "CACHE_FORMAT", "frames/1")  # a cache of another format is another folder
    assert cache_key({"name": "office0"}, "mujoco") != a


def test_the_key_is_the_same_before_and_after_the_renderer_exports_its_gl_platform(monkeypatch) -> None:
    # rendering exports MUJOCO_GL / PYOPENGL_PLATFORM (configure_gl): a run after a rendering in the same process
    # must find the frames that rendering stored; another platform is another key
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.delenv("PYOPENGL_PLATFORM", raising=False)
    before = cache_key({"name": "office0"}, "mujoco")
    chosen = gl_platform()
    monkeypatch.setenv("MUJOCO_GL", chosen)
    monkeypatch.setenv("PYOPENGL_PLATFORM", chosen)
    assert cache_key({"name": "office0"}, "mujoco") == before
    other = "osmesa" if chosen == "egl" else "egl"
    monkeypatch.setenv("MUJOCO_GL", other)
    monkeypatch.setenv("PYOPENGL_PLATFORM", other)
    assert cache_key({"name": "office0"}, "mujoco") != before


def test_timestamps_and_poses_are_kept_beside_the_frames(tmp_path) -> None:
    spec = get_sequence("office1")
    with SimulatedSequence(spec) as plain:
        stamps, poses = plain.timestamps.copy(), plain.poses.copy()

    class NoPath:  # a source that can no longer make its camera path: a second reader gets it from the folder
        name, intrinsics = spec.name, None

        def __len__(self) -> int:
            return spec.n_frames

        def close(self) -> None:
            pass

        @property
        def poses(self):
            raise AssertionError("the trajectory was generated again")

        timestamps = poses

    first = CachedFrames(SimulatedSequence(spec), tmp_path)
    assert np.array_equal(first.timestamps, stamps) and np.array_equal(first.poses, poses)
    assert (tmp_path / "trajectory.npz").is_file() and not first.poses.flags.writeable
    second = CachedFrames(NoPath(), tmp_path)
    assert second.timestamps.tobytes() == stamps.tobytes() and second.poses.tobytes() == poses.tobytes()
    (tmp_path / "trajectory.npz").write_bytes(b"broken")  # made again from the source
    assert np.array_equal(CachedFrames(SimulatedSequence(spec), tmp_path).poses, poses)


def test_a_reader_waits_for_the_process_filling_the_folder(tmp_path) -> None:
    """A second CachedFrames of a folder that a writer is filling (here a thread: flock locks open files, so two of
    one process exclude each other like two processes) waits at its first access and then reads the writer's
    frames instead of rendering them beside it; the writer itself never waits."""
    import threading
    import time

    spec = with_camera(get_sequence("office0"), "clean")
    folder = tmp_path / "office0"
    idle = CachedFrames(SimulatedSequence(spec), tmp_path / "never-filled")
    idle.wait_for_writer()  # no writer ever: nothing to wait for
    assert idle.wait_seconds == 0.0
    writer = CachedFrames(SimulatedSequence(spec), folder)
    reader = CachedFrames(SimulatedSequence(spec), folder)
    holding = threading.Event()

    def fill() -> None:
        with writer.filling():
            holding.set()
            for i in range(3):
                if not writer.has(i):
                    writer.frame(i)
            time.sleep(0.5)

    thread = threading.Thread(target=fill)
    try:
        thread.start()
        assert holding.wait(30)
        start = time.perf_counter()
        first = reader.frame(2)  # waits for the writer, then reads its file
        assert time.perf_counter() - start >= 0.4 and reader.wait_seconds >= 0.4
        thread.join()
        assert (writer.renders, reader.renders, reader.reads) == (3, 0, 1)
        assert first.index == 2 and (folder / frame_cache.WRITER_LOCK).is_file()
        again = time.perf_counter()
        reader.frame(1)  # waited once: no second wait
        assert time.perf_counter() - again < 0.4
    finally:
        thread.join()
        for source in (idle, writer, reader):
            source.close()
