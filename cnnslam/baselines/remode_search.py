"""REMODE's depth filter, its per-pixel core (:class:`cnnslam.baselines.remode.DepthFilter` drives it): the
Vogiatzis-Hernandez posterior update (:func:`vogiatzis_update`), SVO's triangulation uncertainty
(:func:`triangulation_uncertainty`), the epipolar ZNCC search (:func:`search_image`, :func:`best_match`) and one
update of every seed of a reference frame (:func:`_update_seeds`, with REMODE's seedCheck
:func:`_seed_check`).

Hot loops are serial numba kernels (on two shared cores a parallel kernel measured 3x slower than a serial one). The
search reads each sampled patch's sum of I and I^2 from tables made once a frame (:func:`search_tables`: box sums of
the image and of its neighbour products) and its sum of I T from the template's correlation at the sample's integer
corners, which consecutive samples share (:func:`_best_match`): the ZNCC of its definition with the additions in
another order (tests: against the pixel-by-pixel definition). Camera images are grey levels, so the template's
correlations are integers, summed two corners at a time in one 64-bit integer (:func:`search_pairs`). The search's
indices are never negative (its patches lie inside the image: seeds at least a half patch from the border, positions
checked before they are read), so its reads use unsigned indices (``np.uintp``), which numba reads without a
wraparound test. Timings of these choices: ``results/perf_history.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError

# seed states (REMODE's ConvergenceStates)
UPDATE, CONVERGED, DIVERGED, BORDER = 0, 1, 2, 3
# per-frame outcome of a seed (counted in FilterUpdate)
SKIPPED, UPDATED, NO_MATCH, NOT_VISIBLE, FLAT = 0, 1, 2, 3, 4


# ------------------------------------------------------------------------------------------------ the equations


@njit(cache=True, nogil=True)
def _normpdf(x: float, mu: float, var: float) -> float:
    return math.exp(-(x - mu) * (x - mu) / (2.0 * var)) / math.sqrt(2.0 * math.pi * var)


@njit(cache=True, nogil=True)
def _vh_update(mu: float, sigma2: float, a: float, b: float, x: float, tau2: float,
               depth_range: float) -> tuple[float, float, float, float]:
    s2 = 1.0 / (1.0 / sigma2 + 1.0 / tau2)
    m = s2 * (mu / sigma2 + x / tau2)
    c1 = a / (a + b) * _normpdf(x, mu, sigma2 + tau2)
    c2 = b / (a + b) / depth_range
    norm = c1 + c2
    if not norm > 0.0:
        return mu, sigma2, a, b
    c1 /= norm
    c2 /= norm
    f = c1 * (a + 1.0) / (a + b + 1.0) + c2 * a / (a + b + 1.0)
    e = (c1 * (a + 1.0) * (a + 2.0) / ((a + b + 1.0) * (a + b + 2.0))
         + c2 * a * (a + 1.0) / ((a + b + 1.0) * (a + b + 2.0)))
    mu_new = c1 * m + c2 * mu
    sigma2_new = c1 * (s2 + m * m) + c2 * (sigma2 + mu * mu) - mu_new * mu_new
    a_new = (e - f) / (f - e / f)
    b_new = a_new * (1.0 - f) / f
    return mu_new, sigma2_new, a_new, b_new


def vogiatzis_update(mu: float, sigma2: float, a: float, b: float, x: float, tau2: float,
                     depth_range: float) -> tuple[float, float, float, float]:
    """Vogiatzis & Hernandez (2011) eq. 19-26, as REMODE's seedUpdate: the Gaussian x Beta posterior
    N(d | mu, sigma2) Beta(pi | a, b) after a depth measurement x (metres) with variance tau2 (m^2), under the
    model p(x | d, pi) = pi N(x | d, tau2) + (1 - pi) U(x) with U uniform over ``depth_range`` metres.

    With s2 = 1 / (1 / sigma2 + 1 / tau2), m = s2 (mu / sigma2 + x / tau2), C1 = a / (a + b) N(x | mu, sigma2 + tau2),
    C2 = b / (a + b) / range (normalised to C1 + C2 = 1), f = C1 (a + 1) / (a + b + 1) + C2 a / (a + b + 1) and
    e = C1 (a + 1)(a + 2) / ((a + b + 1)(a + b + 2)) + C2 a (a + 1) / ((a + b + 1)(a + b + 2)): mu' = C1 m + C2 mu,
    sigma2' = C1 (s2 + m^2) + C2 (sigma2 + mu^2) - mu'^2, a' = (e - f) / (f - e / f), b' = a' (1 - f) / f.
    Returns (mu', sigma2', a', b').
    """
    return _vh_update(float(mu), float(sigma2), float(a), float(b), float(x), float(tau2), float(depth_range))


@njit(cache=True, nogil=True)
def _tau(fx: float, fy: float, fz: float, depth: float, tx: float, ty: float, tz: float,
         px_error_angle: float) -> float:
    t_norm = math.sqrt(tx * tx + ty * ty + tz * tz)
    ax, ay, az = fx * depth - tx, fy * depth - ty, fz * depth - tz
    a_norm = math.sqrt(ax * ax + ay * ay + az * az)
    if t_norm <= 0.0 or a_norm <= 0.0:
        return math.inf
    alpha = math.acos(min(1.0, max(-1.0, (fx * tx + fy * ty + fz * tz) / t_norm)))
    beta = math.acos(min(1.0, max(-1.0, -(ax * tx + ay * ty + az * tz) / (t_norm * a_norm))))
    beta_plus = beta + px_error_angle
    gamma_plus = math.pi - alpha - beta_plus
    if gamma_plus <= 0.0:
        return math.inf
    z_plus = t_norm * math.sin(beta_plus) / math.sin(gamma_plus)
    return z_plus - depth


def triangulation_uncertainty(bearing_ref: np.ndarray, depth: float, t_ref_cur: np.ndarray,
                              px_error_angle: float) -> float:
    """SVO's computeTau (used by REMODE): the change of depth along the reference bearing when the match moves by
    one pixel of disparity.

    bearing_ref: (3,) unit vector of the reference pixel; depth: metres along it; t_ref_cur: (3,) position of the
    current camera in reference coordinates; px_error_angle: the angle of one pixel, 2 atan(1 / (2 f)) radians.
    With a = bearing depth - t, alpha = angle(bearing, t), beta = angle(a, -t), the law of sines gives the depth
    for beta + px_error_angle: z+ = |t| sin(beta+) / sin(pi - alpha - beta+); tau = z+ - depth (metres).
    """
    f = np.asarray(bearing_ref, dtype=np.float64)
    t = np.asarray(t_ref_cur, dtype=np.float64)
    return float(_tau(f[0], f[1], f[2], float(depth), t[0], t[1], t[2], float(px_error_angle)))


# ------------------------------------------------------------------------------------------------ the filter kernel


@dataclass(frozen=True)
class SearchImage:
    """A current image as the epipolar search reads it (:func:`search_image`): ``gray`` (H, W) float64 intensities,
    ``tables`` (H, W, 6) their sums over patches of ``patch_size`` (:func:`search_tables`) and, for grey levels,
    ``pairs`` (2, H, W) (:func:`search_pairs`; None otherwise). Made once a frame and shared by every reference frame
    the frame updates."""

    gray: np.ndarray
    tables: np.ndarray
    patch_size: int
    pairs: np.ndarray | None = None


def search_tables(gray: np.ndarray, patch_size: int) -> np.ndarray:
    """The sums of the ZNCC search that do not depend on the template: at every pixel (r, c), the sums over the
    ``patch_size`` x ``patch_size`` window centred on it of I, I^2, I(p) I(p + (0, 1)), I(p) I(p + (1, 0)),
    I(p) I(p + (1, 1)) and I(p) I(p + (1, -1)) ((row, column) offsets; pixels outside the image count as 0, and a
    product whose neighbour is outside as 0: such windows are never read). Returns (H, W, 6).

    With them, the sums of I and I^2 over a patch sampled bilinearly at a sub-pixel position (every tap sharing the
    position's weights w00, w01, w10, w11 at its 2x2 integer corners) are 4 and 10 weighted entries: sum I = sum_c
    w_c B[q + c]; sum I^2 = sum_c w_c^2 S0[q + c] + 2 (w00 w01 SR[q] + w00 w10 SD[q] + w00 w11 SDR[q] + w01 w10
    SDL[q + (0, 1)] + w01 w11 SD[q + (0, 1)] + w10 w11 SR[q + (1, 0)]). float64; summed in float32 when the
    intensities are integers in [0, 255] (camera grey levels: every sum is an integer below 2^24, exact in float32
    whatever the order of the additions; twice as fast), in float64 otherwise. The search reads float64 tables 3 %
    faster than float32 ones (120 office0 updates: 15.1 against 15.5 ms), for 0.2 ms a frame of conversion.
    """
    img = np.asarray(gray)
    if img.ndim != 2:
        raise CnnSlamError(f"expected an (H, W) grey image, got shape {img.shape}")
    return _search_tables(img, patch_size, grey_levels(img))


def _search_tables(img: np.ndarray, patch_size: int, exact32: bool) -> np.ndarray:
    """:func:`search_tables` of an (H, W) image whose grey-level test (:func:`grey_levels`) is ``exact32``."""
    i = img.astype(np.float32 if exact32 else np.float64)
    h, w = i.shape
    products = np.zeros((h, w, 6), i.dtype)
    products[..., 0] = i
    products[..., 1] = i * i
    products[:, :-1, 2] = i[:, :-1] * i[:, 1:]
    products[:-1, :, 3] = i[:-1] * i[1:]
    products[:-1, :-1, 4] = i[:-1, :-1] * i[1:, 1:]
    products[:-1, 1:, 5] = i[:-1, 1:] * i[1:, :-1]
    k = int(patch_size)
    return cv2.boxFilter(products, -1, (k, k), normalize=False, borderType=cv2.BORDER_CONSTANT).astype(np.float64)


def grey_levels(image: np.ndarray) -> bool:
    """True when every intensity of ``image`` is an integer in [0, 255] (a camera's grey levels) and it is not empty."""
    img = np.asarray(image)
    return img.size > 0 and bool(np.array_equal(img, np.clip(np.rint(img), 0, 255)))


def search_pairs(gray: np.ndarray) -> np.ndarray:
    """(2, H, W) int64: each pixel packed with its neighbour below (0) and to its right (1) in one integer,
    I(p) + 2^32 I(p + (1, 0)) and I(p) + 2^32 I(p + (0, 1)) ((row, column) offsets; a neighbour outside counts as 0),
    for ``gray`` of grey levels (:func:`grey_levels`; anything else raises).

    Summing template x pair products over a patch gives the template's correlation at two adjacent integer pixels
    at once, in the low and high 32 bits, exactly: a product of grey levels is at most 65 025, so a patch of n <=
    33 025 pixels (sides up to 181) sums to less than 2^31 in each half, and nothing carries from one into the
    other (:func:`_best_match`)."""
    img = np.asarray(gray)
    if img.ndim != 2 or not grey_levels(img):
        raise CnnSlamError("search_pairs needs an (H, W) image of integer grey levels in [0, 255]")
    return _packed_pairs(img)


def _packed_pairs(img: np.ndarray) -> np.ndarray:
    """:func:`search_pairs` of an (H, W) image already known to be grey levels."""
    i = img.astype(np.int64)
    pairs = np.stack([i, i])
    pairs[0, :-1] += i[1:] << 32
    pairs[1, :, :-1] += i[:, 1:] << 32
    return pairs


def search_image(image: np.ndarray, patch_size: int) -> SearchImage:
    """The :class:`SearchImage` of an (H, W) grey or (H, W, 3) uint8 RGB image (with :func:`search_pairs` when its
    intensities are grey levels)."""
    gray = _gray(image)
    grey = grey_levels(gray)
    return SearchImage(gray.astype(np.float64), _search_tables(gray, patch_size, grey), int(patch_size),
                       _packed_pairs(gray) if grey else None)


def _check_pairs(pairs: np.ndarray, shape: tuple[int, ...], who: str) -> None:
    """Raise unless ``pairs`` is the (2, H, W) :func:`search_pairs` of an image of ``shape`` (H, W); ``who`` names the
    caller in the message."""
    if pairs.shape != (2, *shape):
        raise CnnSlamError(f"{who}: search pairs of shape {pairs.shape} for an image of shape {shape}: make them with "
                           f"search_pairs(image), shape (2, H, W)")


@njit(cache=True, nogil=True, inline="always")
def _correlation(cur: np.ndarray, r: int, c: int, tmpl: np.ndarray, half: int) -> float:
    """sum_d T_d I[(r, c) + d] over the (2 half + 1)^2 offsets d, T the template (row-major): the template's
    correlation with ``cur`` at the integer pixel (r, c), one partial sum per template row. Inlined; called with a
    literal ``half`` the compiler unrolls it."""
    side = 2 * half + 1
    s = 0.0
    for oy in range(side):
        row = np.uintp(r + oy - half)
        t = tmpl[oy * side] * cur[row, np.uintp(c - half)]
        for ox in range(1, side):
            t += tmpl[oy * side + ox] * cur[row, np.uintp(c - half + ox)]
        s += t
    return s


_LOW_HALF = (1 << 32) - 1
_MAX_PACKED_SIDE = 181  # a patch of at most 181^2 grey-level products sums below 2^31 (search_pairs)
_NO_PAIRS = np.zeros((2, 1, 1), np.int64)  # the kernels' pairs where there are none


@njit(cache=True, nogil=True, inline="always")
def _packed_correlation(pairs: np.ndarray, r: int, c: int, tmpl: np.ndarray, half: int) -> int:
    """sum_d T_d P[(r, c) + d] over the (2 half + 1)^2 offsets d, P one plane of :func:`search_pairs`, T the integer
    template (row-major): the template's correlation at (r, c) in the low 32 bits and at the pair's other pixel
    ((r + 1, c) or (r, c + 1)) in the high 32 bits. Inlined; called with a literal ``half`` the compiler unrolls
    it."""
    side = 2 * half + 1
    s = 0
    for oy in range(side):
        row = np.uintp(r + oy - half)
        for ox in range(side):
            s += tmpl[np.uintp(oy * side + ox)] * pairs[row, np.uintp(c - half + ox)]
    return s


@njit(cache=True, nogil=True, inline="always")
def _best_match(cur: np.ndarray, tab: np.ndarray, tmpl: np.ndarray, pairs: np.ndarray, tmpl_int: np.ndarray,
                packed: bool, u_mean: float, v_mean: float, du: float, dv: float, half_len: float, step: float,
                half: int, t_mean: float, t_std: float) -> tuple[float, float, float]:
    """REMODE's epipolar search of one seed: the best ZNCC (and its position (u, v)) of the template ``tmpl`` (mean
    ``t_mean``, standard deviation ``t_std``) against the patch of ``cur`` ((H, W) intensities) sampled bilinearly
    every ``step`` px along the segment (u_mean, v_mean) + l (du, dv), |l| <= half_len, skipping positions whose
    patch leaves the image or is flat. ZNCC = (sum I T / n - mean_I t_mean) / (std_I t_std), n = (2 half + 1)^2.
    Sum I and sum I^2 come from the tables ``tab`` (:func:`search_tables`); sum I T is the bilinear mix of the
    template's correlation at the position's four integer corners, each corner computed once while consecutive
    positions share it: with ``packed`` (``cur``'s grey levels as ``pairs``, :func:`search_pairs`, and the template's
    as the integers ``tmpl_int``) two corners at a time in one integer sum (:func:`_packed_correlation`), else one at
    a time (:func:`_correlation`). The two give the same values: a correlation of grey levels is an integer, which
    float64 holds exactly whatever the order of its additions. Returns (-1, 0, 0) when no position was scored."""
    h, w = cur.shape
    inv_n = 1.0 / ((2 * half + 1) * (2 * half + 1))
    best = -1.0
    best_u = 0.0
    best_v = 0.0
    n_steps = int(2.0 * half_len / step) + 1
    qr = -10  # the corner block (qr, qc) whose correlations c00..c11 are held
    qc = -10
    c00 = c01 = c10 = c11 = 0.0
    for k in range(n_steps):
        l_ = -half_len + k * step
        uc = u_mean + l_ * du
        vc = v_mean + l_ * dv
        if uc < half or vc < half or uc >= w - 1 - half or vc >= h - 1 - half:
            continue
        iu = int(uc)
        iv = int(vc)
        fu = uc - iu
        fv = vc - iv
        w00 = (1.0 - fu) * (1.0 - fv)
        w01 = fu * (1.0 - fv)
        w10 = (1.0 - fu) * fv
        w11 = fu * fv
        if iv != qr or iu != qc:  # a new corner block: keep the corners it shares with the last one
            dr = iv - qr
            dc = iu - qc
            # the new corner (iv + i, iu + j) is the held corner (i + dr, j + dc) when both are 0 or 1
            n00, n01, n10, n11 = c00, c01, c10, c11
            if packed:  # two new corners in one sum: a column move's pair from plane 0, a row move's from plane 1
                if dr == 0 and dc == 1:
                    n00, n10 = c01, c11
                    s = _packed_correlation(pairs[0], iv, iu + 1, tmpl_int, half)
                    n01, n11 = float(s & _LOW_HALF), float(s >> 32)
                elif dr == 0 and dc == -1:
                    n01, n11 = c00, c10
                    s = _packed_correlation(pairs[0], iv, iu, tmpl_int, half)
                    n00, n10 = float(s & _LOW_HALF), float(s >> 32)
                elif dr == 1 and dc == 0:
                    n00, n01 = c10, c11
                    s = _packed_correlation(pairs[1], iv + 1, iu, tmpl_int, half)
                    n10, n11 = float(s & _LOW_HALF), float(s >> 32)
                elif dr == -1 and dc == 0:
                    n10, n11 = c00, c01
                    s = _packed_correlation(pairs[1], iv, iu, tmpl_int, half)
                    n00, n01 = float(s & _LOW_HALF), float(s >> 32)
                else:  # a diagonal move or a jump: both columns (a kept corner computed again: the same value)
                    s = _packed_correlation(pairs[0], iv, iu, tmpl_int, half)
                    n00, n10 = float(s & _LOW_HALF), float(s >> 32)
                    s = _packed_correlation(pairs[0], iv, iu + 1, tmpl_int, half)
                    n01, n11 = float(s & _LOW_HALF), float(s >> 32)
            elif dr == 0 and dc == 1:
                n00, n10 = c01, c11
                n01 = _correlation(cur, iv, iu + 1, tmpl, half)
                n11 = _correlation(cur, iv + 1, iu + 1, tmpl, half)
            elif dr == 0 and dc == -1:
                n01, n11 = c00, c10
                n00 = _correlation(cur, iv, iu, tmpl, half)
                n10 = _correlation(cur, iv + 1, iu, tmpl, half)
            elif dr == 1 and dc == 0:
                n00, n01 = c10, c11
                n10 = _correlation(cur, iv + 1, iu, tmpl, half)
                n11 = _correlation(cur, iv + 1, iu + 1, tmpl, half)
            elif dr == -1 and dc == 0:
                n10, n11 = c00, c01
                n00 = _correlation(cur, iv, iu, tmpl, half)
                n01 = _correlation(cur, iv, iu + 1, tmpl, half)
            else:  # a diagonal move keeps one corner (computed, then taken from the block: the same value; this
                # form compiled 10 % faster than skipping it), a jump none
                n00 = _correlation(cur, iv, iu, tmpl, half)
                n01 = _correlation(cur, iv, iu + 1, tmpl, half)
                n10 = _correlation(cur, iv + 1, iu, tmpl, half)
                n11 = _correlation(cur, iv + 1, iu + 1, tmpl, half)
                if dr == 1 and dc == 1:
                    n00 = c11
                elif dr == 1 and dc == -1:
                    n01 = c10
                elif dr == -1 and dc == 1:
                    n10 = c01
                elif dr == -1 and dc == -1:
                    n11 = c00
            c00, c01, c10, c11 = n00, n01, n10, n11
            qr = iv
            qc = iu
        y0 = np.uintp(iv)
        y1 = np.uintp(iv + 1)
        x0 = np.uintp(iu)
        x1 = np.uintp(iu + 1)
        s_i = (w00 * tab[y0, x0, 0] + w01 * tab[y0, x1, 0] + w10 * tab[y1, x0, 0]
               + w11 * tab[y1, x1, 0])
        s_ii = (w00 * w00 * tab[y0, x0, 1] + w01 * w01 * tab[y0, x1, 1] + w10 * w10 * tab[y1, x0, 1]
                + w11 * w11 * tab[y1, x1, 1]
                + 2.0 * (w00 * w01 * tab[y0, x0, 2] + w00 * w10 * tab[y0, x0, 3] + w00 * w11 * tab[y0, x0, 4]
                         + w01 * w10 * tab[y0, x1, 5] + w01 * w11 * tab[y0, x1, 3]
                         + w10 * w11 * tab[y1, x0, 2]))
        s_it = w00 * c00 + w01 * c01 + w10 * c10 + w11 * c11
        mean_i = s_i * inv_n
        var_i = s_ii * inv_n - mean_i * mean_i
        if var_i <= 1e-12:
            continue
        ncc = (s_it * inv_n - mean_i * t_mean) / (math.sqrt(var_i) * t_std)
        if ncc > best:
            best = ncc
            best_u = uc
            best_v = vc
    return best, best_u, best_v


@njit(cache=True, nogil=True)
def _best_match_alone(cur: np.ndarray, tab: np.ndarray, tmpl: np.ndarray, pairs: np.ndarray, tmpl_int: np.ndarray,
                      packed: bool, u_mean: float, v_mean: float, du: float, dv: float, half_len: float, step: float,
                      half: int, t_mean: float, t_std: float) -> tuple[float, float, float]:  # pragma: no cover
    return _best_match(cur, tab, tmpl, pairs, tmpl_int, packed, u_mean, v_mean, du, dv, half_len, step, half, t_mean,
                       t_std)


def best_match(cur: np.ndarray, tab: np.ndarray, tmpl: np.ndarray, u_mean: float, v_mean: float, du: float,
               dv: float, half_len: float, step: float, half: int, t_mean: float, t_std: float,
               pairs: np.ndarray | None = None) -> tuple[float, float, float]:
    """:func:`_best_match` callable on its own (tests; the kernel inlines it): two corners at a time when ``pairs``
    (``cur``'s :func:`search_pairs`) is given and the template ``tmpl`` is grey levels too, else one at a time."""
    tmpl = np.ascontiguousarray(tmpl, dtype=np.float64)
    cur = np.ascontiguousarray(cur, dtype=np.float64)
    side = 2 * int(half) + 1
    if cur.ndim != 2 or tab.shape != (*cur.shape, 6) or tmpl.size != side * side:
        raise CnnSlamError(f"best_match: cur (H, W), its search_tables (H, W, 6) and a template of {side}x{side} "
                           f"values, got {cur.shape}, {tab.shape} and {tmpl.size} values")
    if pairs is not None:
        _check_pairs(pairs, cur.shape, "best_match")
    packed = pairs is not None and grey_levels(tmpl) and side <= _MAX_PACKED_SIDE
    return _best_match_alone(cur, tab, tmpl,
                             pairs if packed else _NO_PAIRS, tmpl.astype(np.int64), packed, float(u_mean),
                             float(v_mean), float(du), float(dv), float(half_len), float(step), int(half),
                             float(t_mean), float(t_std))


@njit(cache=True, nogil=True, error_model="numpy")
def _update_seeds(ref: np.ndarray, cur: np.ndarray, tab: np.ndarray, tmpl_mean: np.ndarray, tmpl_std: np.ndarray,
                  mu: np.ndarray, sigma2: np.ndarray, a: np.ndarray, b: np.ndarray, state: np.ndarray,
                  R_cr: np.ndarray, t_cr: np.ndarray, t_rc: np.ndarray, intr: np.ndarray, depth_range: float,
                  params: np.ndarray, pairs: np.ndarray, packed: bool) -> np.ndarray:
    """One REMODE update of every seed in state UPDATE (epipolar ZNCC search, triangulation, VH update, check).

    ref: (H, W) float32, cur: (H, W) float64 intensities; tab: cur's :func:`search_tables`; tmpl_mean, tmpl_std:
    the reference patches' mean and standard deviation; pairs: cur's :func:`search_pairs`, read when ``packed``
    (``ref`` and ``cur`` grey levels: :func:`_best_match`);
    mu, sigma2, a, b: (H, W) float64 seed parameters, updated in place; state: (H, W) uint8, updated in place;
    R_cr, t_cr: T_cur_ref; t_rc: the current camera's centre in reference coordinates; intr: [fx, fy, cx, cy];
    params: [half patch, step, max extent, min ZNCC, px error angle, eta_in, eta_out, sigma ratio, min template std].
    Returns (H, W) uint8 outcome codes (SKIPPED, UPDATED, NO_MATCH, NOT_VISIBLE, FLAT).
    """
    h, w = ref.shape
    fxk, fyk, cxk, cyk = intr[0], intr[1], intr[2], intr[3]
    half = int(params[0])
    step, max_extent, min_ncc, px_angle = params[1], params[2], params[3], params[4]
    eta_in, eta_out, sig_ratio, min_std = params[5], params[6], params[7], params[8]
    outcome = np.zeros((h, w), np.uint8)
    side = 2 * half + 1
    tmpl = np.empty(side * side)
    tmpl_int = np.zeros(side * side, np.int64)
    for y in range(half, h - half):  # a seed's patch inside the image (DepthFilter's BORDER ring is wider)
        for x in range(half, w - half):
            if state[y, x] != UPDATE:
                continue
            # unit bearing of the reference pixel
            bx = (x - cxk) / fxk
            by = (y - cyk) / fyk
            bn = math.sqrt(bx * bx + by * by + 1.0)
            bx, by, bz = bx / bn, by / bn, 1.0 / bn
            m0 = mu[y, x]
            sd = math.sqrt(sigma2[y, x])
            # project the mean, min and max depth
            pz = R_cr[2, 0] * bx + R_cr[2, 1] * by + R_cr[2, 2] * bz
            px_ = R_cr[0, 0] * bx + R_cr[0, 1] * by + R_cr[0, 2] * bz
            py_ = R_cr[1, 0] * bx + R_cr[1, 1] * by + R_cr[1, 2] * bz
            zc = pz * m0 + t_cr[2]
            if zc <= 1e-6:
                outcome[y, x] = NOT_VISIBLE
                continue
            u_mean = fxk * (px_ * m0 + t_cr[0]) / zc + cxk
            v_mean = fyk * (py_ * m0 + t_cr[1]) / zc + cyk
            if u_mean < half or v_mean < half or u_mean >= w - 1 - half or v_mean >= h - 1 - half:
                outcome[y, x] = NOT_VISIBLE
                continue
            if tmpl_std[y, x] < min_std or tmpl_std[y, x] <= 1e-6:  # ZNCC undefined on a flat template
                outcome[y, x] = FLAT
                b[y, x] += 1.0
                continue
            d_min = max(m0 - 3.0 * sd, 1e-3)
            d_max = m0 + 3.0 * sd
            z_min = pz * d_min + t_cr[2]
            z_max = pz * d_max + t_cr[2]
            if z_min <= 1e-6 or z_max <= 1e-6:
                outcome[y, x] = NOT_VISIBLE
                continue
            u0 = fxk * (px_ * d_min + t_cr[0]) / z_min + cxk
            v0 = fyk * (py_ * d_min + t_cr[1]) / z_min + cyk
            u1 = fxk * (px_ * d_max + t_cr[0]) / z_max + cxk
            v1 = fyk * (py_ * d_max + t_cr[1]) / z_max + cyk
            du, dv = u1 - u0, v1 - v0
            length = math.sqrt(du * du + dv * dv)
            if length > 1e-9:
                du, dv = du / length, dv / length
            else:
                du, dv = 1.0, 0.0
            half_len = 0.5 * min(length, max_extent)
            t_mean = tmpl_mean[y, x]
            t_std = tmpl_std[y, x]
            for oy in range(side):
                for ox in range(side):
                    tmpl[oy * side + ox] = ref[np.uintp(y + oy - half), np.uintp(x + ox - half)]
            if packed:
                for k in range(side * side):
                    tmpl_int[k] = int(tmpl[k])
            if half == 2:  # REMODE's 5x5 patch: constant bounds, the correlations unrolled
                best, best_u, best_v = _best_match(cur, tab, tmpl, pairs, tmpl_int, packed, u_mean, v_mean, du, dv,
                                                   half_len, step, 2, t_mean, t_std)
            else:
                best, best_u, best_v = _best_match(cur, tab, tmpl, pairs, tmpl_int, packed, u_mean, v_mean, du, dv,
                                                   half_len, step, half, t_mean, t_std)
            if best < min_ncc:
                outcome[y, x] = NO_MATCH
                b[y, x] += 1.0
                continue
            # triangulate along the reference bearing (SVO depthFromTriangulation)
            cx_ = (best_u - cxk) / fxk
            cy_ = (best_v - cyk) / fyk
            cn = math.sqrt(cx_ * cx_ + cy_ * cy_ + 1.0)
            cx_, cy_, cz_ = cx_ / cn, cy_ / cn, 1.0 / cn
            rx, ry, rz = px_, py_, pz  # R_cr bearing
            a11 = rx * rx + ry * ry + rz * rz
            a12 = rx * cx_ + ry * cy_ + rz * cz_
            a22 = cx_ * cx_ + cy_ * cy_ + cz_ * cz_
            det = a11 * a22 - a12 * a12
            if det < 1e-6:
                outcome[y, x] = NO_MATCH
                b[y, x] += 1.0
                continue
            r1 = rx * t_cr[0] + ry * t_cr[1] + rz * t_cr[2]
            r2 = cx_ * t_cr[0] + cy_ * t_cr[1] + cz_ * t_cr[2]
            depth = abs(-(a22 * r1 - a12 * r2) / det)
            tau = _tau(bx, by, bz, depth, t_rc[0], t_rc[1], t_rc[2], px_angle)
            if not (tau > 0.0 and tau < math.inf):
                outcome[y, x] = NO_MATCH
                continue
            nm, ns, na, nb = _vh_update(m0, sigma2[y, x], a[y, x], b[y, x], depth, tau * tau, depth_range)
            if math.isnan(nm) or math.isnan(ns) or ns <= 0.0:
                continue
            mu[y, x], sigma2[y, x], a[y, x], b[y, x] = nm, ns, na, nb
            outcome[y, x] = UPDATED
    _seed_check(mu, sigma2, a, b, state, eta_in, eta_out, sig_ratio)
    return outcome


@njit(cache=True, nogil=True, error_model="numpy")
def _seed_check(mu: np.ndarray, sigma2: np.ndarray, a: np.ndarray, b: np.ndarray, state: np.ndarray, eta_in: float,
                eta_out: float, sig_ratio: float) -> None:
    """REMODE's seedCheck of every seed in state UPDATE, ``state`` changed in place: CONVERGED when its inlier ratio
    a / (a + b) > ``eta_in`` and sqrt(sigma2) < ``sig_ratio`` mu, else DIVERGED when (a - 1) / (a + b - 2) <
    ``eta_out``. mu, sigma2, a, b: (H, W) float64 seed parameters; state: (H, W) uint8."""
    h, w = state.shape
    for y in range(h):
        for x in range(w):
            if state[y, x] != UPDATE:
                continue
            aa, bb = a[y, x], b[y, x]
            if aa / (aa + bb) > eta_in and math.sqrt(sigma2[y, x]) < sig_ratio * mu[y, x]:
                state[y, x] = CONVERGED
            elif (aa - 1.0) / (aa + bb - 2.0) < eta_out:
                state[y, x] = DIVERGED


def _gray(image: np.ndarray) -> np.ndarray:
    """(H, W) float32 grey intensities of an (H, W) grey or (H, W, 3) uint8 RGB image (OpenCV's RGB to grey)."""
    image = np.asarray(image)
    if image.ndim == 3:
        if image.shape[2] != 3 or image.dtype != np.uint8:
            raise CnnSlamError(f"expected an (H, W, 3) uint8 RGB image, got {image.shape} {image.dtype}")
        return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
    if image.ndim != 2:
        raise CnnSlamError(f"expected an (H, W) grey or (H, W, 3) RGB image, got shape {image.shape}")
    return np.ascontiguousarray(image, dtype=np.float32)
