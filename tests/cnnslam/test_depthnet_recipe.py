"""Tests of the shipped network's recipe: what it is made of, and a tiny run of it end to end."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig
from cnnslam.depthnet.recipe import CLOSE_RANGE, RECIPES, SHIPPED, Recipe, get_recipe, run_recipe
from cnnslam.depthnet.weights_io import DEFAULT_MANIFEST, DEFAULT_WEIGHTS, load_weights, save_weights
from cnnslam.errors import CnnSlamError

TINY_MODEL = ModelConfig(base_width=8, decoder_min_channels=8, dropout=0.0)


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


def test_the_close_range_recipe_fine_tunes_the_shipped_network_on_close_views() -> None:
    assert get_recipe("shipped-v3") is CLOSE_RANGE and set(RECIPES) == {"shipped-v2", "shipped-v3"}
    with pytest.raises(CnnSlamError, match="unknown recipe 'v9'"):
        get_recipe("v9")
    gen = CLOSE_RANGE.generation
    assert 0 < gen.close_range < 1 and SHIPPED.generation.close_range == 0  # close views beside the SHIPPED mix
    assert replace(gen, n_scenes=SHIPPED.generation.n_scenes, data_seed=SHIPPED.generation.data_seed,
                   close_range=0.0) == SHIPPED.generation  # same rooms' mix, cameras, lighting, detail
    assert gen.data_seed != SHIPPED.generation.data_seed  # new views
    assert CLOSE_RANGE.fit.model == SHIPPED.fit.model and CLOSE_RANGE.fit.lr < SHIPPED.fit.lr
    # its start is the network SHIPPED made (the shipped default, or the start of a default exported from it)
    manifest = json.loads(DEFAULT_MANIFEST.read_text())
    made_by_shipped = manifest["recipe"]["name"] == SHIPPED.name
    expected = manifest["weights_sha256"] if made_by_shipped else manifest["initialised_from"]["sha256"]
    assert CLOSE_RANGE.init_sha256 == expected and CLOSE_RANGE.start_weights() == DEFAULT_WEIGHTS


class _Stop(Exception):
    pass


def _tiny_fine_tune(tmp_path: Path) -> Recipe:
    start = tmp_path / "start.pt"
    save_weights(start, DepthSemanticNet(TINY_MODEL), 51.9, (32, 24))
    import hashlib

    return replace(
        CLOSE_RANGE, name="tiny-close",
        generation=replace(CLOSE_RANGE.generation, n_scenes=2, views_per_scene=2, width=64, height=48),
        val_scenes=1, init_weights=str(start), init_sha256=hashlib.sha256(start.read_bytes()).hexdigest(),
        fit=replace(CLOSE_RANGE.fit, steps=6, batch_size=2, val_every=100, checkpoint_every=2, val_frames=2,
                    log_every=1, model=TINY_MODEL),
    )


@pytest.mark.slow
def test_a_recipe_interrupted_while_rendering_or_fitting_continues(tmp_path: Path) -> None:
    recipe, root = _tiny_fine_tune(tmp_path), tmp_path / "root"

    def one_shard_then_stop(it: object, total: int):  # interrupted after the first room
        for k, item in enumerate(it):  # type: ignore[attr-defined]
            yield item
            if k == 0:
                raise _Stop

    with pytest.raises(_Stop):
        run_recipe(recipe, root, render_workers=0, progress=one_shard_then_stop, train_progress=False)
    first = root / "data" / "train" / "scene_010000"
    mtime = (first / "rgb.npy").stat().st_mtime_ns
    assert not (root / "data" / "train" / "scene_010001").exists()

    def stop_at_3(step: int, loss: float) -> None:
        if step == 3:
            raise _Stop  # after step 3: the checkpoint is step 2's

    Path(recipe.init_weights).write_bytes(b"overwritten")  # e.g. an export over the shipped default
    with pytest.raises(_Stop):
        run_recipe(recipe, root, render_workers=0, train_progress=False, on_step=stop_at_3)
    assert (first / "rgb.npy").stat().st_mtime_ns == mtime  # the finished room was kept, not rendered again
    seen: list[int] = []
    result = run_recipe(recipe, root, render_workers=0, train_progress=False, on_step=lambda s, _: seen.append(s))
    assert seen == [3, 4, 5, 6] and result.fit.steps == 6  # went on from the checkpoint, not from step 0
    manifest = json.loads(result.fit.manifest.read_text())
    assert manifest["recipe"]["name"] == "tiny-close" and manifest["recipe"]["init_sha256"] == recipe.init_sha256
    assert manifest["initialised_from"]["sha256"] == recipe.init_sha256
    assert load_weights(root / "start.pt").config == TINY_MODEL  # its own copy of the start, made on the first call
    assert manifest["data"]["generation"]["config"]["close_range"] == CLOSE_RANGE.generation.close_range
    state = json.loads((root / "recipe.json").read_text())
    assert state["seconds"]["generate"] > 0 and state["seconds"]["fit"] > 0  # summed over the three calls
    steps = [json.loads(line)["step"] for line in (root / "run" / "log.jsonl").read_text().splitlines()
             if json.loads(line)["kind"] == "train"]
    assert steps == [1, 2, 3, 4, 5, 6]
    with pytest.raises(CnnSlamError, match="other settings"):  # another recipe's work is not resumed
        run_recipe(replace(recipe, fit=replace(recipe.fit, seed=99)), root, render_workers=0)
    with pytest.raises(CnnSlamError, match="not the recipe's start"):  # (now overwritten)
        run_recipe(recipe, tmp_path / "other", render_workers=0)
