"""The shipped depth network as a model file: ONNX or TorchScript, with its sidecar (``<file>.json``: training focal
length, input size, normalisation, outputs), loadable by :class:`cnnslam.depth.model_file.ModelFilePredictor`
without this package.

What is exported is the inference network :class:`cnnslam.depthnet.predict.DepthNetPredictor` runs (batch norms
folded into the convolutions, :func:`fold_batch_norms`) at its fixed input size ``train_size``: input (1, 3, H_tr,
W_tr) float32 ImageNet-normalised RGB (:func:`normalize_rgb`), outputs ``depth`` (1, 1, H_tr, W_tr) metres at the
training focal length and ``logits`` (1, 4, H_tr, W_tr). ONNX through torch's TorchScript-based exporter (opset
:data:`ONNX_OPSET`; it needs the ``onnx`` package), TorchScript through ``torch.jit.trace``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import torch

from cnnslam.depth.model_file import ModelFileContract, model_file_kind, write_sidecar
from cnnslam.depthnet.model import fold_batch_norms
from cnnslam.depthnet.weights_io import DEFAULT_WEIGHTS, file_sha256, load_weights
from cnnslam.errors import CnnSlamError

ONNX_OPSET = 17


@dataclass(frozen=True)
class ExportedModel:
    """One written model file: its path, kind ("onnx" / "torchscript"), sidecar and size in bytes."""

    path: Path
    kind: str
    sidecar: Path
    bytes: int


def export_model_file(out: str | Path, weights: str | Path | None = None) -> ExportedModel:
    """Write the network of ``weights`` (None: the shipped default) to ``out`` as ONNX (``.onnx``) or TorchScript
    (``.pt``, ``.pth``, ``.ts``, ``.torchscript``), and its sidecar ``<out>.json``. The extension is checked and the
    weights loaded before anything is written (:class:`CnnSlamError`)."""
    out = Path(out)
    kind = model_file_kind(out)
    weights = DEFAULT_WEIGHTS if weights is None else Path(weights)
    loaded = load_weights(weights)
    net = fold_batch_norms(loaded.model)
    w, h = loaded.train_size
    example = torch.zeros(1, 3, h, w)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp" + out.suffix)
    with warnings.catch_warnings():  # the tracer's notes on the shape checks, fixed at train_size on purpose
        warnings.simplefilter("ignore")
        try:
            if kind == "onnx":
                torch.onnx.export(net, (example,), str(tmp), dynamo=False, input_names=["rgb"],
                                  output_names=["depth", "logits"], opset_version=ONNX_OPSET)
            else:
                with torch.no_grad():
                    torch.jit.save(torch.jit.trace(net, example), str(tmp))
        except ImportError as exc:  # the ONNX exporter needs the onnx package
            raise CnnSlamError(f"exporting to ONNX needs the onnx package ({exc}); install it: pip install "
                               "'cnnslam[onnx]'") from exc
    tmp.replace(out)
    contract = ModelFileContract(train_focal=loaded.train_focal, train_size=(w, h), normalisation="imagenet",
                                 class_output="logits")
    sidecar = write_sidecar(out, contract, {
        "inputs": {"rgb": f"(1, 3, {h}, {w}) float32, ImageNet-normalised RGB"},
        "outputs": {"depth": f"(1, 1, {h}, {w}) float32 metres at train_focal",
                    "logits": f"(1, 4, {h}, {w}) float32 class scores (softmax not applied)"},
        "exported_from": {"weights_file": weights.name, "weights_sha256": file_sha256(weights)},
        "exporter": f"torch {torch.__version__}" + (f", ONNX opset {ONNX_OPSET}" if kind == "onnx" else ""),
    })
    return ExportedModel(out, kind, sidecar, out.stat().st_size)
