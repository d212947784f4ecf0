"""A depth network from a model file: ONNX (run through onnxruntime on the CPU) or TorchScript, as a key-frame
depth predictor (the contract of :class:`cnnslam.depth.depth_prediction.DepthPredictor`) with CNN-SLAM eq. 5.

The contract a model file must meet (what ``cnnslam train export-onnx`` writes for the shipped network):

- input: ONE tensor (1, 3, H_tr, W_tr) float32, RGB channels first, at the training size ``train_size`` = (W_tr,
  H_tr); a frame of another size is resized to it first (area averaging when shrinking, bilinear otherwise). Values
  per ``normalisation``: ``"imagenet"`` ((x / 255 - mean) / std with ImageNet's mean and std per channel),
  ``"unit"`` (x / 255) or ``"none"`` (x in [0, 255]).
- first output: metric depth in metres for a camera with the training focal length, planar z, > 0, as (1, 1, h, w),
  (1, h, w) or (h, w) float; any h, w (resized bilinearly to the frame: an output at half the input size is fine).
- optional second output: class scores (1, C, h, w) with C = 4 (:class:`sim_envs.frames.SemanticClass`), as
  ``class_output`` says: ``"logits"`` (softmax applied here) or ``"probabilities"``; ``"none"`` ignores it. Without
  one the key-frames carry no class probabilities (label fusion then has no evidence from them).
- ``train_focal``: f_tr, ``(fx + fy) / 2`` of the training camera in pixels AT ``train_size``; eq. 5 compares it with
  f_cur brought to the same resolution (:meth:`ModelFilePredictor.current_focal`).

Keywords not given are read from the sidecar ``<model file>.json`` (:func:`sidecar_path`; format
:data:`MODEL_FILE_FORMAT`), and ``train_size`` from the model's fixed input shape where it has one. Every check (the
file, its extension, the training focal length, the input and output shapes, on one forward pass of a blank image)
runs when the predictor is built, before any frame.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from cnnslam.depth.depth_prediction import (
    JITTER_STD_ULPS,
    DepthPrediction,
    focal_at_train_size,
    focal_length_adjustment,
    perturb_last_bits,
)
from cnnslam.errors import CnnSlamError
from sim_envs.frames import NUM_CLASSES

MODEL_FILE_FORMAT = "cnnslam-depth-model-v1"
ONNX_SUFFIXES: tuple[str, ...] = (".onnx",)
TORCHSCRIPT_SUFFIXES: tuple[str, ...] = (".pt", ".pth", ".ts", ".torchscript")
MODEL_FILE_SUFFIXES: tuple[str, ...] = ONNX_SUFFIXES + TORCHSCRIPT_SUFFIXES
Normalisation = Literal["imagenet", "unit", "none"]
NORMALISATIONS: tuple[str, ...] = ("imagenet", "unit", "none")
ClassOutput = Literal["logits", "probabilities", "none"]
CLASS_OUTPUTS: tuple[str, ...] = ("logits", "probabilities", "none")
# ImageNet statistics (the usual ResNet input normalisation; the shipped network's too)
IMAGENET_MEAN: tuple[float, float, float] = (0.485, 0.456, 0.406)
IMAGENET_STD: tuple[float, float, float] = (0.229, 0.224, 0.225)
FOCAL_DEFINITION = "(fx + fy) / 2 in pixels at train_size"


def model_file_kind(path: str | Path) -> Literal["onnx", "torchscript"]:
    """``"onnx"`` or ``"torchscript"`` by the file's extension; :class:`CnnSlamError` for another one."""
    suffix = Path(path).suffix.lower()
    if suffix in ONNX_SUFFIXES:
        return "onnx"
    if suffix in TORCHSCRIPT_SUFFIXES:
        return "torchscript"
    raise CnnSlamError(f"depth model file {str(path)!r} has extension {suffix or '(none)'!r}; valid: "
                       f"{', '.join(ONNX_SUFFIXES)} (ONNX), {', '.join(TORCHSCRIPT_SUFFIXES)} (TorchScript)")


def is_model_file_spec(spec: str) -> bool:
    """Whether a predictor name is a model file (by its extension: :data:`MODEL_FILE_SUFFIXES`)."""
    return Path(spec).suffix.lower() in MODEL_FILE_SUFFIXES


def sidecar_path(model: str | Path) -> Path:
    """The sidecar of a model file: ``<model file name>.json`` beside it (``net.onnx`` -> ``net.onnx.json``)."""
    model = Path(model)
    return model.with_name(model.name + ".json")


@dataclass(frozen=True)
class ModelFileContract:
    """What a model file's network expects and returns (see the module docstring).

    train_focal: f_tr, pixels at ``train_size``; train_size: (W, H) of the network's input, or None where the model's
    input shape gives it; normalisation: of the input; class_output: the second output's kind, None = "logits" when
    the model has a second output, "none" otherwise.
    """

    train_focal: float
    train_size: tuple[int, int] | None = None
    normalisation: Normalisation = "imagenet"
    class_output: ClassOutput | None = None

    def __post_init__(self) -> None:
        f = self.train_focal
        if isinstance(f, bool) or not isinstance(f, int | float) or not math.isfinite(f) or f <= 0:
            raise CnnSlamError(f"train_focal must be a finite positive focal length in pixels at train_size, "
                               f"got {f!r}")
        object.__setattr__(self, "train_focal", float(f))
        size = self.train_size
        if size is not None:
            if (not isinstance(size, list | tuple) or len(size) != 2
                    or not all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in size)):
                raise CnnSlamError(f"train_size must be [W, H], two positive integers, got {size!r}")
            object.__setattr__(self, "train_size", (int(size[0]), int(size[1])))
        if self.normalisation not in NORMALISATIONS:
            raise CnnSlamError(f"unknown normalisation {self.normalisation!r}; valid: {', '.join(NORMALISATIONS)}")
        if self.class_output is not None and self.class_output not in CLASS_OUTPUTS:
            raise CnnSlamError(f"unknown class_output {self.class_output!r}; valid: {', '.join(CLASS_OUTPUTS)}")

    def to_dict(self) -> dict[str, Any]:
        """The sidecar's fields (JSON-ready)."""
        doc = asdict(self)
        doc["train_size"] = None if self.train_size is None else list(self.train_size)
        return doc


def write_sidecar(model: str | Path, contract: ModelFileContract, extra: Mapping[str, Any] | None = None) -> Path:
    """Write ``<model>.json`` (:func:`sidecar_path`): the format tag, ``contract``'s fields, the focal-length
    definition and ``extra`` (e.g. where the network came from). Returns its path."""
    path = sidecar_path(model)
    doc = {"format": MODEL_FILE_FORMAT, **contract.to_dict(), "focal_definition": FOCAL_DEFINITION, **(extra or {})}
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2) + "\n")
    os.replace(tmp, path)
    return path


def read_sidecar(model: str | Path) -> dict[str, Any]:
    """The sidecar's contract fields (``{}`` without a sidecar); :class:`CnnSlamError` for an unreadable one."""
    path = sidecar_path(model)
    if not path.is_file():
        return {}
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise CnnSlamError(f"cannot read the depth model's sidecar {path}: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != MODEL_FILE_FORMAT:
        raise CnnSlamError(f"{path} is not a depth model sidecar (expected format {MODEL_FILE_FORMAT!r})")
    return {k: doc[k] for k in ("train_focal", "train_size", "normalisation", "class_output") if k in doc}


def resolve_contract(model: str | Path, **given: Any) -> ModelFileContract:
    """The contract of ``model``: the keywords given (``train_focal``, ``train_size``, ``normalisation``,
    ``class_output``; None = not given) over its sidecar's. :class:`CnnSlamError` when the training focal length is
    in neither."""
    fields = read_sidecar(model)
    fields.update({k: v for k, v in given.items() if v is not None})
    if "train_focal" not in fields:
        raise CnnSlamError(f"depth model {str(model)!r} needs its training focal length: give train_focal (pixels at "
                           f"train_size) in predictor_options, or write it in {sidecar_path(model).name}")
    return ModelFileContract(**fields)


def resolve_model_path(spec: str | Path) -> Path:
    """The file of a model-file predictor name: ``"package:relative/path"`` inside an installed top-level package's
    folder, else a path (relative to the working directory). :class:`CnnSlamError` when it is not a file."""
    import importlib.util

    text = str(spec)
    package, sep, rel = text.partition(":")
    path = Path(text)
    if sep and package.isidentifier() and rel:
        found = importlib.util.find_spec(package)
        roots = list(found.submodule_search_locations or []) if found else []
        if not roots:
            raise CnnSlamError(f"depth model {text!r} names package {package!r}, which is not installed")
        path = Path(roots[0]) / rel
    model_file_kind(path)
    if not path.is_file():
        origin = "" if str(path) == text else f" (from {text!r})"
        raise CnnSlamError(f"no depth model file at {str(path)!r}{origin}; give an existing .onnx or TorchScript "
                           "file, a path or 'package:path'")
    return path


# ------------------------------------------------------------------------------------------------------- back-ends


def _default_threads() -> int:
    """Threads of a forward pass when none are given: ``OMP_NUM_THREADS`` (which limits torch, and which the
    judge's workers set) where it is a positive integer, else 0 (onnxruntime's choice: every physical core)."""
    value = os.environ.get("OMP_NUM_THREADS", "")
    return int(value) if value.isdigit() and int(value) > 0 else 0


class _OnnxBackend:
    """One onnxruntime session on the CPU provider, ``threads`` intra-op threads (0: onnxruntime's default), one
    inter-op thread, sequential execution."""

    def __init__(self, path: Path, threads: int) -> None:
        try:
            import onnxruntime as ort
        except ImportError as exc:
            raise CnnSlamError(f"an ONNX depth model needs onnxruntime ({exc}); install it: pip install "
                               "'cnnslam[onnx]'") from exc
        options = ort.SessionOptions()
        options.intra_op_num_threads = int(threads)
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.log_severity_level = 3  # errors only: its warnings would go to every run's log
        try:
            self.session = ort.InferenceSession(str(path), sess_options=options, providers=["CPUExecutionProvider"])
        except Exception as exc:  # noqa: BLE001 - any unreadable model is reported the same way
            raise CnnSlamError(f"cannot load the ONNX depth model {path}: {_one_line(exc)}") from exc
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise CnnSlamError(f"ONNX depth model {path} has {len(inputs)} inputs "
                               f"({', '.join(i.name for i in inputs)}); it must take one (1, 3, H, W) float image")
        self.input_name = inputs[0].name
        shape = list(inputs[0].shape)
        if len(shape) != 4 or (isinstance(shape[1], int) and shape[1] != 3):
            raise CnnSlamError(f"ONNX depth model {path} takes input of shape {shape}; it must take (1, 3, H, W)")
        if inputs[0].type != "tensor(float)":
            raise CnnSlamError(f"ONNX depth model {path} takes {inputs[0].type}; it must take tensor(float)")
        h, w = shape[2], shape[3]
        self.input_size = (w, h) if isinstance(h, int) and isinstance(w, int) else None  # (W, H)

    def run(self, x: np.ndarray) -> list[np.ndarray]:
        return [np.asarray(o) for o in self.session.run(None, {self.input_name: x})]


class _TorchScriptBackend:
    """A TorchScript module on the CPU, in eval mode; ``threads`` > 0: torch's intra-op threads during its forward
    passes (the process's setting restored after each)."""

    input_size: tuple[int, int] | None = None  # a TorchScript module does not declare its input shape

    def __init__(self, path: Path, threads: int) -> None:
        import torch

        self.threads = int(threads)
        try:
            with warnings.catch_warnings():  # TorchScript is deprecated in torch, still what such files hold
                warnings.simplefilter("ignore", DeprecationWarning)
                self.module = torch.jit.load(str(path), map_location="cpu").eval()
        except Exception as exc:  # noqa: BLE001 - any unreadable model is reported the same way
            raise CnnSlamError(f"cannot load {path} as a TorchScript depth model: {_one_line(exc)}") from exc

    def run(self, x: np.ndarray) -> list[np.ndarray]:
        import torch

        previous = torch.get_num_threads()
        if self.threads > 0:
            torch.set_num_threads(self.threads)
        try:
            with torch.inference_mode():
                out = self.module(torch.from_numpy(x))
        finally:
            if self.threads > 0:
                torch.set_num_threads(previous)
        outs = list(out) if isinstance(out, list | tuple) else [out]
        return [o.detach().numpy() if isinstance(o, torch.Tensor) else np.asarray(o) for o in outs]


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text if len(text) <= 300 else text[:297] + "..."


# ------------------------------------------------------------------------------------------------------- predictor


def _softmax_last(scores: np.ndarray) -> np.ndarray:
    e = np.exp(scores - scores.max(axis=-1, keepdims=True))
    return (e / e.sum(axis=-1, keepdims=True)).astype(np.float32)


class ModelFilePredictor:
    """A depth network in an ONNX or TorchScript file (see the module docstring for the contract).

    path: the model file (``.onnx``; ``.pt``/``.pth``/``.ts``/``.torchscript`` TorchScript); train_focal,
    train_size, normalisation, class_output: the contract (:class:`ModelFileContract`; None = from the sidecar or the
    model). num_threads: intra-op threads of the forward passes (None: ``OMP_NUM_THREADS``, else the runtime's
    default). jitter_seed / jitter_seed_fallback / output_scale: as :class:`cnnslam.depthnet.predict.DepthNetPredictor`
    (perturb the outputs in their last bits, N(0, 2 ulp); scale the depth), so that a method table's seeds work alike.
    """

    def __init__(
        self,
        path: str | Path,
        train_focal: float | None = None,
        train_size: tuple[int, int] | list[int] | None = None,
        normalisation: Normalisation | None = None,
        class_output: ClassOutput | None = None,
        num_threads: int | None = None,
        jitter_seed: int | None = None,
        output_scale: float = 1.0,
        jitter_seed_fallback: int | None = None,
    ) -> None:
        self.path = resolve_model_path(path)
        self.kind = model_file_kind(self.path)
        contract = resolve_contract(self.path, train_focal=train_focal, train_size=train_size,
                                    normalisation=normalisation, class_output=class_output)
        if not (isinstance(output_scale, int | float) and math.isfinite(output_scale) and output_scale > 0):
            raise CnnSlamError(f"output_scale must be a positive number, got {output_scale!r}")
        if num_threads is not None and (not isinstance(num_threads, int) or num_threads < 1):
            raise CnnSlamError(f"num_threads must be an integer >= 1, got {num_threads!r}")
        threads = _default_threads() if num_threads is None else int(num_threads)
        backend: _OnnxBackend | _TorchScriptBackend = (
            _OnnxBackend(self.path, threads) if self.kind == "onnx" else _TorchScriptBackend(self.path, threads))
        size = contract.train_size
        if size is None:
            if backend.input_size is None:
                raise CnnSlamError(f"depth model {self.path} needs its input size: give train_size [W, H] in "
                                   f"predictor_options, or write it in {sidecar_path(self.path).name}")
            size = backend.input_size
        elif backend.input_size is not None and backend.input_size != size:
            raise CnnSlamError(f"depth model {self.path} takes {backend.input_size[0]}x{backend.input_size[1]} "
                               f"images, but train_size is {size[0]}x{size[1]}")
        self._backend = backend
        self.train_focal = contract.train_focal
        self.train_size = (int(size[0]), int(size[1]))
        self.normalisation = contract.normalisation
        self.output_scale = float(output_scale)
        self.num_threads = threads
        self.class_output: ClassOutput = "none"
        self._normalise = self._normaliser(contract.normalisation)
        self.class_output = self._probe(contract.class_output)
        if not jitter_seed:
            jitter_seed = jitter_seed_fallback
        self._jitter = np.random.default_rng(int(jitter_seed)) if jitter_seed else None

    @staticmethod
    def _normaliser(kind: str) -> Callable[[np.ndarray], np.ndarray]:
        if kind == "imagenet":
            mean = np.asarray(IMAGENET_MEAN, np.float32).reshape(3, 1, 1)
            std = np.asarray(IMAGENET_STD, np.float32).reshape(3, 1, 1)
            return lambda x: (x / np.float32(255.0) - mean) / std
        if kind == "unit":
            return lambda x: x / np.float32(255.0)
        return lambda x: x

    def _probe(self, class_output: ClassOutput | None) -> ClassOutput:
        """One forward pass of a grey image at ``train_size``: the outputs must meet the contract. Returns the
        class output's kind."""
        w, h = self.train_size
        try:
            outs = self._backend.run(self._input(np.full((h, w, 3), 128, np.uint8)))
        except CnnSlamError:
            raise
        except Exception as exc:  # noqa: BLE001 - whatever the runtime says about a wrong input, in one line
            raise CnnSlamError(f"depth model {self.path} fails on a (1, 3, {h}, {w}) float32 input: "
                               f"{_one_line(exc)}") from exc
        if not outs:
            raise CnnSlamError(f"depth model {self.path} returns nothing; it must return depth (1, 1, h, w)")
        self._depth_map(outs[0])  # checks the depth output's shape
        if class_output is None:
            class_output = "logits" if len(outs) > 1 else "none"
        if class_output != "none":
            if len(outs) < 2:
                raise CnnSlamError(f"depth model {self.path} returns one output, but class_output is "
                                   f"{class_output!r}; give class_output = 'none' for a depth-only network")
            scores = outs[1]
            if scores.ndim != 4 or scores.shape[0] != 1 or scores.shape[1] != NUM_CLASSES:
                raise CnnSlamError(f"depth model {self.path}'s class output has shape {scores.shape}; it must be "
                                   f"(1, {NUM_CLASSES}, h, w), or give class_output = 'none'")
        return class_output

    def _input(self, rgb: np.ndarray) -> np.ndarray:
        x = np.ascontiguousarray(rgb.transpose(2, 0, 1), dtype=np.float32)
        return np.ascontiguousarray(self._normalise(x)[None], dtype=np.float32)

    def _depth_map(self, out: np.ndarray) -> np.ndarray:
        d = np.asarray(out)
        if d.ndim == 4 and d.shape[:2] == (1, 1):
            d = d[0, 0]
        elif d.ndim == 3 and d.shape[0] == 1:
            d = d[0]
        if d.ndim != 2 or min(d.shape) < 1 or not np.issubdtype(d.dtype, np.floating):
            raise CnnSlamError(f"depth model {self.path}'s first output is {d.dtype} of shape {np.shape(out)}; it "
                               "must be float depth (1, 1, h, w), (1, h, w) or (h, w)")
        return np.ascontiguousarray(d, dtype=np.float32)

    def _forward(self, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        outs = self._backend.run(self._input(rgb))
        depth = self._depth_map(outs[0])
        probs = None
        if self.class_output != "none":
            scores = np.ascontiguousarray(np.asarray(outs[1], dtype=np.float32)[0].transpose(1, 2, 0))
            probs = _softmax_last(scores) if self.class_output == "logits" else scores
        if self._jitter is not None:
            depth = perturb_last_bits(depth, self._jitter, JITTER_STD_ULPS)
            if probs is not None:
                probs = perturb_last_bits(probs, self._jitter, JITTER_STD_ULPS)
        if self.output_scale != 1.0:
            depth = (depth * np.float32(self.output_scale)).astype(np.float32)
        return depth, probs

    def predict_raw(self, rgb: np.ndarray) -> DepthPrediction:
        """The network's output for ``rgb`` ((H, W, 3) uint8, any size), at (H, W), WITHOUT eq. 5: metres for a
        camera with the training focal length. The image is resized to ``train_size`` on the way in (area
        averaging when shrinking, else bilinear) and the outputs bilinearly to (H, W) on the way out."""
        rgb = np.asarray(rgb)
        if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3 or min(rgb.shape[:2]) < 1:
            raise CnnSlamError(f"rgb must be an (H, W, 3) uint8 image, got shape {rgb.shape} dtype {rgb.dtype}")
        h, w = rgb.shape[:2]
        tw, th = self.train_size
        if (w, h) != (tw, th):
            shrink = w * h > tw * th
            rgb = cv2.resize(rgb, (tw, th), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
        depth, probs = self._forward(rgb)
        if depth.shape != (h, w):
            depth = cv2.resize(depth, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float32)
        if probs is not None and probs.shape[:2] != (h, w):
            probs = cv2.resize(probs, (w, h), interpolation=cv2.INTER_LINEAR).reshape(h, w, -1)
            probs = (probs / probs.sum(axis=-1, keepdims=True)).astype(np.float32)
        return DepthPrediction(depth, probs)

    def current_focal(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> float:
        """f_cur of an image of ``image_size`` (H, W) with ``intrinsics`` [fx, fy, cx, cy] (pixels), brought to
        ``train_size``: ``(fx * W_tr / W + fy * H_tr / H) / 2``."""
        return focal_at_train_size(intrinsics, image_size, self.train_size)

    def predict(self, rgb: np.ndarray, intrinsics: np.ndarray) -> DepthPrediction:
        """Depth for THIS camera: the raw output scaled by f_cur / f_tr (CNN-SLAM eq. 5, with the model's training
        focal length), class probabilities unchanged. rgb: (H, W, 3) uint8; intrinsics: [fx, fy, cx, cy] pixels."""
        raw = self.predict_raw(rgb)
        f_cur = self.current_focal(intrinsics, np.asarray(rgb).shape[:2])
        return DepthPrediction(focal_length_adjustment(raw.depth, f_cur, self.train_focal), raw.label_probs)
