"""slamcommon.output_paths: an output file or folder a command could not write is refused in one line naming the
option and the path, and the check leaves nothing behind."""

from __future__ import annotations

import os

import pytest

from slamcommon.errors import ProjectError
from slamcommon.output_paths import OutputPathError, check_output_file, check_output_folder


def test_writable_paths_pass_and_leave_nothing_behind(tmp_path):
    assert check_output_folder(tmp_path / "a" / "b", "--out") == tmp_path / "a" / "b"
    assert check_output_file(tmp_path / "c" / "d.tum", "--save") == tmp_path / "c" / "d.tum"
    (tmp_path / "e.txt").write_text("kept")
    assert check_output_file(tmp_path / "e.txt", "--save") == tmp_path / "e.txt"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.txt"] and (tmp_path / "e.txt").read_text() == "kept"


@pytest.mark.parametrize(("check", "where", "expected"), [
    (check_output_folder, "file", "a file, not a folder"),
    (check_output_folder, "file/sub", "is a file, not a folder"),
    (check_output_file, "folder", "a folder, not a file"),
    (check_output_file, "file/x.tum", "is a file, not a folder"),
])
def test_a_path_that_cannot_be_written_is_named_in_one_line(tmp_path, check, where, expected):
    (tmp_path / "file").write_text("")
    (tmp_path / "folder").mkdir()
    with pytest.raises(OutputPathError, match=expected) as info:
        check(tmp_path / where, "--out")
    assert isinstance(info.value, ProjectError)
    assert str(info.value).startswith(f"--out {tmp_path / where}") and "\n" not in str(info.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "folder"]


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs a POSIX user other than root (root "
                    "writes into a read-only folder): run the tests as a normal user")
def test_a_read_only_folder_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(OutputPathError, match="cannot write in"):
            check_output_folder(ro / "new", "--out")
        with pytest.raises(OutputPathError, match="cannot write in"):
            check_output_file(ro / "x.tum", "--save")
    finally:
        ro.chmod(0o755)


def test_a_folder_the_user_may_not_write_is_refused_and_what_the_try_made_is_removed(tmp_path, monkeypatch):
    """As the probe sees it when the file system says no (a read-only mount, no permission; as root too)."""
    import slamcommon.output_paths as output_paths

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(output_paths.tempfile, "NamedTemporaryFile", refuse)
    with pytest.raises(OutputPathError, match=r"--out .*new/deeper: cannot write in .*\(Permission denied\)"):
        check_output_folder(tmp_path / "new" / "deeper", "--out")
    with pytest.raises(OutputPathError, match="cannot write in"):
        check_output_file(tmp_path / "x.tum", "--save")
    assert list(tmp_path.iterdir()) == []
