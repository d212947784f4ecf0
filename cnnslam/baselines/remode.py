"""REMODE (Pizzoli, Forster, Scaramuzza, ICRA 2014; the paper's [23]): per-pixel probabilistic monocular dense depth,
as a baseline agent on the LSD-BS trajectory, scored on depth only (CNN-SLAM Sec. 4.1, Table 1).

``"cnnslam.baselines.remode:RemodeAgent"``; keyword arguments (all optional)::

    RemodeAgent(config={"patch_size": 5, ...},        # RemodeConfig field overrides
                lsd_config={"section.field": value},   # overrides of the LSD-BS preset (cnnslam.config)
                threads=False,                         # LSD-BS's two threads, or deterministic single-thread
                seed=None)                             # LSD-BS's system.seed (None: the preset's)

The depth filter (:class:`DepthFilter`, usable alone with any poses):

- Every pixel of a reference image carries a "seed": the Vogiatzis-Hernandez (IVC 2011) posterior over its depth d
  (metres along the pixel's unit bearing vector, as in REMODE) and its inlier probability, a Gaussian x Beta
  ``N(d | mu, sigma^2) Beta(pi | a, b)``, initialised as REMODE does: mu = the middle of the scene's depth range,
  sigma^2 = range^2 / 36, a = b = 10.
- Each later frame with a known pose ``T_world_cam`` updates every seed still in play: the seed's depth interval
  mu +- 3 sigma projects to a segment of the epipolar line in the new frame; a 5x5 patch around the reference pixel
  is matched along it every 0.7 px by zero-mean normalised cross-correlation (ZNCC); the best match (ZNCC >= 0.5)
  is triangulated into a depth measurement x with the uncertainty tau of one pixel of disparity
  (:func:`triangulation_uncertainty`), and the posterior is updated by the moment-matched Gaussian x Beta update of
  Vogiatzis & Hernandez (:func:`vogiatzis_update`). A seed whose patch projects into the image but finds no match
  gets b += 1 (REMODE's NO_MATCH), so textureless pixels drift to outliers.
- A seed converges when its inlier ratio a / (a + b) > 0.7 and sigma falls below ``convergence_sigma_ratio`` times
  its depth; it diverges when (a - 1) / (a + b - 2) < 0.05 (REMODE's seedCheck).
- :func:`tv_smooth`: the final map is smoothed by a weighted Huber-ROF total-variation model, solved by the first-
  order primal-dual algorithm (Chambolle & Pock 2011): the regulariser is weighted per pixel by REMODE's
  G = E[pi] sigma^2 / sigma_max^2 + (1 - E[pi]) (confident pixels are smoothed little), the data term is active
  on converged pixels only. Pixels that have not converged are 0 in the output (no estimate).

The agent: LSD-BS (``cnnslam.agent``'s ``"lsd_bs"`` preset: LSD-SLAM with the first key-frame's depth from ground
truth, hence ``uses_ground_truth = True``; ground truth reaches nothing else) gives the pose of every frame and its
key-frames; each LSD-BS key-frame becomes a REMODE reference frame, updated by the following frames (up to
``max_updates``, at most ``max_active_references`` at a time) with the poses LSD-BS reports, re-expressed relative to
the key-frame's current (pose-graph optimised) pose. ``finish()`` returns LSD-BS's key-frames with REMODE's depth.
The trajectory it answers is LSD-BS's; Table 1 shows '-' for REMODE's ATE (the suite's choice, not the agent's).

The parts: :mod:`cnnslam.baselines.remode_search` (the equations, the epipolar ZNCC search and the seed update, numba
kernels) and :mod:`cnnslam.baselines.remode_smoothing` (the TV denoiser); this module holds the configuration, the
filter and the agent, and re-exports the parts' public names, so that ``from cnnslam.baselines.remode import ...``
and the ``"cnnslam.baselines.remode:RemodeAgent"`` entry point keep working.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from cnnslam.baselines.base import BaselineAgent

# the parts' public names are re-exported (``__all__``): users import them from this module; the private ones are
# the kernel and its checks, which DepthFilter calls
from cnnslam.baselines.remode_search import (
    _MAX_PACKED_SIDE,
    _NO_PAIRS,
    BORDER,
    CONVERGED,
    DIVERGED,
    FLAT,
    NO_MATCH,
    NOT_VISIBLE,
    SKIPPED,
    UPDATE,
    UPDATED,
    SearchImage,
    _check_pairs,
    _gray,
    _update_seeds,
    best_match,
    grey_levels,
    search_image,
    search_pairs,
    search_tables,
    triangulation_uncertainty,
    vogiatzis_update,
)
from cnnslam.baselines.remode_smoothing import tv_smooth
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import se3_inverse
from slamcommon.config import Configurable, configure

__all__ = [
    "BORDER", "CONVERGED", "DIVERGED", "FLAT", "NOT_VISIBLE", "NO_MATCH", "SKIPPED", "UPDATE", "UPDATED",
    "DepthFilter", "FilterUpdate", "RemodeAgent", "RemodeConfig", "SearchImage", "best_match", "depth_range_of",
    "grey_levels", "search_image", "search_pairs", "search_tables", "triangulation_uncertainty", "tv_smooth",
    "vogiatzis_update",
]



@dataclass(frozen=True)
class RemodeConfig(Configurable):
    """Every parameter of the REMODE baseline. Source: "REMODE" (Pizzoli et al. 2014 and rpg_open_remode), "VH"
    (Vogiatzis & Hernandez 2011), "SVO" (Forster et al. 2014, whose depth filter REMODE shares), or "ours"."""

    # REMODE: 5x5 ZNCC patches (RMD_CORR_PATCH_SIDE), samples every 0.7 px along the epipolar segment.
    patch_size: int = 5
    search_step_px: float = 0.7
    # REMODE caps the searched segment (MAX_EXTENT_EPIPOLAR_SEARCH); ours: 35 px at 320x240, chosen by a three-run
    # comparison against 50 px (results/perf_history.md: less time, correct depth within the seeds' spread).
    max_search_px: float = 35.0
    # REMODE: a match needs ZNCC >= 0.5, else NO_MATCH.
    min_zncc: float = 0.5
    # Ours: a template whose intensity standard deviation is below this (grey levels) has no defined ZNCC (REMODE's
    # ZNCC is then 0, a NO_MATCH); it is treated as NO_MATCH without searching.
    min_template_std: float = 1.0
    # REMODE seedInit: a = b = 10; sigma^2 = range^2 / 36 (the range covers +-3 sigma).
    init_a: float = 10.0
    init_b: float = 10.0
    # SVO / REMODE: the measurement noise is the depth change of one pixel of disparity.
    pixel_noise: float = 1.0
    # REMODE seedCheck: converged when a / (a + b) > eta_inlier and sigma^2 < epsilon; diverged when
    # (a - 1) / (a + b - 2) < eta_outlier.
    eta_inlier: float = 0.7
    eta_outlier: float = 0.05
    # REMODE's epsilon is an absolute variance set per scene; ours is relative: sigma < this x mu.
    convergence_sigma_ratio: float = 0.02
    # Depth range of a reference frame from its LSD-BS key-frame depth (ours; REMODE takes SVO's min/max feature
    # depth): the 2nd..98th percentiles widened by this factor on each side; `default_depth_range` when it has none.
    depth_range_margin: float = 1.5
    default_depth_range: tuple[float, float] = (0.3, 8.0)
    # Agent: a reference frame is updated by at most this many frames (ours; REMODE's reference frames live until
    # replaced), and at most this many reference frames are updated at a time (ours: the newest are kept).
    max_updates: int = 60
    max_active_references: int = 3
    # TV smoothing (REMODE's denoiser: 200 primal-dual iterations, Huber norm); lambda and epsilon are ours (depth
    # in metres): data weight (1/m) and Huber threshold (m per pixel).
    tv_iterations: int = 200
    tv_lambda: float = 50.0
    tv_huber_epsilon: float = 0.005
    tv_enabled: bool = True

    def __post_init__(self) -> None:
        if self.patch_size < 3 or self.patch_size % 2 == 0:
            raise CnnSlamError(f"remode.patch_size must be an odd number >= 3, got {self.patch_size!r}")
        for name in ("search_step_px", "max_search_px", "init_a", "init_b", "pixel_noise", "convergence_sigma_ratio",
                     "depth_range_margin", "tv_lambda", "tv_huber_epsilon"):
            if not float(getattr(self, name)) > 0:
                raise CnnSlamError(f"remode.{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("min_zncc", "eta_inlier", "eta_outlier"):
            if not 0 < float(getattr(self, name)) < 1:
                raise CnnSlamError(f"remode.{name} must be in (0, 1), got {getattr(self, name)!r}")
        if self.min_template_std < 0:
            raise CnnSlamError(f"remode.min_template_std must be >= 0, got {self.min_template_std!r}")
        lo, hi = self.default_depth_range
        if not 0 < lo < hi:
            raise CnnSlamError(f"remode.default_depth_range must be 0 < min < max, got {self.default_depth_range!r}")
        for name in ("max_updates", "max_active_references"):
            if int(getattr(self, name)) < 1:
                raise CnnSlamError(f"remode.{name} must be >= 1, got {getattr(self, name)!r}")
        if self.tv_iterations < 0:
            raise CnnSlamError(f"remode.tv_iterations must be >= 0, got {self.tv_iterations!r}")

# ------------------------------------------------------------------------------------------------ the filter


@dataclass(frozen=True)
class FilterUpdate:
    """What one frame did to a reference frame's seeds: counts of seeds updated, without a match (incl. flat
    templates), not visible; converged and diverged totals afterwards; wall time in milliseconds."""

    updated: int
    no_match: int
    not_visible: int
    converged: int
    diverged: int
    milliseconds: float


class DepthFilter:
    """REMODE's seeds of one reference frame (see the module docstring).

    reference: (H, W) uint8 or float grey image (or (H, W, 3) uint8 RGB); T_world_ref: (4, 4) float64 its pose;
    intrinsics: [fx, fy, cx, cy] pixels; depth_range: (min, max) metres of the scene, for the initial seeds and the
    uniform outlier density; config: :class:`RemodeConfig`.
    """

    def __init__(self, reference: np.ndarray, T_world_ref: np.ndarray, intrinsics: np.ndarray,
                 depth_range: tuple[float, float], config: RemodeConfig | None = None) -> None:
        self.config = config or RemodeConfig()
        self.reference = _gray(reference)
        # the search sums correlations two corners at a time when both images are grey levels (_best_match)
        self._packable = grey_levels(self.reference) and self.config.patch_size <= _MAX_PACKED_SIDE
        self.T_world_ref = np.array(T_world_ref, dtype=np.float64)
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64).reshape(4)
        lo, hi = (float(depth_range[0]), float(depth_range[1]))
        if not 0 < lo < hi:
            raise CnnSlamError(f"depth_range must be 0 < min < max metres, got {depth_range!r}")
        self.depth_min, self.depth_max = lo, hi
        self.depth_range = hi - lo
        h, w = self.reference.shape
        self.sigma2_max = self.depth_range**2 / 36.0
        self.mu = np.full((h, w), 0.5 * (lo + hi))
        self.sigma2 = np.full((h, w), self.sigma2_max)
        self.a = np.full((h, w), self.config.init_a)
        self.b = np.full((h, w), self.config.init_b)
        half = self.config.patch_size // 2
        self.state = np.full((h, w), UPDATE, np.uint8)
        self.state[:half + 1] = BORDER
        self.state[h - half - 1:] = BORDER
        self.state[:, :half + 1] = BORDER
        self.state[:, w - half - 1:] = BORDER
        k = (self.config.patch_size, self.config.patch_size)
        img = self.reference.astype(np.float64)
        self.template_mean = cv2.blur(img, k, borderType=cv2.BORDER_REFLECT)
        var = cv2.blur(img * img, k, borderType=cv2.BORDER_REFLECT) - self.template_mean**2
        self.template_std = np.sqrt(np.maximum(var, 0.0))
        fx, fy = self.intrinsics[:2]
        self.px_error_angle = 2.0 * math.atan(self.config.pixel_noise / (2.0 * 0.5 * (fx + fy)))
        u = (np.arange(w) - self.intrinsics[2]) / fx
        v = (np.arange(h) - self.intrinsics[3]) / fy
        self.ray_norm = np.sqrt(u[None, :] ** 2 + v[:, None] ** 2 + 1.0)  # |K^-1 (u, v, 1)|: depth along ray / z
        self.n_updates = 0
        self.milliseconds = 0.0

    def update(self, image: np.ndarray | SearchImage, T_world_cur: np.ndarray) -> FilterUpdate:
        """Update the seeds with one more image taken at ``T_world_cur`` ((4, 4)): (H, W) grey or (H, W, 3) uint8 RGB,
        or its :func:`search_image` (made once a frame when several reference frames use it)."""
        t0 = time.perf_counter()
        cur = image if isinstance(image, SearchImage) else search_image(image, self.config.patch_size)
        if cur.gray.shape != self.reference.shape:
            raise CnnSlamError(f"image of size {cur.gray.shape} for a reference of size {self.reference.shape}")
        if cur.pairs is not None:
            _check_pairs(cur.pairs, cur.gray.shape, "DepthFilter.update")
        if cur.patch_size != self.config.patch_size or cur.tables.shape != (*cur.gray.shape, 6):
            raise CnnSlamError(f"search tables of shape {cur.tables.shape} for {cur.patch_size}-pixel patches, but "
                               f"this filter matches {self.config.patch_size}-pixel patches on {cur.gray.shape} "
                               f"images: make them with search_image(image, {self.config.patch_size})")
        T_cur_ref = se3_inverse(np.asarray(T_world_cur, dtype=np.float64)) @ self.T_world_ref
        T_ref_cur = se3_inverse(T_cur_ref)
        cfg = self.config
        packed = self._packable and cur.pairs is not None
        params = np.array([cfg.patch_size // 2, cfg.search_step_px, cfg.max_search_px, cfg.min_zncc,
                           self.px_error_angle, cfg.eta_inlier, cfg.eta_outlier, cfg.convergence_sigma_ratio,
                           cfg.min_template_std])
        outcome = _update_seeds(self.reference, cur.gray, cur.tables, self.template_mean, self.template_std,
                                self.mu, self.sigma2, self.a, self.b, self.state,
                                np.ascontiguousarray(T_cur_ref[:3, :3]),
                                np.ascontiguousarray(T_cur_ref[:3, 3]), np.ascontiguousarray(T_ref_cur[:3, 3]),
                                self.intrinsics, self.depth_range, params,
                                cur.pairs if packed else _NO_PAIRS, packed)
        self.n_updates += 1
        ms = 1e3 * (time.perf_counter() - t0)
        self.milliseconds += ms
        counts = np.bincount(outcome.ravel(), minlength=5)
        return FilterUpdate(int(counts[UPDATED]), int(counts[NO_MATCH] + counts[FLAT]), int(counts[NOT_VISIBLE]),
                            int((self.state == CONVERGED).sum()), int((self.state == DIVERGED).sum()), ms)

    @property
    def converged(self) -> np.ndarray:
        """(H, W) bool: seeds that have converged."""
        return self.state == CONVERGED

    def inlier_probability(self) -> np.ndarray:
        """(H, W) E[pi] = a / (a + b)."""
        return self.a / (self.a + self.b)

    def depth(self, smooth: bool | None = None) -> np.ndarray:
        """(H, W) float32 planar depth z in metres of the converged seeds, 0 elsewhere; TV-smoothed when ``smooth``
        (default: ``config.tv_enabled``), with REMODE's confidence weights (see :func:`tv_smooth`)."""
        cfg = self.config
        smooth = cfg.tv_enabled if smooth is None else smooth
        conv = self.converged
        z = self.mu / self.ray_norm
        if smooth and conv.any() and cfg.tv_iterations > 0:
            pi = self.inlier_probability()
            g = pi * np.minimum(self.sigma2 / self.sigma2_max, 1.0) + (1.0 - pi)
            start = np.where(conv, z, float(np.median(z[conv])))
            z = tv_smooth(start, conv.astype(np.float64), g, cfg.tv_lambda, cfg.tv_huber_epsilon, cfg.tv_iterations)
        return np.where(conv & (z > 0), z, 0.0).astype(np.float32)

    def depth_variance(self) -> np.ndarray:
        """(H, W) float32 variance of the planar depth (m^2) of converged seeds, inf elsewhere."""
        var = self.sigma2 / self.ray_norm**2
        return np.where(self.converged, var, np.inf).astype(np.float32)



def depth_range_of(depth: np.ndarray, config: RemodeConfig) -> tuple[float, float]:
    """The scene depth range of a reference frame from a (sparse) depth map (metres, 0 = none): the 2nd..98th
    percentiles widened by ``depth_range_margin``; ``default_depth_range`` when fewer than 100 pixels have depth."""
    d = np.asarray(depth, dtype=np.float64)
    d = d[np.isfinite(d) & (d > 0)]
    if d.size < 100:
        return config.default_depth_range
    lo, hi = np.percentile(d, [2.0, 98.0])
    lo, hi = lo / config.depth_range_margin, hi * config.depth_range_margin
    return (float(max(lo, 1e-2)), float(max(hi, 2 * max(lo, 1e-2))))


# ------------------------------------------------------------------------------------------------ the agent


@dataclass
class _Reference:
    """A REMODE reference frame tied to an LSD-BS key-frame (its index and timestamp)."""

    keyframe: int
    timestamp: float
    filter: DepthFilter
    updates: int = 0


class RemodeAgent(BaselineAgent):
    """REMODE on the LSD-BS trajectory as a ``sim_envs`` agent (see the module docstring for the arguments).

    Depth only: Table 1 shows '-' for REMODE's ATE (the trajectory it answers is LSD-BS's). Receives ground truth
    (``uses_ground_truth = True``) for LSD-BS's first key-frame depth only.
    """

    uses_ground_truth = True
    name = "remode"

    def __init__(self, config: RemodeConfig | dict[str, Any] | None = None, lsd_config: dict[str, Any] | None = None,
                 threads: bool = False, seed: int | None = None) -> None:
        from cnnslam.agent import build_config

        super().__init__()
        self.config = configure(RemodeConfig(), config)
        lsd_overrides = dict(lsd_config or {})
        if seed is not None:
            lsd_overrides["system.seed"] = int(seed)
        self.lsd_config = build_config("lsd_bs", lsd_overrides, threads)
        self._system: Any = None
        self._active: list[_Reference] = []
        self._done: dict[int, tuple[np.ndarray, np.ndarray, dict[str, float]]] = {}
        self._ms: list[float] = []

    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        from cnnslam.system import CnnSlam

        if self._system is not None:
            self._system.close()
        self._system = CnnSlam(self.lsd_config, intrinsics, image_size, None)
        self._active, self._done, self._ms = [], {}, []

    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        """Track the frame with LSD-BS (``info["gt_depth"]`` bootstraps its first key-frame), update the active
        REMODE reference frames with it, and start one on each new LSD-BS key-frame. Answers LSD-BS's pose."""
        from cnnslam.depth.depth_prediction import GroundTruthHint

        hint = GroundTruthHint.from_info(info)
        out = self._system.process(observation["rgb"], timestamp, hint)
        gray = _gray(observation["rgb"])
        t0 = time.perf_counter()
        if out.tracked:
            keyframes = {k.index: k for k in self._system.keyframes}
            if self._active:  # the frame's search tables, once for every reference frame it updates
                current = search_image(gray, self.config.patch_size)
                for ref in list(self._active):
                    kf = keyframes[ref.keyframe]
                    # the frame's pose relative to the key-frame as LSD-BS holds it now, in the filter's frame
                    T_kf_cur = se3_inverse(kf.T_world_kf) @ out.T_world_cam
                    ref.filter.update(current, ref.filter.T_world_ref @ T_kf_cur)
                    ref.updates += 1
                    if ref.updates >= self.config.max_updates:
                        self._retire(ref)
            if out.new_keyframe:
                kf = keyframes[out.keyframe]
                rng = depth_range_of(kf.maps.depth, self.config)
                self._active.append(_Reference(kf.index, kf.timestamp,
                                               DepthFilter(gray, kf.T_world_kf, self._intrinsics, rng, self.config)))
                while len(self._active) > self.config.max_active_references:
                    self._retire(self._active[0])
        self._ms.append(1e3 * (time.perf_counter() - t0))
        return out.T_world_cam, out.tracked

    def _retire(self, ref: _Reference) -> None:
        """Finish a reference frame: its (smoothed) depth and variance are kept for ``finish``."""
        f = ref.filter
        depth = f.depth()
        stats = {"updates": float(ref.updates), "converged_share": float(f.converged.mean()),
                 "diverged_share": float((f.state == DIVERGED).mean()),
                 "ms_per_update": f.milliseconds / max(f.n_updates, 1)}
        self._done[ref.keyframe] = (depth, f.depth_variance(), stats)
        self._active.remove(ref)

    def _finish(self) -> Any:
        """An ``AgentOutput``: LSD-BS's key-frames (final poses) with REMODE's depth (0 where not converged)."""
        from sim_envs.agent import AgentOutput, KeyframeDepth

        for ref in list(self._active):
            self._retire(ref)
        result = self._system.finish()
        h, w = self._system.image_size
        keyframes = []
        per_kf = []
        for k in result.keyframes:
            depth, var, stats = self._done.get(k.index, (np.zeros((h, w), np.float32),
                                                         np.full((h, w), np.inf, np.float32), {"updates": 0.0}))
            keyframes.append(KeyframeDepth(timestamp=k.timestamp, depth=depth, T_world_cam=k.T_world_kf,
                                           uncertainty=var))
            per_kf.append({"keyframe": k.index, **stats, "density": float((depth > 0).mean())})
        ms = np.asarray(self._ms)
        extras: dict[str, Any] = {
            "lsd_bs": dict(result.stats),
            "remode_keyframes": per_kf,
            "remode_ms_per_frame": float(ms.mean()) if ms.size else 0.0,
            "mean_density": float(np.mean([p["density"] for p in per_kf])) if per_kf else 0.0,
            "trajectory": "lsd_bs",
            "config": self.config.to_dict(),
            "lsd_config": self.lsd_config.to_dict(),
        }
        return AgentOutput(keyframes=keyframes, extras=extras)
