import json

import cv2
import numpy as np
import pytest
from matplotlib.figure import Figure

from cnnslam.cli import main
from sim_envs.errors import SimEnvError
from sim_envs.frames import NO_LABEL, Frame, SemanticClass
from sim_envs.tools.contact_sheet import LABEL_PALETTE, SheetRow, colorize_labels, draw_contact_sheet


def _frame(i: int) -> Frame:
    labels = np.full((6, 8), SemanticClass.FLOOR, np.uint8)
    labels[:2] = SemanticClass.VERTICAL_STRUCTURE
    labels[0, 0] = NO_LABEL
    depth = np.linspace(0.5, 4.0, 48, dtype=np.float32).reshape(6, 8)
    depth[0, 0] = 0.0
    return Frame(i, i / 30, np.full((6, 8, 3), 40 * i, np.uint8), depth, np.eye(4), labels)


def test_colorize_labels_uses_the_fixed_palette():
    labels = np.array([[0, 1, 2], [3, NO_LABEL, 0]], np.uint8)
    rgb = colorize_labels(labels)
    assert rgb.shape == (2, 3, 3) and rgb.dtype == np.uint8
    for (r, c), cls in np.ndenumerate(labels):
        expected = (0, 0, 0) if cls == NO_LABEL else LABEL_PALETTE[int(cls)]
        assert tuple(rgb[r, c]) == expected
    assert len({tuple(v) for v in LABEL_PALETTE.values()}) == 4  # four distinct colours


def test_draw_contact_sheet_lays_out_three_rows_per_sequence():
    fig = Figure(figsize=(6, 8))
    rows = [SheetRow("a", [_frame(0), _frame(1), _frame(2)]), SheetRow("b", [_frame(3), _frame(4)])]
    draw_contact_sheet(fig, rows)
    image_axes = [ax for ax in fig.axes if ax.get_images()]
    assert len(image_axes) == 3 * 3 + 3 * 2  # RGB, depth, labels per frame; the missing column left empty
    colorbar = fig.axes[-1]
    assert "depth [m]" in colorbar.get_ylabel()
    legend_texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("floor" in t for t in legend_texts) and any("255" in t for t in legend_texts)
    with pytest.raises(SimEnvError, match="at least one"):
        draw_contact_sheet(Figure(), [SheetRow("a", [])])


def test_command_writes_a_png_of_rendered_rooms(tmp_path):
    out = tmp_path / "sheets" / "sheet.png"
    status = main(["contact-sheet", "--out", str(out), "--sequences", "rot_yaw_30", "--fractions", "0", "1"])
    assert status == 0 and out.exists()
    png = cv2.imread(str(out))
    assert png is not None and png.shape[0] > 300 and png.shape[1] > 300
    assert png.std() > 20.0  # images, not an empty canvas
    manifest = json.loads((out.parent / "sheet.provenance.json").read_text())  # what made it
    assert manifest["outputs"] == ["sheet.png"] and manifest["code"]["modules"] == ["sim_envs.tools.contact_sheet"]
