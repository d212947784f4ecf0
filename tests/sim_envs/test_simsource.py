import pickle
from dataclasses import replace

import numpy as np
import pytest

from sim_envs.camera import Intrinsics
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import NO_LABEL, Frame, SemanticClass
from sim_envs.sequences import get_sequence
from sim_envs.source import FrameSource
from sim_envs.sources.simsource import FrameListSource, SimulatedSequence, cached_scene


def _short(name: str, n: int = 60):
    return get_sequence(name).with_frames(n)


def _grad_energy(rgb: np.ndarray) -> float:
    grey = rgb.astype(np.float64).mean(axis=2)
    return float(np.abs(np.diff(grey, axis=0)).mean() + np.abs(np.diff(grey, axis=1)).mean())


def test_a_simulated_sequence_is_a_frame_source_with_ground_truth():
    with SimulatedSequence(_short("office0")) as seq:
        assert isinstance(seq, FrameSource)
        assert len(seq) == 60 and seq.name == "office0" and seq.intrinsics == get_sequence("office0").intrinsics()
        np.testing.assert_allclose(np.diff(seq.timestamps), 1 / 30)
        assert seq.poses.shape == (60, 4, 4) and seq.poses.dtype == np.float64
        f = seq.frame(10)
        assert isinstance(f, Frame) and f.index == 10 and f.timestamp == pytest.approx(10 / 30)
        assert f.rgb.shape == (240, 320, 3) and f.rgb.dtype == np.uint8
        assert f.depth.shape == (240, 320) and f.depth.dtype == np.float32
        assert f.labels.dtype == np.uint8 and f.instances.dtype == np.int32
        np.testing.assert_array_equal(f.T_world_cam, seq.poses[10])
        # indoors: every pixel sees a surface at a plausible distance, labelled with one of the 4 classes
        assert (f.depth > 0.1).all() and f.depth.max() < 15.0
        assert set(np.unique(f.labels)) <= {int(c) for c in SemanticClass}
        np.testing.assert_array_equal(seq.rgb(10), f.rgb)  # the cheap path gives the same bytes
        with pytest.raises(SimEnvError, match="out of range"):
            seq.frame(60)


def test_same_spec_gives_bit_identical_frames_in_any_order():
    a, b = SimulatedSequence(_short("living1")), SimulatedSequence(_short("living1"))
    try:
        fa = [a.frame(i) for i in (3, 40)]
        fb = [b.frame(i) for i in (40, 3)][::-1]
        for x, y in zip(fa, fb, strict=True):
            np.testing.assert_array_equal(x.rgb, y.rgb)
            np.testing.assert_array_equal(x.depth, y.depth)
            np.testing.assert_array_equal(x.labels, y.labels)
        assert not np.array_equal(fa[0].rgb, fa[1].rgb)
    finally:
        a.close()
        b.close()


def test_camera_effects_are_seeded_per_frame_and_spare_the_ground_truth():
    spec = replace(_short("office2", 30), camera_effects="kinect")
    a, b, clean = SimulatedSequence(spec), SimulatedSequence(spec), SimulatedSequence(_short("office2", 30))
    try:
        fa = [a.frame(i) for i in (7, 20)]
        fb = [b.frame(i) for i in (20, 7)][::-1]  # another access order, another process-like instance
        for x, y in zip(fa, fb, strict=True):
            np.testing.assert_array_equal(x.rgb, y.rgb)
        f_clean = clean.frame(7)
        np.testing.assert_array_equal(fa[0].depth, f_clean.depth)  # ground truth has no effects
        np.testing.assert_array_equal(fa[0].labels, f_clean.labels)
        diff = fa[0].rgb.astype(int) - f_clean.rgb.astype(int)
        assert np.abs(diff).mean() > 1.0
        other = SimulatedSequence(replace(spec, seed=99))  # another spec seed gives other noise
        assert not np.array_equal(other.rgb(7), fa[0].rgb)
        other.close()
    finally:
        for s in (a, b, clean):
            s.close()


def test_pickles_before_and_after_use():
    seq = SimulatedSequence(_short("rot_yaw_30"))
    fresh = pickle.loads(pickle.dumps(seq))  # before use: nothing heavy has been made
    assert seq._renderer is None
    rgb = seq.rgb(5)
    used = pickle.loads(pickle.dumps(seq))  # after use: the renderer is dropped and re-created lazily
    assert used._renderer is None
    np.testing.assert_array_equal(fresh.rgb(5), rgb)
    np.testing.assert_array_equal(used.rgb(5), rgb)
    for s in (seq, fresh, used):
        s.close()


def test_pyrender_backend_renders_the_same_room():
    spec = _short("office1", 10)
    with SimulatedSequence(spec, renderer="pyrender") as p, SimulatedSequence(spec, renderer="mujoco") as m:
        fp, fm = p.frame(4), m.frame(4)
        both = (fp.depth > 0) & (fm.depth > 0)
        rel = np.abs(fp.depth[both] - fm.depth[both]) / fm.depth[both]
        assert np.mean(rel < 0.01) > 0.98
        assert np.mean(fp.labels == fm.labels) > 0.98
    with pytest.raises(UnknownNameError, match="mujoco"):
        SimulatedSequence(spec, renderer="povray")


def test_sequence_kinds_show_what_they_promise():
    # close to a textured floor: the view is floor only
    with SimulatedSequence(_short("tum_nostructure_near", 40)) as near:
        for i in (0, 20, 39):
            f = near.frame(i)
            assert np.mean(f.labels == SemanticClass.FLOOR) > 0.97
            assert 0.4 < float(np.median(f.depth)) < 1.1
    # far structure: most of the view is 2-4 m away or more
    with SimulatedSequence(_short("tum_structure_far", 40)) as far:
        assert np.median(far.frame(20).depth) > 1.8
    # a plain wall shows much less texture than the hand-held office views
    with SimulatedSequence(_short("low_texture_wall", 40)) as low, SimulatedSequence(_short("office0", 40)) as hand:
        low_g = np.mean([_grad_energy(low.rgb(i)) for i in (0, 20, 39)])
        hand_g = np.mean([_grad_energy(hand.rgb(i)) for i in (0, 20, 39)])
        assert low_g < 0.5 * hand_g
        assert np.mean(low.frame(20).labels == SemanticClass.VERTICAL_STRUCTURE) > 0.8


def test_scene_cache_returns_one_room_per_key():
    assert cached_scene("office", 1) is cached_scene("office", 1)


def test_frame_list_source_validates():
    intr = Intrinsics(10, 10, 3.5, 2.5, 8, 6)
    f = Frame(0, 0.0, np.zeros((6, 8, 3), np.uint8), np.ones((6, 8), np.float32), np.eye(4))
    src = FrameListSource("x", intr, [f, Frame(1, 0.1, f.rgb, f.depth, np.eye(4), np.full((6, 8), NO_LABEL))])
    assert isinstance(src, FrameSource) and len(src) == 2 and src.frame(1).labels is not None
    with pytest.raises(SimEnvError, match="strictly increasing"):
        FrameListSource("x", intr, [f, f])
    with pytest.raises(SimEnvError, match="frame 0 needs"):
        FrameListSource("x", intr.scaled(16, 12), [f])
    with pytest.raises(SimEnvError, match="empty"):
        FrameListSource("x", intr, [])


def test_a_rich_sequence_shows_more_detail_along_the_same_trajectory_same_bytes():
    standard = _short("office0", 20)
    rich = replace(standard, detail="rich")
    with SimulatedSequence(standard) as a, SimulatedSequence(rich) as b, SimulatedSequence(rich) as again:
        np.testing.assert_array_equal(a.poses, b.poses)  # the standard room's trajectory
        assert b.scene.detail == "rich" and b.scene is cached_scene("office", 1, 1.0, "flat", "rich")
        assert b.scene.free_space(b.poses[:, :3, 3], margin=0.2).all()  # no clutter in the camera's way
        fa, fb = a.frame(10), b.frame(10)
        np.testing.assert_array_equal(fb.rgb, again.frame(10).rgb)
        np.testing.assert_array_equal(fb.depth, again.frame(10).depth)
        assert _grad_energy(fb.rgb) > 1.5 * _grad_energy(fa.rgb)
        assert len(np.unique(fb.instances)) > len(np.unique(fa.instances))
