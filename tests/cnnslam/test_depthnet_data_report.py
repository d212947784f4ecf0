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
    assert "| grey | 3 |" in md and "| bright | 3 |" in md and md.count("\n|") == 4


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
