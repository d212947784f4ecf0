"""Property-based tests of the folder readers of :mod:`sim_envs.folders.folder_layouts` (``fuzz_reader``:
tests/conftest.py):
an ICL-NUIM ``associations.txt`` (read by :func:`index_folder` with a valid ground truth beside it), a TUM RGB-D
folder's ``rgb.txt``, ``depth.txt`` and ``groundtruth.txt`` (one of them mutated), and a 7-Scenes
``frame-XXXXXX.pose.txt`` (:func:`read_pose_matrix`). Mutated valid files give a valid index or pose, or one line
naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_envs.folders.folder_layouts import index_folder, read_pose_matrix

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

ICL_SEEDS = (
    "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n2 depth/2.png 2 rgb/2.png\n3 depth/3.png 3 rgb/3.png\n",
    "# index depth index rgb\n10 depth/10.png 10 rgb/10.png\n11 depth/11.png 11 rgb/11.png\n",
)
ICL_GROUND_TRUTH = "".join(f"{i} {0.01 * i} 0 {0.02 * i} 0 0 0 1\n" for i in (0, 1, 2, 3, 10, 11, 12))
TUM_FILES = {
    "rgb.txt": "# color images\n# timestamp filename\n0.000 rgb/0.000.png\n0.033 rgb/0.033.png\n0.066 rgb/0.066.png\n"
    "0.100 rgb/0.100.png\n",
    "depth.txt": "# depth maps\n0.004 depth/0.004.png\n0.035 depth/0.035.png\n0.070 depth/0.070.png\n"
    "0.101 depth/0.101.png\n",
    "groundtruth.txt": "# timestamp tx ty tz qx qy qz qw\n0.001 0 0 0 0 0 0 1\n0.030 0.01 0 0 0 0 0 1\n"
    "0.068 0.02 0 0 0 0.0087265 0 0.9999619\n0.110 0.03 0 0 0 0.0087265 0 0.9999619\n",
}
SEVEN_SCENES_POSE_SEEDS = (  # as 7-Scenes ships them: tab-separated, a tab at the end of each line
    "9.9935108e-001\t-1.3162127e-002\t-3.2978117e-002\t2.0467613e-002\t\n"
    "1.4019898e-002\t9.9950826e-001\t2.7024969e-002\t-2.0209374e-001\t\n"
    "3.2619465e-002\t-2.7465288e-002\t9.9909037e-001\t-1.4291960e-002\t\n"
    "0.0000000e+000\t0.0000000e+000\t0.0000000e+000\t1.0000000e+000\t\n",
    "1 0 0 0.5\n0 1 0 -0.25\n0 0 1 1.5\n0 0 0 1\n",
    "-inf -inf -inf -inf\n-inf -inf -inf -inf\n-inf -inf -inf -inf\n0 0 0 1\n",  # a frame without pose
)


def _check_index(index) -> None:
    n = len(index.rgb_files)
    assert index.timestamps.shape == (n,) and np.isfinite(index.timestamps).all()
    assert (np.diff(index.timestamps) > 0).all()
    assert index.depth_files is None or len(index.depth_files) == n
    assert index.poses.shape == (n, 4, 4) and np.isfinite(index.poses).all()
    assert index.dropped >= 0


def test_icl_associations_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    (tmp_path / "living_room.gt.freiburg").write_text(ICL_GROUND_TRUTH)
    report = fuzz_reader(tmp_path / "associations.txt", ICL_SEEDS, lambda p: index_folder(p.parent, "icl"),
                         _check_index)  # fmt: skip
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)


def test_tum_folder_index_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    names = list(TUM_FILES)
    for k in range(len(names)):  # folder k: file k mutated, the other two valid
        for name, text in TUM_FILES.items():
            (tmp_path / str(k)).mkdir(exist_ok=True)
            (tmp_path / str(k) / name).write_text(text)
    report = fuzz_reader(lambda k: tmp_path / str(k) / names[k], [TUM_FILES[n] for n in names],
                         lambda p: index_folder(p.parent, "tum"), _check_index)  # fmt: skip
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)


def _check_pose(T: np.ndarray) -> None:
    assert T.shape == (4, 4) and T.dtype == np.float64
    if np.isnan(T).all():
        return  # a frame without pose: dropped by the folder's index
    assert np.isfinite(T).all()
    assert np.allclose(T[:3, :3].T @ T[:3, :3], np.eye(3)) and np.linalg.det(T[:3, :3]) > 0
    assert (T[3] == [0, 0, 0, 1]).all()


def test_seven_scenes_pose_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(tmp_path / "frame-000000.pose.txt", SEVEN_SCENES_POSE_SEEDS, read_pose_matrix, _check_pose)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
