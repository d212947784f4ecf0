"""REMODE's denoiser (:func:`tv_smooth`): weighted Huber-ROF total-variation smoothing of a depth map by the
first-order primal-dual algorithm of Chambolle & Pock (2011), as :meth:`cnnslam.baselines.remode.DepthFilter.depth`
applies it with REMODE's confidence weights. The iterations are a serial numba kernel."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnnslam.errors import CnnSlamError


@njit(cache=True, nogil=True, inline="always")
def _tv_dual_px(px: np.ndarray, py: np.ndarray, y: int, x: int, gx: float, gy: float, gg: float, den: float,
                sig: float, inner: float) -> None:
    """The dual step at one pixel: ascent with the Huber prox (``den`` = 1 + sig eps / gg), then the projection
    onto |p| <= gg: p / n with n = |p| / gg where n > 1. ``inner`` = gg^2 (1 - 1e-9): below it |p|^2 cannot give
    n > 1 (the margin is far above the rounding of n), so the square root and division are spared there and every
    result is the same."""
    qx = (px[y, x] + sig * gx) / den
    qy = (py[y, x] + sig * gy) / den
    n2 = qx * qx + qy * qy
    if n2 > inner:
        n = math.sqrt(n2) / gg
        if n > 1.0:
            qx /= n
            qy /= n
    px[y, x] = qx
    py[y, x] = qy


@njit(cache=True, nogil=True)
def _tv_primal_dual(f: np.ndarray, data_weight: np.ndarray, g: np.ndarray, lam: float, eps: float,
                    iterations: int) -> np.ndarray:
    h, w = f.shape
    u = f.copy()
    u_bar = f.copy()
    px = np.zeros((h, w))
    py = np.zeros((h, w))
    tau = 1.0 / math.sqrt(8.0)
    sig = 1.0 / math.sqrt(8.0)
    # per-pixel constants of the iterations (the same expressions, computed once)
    gg = np.empty((h, w))
    den = np.empty((h, w))
    data = np.empty((h, w))
    den_u = np.empty((h, w))
    inner = np.empty((h, w))
    for y in range(h):
        for x in range(w):
            gg[y, x] = max(g[y, x], 1e-9)
            inner[y, x] = gg[y, x] * gg[y, x] * (1.0 - 1e-9)
            den[y, x] = 1.0 + sig * eps / gg[y, x]
            tau_lw = tau * (lam * data_weight[y, x])
            data[y, x] = tau_lw * f[y, x]
            den_u[y, x] = 1.0 + tau_lw
    for _ in range(iterations):
        # dual ascent with the Huber prox and the projection onto |p| <= g (forward differences; 0 past the edge)
        for y in range(h):
            last_row = y + 1 >= h
            for x in range(w - 1):
                gy = 0.0 if last_row else u_bar[y + 1, x] - u_bar[y, x]
                _tv_dual_px(px, py, y, x, u_bar[y, x + 1] - u_bar[y, x], gy, gg[y, x], den[y, x], sig, inner[y, x])
            x = w - 1
            gy = 0.0 if last_row else u_bar[y + 1, x] - u_bar[y, x]
            _tv_dual_px(px, py, y, x, 0.0, gy, gg[y, x], den[y, x], sig, inner[y, x])
        # primal descent with the weighted quadratic data term, then over-relaxation (backward differences)
        for y in range(h):
            for x in range(w):
                div = px[y, x] - (px[y, x - 1] if x > 0 else 0.0)
                div += py[y, x] - (py[y - 1, x] if y > 0 else 0.0)
                if x == w - 1:
                    div -= px[y, x]
                if y == h - 1:
                    div -= py[y, x]
                old = u[y, x]
                new = (old + tau * div + data[y, x]) / den_u[y, x]
                u[y, x] = new
                u_bar[y, x] = 2.0 * new - old
    return u


def tv_smooth(depth: np.ndarray, data_weight: np.ndarray, regulariser_weight: np.ndarray, lam: float,
              huber_epsilon: float, iterations: int) -> np.ndarray:
    """Weighted Huber-ROF smoothing, min_u sum G |grad u|_eps + lam / 2 sum w (u - f)^2, by the primal-dual
    algorithm of Chambolle & Pock (2011) (REMODE's denoiser; tau = sigma = 1 / sqrt(8), theta = 1).

    depth: (H, W) f, metres; data_weight: (H, W) w >= 0 (0 = no data: inpainted); regulariser_weight: (H, W) G > 0;
    lam: 1/m; huber_epsilon: m. Returns (H, W) float64 u.
    """
    f = np.asarray(depth, dtype=np.float64)
    wgt = np.asarray(data_weight, dtype=np.float64)
    g = np.asarray(regulariser_weight, dtype=np.float64)
    if f.shape != wgt.shape or f.shape != g.shape or f.ndim != 2:
        raise CnnSlamError(f"tv_smooth: depth, data_weight and regulariser_weight must be the same (H, W), got "
                           f"{f.shape}, {wgt.shape}, {g.shape}")
    return _tv_primal_dual(f, wgt, g, float(lam), float(huber_epsilon), int(iterations))
