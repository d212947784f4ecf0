"""The global 3D model and semantic label fusion (CNN-SLAM Sec. 3.5): key-frames (refined depth, pose-graph pose,
uncertainty, CNN class probabilities) fused incrementally into one surfel model.

Why surfels (point-based fusion, Keller et al. 3DV 2013 [11]) and not a TSDF
------------------------------------------------------------------------------
- Re-placement. The pose graph keeps moving key-frames. A surfel records the key-frame that anchors it, so moving a
  key-frame is a rigid transform of its surfels (O(surfels), no input kept). A TSDF bakes every depth map into the
  voxels: moving one needs de-integration and re-integration (BundleFusion), i.e. keeping every key-frame's maps.
- Uncertainty. CNN-SLAM gives a per-pixel depth variance; a surfel keeps an inverse-variance-weighted mean of its
  observations. A TSDF needs a truncation band wider than the depth error (10-30 cm for CNN depth at 3 m), which
  flattens everything thinner than that band (the small objects of the semantic classes).
- Sparse views. Key-frames are about a second apart; a point model stores what they saw, no volume in between.
- The Laina baseline [16] fed CNN depth to Keller's point-based fusion [11]: the same model serves it
  (:mod:`cnnslam.baselines.laina`), as in the paper's comparison.

A model element (surfel) holds: position and unit normal (world, m), radius (m), colour (RGB 0..255), the
position weight W = sum alpha / sigma_d^2 (1/m^2), the confidence c = sum alpha (Keller: alpha = exp(-gamma^2 /
(2 sigma^2)), gamma the pixel's normalised radial distance from the principal point, sigma = 0.6), the number of
frames that observed it, a label distribution (below), its anchor key-frame and its voxel key.

Integration of one depth map (:meth:`GlobalModel.integrate`)
------------------------------------------------------------
1. Measurements: every ``pixel_stride``-th pixel with a depth, a normal (:func:`cnnslam.model.icp.adaptive_normal_map`:
   raw where consistent, else from the depth smoothed by :func:`cnnslam.model.icp.smooth_depth`; none at depth edges),
   an incidence angle below ``max_incidence_deg`` and a depth sigma below ``max_relative_sigma`` of its depth;
   sigma_d from the key-frame's variance map (CNN-SLAM's uncertainty U) or ``default_relative_sigma * d``.
   Radius: the disc around the pixel's footprint, s d / (sqrt(2) f cos(incidence)).
2. Projective data association (as in Keller et al.): the model is splatted into the camera (disc radius in pixels
   capped at ``max_splat_radius_px``); among the surfels covering a measurement's pixel the one closest in depth is
   its candidate (ours: not the front-most one, so that a measurement finds its surface behind unconfirmed clutter,
   e.g. the CNN's blurred depth edges). It merges into it when the depth where its pixel ray meets the surfel's plane
   is within ``tol = clip(association_sigmas * sqrt(sigma_d^2 + sigma_s^2), min_association_distance,
   max_association_distance)`` (sigma_s^2 = c / W, the surfel's typical observation variance) and the normals are
   within ``max_normal_angle_deg``.
3. Merge (Keller et al.'s weighted averaging, one observation per frame and surfel): the measurements that hit one
   surfel are averaged (weights alpha / sigma_d^2 for position and normal, alpha for colour, radius and labels) and
   fused: p <- (W p + w x) / (W + w), n <- normalise(W n + w n_x), colour and radius <- (c . + alpha .) / (c +
   alpha), W <- W + w, c <- c + alpha.
4. New surfels and the memory bound (ours): measurements that associated with nothing are grouped by voxel key
   (voxel of ``voxel_size`` metres x the dominant axis of the normal, 6 directions, so the two sides of a thin
   board stay apart). A key already held by a surfel merges into it (step 3); the others become new surfels. Every
   key holds at most one surfel, so a static scene's model is bounded by its surface area / voxel_size^2 (x the
   few normal directions a voxel's surface has), whatever the sequence length.
5. Free space (ours, in the spirit of Keller et al.'s removal of points that a new measurement sees through): a
   surfel that the frame does not merge into although the depth measured at its pixel lies more than
   ``miss_margin`` behind it gets a miss; with ``max_misses`` misses, and more misses than confirming frames, it is
   removed. This drops the clutter that noisy CNN depth leaves in front of surfaces and slows the model's growth
   well below the bound of step 4 (a negative margin also drops duplicate layers, at a cost in accuracy).

Semantic label fusion (CNN-SLAM Sec. 3.5, the Global Segmentation Model of Tateno et al. 2015 [27] with CNN class
probabilities in place of segment ids): every surfel accumulates L <- L + alpha P, P the mean class probabilities of
the measurements it merged in that frame (``label_weighting = "precision"`` weights alpha / sigma_d^2 instead). Its
distribution is L / sum(L), the average of the frame-wise distributions of the key-frames that saw it; its label is
the argmax (``NO_LABEL`` = 255 with no label evidence).

Re-placement (:meth:`GlobalModel.update_poses`): a surfel's anchor is the key-frame of its largest single
observation weight. When the pose graph moves key-frame k from T_world_k to T'_world_k, every surfel anchored to k
is moved by T'_world_k T_world_k^-1 (position and normal), voxel keys are recomputed and surfels that now share a key
are merged (weights combine as in step 3). Cost O(N log N) in the model size, independent of how many key-frames
were fused. Approximation (ours): a surfel observed from several key-frames moves with its anchor only, not by the
weighted mix of its observers' motions.

Pruning (:meth:`GlobalModel.prune`, Keller et al.'s removal of unstable points): surfels with confidence below a
threshold that were created at least ``min_age`` integrations ago are removed (outliers never confirmed).

Conventions: positions and normals in the world frame of the poses given (``T_world_cam``, camera-to-world, OpenCV
camera axes); depth planar z in metres (0 = none); the integration counter counts calls to :meth:`integrate`.
No I/O here: export is :mod:`cnnslam.model.model_io`, pictures :mod:`cnnslam.model.model_render`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cnnslam.config import LABEL_WEIGHTINGS, GlobalModelConfig, LabelWeighting  # noqa: F401 - re-exported
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import pixel_rays, se3_inverse
from cnnslam.model.icp import ADAPTIVE_NORMAL_CONSISTENCY, SurfaceMaps, smooth_depth
from cnnslam.model.label_fusion import (
    checked_class_scores,
    class_probabilities_at,
    fuse_labels,
    fused_labels,
    label_distribution,
    label_weights,
)
from cnnslam.model.surfel_kernels import (
    associate_kernel,
    group_kernel,
    measure_kernel,
    merge_kernel,
    render_kernel,
    sampled_normals,
)
from cnnslam.model.surfel_keys import (
    N_NORMAL_DIRECTIONS as N_NORMAL_DIRECTIONS,  # re-exported: keys live in surfel_keys
)
from cnnslam.model.surfel_keys import radial_confidence as radial_confidence
from cnnslam.model.surfel_keys import voxel_keys as voxel_keys
from cnnslam.model.surfel_store import SurfelStore
from slamcommon.labels import NO_LABEL  # noqa: F401 - re-exported: an element without label evidence

NO_ANCHOR: int = -1


@dataclass(frozen=True)
class IntegrationStats:
    """What one :meth:`GlobalModel.integrate` did: measurements used, pixels merged by projective association,
    voxel groups merged into existing surfels, surfels created, surfels removed (step 5), and the model size after
    it."""

    frame: int
    measurements: int
    associated: int
    voxel_merged: int
    created: int
    removed: int
    surfels: int


@dataclass(frozen=True)
class ReplacementStats:
    """What one :meth:`GlobalModel.update_poses` did: key-frames moved, surfels moved, surfels merged away by the
    re-hash, and the largest and mean surfel displacement (m)."""

    keyframes_moved: int
    surfels_moved: int
    surfels_merged: int
    max_displacement: float
    mean_displacement: float


@dataclass(frozen=True)
class SurfelCloud:
    """A snapshot of the model (copies; the model goes on changing).

    positions (N, 3) float32 world metres; normals (N, 3) float32 unit; colours (N, 3) uint8 RGB; labels (N,) uint8
    (argmax of label_probs, ``NO_LABEL`` = 255 without label evidence); label_probs (N, C) float32 (rows sum to 1,
    0 without evidence); confidence (N,) float32 (Keller's c = sum alpha); radius (N,) float32 metres;
    observations (N,) uint32 frames merged in; anchors (N,) int32 key-frame ids (-1 = none).
    """

    positions: np.ndarray
    normals: np.ndarray
    colours: np.ndarray
    labels: np.ndarray
    label_probs: np.ndarray
    confidence: np.ndarray
    radius: np.ndarray
    observations: np.ndarray
    anchors: np.ndarray

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    def subset(self, mask: np.ndarray) -> SurfelCloud:
        """The surfels selected by ``mask`` ((N,) bool or an index array)."""
        return SurfelCloud(*(getattr(self, f)[mask] for f in self.__dataclass_fields__))


@dataclass(frozen=True)
class ModelView:
    """The model splatted into a camera: index (H, W) int32 front-most surfel per pixel (-1 = none); vertices (H, W, 3)
    float32 camera coordinates of the point where the pixel's ray meets that surfel's disc plane (its centre when the
    ray grazes the plane), depth (H, W) float32 their z, normals (H, W, 3) float32 the surfel's normal in camera
    coordinates, confidence (H, W) float32 its confidence c (0 where there is no surfel)."""

    index: np.ndarray
    depth: np.ndarray
    vertices: np.ndarray
    normals: np.ndarray
    confidence: np.ndarray


# ------------------------------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class _PixelMeasurements:
    """The measuring pixels of one depth map (step 1): clean depth (H, W); pixel rows, columns (M,); camera points and
    normals (M, 3); depth z, variance sigma_d^2, disc radius (m) and Keller's radial weight alpha (M,)."""

    depth: np.ndarray
    vs: np.ndarray
    us: np.ndarray
    x_cam: np.ndarray
    n_cam: np.ndarray
    z: np.ndarray
    sigma2: np.ndarray
    radius: np.ndarray
    alpha: np.ndarray


@dataclass(frozen=True)
class _Measurements:
    """Grouped measurements of one frame: one row per target (surfel or new voxel). World frame."""

    position: np.ndarray  # (M, 3) float64
    normal: np.ndarray  # (M, 3) float64 unit
    colour: np.ndarray  # (M, 3) float32
    radius: np.ndarray  # (M,)
    weight: np.ndarray  # (M,) mean alpha / sigma^2 of the group
    alpha: np.ndarray  # (M,) mean alpha
    probs: np.ndarray | None  # (M, C) mean class probabilities, or None
    label_weight: np.ndarray  # (M,) mean weight of the label evidence (alpha, or alpha / sigma^2)


class GlobalModel:
    """An incrementally fused surfel model with label distributions (see the module docstring).

    ``config``: :class:`GlobalModelConfig`. Integrate depth maps with :meth:`integrate`, move key-frames with
    :meth:`update_poses`, read with :meth:`snapshot`, :meth:`render` or :meth:`render_surface`. The surfels live in a
    :class:`~cnnslam.model.surfel_store.SurfelStore` (``store``); the per-pixel and per-surfel steps run in the kernels
    of
    :mod:`cnnslam.model.surfel_kernels`; labels are fused by :func:`cnnslam.model.label_fusion.fuse_labels`.
    """

    def __init__(self, config: GlobalModelConfig | None = None) -> None:
        self.config = config or GlobalModelConfig()
        self.store = SurfelStore(self.config.num_classes)
        self._poses: dict[int, np.ndarray] = {}  # anchor id -> T_world_kf the surfels are expressed at
        self._frames = 0
        self._tables_key: tuple | None = None
        self._tables: tuple[np.ndarray, np.ndarray] = (np.zeros((0, 0, 3), np.float32), np.zeros((0, 0), np.float32))

    # ---------------------------------------------------------------------------------------------- reading

    def __len__(self) -> int:
        return len(self.store)

    @property
    def integrations(self) -> int:
        """Number of :meth:`integrate` calls so far."""
        return self._frames

    @property
    def nbytes(self) -> int:
        """Bytes held by the model's arrays (allocated capacity, index included)."""
        return self.store.nbytes + 128 * len(self._poses)

    @property
    def keyframe_poses(self) -> dict[int, np.ndarray]:
        """Anchor id -> the (4, 4) T_world_kf the model currently places that key-frame at (copies)."""
        return {k: v.copy() for k, v in self._poses.items()}

    def _col(self, name: str) -> np.ndarray:
        return self.store.column(name)

    def label_evidence(self) -> np.ndarray:
        """(N, C) float32 copy of the accumulated label evidence L = sum alpha P (not normalised): the weight of the
        measurements fused into each surfel per class."""
        return self.store.live_evidence().copy()

    def label_probabilities(self) -> np.ndarray:
        """(N, C) float32 label distributions L / sum(L) (rows of zeros without label evidence)."""
        return label_distribution(self.store.live_evidence())

    def labels(self) -> np.ndarray:
        """(N,) uint8 argmax labels, ``NO_LABEL`` without label evidence."""
        return fused_labels(self.store.live_evidence())

    def snapshot(self, min_confidence: float = 0.0) -> SurfelCloud:
        """A :class:`SurfelCloud` of the surfels with confidence >= ``min_confidence`` (copies)."""
        keep = self._col("confidence") >= min_confidence
        return SurfelCloud(
            positions=self._col("position")[keep].copy(),
            normals=self._col("normal")[keep].copy(),
            colours=np.clip(np.rint(self._col("colour")[keep]), 0, 255).astype(np.uint8),
            labels=self.labels()[keep],
            label_probs=self.label_probabilities()[keep],
            confidence=self._col("confidence")[keep].copy(),
            radius=self._col("radius")[keep].copy(),
            observations=self._col("n_obs")[keep].copy(),
            anchors=self._col("anchor")[keep].copy(),
        )

    def _raycast(self, T_world_cam: np.ndarray, intrinsics: np.ndarray, image_size: tuple[int, int],
                 min_confidence: float, max_radius_px: float | None) -> tuple[np.ndarray, ...]:
        """:func:`~cnnslam.model.surfel_kernels.render_kernel` in a camera: (vertices, normals, valid, index)."""
        h, w = int(image_size[0]), int(image_size[1])
        k = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        T_cam_world = se3_inverse(np.asarray(T_world_cam, dtype=np.float64))
        R, t = np.ascontiguousarray(T_cam_world[:3, :3]), np.ascontiguousarray(T_cam_world[:3, 3])
        cap = self.config.max_splat_radius_px if max_radius_px is None else float(max_radius_px)
        return render_kernel(
            self._col("position"), self._col("normal"), self._col("confidence"), self._col("radius"),
            float(min_confidence), R.astype(np.float32), t.astype(np.float32), R, t, k[0], k[1], k[2], k[3], h, w,
            float(cap), np.float32(0.75 * self.config.voxel_size))

    def render(self, T_world_cam: np.ndarray, intrinsics: np.ndarray, image_size: tuple[int, int],
               min_confidence: float = 0.0, max_radius_px: float | None = None) -> ModelView:
        """Splat the surfels (confidence >= ``min_confidence``) into a camera: the front-most surfel per pixel, and the
        point of its disc on the pixel's ray (a ray-cast of the surfel model, as KinectFusion ray-casts its TSDF).

        T_world_cam: (4, 4); intrinsics [fx, fy, cx, cy] pixels; image_size (H, W). Disc radii are at least 0.75
        voxel and at most ``max_radius_px`` pixels (default ``config.max_splat_radius_px``).
        """
        V, N, _, index = self._raycast(T_world_cam, intrinsics, image_size, min_confidence, max_radius_px)
        hit = index >= 0
        confidence = np.zeros(index.shape, np.float32)
        confidence[hit] = self._col("confidence")[index[hit]]
        return ModelView(index, V[..., 2].copy(), V, N, confidence)

    def render_surface(self, T_world_cam: np.ndarray, intrinsics: np.ndarray, image_size: tuple[int, int],
                       min_confidence: float = 0.0) -> SurfaceMaps:
        """:meth:`render` as ICP's reference surface (KinectFusion's ray-cast model, frame-to-model tracking): the
        :class:`~cnnslam.model.icp.SurfaceMaps` of the view's vertices and normals, valid where a surfel with a normal
        covers
        the pixel."""
        V, N, valid, _ = self._raycast(T_world_cam, intrinsics, image_size, min_confidence, None)
        return SurfaceMaps(V, N, valid, np.asarray(intrinsics, dtype=np.float64).reshape(4).copy())

    # ------------------------------------------------------------------------------------------- integration

    def integrate(self, depth: np.ndarray, T_world_cam: np.ndarray, intrinsics: np.ndarray,
                  rgb: np.ndarray | None = None, label_probs: np.ndarray | None = None,
                  variance: np.ndarray | None = None, anchor: int | None = None) -> IntegrationStats:
        """Fuse one depth map (see the module docstring, steps 1-5) and its class probabilities (Sec. 3.5).

        depth: (H, W) metres (0 or NaN = none); T_world_cam: (4, 4) camera-to-world; intrinsics: [fx, fy, cx, cy];
        rgb: (H, W, 3) uint8 or None (grey); label_probs: (H, W, C) float class probabilities, or (H, W) integer
        labels (one-hot; ``NO_LABEL`` = no evidence), or None; variance: (H, W) depth variance m^2 (inf / NaN /
        <= 0 = none: the default sigma), or None; anchor: the key-frame id the new and re-weighted surfels may be
        anchored to (for :meth:`update_poses`), None for none (frame-rate fusion without a pose graph).
        """
        cfg = self.config
        depth, T, intr = _checked_view(depth, T_world_cam, intrinsics, variance)
        h, w = depth.shape
        if rgb is not None and np.shape(rgb) != (h, w, 3):
            raise CnnSlamError(f"rgb must be (H, W, 3) = {(h, w, 3)}, got {np.shape(rgb)}")
        scores = checked_class_scores(label_probs, (h, w), cfg.num_classes)  # (checked before any change)
        if anchor is not None:
            anchor = int(anchor)
            if anchor < 0:
                raise CnnSlamError(f"anchor must be a key-frame id >= 0 or None, got {anchor}")
            if anchor in self._poses and not np.allclose(self._poses[anchor], T, atol=1e-9):
                raise CnnSlamError(f"key-frame {anchor} is already fused at another pose; move it with update_poses()")
            self._poses[anchor] = T.copy()
        frame = self._frames
        self._frames += 1

        # 1. measurements
        px = self._measure(depth, intr, variance)
        vs, us, x_cam, n_cam, sigma2, radius, alpha = (px.vs, px.us, px.x_cam, px.n_cam, px.sigma2, px.radius,
                                                       px.alpha)
        weight = alpha / sigma2
        R, t = T[:3, :3], T[:3, 3]
        x_world = x_cam @ R.T + t
        n_world = n_cam @ R.T
        colour = (np.full((vs.size, 3), 128.0, np.float32) if rgb is None
                  else np.asarray(rgb)[vs, us].astype(np.float32))
        probs = None if scores is None else class_probabilities_at(scores, vs, us, cfg.num_classes)
        label_weight = label_weights(alpha, sigma2, cfg.label_weighting, cfg.min_depth_sigma)
        m = vs.size

        # 2. projective data association
        target, in_view = self._associate(px, T, intr, cfg.max_misses > 0)
        assoc = np.flatnonzero(target >= 0)
        associated = int(assoc.size)
        seen = np.zeros(0, np.int64)
        if associated:
            groups, inverse = np.unique(target[assoc], return_inverse=True)
            meas = _group(inverse, groups.size, assoc, x_world, n_world, colour, radius, weight, alpha, probs,
                          label_weight)
            self._merge_into(groups, meas, anchor)
            seen = groups

        # 3-4. voxel-hash merge and new surfels
        rest = np.flatnonzero(target < 0)
        voxel_merged = created = 0
        if rest.size:
            keys = voxel_keys(x_world[rest], n_world[rest], cfg.voxel_size)
            ukeys, inverse = np.unique(keys, return_inverse=True)
            meas = _group(inverse, ukeys.size, rest, x_world, n_world, colour, radius, weight, alpha, probs,
                          label_weight)
            key_ids = self.store.ids_of_keys(ukeys)
            found = key_ids >= 0
            if found.any():
                merged_ids = key_ids[found]
                self._merge_into(merged_ids, _take(meas, found), anchor)
                voxel_merged = int(found.sum())
                seen = np.concatenate([seen, merged_ids])  # (marks the confirmed surfels below)
            new = ~found
            if new.any():
                self._append(_take(meas, new), ukeys[new], frame, anchor)
                created = int(new.sum())

        # 5. surfels in view that this frame did not confirm: seen through, or a duplicate layer. Only a miss makes a
        # surfel removable (a merge raises n_obs, a re-hash keeps the fewest misses and the most n_obs of the surfels
        # it combines), so the missed surfels are the only candidates: no surfel elsewhere meets the test
        removed = 0
        confirmed = np.zeros(len(self.store), bool)
        confirmed[seen] = True
        missed = in_view[~confirmed[in_view]]  # in view, not confirmed (unsorted: the update below is per surfel)
        if missed.size:
            misses_column = self.store.columns["misses"]
            misses = np.minimum(misses_column[missed].astype(np.int64) + 1, 65535)
            misses_column[missed] = misses
            drop = missed[(misses >= cfg.max_misses) & (misses > self.store.columns["n_obs"][missed])]
            removed = int(drop.size)
            if removed:
                keep = np.ones(len(self.store), bool)
                keep[drop] = False
                self._remove_rows(np.flatnonzero(keep))
        return IntegrationStats(frame, m, associated, voxel_merged, created, removed, len(self.store))

    def _measure(self, depth: np.ndarray, intr: np.ndarray, variance: np.ndarray | None) -> _PixelMeasurements:
        """Step 1: the pixels of ``depth`` that make measurements, with their camera points, normals (adaptive
        normals computed at the sampled pixels only) and sigmas."""
        cfg = self.config
        h, w = depth.shape
        rays, alpha_map = self._camera_tables((h, w), intr)
        d = np.where(np.isfinite(depth) & (depth >= cfg.min_depth) & (depth <= cfg.max_depth), depth, 0.0)
        d = np.ascontiguousarray(d, dtype=np.float32)
        adaptive = cfg.normal_smoothing_px > 0
        smoothed = smooth_depth(d, cfg.normal_smoothing_px, cfg.normal_smoothing_relative) if adaptive else d
        s = cfg.pixel_stride
        N = sampled_normals(d, rays, np.ascontiguousarray(smoothed, dtype=np.float32),
                            float(cfg.max_relative_depth_jump), int(cfg.normal_step_px), s,
                            ADAPTIVE_NORMAL_CONSISTENCY, adaptive)
        var = np.zeros((1, 1)) if variance is None else np.ascontiguousarray(variance, dtype=np.float64)
        vs, us, x_cam, n_cam, z, sigma2, radius, alpha = measure_kernel(
            N, d, rays, alpha_map, var, variance is not None, s, float(cfg.default_relative_sigma),
            float(cfg.min_depth_sigma**2), float(cfg.max_relative_sigma), math.cos(math.radians(cfg.max_incidence_deg)),
            float(0.5 * (intr[0] + intr[1])))
        return _PixelMeasurements(d, vs, us, x_cam, n_cam, z, sigma2, radius, alpha)

    def _associate(self, px: _PixelMeasurements, T: np.ndarray, intr: np.ndarray,
                   find_misses: bool) -> tuple[np.ndarray, np.ndarray]:
        """Step 2, Keller's projective data association: (target surfel id per measurement, -1 = none; ids of the
        surfels the frame should see, not hidden behind a nearer measured surface, when ``find_misses``)."""
        cfg = self.config
        m = px.vs.size
        if not (len(self.store) and m):
            return np.full(m, -1, np.int64), np.zeros(0, np.int64)
        k = np.asarray(intr, dtype=np.float64).reshape(4)
        T_cam_world = se3_inverse(np.asarray(T, dtype=np.float64))
        R = np.ascontiguousarray(T[:3, :3], dtype=np.float64)
        return associate_kernel(
            self._col("position"), self._col("radius"), self._col("normal"), self._col("confidence"),
            self._col("weight"), T_cam_world[:3, :3].astype(np.float32), T_cam_world[:3, 3].astype(np.float32), R,
            k[0], k[1], k[2], k[3], float(cfg.max_splat_radius_px), np.float32(0.75 * cfg.voxel_size),
            np.ascontiguousarray(px.depth, dtype=np.float32), px.vs, px.us, np.ascontiguousarray(px.x_cam),
            np.ascontiguousarray(px.n_cam), np.ascontiguousarray(px.z), np.ascontiguousarray(px.sigma2),
            bool(find_misses), float(cfg.miss_margin), float(cfg.association_sigmas),
            float(cfg.min_association_distance), float(cfg.max_association_distance),
            math.cos(math.radians(cfg.max_normal_angle_deg)), int(cfg.pixel_stride))

    def associate(self, depth: np.ndarray, T_world_cam: np.ndarray, intrinsics: np.ndarray,
                  variance: np.ndarray | None = None) -> np.ndarray:
        """(H, W) int64 map of the surfel each pixel of ``depth`` would be fused into now, -1 for none: the data
        association of :meth:`integrate` (steps 1-3: projective association, then the voxel key) without changing
        the model. Same arguments and conventions as :meth:`integrate`.

        Used to read the model back at a key-frame's pixels, e.g. the fused label of the surface a pixel measured.
        """
        depth, T, intr = _checked_view(depth, T_world_cam, intrinsics, variance)
        px = self._measure(depth, intr, variance)
        target, _ = self._associate(px, T, intr, False)
        rest = np.flatnonzero(target < 0)
        if rest.size:
            x_world = px.x_cam[rest] @ T[:3, :3].T + T[:3, 3]
            target[rest] = self.store.ids_of_keys(voxel_keys(x_world, px.n_cam[rest] @ T[:3, :3].T,
                                                             self.config.voxel_size))
        out = np.full(depth.shape, -1, np.int64)
        out[px.vs, px.us] = target
        return out

    def _camera_tables(self, size: tuple[int, int], intr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel rays K^-1 u (H, W, 3) float32 and Keller's radial confidence (H, W) float32 of a camera (cached)."""
        key = (size, tuple(float(x) for x in intr))
        if self._tables_key != key:
            self._tables = (pixel_rays(size, intr).astype(np.float32),
                            radial_confidence(size, intr, self.config.radial_sigma))
            self._tables_key = key
        return self._tables

    def _merge_into(self, ids: np.ndarray, meas: _Measurements, anchor: int | None) -> None:
        """Step 3 on the surfels ``ids`` (unique) with one grouped measurement each, and their labels (Sec. 3.5)."""
        D = self.store.columns
        ids = np.ascontiguousarray(ids, dtype=np.int64)
        merge_kernel(ids, D["position"], D["normal"], D["colour"], D["radius"], D["weight"], D["confidence"],
                     D["n_obs"], D["anchor"], D["anchor_weight"],
                     np.ascontiguousarray(meas.position, dtype=np.float64),
                     np.ascontiguousarray(meas.normal, dtype=np.float64),
                     np.ascontiguousarray(meas.colour, dtype=np.float32),
                     np.ascontiguousarray(meas.radius, dtype=np.float64),
                     np.ascontiguousarray(meas.weight, dtype=np.float64),
                     np.ascontiguousarray(meas.alpha, dtype=np.float64), -1 if anchor is None else int(anchor),
                     anchor is not None)
        if meas.probs is not None:
            fuse_labels(self.store.evidence, ids, meas.probs, meas.label_weight)

    def _append(self, meas: _Measurements, keys: np.ndarray, frame: int, anchor: int | None) -> None:
        """New surfels from grouped measurements whose ``keys`` (sorted, unique, absent from the model) are new."""
        rows = self.store.append(keys)
        D = self.store.columns
        D["position"][rows] = meas.position
        D["normal"][rows] = meas.normal
        D["colour"][rows] = meas.colour
        D["radius"][rows] = meas.radius
        D["weight"][rows] = meas.weight
        D["confidence"][rows] = meas.alpha
        D["n_obs"][rows] = 1
        D["anchor"][rows] = NO_ANCHOR if anchor is None else anchor
        D["anchor_weight"][rows] = meas.weight if anchor is not None else 0.0
        D["first_seen"][rows] = frame
        D["misses"][rows] = 0
        if meas.probs is not None:
            fuse_labels(self.store.evidence, np.arange(rows.start, rows.stop), meas.probs, meas.label_weight)

    # -------------------------------------------------------------------------------------- re-placement, pruning

    def update_poses(self, poses: Mapping[int, np.ndarray]) -> ReplacementStats:
        """Move key-frames to new poses (the pose graph's ``{key-frame id: T_world_kf}``) and their anchored surfels
        with them (module docstring). Ids never fused are ignored; moves below the configured thresholds wait until
        they add up."""
        cfg = self.config
        deltas: dict[int, np.ndarray] = {}
        for kf, T_new in poses.items():
            kf = int(kf)
            if kf not in self._poses:
                continue
            T_new = np.asarray(T_new, dtype=np.float64)
            if T_new.shape != (4, 4) or not np.isfinite(T_new).all():
                raise CnnSlamError(f"the pose of key-frame {kf} must be a finite (4, 4) transform")
            delta = T_new @ se3_inverse(self._poses[kf])
            angle = math.degrees(math.acos(float(np.clip((np.trace(delta[:3, :3]) - 1.0) / 2.0, -1.0, 1.0))))
            if np.linalg.norm(delta[:3, 3]) < cfg.replace_min_translation and angle < cfg.replace_min_rotation_deg:
                continue
            deltas[kf] = delta
            self._poses[kf] = T_new.copy()
        if not deltas or not len(self.store):
            return ReplacementStats(len(deltas), 0, 0, 0.0, 0.0)
        anchors = self._col("anchor")
        # 32-bit temporaries, freed as soon as they are used: after a long episode N is millions of surfels and
        # this runs at the end of the episode, beside everything it kept
        table = np.full(max(max(deltas), int(anchors.max(initial=0))) + 2, -1, np.int32)
        stack = np.stack(list(deltas.values()))
        table[list(deltas)] = np.arange(len(deltas), dtype=np.int32)
        which = np.clip(anchors, 0, None)
        np.take(table, which, out=which)
        which[anchors < 0] = -1
        moved = np.flatnonzero(which >= 0).astype(np.int32)
        if moved.size == 0:
            return ReplacementStats(len(deltas), 0, 0, 0.0, 0.0)
        which = which[moved]
        # key-frame by key-frame (no (N, 4, 4) stack)
        order = np.argsort(which, kind="stable")
        moved, which = moved[order], which[order]
        del order
        bounds = np.flatnonzero(np.r_[True, np.diff(which) != 0, True])
        n_moved, disp_max, disp_sum = int(moved.size), 0.0, 0.0
        D = self.store.columns
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
            idx = moved[lo:hi]
            T = stack[which[lo]]
            p_old = D["position"][idx].astype(np.float64)
            p_new = p_old @ T[:3, :3].T + T[:3, 3]
            D["position"][idx] = p_new
            D["normal"][idx] = D["normal"][idx].astype(np.float64) @ T[:3, :3].T
            disp = np.linalg.norm(p_new - p_old, axis=1)
            disp_max, disp_sum = max(disp_max, float(disp.max())), disp_sum + float(disp.sum())
            D["key"][idx] = voxel_keys(p_new, D["normal"][idx], cfg.voxel_size)
        del moved, which, anchors, table  # the re-hash below needs the memory (millions of surfels)
        before = len(self.store)
        self._rebuild_index(merge=True)
        return ReplacementStats(len(deltas), n_moved, before - len(self.store), disp_max, disp_sum / n_moved)

    def prune(self, min_confidence: float, min_age: int = 0) -> int:
        """Remove surfels with confidence < ``min_confidence`` created at least ``min_age`` integrations ago
        (Keller's removal of unstable points); returns how many were removed."""
        if not (math.isfinite(min_confidence) and min_confidence >= 0) or min_age < 0:
            raise CnnSlamError(f"prune needs min_confidence >= 0 and min_age >= 0, got {min_confidence}, {min_age}")
        drop = (self._col("confidence") < min_confidence) & (self._frames - self._col("first_seen") >= min_age)
        n = int(drop.sum())
        if n:
            self._remove_rows(np.flatnonzero(~drop))
        return n

    def _remove_rows(self, keep: np.ndarray) -> None:
        """Keep the surfels ``keep`` (increasing ids) and drop the others, with the key index the re-sort of
        :meth:`_rebuild_index` would give (kept by :meth:`SurfelStore.remove_rows` where the keys are distinct)."""
        if not self.store.remove_rows(keep):
            self._rebuild_index(merge=False)

    def _rebuild_index(self, merge: bool) -> None:
        """Sort the keys again; with ``merge``, surfels sharing a key are combined into one (weights add)."""
        self.store.drop_index()  # rebuilt below; not kept beside the re-hash's temporaries
        order, first = self.store.key_runs()
        if merge and not first.all():
            self._combine(order, first)
            del order, first
            self.store.reindex(np.arange(len(self.store)))  # the combined rows are in key order
        else:
            self.store.reindex(order)

    def _combine(self, order: np.ndarray, first: np.ndarray) -> None:
        """Merge each run of surfels sharing a key (``order``, sorted by key, runs starting where ``first``) into its
        first member; the model keeps one surfel per run, in run (key) order. Runs of one surfel are copied as they
        are; the weighted means are computed for the runs of several only, so that the float64 work and the memory
        scale with the merges, not with the model (a re-placement after a long episode merges a few per cent of
        millions of surfels). Their label evidence adds (the evidence of every measurement fused into any of them,
        Sec. 3.5)."""
        D = self.store.columns
        evidence = self.store.evidence
        continues = np.zeros(first.size, bool)  # the next position is of the same run
        np.logical_not(first[1:], out=continues[:-1])
        several = continues[first]  # per run: has more than one member
        multi = np.flatnonzero(several)
        merged: dict[str, np.ndarray] = {}
        if multi.size:
            in_multi = continues
            in_multi[1:] |= ~first[1:]  # a member of a run of several: continued, or continuing one
            sub = order[in_multi]  # the members of the runs of several, run by run
            sub_starts = np.flatnonzero(first[in_multi])  # where each of those runs starts in ``sub``
            del in_multi, continues

            def add(values: np.ndarray) -> np.ndarray:  # values of the members in ``sub`` order
                return np.add.reduceat(values, sub_starts, axis=0)

            W = D["weight"][sub].astype(np.float64)
            c = D["confidence"][sub].astype(np.float64)
            W_sum, c_sum = add(W), add(c)
            merged["position"] = add(W[:, None] * D["position"][sub]) / W_sum[:, None]
            normal = add(W[:, None] * D["normal"][sub])
            merged["normal"] = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
            merged["colour"] = add(c[:, None] * D["colour"][sub]) / c_sum[:, None]
            merged["radius"] = add(c * D["radius"][sub]) / c_sum
            merged["weight"], merged["confidence"] = W_sum, c_sum
            merged["evidence"] = add(evidence[sub].astype(np.float64))
            merged["n_obs"] = np.maximum.reduceat(D["n_obs"][sub], sub_starts)
            merged["first_seen"] = np.minimum.reduceat(D["first_seen"][sub], sub_starts)
            merged["misses"] = np.minimum.reduceat(D["misses"][sub], sub_starts)
        lead = order[first]  # per run, the member with the strongest anchor
        # the lead's values, the merged ones where a run had several members (one column at a time)
        self.store.gather(lead, {name: (multi, values) for name, values in merged.items()})


def _group(inverse: np.ndarray, n_groups: int, rows: np.ndarray, x_world: np.ndarray, n_world: np.ndarray,
           colour: np.ndarray, radius: np.ndarray, weight: np.ndarray, alpha: np.ndarray, probs: np.ndarray | None,
           label_weight: np.ndarray) -> _Measurements:
    """Average the measurements ``rows`` per group (``inverse`` maps each row to its group): step 3's one observation
    per frame and target (:func:`~cnnslam.model.surfel_kernels.group_kernel`)."""
    has_probs = probs is not None
    p = np.ascontiguousarray(probs, dtype=np.float32) if has_probs else np.zeros((1, 1), np.float32)
    position, normal, col, rad, w, a, pr, lw = group_kernel(
        np.ascontiguousarray(inverse, dtype=np.int64), int(n_groups), np.ascontiguousarray(rows, dtype=np.int64),
        np.ascontiguousarray(x_world, dtype=np.float64), np.ascontiguousarray(n_world, dtype=np.float64),
        np.ascontiguousarray(colour, dtype=np.float32), np.ascontiguousarray(radius, dtype=np.float64),
        np.ascontiguousarray(weight, dtype=np.float64), np.ascontiguousarray(alpha, dtype=np.float64), p, has_probs,
        np.ascontiguousarray(label_weight, dtype=np.float64))
    return _Measurements(position, normal, col, rad, w, a, pr if has_probs else None, lw)


def _checked_view(depth: np.ndarray, T_world_cam: np.ndarray, intrinsics: np.ndarray,
                  variance: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(depth float32 (H, W), T float64 (4, 4), intrinsics float64 (4,)) of one view, or one clear error."""
    depth = np.asarray(depth, dtype=np.float32)
    if depth.ndim != 2:
        raise CnnSlamError(f"depth must be (H, W) metres, got shape {depth.shape}")
    T = np.asarray(T_world_cam, dtype=np.float64)
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise CnnSlamError(f"T_world_cam must be a finite (4, 4) transform, got shape {T.shape}")
    intr = np.asarray(intrinsics, dtype=np.float64).reshape(-1)
    if intr.shape != (4,) or not np.isfinite(intr).all() or intr[0] <= 0 or intr[1] <= 0:
        raise CnnSlamError(f"intrinsics must be [fx, fy, cx, cy] with positive focal lengths, got {intrinsics!r}")
    if variance is not None and np.shape(variance) != depth.shape:
        raise CnnSlamError(f"variance must be (H, W) = {depth.shape}, got {np.shape(variance)}")
    return depth, T, intr


def _take(meas: _Measurements, mask: np.ndarray) -> _Measurements:
    return _Measurements(meas.position[mask], meas.normal[mask], meas.colour[mask], meas.radius[mask],
                         meas.weight[mask], meas.alpha[mask], None if meas.probs is None else meas.probs[mask],
                         meas.label_weight[mask])
