"""The paper's own Table 1 (CNN-SLAM, Tateno et al., CVPR 2017, Sec. 4.1), as data, for quoting beside ours.

ATE in metres (SE(3)-aligned RMSE, [26] = the TUM benchmark's methodology); percentage of correct depth in 0..100.
REMODE has no ATE (it runs on LSD-BS poses). The paper prints REMODE's ICL/office2 value as ``16.7081``; it is kept
as printed (the printed average 7.649 is consistent with 16.708).
TUM/seq1 = fr3/long_office_household, TUM/seq2 = fr3/nostructure_texture_near_withloop,
TUM/seq3 = fr3/structure_texture_far.
"""

from __future__ import annotations

import math

import pandas as pd

from eval.metrics import catalogue

PAPER_SEQUENCES: tuple[str, ...] = (
    "ICL/office0",
    "ICL/office1",
    "ICL/office2",
    "ICL/living0",
    "ICL/living1",
    "ICL/living2",
    "TUM/seq1",
    "TUM/seq2",
    "TUM/seq3",
)
TUM_SEQUENCE_NAMES: dict[str, str] = {
    "TUM/seq1": "fr3/long_office_household",
    "TUM/seq2": "fr3/nostructure_texture_near_withloop",
    "TUM/seq3": "fr3/structure_texture_far",
}
PAPER_METHODS: tuple[str, ...] = ("CNN-SLAM", "LSD-BS", "LSD", "ORB", "Laina", "REMODE")

_NAN = math.nan
# method -> ATE per sequence (order of PAPER_SEQUENCES), metres
PAPER_ATE: dict[str, tuple[float, ...]] = {
    "CNN-SLAM": (0.266, 0.157, 0.213, 0.196, 0.059, 0.323, 0.542, 0.243, 0.214),
    "LSD-BS": (0.587, 0.790, 0.172, 0.894, 0.540, 0.211, 1.717, 0.106, 0.037),
    "LSD": (0.528, 0.768, 0.794, 0.516, 0.480, 0.667, 1.826, 0.436, 0.937),
    "ORB": (0.430, 0.780, 0.860, 0.493, 0.129, 0.663, 1.206, 0.495, 0.733),
    "Laina": (0.337, 0.218, 0.509, 0.230, 0.060, 0.380, 0.809, 1.337, 0.724),
    "REMODE": (_NAN,) * 9,
}
# method -> percentage of correct depth per sequence, 0..100
PAPER_CORRECT_DEPTH: dict[str, tuple[float, ...]] = {
    "CNN-SLAM": (19.410, 29.150, 37.226, 12.840, 13.038, 26.560, 12.477, 24.077, 27.396),
    "LSD-BS": (0.603, 4.759, 1.435, 1.443, 3.030, 1.807, 3.797, 3.966, 6.449),
    "LSD": (0.335, 0.038, 0.078, 0.360, 0.057, 0.167, 0.086, 0.882, 0.035),
    "ORB": (0.018, 0.023, 0.040, 0.027, 0.021, 0.014, 0.031, 0.059, 0.027),
    "Laina": (17.194, 20.838, 30.639, 15.008, 11.449, 33.010, 12.982, 15.412, 9.450),
    "REMODE": (4.479, 3.132, 16.7081, 4.479, 2.427, 8.681, 9.548, 12.651, 6.739),
}
# the printed "Avg." row
PAPER_AVG_ATE: dict[str, float] = {
    "CNN-SLAM": 0.246,
    "LSD-BS": 0.562,
    "LSD": 0.772,
    "ORB": 0.643,
    "Laina": 0.512,
    "REMODE": _NAN,
}
PAPER_AVG_CORRECT_DEPTH: dict[str, float] = {
    "CNN-SLAM": 22.464,
    "LSD-BS": 3.032,
    "LSD": 0.226,
    "ORB": 0.029,
    "Laina": 18.452,
    "REMODE": 7.649,
}


# metric (the catalogue's Table-1 blocks: ATE, correct depth) -> (the paper's per-sequence figures, its Avg. row)
PAPER_TABLES: dict[str, tuple[dict[str, tuple[float, ...]], dict[str, float]]] = dict(
    zip((key for _, key in catalogue.blocks(catalogue.TABLE1)),
        ((PAPER_ATE, PAPER_AVG_ATE), (PAPER_CORRECT_DEPTH, PAPER_AVG_CORRECT_DEPTH)), strict=True))  # fmt: skip


def paper_table1_frame(method_suffix: str = "") -> pd.DataFrame:
    """The paper's per-sequence numbers in long form (``sequence, method, metric, value, run``), metrics ATE RMSE
    and correct depth (:data:`PAPER_TABLES`); missing cells are left out. ``method_suffix`` (e.g. " (paper)")
    keeps the paper's methods apart from ours in a combined table."""
    rows = []
    for metric, (table, _) in PAPER_TABLES.items():
        for method, values in table.items():
            for sequence, value in zip(PAPER_SEQUENCES, values, strict=True):
                if not math.isnan(value):
                    rows.append(
                        {
                            "sequence": sequence,
                            "method": method + method_suffix,
                            "metric": metric,
                            "value": value,
                            "run": "paper",
                        }
                    )
    return pd.DataFrame(rows)


# our Table-1 analogues -> the paper's sequences they stand for
PAPER_NAMES: dict[str, str] = dict(
    zip(("office0", "office1", "office2", "living0", "living1", "living2", "tum_long_office",
         "tum_nostructure_near", "tum_structure_far"), PAPER_SEQUENCES, strict=True)
)  # fmt: skip


def paper_name(label: object, default: str) -> str:
    """The paper's sequence a Table-1 analogue stands for, whatever camera it is seen through and however its room is
    lit (``office0@kinect`` and ``office0+lit@kinect`` are ICL/office0); ``default`` for a sequence of ours only."""
    return PAPER_NAMES.get(str(label).split("@")[0].split("+")[0], default)


def paper_value(label: object, method: str, metric: str, all_sequences: bool = False) -> float:
    """The paper's Table-1 value beside ours: ``metric`` (one of :data:`PAPER_TABLES`: ATE RMSE or correct depth)
    of ``method`` on the paper's sequence our row ``label`` stands for (:func:`paper_name`), or its printed Avg. for
    the row ``Avg.`` when ``all_sequences`` (ours averages all nine of its sequences: an average over fewer is another
    figure); NaN where the paper has none."""
    if metric not in PAPER_TABLES:
        return math.nan
    per_sequence, average = PAPER_TABLES[metric]
    if str(label) == "Avg.":
        if not all_sequences:
            return math.nan
        return average.get(method, math.nan)
    name = paper_name(label, "")
    values = per_sequence.get(method)
    if not name or values is None:
        return math.nan
    return float(values[PAPER_SEQUENCES.index(name)])


def covers_paper_sequences(labels: object) -> bool:
    """Whether the rows ``labels`` hold an analogue of every one of the paper's nine sequences."""
    return {paper_name(label, "") for label in labels} >= set(PAPER_SEQUENCES)  # type: ignore[union-attr]

