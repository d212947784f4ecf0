"""sim_envs.folders.folder_layouts: a layout is one registered :class:`FolderLayout`; the registry names, detects and
indexes
layouts. ``test_a_new_layout_is_one_class`` is CONTRIBUTING.md's recipe "a new real-folder layout": a toy layout
(``frames.csv``) written in the test, registered, and a tiny folder read through it by ``RgbdFolder`` end to end."""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim_envs.errors import FormatError, SimEnvError, UnknownNameError
from sim_envs.folders.datasets import RgbdFolder
from sim_envs.folders.folder_layouts import (
    LAYOUTS,
    FolderIndex,
    FolderLayout,
    detect_layout,
    folder_layout,
    index_folder,
    register_layout,
    unregister_layout,
)
from slamcommon.errors import FormatError as SharedFormatError
from slamcommon.formats import quaternions_to_matrices


class CsvLayout(FolderLayout):
    """A toy layout: ``frames.csv`` with ``timestamp,rgb,depth,tx,ty,tz,qx,qy,qz,qw`` per frame (no header)."""

    name = "csv_frames"
    description = "CSV frames (frames.csv: timestamp,rgb,depth,tx,ty,tz,qx,qy,qz,qw)"

    def detect(self, folder: Path) -> bool:
        return (folder / "frames.csv").is_file()

    def index(self, folder: Path, max_difference: float) -> FolderIndex:
        with open(folder / "frames.csv", newline="") as handle:
            rows = list(csv.reader(handle))
        if any(len(row) != 10 for row in rows):
            raise SharedFormatError(f"{folder / 'frames.csv'}: expected 10 columns per row")
        values = np.array([[float(row[0]), *map(float, row[3:])] for row in rows])
        return FolderIndex(
            timestamps=values[:, 0],
            rgb_files=[folder / row[1] for row in rows],
            depth_files=[folder / row[2] for row in rows],
            poses=quaternions_to_matrices(values[:, 1:4], values[:, 4:8]),
            dropped=0,
            timing="frames.csv",
        )


@pytest.fixture
def csv_layout():
    register_layout(CsvLayout)
    try:
        yield folder_layout("csv_frames")
    finally:
        unregister_layout("csv_frames")


def write_csv_folder(folder: Path, n: int = 3) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """A tiny 16x12 folder of the toy layout: (poses, RGB images, raw uint16 depth images)."""
    folder.mkdir()
    rng = np.random.default_rng(0)
    rows, images, depths = [], [], []
    for k in range(n):
        rgb = rng.integers(0, 256, (12, 16, 3), dtype=np.uint8)
        depth = rng.integers(2500, 20000, (12, 16), dtype=np.uint16)
        cv2.imwrite(str(folder / f"c{k}.png"), rgb[..., ::-1])
        cv2.imwrite(str(folder / f"d{k}.png"), depth)
        angle = 0.1 * k
        rows.append([0.5 * k, f"c{k}.png", f"d{k}.png", 0.1 * k, 0.0, 1.0, 0.0, np.sin(angle / 2), 0.0,
                     np.cos(angle / 2)])  # fmt: skip
        images.append(rgb)
        depths.append(depth)
    with open(folder / "frames.csv", "w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    values = np.array([[r[3], r[4], r[5], r[6], r[7], r[8], r[9]] for r in rows], dtype=float)
    return quaternions_to_matrices(values[:, :3], values[:, 3:]), images, depths


def test_a_new_layout_is_one_class(tmp_path, csv_layout):
    poses, images, depths = write_csv_folder(tmp_path / "toy")
    assert LAYOUTS["csv_frames"] == CsvLayout.description
    assert detect_layout(tmp_path / "toy") == "csv_frames"
    folder = RgbdFolder(tmp_path / "toy", camera="icl")
    assert folder.layout == "csv_frames" and len(folder) == 3 and folder.size == (16, 12)
    np.testing.assert_array_equal(folder.timestamps, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(folder.poses, poses, atol=1e-12)
    for k in range(3):
        frame = folder.frame(k)
        np.testing.assert_array_equal(frame.rgb, images[k])
        np.testing.assert_array_equal(frame.depth, depths[k].astype(np.float32) / np.float32(5000.0))
        np.testing.assert_allclose(frame.T_world_cam, poses[k], atol=1e-12)
    assert folder.describe()["layout_description"] == CsvLayout.description


def test_a_layouts_shared_format_error_is_the_worlds(tmp_path, csv_layout):
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "frames.csv").write_text("0.0,c0.png\n")
    with pytest.raises(FormatError, match="expected 10 columns") as err:
        index_folder(tmp_path / "bad", "csv_frames")
    assert isinstance(err.value, SimEnvError)


def test_an_unregistered_layout_is_gone(tmp_path):
    write_csv_folder(tmp_path / "toy", n=1)
    assert "csv_frames" not in LAYOUTS
    with pytest.raises(SimEnvError, match="not an RGB-D folder of a known layout"):
        detect_layout(tmp_path / "toy")
    with pytest.raises(UnknownNameError, match="unknown layout 'csv_frames'; valid layouts: tum, icl"):
        index_folder(tmp_path / "toy", "csv_frames")


def test_the_registry_keeps_names_unique_and_detection_in_priority_order(tmp_path, csv_layout):
    with pytest.raises(SimEnvError, match="'csv_frames' is registered already"):
        register_layout(CsvLayout)
    assert list(LAYOUTS)[:5] == ["tum", "icl", "7scenes", "7scenes_split", "rgb_only"]
    folder = tmp_path / "both"  # a TUM rgb.txt beside frames.csv: the built-in layout (priority 30 < 100) wins
    write_csv_folder(folder, n=1)
    (folder / "rgb.txt").write_text("0.0 c0.png\n")
    assert detect_layout(folder) == "rgb_only"
