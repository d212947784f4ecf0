"""A sequence by name (:mod:`eval.bench.sequence_resolve`): registered and rotation names, variant marks and camera
presets parsed back to their refs; names of the local dataset list (relative paths from the list's folder, its
options, its refusals); a simulated sequence named without a camera seen through the default one."""

from pathlib import Path

import pytest

from eval.bench.sequence_ref import SequenceRef
from eval.bench.sequence_resolve import (
    DATASETS_ENV,
    DEFAULT_DATASETS_FILE,
    dataset_list_file,
    load_dataset_list,
    resolve_sequence,
    with_default_camera,
)
from eval.errors import SuiteError


def test_registered_rotation_and_marked_names():
    assert resolve_sequence("office0") == SequenceRef("office0", base="office0")
    assert resolve_sequence("office0@clean") == resolve_sequence("office0")  # clean: the renderer's own image
    marked = resolve_sequence("office0+rich+lit@hard")  # marks in either order, one canonical name
    assert marked.name == "office0+lit+rich@hard" and marked.base == "office0"
    assert dict(marked.overrides)["lighting"] == "lit" and dict(marked.overrides)["camera_effects"] == "hard"
    rotation = resolve_sequence("rot_yaw-pitch_20")
    assert rotation.name == "rot_yaw-pitch_20" and rotation.rotation == ("yaw+pitch", 20.0)


def test_bad_names_are_one_line_naming_them():
    with pytest.raises(SuiteError, match=r"sequence 'rot_yawn_30': bad rotation axes 'yawn'"):
        resolve_sequence("rot_yawn_30")
    with pytest.raises(SuiteError, match=r"unknown sequence 'nope'; valid: office0") as info:
        resolve_sequence("nope")
    assert "\n" not in str(info.value)


def test_the_default_camera_is_added_only_where_none_is_named():
    assert with_default_camera("office0").name == "office0@kinect"
    assert with_default_camera("office0@clean").name == "office0"  # named: kept


def test_dataset_list_names_resolve_to_folders(tmp_path, monkeypatch):
    (tmp_path / "scans" / "a").mkdir(parents=True)
    listing = tmp_path / "list.toml"
    listing.write_text('[datasets]\nmine = "scans/a"\n[datasets.other]\npath = "scans/a"\nsize = "native"\n'
                       'depth_scale = 1000\n')
    monkeypatch.setenv(DATASETS_ENV, str(listing))
    assert dataset_list_file() == listing
    entries = load_dataset_list()
    assert list(entries) == ["mine", "other"]
    assert entries["mine"].path == (tmp_path / "scans" / "a").resolve() and entries["mine"].depth_scale is None
    assert entries["other"].size == "native" and entries["other"].depth_scale == 1000.0
    ref = resolve_sequence("mine")
    assert ref.name == "mine" and ref.folder == str((tmp_path / "scans" / "a").resolve())


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[datasets]\noffice0 = "a"\n', "dataset name 'office0' must"),  # a simulated sequence's name
        ('[datasets.x]\npath = "a"\ndepth_scale = -1\n', "depth_scale = -1; it must be a positive number"),
        ('[datasets.x]\npath = "a"\ncolour = "red"\n', "unknown key\\(s\\) 'colour'"),
        ('[other]\nx = "a"\n', "expected only a \\[datasets\\] table"),
    ],
)
def test_a_bad_dataset_list_is_one_line_naming_the_file(tmp_path, text, message):
    listing = tmp_path / "list.toml"
    listing.write_text(text)
    with pytest.raises(SuiteError, match=message) as info:
        load_dataset_list(listing)
    assert str(listing) in str(info.value) and "\n" not in str(info.value)


def test_a_missing_list_is_empty_unless_named(tmp_path, monkeypatch):
    monkeypatch.delenv(DATASETS_ENV, raising=False)
    assert dataset_list_file() == DEFAULT_DATASETS_FILE == Path(__file__).resolve().parents[3] / "datasets.toml"
    monkeypatch.setenv(DATASETS_ENV, str(tmp_path / "none.toml"))
    with pytest.raises(SuiteError, match="no dataset list at"):
        load_dataset_list()
