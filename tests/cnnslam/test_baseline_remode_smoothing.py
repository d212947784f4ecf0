"""REMODE's denoiser (cnnslam.baselines.remode_smoothing): the weighted Huber-ROF smoothing on a step with noise
and a hole, and the compiled iterations against the same updates written in numpy."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.baselines.remode_smoothing import tv_smooth
from cnnslam.errors import CnnSlamError


def test_tv_smooth_denoises_keeps_edges_and_inpaints() -> None:
    rng = np.random.default_rng(0)
    clean = np.where(np.arange(64)[None, :] < 32, 1.0, 2.0) * np.ones((48, 1))
    noisy = clean + rng.normal(0.0, 0.02, clean.shape)
    weight = np.ones_like(clean)
    weight[10:20, 5:15] = 0.0  # a hole without data
    noisy[10:20, 5:15] = 7.0  # whatever is there is ignored
    out = tv_smooth(noisy, weight, np.ones_like(clean), lam=50.0, huber_epsilon=0.005, iterations=2000)
    flat = (weight > 0) & (np.abs(np.arange(64)[None, :] - 31.5) > 3)
    assert np.std((out - clean)[flat]) < 0.5 * 0.02  # noise reduced
    assert abs(out[:, 40:].mean() - out[25:, :24].mean() - 1.0) < 0.02  # the 1 m step survives
    np.testing.assert_allclose(out[10:20, 5:15], 1.0, atol=0.02)  # the hole takes its surroundings' depth
    with pytest.raises(CnnSlamError, match="same"):
        tv_smooth(noisy, weight[:10], weight, 1.0, 0.01, 1)


def test_tv_smooth_is_the_primal_dual_iteration_in_numpy() -> None:
    """The compiled TV iterations against the Chambolle-Pock updates written as whole-array numpy (forward
    differences, the Huber prox, the projection onto |p| <= G, backward-difference divergence, over-relaxation):
    the same bits."""
    rng = np.random.default_rng(4)
    f = rng.uniform(1.0, 3.0, (12, 16))
    wgt = (rng.random((12, 16)) > 0.3).astype(np.float64)
    g = rng.uniform(0.0, 1.0, (12, 16))
    g[3, 4] = 0.0  # G is floored at 1e-9
    lam, eps, iterations = 50.0, 0.005, 25
    tau = sig = 1.0 / np.sqrt(8.0)
    u, u_bar, px, py = f.copy(), f.copy(), np.zeros_like(f), np.zeros_like(f)
    gg = np.maximum(g, 1e-9)
    for _ in range(iterations):
        gx, gy = np.zeros_like(f), np.zeros_like(f)
        gx[:, :-1] = u_bar[:, 1:] - u_bar[:, :-1]
        gy[:-1] = u_bar[1:] - u_bar[:-1]
        qx = (px + sig * gx) / (1.0 + sig * eps / gg)
        qy = (py + sig * gy) / (1.0 + sig * eps / gg)
        n = np.sqrt(qx * qx + qy * qy) / gg
        with np.errstate(invalid="ignore", divide="ignore"):  # where n <= 1 the quotient is not used
            px, py = np.where(n > 1.0, qx / n, qx), np.where(n > 1.0, qy / n, qy)
        div = px - np.pad(px, ((0, 0), (1, 0)))[:, :-1]
        div += py - np.pad(py, ((1, 0), (0, 0)))[:-1]
        div[:, -1] -= px[:, -1]
        div[-1] -= py[-1]
        lw = lam * wgt
        new = (u + tau * div + tau * lw * f) / (1.0 + tau * lw)
        u, u_bar = new, 2.0 * new - u
    np.testing.assert_array_equal(tv_smooth(f, wgt, g, lam, eps, iterations), u)
