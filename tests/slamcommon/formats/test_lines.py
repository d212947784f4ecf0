"""slamcommon.formats.lines: comments, separators and line numbers; increasing timestamps and repeated ones."""

import numpy as np
import pytest

from slamcommon.errors import FormatError
from slamcommon.formats.lines import check_increasing, data_line_numbers, data_lines, parse_numbers


def test_data_lines_skip_comments_and_split_on_blanks_tabs_and_commas(tmp_path):
    path = tmp_path / "f.txt"
    path.write_text("# head\n\n1, 2\t3 # tail\n  \n4,,5\n")
    assert data_lines(path) == [(3, ["1", "2", "3"]), (5, ["4", "5"])]
    assert data_line_numbers(path.read_text()) == [3, 5]


def test_parse_numbers_names_file_line_and_column(tmp_path):
    path = tmp_path / "f.txt"
    assert parse_numbers(path, 7, ["1", "2.5"], 2, "a b") == [1.0, 2.5]
    with pytest.raises(FormatError, match=r"f\.txt:7: expected 3 columns \(a b c\), found 2"):
        parse_numbers(path, 7, ["1", "2"], 3, "a b c")
    with pytest.raises(FormatError, match=r"f\.txt:7: column 2 is 'inf'; values must be finite"):
        parse_numbers(path, 7, ["1", "inf"], 2, "a b")


@pytest.mark.parametrize(("policy", "kept"), [("first", [0, 1, 3]), ("last", [0, 2, 3])])
def test_repeated_timestamps_keep_one_row_and_warn_once(tmp_path, policy, kept):
    said: list[str] = []
    keep = check_increasing(tmp_path / "t.txt", [1, 2, 3, 4], np.array([0.0, 1.0, 1.0, 2.0]), policy, said.append)
    assert keep.tolist() == kept
    assert said == [f"{tmp_path / 't.txt'}: 1 repeated timestamp(s), the first 1.0 on lines 2 and 3; kept the "
                    f"{policy} pose of each"]  # fmt: skip
    with pytest.raises(FormatError, match=r"t\.txt:3: timestamp 1.0 repeats"):
        check_increasing(tmp_path / "t.txt", [1, 2, 3, 4], np.array([0.0, 1.0, 1.0, 2.0]), "error")
    with pytest.raises(FormatError, match="duplicate_timestamps must be one of"):
        check_increasing(tmp_path / "t.txt", [1], np.array([0.0]), "keep")  # type: ignore[arg-type]
