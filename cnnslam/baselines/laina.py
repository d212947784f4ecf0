"""The "Laina [16]" column of the paper's Table 1: CNN depth used as if it came from an RGB-D sensor, fed to a
depth-based SLAM (point-based fusion [11] with projective ICP tracking), without any refinement.

As the paper ran it (Sec. 4.1: "the CNN-predicted depth maps as input for a state-of-the-art depth-based SLAM method
(point-based fusion [11, 27])"):

- every frame (``cnn_every = 1``, the default) gets a CNN depth map with the focal-length adjustment of eq. 5
  (:func:`cnnslam.depth.depth_prediction.predict_keyframe_depth`) and nothing else: no uncertainty, no refinement, no
  key-frame fusion;
- tracking is frame-to-model, projective point-to-plane ICP coarse to fine (:mod:`cnnslam.model.icp`), against the
global
  model rendered at the previous pose (KinectFusion / Keller et al.), from a constant-velocity guess; a pyramid level
  ends after KinFu's iterations or, earlier, at InfiniTAM's convergence test (``LainaConfig.icp``);
- each tracked frame is fused into the global model (:class:`cnnslam.model.global_model.GlobalModel`, the same model and
  fusion as CNN-SLAM's global model), with the CNN's class probabilities (label fusion comes free); unconfirmed
  surfels are pruned (Keller's unstable points);
- the baseline has no pose graph and no loop closure.

Key-frames (what the paper scored for this column): a tracked frame with a CNN prediction becomes a key-frame
every ``keyframe_every`` frames, or earlier when the camera moved ``keyframe_translation`` metres or
``keyframe_rotation_deg`` degrees from the last key-frame; it reports the CNN depth of that frame (eq. 5 applied),
its tracked pose and the CNN's class probabilities.

Option ``cnn_every = k > 1`` (ours, to save CPU): the CNN runs on every k-th frame only. Frames in between have no
depth, so ICP cannot track them; they are tracked photometrically (:func:`cnnslam.track.tracking.track_frame`,
LSD-SLAM's
direct alignment) against the last predicted frame: its image with its CNN depth ("the last prediction's model"),
and they are not fused.

Option ``icp_downsample = 2`` (ours, to save CPU): ICP at the network's own 160x120 for 320x240 frames (the CNN depth
area-averaged back to it, the model rendered at it): 30.1 -> 35.7 fps in the Table-1 suite, but its ATE leaves the
seed spread of the default (``LainaConfig.icp_downsample``), so the Table-1 column keeps 1.

Speed (one core): the per-pixel work of every frame (the model rendered for ICP, the surface pyramids, the ICP
normal equations, and the measurements, association and merging of the fusion) runs in numba kernels: ICP's in
:mod:`cnnslam.model.icp` (the one ICP, its compiled path), the model's in :mod:`cnnslam.model.surfel_kernels` (the
global
model's only implementation, shared with CNN-SLAM);
with the convergence test the agent takes 53-59 instead of 142-162 ms per frame (200 frames of office0, living1 and
tum_long_office, 3 seeds, one core; about 23 ms of it is the network).

``"cnnslam.baselines.laina:LainaAgent"`` uses the trained network and sees only observations.
``"cnnslam.baselines.laina:GroundTruthAidedLainaAgent"`` is a DEVELOPMENT tool (``uses_ground_truth = True``): its
default predictor is :class:`cnnslam.depth.depth_prediction.DegradedGroundTruthPredictor`, which imitates the CNN from
the
frame's ground-truth depth and labels; ground truth reaches nothing else (never the poses).

Keyword arguments (both classes; all optional)::

    LainaAgent(config={"cnn_every": 1, "icp.max_distance": 0.1, "model.voxel_size": 0.02, ...} | LainaConfig,
               predictor="network" | "degraded_ground_truth" | <an object with predict_raw / train_focal>,
               predictor_options={...})
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from cnnslam.baselines.base import BaselineAgent
from cnnslam.config import TrackingConfig
from cnnslam.depth.depth_prediction import GroundTruthHint, predict_keyframe_depth
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import orthonormalize, pyramid_intrinsics, rotation_angle_deg, se3_inverse
from cnnslam.model.global_model import GlobalModel, GlobalModelConfig
from cnnslam.model.icp import IcpConfig, depth_pyramid, icp_point_to_plane, reference_pyramid
from cnnslam.predictors import make_predictor
from cnnslam.track.tracking import build_image_pyramid, build_tracking_reference, to_gray, track_frame
from slamcommon.config import Configurable, configure


@dataclass(frozen=True)
class LainaConfig(Configurable):
    """The Laina baseline's settings; nested sections ``icp``, ``model`` and ``tracking`` keep their own sources."""

    # Paper [16]: the CNN on every frame. Ours: k > 1 runs it every k-th frame (module docstring).
    cnn_every: int = 1
    # Eq. 5: the CNN depth rescaled by f_cur / f_tr (the paper's Laina column uses the adjusted CNN depth).
    focal_adjustment: bool = True
    # Ours: key-frames about as often as CNN-SLAM makes them on the simulated sequences (one per second at 30 Hz) ...
    keyframe_every: int = 30
    # ... or earlier after this much motion since the last key-frame (metres, degrees).
    keyframe_translation: float = 0.25
    keyframe_rotation_deg: float = 15.0
    # Projective point-to-plane ICP. KinectFusion's gates (10 cm, 20 deg) are for a Kinect's ~1 cm noise; ours for
    # CNN depth, which flickers by several per cent between frames: 20 cm, 30 deg, no pre-smoothing (it shifts the
    # blurred CNN edges), and "lost" only below 5 % inliers or above 15 cm RMS residual. KinFu's iterations (10, 5, 4
    # from fine to coarse) are at most; a level stops once the Gauss-Newton step is short: InfiniTAM's test
    # (ITMDepthTracker::HasConverged with its default ICP setting minstep=1e-3: |xi| / 6 < 1e-3), i.e. |xi| < 6e-3
    # (metres and radians together). On office0 (200 frames) it leaves 1.1 iterations of 10 on the finest level and
    # changes the ATE by less than the run-to-run spread.
    icp: IcpConfig = field(default_factory=lambda: IcpConfig(max_distance=0.2, max_normal_angle_deg=30.0,
                                                             min_inlier_share=0.05, max_rmse=0.15,
                                                             smoothing_px=0.0, convergence=6e-3))
    # Ours, to save CPU (like cnn_every): ICP's finest level is the camera image shrunk by this factor (1, the default:
    # the camera's own pixels; 2: the network's output resolution for 320x240 frames, whose 160x120 depth is
    # up-sampled to the image): the current depth area-averaged to it, the model rendered at it, the pyramid's levels
    # from there. Measured with 2 (Table-1 suite, 9 sequences x 3 seeds, 2-core EPYC): 30.1 -> 35.7 fps end to end
    # (medians), but the ATE moves out of the seed spread on the steady sequences (tum_structure_far 0.337 -> 0.352 m,
    # office1 0.553 -> 0.696 m; ATE and correct-depth medians inside the old runs' range on 3 of 9 sequences each): not
    # the Table-1 protocol.
    icp_downsample: int = 1
    # The global model; ours: every 2nd pixel at frame rate (CPU), CNN depth sigma 10 % of depth, association up to
    # 30 cm (the CNN's frame-to-frame flicker at 3 m), so that the model averages the flicker instead of layering it;
    # at frame rate a surface is seen 30 times a second, so a surfel in view that is not confirmed (also when the
    # measurement is up to 15 cm in front of it, a duplicate layer) is removed after 2 misses.
    model: GlobalModelConfig = field(default_factory=lambda: GlobalModelConfig(
        pixel_stride=2, default_relative_sigma=0.1, max_association_distance=0.3, miss_margin=-0.15))
    # Keller: unstable points (confidence below this after prune_min_age frames) are removed, every prune_every
    # frames (ours: c_stable of about 3 frames seen near the image centre, after 1 s).
    prune_every: int = 30
    prune_min_confidence: float = 2.0
    prune_min_age: int = 30
    # Keller: only stable surfels (confidence at least this; 0 = all) are rendered for ICP, so that unconfirmed
    # surfels (the CNN's flicker) in front of the surface do not hide it ...
    render_min_confidence: float = 3.0
    # ... once they cover this share of the image (ours; all surfels before: the image centre becomes stable first,
    # and a centre-only reference may leave a direction unconstrained; with the development predictor the stable
    # part covers 75-90 % of the image after 10 frames).
    stable_min_coverage: float = 0.7
    # LSD-SLAM's direct tracking, for the frames between CNN predictions when cnn_every > 1 ...
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    # ... with the CNN depth's variance taken as (r d)^2 (ours, FCRN's rel error 0.127 rounded down).
    photometric_relative_sigma: float = 0.1

    def __post_init__(self) -> None:
        if self.icp_downsample not in (1, 2, 4, 8):
            raise CnnSlamError(f"laina.icp_downsample must be 1, 2, 4 or 8, got {self.icp_downsample!r}")
        for name in ("cnn_every", "keyframe_every", "prune_every"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise CnnSlamError(f"laina.{name} must be an integer >= 1, got {value!r}")
        for name in ("keyframe_translation", "keyframe_rotation_deg", "photometric_relative_sigma"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CnnSlamError(f"laina.{name} must be positive, got {value!r}")
        if not 0 <= self.stable_min_coverage <= 1:
            raise CnnSlamError(f"laina.stable_min_coverage must be in [0, 1], got {self.stable_min_coverage}")
        if self.prune_min_confidence < 0 or self.prune_min_age < 0 or self.render_min_confidence < 0:
            raise CnnSlamError("laina.prune_min_confidence, prune_min_age and render_min_confidence must be >= 0")


def area_downsample_depth(depth: np.ndarray, factor: int) -> np.ndarray:
    """(H / factor, W / factor) float32: each ``factor`` x ``factor`` block's mean over its valid depths (> 0, finite;
    metres, planar z), 0 where a block has none. Pixel centres follow :func:`cnnslam.geometry.pyramid_intrinsics`."""
    d = np.asarray(depth, dtype=np.float32)
    h, w = d.shape
    if h % factor or w % factor:
        raise CnnSlamError(f"a depth map of {d.shape} cannot be shrunk by {factor}")
    valid = d > 0  # NaN compares False
    if valid.all():
        return cv2.resize(d, (w // factor, h // factor), interpolation=cv2.INTER_AREA)
    blocks = np.where(valid, d, 0.0).reshape(h // factor, factor, w // factor, factor)
    count = valid.reshape(blocks.shape).sum(axis=(1, 3))
    mean = blocks.sum(axis=(1, 3), dtype=np.float64) / np.maximum(count, 1)
    return np.where(count > 0, mean, 0.0).astype(np.float32)


@dataclass
class _PhotometricReference:
    """The last predicted frame, for direct tracking of the frames in between (cnn_every > 1)."""

    reference: Any
    T_world_ref: np.ndarray


class LainaAgent(BaselineAgent):
    """Laina et al. [16] + point-based fusion [11] as a ``sim_envs`` agent (see the module docstring)."""

    uses_ground_truth = False
    name = "laina"
    default_predictor = "network"

    def __init__(self, config: LainaConfig | dict[str, Any] | None = None, predictor: str | Any | None = None,
                 predictor_options: dict[str, Any] | None = None) -> None:
        super().__init__()
        self.config = configure(LainaConfig(), config)
        self._predictor_spec = self.default_predictor if predictor is None else predictor
        if (isinstance(self._predictor_spec, str) and self._predictor_spec == "degraded_ground_truth"
                and not self.uses_ground_truth):
            raise CnnSlamError("the 'degraded_ground_truth' predictor needs ground truth: use "
                               "cnnslam.baselines.laina:GroundTruthAidedLainaAgent")
        self._predictor_options = dict(predictor_options or {})
        self._predictor: Any = None
        self._model: GlobalModel | None = None

    @property
    def predictor(self) -> Any:
        """The depth predictor, built on first use (the network's weights are loaded lazily)."""
        if self._predictor is None:
            spec = self._predictor_spec
            self._predictor = make_predictor(spec, **self._predictor_options) if isinstance(spec, str) else spec
        return self._predictor

    @property
    def global_model(self) -> GlobalModel:
        """The model fused from every tracked predicted frame of the current episode."""
        if self._model is None:
            raise CnnSlamError("no episode yet: call reset() first")
        return self._model

    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        k = intrinsics
        scale = self.config.icp_downsample
        if image_size[0] % scale or image_size[1] % scale:
            raise CnnSlamError(f"laina.icp_downsample = {scale} needs an image size divisible by it, got {image_size}")
        self._icp_intrinsics = k.copy() if scale == 1 else pyramid_intrinsics(k, int(math.log2(scale)))
        self._icp_size = (image_size[0] // scale, image_size[1] // scale)
        self._model = GlobalModel(self.config.model)
        self._T_world_prev: np.ndarray | None = None
        self._velocity = np.eye(4)  # T_prev_cur of the last tracked motion
        self._keyframes: list[Any] = []
        self._last_kf: tuple[int, np.ndarray] | None = None  # (frame, T_world_kf)
        self._photometric: _PhotometricReference | None = None
        self._model_sizes: list[tuple[int, int, int]] = []  # (frame, surfels, bytes) every 100 frames
        self._counters = {"lost": 0, "predicted": 0, "fused": 0, "pruned": 0, "photometric": 0}
        self._seconds = {"prediction": 0.0, "icp": 0.0, "render": 0.0, "fusion": 0.0, "photometric": 0.0}

    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        """One frame: predict (every ``cnn_every``-th), track (ICP or photometric), fuse, maybe a key-frame; the
        development predictor's ground truth (``info``) is read only with ``uses_ground_truth``."""
        assert self._model is not None  # the base calls _track after _start only
        hint = GroundTruthHint.from_info(info) if self.uses_ground_truth else None
        cfg = self.config
        rgb = np.asarray(observation["rgb"])
        stamp = timestamp
        frame = len(self._tracked)  # this frame's index in the episode
        predicted = frame % cfg.cnn_every == 0
        pred = None
        if predicted:
            t0 = time.perf_counter()
            pred = predict_keyframe_depth(self.predictor, rgb, self._intrinsics, cfg.focal_adjustment, hint)
            self._seconds["prediction"] += time.perf_counter() - t0
            self._counters["predicted"] += 1

        if self._T_world_prev is None:  # the first frame (with a prediction) is the world origin
            T_world_cur, tracked = np.eye(4), pred is not None
        else:
            T_world_pred = orthonormalize(self._T_world_prev @ self._velocity)
            if pred is not None:
                T_world_cur, tracked = self._track_icp(pred.depth, T_world_pred)
            else:
                T_world_cur, tracked = self._track_photometric(rgb, T_world_pred)
        if tracked:
            if self._T_world_prev is not None:
                self._velocity = orthonormalize(se3_inverse(self._T_world_prev) @ T_world_cur)
            self._T_world_prev = T_world_cur
        else:  # lost: report the prediction, but try the next frame from the last tracked pose, at rest
            self._counters["lost"] += 1
            self._velocity = np.eye(4)

        if pred is not None and tracked:
            t0 = time.perf_counter()
            self._model.integrate(pred.depth, T_world_cur, self._intrinsics, rgb, pred.label_probs)
            self._counters["fused"] += 1
            if self._model.integrations % cfg.prune_every == 0:
                self._counters["pruned"] += self._model.prune(cfg.prune_min_confidence, cfg.prune_min_age)
            self._seconds["fusion"] += time.perf_counter() - t0
            if cfg.cnn_every > 1:
                pyramid = build_image_pyramid(to_gray(rgb), self._intrinsics, cfg.tracking.pyramid_levels)
                variance = (cfg.photometric_relative_sigma * pred.depth) ** 2
                self._photometric = _PhotometricReference(
                    build_tracking_reference(pyramid, pred.depth, variance, cfg.tracking), T_world_cur.copy())
            if self._is_keyframe(frame, T_world_cur):
                from sim_envs.agent import KeyframeDepth

                self._keyframes.append(KeyframeDepth(timestamp=stamp, depth=pred.depth.copy(),
                                                     T_world_cam=T_world_cur.copy(), uncertainty=None,
                                                     labels=pred.label_probs))
                self._last_kf = (frame, T_world_cur.copy())
        if frame % 100 == 0:
            self._model_sizes.append((frame, len(self._model), self._model.nbytes))
        return T_world_cur, bool(tracked)

    def _track_icp(self, depth: np.ndarray, T_world_pred: np.ndarray) -> tuple[np.ndarray, bool]:
        """Frame-to-model ICP of the CNN depth against the model rendered at the previous pose."""
        cfg = self.config
        assert self._T_world_prev is not None and self._model is not None
        t0 = time.perf_counter()
        icp = cfg.icp
        intrinsics, size = self._icp_intrinsics, self._icp_size
        if cfg.icp_downsample > 1:
            depth = area_downsample_depth(depth, cfg.icp_downsample)
        reference = self._model.render_surface(self._T_world_prev, intrinsics, size, cfg.render_min_confidence)
        if cfg.render_min_confidence > 0 and reference.valid.mean() < cfg.stable_min_coverage:  # too few stable yet
            reference = self._model.render_surface(self._T_world_prev, intrinsics, size)
        ref_pyramid = reference_pyramid(reference, icp)
        cur_pyramid = depth_pyramid(depth, intrinsics, icp)
        t1 = time.perf_counter()
        self._seconds["render"] += t1 - t0
        res = icp_point_to_plane(ref_pyramid, cur_pyramid, se3_inverse(self._T_world_prev) @ T_world_pred, icp)
        self._seconds["icp"] += time.perf_counter() - t1
        if not res.tracked:
            return T_world_pred, False
        return orthonormalize(self._T_world_prev @ res.T_ref_cur), True

    def _track_photometric(self, rgb: np.ndarray, T_world_pred: np.ndarray) -> tuple[np.ndarray, bool]:
        """Direct tracking of a frame without CNN depth against the last predicted frame (cnn_every > 1)."""
        ref = self._photometric
        if ref is None:
            return T_world_pred, False
        t0 = time.perf_counter()
        cfg = self.config.tracking
        pyramid = build_image_pyramid(to_gray(rgb), self._intrinsics, cfg.pyramid_levels)
        res = track_frame(ref.reference, pyramid, se3_inverse(ref.T_world_ref) @ T_world_pred, cfg)
        self._seconds["photometric"] += time.perf_counter() - t0
        self._counters["photometric"] += 1
        if not res.tracked:
            return T_world_pred, False
        return orthonormalize(ref.T_world_ref @ res.T_kf_cur), True

    def _is_keyframe(self, frame: int, T_world_cur: np.ndarray) -> bool:
        cfg = self.config
        if self._last_kf is None:
            return True
        last_frame, T_world_kf = self._last_kf
        if frame - last_frame >= cfg.keyframe_every:
            return True
        T_kf_cur = se3_inverse(T_world_kf) @ T_world_cur
        return bool(np.linalg.norm(T_kf_cur[:3, 3]) >= cfg.keyframe_translation
                    or rotation_angle_deg(T_kf_cur) >= cfg.keyframe_rotation_deg)

    def _finish(self) -> Any:
        """An ``AgentOutput`` with the key-frames (CNN depth) and JSON-serialisable extras."""
        from sim_envs.agent import AgentOutput

        assert self._model is not None
        extras: dict[str, Any] = {
            **self.episode_extras(),
            "keyframes": len(self._keyframes),
            **self._counters,
            "model_surfels": len(self._model),
            "model_bytes": self._model.nbytes,
            "model_size_history": [list(x) for x in self._model_sizes],
            "seconds": dict(self._seconds),
            "predictor": (self._predictor_spec if isinstance(self._predictor_spec, str)
                          else type(self._predictor_spec).__name__),
            "config": {"cnn_every": self.config.cnn_every, "keyframe_every": self.config.keyframe_every,
                       "keyframe_translation": self.config.keyframe_translation,
                       "keyframe_rotation_deg": self.config.keyframe_rotation_deg,
                       "voxel_size": self.config.model.voxel_size, "pixel_stride": self.config.model.pixel_stride},
        }
        return AgentOutput(keyframes=list(self._keyframes), extras=extras)


class GroundTruthAidedLainaAgent(LainaAgent):
    """The Laina baseline with the development predictor (``uses_ground_truth = True``; a development tool).

    Ground truth (``info["gt_depth"]``, ``info["gt_labels"]``) reaches only the predictor that imitates the CNN.
    """

    uses_ground_truth = True
    default_predictor = "degraded_ground_truth"
