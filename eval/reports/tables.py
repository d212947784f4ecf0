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

Failures (:func:`eval.metrics.results.failure_of`: a run that never initialised or tracked less than
:data:`eval.metrics.results.MIN_TRACKED_SHARE` of its frames) are no figures (the rule every report states:
:data:`eval.metrics.results.FAILURE_RULE`): a cell is a failure when at least half of its runs fail, written
``X (22 %)`` (the mark and the median tracked share of its failed runs) in every table (Markdown, CSV, LaTeX, HTML)
and NaN in the numeric table; otherwise its figure is the median over the runs that did not fail, with
``1/3 failed`` beside it. A cell whose runs tracked less than all their frames shows its share, ``0.117 (99 %)``.
An Avg. over a column with failed sequences averages the other sequences and says how many it covers,
``0.412 (7/9)`` (:func:`cell_failures`, :class:`CellFailure`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.metrics.catalogue import ATE_PAIRS, TRACKED_SHARE
from eval.metrics.results import FAILURE_MARK, coverage, failure_of, failure_text, share_text

TABLE1_BLOCKS: tuple[tuple[str, str], ...] = catalogue.blocks(catalogue.TABLE1)  # (title, metric): ATE, correct depth
AVG_LABEL = "Avg."
MISSING = "-"
_SHARE, _PAIRS = TRACKED_SHARE.key, ATE_PAIRS.key  # what a run's failure is judged by (failure_of)
FAILURE_EVIDENCE: tuple[str, ...] = (_SHARE, _PAIRS)  # the rows of a long frame that cell_failures reads
STATISTICS: tuple[str, ...] = ("median", "q1", "q3", "min", "max")
_QUANTILES = {"median": 0.5, "q1": 0.25, "q3": 0.75}


class CellFailure(NamedTuple):
    """The failures among one (sequence, method) cell's runs (:func:`eval.metrics.results.failure_of`): ``runs``
    (runs with a tracked share or a pose count), ``failed`` (of them, failures), ``share`` (the median tracked share
    of the runs the cell's figure stands for: its failed runs when the cell is a failure, else its other runs)."""

    runs: int
    failed: int
    share: float

    @property
    def is_failure(self) -> bool:
        """The cell is a failure: at least half of its runs failed."""
        return self.runs > 0 and 2 * self.failed >= self.runs

    def text(self) -> str:
        """A failed cell as written, ``X (22 %)``."""
        return failure_text(self.share)

    def note(self) -> str:
        """What a cell that is not a failure carries beside its figure: its tracked share when below 100 % and how
        many of its runs failed, `` (95 %, 1/3 failed)``; empty for a whole cell."""
        parts = []
        if math.isfinite(self.share) and self.share < 1.0:
            parts.append(share_text(self.share))
        if self.failed:
            parts.append(f"{self.failed}/{self.runs} failed")
        return f" ({', '.join(parts)})" if parts else ""


Failures = dict[tuple[str, str], CellFailure]


def _run_metrics(frame: pd.DataFrame) -> pd.DataFrame:
    """One row per run (``sequence``, ``method``, ``run``) with its tracked share and pose pairs (columns named by
    their keys, NaN where absent); without a ``run`` column each tracked-share row is a run of its own."""
    rows = frame[frame["metric"].isin([_SHARE, _PAIRS])]
    if rows.empty:
        return pd.DataFrame(columns=["sequence", "method", "run", _SHARE, _PAIRS])
    rows = rows.assign(value=pd.to_numeric(rows["value"], errors="coerce"))
    if "run" not in rows.columns:
        rows = rows[rows["metric"] == _SHARE]
        rows = rows.assign(run=np.arange(len(rows)).astype(str))
    wide = rows.pivot_table(index=["sequence", "method", "run"], columns="metric", values="value", aggfunc="first",
                            dropna=False).reset_index()  # fmt: skip
    for col in (_SHARE, _PAIRS):
        if col not in wide.columns:
            wide[col] = np.nan
    return wide.dropna(subset=[_SHARE, _PAIRS], how="all")


def failed_runs(frame: pd.DataFrame) -> set[tuple[str, str, str]]:
    """(sequence, method, run) of every run of the long ``frame`` that is a failure
    (:func:`eval.metrics.results.failure_of` of its tracked share and pose pairs)."""
    out = set()
    for row in _run_metrics(frame).to_dict("records"):
        if failure_of({_SHARE: row[_SHARE], _PAIRS: row[_PAIRS]}) is not None:
            out.add((str(row["sequence"]), str(row["method"]), str(row["run"])))
    return out


def cell_failures(frame: pd.DataFrame) -> Failures:
    """(sequence, method) -> :class:`CellFailure` for every cell of the long ``frame`` whose runs carry a tracked
    share or a pose count (a cell without them, e.g. a depth-only method, has none and is never a failure)."""
    runs = _run_metrics(frame)
    if runs.empty:
        return {}
    failed = failed_runs(frame)
    out: Failures = {}
    for (sequence, method), cell in runs.groupby(["sequence", "method"], sort=False):
        bad = np.array([(str(sequence), str(method), str(r)) in failed for r in cell["run"]])
        shares = pd.to_numeric(cell[_SHARE], errors="coerce").to_numpy(dtype=float)
        info = CellFailure(len(cell), int(bad.sum()), math.nan)
        pick = bad if info.is_failure else ~bad
        chosen = shares[pick][np.isfinite(shares[pick])]
        out[(str(sequence), str(method))] = info._replace(share=float(np.median(chosen)) if chosen.size else
                                                          (0.0 if info.is_failure else math.nan))  # fmt: skip
    return out


def without_failures(frame: pd.DataFrame, failures: Failures | None = None) -> pd.DataFrame:
    """The long ``frame`` less what is no figure: every row of a failed cell, and the failed runs of the other cells
    (a cell's figure is the median over the runs that did not fail)."""
    if frame.empty or "metric" not in frame.columns:
        return frame
    failures = cell_failures(frame) if failures is None else failures
    cells = {k for k, v in failures.items() if v.is_failure}
    runs = failed_runs(frame) if "run" in frame.columns else set()
    if not cells and not runs:
        return frame
    key = list(zip(frame["sequence"].astype(str), frame["method"].astype(str), strict=True))
    keep = np.array([k not in cells for k in key], dtype=bool)
    if runs:
        keep &= np.array([(s, m, str(r)) not in runs for (s, m), r in zip(key, frame["run"], strict=True)])
    return frame[keep]


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
    min and max over its runs that did not fail), ``partial``, (sequence, method) -> (poses scored, frames) of the
    cells with a run covering less than its sequence (:func:`partial_cells`), and ``failures``, the failed runs and
    tracked share of each cell (:func:`cell_failures`)."""

    lo: pd.DataFrame
    hi: pd.DataFrame
    partial: Cells
    failures: Failures = {}  # noqa: RUF012 (a NamedTuple's default, never changed in place)


def partial_cells(frame: pd.DataFrame) -> Cells:
    """(sequence, method) -> ``(poses scored, frames)`` of the cell's least covered run, for every cell with a run
    that covers less than its sequence (:func:`eval.metrics.results.coverage` of the run's pose-pair and frame
    rows; runs told apart by the ``run`` column). Empty without a ``run`` column."""
    if frame.empty or "run" not in frame.columns:
        return {}
    rows = frame[frame["metric"].isin([_PAIRS, catalogue.FRAMES.key])]
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
    a method with a missing cell or a run covering less than its sequence (:func:`partial_cells`). Failures
    (:func:`cell_failures`) are no figures: a failed cell is NaN, a cell's statistic is over its runs that did not
    fail, and the Avg. of a column with failed cells is over its other sequences (NaN when all failed).
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
    failures = cell_failures(frame) if len(frame) else {}
    frame = without_failures(frame, failures)
    cells = cell_statistics(frame)[stat] if len(frame) else pd.Series(dtype=float)
    partial = partial_cells(frame)
    columns = []
    data = []
    for title, metric in blocks:
        for method in methods:
            values = [cells.get((seq, method, metric), np.nan) for seq in sequences]
            failed = {seq for seq in sequences if (f := failures.get((seq, method))) is not None and f.is_failure}
            if drop_empty and np.all(np.isnan(values)) and not failed:
                continue
            columns.append((title, method))
            avg = np.nan
            covered = [seq for seq in sequences if seq not in failed]
            kept = [v for seq, v in zip(sequences, values, strict=True) if seq not in failed]
            if covered and not np.any(np.isnan(kept)) and not any((seq, method) in partial for seq in covered):
                per_seed = _avg_over_seeds(frame, covered, method, metric)
                if not per_seed.size:  # no seeds with every sequence: the mean of the cells
                    avg = float(np.mean(kept))
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
    """``"higher"`` or ``"lower"``: which values of ``metric`` are better (its catalogue spec,
    :func:`eval.metrics.catalogue.better_direction`); None when neither is (a scale, a count, a length)."""
    return catalogue.better_direction(metric)


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
    name = method[-1] if isinstance(method, tuple) else method
    fail = spread.failures.get((str(row), str(name))) if spread is not None else None
    if fail is not None and fail.is_failure:
        return _latex_percent(fail.text(), latex)
    covers = avg_coverage(spread, name) if spread is not None and row == AVG_LABEL else None
    if pd.isna(value):
        return f"{FAILURE_MARK} ({covers[0]}/{covers[1]})" if covers is not None and covers[0] == 0 else MISSING
    text = f"{value:.{digits}f}"
    if bold and latex:
        text = f"\\textbf{{{text}}}"
    if spread is None:
        return text
    lo, hi = (t.at[row, method] for t in (spread.lo, spread.hi))
    if not (pd.isna(lo) or pd.isna(hi) or lo == hi):
        rng = f"[{lo:.{digits}f}, {hi:.{digits}f}]"
        text += " " + (f"{{\\scriptsize {rng}}}" if latex else rng)
    if covers is not None:
        text += f" ({covers[0]}/{covers[1]})"
    note = fail.note() if fail is not None else ""
    return text + _latex_percent(note, latex) + coverage_note(spread.partial.get((str(row), str(name))))


def avg_coverage(spread: Spread, method: object) -> tuple[int, int] | None:
    """``(sequences averaged, sequences)`` of ``method``'s Avg. in the table ``spread`` belongs to, when some of its
    sequences are failed cells (left out of the average); None when none is."""
    sequences = [str(r) for r in spread.lo.index if r != AVG_LABEL]
    failed = sum(1 for seq in sequences if (f := spread.failures.get((seq, str(method)))) is not None
                 and f.is_failure)  # fmt: skip
    return (len(sequences) - failed, len(sequences)) if failed else None


def _latex_percent(text: str, latex: bool) -> str:
    return text.replace("%", "\\%") if latex else text


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
    """The ``min`` and ``max`` tables matching ``table1(frame, **kwargs)``, the frame's partial cells (of the runs
    that did not fail) and its failures, for :func:`format_table`'s ``spread``."""
    failures = cell_failures(frame) if len(frame) else {}
    return Spread(table1(frame, stat="min", **kwargs), table1(frame, stat="max", **kwargs),
                  partial_cells(without_failures(frame, failures)), failures)  # fmt: skip


STATISTICS_COLUMNS: tuple[str, ...] = ("sequence", "method", "metric", "runs", *STATISTICS, "failed_runs", "failure")


def statistics_frame(frame: pd.DataFrame, metrics: Sequence[str] | None = None) -> pd.DataFrame:
    """The cell statistics in long form (columns :data:`STATISTICS_COLUMNS`), optionally only for ``metrics``.
    ``runs`` and the statistics are over the runs that did not fail; ``failed_runs``: the cell's runs that failed;
    ``failure``: ``X (22 %)`` for a failed cell (its statistics empty: no figure), else empty."""
    failures = cell_failures(frame) if len(frame) else {}
    every = cell_statistics(frame)
    kept = cell_statistics(without_failures(frame, failures))
    stats = kept.reindex(every.index)
    stats["runs"] = stats["runs"].fillna(0).astype(int)
    keys = list(zip(stats.index.get_level_values(0), stats.index.get_level_values(1), strict=True))
    found = [failures.get((str(s), str(m))) for s, m in keys]
    stats["failed_runs"] = [f.failed if f is not None else 0 for f in found]
    stats["failure"] = [f.text() if f is not None and f.is_failure else "" for f in found]
    stats = stats.reset_index()[list(STATISTICS_COLUMNS)]
    return stats[stats["metric"].isin(metrics)] if metrics is not None else stats


def table_to_csv(table: pd.DataFrame, spread: Spread | None = None) -> str:
    """CSV: two header rows (block, method), numeric medians, empty cells for missing values; with ``spread``
    (:func:`spread_of`), a failed cell is its mark and tracked share, ``X (22 %)``, never a figure, and an Avg. over
    a column with failed cells says how many sequences it covers, ``0.412 (7/9)``."""
    if spread is None or not any(f.is_failure for f in spread.failures.values()):
        return table.to_csv(float_format="%.6g")
    out = table.map(lambda v: "" if pd.isna(v) else f"{v:.6g}").astype(object)
    for col in table.columns:
        name = col[-1] if isinstance(col, tuple) else col
        for row in table.index:
            fail = spread.failures.get((str(row), str(name)))
            if fail is not None and fail.is_failure:
                out.at[row, col] = fail.text()
            elif row == AVG_LABEL and (covers := avg_coverage(spread, name)) is not None:
                out.at[row, col] = (f"{FAILURE_MARK} " if pd.isna(table.at[row, col]) else out.at[row, col] + " ") + \
                    f"({covers[0]}/{covers[1]})"
    return out.to_csv()


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
