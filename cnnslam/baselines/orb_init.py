"""Two-view initialisation of the ORB-SLAM baseline (ORB-SLAM's ``Initializer``, with OpenCV's estimators).

From matched pixels of a reference and a current frame, both an essential matrix (``cv2.findEssentialMat``, 5-point
solver) and a homography (``cv2.findHomography``) are fitted with OpenCV's locally optimised RANSAC
(``USAC_ACCURATE``; ORB-SLAM fits a fundamental matrix with plain 8-point RANSAC: on rendered pairs plain RANSAC
left up to 15 % of the inliers of the true model unexplained and its motion several degrees off) and scored with
ORB-SLAM's symmetric transfer-error score; the homography is
chosen when ``S_H / (S_H + S_F) > 0.45`` (planar or low-parallax scenes). Each model's motion hypotheses (4 from the
essential matrix, up to 4 from ``cv2.decomposeHomographyMat``) are checked by triangulating every inlier (ORB-SLAM's
``CheckRT``: finite, in front of both cameras unless at infinity, reprojection error below 2 sigma in both images).
The best hypothesis is accepted only if it triangulates most inliers, clearly beats the others, and its points see
enough parallax (at least 1 degree for the 51st-largest parallax). Under a pure rotation every hypothesis explains
the points equally well with no parallax, so initialisation fails, as ORB-SLAM does on TUM fr1/rpy (CNN-SLAM Sec.
4.2): nothing here fakes a baseline. One guard is ours: ORB-SLAM relies on the score ratio and the parallax test
alone, and on our renders a pure rotation slipped past both (R_H = 0.45, a 1.2 degree "parallax" from keypoint
noise on a few points); so the initialisation is also refused when a rotation-only model explains at least 85 % of
the chosen model's inliers (:func:`rotation_explained_share`; measured on renders: 52-75 % where hand-held
sequences initialised, 95-100 % on a pure rotation).

Poses: ``T_cur_ref`` maps reference-camera coordinates into current-camera coordinates; its translation has unit
length (the scale of a monocular map is arbitrary; :mod:`cnnslam.baselines.orb` fixes it by median depth = 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from cnnslam.baselines.orb_config import CHI2_1DOF, CHI2_2DOF, OrbConfig

COS_AT_INFINITY: float = 0.99998  # ORB CheckRT: rays this parallel count as a point at infinity (about 0.36 deg)


@dataclass(frozen=True)
class TwoViewResult:
    """Outcome of one initialisation attempt.

    success: the map may be created; reason: why not (or "ok"); model: "essential" or "homography";
    T_cur_ref: (4, 4) float64 with |t| = 1 (identity on failure); points_ref: (K, 3) float64 triangulated points in
    reference-camera coordinates (arbitrary units); match_index: (K,) int64 rows of the input matches they came
    from; parallax_deg: ORB-SLAM's parallax figure of the chosen hypothesis; n_inliers: inliers of the chosen model;
    score_ratio: S_H / (S_H + S_F).
    """

    success: bool
    reason: str
    model: str
    T_cur_ref: np.ndarray
    points_ref: np.ndarray
    match_index: np.ndarray
    parallax_deg: float
    n_inliers: int
    score_ratio: float


def _failure(reason: str, model: str = "", n_inliers: int = 0, ratio: float = float("nan"),
             parallax: float = 0.0) -> TwoViewResult:
    return TwoViewResult(False, reason, model, np.eye(4), np.zeros((0, 3)), np.zeros(0, np.int64), parallax,
                         n_inliers, ratio)


def _normalised(uv: np.ndarray, K: np.ndarray) -> np.ndarray:
    """K^-1 (u, v, 1): (N, 2) pixels -> (N, 2) normalised image coordinates."""
    return (uv - K[:2, 2]) / np.array([K[0, 0], K[1, 1]])


def triangulate(T_a_world: np.ndarray, T_b_world: np.ndarray, xa: np.ndarray, xb: np.ndarray) -> np.ndarray:
    """Linear (DLT) triangulation of normalised coordinates xa, xb ((N, 2)) seen by cameras with extrinsics
    ``T_a_world``, ``T_b_world`` ((4, 4), world -> camera). Returns (N, 3) float64 world points (NaN where the
    homogeneous coordinate vanishes)."""
    if len(xa) == 0:
        return np.zeros((0, 3))
    X = cv2.triangulatePoints(T_a_world[:3].astype(np.float64), T_b_world[:3].astype(np.float64),
                              xa.T.astype(np.float64), xb.T.astype(np.float64))
    w = X[3]
    with np.errstate(divide="ignore", invalid="ignore"):
        pts = (X[:3] / np.where(np.abs(w) > 1e-12, w, np.nan)).T
    return pts


def score_fundamental(F: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, sigma: float) -> tuple[float, np.ndarray]:
    """ORB-SLAM's CheckFundamental: score sum over matches and both images of (5.991 - d^2 / sigma^2) where the
    squared point-to-epipolar-line distance d^2 / sigma^2 < 3.841, and the inlier mask (both images under it)."""
    h1 = np.c_[uv1, np.ones(len(uv1))]
    h2 = np.c_[uv2, np.ones(len(uv2))]
    l2 = h1 @ F.T  # lines in image 2
    l1 = h2 @ F  # lines in image 1
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = np.einsum("ij,ij->i", l2, h2) ** 2 / (l2[:, 0] ** 2 + l2[:, 1] ** 2) / sigma**2
        d1 = np.einsum("ij,ij->i", l1, h1) ** 2 / (l1[:, 0] ** 2 + l1[:, 1] ** 2) / sigma**2
    d1, d2 = np.nan_to_num(d1, nan=np.inf), np.nan_to_num(d2, nan=np.inf)
    ok1, ok2 = d1 < CHI2_1DOF, d2 < CHI2_1DOF
    score = np.where(ok1, CHI2_2DOF - d1, 0.0).sum() + np.where(ok2, CHI2_2DOF - d2, 0.0).sum()
    return float(score), ok1 & ok2


def score_homography(H: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, sigma: float) -> tuple[float, np.ndarray]:
    """ORB-SLAM's CheckHomography: score sum of (5.991 - e^2 / sigma^2) over both transfer directions where the
    squared transfer error e^2 / sigma^2 < 5.991, and the inlier mask (both directions under it)."""
    Hinv = np.linalg.inv(H)
    h1 = np.c_[uv1, np.ones(len(uv1))]
    h2 = np.c_[uv2, np.ones(len(uv2))]
    with np.errstate(divide="ignore", invalid="ignore"):
        p21 = h1 @ H.T
        p21 = p21[:, :2] / p21[:, 2:]
        p12 = h2 @ Hinv.T
        p12 = p12[:, :2] / p12[:, 2:]
    e2 = np.nan_to_num(((uv2 - p21) ** 2).sum(1) / sigma**2, nan=np.inf)
    e1 = np.nan_to_num(((uv1 - p12) ** 2).sum(1) / sigma**2, nan=np.inf)
    ok1, ok2 = e1 < CHI2_2DOF, e2 < CHI2_2DOF
    score = np.where(ok1, CHI2_2DOF - e1, 0.0).sum() + np.where(ok2, CHI2_2DOF - e2, 0.0).sum()
    return float(score), ok1 & ok2


@dataclass(frozen=True)
class _Check:
    n_good: int
    good: np.ndarray  # (N,) bool: triangulated with parallax (used for the map)
    points: np.ndarray  # (N, 3) in the first camera
    parallax_deg: float


def check_rt(R: np.ndarray, t: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, K: np.ndarray, th2: float) -> _Check:
    """ORB-SLAM's CheckRT for the motion (R, t) of camera 2 relative to camera 1 (x2 = R x1 + t).

    A match counts as good when its triangulated point is finite, in front of both cameras (unless the rays are
    parallel: a point at infinity), and reprojects within ``th2`` squared pixels in both images; only those with
    parallax (cos < 0.99998) are kept for the map. parallax_deg: the 51st-largest parallax (or the smallest one
    when fewer), 0 when none.
    """
    T1 = np.eye(4)
    T2 = np.eye(4)
    T2[:3, :3], T2[:3, 3] = R, t
    P = triangulate(T1, T2, _normalised(uv1, K), _normalised(uv2, K))
    finite = np.isfinite(P).all(axis=1)
    P_safe = np.where(finite[:, None], P, 0.0)
    o2 = -R.T @ t
    n1 = P_safe
    n2 = P_safe - o2
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_par = np.einsum("ij,ij->i", n1, n2) / (np.linalg.norm(n1, axis=1) * np.linalg.norm(n2, axis=1))
    cos_par = np.nan_to_num(cos_par, nan=1.0)
    P2 = P_safe @ R.T + t
    infinity = cos_par >= COS_AT_INFINITY
    front = ((P_safe[:, 2] > 0) & (P2[:, 2] > 0)) | infinity
    with np.errstate(divide="ignore", invalid="ignore"):
        proj1 = P_safe[:, :2] / P_safe[:, 2:] * [K[0, 0], K[1, 1]] + K[:2, 2]
        proj2 = P2[:, :2] / P2[:, 2:] * [K[0, 0], K[1, 1]] + K[:2, 2]
    e1 = np.nan_to_num(((proj1 - uv1) ** 2).sum(1), nan=np.inf)
    e2 = np.nan_to_num(((proj2 - uv2) ** 2).sum(1), nan=np.inf)
    ok = finite & front & (e1 <= th2) & (e2 <= th2)
    n_good = int(ok.sum())
    parallax = 0.0
    if n_good:
        cos_sorted = np.sort(cos_par[ok])
        parallax = float(np.degrees(np.arccos(np.clip(cos_sorted[min(50, n_good - 1)], -1.0, 1.0))))
    good = ok & ~infinity
    return _Check(n_good, good, P_safe, parallax)


def ransac_order(n: int, rng: np.random.Generator | None) -> np.ndarray:
    """(n,) int64 order in which to hand n matches to an OpenCV RANSAC: ``arange(n)`` without a generator, else a
    permutation drawn from ``rng``.

    OpenCV's USAC and PnP RANSAC draw their minimal samples from a generator whose state is fixed inside OpenCV, so
    the same inputs always give the same model; permuting the inputs makes them draw other samples, the effect of a
    RANSAC seed. The models are scored on every match afterwards, so the order changes nothing else.
    """
    return np.arange(n) if rng is None else rng.permutation(n)


def initialize_two_view(uv_ref: np.ndarray, uv_cur: np.ndarray, K: np.ndarray, config: OrbConfig,
                        rng: np.random.Generator | None = None, inv_sigma_ref: np.ndarray | None = None,
                        inv_sigma_cur: np.ndarray | None = None, refine: bool = True) -> TwoViewResult:
    """Try to initialise a map from matched pixels (N, 2) of the reference and the current frame (see the module
    docstring). K: (3, 3) intrinsics. ``rng`` (None: the matches' own order) reorders the matches given to OpenCV's
    RANSAC (:func:`ransac_order`): another seed, other minimal samples.

    refine: the accepted motion and points are refined by a two-view bundle adjustment (reference camera fixed;
    ORB-SLAM's global bundle adjustment in CreateInitialMapMonocular), weighting each match by ``inv_sigma_ref`` /
    ``inv_sigma_cur`` ((N,) 1 / sigma of the keypoints' pyramid levels; 1 when not given). Observations that
    end with chi2 > 5.991 are dropped from the result.
    """
    uv_ref = np.asarray(uv_ref, dtype=np.float64)
    uv_cur = np.asarray(uv_cur, dtype=np.float64)
    n = len(uv_ref)
    if n < config.init_min_matches:
        return _failure(f"{n} matches < {config.init_min_matches}")
    # OpenCV's USAC keeps its own generator state (cv2.setRNGSeed does not reach it): a seeded run hands it the
    # matches in another order, so that it draws other minimal samples, which is what another RANSAC seed does
    order = ransac_order(n, rng)
    sigma = config.init_sigma_px
    E, _ = cv2.findEssentialMat(uv_ref[order], uv_cur[order], K, method=cv2.USAC_ACCURATE, prob=0.999,
                                threshold=float(np.sqrt(CHI2_1DOF) * sigma), maxIters=config.init_ransac_iterations)
    H, _ = cv2.findHomography(uv_ref[order], uv_cur[order], cv2.USAC_ACCURATE, float(np.sqrt(CHI2_2DOF) * sigma),
                              maxIters=config.init_ransac_iterations, confidence=0.999)
    score_f, inl_f, Es = -1.0, np.zeros(n, bool), []
    if E is not None and E.shape[0] >= 3:
        Kinv = np.linalg.inv(K)
        for k in range(E.shape[0] // 3):  # the 5-point solver may return several candidates
            Ek = E[3 * k: 3 * k + 3]
            s, inl = score_fundamental(Kinv.T @ Ek @ Kinv, uv_ref, uv_cur, sigma)
            if s > score_f:
                score_f, inl_f, Es = s, inl, [Ek]
    score_h, inl_h = -1.0, np.zeros(n, bool)
    if H is not None and np.isfinite(H).all() and abs(np.linalg.det(H)) > 1e-12:
        score_h, inl_h = score_homography(H, uv_ref, uv_cur, sigma)
    if score_f <= 0 and score_h <= 0:
        return _failure("no model could be fitted")
    ratio = max(score_h, 0.0) / (max(score_h, 0.0) + max(score_f, 0.0))
    th2 = 4.0 * sigma**2
    model, inliers = ("homography", inl_h) if ratio > config.homography_ratio else ("essential", inl_f)
    explained = rotation_explained_share(uv_ref[inliers], uv_cur[inliers], K, sigma)
    if explained >= config.max_rotation_explained:
        return _failure(f"{model}: a pure rotation explains {100 * explained:.0f} % of the inliers (no parallax)",
                        model, int(inliers.sum()), ratio)
    if model == "homography":
        res = _reconstruct_h(H, inl_h, uv_ref, uv_cur, K, th2, config, ratio)
    else:
        res = _reconstruct_f(Es[0], inl_f, uv_ref, uv_cur, K, th2, config, ratio)
    if not res.success or not refine:
        return res
    ones = np.ones(n)
    return refine_two_view(res, uv_ref, uv_cur, K, ones if inv_sigma_ref is None else np.asarray(inv_sigma_ref),
                           ones if inv_sigma_cur is None else np.asarray(inv_sigma_cur))


def rotation_explained_share(uv1: np.ndarray, uv2: np.ndarray, K: np.ndarray, sigma: float,
                             iterations: int = 4) -> float:
    """Share of the matches (N, 2) that the best pure rotation explains (ours; see the module docstring).

    The rotation R with b2 = R b1 for the bearing vectors b = K^-1 (u, v, 1) / |.| is fitted by SVD (Kabsch) and
    refitted on its own inliers; a match is explained when both transfer errors of the homography K R K^-1 are
    below chi2 = 5.991 sigma^2 (ORB-SLAM's homography inlier test).
    """
    n = len(uv1)
    if n < 3:
        return 0.0
    Kinv = np.linalg.inv(K)
    b1 = np.c_[uv1, np.ones(n)] @ Kinv.T
    b2 = np.c_[uv2, np.ones(n)] @ Kinv.T
    b1 /= np.linalg.norm(b1, axis=1)[:, None]
    b2 /= np.linalg.norm(b2, axis=1)[:, None]
    use = np.ones(n, bool)
    inl = use
    for _ in range(iterations):
        U, _, Vt = np.linalg.svd(b2[use].T @ b1[use])
        R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
        _, inl = score_homography(K @ R @ Kinv, uv1, uv2, sigma)
        if inl.sum() < 3:
            break
        use = inl
    return float(inl.mean())


def refine_two_view(res: TwoViewResult, uv_ref: np.ndarray, uv_cur: np.ndarray, K: np.ndarray,
                    inv_sigma_ref: np.ndarray, inv_sigma_cur: np.ndarray) -> TwoViewResult:
    """Two-view bundle adjustment of an accepted initialisation (reference camera fixed), |t| renormalised to 1."""
    from cnnslam.baselines.orb_ba import bundle_adjust  # local import: orb_ba imports nothing from here

    idx = res.match_index
    k = len(idx)
    intr = np.array([K[0, 0], K[1, 1], K[0, 2], K[1, 2]])
    cams = np.stack([np.eye(4), res.T_cur_ref])
    obs_cam = np.r_[np.zeros(k, np.int64), np.ones(k, np.int64)]
    obs_pt = np.r_[np.arange(k), np.arange(k)]
    ba = bundle_adjust(cams, np.array([True, False]), res.points_ref, obs_cam, obs_pt,
                       np.r_[uv_ref[idx], uv_cur[idx]], np.r_[inv_sigma_ref[idx], inv_sigma_cur[idx]], intr,
                       iterations=20)
    T = ba.T_cam_world[1].copy()
    scale = 1.0 / max(float(np.linalg.norm(T[:3, 3])), 1e-12)
    T[:3, 3] *= scale
    pts = ba.points * scale
    keep = (ba.chi2[:k] <= CHI2_2DOF) & (ba.chi2[k:] <= CHI2_2DOF) & (pts[:, 2] > 0)
    keep &= (pts @ T[:3, :3].T + T[:3, 3])[:, 2] > 0
    return TwoViewResult(True, "ok", res.model, T, pts[keep], idx[keep], res.parallax_deg, res.n_inliers,
                         res.score_ratio)


def _accept(model: str, R: np.ndarray, t: np.ndarray, check: _Check, inliers: np.ndarray, ratio: float,
            n_inliers: int) -> TwoViewResult:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t / np.linalg.norm(t)
    scale = 1.0 / np.linalg.norm(t)
    idx = np.flatnonzero(inliers)[check.good[inliers]]
    return TwoViewResult(True, "ok", model, T, check.points[idx] * scale, idx.astype(np.int64), check.parallax_deg,
                         n_inliers, ratio)


def _reconstruct_f(E: np.ndarray, inliers: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, K: np.ndarray, th2: float,
                   config: OrbConfig, ratio: float) -> TwoViewResult:
    """ORB-SLAM's ReconstructF on the essential matrix's four (R, t) hypotheses."""
    n_in = int(inliers.sum())
    R1, R2, t = cv2.decomposeEssentialMat(E)
    t = t.reshape(3)
    hyps = [(R1, t), (R2, t), (R1, -t), (R2, -t)]
    checks = [check_rt(R, tt, uv1[inliers], uv2[inliers], K, th2) for R, tt in hyps]
    goods = np.array([c.n_good for c in checks])
    best = int(np.argmax(goods))
    min_good = max(int(config.min_good_share * n_in), config.min_triangulated)
    similar = int((goods > config.ambiguity_ratio_f * goods[best]).sum())
    c = checks[best]
    if goods[best] < min_good:
        return _failure(f"essential: {goods[best]} good points < {min_good}", "essential", n_in, ratio, c.parallax_deg)
    if similar > 1:
        return _failure("essential: ambiguous motion (no parallax?)", "essential", n_in, ratio, c.parallax_deg)
    if c.parallax_deg < config.min_parallax_deg:
        return _failure(f"essential: parallax {c.parallax_deg:.2f} deg < {config.min_parallax_deg}", "essential",
                        n_in, ratio, c.parallax_deg)
    full = _Check(c.n_good, _expand(c.good, inliers), _expand_points(c.points, inliers), c.parallax_deg)
    return _accept("essential", hyps[best][0], hyps[best][1], full, inliers, ratio, n_in)


def _reconstruct_h(H: np.ndarray, inliers: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, K: np.ndarray, th2: float,
                   config: OrbConfig, ratio: float) -> TwoViewResult:
    """ORB-SLAM's ReconstructH on the homography's motion hypotheses (``cv2.decomposeHomographyMat``)."""
    n_in = int(inliers.sum())
    _, Rs, ts, _ = cv2.decomposeHomographyMat(H, K)
    hyps = [(np.asarray(R), np.asarray(tt).reshape(3)) for R, tt in zip(Rs, ts, strict=True)]
    hyps = [(R, tt) for R, tt in hyps if np.linalg.norm(tt) > 1e-9]
    if not hyps:
        return _failure("homography: no translation (pure rotation)", "homography", n_in, ratio)
    checks = [check_rt(R, tt, uv1[inliers], uv2[inliers], K, th2) for R, tt in hyps]
    goods = np.array([c.n_good for c in checks])
    order = np.argsort(-goods, kind="stable")
    best = int(order[0])
    second = int(goods[order[1]]) if len(order) > 1 else 0
    c = checks[best]
    min_good = max(int(config.min_good_share * n_in), config.min_triangulated)
    if goods[best] < min_good:
        return _failure(f"homography: {goods[best]} good points < {min_good}", "homography", n_in, ratio,
                        c.parallax_deg)
    if second >= config.ambiguity_ratio_h * goods[best]:
        return _failure("homography: ambiguous motion (no parallax?)", "homography", n_in, ratio, c.parallax_deg)
    if c.parallax_deg < config.min_parallax_deg:
        return _failure(f"homography: parallax {c.parallax_deg:.2f} deg < {config.min_parallax_deg}", "homography",
                        n_in, ratio, c.parallax_deg)
    full = _Check(c.n_good, _expand(c.good, inliers), _expand_points(c.points, inliers), c.parallax_deg)
    return _accept("homography", hyps[best][0], hyps[best][1], full, inliers, ratio, n_in)


def _expand(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    out = np.zeros(mask.shape[0], dtype=values.dtype)
    out[mask] = values
    return out


def _expand_points(points: np.ndarray, mask: np.ndarray) -> np.ndarray:
    out = np.zeros((mask.shape[0], 3))
    out[mask] = points
    return out
