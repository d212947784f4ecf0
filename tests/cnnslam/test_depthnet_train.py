"""Smoke tests of training: a tiny model lowers the loss on a fixed batch; the training command writes weights and a
manifest and resumes from its checkpoint. No rendering: shards are written directly in the on-disk format."""

from __future__ import annotations

import hashlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from cnnslam.depthnet.data import AugmentConfig, RenderedDataset
from cnnslam.depthnet.loss import total_loss
from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig, normalize_rgb
from cnnslam.depthnet.train import TrainConfig, learning_rate, train
from cnnslam.depthnet.weights_io import load_weights
from cnnslam.errors import CnnSlamError

TINY = ModelConfig(trunk_depth=18, base_width=8, decoder_min_channels=8, dropout=0.0)
NYU_64 = [103.77, 103.89, 64.9, 50.5]  # any fixed camera


def write_fake_shard(folder: Path, seed: int, n: int = 4, h: int = 48, w: int = 64) -> None:
    """A shard in the format of cnnslam.depthnet.data.render_shard: a floor (bottom) and a wall (top)."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True)
    rows = np.arange(h)[:, None] * np.ones((1, w))
    depth_m = np.where(rows < h / 2, 3.0, 3.0 - 2.0 * (rows - h / 2) / h)
    rgb = np.zeros((n, h, w, 3), np.uint8)
    rgb[:, : h // 2] = (200, 60, 60)
    rgb[:, h // 2 :] = (60, 60, 200)
    rgb = np.clip(rgb + rng.integers(0, 20, rgb.shape), 0, 255).astype(np.uint8)
    depth = np.broadcast_to(np.round(depth_m * 1000).astype(np.uint16), (n, h, w)).copy()
    depth[:, 0, 0] = 0  # one pixel with no surface
    labels = np.broadcast_to(np.where(rows < h / 2, 1, 0).astype(np.uint8), (n, h, w)).copy()
    labels[:, 0, 0] = 255
    np.save(folder / "rgb.npy", rgb)
    np.save(folder / "depth.npy", depth)
    np.save(folder / "labels.npy", labels)
    np.save(folder / "poses.npy", np.tile(np.eye(4), (n, 1, 1)))
    meta = {
        "format": "cnnslam-depthnet-data-v1", "scene_seed": seed, "style": "fake", "texture_density": 0.5,
        "n_views": n, "camera": "nyu", "intrinsics": NYU_64, "width": w, "height": h, "depth_scale": 1000.0,
        "data_seed": 7, "modes": ["free"] * n, "rejected_views": 0,
    }
    (folder / "meta.json").write_text(json.dumps(meta))


@pytest.fixture()
def fake_data(tmp_path: Path) -> Path:
    root = tmp_path / "data"
    for i in range(2):
        write_fake_shard(root / "train" / f"scene_{10000 + i:06d}", 10000 + i)
    write_fake_shard(root / "val" / f"scene_{510000:06d}", 510000, n=2)
    return root


def test_few_steps_lower_the_loss_on_a_fixed_batch() -> None:
    torch.manual_seed(0)
    net = DepthSemanticNet(TINY).train()
    rng = np.random.default_rng(0)
    top = np.arange(32)[:, None] < rng.integers(8, 24, (2, 1, 1))  # (2, 32, 1): a wall above a floor
    top = np.broadcast_to(top, (2, 32, 32))
    rgb_np = np.where(top[..., None], [200, 60, 60], [60, 60, 200]) + rng.integers(0, 30, (2, 32, 32, 3))
    rgb = torch.from_numpy(rgb_np.astype(np.uint8)).permute(0, 3, 1, 2)
    depth = torch.from_numpy(np.where(top, 3.0, 1.5).astype(np.float32))[:, None]
    labels = torch.from_numpy(np.where(top, 1, 0).astype(np.int64))
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)
    losses = []
    for _ in range(15):
        d, logit = net(normalize_rgb(rgb))
        loss = total_loss(d, logit, depth, labels, 0.5).total
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.6 * losses[0]


def test_learning_rate_schedule() -> None:
    cfg = TrainConfig(steps=1000, warmup_steps=100, lr=1e-3, min_lr=1e-5)
    assert learning_rate(0, cfg) == pytest.approx(1e-5)
    assert learning_rate(100, cfg) == pytest.approx(1e-3)
    assert learning_rate(550, cfg) == pytest.approx(1e-5 + 0.5 * (1e-3 - 1e-5))
    assert learning_rate(1000, cfg) == pytest.approx(1e-5)


def _cfg(root: Path, out: Path, steps: int) -> TrainConfig:
    return TrainConfig(
        data_root=str(root), out_dir=str(out), model=TINY, augment=AugmentConfig(crop=(16, 24)), batch_size=2,
        downsample=2,
        steps=steps, warmup_steps=2, checkpoint_every=3, val_every=4, val_frames=2, log_every=2, lr=2e-3,
    )


def test_train_writes_weights_manifest_log_and_resumes(fake_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    first = train(_cfg(fake_data, out, 4), progress=False)
    assert first.steps == 4
    ckpt = torch.load(out / "checkpoint.pt", weights_only=False)
    assert ckpt["step"] == 4

    seen: list[int] = []
    result = train(_cfg(fake_data, out, 7), progress=False, on_step=lambda s, _: seen.append(s))
    assert seen == [5, 6, 7]  # resumed after step 4, not from scratch
    assert result.steps == 7

    manifest = json.loads(result.manifest.read_text())
    for key in ("data_seed", "steps", "wall_time_s", "validation_heldout_train_split", "train_focal", "train_size",
                "architecture", "training", "data", "parameters"):
        assert key in manifest, key
    assert manifest["steps"] == 7
    assert manifest["data_seed"] == 7
    assert manifest["train_size"] == [32, 24]  # the network works at half the stored resolution
    assert manifest["train_focal"] == pytest.approx((NYU_64[0] + NYU_64[1]) / 4)
    assert ModelConfig.from_dict(manifest["architecture"]) == TINY
    assert manifest["weights_sha256"] == hashlib.sha256(result.weights.read_bytes()).hexdigest()
    for key in ("abs_rel", "rmse", "delta_1_25", "within_10pct", "pixel_accuracy", "mean_iou"):
        assert np.isfinite(manifest["validation_heldout_train_split"][key])

    records = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in records if r["kind"] == "train"] == [2, 4, 6, 7]
    assert any(r["kind"] == "val" for r in records)

    loaded = load_weights(result.weights)
    assert loaded.config == TINY
    assert loaded.train_size == (32, 24)


def test_resumed_run_equals_uninterrupted_run(fake_data: Path, tmp_path: Path) -> None:
    a = tmp_path / "a"
    train(_cfg(fake_data, a, 3), progress=False)
    train(_cfg(fake_data, a, 6), progress=False)
    b = tmp_path / "b"
    train(_cfg(fake_data, b, 6), progress=False)
    wa, wb = load_weights(a / "weights.pt").model.state_dict(), load_weights(b / "weights.pt").model.state_dict()
    for k in wa:
        torch.testing.assert_close(wa[k], wb[k], msg=k)


class _Stop(Exception):
    pass


def test_an_interrupted_run_continues_from_its_checkpoint_and_logs_each_step_once(fake_data: Path,
                                                                                  tmp_path: Path) -> None:
    out = tmp_path / "run"

    def stop_at_5(step: int, loss: float) -> None:
        if step == 5:
            raise _Stop  # killed after step 5: the last checkpoint is step 3, the log reached step 4
    with pytest.raises(_Stop):
        train(_cfg(fake_data, out, 8), progress=False, on_step=stop_at_5)
    assert torch.load(out / "checkpoint.pt", weights_only=False)["step"] == 3
    seen: list[int] = []
    result = train(_cfg(fake_data, out, 8), progress=False, on_step=lambda s, _: seen.append(s))
    assert seen == [4, 5, 6, 7, 8] and result.steps == 8
    records = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [r["step"] for r in records if r["kind"] == "train"] == [2, 4, 6, 8]  # step 4 once, not twice
    uninterrupted = train(_cfg(fake_data, tmp_path / "b", 8), progress=False)
    wa, wb = load_weights(result.weights).model.state_dict(), load_weights(uninterrupted.weights).model.state_dict()
    for k in wa:
        torch.testing.assert_close(wa[k], wb[k], msg=k)


def test_dataset_reads_shards(fake_data: Path) -> None:
    ds = RenderedDataset(fake_data, "train")
    assert len(ds) == 8
    s = ds[5]
    assert s.rgb.shape == (48, 64, 3) and s.rgb.dtype == np.uint8
    assert s.depth.dtype == np.float32 and s.depth[0, 0] == 0.0 and s.depth[1, 1] == pytest.approx(3.0)
    assert s.labels[0, 0] == 255
    assert ds.image_size == (64, 48)
    assert ds.summary()["frames"] == 8
    with pytest.raises(IndexError):
        ds[8]
    half = RenderedDataset(fake_data, "train", downsample=2)
    assert half.image_size == (32, 24) and half[0].rgb.shape == (24, 32, 3)
    assert half.train_focal == pytest.approx(ds.train_focal / 2)


def test_init_weights_starts_a_fine_tune_from_a_trained_network(fake_data: Path, tmp_path: Path) -> None:
    from dataclasses import replace

    from cnnslam.errors import CnnSlamError

    base = train(_cfg(fake_data, tmp_path / "base", 3), progress=False)
    still = dict(lr=1e-9, min_lr=1e-9, warmup_steps=0, steps=1)  # one step that cannot move the weights
    tuned = train(replace(_cfg(fake_data, tmp_path / "tuned", 1), init_weights=str(base.weights), **still),
                  progress=False)
    scratch = train(replace(_cfg(fake_data, tmp_path / "scratch", 1), **still), progress=False)
    w0 = dict(load_weights(base.weights).model.named_parameters())
    w1 = dict(load_weights(tuned.weights).model.named_parameters())
    w2 = dict(load_weights(scratch.weights).model.named_parameters())
    for k in w0:
        torch.testing.assert_close(w1[k], w0[k], atol=1e-6, rtol=0, msg=k)
    assert any(not torch.allclose(w2[k], w0[k]) for k in w0)
    manifest = json.loads(tuned.manifest.read_text())
    assert manifest["training"]["init_weights"] == str(base.weights)
    assert manifest["initialised_from"]["manifest"]["steps"] == 3  # the start's own manifest, for provenance
    assert json.loads(base.manifest.read_text())["initialised_from"] is None
    other = replace(TINY, base_width=16)
    with pytest.raises(CnnSlamError, match="holds a"):
        train(replace(_cfg(fake_data, tmp_path / "bad", 1), model=other, init_weights=str(base.weights)),
              progress=False)


@pytest.mark.slow
def test_loader_processes_give_the_batches_of_the_thread(fake_data: Path, tmp_path: Path) -> None:
    from cnnslam.depthnet.train import _BatchStream

    base = replace(_cfg(fake_data, tmp_path / "run", 3), augment=replace(AugmentConfig(), crop=(16, 24), p_camera=0.5))
    ds = RenderedDataset(fake_data, "train", None, base.downsample)
    one = _BatchStream(base, ds, 0)
    two = _BatchStream(replace(base, loader_workers=2), ds, 0)
    try:
        for _ in range(3):
            for a, b in zip(one.next(), two.next(), strict=True):
                assert torch.equal(a, b)
    finally:
        one.close()
        two.close()


def test_train_config_checks_its_device_and_loss_weights(fake_data: Path, tmp_path: Path) -> None:
    with pytest.raises(CnnSlamError, match="device must be"):
        TrainConfig(device="tpu")
    with pytest.raises(CnnSlamError, match="gradient_weight"):
        TrainConfig(gradient_weight=-1.0)
    if not torch.cuda.is_available():
        with pytest.raises(CnnSlamError, match="no GPU"):
            train(replace(_cfg(fake_data, tmp_path / "run", 1), device="cuda"), progress=False)


def test_scale_invariant_terms_enter_the_logged_loss(fake_data: Path, tmp_path: Path) -> None:
    cfg = replace(_cfg(fake_data, tmp_path / "run", 2), silog_weight=0.5, gradient_weight=0.5)
    result = train(cfg, progress=False)
    manifest = json.loads(result.manifest.read_text())
    assert manifest["training"]["silog_weight"] == 0.5 and manifest["training"]["gradient_weight"] == 0.5
    assert TrainConfig.from_dict(manifest["training"]) == cfg
