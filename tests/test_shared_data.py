"""The test machinery's shared data (tests/conftest.py): found from the repository or $CNNSLAM_SHARED, a test skipped
with what is missing where it is absent; and tests/reference_facts.toml, the reference figures the tests assert,
the same as the notes they were copied from."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[1]


def test_shared_data_is_found_beside_the_repository_or_where_the_variable_says(shared_data, monkeypatch, tmp_path):
    monkeypatch.delenv("CNNSLAM_SHARED", raising=False)
    (tmp_path / "data" / "tum").mkdir(parents=True)
    (tmp_path / "data" / "tum" / "a.txt").write_text("0 0 0 0 0 0 0 1\n")
    beside = (REPOSITORY.parent / "shared").resolve()
    with pytest.raises(pytest.skip.Exception) as skipped:
        shared_data("no/such/folder")
    assert str(beside / "no" / "such" / "folder") in str(skipped.value)
    assert "../shared beside the repository" in str(skipped.value) and "CNNSLAM_SHARED" in str(skipped.value)
    monkeypatch.setenv("CNNSLAM_SHARED", str(tmp_path))
    assert shared_data("data/tum", "a.txt") == tmp_path.resolve() / "data" / "tum"
    with pytest.raises(pytest.skip.Exception, match=re.escape(str(tmp_path.resolve() / "data" / "tum" / "b.txt"))):
        shared_data("data/tum", "a.txt", "b.txt")  # the folder is there, a file it must hold is not


def test_the_reference_facts_name_their_source_and_files(reference_facts):
    trajectory = reference_facts["trajectory"]
    assert "evo" in trajectory["source"] and "TUM RGB-D benchmark" in trajectory["source"]
    assert trajectory["max_difference"] == 0.02 and len(trajectory["cases"]) == 2
    for case in trajectory["cases"]:
        assert set(case["rmse"]) == {"tum", "nearest"}
        assert all(set(by_alignment) == {"se3", "sim3"} for by_alignment in case["rmse"].values())
        assert case["groundtruth"].endswith(".txt") and case["estimate"].endswith(".txt")


def test_the_reference_facts_are_the_notes_figures(shared_data, reference_facts):
    """Each case's row of the notes' table (section 2) holds the copied figures, in the table's column order: pairs,
    SE(3) and Sim(3) RMSE with the scale under the TUM association, SE(3) and Sim(3) RMSE under evo's."""
    notes = (shared_data("notes", "reference-facts.md") / "reference-facts.md").read_text()
    for case in reference_facts["trajectory"]["cases"]:
        row = f"| {case['groundtruth']} | {case['estimate']} |"
        rows = [line for line in notes.splitlines() if line.startswith(row)]
        assert len(rows) == 1, case["name"]
        cells = [cell.strip() for cell in rows[0].strip("|").split("|")][2:]
        rmse = case["rmse"]
        assert cells == [str(case["pairs"]), rmse["tum"]["se3"], f"{rmse['tum']['sim3']} ({case['scale']})",
                         rmse["nearest"]["se3"], rmse["nearest"]["sim3"]]  # fmt: skip
    assert "association tolerance 0.02 s" in notes
