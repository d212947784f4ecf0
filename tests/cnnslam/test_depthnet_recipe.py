"""Tests of the shipped network's recipe: what it is made of, and a tiny run of it end to end."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from cnnslam.depthnet.model import ModelConfig
from cnnslam.depthnet.recipe import SHIPPED, run_recipe
from cnnslam.depthnet.weights_io import DEFAULT_MANIFEST, load_weights
from cnnslam.errors import CnnSlamError


def test_the_shipped_recipe_is_the_shipped_network() -> None:
    manifest = json.loads(DEFAULT_MANIFEST.read_text())
    # the shipped weights were made by this recipe (same data, same fit)
    assert manifest["recipe"]["name"] == SHIPPED.name
    assert manifest["recipe"]["generation"]["n_scenes"] == SHIPPED.generation.n_scenes
    assert manifest["steps"] == SHIPPED.fit.steps
    assert ModelConfig.from_dict(manifest["architecture"]) == SHIPPED.fit.model
    gen = SHIPPED.generation
    # training styles only, every room drawn from the domain-randomised mix; the network's architecture unchanged
    assert set(gen.lighting) == {"flat", "lit"} and set(gen.detail) == {"standard", "rich"}
    assert gen.focal_scale[0] < 1.0 < gen.focal_scale[1]
    assert SHIPPED.fit.silog_weight > 0 and SHIPPED.fit.gradient_weight > 0 and SHIPPED.fit.augment.p_camera > 0
    assert load_weights(Path(DEFAULT_MANIFEST).with_suffix(".pt")).config == SHIPPED.fit.model


@pytest.mark.slow
def test_a_tiny_recipe_runs_end_to_end(tmp_path: Path) -> None:
    tiny = replace(
        SHIPPED,
        generation=replace(SHIPPED.generation, n_scenes=2, views_per_scene=2),
        val_scenes=1,
        fit=replace(SHIPPED.fit, steps=2, batch_size=2, warmup_steps=1, val_every=10, checkpoint_every=2, val_frames=2,
                    model=ModelConfig(base_width=8, decoder_min_channels=8, dropout=0.0)),
    )
    result = run_recipe(tiny, tmp_path, render_workers=0, train_progress=False)
    assert result.fit.steps == 2 and result.fit.weights.is_file()
    manifest = json.loads(result.fit.manifest.read_text())
    assert manifest["recipe"]["name"] == SHIPPED.name and manifest["recipe"]["device"] == "cpu"
    assert manifest["data"]["generation"]["train_frames"] == 4
    assert {"generate", "fit"} <= set(manifest["recipe"]["seconds"])
    with pytest.raises(CnnSlamError, match="loader_workers"):
        run_recipe(tiny, tmp_path, loader_workers=0)
