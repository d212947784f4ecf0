"""Table-1-style tables (CNN-SLAM Table 1): rows = sequences plus an "Avg." row; column blocks = one metric each
(ATE per method, percentage of correct depth per method).

Input is the long frame of :func:`eval.metrics.results.runs_frame` (``sequence, method, metric, value``). The runs of
one (sequence, method) (its seeds) are summarised by :func:`cell_statistics`: a cell of the table is their **median**
(the field's figure for non-deterministic SLAM: DPVO, DPV-SLAM report the median of 5 runs), its spread the
**min-max range** (with 3 runs the interquartile range says little more; both are in the statistics). The Avg. row
averages each seed's runs over the table's sequences and gives the median and range of those per-seed averages (the
mean of the cells where seeds do not line up), shown only for a column with a value on every sequence (an average
over a different subset of sequences would not compare). Missing cells are NaN in the numeric table and ``-`` when
written, like REMODE's ATE in the paper. Written as CSV (numeric medians, two header rows), Markdown and LaTeX
(``median [min, max]`` per cell where its runs differ), and the statistics in long form (:func:`statistics_frame`).
LaTeX (and the HTML report) set the best value of each row of a block in bold (:func:`best_cells`: lower or higher
is better by the metric, :func:`better_direction`), among the methods that receive no ground truth: a method fed
the true depth or poses (the oracle, LSD-BS, REMODE) is a reference, not a competitor, as VSLAM-LAB's tables bold the
best of the compared systems.

A run that covers less than its sequence (an external trajectory with frames missing:
:func:`eval.metrics.results.coverage`) shows it in its cell, ``0.012 (10/60 frames)`` (the cell's least covered
run), and its column gets no Avg.: an average over part of a sequence is no average over the sequences.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from eval.errors import EvalError
from eval.metrics.results import coverage

TABLE1_BLOCKS: tuple[tuple[str, str], ...] = (
    ("Abs. Trajectory Error [m]", "ate_rmse"),
    ("Perc. Correct Depth [%]", "depth_percent_correct"),
)
AVG_LABEL = "Avg."
MISSING = "-"
# which way is better, by metric name prefix (the first that matches): higher for shares and rates, lower for errors
HIGHER_IS_BETTER: tuple[str, ...] = ("depth_percent_correct", "depth_density", "depth_delta_1_25", "tracked_share",
                                     "map_accuracy_within", "map_completeness_within", "map_label_accuracy",
                                     "semantic_", "fps")  # fmt: skip
LOWER_IS_BETTER: tuple[str, ...] = ("ate_", "rot_deg_", "rpe_trans_", "rpe_rot_deg_", "scale_error", "depth_abs_rel",
                                    "depth_rmse", "map_accuracy_median", "map_completeness_median", "wall_s",
                                    "peak_rss_")  # fmt: skip
STATISTICS: tuple[str, ...] = ("median", "q1", "q3", "min", "max")
_QUANTILES = {"median": 0.5, "q1": 0.25, "q3": 0.75}


def cell_statistics(frame: pd.DataFrame) -> pd.DataFrame:
    """Per (sequence, method, metric): ``runs`` (finite values), ``median``, ``q1``, ``q3`` (quartiles, linear
    interpolation), ``min``, ``max`` over its runs; NaN values (a metric a run could not compute) are left out."""
    frame = frame.assign(value=pd.to_numeric(frame["value"], errors="coerce"))  # an empty frame's may be object
    values = frame.dropna(subset=["value"]).groupby(["sequence", "method", "metric"], sort=False)["value"]
    stats = values.agg(runs="count", median="median", min="min", max="max")
    stats["q1"] = values.quantile(0.25)
    stats["q3"] = values.quantile(0.75)
    return stats[["runs", *STATISTICS]]


Cells = dict[tuple[str, str], tuple[int, int]]


class Spread(NamedTuple):
    """What a table's cells are written with besides their medians: the ``lo`` and ``hi`` tables (each cell's
    min and max over its runs) and ``partial``, (sequence, method) -> (poses scored, frames) of the cells with a run
    covering less than its sequence (:func:`partial_cells`)."""

    lo: pd.DataFrame
    hi: pd.DataFrame
    partial: Cells


def partial_cells(frame: pd.DataFrame) -> Cells:
    """(sequence, method) -> ``(poses scored, frames)`` of the cell's least covered run, for every cell with a run
    that covers less than its sequence (:func:`eval.metrics.results.coverage` of the run's ``ate_pairs`` and
    ``frames`` rows; runs told apart by the ``run`` column). Empty without a ``run`` column."""
    if frame.empty or "run" not in frame.columns:
        return {}
    rows = frame[frame["metric"].isin(["ate_pairs", "frames"])]
    out: Cells = {}
    for (sequence, method, _), run in rows.groupby(["sequence", "method", "run"], sort=False):
        covered = coverage(dict(zip(run["metric"], pd.to_numeric(run["value"], errors="coerce"), strict=True)))
        old = out.get((sequence, method))
        if covered is not None and (old is None or covered[0] / covered[1] < old[0] / old[1]):
            out[(sequence, method)] = covered
    return out


def coverage_note(covered: tuple[int, int] | None) -> str:
    """`` (10/60 frames)`` for a partial cell, empty for a whole one."""
    return "" if covered is None else f" ({covered[0]}/{covered[1]} frames)"


def _avg_over_seeds(frame: pd.DataFrame, sequences: Sequence[str], method: str, metric: str) -> np.ndarray:
    """Each seed's mean over ``sequences`` (only seeds with a value on every sequence)."""
    if "seed" not in frame.columns:
        return np.zeros(0)
    sub = frame[(frame["method"] == method) & (frame["metric"] == metric) & frame["sequence"].isin(sequences)]
    wide = sub.pivot_table(index="seed", columns="sequence", values="value", aggfunc="mean")
    if wide.shape[1] != len(set(sequences)):
        return np.zeros(0)
    return wide.dropna().mean(axis=1).to_numpy()


def table1(
    frame: pd.DataFrame,
    *,
    methods: Sequence[str] | None = None,
    sequences: Sequence[str] | None = None,
    blocks: Sequence[tuple[str, str]] = TABLE1_BLOCKS,
    drop_empty: bool = False,
    stat: str = "median",
) -> pd.DataFrame:
    """Numeric Table 1: index = sequences + ``Avg.``; columns = MultiIndex (block title, method); NaN = missing.

    Each cell is the statistic ``stat`` (one of :data:`STATISTICS`) of the cell's runs (:func:`cell_statistics`);
    the Avg. row is that statistic of the per-seed averages over the sequences (see the module docstring), NaN for
    a method with a missing cell or a run covering less than its sequence (:func:`partial_cells`).
    ``methods`` / ``sequences`` fix the order (default: order of first
    appearance). ``drop_empty`` leaves out a method's column in a block where it has no value at all (the paper
    leaves REMODE out of the ATE block).
    """
    missing = {"sequence", "method", "metric", "value"} - set(frame.columns)
    if missing:
        raise EvalError(f"the results frame lacks the column(s) {sorted(missing)}; see eval.metrics.results.runs_frame")
    methods = list(methods) if methods is not None else list(dict.fromkeys(frame["method"]))
    sequences = list(sequences) if sequences is not None else list(dict.fromkeys(frame["sequence"]))
    if stat not in STATISTICS:
        raise EvalError(f"unknown statistic {stat!r}; valid: {', '.join(STATISTICS)}")
    cells = cell_statistics(frame)[stat] if len(frame) else pd.Series(dtype=float)
    partial = partial_cells(frame)
    columns = []
    data = []
    for title, metric in blocks:
        for method in methods:
            values = [cells.get((seq, method, metric), np.nan) for seq in sequences]
            if drop_empty and np.all(np.isnan(values)):
                continue
            columns.append((title, method))
            avg = np.nan
            if not np.any(np.isnan(values)) and not any((seq, method) in partial for seq in sequences):
                per_seed = _avg_over_seeds(frame, sequences, method, metric)
                if not per_seed.size:  # no seeds with every sequence: the mean of the cells
                    avg = float(np.mean(values))
                else:
                    avg = float(np.quantile(per_seed, _QUANTILES[stat], method="linear") if stat in _QUANTILES
                                else (np.min if stat == "min" else np.max)(per_seed))  # fmt: skip
            data.append([*values, avg])
    table = pd.DataFrame(
        np.array(data, dtype=np.float64).T if data else np.zeros((len(sequences) + 1, 0)),
        index=pd.Index([*sequences, AVG_LABEL], name="sequence"),
        columns=pd.MultiIndex.from_tuples(columns, names=["metric", "method"]),
    )
    return table


def better_direction(metric: str) -> str | None:
    """``"higher"`` or ``"lower"``: which values of ``metric`` are better (:data:`HIGHER_IS_BETTER`,
    :data:`LOWER_IS_BETTER`); None when neither is (a scale, a count, a length)."""
    if metric.startswith(HIGHER_IS_BETTER):
        return "higher"
    if metric.startswith(LOWER_IS_BETTER):
        return "lower"
    return None


def best_cells(table: pd.DataFrame, blocks: Sequence[tuple[str, str]], digits: int = 3,
               exclude: Sequence[str] = ()) -> set[tuple[object, tuple[str, str]]]:
    """(row, (block title, method)) of the best value of each row in each block of ``table`` (a :func:`table1`
    table; ``blocks``: its (title, metric) pairs) whose metric has a direction (:func:`better_direction`), among the
    methods not in ``exclude``; values equal at ``digits`` decimals tie (all bold)."""
    out: set[tuple[object, tuple[str, str]]] = set()
    titles = set(table.columns.get_level_values(0)) if len(table.columns) else set()
    for title, metric in blocks:
        direction = better_direction(metric)
        if direction is None or title not in titles:
            continue
        block = table[title]
        block = block[[m for m in block.columns if m not in set(exclude)]].round(digits)
        for row, values in block.iterrows():
            finite = values.dropna()
            if finite.empty:
                continue
            best = finite.max() if direction == "higher" else finite.min()
            out.update((row, (title, method)) for method, v in finite.items() if v == best)
    return out


def cell_text(value: float, row: object, method: object, spread: Spread | None, digits: int,
              latex: bool = False, bold: bool = False) -> str:
    """One cell as written: ``-`` when missing, else the median with ``digits`` decimals (LaTeX and ``bold``: in
    ``\\textbf``), its runs' range ``[min, max]`` where they differ (LaTeX: in small type) and its coverage where a
    run is partial (``spread``: the cell's :class:`Spread`; the range looked up by (row, column) of the table the
    value comes from)."""
    if pd.isna(value):
        return MISSING
    text = f"{value:.{digits}f}"
    if bold and latex:
        text = f"\\textbf{{{text}}}"
    if spread is None:
        return text
    lo, hi = (t.at[row, method] for t in (spread.lo, spread.hi))
    if not (pd.isna(lo) or pd.isna(hi) or lo == hi):
        rng = f"[{lo:.{digits}f}, {hi:.{digits}f}]"
        text += " " + (f"{{\\scriptsize {rng}}}" if latex else rng)
    name = method[-1] if isinstance(method, tuple) else method
    return text + coverage_note(spread.partial.get((str(row), str(name))))


def format_table(table: pd.DataFrame, digits: int = 3, spread: Spread | None = None,
                 latex: bool = False, bold: set | frozenset = frozenset()) -> pd.DataFrame:
    """The table as strings with ``digits`` decimals and ``-`` for missing cells; with ``spread``
    (:func:`spread_of`), ``median [min, max]`` where the runs differ (LaTeX: the range in small type) and a partial
    run's coverage, ``(10/60 frames)``; a bare number is a cell whose runs all agree (or a single run). LaTeX:
    the cells of ``bold`` ((row, column) pairs, :func:`best_cells`) in bold."""
    out = table.map(lambda v: MISSING if pd.isna(v) else f"{v:.{digits}f}")
    if spread is None and not bold:
        return out
    for col in table.columns:
        for row in table.index:
            out.at[row, col] = cell_text(table.at[row, col], row, col, spread, digits, latex, (row, col) in bold)
    return out


def spread_of(frame: pd.DataFrame, **kwargs) -> Spread:
    """The ``min`` and ``max`` tables matching ``table1(frame, **kwargs)`` and the frame's partial cells, for
    :func:`format_table`'s ``spread``."""
    return Spread(table1(frame, stat="min", **kwargs), table1(frame, stat="max", **kwargs), partial_cells(frame))


def statistics_frame(frame: pd.DataFrame, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """The cell statistics in long form (columns ``sequence, method, metric, runs, median, q1, q3, min, max``),
    optionally only for ``metrics``."""
    stats = cell_statistics(frame).reset_index()
    return stats[stats["metric"].isin(metrics)] if metrics is not None else stats


def table_to_csv(table: pd.DataFrame) -> str:
    """Numeric CSV: two header rows (block, method), empty cells for missing values."""
    return table.to_csv(float_format="%.6g")


def table_to_markdown(table: pd.DataFrame, digits: int = 3, spread: Spread | None = None) -> str:
    """A GitHub Markdown table; column headers ``block: method``; missing cells ``-``; ``spread``: see
    :func:`format_table`."""
    text = format_table(table, digits, spread)
    header = [table.index.name or ""] + [
        f"{block}: {method}" if isinstance((block, method), tuple) else str(block) for block, method in text.columns
    ]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" + "---:|" * len(text.columns)]
    for label, row in text.iterrows():
        lines.append("| " + " | ".join([str(label), *row.tolist()]) + " |")
    return "\n".join(lines) + "\n"


def table_to_latex(table: pd.DataFrame, digits: int = 3, caption: str | None = None,
                   spread: Spread | None = None, blocks: Sequence[tuple[str, str]] = (),
                   exclude: Sequence[str] = ()) -> str:
    """LaTeX (booktabs) with a multicolumn header per block; missing cells ``-``; ``spread``: see
    :func:`format_table`; ``blocks`` (the table's (title, metric) pairs): the best value of each row of each block
    in bold, among the methods not in ``exclude`` (:func:`best_cells`)."""
    bold = best_cells(table, blocks, digits, exclude) if blocks else set()
    if spread is not None or bold:  # cells carry LaTeX markup, so the labels are escaped here instead of by pandas
        cells = format_table(table, digits, spread, latex=True, bold=bold)
        cells = cells.rename(columns=_latex_escape, index=_latex_escape)
        cells.index.name = _latex_escape(table.index.name or "")
        return cells.to_latex(multicolumn=True, multicolumn_format="c", caption=caption, escape=False,
                              column_format="l" + "r" * len(cells.columns))  # fmt: skip
    return table.to_latex(
        na_rep=MISSING,
        float_format=lambda v: f"{v:.{digits}f}",
        multicolumn=True,
        multicolumn_format="c",
        caption=caption,
    )


def _latex_escape(text: object) -> str:
    return "".join("\\" + c if c in "&%$#_{}" else c for c in str(text))


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
