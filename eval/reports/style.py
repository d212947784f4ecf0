"""One look per method in every figure and page of the judge: a colour and a marker per method name, defined here
once (:data:`METHOD_STYLES`), so that CNN-SLAM is the same red in a suite's runs figure, its per-sequence
trajectories, the relative-error boxplots, the sweep, the transfer and length charts and the HTML report.

A method that is not in the table (a user's ``--method-file`` or ``--external`` method) gets a colour and a marker
from its name alone (:func:`method_style`: a hash of the name picks them from palettes the table does not use), so
it too keeps its look from figure to figure and from suite to suite, whatever other methods are shown beside it,
never by its position in a list. The colours of the table are Okabe and Ito's colour-blind-safe set first, then the
Tableau ones; the markers tell methods apart where colours are close or printed in grey.

Also here: the figure formats a suite's report can write (:data:`FIGURE_FORMATS`) and the ground truth's look.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass


@dataclass(frozen=True)
class MethodStyle:
    """How a method is drawn: ``color`` (``#rrggbb``), ``marker`` (a marker code: ``o`` circle, ``s`` square, ``^``
    triangle, ``D`` diamond, ...), ``linestyle`` (``-`` solid, ``--`` dashed, ...)."""

    color: str
    marker: str
    linestyle: str = "-"


# The methods of eval/methods.toml (and the ones the suites name), one look each; close relatives share a hue family
# and differ in marker (the ablation's variants, the dev-depth references).
METHOD_STYLES: dict[str, MethodStyle] = {
    "CNN-SLAM": MethodStyle("#d55e00", "o"),  # vermillion
    "LSD-BS": MethodStyle("#0072b2", "s"),  # blue
    "LSD": MethodStyle("#56b4e9", "^"),  # sky blue
    "ORB": MethodStyle("#009e73", "D"),  # bluish green
    "ORB-SLAM3": MethodStyle("#2ca02c", "P"),  # green
    "Laina": MethodStyle("#cc79a7", "v"),  # reddish purple
    "REMODE": MethodStyle("#e69f00", "X"),  # orange
    "oracle": MethodStyle("#8f8f8f", "*", ":"),  # grey, dotted: the ground truth through the pipeline
    "constant-pose": MethodStyle("#b5b5b5", "x", "-."),  # light grey
    "raw-CNN": MethodStyle("#f0e442", "<"),  # yellow
    "focal-adjusted": MethodStyle("#bcbd22", ">"),  # olive
    "adjusted+refined": MethodStyle("#8c564b", "h"),  # brown
    "dev-depth-5": MethodStyle("#9467bd", "1"),  # purple family: ground-truth depth degraded by 5/10/20 %
    "dev-depth-10": MethodStyle("#7b4fa6", "2"),
    "dev-depth-20": MethodStyle("#5e3c80", "3"),
    "COLMAP": MethodStyle("#17becf", "d"),  # cyan
    "Open3D-odometry": MethodStyle("#1f3a93", "p"),  # navy
}
GROUND_TRUTH_STYLE = MethodStyle("#404040", "o", "--")  # the reference every figure draws its estimates against
# For methods not in the table: colours and markers none of the table's uses, picked by a hash of the name.
FALLBACK_COLORS: tuple[str, ...] = ("#1b9e77", "#a6761d", "#666666", "#e7298a", "#66a61e", "#7570b3", "#b15928",
                                    "#6a3d9a", "#ff7f00", "#33a02c", "#fb9a99", "#a6cee3")  # fmt: skip
FALLBACK_MARKERS: tuple[str, ...] = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h", "p", "*")
FIGURE_FORMATS: tuple[str, ...] = ("png", "pdf", "svg")  # what --figure-format takes
DEFAULT_FIGURE_FORMAT = "png"


def method_style(name: str) -> MethodStyle:
    """The look of method ``name``: its entry of :data:`METHOD_STYLES`, else a colour and a marker picked from the
    fallback palettes by the SHA-256 of the name (the same name, the same look, in every figure and run)."""
    if name in METHOD_STYLES:
        return METHOD_STYLES[name]
    digest = int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "big")
    return MethodStyle(FALLBACK_COLORS[digest % len(FALLBACK_COLORS)],
                       FALLBACK_MARKERS[(digest // len(FALLBACK_COLORS)) % len(FALLBACK_MARKERS)])  # fmt: skip
