"""Tests of the training data: shard rendering (deterministic, training split only), augmentation."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cnnslam.depthnet.data import (
    AugmentConfig,
    GenerationConfig,
    RenderedDataset,
    Sample,
    augment,
    camera_pipeline,
    camera_velocity,
    downsample_ground_truth,
    downsample_rgb,
    generate_dataset,
    half_resolution_arrays,
    jpeg_roundtrip,
    scene_seeds,
    shard_jobs,
    training_batch,
)
from cnnslam.errors import CnnSlamError


def test_split_seeds_are_training_seeds_and_disjoint() -> None:
    train, val = scene_seeds("train", 50), scene_seeds("val", 50)
    assert min(train + val) >= 10_000
    assert not set(train) & set(val)
    with pytest.raises(CnnSlamError):
        scene_seeds("test", 1)


def test_jobs_use_training_styles_only(tmp_path: Path) -> None:
    from sim_envs.scenes.scenegen import TEST_STYLES, TRAIN_STYLES

    jobs = shard_jobs(tmp_path, "train", GenerationConfig(n_scenes=8))
    assert {j.style for j in jobs} == set(TRAIN_STYLES)
    assert not {j.style for j in jobs} & set(TEST_STYLES)


def test_generation_is_deterministic_resumable_and_readable(tmp_path: Path) -> None:
    cfg = GenerationConfig(n_scenes=1, views_per_scene=2, width=64, height=48, data_seed=3)
    a, b = tmp_path / "a", tmp_path / "b"
    (shard_a,) = generate_dataset(a, "train", cfg, workers=0)
    (shard_b,) = generate_dataset(b, "train", cfg, workers=0)
    for name in ("rgb", "depth", "labels", "poses"):
        assert (shard_a / f"{name}.npy").read_bytes() == (shard_b / f"{name}.npy").read_bytes(), name
    meta = json.loads((shard_a / "meta.json").read_text())
    assert meta["scene_seed"] >= 10_000 and meta["camera"] == "nyu" and meta["data_seed"] == 3
    mtime = (shard_a / "rgb.npy").stat().st_mtime_ns
    generate_dataset(a, "train", cfg, workers=0)  # resume: nothing left to do
    assert (shard_a / "rgb.npy").stat().st_mtime_ns == mtime
    ds = RenderedDataset(a, "train")
    assert len(ds) == 2
    s = ds[1]
    assert s.rgb.shape == (48, 64, 3) and s.depth.shape == (48, 64) and s.labels.shape == (48, 64)
    assert (s.depth > 0).mean() > 0.9 and s.labels.max() <= 3
    assert ds.train_focal == pytest.approx((518.8579 + 519.4696) / 2 / 10)  # NYU at 64x48


# sha256 over (poses, depth, labels, rgb) of the SHIPPED recipe's first two training rooms, 3 views at 64x48, per CPU
# (the tests' cpu_label; "unrecorded": the first machine's, whose CPU was not written down), recorded before
# close-range views existed: close_range 0 (the default) must draw and render the same views. On the AMD EPYC both
# differ (numpy's vectorised maths rounds differently there: the likely cause, not isolated)
SHIPPED_ROOM_DIGESTS = {
    "unrecorded": {
        "scene_010000": "8367c1feaec6920250f01ac7ad1e623e7a6cd7da12f3d2319d98a3769c3628aa",
        "scene_010001": "946452064949bae5cb2ff09514a1f3cc7de82cd1095fc91fcc2fc6832898cc03",
    },
    "AMD EPYC, avx2": {
        "scene_010000": "b2d7ce1c93f7687070064e4fd15a22dd2b260d64c4229749c821510a7698de07",
        "scene_010001": "339e9b94731f9c9984dc578e1a3a24f30eb5a638e3b7a7c3a2565692eff0eb7c",
    },
}
# the same rooms' figures, checked on every CPU: mean and mean absolute value of the poses (m), depth mean and standard
# deviation (mm), rgb mean per channel and standard deviation (levels), share of each label (measured on the AMD EPYC)
SHIPPED_ROOM_FIGURES = {
    "scene_010000": [0.32386348, 0.60323811, 1561.2856, 551.82849, 98.905056, 102.83181, 107.52018, 44.28562,
                     0.0071614583, 0.66753472, 0.16384549, 0.16145833],
    "scene_010001": [0.20123417, 0.64713467, 1751.2896, 1030.3588, 128.12804, 114.44021, 100.30653, 41.288654,
                     0.16427951, 0.49631076, 0.30750868, 0.031901042],
}  # fmt: skip
SHIPPED_ROOM_TOLERANCE = [1e-6, 1e-6, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5, 0.005, 0.005, 0.005, 0.005]


def _shard_digest(shard: Path) -> str:
    import hashlib

    h = hashlib.sha256()
    for name in ("poses", "depth", "labels", "rgb"):
        h.update(np.load(shard / f"{name}.npy").tobytes())
    return h.hexdigest()


def _shard_figures(shard: Path) -> list[float]:
    """The figures of SHIPPED_ROOM_FIGURES for one shard."""
    poses = np.load(shard / "poses.npy")
    depth = np.load(shard / "depth.npy").astype(np.float64)
    rgb = np.load(shard / "rgb.npy").astype(np.float64)
    labels = np.load(shard / "labels.npy")
    shares = np.bincount(labels.ravel(), minlength=4)[:4] / labels.size
    return [poses.mean(), np.abs(poses).mean(), depth.mean(), depth.std(), *rgb.reshape(-1, 3).mean(0), rgb.std(),
            *shares]  # fmt: skip


@pytest.mark.slow
def test_the_shipped_recipes_data_bytes_are_unchanged(tmp_path: Path, pinned_bytes) -> None:
    from cnnslam.depthnet.recipe import SHIPPED

    assert SHIPPED.generation.close_range == 0.0
    cfg = replace(SHIPPED.generation, n_scenes=2, views_per_scene=3, width=64, height=48)
    shards = generate_dataset(tmp_path, "train", cfg, workers=0)
    for shard in shards:  # every CPU: the figures, within a tolerance
        off = np.abs(np.subtract(_shard_figures(shard), SHIPPED_ROOM_FIGURES[shard.name])) / SHIPPED_ROOM_TOLERANCE
        assert off.max() <= 1.0, f"{shard.name}: figure {int(off.argmax())} off by {off.max():.1f} tolerances"
    digests = {p.name: _shard_digest(p) for p in shards}
    assert digests == pinned_bytes(digests, SHIPPED_ROOM_DIGESTS, "this test's figure assertions")


@pytest.mark.slow
def test_close_range_views_are_close_deterministic_and_a_share(tmp_path: Path) -> None:
    from cnnslam.depthnet.views import CLOSE_KINDS

    cfg = GenerationConfig(n_scenes=2, views_per_scene=8, width=64, height=48, data_seed=5, close_range=0.5)
    shards = generate_dataset(tmp_path / "a", "train", cfg, workers=0)
    again = generate_dataset(tmp_path / "b", "train", replace(cfg, n_scenes=1), workers=0)
    assert _shard_digest(shards[0]) == _shard_digest(again[0])  # seeded: same room, same bytes
    close = far = 0
    for shard in shards:
        modes = json.loads((shard / "meta.json").read_text())["modes"]
        depth = np.load(shard / "depth.npy").astype(np.float32) / 1000.0
        for mode, d in zip(modes, depth, strict=True):
            median = float(np.median(d[d > 0]))
            if mode in CLOSE_KINDS:
                close += 1
                assert cfg.view.close_median_depth_m[0] <= median <= cfg.view.close_median_depth_m[1]
            else:
                far += 1
                assert median >= cfg.view.min_median_depth_m
    assert close >= 3 and far >= 3  # 16 views, each close with probability 0.5
    with pytest.raises(CnnSlamError, match="close_range"):
        GenerationConfig(close_range=1.5)


def test_focal_scaled_rooms_read_as_the_nominal_camera(tmp_path: Path) -> None:
    cfg = GenerationConfig(n_scenes=1, views_per_scene=1, width=64, height=48, data_seed=3, focal_scale=(1.25, 1.25))
    (shard,) = generate_dataset(tmp_path, "train", cfg, workers=0)
    meta = json.loads((shard / "meta.json").read_text())
    assert meta["focal_scale"] == pytest.approx(1.25)
    ds = RenderedDataset(tmp_path, "train")
    stored = np.load(shard / "depth.npy")[0].astype(np.float32) / 1000.0
    # eq. 5's premise: an image seen at focal 1.25 f_tr must predict D / 1.25 for the nominal camera
    np.testing.assert_allclose(ds[0].depth, stored / 1.25, rtol=1e-6)
    assert ds.train_focal == pytest.approx((518.8579 + 519.4696) / 2 / 10)  # the nominal camera
    assert ds.summary()["focal_scale"] == pytest.approx([1.25, 1.25])
    # a room of the nominal camera draws nothing extra: the first stage's data stay byte for byte the same
    assert GenerationConfig().draw_focal_scale(np.random.default_rng(0)) == 1.0
    with pytest.raises(CnnSlamError, match="focal_scale"):
        GenerationConfig(focal_scale=(1.2, 0.8))


def test_camera_rooms_keep_views_and_ground_truth_and_change_the_images(tmp_path: Path) -> None:
    clean = GenerationConfig(n_scenes=1, views_per_scene=2, width=64, height=48, data_seed=3)
    (shard_c,) = generate_dataset(tmp_path / "c", "train", clean, workers=0)
    kinect = replace(clean, camera_effects=("kinect",))
    (shard_k,) = generate_dataset(tmp_path / "k", "train", kinect, workers=0)
    (shard_k2,) = generate_dataset(tmp_path / "k2", "train", kinect, workers=0)
    assert json.loads((shard_k / "meta.json").read_text())["camera_effects"] == "kinect"
    for name in ("depth", "labels", "poses"):  # the same views: the camera draws from its own generator
        assert (shard_c / f"{name}.npy").read_bytes() == (shard_k / f"{name}.npy").read_bytes(), name
    assert (shard_k / "rgb.npy").read_bytes() == (shard_k2 / "rgb.npy").read_bytes()  # deterministic
    a = np.load(shard_c / "rgb.npy").astype(np.float32)
    b = np.load(shard_k / "rgb.npy").astype(np.float32)
    diff = np.abs(a - b)
    assert diff.mean() > 1.0  # noise, exposure, vignetting, blur
    assert 0.5 < b.mean() / a.mean() < 2.0  # auto-exposure keeps the brightness in range
    with pytest.raises(Exception, match="unknown camera-effects preset"):
        GenerationConfig(camera_effects=("nonsense",))
    with pytest.raises(CnnSlamError, match="at least one"):
        GenerationConfig(camera_effects=())


def test_lit_rooms_keep_views_and_ground_truth_and_change_the_images(tmp_path: Path) -> None:
    flat = GenerationConfig(n_scenes=1, views_per_scene=2, width=64, height=48, data_seed=3)
    (shard_f,) = generate_dataset(tmp_path / "f", "train", flat, workers=0)
    (shard_l,) = generate_dataset(tmp_path / "l", "train", replace(flat, lighting=("lit",)), workers=0)
    assert json.loads((shard_l / "meta.json").read_text())["lighting"] == "lit"
    assert json.loads((shard_f / "meta.json").read_text())["lighting"] == "flat"
    for name in ("depth", "labels", "poses"):  # lamps change the light, not the room or the views drawn
        assert (shard_f / f"{name}.npy").read_bytes() == (shard_l / f"{name}.npy").read_bytes(), name
    a = np.load(shard_f / "rgb.npy").astype(np.float32)
    b = np.load(shard_l / "rgb.npy").astype(np.float32)
    assert np.abs(a - b).mean() > 2.0  # shadows, lamps, highlights
    mixed = replace(flat, lighting=("flat", "lit"))
    assert {mixed.draw_lighting(seed) for seed in range(40)} == {"flat", "lit"}  # one drawn per room
    with pytest.raises(CnnSlamError, match="lighting must name"):
        GenerationConfig(lighting=("candle",))
    with pytest.raises(CnnSlamError, match="mujoco renderer only"):
        GenerationConfig(lighting=("lit",), backend="pyrender")


def test_camera_velocity_within_limits() -> None:
    rng = np.random.default_rng(0)
    twists = np.array([camera_velocity(rng, 0.6, 35.0) for _ in range(200)])
    speed, ang = np.linalg.norm(twists[:, :3], axis=1), np.degrees(np.linalg.norm(twists[:, 3:], axis=1))
    assert speed.max() <= 0.6 and ang.max() <= 35.0 and speed.mean() == pytest.approx(0.3, abs=0.05)
    assert np.abs(twists[:, :3].mean(0)).max() < 0.06  # no preferred direction


def _sample(h: int = 24, w: int = 32) -> Sample:
    yy, xx = np.mgrid[0:h, 0:w]
    rgb = np.stack([xx * 7 % 256, yy * 9 % 256, (xx + yy) % 256], -1).astype(np.uint8)
    depth = (1.0 + 0.1 * xx + 0.001 * yy).astype(np.float32)
    labels = (xx % 4).astype(np.uint8)
    return Sample(rgb, depth, labels)


def test_augment_crops_keep_pixel_scale_and_geometry() -> None:
    s = _sample()
    cfg = AugmentConfig(crop=(16, 20))
    rng = np.random.default_rng(0)
    flips = 0
    for _ in range(20):
        out = augment(s, rng, cfg)
        assert out.rgb.shape == (16, 20, 3) and out.depth.shape == (16, 20) and out.labels.shape == (16, 20)
        # depth values are unchanged, only windowed (and possibly mirrored): neighbours differ by exactly 0.1 m
        step = np.diff(out.depth, axis=1)
        flipped = bool(step[0, 0] < 0)
        flips += flipped
        np.testing.assert_allclose(np.abs(step), 0.1, atol=1e-5)
        np.testing.assert_allclose(np.diff(out.depth, axis=0), 0.001, atol=1e-5)
        # labels follow the same window as depth: depth = 1 + 0.1 x + 0.001 y and label = x % 4
        x = np.floor((out.depth - 1.0) / 0.1 + 1e-3).astype(int)
        np.testing.assert_array_equal(out.labels, x % 4)
    assert 0 < flips < 20


def test_augment_without_photometric_jitter_is_an_exact_crop() -> None:
    s = _sample()
    cfg = AugmentConfig(crop=(24, 32), p_flip=0.0, brightness=(1, 1), contrast=(1, 1), saturation=(1, 1),
                        channel_gain=(1, 1), gamma=(1, 1), p_channel_shuffle=0.0, noise_std=(0, 0), p_blur=0.0)
    out = augment(s, np.random.default_rng(1), cfg)
    np.testing.assert_array_equal(out.rgb, s.rgb)
    np.testing.assert_array_equal(out.depth, s.depth)


def test_training_batch_shapes(tmp_path: Path) -> None:
    class Two:
        def __len__(self) -> int:
            return 2

        def __getitem__(self, i: int) -> Sample:
            return _sample()

    rgb, depth, labels = training_batch(Two(), np.random.default_rng(0), 3, AugmentConfig(crop=(16, 16)))
    assert tuple(rgb.shape) == (3, 3, 16, 16) and str(rgb.dtype) == "torch.uint8"
    assert tuple(depth.shape) == (3, 1, 16, 16) and tuple(labels.shape) == (3, 16, 16)


def test_downsampled_ground_truth_known_values() -> None:
    depth = np.array(
        [[1.0, 1.0, 2.0, 0.0],
         [1.0, 1.02, 2.0, 2.0],
         [3.0, 3.0, 1.0, 1.0],
         [3.0, 3.0, 1.0, 1.5]], np.float32)
    labels = np.array([[0, 0, 1, 255], [0, 0, 1, 1], [2, 2, 3, 3], [2, 2, 3, 1]], np.uint8)
    d, lab = downsample_ground_truth(depth, labels, 2)
    np.testing.assert_allclose(d, [[1.005, 0.0], [3.0, 0.0]], rtol=1e-6)  # a hole and an edge give no gt
    np.testing.assert_array_equal(lab, [[0, 255], [2, 255]])
    with pytest.raises(CnnSlamError):
        downsample_ground_truth(depth[:3], labels[:3], 2)


def test_downsampled_rgb_is_the_block_mean() -> None:
    rgb = np.zeros((4, 6, 3), np.uint8)
    rgb[0::2, 0::2] = 200
    out = downsample_rgb(rgb, 2)
    assert out.shape == (2, 3, 3)
    np.testing.assert_array_equal(out, 50)


def test_camera_pipeline_keeps_geometry_and_is_seeded() -> None:
    s = _sample()
    cfg = AugmentConfig(p_camera=1.0, vignetting=(0.4, 0.4), p_motion_blur=1.0, motion_blur_px=(3.0, 3.0),
                        shot_noise=(0.0, 0.0))
    img = np.full((24, 32, 3), 0.5, np.float32)
    out = camera_pipeline(img, np.random.default_rng(0), cfg)
    assert out.shape == img.shape and out.dtype == np.float32
    # vignetting: the centre keeps its value, the corners lose v = 40 % (blur of a smooth field changes little)
    assert out[12, 16, 0] == pytest.approx(0.5, abs=0.01) and out[0, 0, 0] == pytest.approx(0.3, abs=0.02)
    # a motion blur of a vertical edge spreads it over about its length, keeps the mean
    edge = np.zeros((24, 32, 3), np.float32)
    edge[:, 16:] = 1.0
    flat = replace(cfg, vignetting=(0.0, 0.0))
    blurred = camera_pipeline(edge, np.random.default_rng(3), flat)
    assert blurred.mean() == pytest.approx(edge.mean(), abs=0.02)
    a = augment(s, np.random.default_rng(5), replace(cfg, crop=(24, 32), shot_noise=(0.02, 0.02)))
    b = augment(s, np.random.default_rng(5), replace(cfg, crop=(24, 32), shot_noise=(0.02, 0.02)))
    np.testing.assert_array_equal(a.rgb, b.rgb)  # seeded
    assert a.depth.shape == s.depth.shape and a.labels.shape == s.labels.shape


def test_jpeg_roundtrip_loses_detail_at_low_quality() -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (48, 64, 3)).astype(np.uint8)
    hi, lo = jpeg_roundtrip(img, 95), jpeg_roundtrip(img, 20)
    assert hi.shape == img.shape and hi.dtype == np.uint8
    err_hi = np.abs(hi.astype(int) - img).mean()
    err_lo = np.abs(lo.astype(int) - img).mean()
    assert err_hi < err_lo


def test_half_resolution_copies_are_what_reading_makes(tmp_path: Path) -> None:
    cfg = GenerationConfig(n_scenes=1, views_per_scene=2, width=64, height=48, data_seed=3, focal_scale=(1.2, 1.2))
    (shard,) = generate_dataset(tmp_path, "train", cfg, workers=0)
    for name in ("rgb_d2", "depth_d2", "labels_d2"):
        assert (shard / f"{name}.npy").is_file()
    fast = RenderedDataset(tmp_path, "train", downsample=2)
    arrays = half_resolution_arrays(np.load(shard / "rgb.npy"), np.load(shard / "depth.npy"),
                                    np.load(shard / "labels.npy"), 1.2)
    for name in ("rgb_d2", "depth_d2", "labels_d2"):
        (shard / f"{name}.npy").unlink()  # the same dataset read the slow way: every frame resampled on reading
    slow = RenderedDataset(tmp_path, "train", downsample=2)
    for i in range(2):
        assert fast[i].rgb.shape == (24, 32, 3)
        for field in ("rgb", "depth", "labels"):
            np.testing.assert_array_equal(getattr(fast[i], field), getattr(slow[i], field))
        np.testing.assert_array_equal(arrays["depth_d2"][i], slow[i].depth)


def test_rich_rooms_are_drawn_per_room_and_recorded(tmp_path: Path) -> None:
    mixed = GenerationConfig(detail=("standard", "rich"))
    assert {mixed.draw_detail(seed) for seed in range(40)} == {"standard", "rich"}
    assert GenerationConfig().draw_detail(123) == "standard"  # one option draws nothing
    rich = GenerationConfig(n_scenes=1, views_per_scene=1, width=64, height=48, data_seed=3, detail=("rich",))
    (shard,) = generate_dataset(tmp_path, "train", rich, workers=0)
    assert json.loads((shard / "meta.json").read_text())["detail"] == "rich"
    with pytest.raises(CnnSlamError, match="detail must name"):
        GenerationConfig(detail=("baroque",))
