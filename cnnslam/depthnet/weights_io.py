"""The weights file of the depth network: architecture, training camera and parameters in one ``torch.save`` file.

Format (a dict, ``format == WEIGHTS_FORMAT``):

- ``config``: :meth:`ModelConfig.to_dict`;
- ``train_focal``: f_tr, the training camera's focal length in pixels at ``train_size``, ``(fx + fy) / 2``;
- ``train_size``: ``[W, H]`` of the training images (the resolution the network's pixel scale belongs to);
- ``state_dict``: parameters in float16 (storage only; loaded as float32), BatchNorm statistics in float32;
- ``meta``: free-form JSON-serialisable facts (data seed, steps, ...); the full manifest is the ``.json`` beside it.

The manifest beside a weights file (``<weights>.json``, as shipped, or ``manifest.json`` in a run folder) records
the file's SHA-256 (``weights_sha256``); :func:`load_weights` checks it (hashing 8 MB takes a few milliseconds) and
refuses a file that differs from its manifest.

A training checkpoint (resumable state) is another format, written by :mod:`cnnslam.depthnet.train`.
"""

from __future__ import annotations

import hashlib
import json
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
MANIFEST_FORMAT = "cnnslam-depthnet-manifest-v1"
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


def file_sha256(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def manifest_path_for(weights: str | Path) -> Path | None:
    """The manifest beside a weights file: ``<weights>.json`` (the shipped ``default.json``) or ``manifest.json`` in
    its folder (a training run); None when neither is a file."""
    weights = Path(weights)
    for candidate in (weights.with_suffix(".json"), weights.with_name("manifest.json")):
        if candidate.is_file():
            return candidate
    return None


def check_weights_checksum(path: str | Path, manifest_path: str | Path | None = None) -> str | None:
    """Compare the SHA-256 of the weights file ``path`` with the ``weights_sha256`` its manifest records
    (``manifest_path``, else the one :func:`manifest_path_for` finds). Returns the checked digest, or None when
    there is no manifest or it records no checksum. Raises :class:`CnnSlamError` when the file differs from its
    manifest or the manifest cannot be read."""
    path = Path(path)
    found = Path(manifest_path) if manifest_path is not None else manifest_path_for(path)
    if found is None:
        return None
    try:
        manifest = json.loads(found.read_text())
    except (OSError, ValueError) as exc:
        raise CnnSlamError(f"cannot read the depth-network manifest {found}: {exc}") from exc
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        return None  # another JSON file beside the weights, not their manifest
    expected = manifest.get("weights_sha256")
    if expected is None:
        return None
    actual = file_sha256(path)
    if actual != expected:
        raise CnnSlamError(
            f"depth-network weights {path} have SHA-256 {actual}, but their manifest {found} records {expected}: "
            "the file was changed after export; restore it or export weights and manifest together "
            "('cnnslam train export')"
        )
    return actual


def load_weights(path: str | Path) -> LoadedWeights:
    """Read a file written by :func:`save_weights`; the model comes back float32 in eval mode. When a manifest
    beside the file records its SHA-256, the file must match it (:func:`check_weights_checksum`)."""
    path = Path(path)
    if not path.is_file():
        raise CnnSlamError(f"no depth-network weights at {path}; train them with 'cnnslam train fit'")
    check_weights_checksum(path)
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


def export_weights(
    weights: str | Path,
    manifest: str | Path,
    weights_dst: str | Path = DEFAULT_WEIGHTS,
    manifest_dst: str | Path | None = None,
) -> dict[str, Any]:
    """Copy a run's weights and manifest to ``weights_dst`` (default: the shipped ``default.pt``) and the manifest
    beside it (``<weights_dst>.json``), the manifest recording the copy's name, size and SHA-256
    (``weights_file``, ``weights_bytes``, ``weights_sha256``). The run's own manifest must match its weights where
    it records a checksum. Returns the manifest written. Raises :class:`CnnSlamError` on a missing or mismatched
    input, before anything is copied."""
    weights, manifest = Path(weights), Path(manifest)
    weights_dst = Path(weights_dst)
    manifest_dst = weights_dst.with_suffix(".json") if manifest_dst is None else Path(manifest_dst)
    for src in (weights, manifest):
        if not src.is_file():
            raise CnnSlamError(f"{src} does not exist: finish 'cnnslam train fit' in {src.parent} first")
    check_weights_checksum(weights, manifest)
    try:
        doc = json.loads(manifest.read_text())
    except ValueError as exc:
        raise CnnSlamError(f"cannot read the depth-network manifest {manifest}: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT:
        raise CnnSlamError(f"{manifest} is not a depth-network manifest (expected format {MANIFEST_FORMAT!r})")
    weights_dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = weights_dst.with_name(weights_dst.name + ".tmp")
    tmp.write_bytes(weights.read_bytes())
    os.replace(tmp, weights_dst)
    doc.update(weights_file=weights_dst.name, weights_bytes=weights_dst.stat().st_size,
               weights_sha256=file_sha256(weights_dst))
    tmp = manifest_dst.with_name(manifest_dst.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    os.replace(tmp, manifest_dst)
    return doc
