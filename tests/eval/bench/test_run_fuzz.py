"""Property-based test of the reader of an external system's ``<sequence>/run.toml`` (its own run time, ``wall_s``;
``fuzz_reader``: tests/conftest.py): mutated valid files give a finite number of seconds >= 0, or one
:class:`~eval.errors.RunnerError` line naming the file."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from eval.bench.run import _declared_seconds

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

RUN_SEEDS = ("wall_s = 12.5\n", "# ORB-SLAM3's own timing\nwall_s = 3\nframes = 60\n", 'wall_s = 1.5e2\nnote = "x"\n')


def _check_wall_s(value: float | None) -> None:
    assert value is None or (isinstance(value, float) and math.isfinite(value) and value >= 0)


def test_run_file_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(tmp_path / "run.toml", RUN_SEEDS, _declared_seconds, _check_wall_s)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
