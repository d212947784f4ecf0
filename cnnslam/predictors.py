"""Depth predictors by name: the trained network (:mod:`cnnslam.depthnet.predict`), the development predictor
(:class:`cnnslam.depth.depth_prediction.DegradedGroundTruthPredictor`), a user's predictor class (``"module:Class"``)
or a model file (:class:`cnnslam.depth.model_file.ModelFilePredictor`: ONNX or TorchScript).

Kept apart from :mod:`cnnslam.depth.depth_prediction` (eq. 5, the prediction contract), which the network's module
imports: naming both here, above them, keeps the import graph free of cycles.
"""

from __future__ import annotations

import importlib
from typing import Any

from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor
from cnnslam.depth.model_file import MODEL_FILE_SUFFIXES, ModelFilePredictor, is_model_file_spec
from cnnslam.errors import CnnSlamError

PREDICTOR_KINDS: tuple[str, ...] = ("network", "degraded_ground_truth")
_FORMS = (f"valid predictors: {', '.join(PREDICTOR_KINDS)}, 'package.module:Class' (a predictor class) or a model "
          f"file ({', '.join(MODEL_FILE_SUFFIXES)}, with train_focal in predictor_options or its sidecar)")


def predictor_form(spec: str) -> str:
    """Which form a predictor name has: ``"registered"`` (:data:`PREDICTOR_KINDS`), ``"model_file"`` (by its
    extension: a path or ``"package:path"``) or ``"class"`` (``"package.module:Class"``). :class:`CnnSlamError`
    naming the valid forms otherwise."""
    if not isinstance(spec, str):
        raise CnnSlamError(f"a predictor name must be a string, got {type(spec).__name__}; {_FORMS}")
    if spec in PREDICTOR_KINDS:
        return "registered"
    if is_model_file_spec(spec):
        return "model_file"
    module, sep, attr = spec.partition(":")
    if sep and attr.isidentifier() and all(part.isidentifier() for part in module.split(".")):
        return "class"
    raise CnnSlamError(f"unknown predictor {spec!r}; {_FORMS}")


def _predictor_class(spec: str) -> type:
    module_name, _, attr = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise CnnSlamError(f"predictor {spec!r}: cannot import {module_name!r} ({exc})") from exc
    factory = getattr(module, attr, None)
    if factory is None or not callable(factory):
        raise CnnSlamError(f"predictor {spec!r}: module {module_name!r} has no class {attr!r}")
    return factory


def make_predictor(kind: str = "network", **kwargs: Any) -> Any:
    """A depth predictor by name, built with ``kwargs``:

    - "network": the trained network (``weights``, ``num_threads``, ``jitter_seed`` ... keywords of
      :func:`cnnslam.depthnet.predict.load_predictor`);
    - "degraded_ground_truth": :class:`DegradedGroundTruthPredictor` (development only);
    - "package.module:Class": a user's predictor class, called with ``kwargs``; what it builds must have
      ``predict_raw(rgb)`` and a positive ``train_focal`` (:class:`cnnslam.depth.depth_prediction.DepthPredictor`);
    - a model file, ``path/net.onnx`` or ``package:path/net.pt`` (ONNX or TorchScript):
      :class:`ModelFilePredictor` (``train_focal``, ``train_size``, ``normalisation``, ``class_output``,
      ``num_threads``, ``jitter_seed`` ... keywords; what is not given comes from its sidecar).

    :class:`CnnSlamError` (one line) for an unknown name or a predictor that cannot be built.
    """
    form = predictor_form(kind)
    if kind == "network":
        try:
            from cnnslam.depthnet.predict import load_predictor  # torch: only when asked for
        except ImportError as exc:  # torch or the network package missing
            raise CnnSlamError(f"the depth network cannot be imported ({exc})") from exc
        return load_predictor(**kwargs)
    if kind == "degraded_ground_truth":
        return DegradedGroundTruthPredictor(**kwargs)
    if form == "model_file":
        try:
            return ModelFilePredictor(kind, **kwargs)
        except TypeError as exc:  # an unknown keyword
            raise CnnSlamError(f"predictor {kind!r}: {exc}") from exc
    factory = _predictor_class(kind)
    try:
        predictor = factory(**kwargs)
    except TypeError as exc:
        raise CnnSlamError(f"predictor {kind!r} cannot be built with {kwargs}: {exc}") from exc
    check_predictor(predictor, kind)
    return predictor


def check_predictor(predictor: Any, name: str = "predictor") -> None:
    """:class:`CnnSlamError` unless ``predictor`` has what the SLAM system calls: ``predict_raw`` and a finite
    positive ``train_focal`` (or ``needs_ground_truth`` with ``predict_raw_from_ground_truth``)."""
    raw = "predict_raw_from_ground_truth" if getattr(predictor, "needs_ground_truth", False) else "predict_raw"
    if not callable(getattr(predictor, raw, None)):
        raise CnnSlamError(f"{name}: {type(predictor).__name__} has no {raw}(rgb) method; a depth predictor needs "
                           "predict_raw(rgb) -> depth (H, W) metres [, label_probs] and train_focal")
    focal = getattr(predictor, "train_focal", None)
    try:
        ok = float(focal) > 0 and float(focal) < float("inf")
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise CnnSlamError(f"{name}: {type(predictor).__name__}.train_focal is {focal!r}; a depth predictor needs "
                           "its training focal length in pixels (> 0) for eq. 5")


def check_predictor_spec(spec: Any, options: dict[str, Any] | None = None) -> None:
    """The checks of a predictor name that need no model loaded, for an agent's constructor: the name's form
    (:func:`predictor_form`); for a class that its module imports and has it; for a model file that it exists, has a
    valid extension and that its training focal length is known (``options`` or the sidecar). A predictor object
    passes as it is. The network's weights and the model itself are loaded (and checked further) when the predictor
    is built."""
    if not isinstance(spec, str):
        return
    form = predictor_form(spec)
    if form == "class":
        _predictor_class(spec)
    if form != "model_file":
        return
    from cnnslam.depth.model_file import resolve_contract, resolve_model_path

    opts = dict(options or {})
    path = resolve_model_path(spec)
    resolve_contract(path, **{k: opts.get(k) for k in ("train_focal", "train_size", "normalisation", "class_output")})
