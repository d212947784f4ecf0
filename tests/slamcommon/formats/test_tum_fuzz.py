"""Property-based test of the TUM trajectory readers (``fuzz_reader``: tests/conftest.py): the fast reader
:func:`slamcommon.formats.tum.read_tum_trajectory` and the line-by-line :func:`read_tum_trajectory_by_line`, on
mutated valid files, under both duplicate-timestamp policies the commands use. Each input: both give the same bits,
or both refuse it with the same one line naming the file; a result is a valid trajectory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from slamcommon.errors import FormatError
from slamcommon.formats.tum import read_tum_trajectory as read_tum_file
from slamcommon.formats.tum import read_tum_trajectory_by_line as read_tum_trajectory

TumFileError = FormatError  # the fast reader's error: the same class

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

TUM_SEEDS = (
    "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
    "1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
    "1305031102.1858 1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189\n"
    "1305031102.1958 1.3160 0.6254 1.6302 0.6609 0.6199 -0.2893 -0.3086\n"
    "1305031102.2058 1.3066 0.6256 1.6195 0.6629 0.6219 -0.2857 -0.3030\n",
    "0.0 0 0 0 0 0 0 1\n0.033333 0.01 0 0.002 0 0.0087265 0 0.9999619\n"
    "0.066667 0.02 0.001 0.004 0 0.017452 0 0.9998477\n",
    "1.0,0.5,0.25,2.0,0,0,0.7071068,0.7071068\n2.0,\t0.6,0.25,2.0,0,0,0.7071068,0.7071068\n",
)
POLICIES = ("error", "last")  # cnnslam eval's default; the folder readers' (a ground truth that repeats a stamp)


def _read_both(path: Path) -> tuple[np.ndarray, np.ndarray]:
    policy = path.stem.rpartition("_")[2]
    try:
        reference = read_tum_trajectory(path, duplicate_timestamps=policy)
    except FormatError as exc:
        try:
            read_tum_file(path, duplicate_timestamps=policy)
        except TumFileError as fast:
            assert str(fast) == str(exc)
            raise
        raise AssertionError(f"the fast reader takes what the reference refuses: {exc}") from None
    try:
        stamps, T = read_tum_file(path, duplicate_timestamps=policy)
    except TumFileError as exc:
        raise AssertionError(f"the fast reader refuses what the reference takes: {exc}") from None
    assert stamps.tobytes() == reference[0].tobytes() and T.tobytes() == reference[1].tobytes()
    return stamps, T


def _check_trajectory(result: tuple[np.ndarray, np.ndarray]) -> None:
    stamps, T = result
    assert T.ndim == 3 and T.shape[1:] == (4, 4) and T.shape[0] >= 1 and np.isfinite(T).all()
    R = T[:, :3, :3]
    assert np.allclose(R.transpose(0, 2, 1) @ R, np.eye(3), atol=1e-6)
    assert np.allclose(T[:, 3], [0, 0, 0, 1])
    assert stamps.shape == (T.shape[0],) and np.isfinite(stamps).all() and (np.diff(stamps) > 0).all()


def test_tum_trajectory_readers_agree_and_never_traceback(tmp_path: Path, fuzz_reader) -> None:
    seeds = [seed for seed in TUM_SEEDS for _ in POLICIES]
    report = fuzz_reader(lambda i: tmp_path / f"traj_{POLICIES[i % 2]}.txt", seeds, _read_both, _check_trajectory)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
