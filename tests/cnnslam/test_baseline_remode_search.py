"""REMODE's depth filter core (cnnslam.baselines.remode_search): the Vogiatzis-Hernandez update and SVO's
triangulation uncertainty against hand-computed cases, the search tables and pairs against their definitions, the
epipolar search against ZNCC computed by its definition, REMODE's seedCheck."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cnnslam.baselines.remode import DepthFilter, RemodeConfig
from cnnslam.baselines.remode_search import (
    BORDER,
    CONVERGED,
    DIVERGED,
    UPDATE,
    _seed_check,
    best_match,
    search_image,
    search_pairs,
    search_tables,
    triangulation_uncertainty,
    vogiatzis_update,
)
from cnnslam.errors import CnnSlamError

# ------------------------------------------------------------------------------------------------ equations


def test_vogiatzis_update_hand_computed_inlier() -> None:
    # mu = 2, sigma2 = 0.04, a = b = 10; measurement x = 2.1 with tau2 = 0.01; uniform outliers over 4 m.
    # s2 = 1 / (25 + 100) = 0.008; m = 0.008 (2 / 0.04 + 2.1 / 0.01) = 2.08
    # N(2.1 | 2, 0.05) = exp(-0.01 / 0.1) / sqrt(2 pi 0.05) = 1.6143423; C1 = 0.5 N, C2 = 0.5 / 4, normalised:
    # C1 = 0.8659045, C2 = 0.1340955; f = C1 11/21 + C2 10/21 = 0.5174240; e = C1 132/462 + C2 110/462 = 0.2793288
    # mu' = C1 2.08 + C2 2 = 2.0692724; sigma2' = C1 (0.008 + 2.08^2) + C2 (0.04 + 4) - mu'^2 = 0.0130342
    # a' = (e - f) / (f - e / f) = 10.619295; b' = a' (1 - f) / f = 9.904095
    mu, sigma2, a, b = vogiatzis_update(2.0, 0.04, 10.0, 10.0, 2.1, 0.01, 4.0)
    assert mu == pytest.approx(2.0692724, abs=1e-6)
    assert sigma2 == pytest.approx(0.0130342, abs=1e-6)
    assert a == pytest.approx(10.619295, abs=1e-5)
    assert b == pytest.approx(9.904095, abs=1e-5)


def test_vogiatzis_update_outlier_measurement_only_raises_b() -> None:
    # x = 3.5 is 6.7 standard deviations away: C1 = 1.2e-9, so the Gaussian stays and the Beta gains an outlier
    mu, sigma2, a, b = vogiatzis_update(2.0, 0.04, 10.0, 10.0, 3.5, 0.01, 4.0)
    assert mu == pytest.approx(2.0, abs=1e-8) and sigma2 == pytest.approx(0.04, abs=1e-8)
    assert a == pytest.approx(10.0, abs=1e-7) and b == pytest.approx(11.0, abs=1e-7)


def test_triangulation_uncertainty_hand_computed() -> None:
    # bearing (0, 0, 1) at 2 m, current camera 0.1 m to the side: alpha = 90 deg, tan(beta) = 2 / 0.1 = 20, and
    # the law of sines gives z+ = 0.1 tan(beta + px_angle); one pixel at f = 240 is px_angle = 2 atan(1 / 480)
    px_angle = 2.0 * math.atan(1.0 / 480.0)
    expected = 0.1 * math.tan(math.atan(20.0) + px_angle) - 2.0  # = 0.182274 m
    tau = triangulation_uncertainty(np.array([0.0, 0.0, 1.0]), 2.0, np.array([0.1, 0.0, 0.0]), px_angle)
    assert tau == pytest.approx(expected, rel=1e-9)
    assert tau == pytest.approx(0.182274, abs=1e-6)
    # a longer baseline makes the measurement more precise; no baseline makes it useless
    assert triangulation_uncertainty(np.array([0.0, 0.0, 1.0]), 2.0, np.array([0.4, 0.0, 0.0]), px_angle) < 0.05
    assert triangulation_uncertainty(np.array([0.0, 0.0, 1.0]), 2.0, np.zeros(3), px_angle) == math.inf


def _box_sums(p: np.ndarray, half: int) -> np.ndarray:
    """sum of p over the (2 half + 1)^2 window centred on each pixel at least ``half`` from the border (0 elsewhere)."""
    h, w = p.shape
    out = np.zeros((h, w))
    for oy in range(-half, half + 1):
        for ox in range(-half, half + 1):
            out[half:h - half, half:w - half] += p[half + oy:h - half + oy, half + ox:w - half + ox]
    return out


def test_search_tables_are_the_patch_sums() -> None:
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (30, 41)).astype(np.float32)  # camera grey levels
    i = img.astype(np.float64)
    right, down, down_right, down_left = (np.zeros_like(i) for _ in range(4))
    right[:, :-1] = i[:, :-1] * i[:, 1:]
    down[:-1] = i[:-1] * i[1:]
    down_right[:-1, :-1] = i[:-1, :-1] * i[1:, 1:]
    down_left[:-1, 1:] = i[:-1, 1:] * i[1:, :-1]
    inner = (slice(2, -2), slice(2, -2))
    for half, size in ((2, 5), (1, 3)):
        tab = search_tables(img, size)
        assert tab.shape == (30, 41, 6) and tab.dtype == np.float64  # summed in float32: integers below 2^24, exact
        for k, p in enumerate((i, i * i, right, down, down_right, down_left)):
            assert np.array_equal(tab[..., k][inner].astype(np.float64), _box_sums(p, half)[inner])
    noninteger = search_tables(img + 0.25, 5)  # summed in float64
    assert np.allclose(noninteger[..., 1][inner], _box_sums((i + 0.25) ** 2, 2)[inner], rtol=1e-12)
    with pytest.raises(CnnSlamError, match="grey image"):
        search_tables(np.zeros((4, 4, 3)), 5)


def _zncc_by_definition(cur: np.ndarray, tmpl: np.ndarray, u: float, v: float, half: int) -> float | None:
    """The ZNCC of the template (side x side, row-major) against the patch of ``cur`` bilinearly sampled around
    (u, v), pixel by pixel; None where the patch is flat."""
    side = 2 * half + 1
    iu, iv = int(u), int(v)
    fu, fv = u - iu, v - iv
    patch = np.empty((side, side))
    for oy in range(side):
        for ox in range(side):
            r, c = iv + oy - half, iu + ox - half
            patch[oy, ox] = ((1 - fu) * (1 - fv) * cur[r, c] + fu * (1 - fv) * cur[r, c + 1]
                             + (1 - fu) * fv * cur[r + 1, c] + fu * fv * cur[r + 1, c + 1])
    t = tmpl.reshape(side, side)
    if patch.var() <= 1e-12:
        return None
    return float(np.mean((patch - patch.mean()) * (t - t.mean())) / (patch.std() * t.std()))


def test_best_match_is_the_zncc_maximum_along_the_segment() -> None:
    """Every direction of segment (so that the corner block moves along a row, a column, diagonally and, with long
    steps, jumps) and both patch sizes: the search's best ZNCC and position are those of ZNCC by its definition."""
    rng = np.random.default_rng(7)
    cur_u8 = cv2.GaussianBlur(rng.integers(0, 256, (60, 80)).astype(np.uint8), (3, 3), 0)
    cur = cur_u8.astype(np.float64)
    image = search_image(cur_u8, 5)
    assert np.array_equal(image.gray, cur) and image.patch_size == 5
    filt = DepthFilter(cur_u8, np.eye(4), np.array([60.0, 60.0, 40.0, 30.0]), (0.5, 5.0), RemodeConfig(patch_size=3))
    with pytest.raises(CnnSlamError, match="3-pixel patches"):
        filt.update(image, np.eye(4))
    assert filt.update(search_image(cur_u8, 3), np.eye(4)).milliseconds > 0  # the filter's own patch size
    cases = 0
    for half in (2, 1):
        tab = search_tables(cur_u8.astype(np.float32), 2 * half + 1)
        for angle in np.linspace(0.0, 2 * np.pi, 13):
            for step in (0.7, 2.3):
                y0, x0 = (int(x) for x in rng.integers(10, 50, 2))
                noise = rng.normal(0, 4.0, (2 * half + 1) ** 2)
                tmpl = cur[y0 - half:y0 + half + 1, x0 - half:x0 + half + 1].ravel() + noise
                u_mean, v_mean = x0 + rng.uniform(-3, 3), y0 + rng.uniform(-3, 3)
                du, dv = math.cos(angle), math.sin(angle)
                half_len = 25.0
                got = best_match(cur, tab, tmpl, u_mean, v_mean, du, dv, half_len, step, half,
                                 float(tmpl.mean()), float(tmpl.std()))
                scores = []
                for k in range(int(2.0 * half_len / step) + 1):
                    u, v = u_mean + (-half_len + k * step) * du, v_mean + (-half_len + k * step) * dv
                    if u < half or v < half or u >= 80 - 1 - half or v >= 60 - 1 - half:
                        continue
                    score = _zncc_by_definition(cur, tmpl, u, v, half)
                    if score is not None:
                        scores.append((score, u, v))
                best = max(scores, key=lambda x: x[0])
                assert got[0] == pytest.approx(best[0], abs=1e-9)
                assert (got[1], got[2]) == (best[1], best[2])
                cases += 1
    assert cases == 52


def test_search_pairs_pack_each_pixel_with_its_neighbours() -> None:
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (7, 9)).astype(np.float32)
    pairs = search_pairs(img)
    i = img.astype(np.int64)
    assert pairs.shape == (2, 7, 9) and pairs.dtype == np.int64
    assert np.array_equal(pairs[0] & 0xFFFFFFFF, i) and np.array_equal(pairs[1] & 0xFFFFFFFF, i)
    assert np.array_equal(pairs[0, :-1] >> 32, i[1:]) and np.array_equal(pairs[0, -1] >> 32, np.zeros(9))
    assert np.array_equal(pairs[1, :, :-1] >> 32, i[:, 1:]) and np.array_equal(pairs[1, :, -1] >> 32, np.zeros(7))
    for bad in (img + 0.5, img + 256, -img - 1, np.zeros((0, 4)), np.zeros((4, 4, 3))):
        with pytest.raises(CnnSlamError, match="integer grey levels"):
            search_pairs(bad)
    # a search image carries them for grey levels only
    assert np.array_equal(search_image(img.astype(np.uint8), 5).pairs, pairs)
    assert search_image(img + 0.5, 5).pairs is None


def test_best_match_two_corners_at_a_time_is_the_same_search() -> None:
    """Grey levels in the image and the template: the packed sums give the same best ZNCC and position, bit for
    bit, as the corner-by-corner search, in every direction (row, column, diagonal moves and jumps), with both patch
    sizes; a template that is not grey levels is searched corner by corner."""
    rng = np.random.default_rng(11)
    cur_u8 = cv2.GaussianBlur(rng.integers(0, 256, (60, 80)).astype(np.uint8), (3, 3), 0)
    cur = cur_u8.astype(np.float64)
    pairs = search_pairs(cur_u8)
    scored = 0
    for half in (2, 1):
        tab = search_tables(cur_u8.astype(np.float32), 2 * half + 1)
        for angle in np.linspace(0.0, 2 * np.pi, 17):
            for step in (0.7, 1.3, 2.3):
                y0, x0 = (int(x) for x in rng.integers(10, 50, 2))
                tmpl = np.clip(cur[y0 - half:y0 + half + 1, x0 - half:x0 + half + 1].ravel()
                               + rng.integers(-9, 10, (2 * half + 1) ** 2), 0, 255)
                args = (x0 + rng.uniform(-3, 3), y0 + rng.uniform(-3, 3), math.cos(angle), math.sin(angle), 25.0,
                        step, half, float(tmpl.mean()), float(tmpl.std()))
                one = best_match(cur, tab, tmpl, *args)
                two = best_match(cur, tab, tmpl, *args, pairs=pairs)
                assert one == two
                scored += one[0] > -1.0
                noisy = tmpl + 0.25  # not grey levels: the corner-by-corner sums
                assert best_match(cur, tab, noisy, *args, pairs=pairs) == best_match(cur, tab, noisy, *args)
    assert scored == 102


def test_best_match_refuses_tables_pairs_or_template_of_another_size() -> None:
    """The search reads its tables, pairs and template without bounds checks: best_match checks their shapes."""
    cur = np.random.default_rng(2).integers(0, 256, (30, 40)).astype(np.uint8)
    tab = search_tables(cur.astype(np.float32), 5)
    args = (20.0, 15.0, 1.0, 0.0, 10.0, 0.7, 2, 100.0, 20.0)
    tmpl = np.full(25, 100.0)
    for bad_tab, bad_tmpl, bad_pairs, message in ((tab[:20], tmpl, None, "search_tables"),
                                                  (tab, tmpl[:9], None, "5x5"),
                                                  (tab, tmpl, search_pairs(cur[:, :30]), "search_pairs")):
        with pytest.raises(CnnSlamError, match=message):
            best_match(cur, bad_tab, bad_tmpl, *args, pairs=bad_pairs)



def test_seed_check_converges_diverges_or_keeps_each_seed() -> None:
    """REMODE's seedCheck with eta_in 0.7, eta_out 0.05, sigma ratio 0.02, each seed by hand: converged needs both
    a / (a + b) > 0.7 and sigma < 0.02 mu; diverged is (a - 1) / (a + b - 2) < 0.05; seeds not in UPDATE stay."""
    #            inlier ratio, sigma / mu      -> expected
    cases = [((30.0, 10.0, 0.01), UPDATE, CONVERGED),    # 0.75 > 0.7, sigma 0.01 < 0.02 * 2
             ((30.0, 10.0, 0.05), UPDATE, UPDATE),       # sigma 0.05 >= 0.04: not yet
             ((20.0, 10.0, 0.01), UPDATE, UPDATE),       # 0.667 <= 0.7: not yet (and 19 / 28 >= 0.05)
             ((2.0, 30.0, 0.5), UPDATE, DIVERGED),       # (2 - 1) / 30 = 0.033 < 0.05
             ((3.0, 30.0, 0.5), UPDATE, UPDATE),         # (3 - 1) / 31 = 0.065 >= 0.05
             ((2.0, 30.0, 0.5), BORDER, BORDER),         # only seeds in UPDATE are checked
             ((30.0, 10.0, 0.01), DIVERGED, DIVERGED)]
    a = np.array([[c[0][0] for c in cases]])
    b = np.array([[c[0][1] for c in cases]])
    sigma2 = np.array([[c[0][2] ** 2 for c in cases]])
    mu = np.full(a.shape, 2.0)
    state = np.array([[c[1] for c in cases]], np.uint8)
    _seed_check(mu, sigma2, a, b, state, 0.7, 0.05, 0.02)
    assert state.tolist() == [[c[2] for c in cases]]
