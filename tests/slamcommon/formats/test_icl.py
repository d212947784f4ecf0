"""slamcommon.formats.icl: ICL-NUIM associations.txt read in frame order; bad lines named by file and line."""

import pytest

from slamcommon.errors import FormatError
from slamcommon.formats.icl import read_icl_associations


def test_associations_come_back_in_frame_order(tmp_path):
    path = tmp_path / "associations.txt"
    path.write_text("2 depth/2.png 2 rgb/2.png\n# c\n0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n")
    index, rgb, depth = read_icl_associations(path)
    assert index.tolist() == [0.0, 1.0, 2.0]
    assert rgb == ["rgb/0.png", "rgb/1.png", "rgb/2.png"] and depth == ["depth/0.png", "depth/1.png", "depth/2.png"]


@pytest.mark.parametrize(("text", "message"), [
    ("0 depth/0.png 0\n", r":1: expected 4 columns"),
    ("0 depth/0.png x rgb/0.png\n", r":1: column 3 is 'x', not a frame index"),
    ("# nothing\n", r": no entries"),
])  # fmt: skip
def test_bad_associations_are_one_line_naming_file_and_line(tmp_path, text, message):
    path = tmp_path / "associations.txt"
    path.write_text(text)
    with pytest.raises(FormatError, match=r"associations\.txt" + message):
        read_icl_associations(path)
