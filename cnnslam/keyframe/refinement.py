"""Frame-wise depth refinement (CNN-SLAM Sec. 3.4, eq. 10-11) by small-baseline epipolar stereo.

For every new tracked frame t, each key-frame pixel u gets a depth observation D_t(u) with uncertainty U_t(u) from
the semi-dense stereo of LSD-SLAM / semi-dense VO [5] (``DepthMap::doLineStereo``): 5 intensity samples 1 px apart
along the epipolar line in the key-frame are matched by SSD against 5 samples stepping 1 px at a time along the
epipolar segment in frame t that the pixel's current depth +- 2 standard deviations allows (3 to 30 px), the best
match is refined to sub-pixel precision, and its inverse depth triangulated. The observation variance is
LSD-SLAM's: alpha^2 (discretisation + geometric + photometric disparity error), alpha = d(inverse depth) / d(pixel
along the line), the geometric error growing where the line is parallel to the image gradient, the photometric
error 4 sigma_I^2 / (gradient along the line)^2. The observation is then fused with the key-frame's depth by eq. 10-11.

The paper does this DENSELY (``RefinementConfig.density = "dense"``): every pixel is attempted. A pixel whose
epipolar line is too short, whose gradient along the line is too weak or at too steep an angle (LSD-SLAM's checks),
or whose match is ambiguous or too poor, gets U_t = infinity, the limit in which eq. 10-11 leave it unchanged: it
keeps the CNN depth, exactly the paper's "elements within low-textured regions gradually hold the predicted depth".
``"semi_dense"`` attempts only high-gradient pixels (LSD-SLAM); without a CNN, pixels without a depth get one from
a search over the whole inverse-depth range [0, 1 / MIN_DEPTH] (LSD-SLAM's hypothesis creation).

Hot loop: one numba kernel over the key-frame (``@njit(cache=True, nogil=True)``), built from named steps compiled
into it (the epipolar line, the search range, the segment, the SSD search, sub-pixel refinement, triangulation, the
observation variance); its settings are one :class:`StereoSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from cnnslam.config import RefinementConfig
from cnnslam.errors import CnnSlamError

_MIN_IDEPTH = 1e-3  # 1/m: observations farther than 1 km carry no usable depth indoors (ours)

# status codes of the per-pixel search (counted in RefinementStats)
OK, SKIPPED, EPL_SHORT, EPL_GRAD, EPL_ANGLE, OUT_OF_IMAGE, BIG_ERROR, AMBIGUOUS, BAD_DEPTH = range(9)
STATUS_NAMES = ("ok", "skipped", "epl_short", "epl_grad", "epl_angle", "out_of_image", "big_error", "ambiguous",
                "bad_depth")


class StereoSettings(NamedTuple):
    """The epipolar search's settings (a :class:`RefinementConfig`'s numeric fields, LSD-SLAM's constants), as one
    immutable record of named fields that the compiled kernels take whole (numba types a ``NamedTuple``; it does not
    type dataclasses). Built by :meth:`from_config`."""

    min_epl_length_squared: float  # px^2: shorter epipolar lines are not searched (LSD MIN_EPL_LENGTH_SQUARED)
    min_epl_grad_squared: float  # squared gradient along the line below which a pixel is skipped (LSD)
    min_epl_angle_squared: float  # squared cosine between the line and the gradient below which it is skipped
    search_sigmas: float  # the prior's inverse depth +- this many standard deviations is searched (LSD)
    max_epl_length: float  # px: longest searched segment (LSD MAX_EPL_LENGTH_CROP)
    min_epl_length: float  # px: shortest searched segment (LSD MIN_EPL_LENGTH_CROP)
    sample_distance: float  # px between the SSD samples (LSD GRADIENT_SAMPLE_DIST)
    border: float  # px: search positions stay this far inside the image (LSD SAMPLE_POINT_TO_BORDER)
    max_error_stereo: float  # SSD above which a match is rejected (LSD MAX_ERROR_STEREO)
    min_distance_error_stereo: float  # factor of a non-adjacent second best that makes a match ambiguous (LSD)
    min_rescale: float  # the depth ratio between the frames must lie in (min_rescale, max_rescale) (LSD)
    max_rescale: float
    max_idepth_create: float  # 1/m: the inverse-depth search range's top without a prior (1 / MIN_DEPTH, LSD)
    photometric_variance: float  # sigma_I^2 of the photometric disparity error (LSD cameraPixelNoise2)
    subpixel: bool  # refine the best match to sub-pixel precision (LSD useSubpixelStereo)

    @classmethod
    def from_config(cls, cfg: RefinementConfig) -> StereoSettings:
        """The settings of ``cfg`` (floats as float64, so that the kernel computes in float64 throughout)."""
        return cls(
            float(cfg.min_epl_length_squared), float(cfg.min_epl_grad_squared), float(cfg.min_epl_angle_squared),
            float(cfg.search_sigmas), float(cfg.max_epl_length), float(cfg.min_epl_length),
            float(cfg.sample_distance), float(cfg.border), float(cfg.max_error_stereo),
            float(cfg.min_distance_error_stereo), float(cfg.min_rescale), float(cfg.max_rescale),
            1.0 / cfg.min_depth, float(cfg.photometric_variance), bool(cfg.subpixel),
        )


# The kernel's steps are compiled into it (inline="always"); error_model="numpy": a division by zero gives inf or
# nan, which the steps' checks turn into a status, never an exception inside the pixel loop.
_step = njit(cache=True, nogil=True, error_model="numpy", inline="always")


@_step
def _interp(img: np.ndarray, x: float, y: float) -> float:
    ix = int(x)
    iy = int(y)
    ax = x - ix
    ay = y - iy
    return ((1.0 - ax) * (1.0 - ay) * img[iy, ix] + ax * (1.0 - ay) * img[iy, ix + 1]
            + (1.0 - ax) * ay * img[iy + 1, ix] + ax * ay * img[iy + 1, ix + 1])


@_step
def _epipolar_line(kf_img, x, y, t_kf_cur, fx, fy, cx, cy, s):  # pragma: no cover - compiled
    """LSD-SLAM's makeAndCheckEPL: the epipolar line through key-frame pixel (x, y) and its checks (length, gradient
    along it, angle to the gradient). Returns (status, epx, epy): OK and the line's direction scaled to one sample
    step (px), or the failed check's status."""
    epx = -fx * t_kf_cur[0] + t_kf_cur[2] * (x - cx)
    epy = -fy * t_kf_cur[1] + t_kf_cur[2] * (y - cy)
    epl_len_sq = epx * epx + epy * epy
    if not epl_len_sq >= s.min_epl_length_squared:
        return EPL_SHORT, 0.0, 0.0
    gx2 = kf_img[y, x + 1] - kf_img[y, x - 1]
    gy2 = kf_img[y + 1, x] - kf_img[y - 1, x]
    epl_grad_sq = gx2 * epx + gy2 * epy
    epl_grad_sq = epl_grad_sq * epl_grad_sq / epl_len_sq
    if epl_grad_sq < s.min_epl_grad_squared:
        return EPL_GRAD, 0.0, 0.0
    if epl_grad_sq / (gx2 * gx2 + gy2 * gy2) < s.min_epl_angle_squared:
        return EPL_ANGLE, 0.0, 0.0
    scale = s.sample_distance / np.sqrt(epl_len_sq)
    return OK, epx * scale, epy * scale


@_step
def _search_range(d, var, s):  # pragma: no cover - compiled
    """(prior inverse depth, lowest, highest searched inverse depth) (1/m) of a pixel with depth ``d`` (m, 0 = none)
    and variance ``var`` (m^2): the prior +- ``search_sigmas`` standard deviations, or the whole range without one."""
    if d > 0.0:
        prior_id = 1.0 / d
        sv = np.sqrt(var) * prior_id * prior_id
        min_id = prior_id - s.search_sigmas * sv
        max_id = prior_id + s.search_sigmas * sv
        if min_id < 0.0:
            min_id = 0.0
        if max_id > s.max_idepth_create:
            max_id = s.max_idepth_create
        return prior_id, min_id, max_id
    return 1.0, 0.0, s.max_idepth_create


@_step
def _samples_inside(x, y, sx, sy, w, h):  # pragma: no cover - compiled
    """Whether the 5 reference samples at -2..2 steps (sx, sy) (px) from (x, y) lie inside a (h, w) image."""
    first_x = x - 2.0 * sx
    first_y = y - 2.0 * sy
    last_x = x + 2.0 * sx
    last_y = y + 2.0 * sy
    return not (first_x <= 0 or first_x >= w - 2 or first_y <= 0 or first_y >= h - 2 or last_x <= 0
                or last_x >= w - 2 or last_y <= 0 or last_y >= h - 2)


@_step
def _reference_samples(kf_img, x, y, sx, sy):  # pragma: no cover - compiled
    """The 5 key-frame intensities at -2, -1, 0, 1, 2 steps (sx, sy) (px) along the epipolar line from (x, y)."""
    real_p1 = _interp(kf_img, x + sx, y + sy)
    real_m1 = _interp(kf_img, x - sx, y - sy)
    real_0 = _interp(kf_img, float(x), float(y))
    real_m2 = _interp(kf_img, x - 2.0 * sx, y - 2.0 * sy)
    real_p2 = _interp(kf_img, x + 2.0 * sx, y + 2.0 * sy)
    return real_m2, real_m1, real_0, real_p1, real_p2


@_step
def _segment_ends(pinf0, pinf1, pinf2, Kt, min_id, max_id):  # pragma: no cover - compiled
    """The key-frame ray's points at inverse depths ``min_id`` (far) and ``max_id`` (close) in the current image
    (homogeneous K R x + K t id), the close end pulled in front of the camera. Returns (ok, far x, far y, close x,
    close y) in px; not ok when the far end is behind the camera or the range is empty."""
    pc0 = pinf0 + Kt[0] * max_id
    pc1 = pinf1 + Kt[1] * max_id
    pc2 = pinf2 + Kt[2] * max_id
    if pc2 < 0.001:
        max_id = (0.001 - pinf2) / Kt[2]
        pc0 = pinf0 + Kt[0] * max_id
        pc1 = pinf1 + Kt[1] * max_id
        pc2 = pinf2 + Kt[2] * max_id
    pf0 = pinf0 + Kt[0] * min_id
    pf1 = pinf1 + Kt[1] * min_id
    pf2 = pinf2 + Kt[2] * min_id
    if pf2 < 0.001 or max_id < min_id:
        return False, 0.0, 0.0, 0.0, 0.0
    return True, pf0 / pf2, pf1 / pf2, pc0 / pc2, pc1 / pc2


@_step
def _clip_near_end(close_x, close_y, incx, incy, far_x, far_y, w, h, s):  # pragma: no cover - compiled
    """Move the segment's close end back inside the image border along the line. Returns (ok, close x, close y);
    not ok when it cannot be moved inside or the segment left is shorter than ``min_epl_length``."""
    border = s.border
    if close_x <= border:
        k = (border - close_x) / incx
        close_x += k * incx
        close_y += k * incy
    if close_x >= w - border:
        k = (w - border - close_x) / incx
        close_x += k * incx
        close_y += k * incy
    if close_y <= border:
        k = (border - close_y) / incy
        close_x += k * incx
        close_y += k * incy
    if close_y >= h - border:
        k = (h - border - close_y) / incy
        close_x += k * incx
        close_y += k * incy
    nl = np.sqrt((close_x - far_x) ** 2 + (close_y - far_y) ** 2)
    if (close_x <= border - 1e-3 or close_x >= w - border + 1e-3 or close_y <= border - 1e-3
            or close_y >= h - border + 1e-3 or not nl >= s.min_epl_length or not np.isfinite(nl)):
        return False, close_x, close_y
    return True, close_x, close_y


@_step
def _crop_segment(far_x, far_y, close_x, close_y, w, h, s):  # pragma: no cover - compiled
    """LSD-SLAM's cropping of the searched segment: at most ``max_epl_length`` px from the far end, extended by a
    sample at each end and padded to ``min_epl_length`` px, inside the image border. Returns (ok, far x, far y,
    close x, close y, step x, step y) in px, the step one ``sample_distance`` along the line."""
    incx = close_x - far_x
    incy = close_y - far_y
    epl_length = np.sqrt(incx * incx + incy * incy)
    if not (epl_length > 0.0) or not np.isfinite(epl_length):
        return False, far_x, far_y, close_x, close_y, incx, incy
    if epl_length > s.max_epl_length:
        close_x = far_x + incx * s.max_epl_length / epl_length
        close_y = far_y + incy * s.max_epl_length / epl_length
    incx *= s.sample_distance / epl_length
    incy *= s.sample_distance / epl_length
    far_x -= incx
    far_y -= incy
    close_x += incx
    close_y += incy
    if epl_length < s.min_epl_length:
        pad = (s.min_epl_length - epl_length) / 2.0
        far_x -= incx * pad
        far_y -= incy * pad
        close_x += incx * pad
        close_y += incy * pad
    border = s.border
    if far_x <= border or far_x >= w - border or far_y <= border or far_y >= h - border:
        return False, far_x, far_y, close_x, close_y, incx, incy
    if close_x <= border or close_x >= w - border or close_y <= border or close_y >= h - border:
        ok, close_x, close_y = _clip_near_end(close_x, close_y, incx, incy, far_x, far_y, w, h, s)
        if not ok:
            return False, far_x, far_y, close_x, close_y, incx, incy
    return True, far_x, far_y, close_x, close_y, incx, incy


@_step
def _ssd_search(cur_img, far_x, far_y, close_x, close_y, incx, incy, ref, sample_dist):  # pragma: no cover
    """LSD-SLAM's SSD over the 5 reference samples ``ref``, stepping (incx, incy) from the far end to the close end
    of the segment in the current image. Returns (best error, second best error, best x, best y, best step, second
    step, error one step before the best, error one step after it (-1 where there is none))."""
    real_m2, real_m1, real_0, real_p1, real_p2 = ref
    cpx = far_x
    cpy = far_y
    v_m2 = _interp(cur_img, cpx - 2.0 * incx, cpy - 2.0 * incy)
    v_m1 = _interp(cur_img, cpx - incx, cpy - incy)
    v_0 = _interp(cur_img, cpx, cpy)
    v_p1 = _interp(cur_img, cpx + incx, cpy + incy)
    best_err = 1e50
    second_err = 1e50
    best_x = -1.0
    best_y = -1.0
    loop_best = -1
    loop_second = -1
    err_pre = -1.0
    err_post = -1.0
    last_err = -1.0
    best_was_last = False
    n_loop = 0
    n_steps = int(np.sqrt((close_x - far_x) ** 2 + (close_y - far_y) ** 2) / sample_dist) + 1
    while n_loop < n_steps:
        v_p2 = _interp(cur_img, cpx + 2.0 * incx, cpy + 2.0 * incy)
        e1 = v_p2 - real_p2
        e2 = v_p1 - real_p1
        e3 = v_0 - real_0
        e4 = v_m1 - real_m1
        e5 = v_m2 - real_m2
        ee = e1 * e1 + e2 * e2 + e3 * e3 + e4 * e4 + e5 * e5
        if ee < best_err:
            second_err = best_err
            loop_second = loop_best
            best_err = ee
            loop_best = n_loop
            err_pre = last_err
            err_post = -1.0
            best_x = cpx
            best_y = cpy
            best_was_last = True
        else:
            if best_was_last:
                err_post = ee
                best_was_last = False
            if ee < second_err:
                second_err = ee
                loop_second = n_loop
        last_err = ee
        v_m2 = v_m1
        v_m1 = v_0
        v_0 = v_p1
        v_p1 = v_p2
        cpx += incx
        cpy += incy
        n_loop += 1
    return best_err, second_err, best_x, best_y, loop_best, loop_second, err_pre, err_post


@_step
def _subpixel_match(best_x, best_y, best_err, err_pre, err_post, incx, incy):  # pragma: no cover - compiled
    """The best match moved to the minimum of the parabola through the errors before, at and after it (at most half
    a step). Returns (x, y, error, refined); unchanged and not refined where the parabola does not open upwards."""
    denom = err_pre - 2.0 * best_err + err_post
    if denom > 0.0:
        off = 0.5 * (err_pre - err_post) / denom
        if off > 0.5:
            off = 0.5
        if off < -0.5:
            off = -0.5
        best_x += off * incx
        best_y += off * incy
        best_err = best_err - 0.25 * (err_pre - err_post) * off
        return best_x, best_y, best_err, True
    return best_x, best_y, best_err, False


@_step
def _gradient_along(ref, sample_d):  # pragma: no cover - compiled
    """Squared intensity gradient along the epipolar line from the 5 reference samples ``sample_d`` px apart."""
    real_m2, real_m1, real_0, real_p1, real_p2 = ref
    return ((real_p2 - real_p1) ** 2 + (real_p1 - real_0) ** 2 + (real_0 - real_m1) ** 2
            + (real_m1 - real_m2) ** 2) / (sample_d * sample_d)


@_step
def _triangulate(best_x, best_y, incx, incy, kx, ky, R, t, fxi, fyi, cxi, cyi):  # pragma: no cover - compiled
    """Inverse depth (1/m) of the key-frame ray (kx, ky, 1) whose match in the current image is (best_x, best_y),
    from the image coordinate that varies most along the line, and alpha = d(inverse depth) / d(px along it)."""
    if incx * incx > incy * incy:
        old = fxi * best_x + cxi
        nom = old * t[2] - t[0]
        dot0 = R[0, 0] * kx + R[0, 1] * ky + R[0, 2]
        dot2 = R[2, 0] * kx + R[2, 1] * ky + R[2, 2]
        id_new = (dot0 - old * dot2) / nom
        alpha = incx * fxi * (dot0 * t[2] - dot2 * t[0]) / (nom * nom)
        return id_new, alpha
    old = fyi * best_y + cyi
    nom = old * t[2] - t[1]
    dot1 = R[1, 0] * kx + R[1, 1] * ky + R[1, 2]
    dot2 = R[2, 0] * kx + R[2, 1] * ky + R[2, 2]
    id_new = (dot1 - old * dot2) / nom
    alpha = incy * fyi * (dot1 * t[2] - dot2 * t[1]) / (nom * nom)
    return id_new, alpha


@_step
def _observation_variance(alpha, sample_d, grad_along, ggx, ggy, epx, epy, tracking_fac, did_subpixel,
                          s):  # pragma: no cover - compiled
    """LSD-SLAM's inverse-depth observation variance alpha^2 (discretisation + geometric + photometric disparity
    error): ggx, ggy the key-frame gradient, (epx, epy) the line's step, tracking_fac the tracking quality's
    scale of the geometric error."""
    photo = 4.0 * s.photometric_variance / (grad_along + 1e-10)
    geo = ggx * epx + ggy * epy + 1e-10
    geo = tracking_fac * tracking_fac * (ggx * ggx + ggy * ggy) / (geo * geo)
    disc = 0.05 if did_subpixel else 0.5
    return alpha * alpha * (disc * sample_d * sample_d + geo + photo)


@njit(cache=True, nogil=True, error_model="numpy")
def _epipolar_stereo(
    kf_img: np.ndarray, kf_gx: np.ndarray, kf_gy: np.ndarray, cur_img: np.ndarray,
    depth: np.ndarray, variance: np.ndarray, attempt: np.ndarray,
    R: np.ndarray, t: np.ndarray, t_kf_cur: np.ndarray, intr: np.ndarray,
    tracking_residual: float, s: StereoSettings,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LSD-SLAM's makeAndCheckEPL + doLineStereo for every key-frame pixel with ``attempt`` set, step by step.

    kf_img, cur_img: (H, W) float32 intensities; kf_gx, kf_gy: key-frame central-difference gradients (per px);
    depth (m, 0 = no prior), variance (m^2): the key-frame's maps; R, t: T_cur_kf (key-frame -> current);
    t_kf_cur: position of the current camera in key-frame coordinates; intr: (fx, fy, cx, cy). Returns (inverse
    depth (H, W) float32, inverse-depth variance (H, W) float32, status (H, W) int8); inverse depth 0 and variance
    inf where there is no observation. (The pixel's steps stay in this loop: returned through a per-pixel function,
    the kernel ran 1.4 times slower.)
    """
    h, w = kf_img.shape
    fx, fy, cx, cy = intr[0], intr[1], intr[2], intr[3]
    fxi, fyi = 1.0 / fx, 1.0 / fy
    cxi, cyi = -cx / fx, -cy / fy
    out_id = np.zeros((h, w), np.float32)
    out_var = np.full((h, w), np.inf, np.float32)
    status = np.full((h, w), SKIPPED, np.int8)
    # K R and K t (the warp of a key-frame ray into the current image)
    KR = np.empty((3, 3))
    Kt = np.empty(3)
    for j in range(3):
        KR[0, j] = fx * R[0, j] + cx * R[2, j]
        KR[1, j] = fy * R[1, j] + cy * R[2, j]
        KR[2, j] = R[2, j]
    Kt[0] = fx * t[0] + cx * t[2]
    Kt[1] = fy * t[1] + cy * t[2]
    Kt[2] = t[2]
    tracking_fac = 0.25 * (1.0 + tracking_residual)
    for y in range(3, h - 3):
        for x in range(3, w - 3):
            if not attempt[y, x]:
                continue
            code, epxn, epyn = _epipolar_line(kf_img, x, y, t_kf_cur, fx, fy, cx, cy, s)
            if code != OK:
                status[y, x] = code
                continue
            prior_id, min_id, max_id = _search_range(depth[y, x], variance[y, x], s)
            # ---- doLineStereo: the pixel's ray in the current image at infinity (K R x) and at the prior depth
            kx = fxi * x + cxi
            ky = fyi * y + cyi
            pinf0 = KR[0, 0] * kx + KR[0, 1] * ky + KR[0, 2]
            pinf1 = KR[1, 0] * kx + KR[1, 1] * ky + KR[1, 2]
            pinf2 = KR[2, 0] * kx + KR[2, 1] * ky + KR[2, 2]
            preal2 = pinf2 / prior_id + Kt[2]
            rescale = preal2 * prior_id
            if not (rescale > s.min_rescale and rescale < s.max_rescale):
                status[y, x] = OUT_OF_IMAGE
                continue
            sx = epxn * rescale
            sy = epyn * rescale
            if not _samples_inside(x, y, sx, sy, w, h):
                status[y, x] = OUT_OF_IMAGE
                continue
            ref = _reference_samples(kf_img, x, y, sx, sy)
            ok, far_x, far_y, close_x, close_y = _segment_ends(pinf0, pinf1, pinf2, Kt, min_id, max_id)
            if ok:
                ok, far_x, far_y, close_x, close_y, incx, incy = _crop_segment(far_x, far_y, close_x, close_y, w, h, s)
            if not ok:
                status[y, x] = OUT_OF_IMAGE
                continue
            best_err, second_err, best_x, best_y, loop_best, loop_second, err_pre, err_post = _ssd_search(
                cur_img, far_x, far_y, close_x, close_y, incx, incy, ref, s.sample_distance)
            if best_err > 4.0 * s.max_error_stereo:
                status[y, x] = BIG_ERROR
                continue
            if abs(loop_best - loop_second) > 1 and s.min_distance_error_stereo * best_err > second_err:
                status[y, x] = AMBIGUOUS
                continue
            did_subpixel = False
            if s.subpixel and err_pre >= 0.0 and err_post >= 0.0:
                best_x, best_y, best_err, did_subpixel = _subpixel_match(best_x, best_y, best_err, err_pre, err_post,
                                                                         incx, incy)
            sample_d = s.sample_distance * rescale
            grad_along = _gradient_along(ref, sample_d)
            if best_err > s.max_error_stereo + np.sqrt(grad_along) * 20.0:
                status[y, x] = BIG_ERROR
                continue
            id_new, alpha = _triangulate(best_x, best_y, incx, incy, kx, ky, R, t, fxi, fyi, cxi, cyi)
            if not (id_new > 0.0) or not np.isfinite(id_new) or not np.isfinite(alpha):
                status[y, x] = BAD_DEPTH
                continue
            out_id[y, x] = id_new
            out_var[y, x] = _observation_variance(alpha, sample_d, grad_along, kf_gx[y, x], kf_gy[y, x], epxn, epyn,
                                                  tracking_fac, did_subpixel, s)
            status[y, x] = OK
    return out_id, out_var, status


# ------------------------------------------------------------------------------------------------- eq. 10 and 11


@njit(cache=True, nogil=True)
def _eq10(depth_kf, uncertainty_kf, depth_obs, uncertainty_obs):  # pragma: no cover - compiled
    """CNN-SLAM eq. 10 for numbers or arrays (see :func:`fuse_observation_depth`)."""
    return (uncertainty_obs * depth_kf + uncertainty_kf * depth_obs) / (uncertainty_kf + uncertainty_obs)


@njit(cache=True, nogil=True)
def _eq11(uncertainty_kf, uncertainty_obs):  # pragma: no cover - compiled
    """CNN-SLAM eq. 11 for numbers or arrays (see :func:`fuse_observation_uncertainty`)."""
    return uncertainty_obs * uncertainty_kf / (uncertainty_kf + uncertainty_obs)


@njit(cache=True, nogil=True)
def _outlier(depth_kf, uncertainty_kf, depth_obs, uncertainty_obs, factor):  # pragma: no cover - compiled
    """LSD-SLAM's consistency gate for numbers or arrays (see :func:`observation_outliers`)."""
    diff = depth_obs - depth_kf
    return factor * diff * diff > uncertainty_kf + uncertainty_obs


def _float64_arrays(*values: np.ndarray) -> list[np.ndarray]:
    """The compiled equations' arguments: float64 arrays of at least one dimension."""
    return [np.atleast_1d(np.asarray(v, np.float64)) for v in values]


def fuse_observation_depth(depth_kf: np.ndarray, uncertainty_kf: np.ndarray, depth_obs: np.ndarray,
                           uncertainty_obs: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 10: D_ki = (U_t D_ki + U_ki D_t) / (U_ki + U_t), element-wise (metres), in float64.

    depth_kf, uncertainty_kf: the key-frame's D_ki (m) and U_ki (m^2); depth_obs, uncertainty_obs: the frame's
    observation D_t (m) and U_t (m^2). Callers pass only pixels with a finite U_t (U_t = inf leaves D_ki unchanged).
    """
    return _eq10(*_float64_arrays(depth_kf, uncertainty_kf, depth_obs, uncertainty_obs))


def observation_outliers(depth_kf: np.ndarray, uncertainty_kf: np.ndarray, depth_obs: np.ndarray,
                         uncertainty_obs: np.ndarray, factor: float) -> np.ndarray:
    """LSD-SLAM's consistency gate before eq. 10-11 (updateKeyframe, DIFF_FAC_OBSERVE), in depth: True where
    factor * (D_t - D_ki)^2 > U_t + U_ki, i.e. the observation and the key-frame disagree by more than their
    combined standard deviation allows (a wrong stereo match, or another surface). factor = 0 flags nothing.
    """
    return _outlier(*_float64_arrays(depth_kf, uncertainty_kf, depth_obs, uncertainty_obs), float(factor))


def fuse_observation_uncertainty(uncertainty_kf: np.ndarray, uncertainty_obs: np.ndarray) -> np.ndarray:
    """CNN-SLAM eq. 11: U_ki = U_t U_ki / (U_ki + U_t), element-wise (m^2), in float64."""
    return _eq11(*_float64_arrays(uncertainty_kf, uncertainty_obs))


@njit(cache=True, nogil=True)
def _refine_kernel(d, u, d_obs, u_obs, outlier_factor, inflation, keep_without_observation,
                   max_id_var):  # pragma: no cover - compiled
    """:func:`refine_keyframe`'s pixel loop: (new depth, new variance, fused-or-created mask, [observed, fused,
    created, rejected, dropped]). Every pixel's arithmetic is the function's, in the same order (float64 for eq.
    10-11 and the gate, float32 for the inverse-depth variance test)."""
    h, w = d.shape
    new_d = d.copy()
    new_u = u.copy()
    mask = np.zeros((h, w), np.bool_)
    counts = np.zeros(5, np.int64)
    for y in range(h):
        for x in range(w):
            do, uo = d_obs[y, x], u_obs[y, x]
            if np.isfinite(uo) and do > 0:
                counts[0] += 1
                dk = d[y, x]
                if dk > 0:
                    uk = np.float64(u[y, x])
                    if outlier_factor > 0 and _outlier(np.float64(dk), uk, np.float64(do), np.float64(uo),
                                                       outlier_factor):
                        counts[3] += 1
                    else:
                        u_prior = uk * inflation
                        new_d[y, x] = _eq10(np.float64(dk), u_prior, np.float64(do), np.float64(uo))
                        new_u[y, x] = _eq11(u_prior, np.float64(uo))
                        mask[y, x] = True
                        counts[1] += 1
                else:
                    new_d[y, x] = do
                    new_u[y, x] = uo
                    mask[y, x] = True
                    counts[2] += 1
            if not keep_without_observation:
                nd = new_d[y, x]
                if nd > 0:
                    sq = nd * nd
                    if new_u[y, x] / sq / sq > max_id_var:
                        new_d[y, x] = 0.0
                        new_u[y, x] = np.inf
                        counts[4] += 1
    return new_d, new_u, mask, counts


# --------------------------------------------------------------------------------------------------- the stage


@dataclass(frozen=True)
class StereoObservation:
    """One frame's depth observation of a key-frame (the D_t and U_t of eq. 10-11).

    depth: (H, W) float32 metres (0 = no observation); variance: (H, W) float32 m^2 (inf = no observation);
    status: (H, W) int8 per-pixel outcome (:data:`STATUS_NAMES`).
    """

    depth: np.ndarray
    variance: np.ndarray
    status: np.ndarray

    def counts(self) -> dict[str, int]:
        """Pixels per outcome."""
        values = np.bincount(self.status.ravel().astype(np.intp), minlength=len(STATUS_NAMES))
        return {name: int(n) for name, n in zip(STATUS_NAMES, values, strict=True)}


def stereo_observation(
    kf_image: np.ndarray, kf_grad_x: np.ndarray, kf_grad_y: np.ndarray, depth: np.ndarray, variance: np.ndarray,
    cur_image: np.ndarray, T_kf_cur: np.ndarray, intrinsics: np.ndarray, config: RefinementConfig,
    tracking_residual: float = 0.0,
) -> StereoObservation:
    """The depth map D_t and uncertainty map U_t that frame t observes for the key-frame (Sec. 3.4), by epipolar
    stereo at every pixel the density setting attempts.

    kf_image, cur_image: (H, W) float32 intensities 0..255; kf_grad_x/y: (H, W) float32 central differences;
    depth (m, 0 = none) and variance (m^2): the key-frame's current maps, which set each pixel's search range;
    T_kf_cur: (4, 4) current camera into key-frame coordinates (from tracking); tracking_residual: the frame's mean
    normalised squared tracking residual (scales LSD-SLAM's geometric error).
    """
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    if depth.shape != kf_image.shape or cur_image.shape != kf_image.shape:
        raise CnnSlamError(f"image/depth shapes differ: {kf_image.shape}, {depth.shape}, {cur_image.shape}")
    if config.density == "dense":
        attempt = np.ones(depth.shape, np.bool_)
    else:
        attempt = np.sqrt(kf_grad_x**2 + kf_grad_y**2) >= config.min_gradient_create
    T_cur_kf = np.linalg.inv(np.asarray(T_kf_cur, dtype=np.float64))
    idepth, id_var, status = _epipolar_stereo(
        np.ascontiguousarray(kf_image, np.float32), np.ascontiguousarray(kf_grad_x, np.float32),
        np.ascontiguousarray(kf_grad_y, np.float32), np.ascontiguousarray(cur_image, np.float32), depth,
        np.ascontiguousarray(variance, np.float32), attempt, np.ascontiguousarray(T_cur_kf[:3, :3]),
        np.ascontiguousarray(T_cur_kf[:3, 3]), np.ascontiguousarray(np.asarray(T_kf_cur, np.float64)[:3, 3]),
        np.asarray(intrinsics, np.float64), float(tracking_residual), StereoSettings.from_config(config),
    )
    ok = idepth > _MIN_IDEPTH
    status[(idepth > 0) & ~ok] = BAD_DEPTH
    d_obs = np.zeros(depth.shape, np.float32)
    var_obs = np.full(depth.shape, np.inf, np.float32)
    id_ok = idepth[ok].astype(np.float64)
    d_obs[ok] = 1.0 / id_ok
    var_obs[ok] = id_var[ok] / id_ok**4  # inverse-depth variance -> depth variance (first order)
    return StereoObservation(d_obs, var_obs, status)


@dataclass(frozen=True)
class RefinementStats:
    """What one refinement step did: pixels observed, pixels fused, pixels dropped (semi-dense), per-status counts."""

    observed: int
    fused: int
    created: int
    dropped: int
    status_counts: dict[str, int]
    rejected: int = 0  # observations failing the outlier gate (not fused)
    fused_mask: np.ndarray | None = None  # (H, W) bool: the pixels whose depth took this frame's observation


def refine_keyframe(
    depth: np.ndarray, variance: np.ndarray, observation: StereoObservation, config: RefinementConfig,
    keep_without_observation: bool = True,
) -> tuple[np.ndarray, np.ndarray, RefinementStats]:
    """Fuse one frame's observation into the key-frame maps by eq. 10-11 (new arrays; the inputs are not changed).

    depth (m), variance (m^2): (H, W) float32 key-frame maps. Pixels with a prior and an observation are fused
    (after LSD-SLAM's prior inflation, ``prior_variance_inflation``); pixels without a prior take the observation
    (hypothesis creation). With ``keep_without_observation=False`` (semi-dense without a CNN, LSD-SLAM),
    hypotheses whose inverse-depth variance exceeds ``max_inverse_depth_variance`` are dropped.
    Returns (depth (H, W) float32, variance (H, W) float32, stats).
    """
    d = np.ascontiguousarray(depth, dtype=np.float32)
    u = np.ascontiguousarray(variance, dtype=np.float32)
    new_d, new_u, mask, counts = _refine_kernel(
        d, u, np.ascontiguousarray(observation.depth, dtype=np.float32),
        np.ascontiguousarray(observation.variance, dtype=np.float32), float(config.outlier_factor),
        float(config.prior_variance_inflation), bool(keep_without_observation),
        np.float32(config.max_inverse_depth_variance))
    observed, fused, created, rejected, dropped = (int(c) for c in counts)
    stats = RefinementStats(observed, fused, created, dropped, observation.counts(), rejected, mask)
    return new_d, new_u, stats
