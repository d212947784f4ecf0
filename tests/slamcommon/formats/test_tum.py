"""slamcommon.formats.tum: the fast TUM reader (:func:`read_tum_trajectory`) gives the line-by-line reader's poses
(bit for bit) and its errors; the old import paths (``eval.metrics.tum_reader``, ``sim_envs.folders.formats``) are
it."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import eval.metrics.tum_reader
import sim_envs.errors
import sim_envs.folders.formats
from eval.metrics.trajectory import PoseTrajectory, TrajectoryError
from slamcommon.errors import FormatError
from slamcommon.formats.lines import data_line_numbers
from slamcommon.formats.tum import (
    QUATERNION_TOL,
    parse_plain_tum_text,
    quaternions_to_matrices,
    read_tum_trajectory_by_line,
)
from slamcommon.formats.tum import read_tum_trajectory as read_tum_file


class reference:  # noqa: N801 - the line-by-line reader and scipy, what the fast path must equal
    read_tum_trajectory = staticmethod(read_tum_trajectory_by_line)

    @staticmethod
    def quaternions_to_matrices(p, q):
        T = np.tile(np.eye(4), (len(p), 1, 1))
        if len(p):
            T[:, :3, :3] = Rotation.from_quat(q).as_matrix()
            T[:, :3, 3] = p
        return T

GOOD = [
    "1.0 0 0 0 0 0 0 1",
    "2.0 1 0 0 0 0 0 1",
    "3.0 1 1 0 0 0 0 1",
    "4.0 2 1 0.5 0 0 0.7071068 0.7071068",
    "5.0 2 2 1 0 0 0 1",
]
CLEAN = {  # the fast path takes these
    "plain": "\n".join(GOOD) + "\n",
    "no final newline": "\n".join(GOOD),
    "comments and blank lines": "# header\n\n"
    + f"{GOOD[0]}  # trailing\n   \n\t{GOOD[1]}\n#x\n"
    + "\n".join(GOOD[2:])
    + "\n# end\n",
    "commas and tabs": "\n".join(
        [GOOD[0].replace(" ", ","), GOOD[1].replace(" ", ", "), GOOD[2].replace(" ", "\t"), *GOOD[3:]]
    ),
    "leading comma": "," + "\n".join(GOOD),
    "crlf": "\r\n".join(GOOD) + "\r\n",
    "cr": "\r".join(GOOD) + "\r",
    "exponents and signs": "1.0e0 1E-3 +0 -0 0 0 0 1\n2 .5 5. 1e+0 0 0 0 1.0000\n" + "\n".join(GOOD[2:]),
    "non-ASCII comment": "# überschrift\n" + "\n".join(GOOD),
}
LEFT_TO_THE_REFERENCE = {  # (content, first words of the error; None: read by the reference, no error)
    "7 columns": ("\n".join([*GOOD[:2], "3.0 1 1 0 0 0 1", *GOOD[3:]]), ":3: expected 8 columns"),
    "9 columns": ("\n".join([*GOOD[:2], "3.0 1 1 0 0 0 0 1 7", *GOOD[3:]]), ":3: expected 8 columns"),
    "1 column": ("1.0\n", ":1: expected 8 columns"),
    "commas only": ("\n".join([*GOOD[:2], " , ,", *GOOD[2:]]), ":3: expected 8 columns"),
    "not a number": ("\n".join([*GOOD[:3], "4.0 2 x 0.5 0 0 0.7071068 0.7071068"]), ":4: column 3 is 'x'"),
    "hexadecimal": ("\n".join([*GOOD[:3], "4.0 0x10 1 0.5 0 0 0.7071068 0.7071068"]), ":4: column 2 is '0x10'"),
    "two dots": ("\n".join([*GOOD[:3], "4.0 1.2.3 1 0.5 0 0 0.7071068 0.7071068"]), ":4: column 2 is '1.2.3'"),
    "bare exponent": ("\n".join([*GOOD[:3], "4.0 1e 1 0.5 0 0 0.7071068 0.7071068"]), ":4: column 2 is '1e'"),
    "nan": ("\n".join([*GOOD[:3], "4.0 2 nan 0.5 0 0 0.7071068 0.7071068"]), ":4: column 3 is 'nan'"),
    "-inf": ("\n".join([*GOOD[:3], "4.0 2 1 -inf 0 0 0.7071068 0.7071068"]), ":4: column 4 is '-inf'"),
    "overflow": ("\n".join([*GOOD[:3], "4.0 2 1 1e999 0 0 0.7071068 0.7071068"]), ":4: column 4 is '1e999'"),
    "non-unit quaternion": ("\n".join([*GOOD[:3], "4.0 2 1 0.5 0 0 0.7 0.7"]), ":4: quaternion"),
    "decreasing": ("\n".join([*GOOD[:3], "2.5 2 1 0.5 0 0 0.7071068 0.7071068"]), ":4: timestamp 2.5 is smaller"),
    "repeated": ("\n".join([*GOOD[:3], "3.0 2 1 0.5 0 0 0.7071068 0.7071068"]), ":4: timestamp 3.0 repeats"),
    "only comments": ("# nothing\n\n", ": no poses found"),
    "empty": ("", ": no poses found"),
    "byte order mark": ("\ufeff" + "\n".join(GOOD), ":1: column 1 is '\\ufeff1.0'"),
    "form feed in a comment": ("# a\x0c1.0 0 0 0 0 0 0 2\n" + "\n".join(GOOD[1:]), ":2: quaternion"),
    "no-break space": ("\n".join([GOOD[0], GOOD[1].replace(" ", "\u00a0"), *GOOD[2:]]), None),
    "underscore": ("\n".join([*GOOD[:3], "4.0 2_0 1 0.5 0 0 0.7071068 0.7071068"]), None),
}


def read_both(path, **kwargs):
    """(ours, reference's) result or error message for one file."""
    results = []
    for read, error in ((read_tum_file, FormatError), (reference.read_tum_trajectory, FormatError)):
        try:
            results.append(read(path, **kwargs))
        except error as exc:
            results.append(str(exc))
    return results


def assert_same(ours, theirs):
    if isinstance(theirs, str):
        assert ours == theirs
    else:
        assert not isinstance(ours, str), ours
        for a, b in zip(ours, theirs, strict=True):
            assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def test_the_old_import_paths_are_the_one_reader(tmp_path):
    """eval.metrics.tum_reader re-exports it; sim_envs.folders.formats wraps it, raising the world's FormatError."""
    assert eval.metrics.tum_reader.read_tum_file is read_tum_file
    assert eval.metrics.tum_reader.TumFileError is FormatError
    assert sim_envs.folders.formats.read_tum_trajectory.__wrapped__ is read_tum_file
    path = tmp_path / "bad.txt"
    path.write_text("1.0 0 0 0 0 0 0\n")
    with pytest.raises(sim_envs.errors.FormatError, match=r"bad\.txt:1: expected 8 columns") as err:
        sim_envs.folders.formats.read_tum_trajectory(path)
    assert isinstance(err.value, sim_envs.errors.SimEnvError) and isinstance(err.value, FormatError)


def test_quaternions_to_matrices_are_scipys_bit_for_bit():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(20_000, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= rng.uniform(1 - QUATERNION_TOL, 1 + QUATERNION_TOL, size=(q.shape[0], 1))  # what the tolerance lets in
    q = np.concatenate([q, np.round(q, 4), [[0, 0, 0, 1], [1, 0, 0, 0], [0, 0, 0, -1]]])
    p = rng.normal(size=(q.shape[0], 3))
    ours, theirs = quaternions_to_matrices(p, q), reference.quaternions_to_matrices(p, q)
    assert ours.tobytes() == theirs.tobytes()
    assert np.array_equal(ours[:, :3, :3], Rotation.from_quat(q).as_matrix())
    assert quaternions_to_matrices(np.zeros((0, 3)), np.zeros((0, 4))).shape == (0, 4, 4)
    assert quaternions_to_matrices(p[:1], q[:1]).tobytes() == reference.quaternions_to_matrices(p[:1], q[:1]).tobytes()


@pytest.mark.parametrize("name", sorted(CLEAN))
def test_clean_files_take_the_fast_path_and_read_as_the_reference(tmp_path, name):
    path = tmp_path / "traj.txt"
    path.write_bytes(CLEAN[name].encode("utf-8"))
    values = parse_plain_tum_text(path.read_bytes().decode("utf-8"))
    assert values is not None and values.shape == (5, 8)
    ours, theirs = read_both(path)
    assert_same(ours, theirs)
    assert ours[0].tolist() == [1.0, 2.0, 3.0, 4.0, 5.0]


@pytest.mark.parametrize("name", sorted(LEFT_TO_THE_REFERENCE))
def test_other_files_get_the_references_result_and_one_error_naming_file_and_line(tmp_path, name):
    content, message = LEFT_TO_THE_REFERENCE[name]
    path = tmp_path / "traj.txt"
    path.write_bytes(content.encode("utf-8"))
    ours, theirs = read_both(path)
    assert_same(ours, theirs)
    if message is None:
        assert not isinstance(ours, str)
    else:
        assert ours.startswith(f"{path}{message}")
        with pytest.raises(TrajectoryError, match="^" + re.escape(f"{path}{message}")):
            PoseTrajectory.from_tum_file(path)


def test_unreadable_and_binary_files(tmp_path):
    missing, folder, binary = tmp_path / "missing.txt", tmp_path, tmp_path / "binary.txt"
    binary.write_bytes(b"1.0 0 0 0 0 0 0 1\n\xff\xfe 2\n")
    for path, words in ((missing, "cannot read the file"), (folder, "cannot read the file"), (binary, "UTF-8")):
        ours, theirs = read_both(path)
        assert ours == theirs and ours.startswith(f"{path}: ") and words in ours


@pytest.mark.parametrize("policy", ["first", "last"])
def test_repeated_timestamps_as_the_reference(tmp_path, policy):
    lines = [*GOOD[:3], "3.0 2 1 0.5 0 0 0.7071068 0.7071068", *GOOD[3:], "6.0 0 0 0 0 0 0 1", "6.0 1 0 0 0 0 0 1"]
    path = tmp_path / "dup.txt"
    path.write_text("# stamps repeat\n\n" + "\n".join(lines) + "\n")
    ours_said: list[str] = []
    theirs_said: list[str] = []
    ours = read_tum_file(path, duplicate_timestamps=policy, on_duplicates=ours_said.append)
    theirs = reference.read_tum_trajectory(path, duplicate_timestamps=policy, on_duplicates=theirs_said.append)
    assert_same(ours, theirs)
    assert (
        ours_said
        == theirs_said
        == [f"{path}: 2 repeated timestamp(s), the first 3.0 on lines 5 and 6; kept the {policy} pose of each"]
    )
    assert ours[1][:, 0, 3].tolist() == {"first": [0, 1, 1, 2, 2, 0], "last": [0, 1, 2, 2, 2, 1]}[policy]
    ours, theirs = read_both(path)  # duplicate_timestamps="error"
    assert ours == theirs and ours.startswith(f"{path}:6: timestamp 3.0 repeats the timestamp 3.0 of line 5")


def test_data_line_numbers_count_as_the_reference():
    text = "# a\n\n1 2\r\n  # b\n3 4 # c\r5\x0c6\n"
    assert data_line_numbers(text) == [3, 5, 6, 7]


def test_real_files_read_as_the_reference(tum_dir):
    paths = sorted(tum_dir.glob("*.txt"))
    assert len(paths) >= 4  # the reference cases' ground truths and estimates, at least
    for path in paths:
        for policy in ("last", "first"):
            messages: tuple[list[str], list[str]] = ([], [])
            ours = read_tum_file(path, duplicate_timestamps=policy, on_duplicates=messages[0].append)
            theirs = reference.read_tum_trajectory(path, duplicate_timestamps=policy,
                                                   on_duplicates=messages[1].append)  # fmt: skip
            assert_same(ours, theirs)
            assert messages[0] == messages[1], path.name
        assert parse_plain_tum_text(path.read_text()) is not None, path.name  # all on the fast path
