"""The weights file of the depth network: architecture, training camera and parameters in one ``torch.save`` file.

Format (a dict, ``format == WEIGHTS_FORMAT``):

- ``config``: :meth:`ModelConfig.to_dict`;
- ``train_focal``: f_tr, the training camera's focal length in pixels at ``train_size``, ``(fx + fy) / 2``;
- ``train_size``: ``[W, H]`` of the training images (the resolution the network's pixel scale belongs to);
- ``state_dict``: parameters in float16 (storage only; loaded as float32), BatchNorm statistics in float32;
- ``meta``: free-form JSON-serialisable facts (data seed, steps, ...); the full manifest is the ``.json`` beside it.

A training checkpoint (resumable state) is another format, written by :mod:`cnnslam.depthnet.train`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig
from cnnslam.errors import CnnSlamError

WEIGHTS_FORMAT = "cnnslam-depthnet-weights-v1"
WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"
DEFAULT_WEIGHTS = WEIGHTS_DIR / "default.pt"
DEFAULT_MANIFEST = WEIGHTS_DIR / "default.json"
_FP32_BUFFERS = ("running_mean", "running_var", "num_batches_tracked")


@dataclass(frozen=True)
class LoadedWeights:
    """A network rebuilt from a weights file, in eval mode, float32 on the CPU, with its training camera."""

    model: DepthSemanticNet
    config: ModelConfig
    train_focal: float
    train_size: tuple[int, int]
    meta: dict[str, Any] = field(default_factory=dict)


def save_weights(
    path: str | Path,
    model: DepthSemanticNet,
    train_focal: float,
    train_size: tuple[int, int],
    meta: dict[str, Any] | None = None,
) -> Path:
    """Write ``model``'s weights (float16 storage) with its config and training camera; atomic (tmp + rename).

    train_focal: pixels at train_size; train_size: (W, H). Returns the path written.
    """
    if not (math.isfinite(train_focal) and train_focal > 0):
        raise CnnSlamError(f"train_focal must be a finite positive focal length in pixels, got {train_focal!r}")
    w, h = (int(v) for v in train_size)
    if w <= 0 or h <= 0:
        raise CnnSlamError(f"train_size must be (W, H) with positive sizes, got {train_size!r}")
    state = {}
    for key, value in model.state_dict().items():
        keep32 = key.endswith(_FP32_BUFFERS) or not value.is_floating_point()
        state[key] = value.detach().cpu().clone() if keep32 else value.detach().cpu().half()
    payload = {
        "format": WEIGHTS_FORMAT,
        "config": model.config.to_dict(),
        "train_focal": float(train_focal),
        "train_size": [w, h],
        "state_dict": state,
        "meta": dict(meta or {}),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)
    return path


def load_weights(path: str | Path) -> LoadedWeights:
    """Read a file written by :func:`save_weights`; the model comes back float32 in eval mode."""
    path = Path(path)
    if not path.is_file():
        raise CnnSlamError(f"no depth-network weights at {path}; train them with 'cnnslam train fit'")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is reported the same way
        raise CnnSlamError(f"cannot read depth-network weights {path}: {exc}") from exc
    if not isinstance(payload, dict) or payload.get("format") != WEIGHTS_FORMAT:
        raise CnnSlamError(f"{path} is not a depth-network weights file (expected format {WEIGHTS_FORMAT!r})")
    config = ModelConfig.from_dict(payload["config"])
    model = DepthSemanticNet(config)
    state = {k: v.float() if v.is_floating_point() else v for k, v in payload["state_dict"].items()}
    model.load_state_dict(state)
    model.eval()
    w, h = payload["train_size"]
    return LoadedWeights(model, config, float(payload["train_focal"]), (int(w), int(h)), dict(payload["meta"]))
