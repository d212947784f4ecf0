"""Tests of the training-data report: statistics of known frames, the table."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.depthnet.data_report import data_statistics_markdown, domain_statistics, evenly, source_frames


def _frames(level: int, depth_m: float, n: int = 3):
    rng = np.random.default_rng(level)
    for _ in range(n):
        rgb = np.clip(level + rng.normal(0, 4, (48, 64, 3)), 0, 255).astype(np.uint8)
        depth = np.full((48, 64), depth_m, np.float32)
        depth[:4] = 0.0  # no surface on the top rows
        yield rgb, depth


def test_domain_statistics_of_known_frames() -> None:
    stats = domain_statistics("grey", _frames(120, 2.5))
    assert stats.camera.frames == 3 and stats.camera.brightness_mean == pytest.approx(120, abs=1)
    assert stats.depth.median == pytest.approx(2.5) and stats.depth.valid_share == pytest.approx(44 / 48)
    assert stats.saturation_mean < 40  # nearly grey
    md = data_statistics_markdown([stats, domain_statistics("bright", _frames(200, 1.0))])
    images = md.split("## Depth distribution")[0]
    assert "| grey | 3 |" in images and "| bright | 3 |" in images and images.count("\n|") == 4


def test_evenly_spread_indices_and_frames_of_a_source() -> None:
    assert evenly(10, 3) == [0, 4, 9] and evenly(2, 5) == [0, 1]

    class Source:
        def __len__(self) -> int:
            return 7

        def frame(self, i: int):
            class F:
                rgb = np.full((4, 4, 3), i, np.uint8)
                depth = np.full((4, 4), float(i + 1), np.float32)

            return F

    got = [int(rgb[0, 0, 0]) for rgb, _ in source_frames(Source(), 3)]
    assert got == [0, 3, 6]


def test_depth_distribution_of_known_depths() -> None:
    """Two frames: one with 20 pixels at 0.5 m, 10 at 1.2 m, 67 at 2 m; one with 50 at 5 m; holes (0, nan,
    negative) are no depth, a frame without depth adds nothing."""
    from cnnslam.depthnet.data_report import HISTOGRAM_EDGES_M, NEAR_M, depth_distribution

    a = np.full((10, 10), 2.0, np.float32)
    a[:, :2] = 0.5  # 20 pixels
    a[:, 2] = 1.2  # 10 pixels
    a[0, 3], a[1, 3], a[2, 3] = 0.0, np.nan, -1.0  # 3 holes: 67 pixels at 2 m
    b = np.full((10, 10), 5.0, np.float32)
    b[5:] = 0.0
    d = depth_distribution([a, b, np.zeros((4, 4), np.float32)])
    assert d.frames == 2 and NEAR_M == (1.0, 1.5)
    n = 97 + 50
    assert d.near_share == pytest.approx((20 / n, 30 / n))
    assert sum(d.histogram) == pytest.approx(1.0) and len(d.histogram) == len(HISTOGRAM_EDGES_M) - 1
    assert d.histogram[1] == pytest.approx(20 / n) and d.histogram[2] == pytest.approx(10 / n)  # 0.5-1, 1-1.5 m
    assert d.histogram[4] == pytest.approx(67 / n) and d.histogram[-1] == pytest.approx(50 / n)  # 2-2.5, >= 4 m
    assert d.quantiles[0] == pytest.approx(0.5) and d.quantiles[2] == pytest.approx(2.0) and d.quantiles[4] == 5.0
    assert d.frame_median_quartiles == pytest.approx((2.75, 3.5, 4.25))  # frame medians 2 and 5
    empty = depth_distribution([np.zeros((3, 3), np.float32)])
    assert empty.frames == 0 and np.isnan(empty.quantiles[2]) and np.isnan(empty.near_share[0])


def test_the_report_has_the_depth_distribution() -> None:
    stats = domain_statistics("grey", _frames(120, 2.5))
    assert stats.distribution is not None and stats.distribution.near_share == (0.0, 0.0)
    md = data_statistics_markdown([stats, domain_statistics("near", _frames(90, 0.8))])
    assert "## Depth distribution" in md
    assert "| near | 3 | 0.80 | 0.80 | 0.80 | 0.80 | 0.80 | 100.0 % | 100.0 % | 0.80 / 0.80 / 0.80 |" in md
