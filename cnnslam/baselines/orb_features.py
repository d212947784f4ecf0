"""ORB features and descriptor matching for the ORB-SLAM baseline (OpenCV's ORB, ORB-SLAM's matching rules).

Pixel (u, v) = (column, row) at full resolution, pixel centres at integers. Descriptors are (N, 32) uint8 (256-bit
rBRIEF); distances are Hamming bit counts. A keypoint's ``octave`` is its pyramid level (scale ``1.2 ** octave``);
ORB-SLAM weights its reprojection errors by ``1 / scale^2`` of the observing level (:func:`level_inv_sigma`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from cnnslam.baselines.orb_config import OrbConfig


@dataclass(frozen=True)
class Features:
    """ORB features of one image.

    uv: (N, 2) float64 pixel positions at full resolution; octave: (N,) int64 pyramid level; descriptors: (N, 32)
    uint8; response: (N,) float32 FAST/Harris response (higher = stronger).
    """

    uv: np.ndarray
    octave: np.ndarray
    descriptors: np.ndarray
    response: np.ndarray

    def __len__(self) -> int:
        return int(self.uv.shape[0])


def make_orb(config: OrbConfig) -> cv2.ORB:
    """OpenCV's ORB detector/descriptor with ORB-SLAM's pyramid; it detects 3x the wanted count at the low FAST
    threshold so that :func:`extract_features` can distribute the features over a grid."""
    return cv2.ORB_create(
        nfeatures=3 * config.n_features,
        scaleFactor=config.scale_factor,
        nlevels=config.n_levels,
        edgeThreshold=config.edge_threshold,
        patchSize=config.patch_size,
        fastThreshold=config.fast_threshold,
    )


def to_gray(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 RGB (or an (H, W) uint8 image) -> (H, W) uint8 grey."""
    rgb = np.asarray(rgb)
    if rgb.ndim == 2:
        return np.ascontiguousarray(rgb, dtype=np.uint8)
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2GRAY)


def grid_select(uv: np.ndarray, response: np.ndarray, image_size: tuple[int, int], cell_px: int, n: int) -> np.ndarray:
    """Indices of at most ``n`` keypoints spread over a grid of ``cell_px`` cells (ORB-SLAM's distribution).

    Each cell keeps its strongest ``ceil(n / cells)`` keypoints; if that leaves fewer than ``n`` (textureless cells),
    the next strongest of the rest fill up to ``n``. uv: (N, 2) pixels; response: (N,); image_size: (H, W).
    Returns sorted int64 indices.
    """
    count = uv.shape[0]
    if count <= n:
        return np.arange(count, dtype=np.int64)
    h, w = image_size
    nx, ny = max(1, int(np.ceil(w / cell_px))), max(1, int(np.ceil(h / cell_px)))
    cx = np.clip((uv[:, 0] // cell_px).astype(np.int64), 0, nx - 1)
    cy = np.clip((uv[:, 1] // cell_px).astype(np.int64), 0, ny - 1)
    cell = cy * nx + cx
    order = np.lexsort((-response, cell))  # by cell, strongest first within a cell
    sorted_cell = cell[order]
    start = np.searchsorted(sorted_cell, sorted_cell, side="left")
    rank = np.empty(count, dtype=np.int64)
    rank[order] = np.arange(count) - start
    cap = int(np.ceil(n / (nx * ny)))
    keep = rank < cap
    if keep.sum() > n:
        first = np.flatnonzero(keep)
        keep[:] = False
        keep[first[np.argsort(-response[first], kind="stable")[:n]]] = True
    elif keep.sum() < n:
        rest = np.flatnonzero(~keep)
        extra = rest[np.argsort(-response[rest], kind="stable")[: n - int(keep.sum())]]
        keep[extra] = True
    return np.flatnonzero(keep)


def extract_features(gray: np.ndarray, orb: cv2.ORB, config: OrbConfig) -> Features:
    """Detect, distribute over the grid and describe ORB features of an (H, W) uint8 image."""
    keypoints = orb.detect(gray, None)
    if not keypoints:
        return empty_features()
    uv = cv2.KeyPoint_convert(keypoints).astype(np.float64).reshape(-1, 2)  # k.pt of each, as float32 -> float64
    response = np.array([k.response for k in keypoints], dtype=np.float32)
    chosen = grid_select(uv, response, gray.shape[:2], config.grid_cell_px, config.n_features)
    keypoints, descriptors = orb.compute(gray, [keypoints[i] for i in chosen])
    if descriptors is None or not keypoints:
        return empty_features()
    return Features(
        uv=cv2.KeyPoint_convert(keypoints).astype(np.float64).reshape(-1, 2),
        octave=np.array([k.octave for k in keypoints], dtype=np.int64),
        descriptors=np.ascontiguousarray(descriptors, dtype=np.uint8),
        response=np.array([k.response for k in keypoints], dtype=np.float32),
    )


def empty_features() -> Features:
    """Features of an image without any."""
    return Features(np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros((0, 32), np.uint8), np.zeros(0, np.float32))


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamming distances of (..., 32) uint8 descriptors (broadcasting), int64 (...)."""
    return np.bitwise_count(np.bitwise_xor(a, b)).sum(axis=-1, dtype=np.int64)


def level_inv_sigma(octave: np.ndarray, scale_factor: float) -> np.ndarray:
    """1 / sigma of a keypoint's position per octave (ORB-SLAM: sigma = scale_factor ** octave, in pixels)."""
    return scale_factor ** (-np.asarray(octave, dtype=np.float64))


def match_descriptors(desc_a: np.ndarray, desc_b: np.ndarray, max_distance: int, ratio: float) -> np.ndarray:
    """Nearest-neighbour matches a -> b by Hamming distance with the ratio test, one-to-one.

    Returns (M, 2) int64 index pairs (i in a, j in b): d(best) <= max_distance and d(best) < ratio d(second best);
    when several a's pick the same b, the closest is kept.
    """
    if len(desc_a) == 0 or len(desc_b) < 2:
        return np.zeros((0, 2), np.int64)
    knn = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(desc_a, desc_b, k=2)
    pairs, dist = [], []
    for m in knn:
        if len(m) < 2:
            continue
        best, second = m
        if best.distance <= max_distance and best.distance < ratio * second.distance:
            pairs.append((best.queryIdx, best.trainIdx))
            dist.append(best.distance)
    return unique_matches(np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(dist, dtype=np.float64))


def unique_matches(pairs: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Keep, for every second index, only the pair with the smallest distance (then for every first index).

    pairs: (M, 2) int64 (i, j); distance: (M,). Returns the kept pairs ordered by i."""
    if len(pairs) == 0:
        return pairs.reshape(0, 2)
    order = np.argsort(distance, kind="stable")
    pairs = pairs[order]
    _, first_b = np.unique(pairs[:, 1], return_index=True)
    pairs = pairs[np.sort(first_b)]
    _, first_a = np.unique(pairs[:, 0], return_index=True)
    return pairs[first_a]  # np.unique sorts: pairs ordered by the first index


def _descriptor_words(desc: np.ndarray) -> np.ndarray:
    """(N, 32) uint8 descriptors as (N, 4) uint64 words (the same bits)."""
    return np.ascontiguousarray(desc, dtype=np.uint8).view(np.uint64).reshape(-1, 4)


@njit(cache=True, nogil=True)
def popcount64(x):  # pragma: no cover - compiled
    """Set bits of a uint64 (SWAR)."""
    x = x - ((x >> np.uint64(1)) & np.uint64(0x5555555555555555))
    x = (x & np.uint64(0x3333333333333333)) + ((x >> np.uint64(2)) & np.uint64(0x3333333333333333))
    x = (x + (x >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return (x * np.uint64(0x0101010101010101)) >> np.uint64(56)


@njit(cache=True, nogil=True)
def _window_search(uv_a, radius, words_a, uv_b, words_b, allowed):  # pragma: no cover - compiled
    """For each a: the smallest and second smallest Hamming distance to the allowed b keypoints within its radius
    (Euclidean, pixels) and the b of the smallest (first in ``allowed`` order among equals); inf / -1 when none.
    The b keypoints are bucketed in a grid of cells as wide as the largest radius."""
    m = uv_a.shape[0]
    cell = max(radius.max(), 1.0)
    k = allowed.shape[0]
    cx = np.empty(k, np.int64)
    cy = np.empty(k, np.int64)
    for q in range(k):
        cx[q] = int(math.floor(uv_b[allowed[q], 0] / cell))
        cy[q] = int(math.floor(uv_b[allowed[q], 1] / cell))
    x0, y0 = cx.min(), cy.min()
    nx, ny = cx.max() - x0 + 1, cy.max() - y0 + 1
    count = np.zeros(nx * ny + 1, np.int64)
    for q in range(k):
        count[(cy[q] - y0) * nx + (cx[q] - x0) + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    members = np.empty(k, np.int64)
    for q in range(k):  # allowed order kept within a cell
        c = (cy[q] - y0) * nx + (cx[q] - x0)
        members[fill[c]] = q
        fill[c] += 1
    best = np.full(m, np.inf)
    second = np.full(m, np.inf)
    best_j = np.full(m, -1, np.int64)
    for i in range(m):
        u, v, r = uv_a[i, 0], uv_a[i, 1], radius[i]
        if not (math.isfinite(u) and math.isfinite(v)):
            continue
        gx0 = max(int(math.floor((u - r) / cell)), x0)
        gx1 = min(int(math.floor((u + r) / cell)), x0 + nx - 1)
        gy0 = max(int(math.floor((v - r) / cell)), y0)
        gy1 = min(int(math.floor((v + r) / cell)), y0 + ny - 1)
        b1, b2, bj, bq = np.inf, np.inf, -1, k
        for gy in range(gy0, gy1 + 1):
            for gx in range(gx0, gx1 + 1):
                c = (gy - y0) * nx + (gx - x0)
                for s in range(start[c], start[c + 1]):
                    q = members[s]
                    j = allowed[q]
                    du = uv_b[j, 0] - u
                    dv = uv_b[j, 1] - v
                    if not math.sqrt(du * du + dv * dv) <= r:
                        continue
                    d = 0.0
                    for w in range(4):
                        d += popcount64(words_a[i, w] ^ words_b[j, w])
                    if d < b1 or (d == b1 and q < bq):
                        b2 = b1 if d < b1 else d
                        b1, bj, bq = d, j, q
                    elif d < b2:
                        b2 = d
        best[i], second[i], best_j[i] = b1, b2, bj
    return best, best_j, second


def match_in_windows(
    uv_a: np.ndarray, desc_a: np.ndarray, uv_b: np.ndarray, desc_b: np.ndarray, radius: np.ndarray | float,
    max_distance: int, ratio: float, candidates_b: np.ndarray | None = None,
) -> np.ndarray:
    """Match each a (a predicted position ``uv_a`` and a descriptor) to the b keypoint within ``radius`` pixels
    with the smallest Hamming distance (ORB-SLAM's SearchByProjection / SearchForInitialization).

    uv_a: (M, 2) predicted pixels; desc_a: (M, 32); uv_b: (N, 2) keypoints; desc_b: (N, 32); radius: scalar or (M,)
    pixels; candidates_b: optional (N,) bool, the b keypoints that may be matched. A match needs d(best) <=
    max_distance and d(best) < ratio d(second best within the window). One-to-one. Returns (K, 2) int64 (i, j).
    """
    m, n = len(uv_a), len(uv_b)
    if m == 0 or n == 0:
        return np.zeros((0, 2), np.int64)
    radius = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=np.float64), (m,)))
    allowed = np.arange(n) if candidates_b is None else np.flatnonzero(candidates_b)
    if allowed.size == 0:
        return np.zeros((0, 2), np.int64)
    best, best_j, second = _window_search(np.ascontiguousarray(uv_a, dtype=np.float64), radius,
                                          _descriptor_words(desc_a), np.ascontiguousarray(uv_b, dtype=np.float64),
                                          _descriptor_words(desc_b), allowed.astype(np.int64))
    ok = (best <= max_distance) & (best < ratio * second)
    pairs = np.stack([np.flatnonzero(ok), best_j[ok]], axis=1)
    return unique_matches(pairs, best[ok])
