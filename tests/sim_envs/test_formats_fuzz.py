"""Property-based test of the KITTI pose reader of :mod:`sim_envs.folders.formats` (``fuzz_reader``: tests/conftest.py):
mutated valid files give valid poses or one :class:`FormatError` line naming the file. The TUM trajectory reader's
fast path is fuzzed against its line reader (tests/slamcommon/formats/test_tum_fuzz.py); the TUM image lists as a
TUM RGB-D folder's (tests/sim_envs/test_folder_layouts_fuzz.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_envs.folders.formats import read_kitti_poses

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

KITTI_SEEDS = (
    "1.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00 0.000000e+00 "
    "0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
    "9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 -5.296506e-04 9.999992e-01 -1.154865e-03 -2.839928e-02 "
    "2.066324e-03 1.155958e-03 9.999971e-01 8.586941e-01\n",
)


def _check_poses(T: np.ndarray) -> None:
    assert T.ndim == 3 and T.shape[1:] == (4, 4) and T.shape[0] >= 1
    assert np.isfinite(T).all()
    R = T[:, :3, :3]
    assert np.allclose(R.transpose(0, 2, 1) @ R, np.eye(3), atol=1e-3)
    assert np.allclose(T[:, 3], [0, 0, 0, 1])


def test_kitti_pose_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(tmp_path / "00.txt", KITTI_SEEDS, read_kitti_poses, _check_poses)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
