"""Tests of the one configuration: defaults, validation, overrides, and the ablation / baseline presets."""

from __future__ import annotations

import json

import pytest

from cnnslam.config import (
    ABLATIONS,
    BASELINES,
    CnnSlamConfig,
    TrackingConfig,
    ablation_config,
    baseline_config,
)
from cnnslam.errors import CnnSlamError
from slamcommon.errors import ProjectError


def test_defaults_follow_lsd_slam_constants() -> None:
    cfg = CnnSlamConfig()
    assert cfg.tracking.photometric_variance == 16.0  # cameraPixelNoise2 = 4^2
    assert cfg.tracking.huber_threshold == 1.5  # huber_d / 2
    assert cfg.tracking.min_gradient == 5.0  # minUseGrad
    assert cfg.tracking.max_iterations == (20, 50, 100, 100)  # LSD levels 1..4
    assert (cfg.keyframes.distance_weight, cfg.keyframes.usage_weight) == (4.0, 3.0)
    assert cfg.refinement.max_error_stereo == 1300.0 and cfg.refinement.min_distance_error_stereo == 1.5
    assert (cfg.refinement.min_epl_length, cfg.refinement.max_epl_length) == (3.0, 30.0)
    assert cfg.depth.source == "cnn" and cfg.depth.focal_adjustment and cfg.refinement.enabled
    assert cfg.refinement.density == "dense"


def test_overrides_by_dotted_key_and_keyword() -> None:
    cfg = CnnSlamConfig().with_overrides({"depth.propagation_noise_variance": 0.01}, tracking__huber_threshold=2.0)
    assert cfg.depth.propagation_noise_variance == 0.01
    assert cfg.tracking.huber_threshold == 2.0
    assert CnnSlamConfig().depth.propagation_noise_variance != 0.01  # frozen: the original is unchanged


@pytest.mark.parametrize(
    "overrides, message",
    [
        ({"nosuch.field": 1}, "unknown config key 'nosuch.field'; valid keys: tracking.*, keyframes.*"),
        ({"depth.nosuch": 1}, "valid keys of depth .*: source, focal_adjustment"),
        ({"depth.source": "oracle"}, "'depth.source' must be one of 'cnn', 'constant'"),
        ({"tracking.pyramid_levels": "abc"}, "'tracking.pyramid_levels' must be an integer, got 'abc'"),
        ({"refinement.enabled": "maybe"}, "'refinement.enabled' must be a bool"),
        ({"tracking.max_iterations": (5, 5)}, "one positive count per pyramid level"),
        ({"refinement.min_epl_length": 40.0}, "must not exceed max_epl_length"),
        ({"tracking.huber_threshold": -1.0}, "must be > 0"),
    ],
)
def test_bad_values_are_named(overrides: dict, message: str) -> None:
    with pytest.raises(ProjectError, match=message):  # a type or key (ConfigError) or a range (CnnSlamError)
        CnnSlamConfig().with_overrides(overrides)


def test_tracking_config_validates_alone() -> None:
    with pytest.raises(CnnSlamError, match="finest_level"):
        CnnSlamConfig(tracking=TrackingConfig(finest_level=4))


def test_ablations_of_fig3() -> None:
    assert set(ABLATIONS) == {"raw", "adjusted", "refined"}
    raw, adjusted, refined = (ablation_config(n) for n in ("raw", "adjusted", "refined"))
    assert (raw.depth.focal_adjustment, raw.refinement.enabled) == (False, False)
    assert (adjusted.depth.focal_adjustment, adjusted.refinement.enabled) == (True, False)
    assert (refined.depth.focal_adjustment, refined.refinement.enabled) == (True, True)
    with pytest.raises(CnnSlamError, match="ablation.name"):
        ablation_config("sharpened")  # type: ignore[arg-type]


def test_baselines_are_configurations() -> None:
    assert set(BASELINES) >= {"lsd", "lsd_bs", "cnn_slam"}
    lsd, lsd_bs = baseline_config("lsd"), baseline_config("lsd_bs")
    assert not lsd.depth.uses_cnn and lsd.depth.source == "random" and lsd.refinement.density == "semi_dense"
    assert lsd_bs.depth.source == "ground_truth_first"
    assert baseline_config("cnn_slam") == CnnSlamConfig()
    # brightness: CNN-SLAM (ours) estimates each frame's affine brightness, the LSD baselines track as published
    assert CnnSlamConfig().tracking.affine_brightness
    assert not lsd.tracking.affine_brightness and not lsd_bs.tracking.affine_brightness


def test_to_dict_is_json() -> None:
    text = json.dumps(CnnSlamConfig().to_dict())
    assert '"propagation_noise_variance"' in text
