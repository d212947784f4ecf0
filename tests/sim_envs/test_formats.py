import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.errors import FormatError
from sim_envs.folders.formats import (
    associate_greedy,
    format_tum_trajectory,
    read_kitti_poses,
    read_tum_image_list,
    read_tum_trajectory,
    write_kitti_poses,
    write_tum_image_list,
    write_tum_trajectory,
)


def random_poses(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.random(n, random_state=seed).as_matrix()
    T[:, :3, 3] = rng.normal(0, 3, (n, 3))
    return T


# ---------------------------------------------------------------------------------------------------------- TUM
def test_tum_round_trip(tmp_path):
    stamps = 1311868164.363181 + np.cumsum(np.full(50, 1 / 30))
    T = random_poses(50)
    path = write_tum_trajectory(tmp_path / "traj.txt", stamps, T, header="two\nlines")
    text = path.read_text().splitlines()
    assert text[:3] == ["# two", "# lines", "# timestamp tx ty tz qx qy qz qw"]
    stamps2, T2 = read_tum_trajectory(path)
    np.testing.assert_array_equal(stamps2, stamps)  # timestamps are written exactly
    np.testing.assert_allclose(T2, T, atol=2e-9)


def test_tum_quaternion_is_xyzw_and_pose_is_camera_to_world(tmp_path):
    # 90 degrees about z: qz = qw = sqrt(1/2); the camera sits at (1, 2, 3)
    path = tmp_path / "one.txt"
    path.write_text("0.5 1 2 3 0 0 0.7071068 0.7071068\n")
    stamps, T = read_tum_trajectory(path)
    assert stamps.tolist() == [0.5]
    np.testing.assert_allclose(T[0, :3, 3], [1, 2, 3])
    np.testing.assert_allclose(T[0, :3, :3] @ [1, 0, 0], [0, 1, 0], atol=1e-6)


def test_tum_comments_blank_lines_tabs_and_commas(tmp_path):
    path = tmp_path / "c.txt"
    path.write_text("# header\n\n1.0\t0 0 0 0 0 0 1  # inline comment\n   \n2.0,1,0,0,0,0,0,1\n# end\n")
    stamps, T = read_tum_trajectory(path)
    assert stamps.tolist() == [1.0, 2.0]
    assert T[1, 0, 3] == 1.0


@pytest.mark.parametrize(
    ("content", "line", "fragment"),
    [
        ("# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", 3, "expected 8 columns"),
        ("1 0 0 0 0 0 0 1\n2 0 0 x 0 0 0 1\n", 2, "column 4 is 'x', not a number"),
        ("1 0 0 0 0 0 0 1\n2 0 0 0 0 0 0 1.5\n", 2, "norm 1.5"),
        ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "repeats the timestamp"),
        ("2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", 2, "is smaller than"),
        ("1 0 0 nan 0 0 0 1\n", 1, "finite"),
    ],
)
def test_tum_bad_lines_name_file_and_line(tmp_path, content, line, fragment):
    path = tmp_path / "bad.txt"
    path.write_text(content)
    with pytest.raises(FormatError) as err:
        read_tum_trajectory(path)
    message = str(err.value)
    assert message.startswith(f"{path}:{line}:")
    assert fragment in message


def test_tum_empty_file_and_missing_file(tmp_path):
    path = tmp_path / "empty.txt"
    path.write_text("# nothing\n\n")
    with pytest.raises(FormatError, match="no poses found"):
        read_tum_trajectory(path)
    with pytest.raises(FormatError, match="cannot read"):
        read_tum_trajectory(tmp_path / "missing.txt")


def test_tum_quaternion_tolerance_and_normalisation(tmp_path):
    path = tmp_path / "q.txt"
    path.write_text("1 0 0 0 0 0 0 1.0005\n")  # 4-decimal files are a little off unit
    _, T = read_tum_trajectory(path)
    np.testing.assert_allclose(T[0, :3, :3], np.eye(3))
    with pytest.raises(FormatError, match="unit quaternion"):
        read_tum_trajectory(path, quaternion_tol=1e-5)


def test_tum_duplicate_policies(tmp_path):
    path = tmp_path / "d.txt"
    path.write_text("1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n3 3 0 0 0 0 0 1\n")
    with pytest.raises(FormatError, match="duplicate_timestamps='last'"):
        read_tum_trajectory(path)
    stamps, T = read_tum_trajectory(path, duplicate_timestamps="last")
    assert stamps.tolist() == [1, 2, 3] and T[:, 0, 3].tolist() == [0, 2, 3]
    stamps, T = read_tum_trajectory(path, duplicate_timestamps="first")
    assert stamps.tolist() == [1, 2, 3] and T[:, 0, 3].tolist() == [0, 1, 3]
    path.write_text("1 0 0 0 0 0 0 1\n0.5 1 0 0 0 0 0 1\n")
    with pytest.raises(FormatError, match="is smaller than"):
        read_tum_trajectory(path, duplicate_timestamps="last")


def test_real_tum_ground_truth_with_a_repeated_timestamp(tum_dir):
    path = tum_dir / "fr2_desk_groundtruth.txt"
    with pytest.raises(FormatError) as err:
        read_tum_trajectory(path)
    assert f"{path}:10863:" in str(err.value) and "line 10862" in str(err.value)
    messages: list[str] = []
    stamps, T = read_tum_trajectory(path, duplicate_timestamps="last", on_duplicates=messages.append)
    assert stamps.shape == (20956,) and T.shape == (20956, 4, 4)
    assert messages == [
        f"{path}: 1 repeated timestamp(s), the first 1311868229.576 on lines 10862 and 10863; kept the last pose of "
        "each"
    ]
    read_tum_trajectory(tum_dir / "fr2_desk_ORB.txt", duplicate_timestamps="last", on_duplicates=messages.append)
    assert len(messages) == 1  # nothing dropped, nothing said


def test_format_tum_rejects_mismatched_lengths():
    with pytest.raises(FormatError, match="pair one to one"):
        format_tum_trajectory(np.zeros(3), random_poses(2))


# -------------------------------------------------------------------------------------------------------- KITTI
def test_kitti_round_trip(tmp_path):
    T = random_poses(20, seed=3)
    path = write_kitti_poses(tmp_path / "poses.txt", T)
    rows = path.read_text().splitlines()
    assert len(rows) == 20 and len(rows[0].split()) == 12
    np.testing.assert_allclose(read_kitti_poses(path), T, atol=1e-11)


def test_kitti_bad_lines(tmp_path):
    path = tmp_path / "k.txt"
    path.write_text("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(FormatError, match=r"k\.txt:2: expected 12 columns"):
        read_kitti_poses(path)
    path.write_text("1 0 0 0 0 1 0 0 0 0 2 0\n")
    with pytest.raises(FormatError, match=r"k\.txt:1: the 3x3 block is not a rotation"):
        read_kitti_poses(path)
    path.write_text("1 0 0 0 0 1 0 0 0 0 -1 0\n")  # a reflection
    with pytest.raises(FormatError, match="det"):
        read_kitti_poses(path)


# -------------------------------------------------------------------------------------------------- image lists
def test_image_list_round_trip_and_errors(tmp_path):
    stamps = np.array([0.0, 0.033333, 0.066667])
    path = write_tum_image_list(tmp_path / "rgb.txt", stamps, ["rgb/a.png", "rgb/b.png", "rgb/c.png"], "color")
    s, names = read_tum_image_list(path)
    np.testing.assert_array_equal(s, stamps)
    assert names == ["rgb/a.png", "rgb/b.png", "rgb/c.png"]
    path.write_text("# color\n1.0 rgb/a.png extra\n")
    with pytest.raises(FormatError, match=r"rgb\.txt:2: expected 2 columns"):
        read_tum_image_list(path)


# -------------------------------------------------------------------------------------------------- association
def tum_associate_reference(first, second, offset, max_difference):
    """The TUM tools' associate() written out literally: all candidates, tuple sort, greedy."""
    candidates = sorted(
        (abs(a - (b + offset)), a, b) for a in first for b in second if abs(a - (b + offset)) < max_difference
    )
    free_a, free_b, matches = set(first), set(second), []
    for _, a, b in candidates:
        if a in free_a and b in free_b:
            free_a.remove(a)
            free_b.remove(b)
            matches.append((a, b))
    return sorted(matches)


@pytest.mark.parametrize(("seed", "offset"), list(itertools.product(range(4), (0.0, 0.013))))
def test_associate_greedy_equals_the_tum_tools(seed, offset):
    rng = np.random.default_rng(seed)
    first = np.sort(rng.uniform(0, 5, 150))
    second = np.sort(rng.uniform(0, 5, 120))
    i, j = associate_greedy(first, second, 0.02, offset)
    expected = tum_associate_reference(first.tolist(), second.tolist(), offset, 0.02)
    assert list(zip(first[i].tolist(), second[j].tolist(), strict=True)) == expected
    assert len(set(i.tolist())) == i.size and len(set(j.tolist())) == j.size  # one to one


def test_associate_greedy_small_known_case():
    # 1.0 is closer to 1.005 than 1.012 is; 1.012 then has no partner left within 0.02
    i, j = associate_greedy(np.array([1.0, 1.012, 3.0]), np.array([1.005, 2.0]), 0.02)
    assert i.tolist() == [0] and j.tolist() == [0]
    # strict inequality, like the TUM tools: a difference of exactly max_difference is no pair
    i, _ = associate_greedy(np.array([1.0]), np.array([1.5]), 0.5)
    assert i.size == 0
    with pytest.raises(FormatError, match="max_difference"):
        associate_greedy(np.array([1.0]), np.array([1.0]), 0.0)
