"""Depth predictors by name: the trained network (:mod:`cnnslam.depthnet.predict`) or the development predictor
(:class:`cnnslam.depth.depth_prediction.DegradedGroundTruthPredictor`).

Kept apart from :mod:`cnnslam.depth.depth_prediction` (eq. 5, the prediction contract), which the network's module
imports: naming both here, above them, keeps the import graph free of cycles.
"""

from __future__ import annotations

from typing import Any

from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor
from cnnslam.errors import CnnSlamError

PREDICTOR_KINDS: tuple[str, ...] = ("network", "degraded_ground_truth")


def make_predictor(kind: str = "network", **kwargs: Any) -> Any:
    """A depth predictor by name: "network" (the trained network; ``weights``, ``num_threads`` keywords) or
    "degraded_ground_truth" (:class:`DegradedGroundTruthPredictor`, development only)."""
    if kind == "network":
        try:
            from cnnslam.depthnet.predict import load_predictor  # torch: only when asked for
        except ImportError as exc:  # torch or the network package missing
            raise CnnSlamError(f"the depth network cannot be imported ({exc})") from exc
        return load_predictor(**kwargs)
    if kind == "degraded_ground_truth":
        return DegradedGroundTruthPredictor(**kwargs)
    raise CnnSlamError(f"unknown predictor {kind!r}; valid predictors: {', '.join(PREDICTOR_KINDS)}")
