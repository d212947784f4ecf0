"""The one configuration of CNN-SLAM: a frozen dataclass per stage of the paper's Fig. 2, each field with its source.

Sources: "paper" (Tateno et al., CVPR 2017), "LSD" (tum-vision/lsd_slam, the paper's baseline [4]; its constants are
listed in ``../shared/notes/reference-facts.md`` sec. 4 and in LSD-SLAM's ``util/settings.{h,cpp}``), "ours" (a
choice the paper and LSD-SLAM do not make for us; the comment says why).

Resolution note: LSD-SLAM runs at 640x480 and tracks on pyramid levels 1..4 (320x240 down to 40x30), never at full
resolution. CNN-SLAM runs every stage but the CNN at 320x240 (paper Sec. 4), which is LSD-SLAM's level 1. So our
level 0 (320x240) is LSD's level 1 and every per-level LSD constant is shifted by one level.

Switches for the paper's ablation (Fig. 3) and for the baselines of the paper's Table 1 (LSD, LSD-BS) are fields of
this same config (:func:`ablation_config`, :func:`baseline_config`): the baselines are configurations of this code,
not forks of it.

Usage::

    cfg = CnnSlamConfig()                                   # the paper's system
    cfg = cfg.with_overrides({"depth.focal_adjustment": False, "refinement.enabled": False})
    cfg = ablation_config("adjusted")                       # Fig. 3 (b)
    cfg = baseline_config("lsd_bs")                         # LSD-SLAM with ground-truth scale bootstrap
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Literal, get_args

from cnnslam.errors import CnnSlamError
from slamcommon.config import Configurable

DepthSource = Literal["cnn", "constant", "random", "ground_truth_first"]
RefinementDensity = Literal["dense", "semi_dense"]
MotionModel = Literal["constant_velocity", "last_pose"]
AblationName = Literal["raw", "adjusted", "refined"]
BaselineName = Literal["cnn_slam", "lsd", "lsd_constant", "lsd_bs"]
OutputTrajectory = Literal["final", "online"]

DEPTH_SOURCES: tuple[str, ...] = get_args(DepthSource)
REFINEMENT_DENSITIES: tuple[str, ...] = get_args(RefinementDensity)
MOTION_MODELS: tuple[str, ...] = get_args(MotionModel)
ABLATIONS: tuple[str, ...] = get_args(AblationName)
BASELINES: tuple[str, ...] = get_args(BaselineName)
OUTPUT_TRAJECTORIES: tuple[str, ...] = get_args(OutputTrajectory)


def _positive(section: str, name: str, value: float, allow_zero: bool = False) -> None:
    ok = value >= 0 if allow_zero else value > 0
    if not ok or value != value:  # NaN check without numpy
        bound = ">= 0" if allow_zero else "> 0"
        raise CnnSlamError(f"{section}.{name} must be {bound}, got {value!r}")


def _choice(section: str, name: str, value: str, valid: tuple[str, ...]) -> None:
    if value not in valid:
        raise CnnSlamError(f"{section}.{name} must be one of {', '.join(valid)}, got {value!r}")


@dataclass(frozen=True)
class TrackingConfig:
    """Frame-to-key-frame direct tracking (CNN-SLAM Sec. 3.1, eq. 1-4; LSD-SLAM's SE3Tracker)."""

    # LSD: 5 levels at 640x480 (40x30 at the top); at 320x240 the same image sizes are 4 levels.
    pyramid_levels: int = 4
    # LSD: SE3TRACKING_MIN_LEVEL = 1 at 640x480, i.e. 320x240 = our level 0.
    finest_level: int = 0
    # LSD maxIterations {5, 20, 50, 100, 100} on its levels 0..4; ours are its levels 1..4.
    max_iterations: tuple[int, ...] = (20, 50, 100, 100)
    # LSD convergenceEps: stop a level when E_new / E_old > 0.999.
    convergence_eps: float = 0.999
    # LSD stepSizeMin: stop when the squared norm of the pose update (rad, m) is below this.
    step_size_min: float = 1e-8
    # LSD lambdaSuccessFac / lambdaFailFac; lambda starts at 0 and jumps to 0.2 on the first failure (LSD).
    lambda_success_factor: float = 0.5
    lambda_fail_factor: float = 2.0
    lambda_first_fail: float = 0.2
    # LSD minUseGrad: a pixel is used where the 3x3 max of |grad I| (8-bit intensities) is at least this.
    min_gradient: float = 5.0
    # LSD cameraPixelNoise2 = 4^2: sigma_I^2 of eq. 1's residual uncertainty (intensity levels^2).
    photometric_variance: float = 16.0
    # LSD var_weight: multiplies the propagated depth variance in the residual uncertainty.
    depth_variance_weight: float = 1.0
    # LSD huber_d / 2 = 1.5: Huber threshold on r / sigma(r) (eq. 1's rho).
    huber_threshold: float = 1.5
    # LSD MAX_DIFF_CONSTANT = 40^2 and MAX_DIFF_GRAD_MULT = 0.5^2: a residual is "good" when
    # r^2 / (MAX_DIFF_CONSTANT + MAX_DIFF_GRAD_MULT * |grad I|^2) < 1.
    max_diff_constant: float = 1600.0
    max_diff_grad_mult: float = 0.25
    # LSD MIN_GOODPERGOODBAD_PIXEL: a frame is lost when good / (good + bad) residuals fall below this.
    min_good_per_good_bad: float = 0.5
    # LSD MIN_GOODPERALL_PIXEL: ... or when good residuals are fewer than this share of the finest level's pixels.
    min_good_per_all: float = 0.04
    # Ours: ... or when eq. 1's energy per point at the solution exceeds max(energy_floor, max_energy_ratio *
    # E_null), E_null being the energy of the key-frame's own intensities about their median (what an alignment
    # that explains nothing leaves). LSD's "good" residual (|r| < 40 intensity levels) accepts most residuals of
    # low-contrast indoor images even for a wrong pose; a correct pose explains most of the key-frame's contrast
    # (E / E_null ~ 0.05-0.3), a wrong one none of it (~1). The floor (energy of residuals about twice sigma_I)
    # keeps nearly textureless key-frames, whose E_null is itself small, from being declared lost on noise.
    max_energy_ratio: float = 0.5
    energy_floor: float = 1.0
    # LSD MIN_GOODPERALL_PIXEL_ABSMIN: a level diverges when fewer points than this share of its pixels project in.
    min_points_per_all: float = 0.01
    # Initial guess of each frame's pose. LSD (useMotionModel = false) starts from the last pose; we start from a
    # constant-velocity prediction and fall back to the last pose when that tracks worse (ours).
    motion_model: MotionModel = "constant_velocity"
    # LSD INITIALIZATION_PHASE_COUNT: while the map has at most this many key-frames and key-frame depth does not
    # come from the CNN (the LSD baselines, whose first depth is random or constant and must first converge), a
    # frame counts as lost only when tracking diverges (LSD-SLAM does the same). With CNN depth it has no effect.
    initialization_keyframes: int = 5
    # Recovery after a lost frame: re-track against up to this many other key-frames near the last good pose
    # (LSD re-localises against key-frames found by findEuclideanOverlapFrames; ours: the number tried).
    recovery_candidates: int = 3
    # Ours, after DSO's photometric model: estimate each frame's affine brightness against its key-frame,
    # I_kf = exp(a) I_cur + b, jointly with the pose (an auto-exposure camera changes gain from frame to frame);
    # refinement compares the frame in the key-frame's brightness too. False: eq. 2 as the paper writes it, and the
    # LSD baselines' choice (LSD-SLAM's ROS default leaves its "EXPERIMENTAL" useAffineLightningEstimation off).
    # Measured (docs/benchmarks.md): Table-1 analogues SE(3) ATE -3 % (kinect camera) and -8 % (hard), real
    # redkitchen within its runs' spread, correct depth +0.5 to +1.2 points on both.
    affine_brightness: bool = True

    def validate(self) -> None:
        if not 1 <= self.pyramid_levels <= 8:
            raise CnnSlamError(f"tracking.pyramid_levels must be in 1..8, got {self.pyramid_levels}")
        if not 0 <= self.finest_level < self.pyramid_levels:
            raise CnnSlamError(
                f"tracking.finest_level must be in 0..{self.pyramid_levels - 1}, got {self.finest_level}"
            )
        if len(self.max_iterations) != self.pyramid_levels or min(self.max_iterations) < 1:
            raise CnnSlamError(
                f"tracking.max_iterations needs one positive count per pyramid level ({self.pyramid_levels}), "
                f"got {self.max_iterations}"
            )
        if not 0 < self.convergence_eps <= 1:
            raise CnnSlamError(f"tracking.convergence_eps must be in (0, 1], got {self.convergence_eps}")
        for name in ("photometric_variance", "huber_threshold", "max_diff_constant", "lambda_first_fail",
                     "max_energy_ratio", "energy_floor",
                     "lambda_fail_factor", "lambda_success_factor"):
            _positive("tracking", name, getattr(self, name))
        for name in ("min_gradient", "depth_variance_weight", "max_diff_grad_mult", "step_size_min",
                     "min_good_per_good_bad", "min_good_per_all", "min_points_per_all"):
            _positive("tracking", name, getattr(self, name), allow_zero=True)
        _choice("tracking", "motion_model", self.motion_model, MOTION_MODELS)
        if self.initialization_keyframes < 0:
            raise CnnSlamError(f"tracking.initialization_keyframes must be >= 0, got {self.initialization_keyframes}")
        if self.recovery_candidates < 0:
            raise CnnSlamError(f"tracking.recovery_candidates must be >= 0, got {self.recovery_candidates}")


@dataclass(frozen=True)
class KeyframeConfig:
    """Key-frame selection (CNN-SLAM Sec. 3.3: "if the currently estimated pose is far from that of existing
    key-frames"); the paper gives no rule, so LSD-SLAM's score is used."""

    # LSD KFDistWeight and KFUsageWeight: score = (dist * 4)^2 + ((1 - usage) * 3)^2, dist = |t_kf_cur| * mean
    # inverse depth of the key-frame, usage = share of key-frame points still seen (weighted by depth change).
    distance_weight: float = 4.0
    usage_weight: float = 3.0
    # LSD: a new key-frame when the score exceeds 1 (after its initialisation phase; CNN depth needs none).
    score_threshold: float = 1.0
    # LSD MIN_NUM_MAPPED = 5: at least this many frames tracked on a key-frame before it may be replaced.
    min_frames_per_keyframe: int = 5

    def validate(self) -> None:
        for name in ("distance_weight", "usage_weight", "score_threshold"):
            _positive("keyframes", name, getattr(self, name))
        if self.min_frames_per_keyframe < 0:
            raise CnnSlamError(f"keyframes.min_frames_per_keyframe must be >= 0, got {self.min_frames_per_keyframe}")


@dataclass(frozen=True)
class DepthConfig:
    """Key-frame depth and uncertainty initialisation (CNN-SLAM Sec. 3.2-3.3, eq. 5-9)."""

    # Where a key-frame's depth comes from. "cnn": the network on that frame (the paper). Without a CNN (the LSD
    # baselines) the first key-frame is initialised from "constant" depth, "random" depth (LSD's
    # initializeRandomly) or "ground_truth_first" (LSD-BS: the paper's scale bootstrap; needs an agent that
    # receives ground truth); later key-frames inherit depth propagated from the previous key-frame.
    source: DepthSource = "cnn"
    # Paper eq. 5 (Fig. 3 (a) vs (b)): multiply the CNN depth by f_cur / f_tr. False = raw CNN depth.
    focal_adjustment: bool = True
    # Paper eq. 7-9: fuse a new key-frame's CNN depth with the depth propagated from the nearest key-frame.
    fuse_with_previous: bool = True
    # Paper eq. 7: sigma_p^2, the white-noise variance added to propagated uncertainty (m^2). The paper gives no
    # value (nor does LSD-SLAM's code): ours, (5 cm)^2, about the error of a well-refined depth at 2-3 m.
    propagation_noise_variance: float = 0.0025
    # Occlusion test before eq. 7-9 (LSD DIFF_FAC_PROP_MERGE = 1: a propagated and an existing hypothesis are merged
    # only when diff^2 * factor <= the sum of their variances, else they see different surfaces). Here: the CNN's
    # prior (first_keyframe_relative_sigma * D)^2 plus eq. 7's U~. Pixels that fail keep the CNN depth with the
    # unmatched prior, as the neighbour saw another surface there (an occluder or what it hid).
    occlusion_diff_factor: float = 1.0
    # The very first key-frame has no neighbour for eq. 6. Ours: U = (r * D)^2 with r the CNN's typical relative
    # error (FCRN: rel 0.127 on NYU v2, reference-facts sec. 5), rounded up to 0.2.
    first_keyframe_relative_sigma: float = 0.2
    # Pixels of a new key-frame that eq. 6 cannot evaluate (the nearest key-frame does not see them) get the same
    # prior as the first key-frame (ours).
    unmatched_relative_sigma: float = 0.2
    # Floor on the uncertainty of eq. 6: U >= (r * D)^2. Without it a pixel where two CNN predictions agree
    # exactly would get U = 0 and could never be refined (ours).
    min_relative_sigma: float = 0.01
    # Ours, not in the paper: scale anchoring. Before eq. 6-9, the map carried over from the nearest key-frame is
    # rescaled towards the CNN by exp(gain * r), r = median log(D_cnn / D_kj) over the pixels both see
    # (:func:`cnnslam.keyframe.keyframes.scale_anchor`). Eq. 6 gives the CNN a large uncertainty exactly where the
    # map's scale
    # has drifted away from it (they disagree everywhere), so eq. 8 alone lets the monocular scale drift; the paper
    # counts on the CNN for absolute scale. 0 = the paper (no anchoring), 1 = the CNN's median scale at every
    # key-frame. Off by default: with the shipped network over the 9 full Table-1 sequences, 1 moved ATE / length
    # from 2.04 % to 2.24 % on average (living0 3.94 -> 3.33 %, living2 2.12 -> 4.56 %) and the scale error from
    # 26 to 19 % on living0 but from 5 to 19 % on living2: the CNN's scale jitter between key-frames (about 10 %)
    # then enters the map directly.
    scale_anchoring: float = 0.0
    # Ours, not in the paper: prediction scale alignment, the other direction. Before eq. 6-9, the new key-frame's
    # CNN depth is rescaled by exp(-gain * (q - target)), q being the CNN's log scale measured against the map (in
    # the first key-frame's units) and target the reference below: the key-frame's own swing of scale no longer
    # enters the map and the trajectory, while the CNN still sets the absolute scale. 0 = the paper, 1 = the
    # reference's scale.
    # Off by default (the paper): on the simulated Table-1 analogues at whole length (the paper's protocol) it costs
    # ATE and correct depth, though it helps at 400 frames (docs/investigations/kitchen-scale.md has the figures);
    # real frames played no part in the choice.
    prediction_scale_alignment: float = 0.0
    # What the CNN is aligned towards: "map", the nearest key-frame's scale; or "running_median", the median of the
    # CNN's scales at every key-frame so far (in the first key-frame's units), so that the absolute scale follows
    # the network's long-run median rather than the first key-frame's (ours).
    prediction_scale_reference: str = "running_median"
    # Where the CNN's scale is measured against the map: "all" pixels both key-frames see (the map there is mostly
    # the propagated CNN depth of earlier key-frames), or "stereo": only those where the neighbour's depth took at
    # least ``stereo_min_observations`` frames' small-baseline stereo (eq. 10-11), the images' own geometry at the map's
    # scale (ours, after DeepRelativeFusion, Loo et al. IROS 2021, which fits CNN depth to the SLAM's semi-dense depth).
    # Fewer than 100 such pixels (a key-frame whose neighbour saw no parallax): the CNN keeps the neighbour's scale
    # offset and only the pull towards the reference applies.
    prediction_scale_pixels: str = "stereo"
    stereo_min_observations: int = 3
    # Depth of the "constant" source (m) for the first key-frame; LSD-like inverse-depth variance below.
    constant_depth: float = 1.0
    # LSD initializeRandomly: inverse depth uniform in [0.5, 1.5] 1/m ...
    random_inverse_depth_range: tuple[float, float] = (0.5, 1.5)
    # ... with inverse-depth variance VAR_RANDOM_INIT_INITIAL = 0.5 * MAX_VAR = 0.125 (1/m)^2 (LSD).
    random_inverse_depth_variance: float = 0.125
    # LSD VAR_GT_INIT_INITIAL = 0.01^2 (1/m)^2: inverse-depth variance of a ground-truth-initialised key-frame.
    ground_truth_inverse_depth_variance: float = 1e-4

    def validate(self) -> None:
        _choice("depth", "source", self.source, DEPTH_SOURCES)
        for name in ("first_keyframe_relative_sigma", "unmatched_relative_sigma", "constant_depth",
                     "random_inverse_depth_variance", "ground_truth_inverse_depth_variance"):
            _positive("depth", name, getattr(self, name))
        _choice("depth", "prediction_scale_reference", self.prediction_scale_reference, ("map", "running_median"))
        _choice("depth", "prediction_scale_pixels", self.prediction_scale_pixels, ("all", "stereo"))
        if self.stereo_min_observations < 1:
            raise CnnSlamError(f"depth.stereo_min_observations must be >= 1, got {self.stereo_min_observations}")
        for name in ("scale_anchoring", "prediction_scale_alignment"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise CnnSlamError(f"depth.{name} must be in [0, 1], got {getattr(self, name)!r}")
        for name in ("propagation_noise_variance", "min_relative_sigma", "occlusion_diff_factor"):
            _positive("depth", name, getattr(self, name), allow_zero=True)
        lo, hi = self.random_inverse_depth_range
        if not 0 < lo < hi:
            raise CnnSlamError(f"depth.random_inverse_depth_range must be (lo, hi) with 0 < lo < hi, got {(lo, hi)}")

    @property
    def uses_cnn(self) -> bool:
        """True when key-frame depth comes from the CNN (False for the LSD baselines)."""
        return self.source == "cnn"


@dataclass(frozen=True)
class RefinementConfig:
    """Frame-wise depth refinement by small-baseline epipolar stereo (CNN-SLAM Sec. 3.4, eq. 10-11; the stereo is
    LSD-SLAM's / semi-dense VO's [5] ``doLineStereo``)."""

    # Paper Fig. 3 (c) vs (b): refine key-frame depth with every tracked frame.
    enabled: bool = True
    # "dense": every key-frame pixel is attempted (the paper); "semi_dense": only pixels with |grad I| >=
    # min_gradient_create, and without a CNN only those pixels carry depth at all (LSD-SLAM).
    density: RefinementDensity = "dense"
    # LSD MIN_ABS_GRAD_CREATE (= minUseGrad = 5): pixels of the semi-dense map.
    min_gradient_create: float = 5.0
    # LSD MIN_EPL_LENGTH_SQUARED, MIN_EPL_GRAD_SQUARED, MIN_EPL_ANGLE_SQUARED: a pixel is not searched when its
    # epipolar line is shorter than 1 px, its gradient along the line below 2, or the angle term below 0.3^2.
    min_epl_length_squared: float = 1.0
    min_epl_grad_squared: float = 4.0
    min_epl_angle_squared: float = 0.09
    # LSD STEREO_EPL_VAR_FAC: search inverse depth mean +- 2 standard deviations.
    search_sigmas: float = 2.0
    # LSD MAX_EPL_LENGTH_CROP / MIN_EPL_LENGTH_CROP: searched segment 3 to 30 px.
    max_epl_length: float = 30.0
    min_epl_length: float = 3.0
    # LSD GRADIENT_SAMPLE_DIST: the 5 SSD samples are 1 px apart along the epipolar line.
    sample_distance: float = 1.0
    # LSD SAMPLE_POINT_TO_BORDER: search positions stay this many px inside the image.
    border: float = 7.0
    # LSD MAX_ERROR_STEREO: reject when the best SSD over the 5 samples exceeds 4 * 1300 ...
    max_error_stereo: float = 1300.0
    # LSD MIN_DISTANCE_ERROR_STEREO: ... or when a non-adjacent second best is within a factor 1.5 (ambiguous).
    min_distance_error_stereo: float = 1.5
    # LSD useSubpixelStereo = true.
    subpixel: bool = True
    # LSD: the search is skipped when the depth ratio between the frames (rescale factor) leaves [0.7, 1.4].
    min_rescale: float = 0.7
    max_rescale: float = 1.4
    # LSD MIN_DEPTH = 0.05 m: nearest depth searched for a pixel without a prior (max inverse depth 20).
    min_depth: float = 0.05
    # LSD SUCC_VAR_INC_FAC: the prior variance is inflated by 1.01 before each fusion, so that it never collapses.
    prior_variance_inflation: float = 1.01
    # LSD MAX_VAR = 0.5^2 (1/m)^2: a semi-dense hypothesis whose inverse-depth variance exceeds this is dropped.
    max_inverse_depth_variance: float = 0.25
    # The photometric noise sigma_I^2 of the observation variance (LSD cameraPixelNoise2, as in tracking).
    photometric_variance: float = 16.0
    # LSD DIFF_FAC_OBSERVE: an observation is an outlier, and not fused, when factor * (D_t - D_ki)^2 exceeds
    # U_t + U_ki (a chi-square gate; LSD-SLAM's updateKeyframe). 0 fuses every observation.
    outlier_factor: float = 1.0

    def validate(self) -> None:
        _choice("refinement", "density", self.density, REFINEMENT_DENSITIES)
        for name in ("min_epl_length", "max_epl_length", "sample_distance", "max_error_stereo",
                     "min_distance_error_stereo", "min_rescale", "max_rescale", "min_depth", "search_sigmas",
                     "max_inverse_depth_variance", "photometric_variance"):
            _positive("refinement", name, getattr(self, name))
        for name in ("min_gradient_create", "min_epl_length_squared", "min_epl_grad_squared",
                     "min_epl_angle_squared", "border", "outlier_factor"):
            _positive("refinement", name, getattr(self, name), allow_zero=True)
        if self.min_epl_length > self.max_epl_length:
            raise CnnSlamError(
                f"refinement.min_epl_length ({self.min_epl_length}) must not exceed max_epl_length "
                f"({self.max_epl_length})"
            )
        if not self.min_rescale < self.max_rescale:
            raise CnnSlamError(f"refinement.min_rescale must be below max_rescale, got {self.min_rescale}")
        if self.prior_variance_inflation < 1:
            raise CnnSlamError(f"refinement.prior_variance_inflation must be >= 1, got {self.prior_variance_inflation}")


@dataclass(frozen=True)
class PoseGraphConfig:
    """Key-frame pose graph (CNN-SLAM Sec. 3.3: edges to key-frames "that share a similar field of view (i.e.
    having a small relative pose)", global optimisation at each new key-frame)."""

    enabled: bool = True
    # LSD findCandidates: neighbours within (|t| * mean inverse depth)^2 < closenessTH * 15 / KFDistWeight^2
    # with closenessTH = 1 ...
    neighbour_distance_squared: float = 15.0 / 16.0
    # ... and viewing directions within 1 - 0.25 * closenessTH = 0.75 of the mean field of view (LSD).
    neighbour_angle_fov_fraction: float = 0.75
    # LSD maxLoopClosureCandidates: at most this many candidate key-frames are aligned per new key-frame.
    max_candidates: int = 10
    # Levels of the key-frame-to-key-frame direct alignment (coarse to fine). LSD's constraint search runs its
    # Sim3 tracker on levels 4..1 at 640x480, i.e. ours 3..0; we stop at level 1 to keep the key-frame thread fast
    # (ours).
    alignment_finest_level: int = 1
    # An edge is accepted when both directions track well and agree (LSD checks the reciprocal tracking too):
    # |log(T_ij T_ji)| translation below this times the mean depth, rotation below the angle (ours).
    consistency_translation_relative: float = 0.02
    consistency_rotation_deg: float = 1.0
    # Edges to key-frames further back than this in creation order count as loop closures (reported) (ours).
    loop_min_index_gap: int = 5
    # LSD maxOptimizationIterations = 100; given to scipy's least_squares as its evaluation budget per variable.
    max_iterations: int = 100

    def validate(self) -> None:
        for name in ("neighbour_distance_squared", "neighbour_angle_fov_fraction", "consistency_translation_relative",
                     "consistency_rotation_deg"):
            _positive("pose_graph", name, getattr(self, name))
        if self.max_candidates < 0 or self.max_iterations < 1 or self.loop_min_index_gap < 1:
            raise CnnSlamError(
                "pose_graph.max_candidates must be >= 0, max_iterations >= 1, loop_min_index_gap >= 1; got "
                f"{self.max_candidates}, {self.max_iterations}, {self.loop_min_index_gap}"
            )
        if self.alignment_finest_level < 0:
            raise CnnSlamError(f"pose_graph.alignment_finest_level must be >= 0, got {self.alignment_finest_level}")


LabelWeighting = Literal["confidence", "precision"]
LABEL_WEIGHTINGS: tuple[str, ...] = get_args(LabelWeighting)


@dataclass(frozen=True)
class GlobalModelConfig:
    """The global model (CNN-SLAM Sec. 3.5, Fig. 1c): surfel fusion of the key-frames' depth and class
    probabilities (Keller et al. 3DV 2013 unless marked ours). :mod:`cnnslam.model.global_model` implements it."""

    # Paper Sec. 3.5 / 4: the key-frame thread fuses every key-frame into the model live (at its switch, then
    # re-placed at the final pose-graph poses at the end). False: no model (the agent hands back none).
    enabled: bool = True

    # Ours: voxel edge (m) of the hash that bounds the model: at most one surfel per voxel and normal direction.
    voxel_size: float = 0.02
    # Ours: fuse every s-th pixel in both directions (1 = all; the radius grows with s).
    pixel_stride: int = 1
    # Keller: sigma of the radial confidence weight alpha = exp(-gamma^2 / (2 sigma^2)).
    radial_sigma: float = 0.6
    # Ours: depth sigma = this x depth where no variance map is given (about a refined CNN depth's error).
    default_relative_sigma: float = 0.05
    # Ours: floor on a measurement's depth sigma (m), so that no single measurement dominates the average.
    min_depth_sigma: float = 0.005
    # Ours: measurements with sigma_d above this x depth are not fused (unconverged CNN-SLAM pixels).
    max_relative_sigma: float = 0.5
    # Ours: association tolerance = clip(k sqrt(sigma_d^2 + sigma_s^2), min, max) metres (Keller: a fixed delta).
    association_sigmas: float = 3.0
    min_association_distance: float = 0.02
    max_association_distance: float = 0.15
    # Keller delta_norm = 20 deg; ours 60 deg: normals of CNN / refined depth are off by about 30 deg (median, on
    # the simulator); the test only has to keep different sides and orientations (90-180 deg) apart.
    max_normal_angle_deg: float = 60.0
    # Ours, after KinectFusion's bilateral filter: where the raw normals are noisy, normals come from the depth
    # smoothed by a bilateral filter in log depth (spatial sigma in pixels; range sigma relative to depth) with
    # central differences ``normal_step_px`` apart; where they agree with their neighbours the raw ones are kept
    # (:func:`cnnslam.model.icp.adaptive_normal_map`). Positions always use the raw depth. 0 px = raw normals only
    # (exact
    # depth). With 1 px and 2-pixel steps the median normal error of refined key-frame depth on the simulator drops
    # from 55 to 30 degrees, while 90 % of the normals of exact depth stay exact.
    normal_smoothing_px: float = 1.0
    normal_smoothing_relative: float = 0.1
    normal_step_px: int = 2
    # Ours: measurements seen at a more grazing angle are not fused (their depth error is large).
    max_incidence_deg: float = 80.0
    # Ours: neighbouring depths differing by more than this fraction are an edge: no normal, no measurement.
    max_relative_depth_jump: float = 0.05
    # Ours: splat radius cap (pixels) of a surfel in the association index map.
    max_splat_radius_px: float = 3.0
    # Ours: depth range (m) of fused measurements.
    min_depth: float = 0.1
    max_depth: float = 10.0
    # Ours: a surfel "missed" by this many frames, and by more frames than confirmed it, is removed (0 = never) ...
    max_misses: int = 2
    # ... where a frame misses a surfel when it does not merge into it although the depth it measures at the
    # surfel's pixel lies more than this behind the surfel (metres): the frame sees through it (free space).
    # Negative: also a measurement up to that much in front of it (a duplicate layer). On office0 with 3000 frames
    # (69 key-frames, development predictor): 0.1 m -> 587k surfels, accuracy 7.1 cm, completeness 88 % within 5 cm;
    # -0.15 m -> 313k, 8.3 cm, 84 %; never -> 796k, 7.0 cm, 93 %.
    miss_margin: float = 0.1
    # Keller's removal of unstable points, per key-frame fused (0 = never): a surfel whose confidence (sum of alpha)
    # is still below this ``unstable_age`` key-frames after it was made is removed. 1.0: it must be seen again.
    # Off by default: measured with the network on office0, office1, living0 (500 frames, seed 0), 1.0 keeps 46 % of
    # the surfels (the model's memory) and the median accuracy (8.4 -> 8.2 cm, 9.1 -> 8.7, 25.5 -> 29.4) but the
    # share of seen surfaces within 5 cm falls from 63 / 61 / 15 % to 44 / 47 / 11 %.
    unstable_confidence: float = 0.0
    unstable_age: int = 3
    # Ours: a key-frame whose pose moved less than this (m, deg) is not re-placed (the motion accumulates).
    replace_min_translation: float = 1e-4
    replace_min_rotation_deg: float = 0.01
    # The paper's 4 NYU super-classes (sim_envs.frames.SemanticClass).
    num_classes: int = 4
    # How much one frame's class probabilities count in a surfel's label distribution: "confidence" = alpha (the
    # GSM of [27] averages frames; Keller's alpha discounts the image border); "precision" (ours, an option) =
    # alpha x (min_depth_sigma / sigma_d)^2, so labels attached to an uncertain depth count less (on office0 with
    # the development predictor it changed the fused accuracy by less than 0.1 point).
    label_weighting: LabelWeighting = "confidence"

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        for name in ("voxel_size", "radial_sigma", "default_relative_sigma", "min_depth_sigma", "max_relative_sigma",
                     "association_sigmas", "min_association_distance", "max_association_distance",
                     "max_relative_depth_jump", "max_splat_radius_px", "min_depth", "max_depth"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise CnnSlamError(f"global_model.{name} must be a positive number, got {value!r}")
        if not (self.normal_smoothing_px >= 0 and self.normal_smoothing_relative > 0):
            raise CnnSlamError("global_model.normal_smoothing_px must be >= 0 and normal_smoothing_relative > 0, got "
                               f"{self.normal_smoothing_px}, {self.normal_smoothing_relative}")
        if not (math.isfinite(self.unstable_confidence) and self.unstable_confidence >= 0
                and isinstance(self.unstable_age, int) and self.unstable_age >= 0):
            raise CnnSlamError("global_model.unstable_confidence must be >= 0 and unstable_age an integer >= 0, got "
                               f"{self.unstable_confidence!r}, {self.unstable_age!r}")
        if not (isinstance(self.max_misses, int) and self.max_misses >= 0):
            raise CnnSlamError(f"global_model.max_misses must be an integer >= 0, got {self.max_misses!r}")
        if not (isinstance(self.normal_step_px, int) and self.normal_step_px >= 1):
            raise CnnSlamError(f"global_model.normal_step_px must be an integer >= 1, got {self.normal_step_px!r}")
        if not (isinstance(self.pixel_stride, int) and self.pixel_stride >= 1):
            raise CnnSlamError(f"global_model.pixel_stride must be an integer >= 1, got {self.pixel_stride!r}")
        if self.min_association_distance > self.max_association_distance:
            raise CnnSlamError("global_model.min_association_distance must not exceed max_association_distance, got "
                               f"{self.min_association_distance} > {self.max_association_distance}")
        if self.min_depth >= self.max_depth:
            raise CnnSlamError(f"global_model.min_depth ({self.min_depth}) must be below max_depth ({self.max_depth})")
        for name in ("max_normal_angle_deg", "max_incidence_deg"):
            if not 0 < getattr(self, name) <= 90:
                raise CnnSlamError(f"global_model.{name} must be in (0, 90] degrees, got {getattr(self, name)}")
        if self.replace_min_translation < 0 or self.replace_min_rotation_deg < 0:
            raise CnnSlamError("global_model.replace_min_translation / replace_min_rotation_deg must be >= 0")
        if self.label_weighting not in LABEL_WEIGHTINGS:
            raise CnnSlamError(f"global_model.label_weighting must be one of {', '.join(LABEL_WEIGHTINGS)}, got "
                               f"{self.label_weighting!r}")
        if not 1 <= self.num_classes < 255:  # 255 = slamcommon.labels.NO_LABEL
            raise CnnSlamError(f"global_model.num_classes must be in 1..254, got {self.num_classes}")


@dataclass(frozen=True)
class SystemConfig:
    """The two threads of the paper (Sec. 4) and determinism."""

    # Paper Sec. 4: a frame thread (tracking + refinement) and a key-frame thread (CNN, key-frame initialisation
    # and fusion, pose graph). False: everything in the caller's thread, in a fixed order (deterministic; tests).
    threads: bool = True
    # Seeds the numpy Generator of the "random" depth source (the only randomness of the system). With the
    # "ground_truth_first" source (LSD-BS), a seed > 0 perturbs the bootstrapped depth in its last float32 bits (2 ulp):
    # the spread another CPU shows, for a method that is otherwise deterministic given the images.
    seed: int = 0
    # Ours (memory): besides the active key-frame, this many of the newest key-frames keep their tracking working
    # set (image pyramid, gradient masks, tracking points: 2.7 MB at 320x240); older ones drop it and make it again,
    # with the same bytes, when recovery or a pose-graph alignment uses them. Bounds a long sequence's memory.
    working_keyframes: int = 3
    # Ours (memory): once the global model has fused a key-frame's CNN class probabilities (Sec. 3.5), the key-frame
    # keeps only their argmax (uint8, 1/8 of the float16 distribution); True keeps the distributions too (e.g. for
    # `cnnslam map`, whose replays fuse them again). Changes no output but the key-frames' label_probs.
    keep_label_probabilities: bool = False
    # Which trajectory the agent hands back at the end (ours; the paper does not say which one Table 1 scores):
    # "final", every frame re-expressed through its key-frame's pose-graph-optimised pose (T_world_kf T_kf_cur), what
    # the system writes as its TUM file (:meth:`cnnslam.agent.CnnSlamAgent.save_trajectory`) and what LSD-SLAM's
    # key-frame graph gives; "online", the poses answered frame by frame while tracking.
    output_trajectory: OutputTrajectory = "final"

    def validate(self) -> None:
        _choice("system", "output_trajectory", self.output_trajectory, OUTPUT_TRAJECTORIES)
        if self.seed < 0:
            raise CnnSlamError(f"system.seed must be >= 0, got {self.seed}")
        if self.working_keyframes < 0:
            raise CnnSlamError(f"system.working_keyframes must be >= 0, got {self.working_keyframes}")


@dataclass(frozen=True)
class CnnSlamConfig(Configurable):
    """Every parameter of the system, one section per stage. Frozen; derive variants with :meth:`with_overrides`
    (:func:`slamcommon.config.with_overrides`: dotted keys, values checked against the fields' types)."""

    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    keyframes: KeyframeConfig = field(default_factory=KeyframeConfig)
    depth: DepthConfig = field(default_factory=DepthConfig)
    refinement: RefinementConfig = field(default_factory=RefinementConfig)
    pose_graph: PoseGraphConfig = field(default_factory=PoseGraphConfig)
    system: SystemConfig = field(default_factory=SystemConfig)
    global_model: GlobalModelConfig = field(default_factory=GlobalModelConfig)

    def __post_init__(self) -> None:
        for f in fields(self):
            getattr(self, f.name).validate()
        if self.pose_graph.alignment_finest_level >= self.tracking.pyramid_levels:
            raise CnnSlamError(
                f"pose_graph.alignment_finest_level ({self.pose_graph.alignment_finest_level}) must be below "
                f"tracking.pyramid_levels ({self.tracking.pyramid_levels})"
            )


def ablation_config(name: AblationName, base: CnnSlamConfig | None = None) -> CnnSlamConfig:
    """The paper's Fig. 3 variants: "raw" CNN depth (no eq. 5, no refinement), "adjusted" (eq. 5, no refinement),
    "refined" (eq. 5 and eq. 10-11: the full system)."""
    _choice("ablation", "name", name, ABLATIONS)
    base = base or CnnSlamConfig()
    if name == "raw":
        return base.with_overrides({"depth.focal_adjustment": False, "refinement.enabled": False})
    if name == "adjusted":
        return base.with_overrides({"depth.focal_adjustment": True, "refinement.enabled": False})
    return base.with_overrides({"depth.focal_adjustment": True, "refinement.enabled": True})


def baseline_config(name: BaselineName, base: CnnSlamConfig | None = None) -> CnnSlamConfig:
    """Configurations of this code that play the paper's Table-1 baselines.

    "cnn_slam": the paper's system. "lsd": LSD-SLAM-like: no CNN, random first key-frame depth, semi-dense
    refinement, depth propagated between key-frames. "lsd_constant": the same with a constant first depth.
    "lsd_bs": LSD-BS, the first key-frame's depth bootstrapped from ground truth (needs a ground-truth agent).
    The LSD baselines track with eq. 2 as written (no affine brightness, ``tracking.affine_brightness``), and build
    no global model (``global_model.enabled``; Table 1 scores their key-frame depth, as the paper does).
    """
    _choice("baseline", "name", name, BASELINES)
    base = base or CnnSlamConfig()
    if name == "cnn_slam":
        return base
    source = {"lsd": "random", "lsd_constant": "constant", "lsd_bs": "ground_truth_first"}[name]
    return base.with_overrides(
        {"depth.source": source, "refinement.enabled": True, "refinement.density": "semi_dense",
         "tracking.affine_brightness": False, "global_model.enabled": False}
    )
