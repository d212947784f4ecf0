"""Training loop of the depth + semantic network: resumable, logged, validated, writing weights and a manifest.

Everything a run does is a function of its :class:`TrainConfig` and the data: the batch of step ``s`` is drawn from
``numpy.random.default_rng((seed, s))`` and the learning rate is a closed-form function of ``s`` (linear warm-up,
then cosine decay), so a run resumed from its checkpoint continues exactly where it stopped.

Files in ``out_dir``: ``checkpoint.pt`` (model, optimiser, step, RNG state; rewritten every ``checkpoint_every``
steps, atomically), ``log.jsonl`` (one JSON object per line: ``{"kind": "train", "step", "loss", "depth",
"semantic", "lr", "elapsed_s"}`` every ``log_every`` steps and ``{"kind": "val", "step", ...metrics}`` at each
validation), and at the end ``weights.pt`` (:mod:`cnnslam.depthnet.weights_io`) and ``manifest.json``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import torch

from cnnslam.depthnet.data import AugmentConfig, RenderedDataset, collate, training_batch
from cnnslam.depthnet.loss import LossTerms, total_loss
from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig, count_parameters, normalize_rgb
from cnnslam.depthnet.weights_io import MANIFEST_FORMAT, file_sha256, load_weights, save_weights
from cnnslam.errors import CnnSlamError
from slamcommon.depth_metrics import aggregate_depth_metrics, depth_metrics
from slamcommon.semantic_metrics import confusion_matrix, metrics_from_confusion

CHECKPOINT_FORMAT = "cnnslam-depthnet-checkpoint-v1"


@dataclass(frozen=True)
class TrainConfig:
    """One training run (defaults: the shipped model's run, sized for about 3 h on 2 shared CPU cores; ours)."""

    data_root: str = "data/depthnet"  # generate_dataset's root, with train/ and val/ shard folders
    out_dir: str = "data/depthnet/run"  # checkpoint, log, weights and manifest
    model: ModelConfig = field(default_factory=ModelConfig)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    batch_size: int = 16
    steps: int = 16_000
    lr: float = 1e-3  # AdamW peak learning rate
    min_lr: float = 1e-5  # end of the cosine decay
    warmup_steps: int = 500  # linear warm-up from lr / 100
    weight_decay: float = 1e-4
    semantic_weight: float = 0.5  # total loss = berHu + semantic_weight * cross-entropy
    depth_space: str = "log"  # berHu on log depth ("log", ours) or on depth ("linear", FCRN); see loss.py
    # Scale-invariant terms added to the depth loss (ours, after Eigen et al. 2014 and MiDaS; see loss.py): 0 = off,
    # the first shipped networks' loss.
    silog_weight: float = 0.0
    gradient_weight: float = 0.0
    grad_clip: float = 5.0  # global gradient-norm clip
    seed: int = 0  # weight init, dropout and the batch stream
    checkpoint_every: int = 250
    val_every: int = 1_000
    val_frames: int = 240  # held-out training-split frames for validation (evenly spaced over the val split)
    log_every: int = 25
    num_threads: int = 2  # torch intra-op threads (the machine's 2 cores)
    # Where the network trains: "cpu" or "cuda" (a GPU, where one is lent; bf16 autocast). The batches are the same
    # on either (drawn on the CPU from (seed, step)); the arithmetic differs in its last bits.
    device: str = "cpu"
    # Processes that read and augment the coming batches ahead of the optimiser (1: one thread, as on 2 cores).
    loader_workers: int = 1
    max_shards: int | None = None  # use only the first shards (smoke tests)
    downsample: int = 2  # the network works at 1 / downsample of the rendered 320x240 (160x120; see model.py)
    # Ours: start from these weights (a file of save_weights, same architecture) instead of a random init, e.g. to
    # fine-tune the shipped network on full images (crop = the image size); None = train from scratch.
    init_weights: str | None = None

    def __post_init__(self) -> None:
        for name in ("batch_size", "steps", "checkpoint_every", "val_every", "log_every", "num_threads"):
            if int(getattr(self, name)) < 1:
                raise CnnSlamError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.device not in ("cpu", "cuda"):
            raise CnnSlamError(f"device must be 'cpu' or 'cuda', got {self.device!r}")
        if self.silog_weight < 0 or self.gradient_weight < 0:
            raise CnnSlamError(f"silog_weight and gradient_weight must be >= 0, got {self.silog_weight}, "
                               f"{self.gradient_weight}")
        if self.depth_space not in ("linear", "log"):
            raise CnnSlamError(f"depth_space must be 'linear' or 'log', got {self.depth_space!r}")
        if not (self.lr > 0 and 0 <= self.min_lr <= self.lr):
            raise CnnSlamError(f"need lr > 0 and 0 <= min_lr <= lr, got lr={self.lr}, min_lr={self.min_lr}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        """Inverse of :meth:`to_dict`."""
        d = dict(data)
        d["model"] = ModelConfig.from_dict(d["model"])
        aug = dict(d["augment"])
        d["augment"] = AugmentConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in aug.items()})
        return cls(**d)


def learning_rate(step: int, cfg: TrainConfig) -> float:
    """Linear warm-up from lr / 100 to lr over ``warmup_steps``, then cosine decay to ``min_lr`` at ``steps``."""
    if step < cfg.warmup_steps:
        return cfg.lr * (0.01 + 0.99 * step / cfg.warmup_steps)
    t = (step - cfg.warmup_steps) / max(1, cfg.steps - cfg.warmup_steps)
    return cfg.min_lr + 0.5 * (cfg.lr - cfg.min_lr) * (1.0 + math.cos(math.pi * min(1.0, t)))


@torch.inference_mode()
def evaluate(
    model: DepthSemanticNet, dataset: RenderedDataset, indices: list[int], batch_size: int = 8
) -> dict[str, float]:
    """Depth and semantic metrics of ``model`` (eval mode, full frames, raw depth) on ``dataset[indices]``, pooled
    over pixels (the shared :mod:`slamcommon` definitions). Keys as the training manifests store them: shares 0..1
    (``delta_1_25``, ``within_10pct`` = the paper's correct depth / 100, ``pixel_accuracy``, ``mean_iou``)."""
    was_training = model.training
    model.eval()
    per_frame = []
    conf = np.zeros((model.config.num_classes, model.config.num_classes + 1), np.int64)
    for start in range(0, len(indices), batch_size):
        rgb, depth, labels = collate([dataset[i] for i in indices[start : start + batch_size]])
        device = next(model.parameters()).device
        pred, logits = model(normalize_rgb(rgb.to(device)))
        pred_np, lab_np = pred[:, 0].float().cpu().numpy(), logits.argmax(1).cpu().numpy()
        for k in range(len(pred_np)):
            per_frame.append(depth_metrics(pred_np[k], depth[k, 0].numpy()))
            conf += confusion_matrix(lab_np[k], labels[k].numpy(), model.config.num_classes)
    model.train(was_training)
    dm, sm = aggregate_depth_metrics(per_frame, "pooled"), metrics_from_confusion(conf)
    return {
        "abs_rel": dm.abs_rel,
        "rmse": dm.rmse,
        "delta_1_25": dm.delta_1_25 / 100.0,
        "within_10pct": dm.percent_correct / 100.0,
        "pixel_accuracy": sm.pixel_accuracy,
        "mean_iou": sm.mean_iou,
        "frames": len(indices),
    }


@dataclass(frozen=True)
class TrainResult:
    """What a finished run wrote and measured."""

    weights: Path
    manifest: Path
    steps: int
    wall_time_s: float
    validation: dict[str, float]


def _atomic_torch_save(obj: Any, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _append_log(path: Path, record: dict[str, Any]) -> None:
    with path.open("a") as f:
        f.write(json.dumps(record) + "\n")


_WORKER_DATASET: RenderedDataset | None = None


def _init_batch_worker(root: str, max_shards: int | None, downsample: int) -> None:
    """Open the training split once per loader process (memory-mapped: the shards are shared, not copied)."""
    global _WORKER_DATASET
    torch.set_num_threads(1)
    _WORKER_DATASET = RenderedDataset(root, "train", max_shards, downsample)


def _batch_in_worker(seed: int, step: int, batch_size: int, augment: AugmentConfig,
                     ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    assert _WORKER_DATASET is not None
    return training_batch(_WORKER_DATASET, np.random.default_rng((seed, step)), batch_size, augment)


class _BatchStream:
    """The batches of steps start, start + 1, ... (each a function of (seed, step) alone), produced ahead of the
    optimiser by one thread or by ``cfg.loader_workers`` processes; the same batches either way."""

    def __init__(self, cfg: TrainConfig, dataset: RenderedDataset, start: int) -> None:
        self.cfg, self.dataset, self.next_step = cfg, dataset, start
        if cfg.loader_workers > 1:
            import multiprocessing

            self.pool: Any = ProcessPoolExecutor(
                cfg.loader_workers, mp_context=multiprocessing.get_context("spawn"), initializer=_init_batch_worker,
                initargs=(cfg.data_root, cfg.max_shards, cfg.downsample))
            self.ahead = 2 * cfg.loader_workers
        else:
            self.pool, self.ahead = ThreadPoolExecutor(max_workers=1), 1
        self.pending: list[Any] = []
        self._fill()

    def _submit(self, step: int) -> Any:
        cfg = self.cfg
        if cfg.loader_workers > 1:
            return self.pool.submit(_batch_in_worker, cfg.seed, step, cfg.batch_size, cfg.augment)
        return self.pool.submit(training_batch, self.dataset, np.random.default_rng((cfg.seed, step)),
                                cfg.batch_size, cfg.augment)

    def _fill(self) -> None:
        while len(self.pending) < self.ahead and self.next_step < self.cfg.steps:
            self.pending.append(self._submit(self.next_step))
            self.next_step += 1

    def next(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        batch = self.pending.pop(0).result()
        self._fill()
        return batch

    def close(self) -> None:
        for fut in self.pending:
            fut.cancel()
        self.pool.shutdown(wait=True)


def _val_indices(n: int, k: int) -> list[int]:
    return sorted({int(i) for i in np.linspace(0, n - 1, min(k, n)).round()})


def _resume_or_start(cfg: TrainConfig, model: DepthSemanticNet, opt: torch.optim.Optimizer, ckpt_path: Path,
                     log_path: Path, resume: bool) -> tuple[int, float, list[dict[str, Any]]]:
    """(step, training seconds, validation history) to go on from: the checkpoint's, with the model, optimiser and
    torch generator restored from it (``resume`` and a checkpoint there; its architecture must be ``cfg.model``);
    otherwise (0, 0.0, []) after removing an old log, the model starting from ``cfg.init_weights`` where given."""
    if resume and ckpt_path.is_file():
        ckpt = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        if ckpt.get("format") != CHECKPOINT_FORMAT:
            raise CnnSlamError(f"{ckpt_path} is not a training checkpoint")
        saved = TrainConfig.from_dict(ckpt["config"])
        if saved.model != cfg.model:
            raise CnnSlamError(f"{ckpt_path} was trained with {saved.model}, not {cfg.model}; use another out_dir")
        model.load_state_dict(ckpt["model"])
        opt.load_state_dict(ckpt["optimizer"])  # its state follows the parameters' device
        torch.set_rng_state(ckpt["torch_rng"])
        _truncate_log(log_path, int(ckpt["step"]))
        return int(ckpt["step"]), float(ckpt["elapsed_s"]), list(ckpt["val_history"])
    if log_path.exists():
        log_path.unlink()
    if cfg.init_weights is not None:
        start = load_weights(cfg.init_weights)
        if start.config != cfg.model:
            raise CnnSlamError(f"{cfg.init_weights} holds a {start.config} network, not the configured "
                               f"{cfg.model}; pass the matching architecture")
        model.load_state_dict(start.model.state_dict())
    return 0, 0.0, []


def _truncate_log(log_path: Path, step: int) -> None:
    """Drop the log's records of steps after ``step`` (those an interrupted run logged after its last checkpoint:
    the resumed run logs them again), and a last line cut short."""
    if not log_path.is_file():
        return
    kept = []
    for line in log_path.read_text().splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue
        if int(record.get("step", 0)) <= step:
            kept.append(line)
    log_path.write_text("".join(f"{line}\n" for line in kept))


def _optimiser_step(cfg: TrainConfig, model: DepthSemanticNet, opt: torch.optim.Optimizer, autocast: Any,
                    batch: tuple[torch.Tensor, ...], step: int) -> tuple[LossTerms, float]:
    """One optimiser step on ``batch`` (rgb, depth, labels) at the schedule's learning rate of ``step``: the loss
    terms (:func:`total_loss`; raises on a non-finite loss) and the learning rate used. Gradients are clipped to
    ``cfg.grad_clip``."""
    rgb, depth, labels = batch
    lr = learning_rate(step, cfg)
    for group in opt.param_groups:
        group["lr"] = lr
    with autocast:
        pred, logits = model(normalize_rgb(rgb))
    terms = total_loss(pred.float(), logits.float(), depth, labels, cfg.semantic_weight, cfg.depth_space,
                       cfg.silog_weight, cfg.gradient_weight)
    if not torch.isfinite(terms.total):
        raise CnnSlamError(f"non-finite loss at step {step}; lower lr (now {lr:.2e})")
    opt.zero_grad(set_to_none=True)
    terms.total.backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
    opt.step()
    return terms, lr


def train(
    cfg: TrainConfig,
    resume: bool = True,
    progress: bool = True,
    on_step: Callable[[int, float], None] | None = None,
) -> TrainResult:
    """Run (or resume) training to ``cfg.steps`` and write weights + manifest into ``cfg.out_dir``.

    resume: continue from ``out_dir/checkpoint.pt`` when it exists (its config must match; the log keeps the records up
    to the checkpoint's step); otherwise start over.
    progress: show a tqdm bar. on_step(step, loss): called after every optimiser step (tests, monitoring).
    """
    from tqdm import tqdm

    torch.set_num_threads(cfg.num_threads)
    out = Path(cfg.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ckpt_path, log_path = out / "checkpoint.pt", out / "log.jsonl"
    train_set = RenderedDataset(cfg.data_root, "train", cfg.max_shards, cfg.downsample)
    val_set = RenderedDataset(cfg.data_root, "val", cfg.max_shards, cfg.downsample)
    if val_set.intrinsics != train_set.intrinsics:
        raise CnnSlamError("the val split was rendered with another camera than the train split")
    val_idx = _val_indices(len(val_set), cfg.val_frames)

    if cfg.device == "cuda" and not torch.cuda.is_available():
        raise CnnSlamError("device 'cuda' asked for, but torch sees no GPU here; use device 'cpu'")
    device = torch.device(cfg.device)
    torch.manual_seed(cfg.seed)
    model = DepthSemanticNet(cfg.model).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    step, elapsed, history = _resume_or_start(cfg, model, opt, ckpt_path, log_path, resume)
    model.train()
    autocast = torch.autocast("cuda", dtype=torch.bfloat16, enabled=cfg.device == "cuda")

    def checkpoint() -> None:
        _atomic_torch_save(
            {
                "format": CHECKPOINT_FORMAT,
                "config": cfg.to_dict(),
                "model": model.state_dict(),
                "optimizer": opt.state_dict(),
                "torch_rng": torch.get_rng_state(),
                "step": step,
                "elapsed_s": elapsed,
                "val_history": history,
            },
            ckpt_path,
        )

    def validate() -> dict[str, float]:
        t0 = time.perf_counter()
        metrics = evaluate(model, val_set, val_idx)
        record = {"kind": "val", "step": step, **metrics, "seconds": round(time.perf_counter() - t0, 1)}
        history.append(record)
        _append_log(log_path, record)
        return metrics

    bar = tqdm(total=cfg.steps, initial=step, disable=not progress, desc="train", dynamic_ncols=True)
    acc = {"loss": 0.0, "depth": 0.0, "semantic": 0.0, "n": 0}
    # the coming batches are read and augmented ahead (a thread, or loader processes) while this step computes;
    # batches depend only on (seed, step), so prefetching changes nothing in the result
    loader = _BatchStream(cfg, train_set, step)
    t_last = time.perf_counter()
    while step < cfg.steps:
        batch = tuple(t.to(device, non_blocking=True) for t in loader.next())
        terms, lr = _optimiser_step(cfg, model, opt, autocast, batch, step)
        step += 1
        now = time.perf_counter()
        elapsed += now - t_last
        t_last = now
        loss = float(terms.total.detach())
        acc["loss"] += loss
        acc["depth"] += float(terms.depth.detach())
        acc["semantic"] += float(terms.semantic.detach())
        acc["n"] += 1
        bar.update(1)
        if on_step is not None:
            on_step(step, loss)
        if step % cfg.log_every == 0 or step == cfg.steps:
            n = acc.pop("n")
            rec = {k: round(v / n, 5) for k, v in acc.items()}
            _append_log(log_path, {"kind": "train", "step": step, **rec, "lr": lr, "elapsed_s": round(elapsed, 1)})
            bar.set_postfix(loss=rec["loss"], depth=rec["depth"], sem=rec["semantic"], lr=f"{lr:.1e}")
            acc = {"loss": 0.0, "depth": 0.0, "semantic": 0.0, "n": 0}
        if step % cfg.val_every == 0 and step < cfg.steps:
            m = validate()
            bar.write(f"step {step}: val abs_rel {m['abs_rel']:.3f} within10 {m['within_10pct']:.3f} "
                      f"pix_acc {m['pixel_accuracy']:.3f}")
            t_last = time.perf_counter()  # validation time is not training time
        if step % cfg.checkpoint_every == 0 or step == cfg.steps:
            checkpoint()
            t_last = time.perf_counter()
    bar.close()
    loader.close()

    if not history or history[-1]["step"] != step:
        validate()
        checkpoint()
    final_val = {k: v for k, v in history[-1].items() if k not in ("kind", "seconds")}
    meta = {"steps": step, "data_seed": train_set.metas[0]["data_seed"]}
    model.to("cpu")
    weights = save_weights(out / "weights.pt", model, train_set.train_focal, train_set.image_size, meta)
    manifest = build_manifest(cfg, model, train_set, val_set, step, elapsed, final_val, weights)
    manifest_path = out / "manifest.json"
    manifest_path.write_text(json.dumps(manifest, indent=2) + "\n")
    return TrainResult(weights, manifest_path, step, elapsed, final_val)


def start_manifest(init_weights: str | None) -> dict[str, Any] | None:
    """Provenance of a fine-tune's start: the weights path, their SHA-256 (the path may be overwritten later, e.g.
    the shipped default) and the manifest found beside them (``<weights>.json``, as shipped, or ``manifest.json`` in
    a run folder; None when there is none), or None for a run from scratch."""
    if init_weights is None:
        return None
    path = Path(init_weights)
    digest = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None
    for candidate in (path.with_suffix(".json"), path.with_name("manifest.json")):
        if candidate.is_file():
            return {"weights": str(init_weights), "sha256": digest, "manifest": json.loads(candidate.read_text())}
    return {"weights": str(init_weights), "sha256": digest, "manifest": None}


def build_manifest(
    cfg: TrainConfig,
    model: DepthSemanticNet,
    train_set: RenderedDataset,
    val_set: RenderedDataset,
    steps: int,
    wall_time_s: float,
    validation: dict[str, Any],
    weights: Path,
) -> dict[str, Any]:
    """The manifest shipped beside the weights: what was trained on what, for how long, and how well."""
    gen = Path(cfg.data_root) / "generation.json"
    return {
        "format": MANIFEST_FORMAT,
        "created_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "weights_file": weights.name,
        "weights_bytes": weights.stat().st_size,
        "weights_sha256": file_sha256(weights),  # load_weights checks the file against it
        "architecture": model.config.to_dict(),
        "parameters": count_parameters(model),
        "train_focal": train_set.train_focal,
        "train_size": list(train_set.image_size),
        "focal_definition": "(fx + fy) / 2 in pixels at train_size",
        "data_seed": train_set.metas[0]["data_seed"],
        "data": {
            "train": train_set.summary(),
            "val": val_set.summary(),
            "generation": json.loads(gen.read_text()) if gen.is_file() else None,
        },
        "steps": steps,
        "wall_time_s": round(wall_time_s, 1),
        "training": cfg.to_dict(),
        "initialised_from": start_manifest(cfg.init_weights),
        "validation_heldout_train_split": validation,
        "validation_test_sequences": None,
        "environment": {"torch": torch.__version__, "python": platform.python_version(), "threads": cfg.num_threads,
                        "device": torch.cuda.get_device_name(0) if cfg.device == "cuda" else platform.processor()
                        or platform.machine(), "loader_workers": cfg.loader_workers},
    }
