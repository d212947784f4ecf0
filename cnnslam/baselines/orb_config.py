"""The configuration of the ORB-SLAM baseline (:mod:`cnnslam.baselines.orb`): one frozen dataclass, a source per field.

Sources: "ORB" (Mur-Artal et al., ORB-SLAM, T-RO 2015, and its code raulmur/ORB_SLAM2, the paper's [20]: its
constants are those of ``ORBmatcher``, ``Initializer``, ``Tracking``, ``LocalMapping`` and ``Optimizer``), "ours" (a
choice ORB-SLAM does not make for us, or one changed for 320x240 images; the comment says why). ORB-SLAM's pixel
constants are for 640x480; at 320x240 (the paper's resolution for everything but the CNN) a pixel spans twice the
angle, so search radii that are angular in nature are halved, while thresholds on reprojection errors (which are
about detector noise, about a pixel at any resolution) are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

from cnnslam.errors import CnnSlamError
from slamcommon.config import Configurable

CHI2_1DOF: float = 3.841  # ORB: chi-square 95 % with 1 degree of freedom (epipolar distance)
CHI2_2DOF: float = 5.991  # ORB: chi-square 95 % with 2 degrees of freedom (reprojection error)


@dataclass(frozen=True)
class OrbConfig(Configurable):
    """Every parameter of the ORB-SLAM baseline. Frozen; derive variants with :meth:`with_overrides`."""

    # ---- features (ORBextractor)
    # ORB: 1000 features per 640x480 image; ours keeps 1000 at 320x240 (denser, so that small images still give the
    # 100 initialisation matches ORB requires).
    n_features: int = 1000
    # ORB: scale factor 1.2 between pyramid levels, 8 levels.
    scale_factor: float = 1.2
    n_levels: int = 8
    # ORB: FAST threshold 20, 7 where a cell has nothing at 20; ours detects once at the low threshold and keeps the
    # strongest responses per grid cell (below).
    fast_threshold: int = 7
    # ORB EDGE_THRESHOLD = 19 and PATCH_SIZE = 31.
    edge_threshold: int = 19
    patch_size: int = 31
    # ORB distributes features over 30 px cells at 640x480; ours: 20 px cells at 320x240 (ORB's quadtree per level
    # is replaced by a per-cell cap on the strongest responses, topped up with the next strongest).
    grid_cell_px: int = 20
    # ---- descriptor matching (ORBmatcher)
    # ORB TH_HIGH = 100 and TH_LOW = 50 (Hamming distances of 256-bit descriptors).
    th_high: int = 100
    th_low: int = 50
    # ORB: nearest / second-nearest ratio 0.9 in initialisation and in projection searches, 0.6 for triangulation.
    ratio_init: float = 0.9
    ratio_projection: float = 0.9
    ratio_triangulation: float = 0.6
    # ORB SearchForInitialization window 100 px at 640x480; ours 50 px at 320x240.
    init_window_px: float = 50.0
    # ORB TrackWithMotionModel th = 15 px (x scale factor of the level) at 640x480; ours 7.5 px at 320x240.
    motion_radius_px: float = 7.5
    # ORB SearchLocalPoints th = 1 times r (2.5 or 4 by view angle) at 640x480; ours 3 px at 320x240.
    local_radius_px: float = 3.0
    # ORB SearchByProjection for fusing duplicates in neighbours: th = 3 px at 640x480; ours 2 px.
    fuse_radius_px: float = 2.0
    # ---- two-view initialisation (Initializer)
    # ORB: at least 100 matches between the reference and the current frame, else a new reference frame.
    init_min_matches: int = 100
    # ORB: 200 RANSAC iterations, sigma = 1 px.
    init_ransac_iterations: int = 200
    init_sigma_px: float = 1.0
    # ORB: homography chosen when R_H = S_H / (S_H + S_F) > 0.45.
    homography_ratio: float = 0.45
    # ORB ReconstructF / ReconstructH: minParallax 1 deg, minTriangulated 50; the best solution must triangulate at
    # least 90 % of the inliers and clearly beat the others (0.7 of it for F, 0.75 for H).
    min_parallax_deg: float = 1.0
    min_triangulated: int = 50
    min_good_share: float = 0.9
    ambiguity_ratio_f: float = 0.7
    ambiguity_ratio_h: float = 0.75
    # Ours (see cnnslam.baselines.orb_init): refuse when a pure rotation explains this share of the model's inliers.
    max_rotation_explained: float = 0.85
    # ORB CreateInitialMapMonocular: reset when fewer than 100 points survive the initial bundle adjustment; the
    # map is scaled so that the first key-frame's median depth is 1 (NO absolute scale).
    init_min_points: int = 100
    # ---- tracking (Tracking)
    # ORB: a frame is tracked with at least 30 inlier matches after TrackLocalMap (50 right after relocalisation).
    min_tracked_inliers: int = 30
    min_relocalised_inliers: int = 50
    # ORB: TrackWithMotionModel needs 20 matches (then TrackReferenceKeyFrame with 15).
    min_motion_matches: int = 20
    min_reference_matches: int = 15
    # ORB Relocalization: PnP RANSAC, at least 15 matches per candidate; ours tries the best `n` candidates of a
    # descriptor vote over all key-frames (ORB uses its bag-of-words database).
    relocalisation_candidates: int = 3
    pnp_iterations: int = 300
    pnp_reprojection_px: float = 3.0
    # ORB: a map with at most this many key-frames is reset when tracking is lost (then initialised again).
    reset_if_lost_with_keyframes: int = 5
    # ---- key-frames (Tracking::NeedNewKeyFrame, LocalMapping)
    # ORB: thRefRatio 0.9 for monocular (a new key-frame when the frame tracks fewer than 90 % of the reference
    # key-frame's points); ours requires also `keyframe_min_frames` frames since the last one (ORB inserts only
    # when local mapping is idle, which at 30 Hz on a desktop is every few frames) and inserts after at most
    # `keyframe_max_frames` (ORB: mMaxFrames = fps).
    keyframe_ref_ratio: float = 0.9
    keyframe_min_frames: int = 4
    keyframe_max_frames: int = 30
    # ORB: new points are triangulated with the 20 best covisible key-frames (monocular); ours 8 (speed, 2 cores).
    triangulation_neighbours: int = 8
    # ORB: a key-frame pair is triangulated when baseline / median scene depth > 0.01.
    min_baseline_ratio: float = 0.01
    # ORB CreateNewMapPoints: cos(parallax) of the two rays < 0.9998 (about 1.15 deg).
    max_cos_parallax: float = 0.9998
    # ORB: the scale-consistency check allows a ratio of 1.5 x the scale factor.
    scale_consistency: float = 1.5
    # ORB MapPointCulling: a recent point is removed when found in fewer than 25 % of the frames it should have been
    # visible in, or when two key-frames after its creation it is observed by at most 2 key-frames (monocular).
    min_found_ratio: float = 0.25
    # ORB KeyFrameCulling: a key-frame is redundant when 90 % of its points are seen by at least 3 other key-frames.
    redundant_share: float = 0.9
    redundant_observers: int = 3
    # ---- bundle adjustment (Optimizer)
    # ORB LocalBundleAdjustment: the covisible key-frames of the new one are optimised (ours: at most 10, by shared
    # points), every other key-frame that sees their points is held fixed (ours: at most 10).
    local_ba_keyframes: int = 10
    local_ba_fixed_keyframes: int = 10
    # ORB: 5 then 10 Levenberg-Marquardt iterations, outliers (chi2 > 5.991) removed in between. Ours the same
    # (g2o's LM, points marginalised), except that the Huber kernel stays on in the second run (ORB drops it).
    local_ba_rounds: tuple[int, int] = (5, 10)
    # ORB PoseOptimization: 4 rounds of 10 iterations, outliers re-classified each round at chi2 = 5.991.
    pose_rounds: int = 4
    pose_iterations: int = 10

    def __post_init__(self) -> None:
        for name in ("n_features", "n_levels", "grid_cell_px", "th_high", "th_low", "init_min_matches",
                     "init_ransac_iterations", "min_triangulated", "init_min_points", "min_tracked_inliers",
                     "min_relocalised_inliers", "min_motion_matches", "min_reference_matches",
                     "relocalisation_candidates", "pnp_iterations", "keyframe_max_frames", "triangulation_neighbours",
                     "redundant_observers", "local_ba_keyframes", "pose_rounds", "pose_iterations", "patch_size"):
            if int(getattr(self, name)) < 1:
                raise CnnSlamError(f"orb.{name} must be >= 1, got {getattr(self, name)!r}")
        for name in ("fast_threshold", "edge_threshold", "keyframe_min_frames", "reset_if_lost_with_keyframes",
                     "local_ba_fixed_keyframes"):
            if int(getattr(self, name)) < 0:
                raise CnnSlamError(f"orb.{name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("init_window_px", "motion_radius_px", "local_radius_px", "fuse_radius_px", "init_sigma_px",
                     "pnp_reprojection_px", "min_parallax_deg", "scale_consistency"):
            value = float(getattr(self, name))
            if not value > 0:
                raise CnnSlamError(f"orb.{name} must be > 0, got {value!r}")
        for name in ("ratio_init", "ratio_projection", "ratio_triangulation", "homography_ratio", "min_good_share",
                     "ambiguity_ratio_f", "ambiguity_ratio_h", "keyframe_ref_ratio", "max_cos_parallax",
                     "min_found_ratio", "redundant_share", "min_baseline_ratio", "max_rotation_explained"):
            value = float(getattr(self, name))
            if not 0 < value <= 1:
                raise CnnSlamError(f"orb.{name} must be in (0, 1], got {value!r}")
        if not self.scale_factor > 1:
            raise CnnSlamError(f"orb.scale_factor must be > 1, got {self.scale_factor!r}")
        if len(self.local_ba_rounds) != 2 or min(self.local_ba_rounds) < 1:
            raise CnnSlamError(f"orb.local_ba_rounds must be two positive counts, got {self.local_ba_rounds!r}")
        if self.keyframe_max_frames < self.keyframe_min_frames:
            raise CnnSlamError(f"orb.keyframe_max_frames ({self.keyframe_max_frames}) must be >= "
                               f"keyframe_min_frames ({self.keyframe_min_frames})")

    def level_scales(self) -> list[float]:
        """Scale factor of each pyramid level, ``scale_factor ** level``."""
        return [self.scale_factor**i for i in range(self.n_levels)]
