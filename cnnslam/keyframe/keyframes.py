"""Key-frames: selection, depth and uncertainty initialisation, and fusion with the previous key-frame
(CNN-SLAM Sec. 3.3, eq. 6-9; eq. 5 is :func:`cnnslam.depth.depth_prediction.focal_length_adjustment`).

A new key-frame is made when LSD-SLAM's score (the paper gives no rule) exceeds its threshold:
``(4 |t_kf_cur| mean_idepth)^2 + (3 (1 - usage))^2 > 1`` (:func:`keyframe_score`). Its depth is the CNN's on that
frame only. Its uncertainty is eq. 6, the squared difference with the nearest key-frame's depth warped into it; then
depth and uncertainty are fused with those propagated from the nearest key-frame (eq. 7-9).

Before eq. 7-9 an occlusion test (LSD-SLAM's DIFF_FAC_PROP_MERGE) drops pixels where the neighbour's surface and the
CNN's disagree beyond the CNN's prior plus the propagated uncertainty: there the neighbour saw another surface (an
occluder, or the background it hid), and fusing would paste that surface into the new key-frame.

The nearest key-frame is the one the new key-frame's frame was tracked against (the previous active key-frame): its
relative pose is the best known and its depth has just been refined by every frame in between.

The very first key-frame has no neighbour: its uncertainty is ``(r D)^2`` with ``r =
DepthConfig.first_keyframe_relative_sigma`` (the CNN's typical relative error); pixels of later key-frames that the
neighbour does not see get the same kind of prior (``unmatched_relative_sigma``).

Without a CNN (the LSD baselines, ``DepthConfig.source != "cnn"``) the first key-frame is initialised from a
constant, random (LSD-SLAM's initializeRandomly) or ground-truth depth (LSD-BS), and every later key-frame takes the
depth of the previous one propagated by a z-buffered forward warp (LSD-SLAM's propagation), with eq. 7's variance.

Units: depth D in metres, uncertainty U as a depth variance in m^2 (the paper's eq. 6 is a squared depth
difference), (H, W) float32 maps, 0 depth = no estimate.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

from cnnslam.config import DepthConfig, KeyframeConfig, TrackingConfig
from cnnslam.depth.depth_prediction import perturb_last_bits
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import depth_of_neighbour_in, sample_nearest, warp_keyframe_pixels
from cnnslam.track.tracking import (
    ImagePyramid,
    TrackingReference,
    build_image_pyramid,
    build_tracking_reference,
    gradient_masks,
    to_gray,
)

# ----------------------------------------------------------------------------------------------------- selection


def keyframe_score(translation_kf_cur: np.ndarray, mean_inverse_depth: float, usage: float,
                   config: KeyframeConfig) -> float:
    """LSD-SLAM's key-frame score: (w_d |t| mean_idepth)^2 + (w_u (1 - usage))^2.

    translation_kf_cur: (3,) translation of T_kf_cur, metres; mean_inverse_depth: of the key-frame, 1/m; usage:
    share of key-frame points still seen by the current frame (LSD's pointUsage), in [0, 1].
    """
    dist = np.asarray(translation_kf_cur, dtype=np.float64) * mean_inverse_depth
    return float(config.distance_weight**2 * (dist @ dist) + (config.usage_weight * (1.0 - usage)) ** 2)


def needs_new_keyframe(score: float, frames_on_keyframe: int, config: KeyframeConfig) -> bool:
    """True when the score exceeds the threshold and the key-frame has had enough frames (LSD MIN_NUM_MAPPED)."""
    return score > config.score_threshold and frames_on_keyframe >= config.min_frames_per_keyframe


# ----------------------------------------------------------------------------------------------------- eq. 6 - 9


def initial_uncertainty(depth_new: np.ndarray, depth_neighbour_warped: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 6: U_ki(u) = (D_ki(u) - D_kj(pi(K T_kj_ki V_ki(u))))^2, element-wise (m^2).

    depth_new: D_ki, the new key-frame's (CNN) depth; depth_neighbour_warped: the nearest key-frame's depth at the
    warped position, seen from k_i (:func:`cnnslam.geometry.depth_of_neighbour_in`). Both (H, W) metres.
    """
    diff = np.asarray(depth_new, dtype=np.float64) - np.asarray(depth_neighbour_warped, dtype=np.float64)
    return diff * diff


def propagated_uncertainty(
    depth_neighbour_at_v: np.ndarray, depth_new: np.ndarray, uncertainty_neighbour_at_v: np.ndarray,
    propagation_noise_variance: float,
) -> np.ndarray:
    """CNN-SLAM eq. 7: U~_kj(v) = D_kj(v) / D_ki(u) * U_kj(v) + sigma_p^2 (m^2).

    depth_neighbour_at_v: D_kj(v), the nearest key-frame's depth at v (its own frame); depth_new: D_ki(u);
    uncertainty_neighbour_at_v: U_kj(v); propagation_noise_variance: sigma_p^2 (m^2). Arrays (H, W), D in metres.
    """
    ratio = np.asarray(depth_neighbour_at_v, dtype=np.float64) / np.asarray(depth_new, dtype=np.float64)
    return ratio * np.asarray(uncertainty_neighbour_at_v, dtype=np.float64) + float(propagation_noise_variance)


def fuse_keyframe_depth(depth_new: np.ndarray, uncertainty_new: np.ndarray, depth_propagated: np.ndarray,
                        uncertainty_propagated: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 8: D_ki = (U~_kj D_ki + U_ki D_kj) / (U~_kj + U_ki): the uncertainty-weighted mean (metres)."""
    u_new = np.asarray(uncertainty_new, dtype=np.float64)
    u_prop = np.asarray(uncertainty_propagated, dtype=np.float64)
    return (u_prop * depth_new + u_new * depth_propagated) / (u_prop + u_new)


def fuse_keyframe_uncertainty(uncertainty_new: np.ndarray, uncertainty_propagated: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 9: U_ki = U~_kj U_ki / (U~_kj + U_ki) (m^2)."""
    u_new = np.asarray(uncertainty_new, dtype=np.float64)
    u_prop = np.asarray(uncertainty_propagated, dtype=np.float64)
    return u_prop * u_new / (u_prop + u_new)


def scale_anchor(cnn_depth: np.ndarray, neighbour_depth_in_new: np.ndarray, valid: np.ndarray, gain: float,
                 min_pixels: int = 100) -> float:
    """Ours (not in the paper): k = exp(gain * r), r = median over ``valid`` pixels of log(D_cnn / D_kj), the CNN's
    scale relative to the map. Scale anchoring rescales the map carried over from the nearest key-frame by k before
    eq. 6-9 (``depth.scale_anchoring``); prediction scale alignment divides the CNN depth by it instead
    (``depth.prediction_scale_alignment``). k = 1 with gain 0 or fewer than ``min_pixels`` valid pixels.

    cnn_depth: the new key-frame's CNN depth D_cnn (H, W) metres; neighbour_depth_in_new: the neighbour's depth seen
    from the new key-frame (:func:`cnnslam.geometry.depth_of_neighbour_in`), (H, W) metres; valid: (H, W) bool.
    """
    if gain <= 0:  # the paper's setting: nothing to compute on the key-frame thread
        return 1.0
    d_new = np.asarray(cnn_depth, dtype=np.float64)
    d_old = np.asarray(neighbour_depth_in_new, dtype=np.float64)
    ok = np.asarray(valid, dtype=bool) & (d_new > 0) & (d_old > 0)
    if int(ok.sum()) < min_pixels:
        return 1.0
    return float(np.exp(gain * np.median(np.log(d_new[ok] / d_old[ok]))))


@dataclass(frozen=True)
class KeyframeInit:
    """Depth and uncertainty of a new key-frame, with how they came about.

    depth: (H, W) float32 metres (0 = none); variance: (H, W) float32 m^2 (inf where no depth); matched_share:
    share of pixels that eq. 6-9 could evaluate against the neighbour (0 for the first key-frame);
    mean_abs_change: mean |fused - initial| depth over those pixels (m), a diagnostic of eq. 8; anchor_scale: the
    factor the neighbour's map was rescaled by (:func:`scale_anchor`, 1 without anchoring); prediction_scale: the
    factor the CNN depth was rescaled by (``depth.prediction_scale_alignment``, 1 without); cnn_log_scale and
    log_scale: log of the CNN's scale and of the key-frame's, in the first key-frame's units (0 unless aligning).
    """

    depth: np.ndarray
    variance: np.ndarray
    matched_share: float
    mean_abs_change: float
    anchor_scale: float = 1.0
    prediction_scale: float = 1.0
    cnn_log_scale: float = 0.0
    log_scale: float = 0.0


def relative_prior(depth: np.ndarray, relative_sigma: float) -> np.ndarray:
    """(r D)^2: the prior variance of a depth map without a neighbour (m^2), inf where there is no depth."""
    d = np.asarray(depth, dtype=np.float64)
    return np.where(d > 0, (relative_sigma * d) ** 2, np.inf)


def init_cnn_keyframe(
    cnn_depth: np.ndarray,
    intrinsics: np.ndarray,
    config: DepthConfig,
    neighbour_depth: np.ndarray | None = None,
    neighbour_variance: np.ndarray | None = None,
    T_neighbour_new: np.ndarray | None = None,
    neighbour_log_scale: float = 0.0,
    scale_history: Sequence[float] = (),
    neighbour_stereo_count: np.ndarray | None = None,
) -> KeyframeInit:
    """A CNN key-frame's depth and uncertainty: eq. 6, then eq. 7-9 against the nearest key-frame.

    cnn_depth: (H, W) metres (after eq. 5 or raw, as configured); neighbour_depth / neighbour_variance: the nearest
    key-frame's refined maps (metres, m^2), None for the first key-frame; T_neighbour_new: (4, 4) maps the new
    key-frame's coordinates into the neighbour's (T_kj_ki of the paper). neighbour_log_scale: the neighbour's
    ``log_scale``; scale_history: the ``cnn_log_scale`` of every earlier key-frame; neighbour_stereo_count: the
    neighbour's :attr:`KeyframeMaps.stereo_count` (the last three only for ``depth.prediction_scale_alignment``; the
    count only with ``depth.prediction_scale_pixels = "stereo"``).
    """
    d_new = np.asarray(cnn_depth, dtype=np.float64)
    if d_new.ndim != 2 or not (d_new > 0).any():
        raise CnnSlamError(f"CNN depth must be an (H, W) map with positive values, got shape {d_new.shape}")
    floor = relative_prior(d_new, config.min_relative_sigma)
    if neighbour_depth is None:
        var = relative_prior(d_new, config.first_keyframe_relative_sigma)
        return KeyframeInit(d_new.astype(np.float32), var.astype(np.float32), 0.0, 0.0)
    if neighbour_variance is None or T_neighbour_new is None:
        raise CnnSlamError("a neighbour key-frame needs its variance map and the relative pose T_neighbour_new")
    d_j_in_i, d_j_at_v, u_j_at_v, matched = _neighbour_seen_from(d_new, neighbour_depth, neighbour_variance,
                                                                 intrinsics, T_neighbour_new)
    a, q = 1.0, neighbour_log_scale
    if config.prediction_scale_alignment > 0:
        where = matched
        if config.prediction_scale_pixels == "stereo":  # only where the neighbour's depth is the stereo's
            where = matched & stereo_pixels(d_new, neighbour_stereo_count, intrinsics, T_neighbour_new,
                                            config.stereo_min_observations)
        q += math.log(scale_anchor(d_new, d_j_in_i, where, 1.0))  # the CNN's log scale, first key-frame units
        median = config.prediction_scale_reference == "running_median"
        target = float(np.median([*scale_history, q])) if median else neighbour_log_scale
        a = math.exp(config.prediction_scale_alignment * (q - target))
    if a != 1.0:  # the CNN's scale moved towards the map's; correspondences follow the rescaled depth
        d_new = d_new / a
        floor = relative_prior(d_new, config.min_relative_sigma)
        d_j_in_i, d_j_at_v, u_j_at_v, matched = _neighbour_seen_from(d_new, neighbour_depth, neighbour_variance,
                                                                     intrinsics, T_neighbour_new)
    k = scale_anchor(d_new, d_j_in_i, matched, config.scale_anchoring)
    if k != 1.0:  # the whole carried-over map scaled by k: depths by k, variances by k^2
        d_j_in_i, d_j_at_v, u_j_at_v = d_j_in_i * k, d_j_at_v * k, u_j_at_v * (k * k)
    u_new = np.maximum(initial_uncertainty(d_new, d_j_in_i), floor)  # eq. 6 (floored)
    u_prop = propagated_uncertainty(d_j_at_v, np.where(d_new > 0, d_new, 1.0), np.where(matched, u_j_at_v, 0.0),
                                    config.propagation_noise_variance)  # eq. 7
    # occlusion test (LSD-SLAM's DIFF_FAC_PROP_MERGE): the neighbour saw another surface where the disagreement
    # exceeds what the CNN's prior and the propagated uncertainty allow
    diff2 = (d_new - d_j_in_i) ** 2
    matched &= config.occlusion_diff_factor * diff2 <= relative_prior(d_new, config.first_keyframe_relative_sigma) \
        + u_prop
    if config.fuse_with_previous:
        fused_d = fuse_keyframe_depth(d_new, u_new, d_j_in_i, u_prop)  # eq. 8
        fused_u = fuse_keyframe_uncertainty(u_new, u_prop)  # eq. 9
    else:
        fused_d, fused_u = d_new, u_new
    prior = relative_prior(d_new, config.unmatched_relative_sigma)
    depth = np.where(matched, fused_d, d_new)
    var = np.where(matched, np.maximum(fused_u, 1e-12), prior)
    share = float(matched.mean())
    change = float(np.abs(depth - d_new)[matched].mean()) if matched.any() else 0.0
    return KeyframeInit(depth.astype(np.float32), var.astype(np.float32), share, change, k, 1.0 / a, q,
                        q - math.log(a))


def stereo_pixels(depth_new: np.ndarray, neighbour_stereo_count: np.ndarray | None, intrinsics: np.ndarray,
                  T_neighbour_new: np.ndarray, min_observations: int) -> np.ndarray:
    """(H, W) bool: the pixels of a new key-frame whose point, seen in the neighbour (T_neighbour_new maps the new
    key-frame's coordinates into the neighbour's), landed where the neighbour's depth took at least
    ``min_observations`` frames' small-baseline stereo (eq. 10-11; :attr:`KeyframeMaps.stereo_count`). There the
    map's depth is the images' own geometry, not a propagated CNN prediction (ours, after DeepRelativeFusion's
    fit of CNN depth to the SLAM's semi-dense depth). All False without a count.
    """
    d = np.asarray(depth_new, dtype=np.float64)
    if neighbour_stereo_count is None:
        return np.zeros(d.shape, bool)
    uv, _ = warp_keyframe_pixels(d, intrinsics, T_neighbour_new)
    count, inside = sample_nearest(np.asarray(neighbour_stereo_count, dtype=np.float64), uv)
    return inside & (count >= min_observations)


def _neighbour_seen_from(d_new: np.ndarray, neighbour_depth: np.ndarray, neighbour_variance: np.ndarray,
                         intrinsics: np.ndarray, T_neighbour_new: np.ndarray,
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The nearest key-frame's depth seen from the new one (metres), its own depth and variance at the warped
    positions v, and where both exist: the inputs of eq. 6-9."""
    d_j_in_i, d_j_at_v, matched = depth_of_neighbour_in(d_new, neighbour_depth, intrinsics, T_neighbour_new)
    uv, _ = warp_keyframe_pixels(d_new, intrinsics, T_neighbour_new)
    u_j_at_v, _ = sample_nearest(np.asarray(neighbour_variance, dtype=np.float64), uv)
    matched &= np.isfinite(u_j_at_v) & (d_new > 0)
    return d_j_in_i, d_j_at_v, u_j_at_v, matched


# ------------------------------------------------------------------------------------ without a CNN (LSD baselines)


@njit(cache=True, nogil=True)
def _forward_warp(depth: np.ndarray, variance: np.ndarray, T_i_j: np.ndarray, intr: np.ndarray,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Splat every pixel of key-frame j with depth into key-frame i (nearest pixel, nearest depth wins).

    Returns (depth_i, depth_j of the winner (its own frame), variance_j of the winner); 0 / inf where none.
    """
    h, w = depth.shape
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    out_d = np.zeros((h, w), np.float32)
    out_dj = np.zeros((h, w), np.float32)
    out_v = np.full((h, w), np.inf, np.float32)
    for y in range(h):
        for x in range(w):
            d = depth[y, x]
            if not d > 0.0:
                continue
            px = (x - cx) / fx * d
            py = (y - cy) / fy * d
            X = T_i_j[0, 0] * px + T_i_j[0, 1] * py + T_i_j[0, 2] * d + T_i_j[0, 3]
            Y = T_i_j[1, 0] * px + T_i_j[1, 1] * py + T_i_j[1, 2] * d + T_i_j[1, 3]
            Z = T_i_j[2, 0] * px + T_i_j[2, 1] * py + T_i_j[2, 2] * d + T_i_j[2, 3]
            if Z <= 1e-6:
                continue
            u = int(np.floor(fx * X / Z + cx + 0.5))
            v = int(np.floor(fy * Y / Z + cy + 0.5))
            if u < 0 or v < 0 or u >= w or v >= h:
                continue
            if out_d[v, u] == 0.0 or Z < out_d[v, u]:
                out_d[v, u] = Z
                out_dj[v, u] = d
                out_v[v, u] = variance[y, x]
    return out_d, out_dj, out_v


def propagate_keyframe(
    depth_j: np.ndarray, variance_j: np.ndarray, intrinsics: np.ndarray, T_new_j: np.ndarray, config: DepthConfig,
) -> KeyframeInit:
    """LSD-SLAM's depth propagation to a new key-frame (no CNN): forward-warp key-frame j's depth into the new one
    (z-buffered), with eq. 7's uncertainty U~ = D_j / D_new U_j + sigma_p^2. Pixels nothing lands on stay empty.

    depth_j: (H, W) metres; variance_j: (H, W) m^2; T_new_j: (4, 4) maps j-coordinates into the new key-frame's.
    """
    d, d_j, v_j = _forward_warp(np.ascontiguousarray(depth_j, dtype=np.float32),
                                np.ascontiguousarray(variance_j, dtype=np.float32),
                                np.ascontiguousarray(T_new_j, dtype=np.float64),
                                np.asarray(intrinsics, dtype=np.float64))
    has = d > 0
    var = np.full(d.shape, np.inf)
    var[has] = propagated_uncertainty(d_j[has], d[has], v_j[has], config.propagation_noise_variance)  # eq. 7
    return KeyframeInit(d.astype(np.float32), var.astype(np.float32), float(has.mean()), 0.0)


def init_first_keyframe_without_cnn(
    shape: tuple[int, int], config: DepthConfig, rng: np.random.Generator, mask: np.ndarray | None = None,
    ground_truth_depth: np.ndarray | None = None, perturb_last_bits_of_ground_truth: bool = False,
) -> KeyframeInit:
    """The first key-frame's depth when there is no CNN: "constant", "random" (LSD-SLAM initializeRandomly) or
    "ground_truth_first" (LSD-BS), on the pixels of ``mask`` ((H, W) bool, all when None).

    ``perturb_last_bits_of_ground_truth``: "ground_truth_first" takes the depth perturbed in its last float32 bits with
    draws from ``rng`` (:func:`cnnslam.depth.depth_prediction.perturb_last_bits`; the benchmark's seeds > 0).

    Inverse-depth variances are LSD-SLAM's (VAR_RANDOM_INIT_INITIAL for constant/random, VAR_GT_INIT_INITIAL for
    ground truth), converted to depth variance var_D = var_id D^4.
    """
    h, w = shape
    mask = np.ones(shape, bool) if mask is None else np.asarray(mask, bool)
    if config.source == "constant":
        idepth = np.full(shape, 1.0 / config.constant_depth)
        id_var = config.random_inverse_depth_variance
    elif config.source == "random":
        lo, hi = config.random_inverse_depth_range
        idepth = rng.uniform(lo, hi, size=(h, w))
        id_var = config.random_inverse_depth_variance
    elif config.source == "ground_truth_first":
        if ground_truth_depth is None:
            raise CnnSlamError(
                "depth.source = 'ground_truth_first' (LSD-BS) needs the first frame's ground-truth depth: use "
                "cnnslam.agent:GroundTruthAidedAgent, which receives it"
            )
        gt = np.asarray(ground_truth_depth, dtype=np.float64)
        if perturb_last_bits_of_ground_truth:
            gt = perturb_last_bits(gt, rng).astype(np.float64)
        mask = mask & (gt > 0)
        idepth = np.where(gt > 0, 1.0 / np.where(gt > 0, gt, 1.0), 0.0)
        id_var = config.ground_truth_inverse_depth_variance
    else:
        raise CnnSlamError(f"init_first_keyframe_without_cnn does not handle depth.source = {config.source!r}")
    depth = np.where(mask, 1.0 / np.where(idepth > 0, idepth, 1.0), 0.0)
    var = np.where(mask, id_var * depth**4, np.inf)
    return KeyframeInit(depth.astype(np.float32), var.astype(np.float32), 0.0, 0.0)


# ---------------------------------------------------------------------------------------------- key-frame state


@dataclass(frozen=True)
class KeyframeMaps:
    """A key-frame's depth D (m, (H, W) float32, 0 = none), uncertainty U (m^2, (H, W) float32, inf = none) and the
    tracking points built from them (None while released: :meth:`Keyframe.release_working_set`), with their mean
    inverse depth (1/m, LSD's meanIdepth, kept when the points are released), and ``stereo_count``: (H, W) uint16,
    how many frames' small-baseline stereo observations eq. 10-11 fused into each pixel (None before the first).
    Immutable: refinement publishes a new instance (one atomic attribute swap), so a reader in another thread always
    sees a depth, variance and reference that belong together."""

    depth: np.ndarray
    variance: np.ndarray
    reference: TrackingReference | None
    mean_inverse_depth: float = math.nan
    stereo_count: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.reference is not None:
            object.__setattr__(self, "mean_inverse_depth", self.reference.mean_inverse_depth)


@dataclass(frozen=True)
class WorkingSetBuilder:
    """How a key-frame's tracking working set is made from its image and maps: the grey pyramid
    (:func:`cnnslam.track.tracking.build_image_pyramid`), the gradient masks and the tracking points, exactly as at its
    creation (same inputs, same bytes). intrinsics: [fx, fy, cx, cy] of level 0; config: the tracker's."""

    intrinsics: np.ndarray
    config: TrackingConfig

    def pyramid(self, rgb: np.ndarray) -> ImagePyramid:
        return build_image_pyramid(to_gray(rgb), self.intrinsics, self.config.pyramid_levels)

    def masks(self, pyramid: ImagePyramid) -> tuple[np.ndarray, ...]:
        return gradient_masks(pyramid, self.config.min_gradient)

    def reference(self, pyramid: ImagePyramid, depth: np.ndarray, variance: np.ndarray,
                  masks: tuple[np.ndarray, ...]) -> TrackingReference:
        return build_tracking_reference(pyramid, depth, variance, self.config, masks)


class Keyframe:
    """One key-frame k_i of the paper: image, pose T_k_i, depth D_k_i and uncertainty U_k_i (Sec. 3.1).

    index: creation order (0 = first); timestamp: seconds of its frame; rgb: (H, W, 3) uint8; pyramid: its grey
    :class:`ImagePyramid`; label_probs: (H, W, C) float16 CNN class probabilities (None without a CNN; dropped by
    :meth:`keep_labels_only` once the global model has fused them, leaving ``labels``, their argmax); cnn_depth:
    (H, W) float32 metres, the CNN depth it was initialised with (after eq. 5 when enabled; None without a CNN);
    parent: index of the key-frame it was tracked from (None for the first); gradient_masks: its tracking-pixel
    masks per pyramid level (:func:`cnnslam.track.tracking.gradient_masks`, fixed by the image).

    Working set: the pyramid, the masks and the tracking points (``maps.reference``) are what tracking and
    alignment read; together 2.7 MB at 320x240, against 1.8 MB for the rest. With a ``builder``
    (:class:`WorkingSetBuilder`), :meth:`release_working_set` drops them and :attr:`pyramid`,
    :attr:`gradient_masks` and :attr:`reference` make them again on use, with the same bytes, so that a long
    sequence keeps only its recent key-frames' working sets (``SystemConfig.working_keyframes``).

    Thread ownership (the hand-over of the two threads, see :mod:`cnnslam.system`):

    - ``maps`` (:class:`KeyframeMaps`): WRITTEN by the frame thread (refinement, eq. 10-11) while this is the
      active key-frame, by swapping in a new immutable instance (:meth:`set_maps`); a released working set is
      swapped back in by whichever thread uses it first, only if ``maps`` is still the one it was made from.
      READ by both threads.
    - ``T_world_kf`` ((4, 4) float64): WRITTEN by the key-frame thread (pose-graph optimisation), by swapping in a
      new array; READ by both threads.
    - ``frames_tracked``: frame thread only. Everything else is set once, before the key-frame is published.
    """

    def __init__(
        self, index: int, timestamp: float, rgb: np.ndarray, pyramid: ImagePyramid, maps: KeyframeMaps,
        T_world_kf: np.ndarray, label_probs: np.ndarray | None, cnn_depth: np.ndarray | None, parent: int | None,
        gradient_masks: tuple[np.ndarray, ...] | None = None, builder: WorkingSetBuilder | None = None,
    ) -> None:
        self.index = int(index)
        self.timestamp = float(timestamp)
        self.rgb = rgb
        self._pyramid: ImagePyramid | None = pyramid
        self.maps = maps
        self.T_world_kf = np.array(T_world_kf, dtype=np.float64)
        self.label_probs = None if label_probs is None else np.asarray(label_probs, dtype=np.float16)
        self._labels: np.ndarray | None = None
        self.cnn_depth = cnn_depth
        self.parent = parent
        self._masks = gradient_masks
        self._builder = builder
        self._maps_lock = threading.Lock()
        self.frames_tracked = 0

    @property
    def labels(self) -> np.ndarray | None:
        """(H, W) uint8 CNN labels, the argmax of the class probabilities (None without a CNN)."""
        probs = self.label_probs  # read first: keep_labels_only sets the labels before it drops the distribution
        return self._labels if probs is None else _argmax_labels(probs)

    def keep_labels_only(self) -> None:
        """Keep the argmax of the class probabilities and drop the distribution (1/8 of its memory at C = 4): after
        the global model has fused them (Sec. 3.5) it holds the distributions; the key-frame keeps the label it gave
        each pixel. Key-frame thread, once the key-frame is frozen."""
        if self.label_probs is not None:
            self._labels = _argmax_labels(self.label_probs)
            self.label_probs = None

    @property
    def pyramid(self) -> ImagePyramid:
        """The grey image pyramid (made again from ``rgb`` after a release)."""
        pyramid = self._pyramid
        if pyramid is None:
            pyramid = self._pyramid = self._need_builder().pyramid(self.rgb)
        return pyramid

    @property
    def gradient_masks(self) -> tuple[np.ndarray, ...] | None:
        """The tracking-pixel masks per level (made again after a release; None when never given)."""
        masks = self._masks
        if masks is None and self._builder is not None:
            masks = self._masks = self._builder.masks(self.pyramid)
        return masks

    @property
    def reference(self) -> TrackingReference:
        """The tracking points of the current maps (made again after a release)."""
        maps = self.maps
        if maps.reference is not None:
            return maps.reference
        reference = self._need_builder().reference(self.pyramid, maps.depth, maps.variance, self.gradient_masks)
        with self._maps_lock:
            if self.maps is maps:
                self.maps = KeyframeMaps(maps.depth, maps.variance, reference, stereo_count=maps.stereo_count)
        return reference

    @property
    def mean_inverse_depth(self) -> float:
        """LSD-SLAM's meanIdepth of the current maps (1/m)."""
        return self.maps.mean_inverse_depth

    def set_maps(self, maps: KeyframeMaps) -> None:
        """Publish new maps (refinement: one atomic swap)."""
        with self._maps_lock:
            self.maps = maps

    def release_working_set(self) -> None:
        """Drop the pyramid, the masks and the tracking points (kept: image, depth, variance, labels); they are made
        again on use. Without a builder nothing is released."""
        if self._builder is None:
            return
        self._pyramid = None
        self._masks = None
        with self._maps_lock:
            maps = self.maps
            if maps.reference is not None:
                self.maps = KeyframeMaps(maps.depth, maps.variance, None, maps.mean_inverse_depth, maps.stereo_count)

    @property
    def working_set_held(self) -> bool:
        """Whether the pyramid and the tracking points are in memory."""
        return self._pyramid is not None and self.maps.reference is not None

    def _need_builder(self) -> WorkingSetBuilder:
        if self._builder is None:
            raise CnnSlamError(f"key-frame {self.index}: its working set was released without a builder")
        return self._builder

    def __repr__(self) -> str:
        return f"Keyframe(index={self.index}, timestamp={self.timestamp:.3f}, parent={self.parent})"


def _argmax_labels(probs: np.ndarray) -> np.ndarray:
    """(H, W) uint8 labels: the argmax of (H, W, C) class probabilities."""
    return np.argmax(probs, axis=2).astype(np.uint8)
