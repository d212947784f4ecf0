"""Table-1-style tables (CNN-SLAM Table 1): rows = sequences plus an "Avg." row; column blocks = one metric each
(ATE per method, percentage of correct depth per method).

Input is the long frame of :func:`eval.results.runs_frame` (``sequence, method, metric, value``). Several runs of
one (sequence, method) (seeds) are averaged. The Avg. row is the mean over the table's sequences and is shown only
for a column with a value on every sequence (an average over a different subset of sequences would not compare);
missing cells are NaN in the numeric table and ``-`` when written, like REMODE's ATE in the paper.
Written as CSV (numeric, two header rows), Markdown and LaTeX (``DataFrame.to_latex``, booktabs rules).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from eval.errors import EvalError

TABLE1_BLOCKS: tuple[tuple[str, str], ...] = (
    ("Abs. Trajectory Error [m]", "ate_rmse"),
    ("Perc. Correct Depth [%]", "depth_percent_correct"),
)
AVG_LABEL = "Avg."
MISSING = "-"


def table1(
    frame: pd.DataFrame,
    *,
    methods: Sequence[str] | None = None,
    sequences: Sequence[str] | None = None,
    blocks: Sequence[tuple[str, str]] = TABLE1_BLOCKS,
    drop_empty: bool = False,
) -> pd.DataFrame:
    """Numeric Table 1: index = sequences + ``Avg.``; columns = MultiIndex (block title, method); NaN = missing.

    ``methods`` / ``sequences`` fix the order (default: order of first appearance). ``drop_empty`` leaves out a
    method's column in a block where it has no value at all (the paper leaves REMODE out of the ATE block).
    """
    missing = {"sequence", "method", "metric", "value"} - set(frame.columns)
    if missing:
        raise EvalError(f"the results frame lacks the column(s) {sorted(missing)}; see eval.results.runs_frame")
    methods = list(methods) if methods is not None else list(dict.fromkeys(frame["method"]))
    sequences = list(sequences) if sequences is not None else list(dict.fromkeys(frame["sequence"]))
    mean = frame.groupby(["sequence", "method", "metric"], sort=False)["value"].mean()
    columns = []
    data = []
    for title, metric in blocks:
        for method in methods:
            values = [mean.get((seq, method, metric), np.nan) for seq in sequences]
            if drop_empty and np.all(np.isnan(values)):
                continue
            columns.append((title, method))
            data.append(values + [float(np.mean(values)) if not np.any(np.isnan(values)) else np.nan])
    table = pd.DataFrame(
        np.array(data, dtype=np.float64).T if data else np.zeros((len(sequences) + 1, 0)),
        index=pd.Index([*sequences, AVG_LABEL], name="sequence"),
        columns=pd.MultiIndex.from_tuples(columns, names=["metric", "method"]),
    )
    return table


def format_table(table: pd.DataFrame, digits: int = 3) -> pd.DataFrame:
    """The table as strings with ``digits`` decimals and ``-`` for missing cells."""
    return table.map(lambda v: MISSING if pd.isna(v) else f"{v:.{digits}f}")


def table_to_csv(table: pd.DataFrame) -> str:
    """Numeric CSV: two header rows (block, method), empty cells for missing values."""
    return table.to_csv(float_format="%.6g")


def table_to_markdown(table: pd.DataFrame, digits: int = 3) -> str:
    """A GitHub Markdown table; column headers ``block: method``; missing cells ``-``."""
    text = format_table(table, digits)
    header = [table.index.name or ""] + [
        f"{block}: {method}" if isinstance((block, method), tuple) else str(block) for block, method in text.columns
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" + "---:|" * len(text.columns)]
    for label, row in text.iterrows():
        lines.append("| " + " | ".join([str(label), *row.tolist()]) + " |")
    return "\n".join(lines) + "\n"


def table_to_latex(table: pd.DataFrame, digits: int = 3, caption: str | None = None) -> str:
    """LaTeX (booktabs) with a multicolumn header per block; missing cells ``-``."""
    return table.to_latex(
        na_rep=MISSING,
        float_format=lambda v: f"{v:.{digits}f}",
        multicolumn=True,
        multicolumn_format="c",
        caption=caption,
    )


def write_table(table: pd.DataFrame, stem: str | Path, digits: int = 3, caption: str | None = None) -> list[Path]:
    """Write ``stem``.csv, ``stem``.md and ``stem``.tex; returns the three paths."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    out = []
    for suffix, text in (
        (".csv", table_to_csv(table)),
        (".md", table_to_markdown(table, digits)),
        (".tex", table_to_latex(table, digits, caption)),
    ):
        path = stem.with_suffix(suffix)
        path.write_text(text)
        out.append(path)
    return out
