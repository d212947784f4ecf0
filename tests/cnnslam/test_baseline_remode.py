"""The REMODE baseline (cnnslam.baselines.remode): the filter's seeds at the border and with or without the packed
search, its depth range and configuration, the filter on a rendered sequence with ground-truth poses (textured
surfaces converge to the right depth, a plain wall does not), the agent on the LSD-BS trajectory, and the names its
parts' modules export importable from this one."""

from __future__ import annotations

import dataclasses
import inspect
import json

import cv2
import numpy as np
import pytest

from cnnslam.baselines import remode, remode_search, remode_smoothing
from cnnslam.baselines.remode import (
    CONVERGED,
    UPDATE,
    DepthFilter,
    RemodeAgent,
    RemodeConfig,
    depth_range_of,
    search_image,
)
from cnnslam.errors import CnnSlamError
from sim_envs.driver import run_episode
from sim_envs.env import SlamEnv
from sim_envs.frames import SemanticClass
from sim_envs.sequences import get_sequence
from sim_envs.sources.simsource import SimulatedSequence
from slamcommon.depth_metrics import depth_metrics
from slamcommon.errors import ConfigError

# ------------------------------------------------------------------------------------------------ the filter


def test_a_seed_whose_patch_leaves_the_image_is_never_searched() -> None:
    """Seeds in the ring where a patch would leave the image stay as they were, even when set to UPDATE by hand
    (DepthFilter marks a wider ring BORDER); the others are updated as usual."""
    rng = np.random.default_rng(8)
    ref = cv2.GaussianBlur(rng.integers(0, 256, (40, 56)).astype(np.uint8), (3, 3), 0)
    f = DepthFilter(ref, np.eye(4), np.array([50.0, 50.0, 28.0, 20.0]), (0.5, 4.0))
    f.state[:] = UPDATE
    before = f.b.copy()
    pose = np.eye(4)
    pose[0, 3] = 0.05
    assert f.update(np.roll(ref, -2, axis=1), pose).updated > 0
    ring = np.ones(ref.shape, bool)
    ring[2:-2, 2:-2] = False
    assert np.array_equal(f.b[ring], before[ring]) and np.array_equal(f.mu[ring], np.full(ring.sum(), f.mu[0, 0]))


def test_filter_update_is_the_same_with_and_without_pairs() -> None:
    """Every seed after three updates (the packed sums against the corner-by-corner ones): equal, bit for bit."""
    rng = np.random.default_rng(5)
    ref = cv2.GaussianBlur(rng.integers(0, 256, (48, 64)).astype(np.uint8), (3, 3), 0)
    intr = np.array([60.0, 60.0, 32.0, 24.0])
    filters = [DepthFilter(ref, np.eye(4), intr, (0.5, 4.0)) for _ in range(2)]
    for k, axes in ((2, (1,)), (3, (0,)), (2, (0, 1))):  # the image moved k px left, up, diagonally: 1.5 m away
        pose = np.eye(4)
        shifted = ref
        for axis in axes:
            pose[1 - axis, 3] = 0.025 * k
            shifted = np.roll(shifted, -k, axis=axis)
        with_pairs = search_image(shifted, 5)
        without = dataclasses.replace(with_pairs, pairs=None)
        outcomes = [f.update(image, pose) for f, image in zip(filters, (with_pairs, without), strict=True)]
        assert outcomes[0].updated == outcomes[1].updated and outcomes[0].updated > 0
    for name in ("mu", "sigma2", "a", "b", "state"):
        assert np.array_equal(getattr(filters[0], name), getattr(filters[1], name))
    with pytest.raises(CnnSlamError, match="search_pairs"):
        filters[0].update(dataclasses.replace(with_pairs, pairs=with_pairs.pairs[:, :10]), np.eye(4))


def test_depth_range_of() -> None:
    cfg = RemodeConfig()
    depth = np.zeros((20, 20), np.float32)
    assert depth_range_of(depth, cfg) == cfg.default_depth_range
    depth[:] = np.linspace(1.0, 3.0, 400).reshape(20, 20)
    lo, hi = depth_range_of(depth, cfg)
    assert lo == pytest.approx(np.percentile(depth, 2) / 1.5) and hi == pytest.approx(np.percentile(depth, 98) * 1.5)


def test_config_validation() -> None:
    with pytest.raises(CnnSlamError, match="odd"):
        RemodeConfig(patch_size=4)
    with pytest.raises(ConfigError, match="unknown config key 'patch'; valid keys: patch_size"):
        RemodeConfig().with_overrides({"patch": 5})
    with pytest.raises(CnnSlamError, match="depth_range"):
        DepthFilter(np.zeros((20, 20), np.float32), np.eye(4), np.array([20.0, 20.0, 10.0, 10.0]), (2.0, 1.0))


# ------------------------------------------------------------------------------------------------ rendered


@pytest.fixture(scope="module")
def office_filter():
    """A depth filter on frame 0 of the office0 analogue, updated by frames 1..40 with ground-truth poses."""
    spec = get_sequence("office0").with_frames(41)
    with SimulatedSequence(spec) as seq:
        frames = [seq.frame(i) for i in range(len(seq))]
        intrinsics = seq.intrinsics.as_array()
    ref = frames[0]
    filt = DepthFilter(ref.rgb, ref.T_world_cam, intrinsics, (0.5, 5.0))
    updates = [filt.update(f.rgb, f.T_world_cam) for f in frames[1:]]
    return ref, filt, updates


def test_filter_converges_on_texture_and_not_on_a_plain_wall(office_filter) -> None:
    ref, filt, updates = office_filter
    gray = cv2.cvtColor(ref.rgb, cv2.COLOR_RGB2GRAY).astype(np.float64)
    mean = cv2.blur(gray, (9, 9))
    local_std = np.sqrt(np.maximum(cv2.blur(gray * gray, (9, 9)) - mean**2, 0.0))
    textured = np.isin(ref.labels, [SemanticClass.LARGE_STRUCTURE, SemanticClass.SMALL_STRUCTURE]) & (local_std >= 8)
    wall = (ref.labels == SemanticClass.VERTICAL_STRUCTURE) & (local_std < 2)
    assert textured.mean() > 0.05 and wall.mean() > 0.05  # the view holds both
    depth = filt.depth()
    assert depth.dtype == np.float32
    np.testing.assert_array_equal(depth > 0, filt.state == CONVERGED)  # 0 = not converged
    rel = np.abs(depth - ref.depth) / np.maximum(ref.depth, 1e-6)
    has = depth > 0
    # measured: 64 % of the textured pixels converge, 93 % of those within 10 %; 2 % of the plain wall converges
    assert has[textured].mean() > 0.4
    assert np.mean(rel[textured & has] < 0.1) > 0.85
    assert has[wall].mean() < 0.1
    m = depth_metrics(depth, ref.depth)
    assert m.percent_correct > 25.0 and m.density < 80.0
    assert updates[-1].converged == int(has.sum())
    assert all(u.milliseconds > 0 for u in updates)


def test_filter_without_tv_gives_the_seed_means(office_filter) -> None:
    _, filt, _ = office_filter
    raw = filt.depth(smooth=False)
    conv = filt.converged
    np.testing.assert_allclose(raw[conv], (filt.mu / filt.ray_norm)[conv], rtol=1e-6)
    var = filt.depth_variance()
    assert np.isfinite(var[conv]).all() and np.isinf(var[~conv]).all()


def test_remode_agent_on_the_lsd_bs_trajectory() -> None:
    spec = get_sequence("office0").with_frames(45)
    agent = RemodeAgent(config={"max_updates": 40})
    res = run_episode(SlamEnv(spec=spec), agent, progress=False)
    assert res.uses_ground_truth and res.tracked.all()
    assert len(res.keyframes) >= 1 and res.extras["trajectory"] == "lsd_bs"
    lsd = res.extras["lsd_bs"]
    assert lsd["keyframes"] == len(res.keyframes)
    for kf, gt, stats in zip(res.keyframes, res.keyframe_gt, res.extras["remode_keyframes"], strict=True):
        assert kf.depth.shape == gt.depth.shape and kf.depth.dtype == np.float32
        assert stats["density"] == pytest.approx(float((kf.depth > 0).mean()))
        assert np.isinf(kf.uncertainty[kf.depth == 0]).all()
    first = depth_metrics(res.keyframes[0].depth, res.keyframe_gt[0].depth)
    # LSD-BS's first key-frame has ground-truth scale, so REMODE's depth on it is metric: measured 41 % correct
    assert first.percent_correct > 20.0 and 20.0 < first.density < 90.0
    assert res.extras["remode_ms_per_frame"] > 0
    json.dumps(res.extras)  # JSON-serialisable diagnostics


def test_remode_agent_contract() -> None:
    agent = RemodeAgent()
    assert agent.uses_ground_truth and agent.lsd_config.depth.source == "ground_truth_first"
    with pytest.raises(CnnSlamError, match="reset"):
        agent.step({"rgb": np.zeros((240, 320, 3), np.uint8), "timestamp": np.zeros(1)}, {})
    with pytest.raises(ConfigError, match="RemodeConfig"):
        RemodeAgent(config=3)  # type: ignore[arg-type]
    assert RemodeAgent(seed=5).lsd_config.system.seed == 5


def test_the_parts_public_names_are_importable_from_remode() -> None:
    """Users import the filter's pieces from cnnslam.baselines.remode: every public name of its parts' modules is
    the same object there and listed in its ``__all__``; the agent's entry point names this module."""
    for part in (remode_search, remode_smoothing):
        public = [n for n, v in vars(part).items() if not n.startswith("_") and not inspect.ismodule(v)
                  and getattr(v, "__module__", part.__name__) in (part.__name__, "builtins")]
        assert "tv_smooth" in public or "search_image" in public
        for name in public:
            assert getattr(remode, name) is getattr(part, name), name
            assert name in remode.__all__, name
    assert all(hasattr(remode, name) for name in remode.__all__)
    assert f"{RemodeAgent.__module__}:{RemodeAgent.__name__}" == "cnnslam.baselines.remode:RemodeAgent"
