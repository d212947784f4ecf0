"""A contact sheet of named sequences: RGB, depth (colour-mapped, colour bar in metres) and semantic labels (the
paper's 4 classes, fixed palette with legend) for a few frames of each, so a person can see the scenes.

The drawing function draws into a figure the caller passes; :func:`make_contact_sheet` renders the frames and writes
the PNG. matplotlib is used through :class:`matplotlib.figure.Figure` only (no pyplot, no GUI backend).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from sim_envs.errors import SimEnvError
from sim_envs.frames import NO_DEPTH, NO_LABEL, Frame, SemanticClass

# RGB (uint8) of each semantic class; pixels with no surface are black
LABEL_PALETTE: dict[int, tuple[int, int, int]] = {
    SemanticClass.FLOOR: (214, 162, 60),
    SemanticClass.VERTICAL_STRUCTURE: (90, 140, 220),
    SemanticClass.LARGE_STRUCTURE: (60, 180, 90),
    SemanticClass.SMALL_STRUCTURE: (220, 70, 90),
}
LABEL_NAMES: dict[int, str] = {
    SemanticClass.FLOOR: "floor",
    SemanticClass.VERTICAL_STRUCTURE: "vertical structure",
    SemanticClass.LARGE_STRUCTURE: "large structure / furniture",
    SemanticClass.SMALL_STRUCTURE: "small structure / objects",
}
DEPTH_CMAP = "turbo"
DEFAULT_SEQUENCES: tuple[str, ...] = ("office0", "living0", "rot_rpy_30")
DEFAULT_FRACTIONS: tuple[float, ...] = (0.0, 0.3, 0.6, 0.9)  # where in each sequence the frames are taken


@dataclass(frozen=True)
class SheetRow:
    """The frames of one sequence on the sheet: ``name`` and its rendered frames (with depth and labels)."""

    name: str
    frames: list[Frame]


def colorize_labels(labels: np.ndarray) -> np.ndarray:
    """(H, W) uint8 semantic classes -> (H, W, 3) uint8 colours of :data:`LABEL_PALETTE` (no surface: black)."""
    lut = np.zeros((256, 3), dtype=np.uint8)
    for cls, rgb in LABEL_PALETTE.items():
        lut[int(cls)] = rgb
    lut[NO_LABEL] = 0
    return lut[np.asarray(labels, dtype=np.uint8)]


def draw_contact_sheet(fig: Figure, rows: Sequence[SheetRow], max_depth: float | None = None) -> None:
    """Draw ``rows`` into ``fig``: per sequence three image rows (RGB, depth, labels), one column per frame, one
    shared depth colour bar (metres, ``0..max_depth``; default the largest depth shown) and the label legend."""
    if not rows or any(not r.frames for r in rows):
        raise SimEnvError("a contact sheet needs at least one sequence with at least one frame")
    n_cols = max(len(r.frames) for r in rows)
    if max_depth is None:
        max_depth = float(max(f.depth.max() for r in rows for f in r.frames))
    norm = Normalize(0.0, max_depth)
    cmap = colormaps[DEPTH_CMAP].with_extremes(bad="black")
    axes = fig.subplots(3 * len(rows), n_cols, squeeze=False)
    image = None
    for r, row in enumerate(rows):
        for c in range(n_cols):
            ax_rgb, ax_depth, ax_labels = axes[3 * r, c], axes[3 * r + 1, c], axes[3 * r + 2, c]
            for ax in (ax_rgb, ax_depth, ax_labels):
                ax.set_xticks([])
                ax.set_yticks([])
            if c >= len(row.frames):
                for ax in (ax_rgb, ax_depth, ax_labels):
                    ax.set_axis_off()
                continue
            f = row.frames[c]
            ax_rgb.imshow(f.rgb)
            ax_rgb.set_title(f"{row.name}  frame {f.index}  t={f.timestamp:.2f} s", fontsize=7)
            depth = np.ma.masked_equal(f.depth, NO_DEPTH)
            image = ax_depth.imshow(depth, cmap=cmap, norm=norm)
            if f.labels is not None:
                ax_labels.imshow(colorize_labels(f.labels))
            if c == 0:
                ax_rgb.set_ylabel(f"{row.name}\nRGB", fontsize=8)
                ax_depth.set_ylabel("depth", fontsize=8)
                ax_labels.set_ylabel("labels", fontsize=8)
    bottom = 0.9 / fig.get_figheight()  # room for the legend, inches -> figure fraction
    fig.subplots_adjust(left=0.08, right=0.88, top=0.97, bottom=bottom, wspace=0.04, hspace=0.18)
    cax = fig.add_axes((0.9, 0.35, 0.02, 0.5))
    bar = fig.colorbar(image, cax=cax)
    bar.set_label("depth [m] (black: no surface)", fontsize=8)
    handles = [Patch(color=np.array(LABEL_PALETTE[c]) / 255, label=f"{int(c)} {LABEL_NAMES[c]}") for c in LABEL_PALETTE]
    handles.append(Patch(color="black", label=f"{NO_LABEL} no surface"))
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False)


def sheet_rows(
    sequences: Sequence[str] = DEFAULT_SEQUENCES,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    renderer: str = "mujoco",
) -> list[SheetRow]:
    """Render the frames of each named sequence at ``fractions`` (0..1) of its length."""
    from sim_envs.sequences import get_sequence
    from sim_envs.sources.simsource import SimulatedSequence

    if any(not 0.0 <= f <= 1.0 for f in fractions):
        raise SimEnvError(f"fractions must lie in [0, 1], got {list(fractions)}")
    rows = []
    for name in sequences:
        with SimulatedSequence(get_sequence(name), renderer=renderer) as source:
            idx = [round(f * (len(source) - 1)) for f in fractions]
            rows.append(SheetRow(name, [source.frame(i) for i in idx]))
    return rows


def make_contact_sheet(
    out: str | Path,
    sequences: Sequence[str] = DEFAULT_SEQUENCES,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    renderer: str = "mujoco",
    dpi: int = 110,
) -> Path:
    """Render the sheet of ``sequences`` and write it as a PNG to ``out`` (parent folders created); returns the path."""
    rows = sheet_rows(sequences, fractions, renderer)
    n_cols = max(len(r.frames) for r in rows)
    fig = Figure(figsize=(2.3 * n_cols + 1.2, 1.85 * 3 * len(rows) + 0.6))
    draw_contact_sheet(fig, rows)
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path
