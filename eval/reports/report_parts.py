"""The parts every suite report is made of (:mod:`eval.reports.suite_reports` writes one per report layout): the
long form of a suite's runs (``<suite>_long.csv``), the Markdown header (command, frames, seeds, revision, camera,
machines, the failure rule in one line), the runs' status (failure rate per method, skipped methods, failed runs and
their errors), the methods and alignment notes, a table of column blocks with its spread written as CSV and LaTeX,
and the report's files around a layout's own text (:func:`write_suite_report`: the runs figure, speed and memory,
relative errors, per-sequence figures, the HTML twin, the statistics CSV).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from eval.metrics import catalogue
from eval.metrics.catalogue import (
    ATE_ALIGNMENT_DEGENERATE,
    ATE_ALIGNMENT_FALLBACK,
    ATE_PERCENT_LENGTH,
    ATE_RMSE,
    LENGTH_GT_M,
    SCALE_ERROR,
    SCALE_ERROR_PERCENT,
    WALL_S,
)
from eval.metrics.results import FAILURE_RULE, MIN_TRACKED_SHARE, failure_of, runs_frame
from eval.reports.html_report import write_html_report
from eval.reports.inputs import SuiteRun, machine_label
from eval.reports.paper_figures import figures_dir, resources_figure, sequence_figures
from eval.reports.plots import save_runs_figure
from eval.reports.run_data import missing_reasons, suite_tracks
from eval.reports.run_tables import relative_error_markdown, resources_markdown
from eval.reports.style import DEFAULT_FIGURE_FORMAT
from eval.reports.tables import (
    TABLE1_BLOCKS,
    Spread,
    spread_of,
    statistics_frame,
    table1,
    table_to_csv,
    table_to_latex,
)

LOST_BELOW_TRACKED_SHARE = MIN_TRACKED_SHARE
RUNS_FIGURE_METRICS: tuple[tuple[str, str], ...] = tuple((key, label) for label, key in
                                                          catalogue.blocks(catalogue.RUNS_FIGURE))  # fmt: skip


def camera_sentence(suite: Any) -> str:
    """Which simulated camera(s) the suite's simulated sequences are seen through
    (:mod:`sim_envs.sensor.camera_effects`),
    as a sentence for a report's header; empty when it has none."""
    cameras = sorted({str(dict(r.overrides).get("camera_effects", "clean")) for r in suite.sequences
                      if r.folder is None})  # fmt: skip
    if not cameras:
        return ""
    lit = sorted({r.name for r in suite.sequences if r.folder is None and dict(r.overrides).get("lighting", "flat")
                  != "flat"})  # fmt: skip
    rooms = (f"Rooms lit with lamps, shadows and highlights (`sim_envs/scenes/lighting.py`, the `+lit` names): "
             f"{len(lit)} of "
             f"{sum(r.folder is None for r in suite.sequences)} simulated sequences. ") if lit else ""  # fmt: skip
    return (f"Simulated camera: **{', '.join(cameras)}** (`sim_envs/sensor/camera_stages.py`; "
            f"`--camera clean|kinect|hard` "
            "switches; a sequence's `@PRESET` suffix names its camera). " + rooms)  # fmt: skip


# --------------------------------------------------------------------------------------------------- long form
def long_frame(run: SuiteRun) -> pd.DataFrame:
    """All finished runs in long form (:func:`eval.metrics.results.runs_frame`) with the wall time of each run's
    timing."""
    wall = WALL_S.key
    records = [r.replace(metadata={**r.metadata, wall: run.timings.get(r.run, {}).get(wall, math.nan)})
               for r in run.records]  # fmt: skip
    return runs_frame(records)


def write_long_csv(run: SuiteRun, results_dir: str | Path, frame: pd.DataFrame | None = None) -> Path:
    """``<suite>_long.csv`` in ``results_dir`` (``frame``: the run's :func:`long_frame`, when already built)."""
    path = Path(results_dir) / f"{run.suite.name}_long.csv"
    path.parent.mkdir(parents=True, exist_ok=True)
    (long_frame(run) if frame is None else frame).to_csv(path, index=False, float_format="%.6g")
    return path


# ------------------------------------------------------------------------------------------------ Markdown parts
def header_markdown(run: SuiteRun, title: str, command: str) -> str:
    """Title, what the report holds (the suite, or the selection from it: :meth:`Suite.selection_note`), and how it
    was made."""
    suite = run.suite
    revisions = sorted({str(r.metadata.get("git_revision")) for r in run.records}) or ["-"]
    frames = "whole sequences" if suite.frames is None else f"the first {suite.frames} frames of each sequence"
    note = suite.selection_note()
    holds = (f"**A selection from suite `{suite.name}`**: {note}. The suite as defined: {suite.description}"
             if note else f"{suite.description[:1].upper()}{suite.description[1:]}")  # fmt: skip
    return (
        f"# {title}\n\n{holds}.\n\n"
        f"Made by `{command}`: {frames}, {len(suite.seeds)} run(s) per cell (seeds "
        f"{', '.join(map(str, suite.seeds))}; what a seed changes per method: `eval/methods.toml`; a method that "
        "takes no seed is exact given its inputs and runs once), ATE after "
        f"{suite.alignment.upper()} alignment unless a method says otherwise, git revision {', '.join(revisions)}. "
        f"{camera_sentence(suite)}Each cell: the **median** of its runs and their range **[min, max]** where the "
        f"runs differ. **Failures**: {FAILURE_RULE} Per-run "
        "artifacts (trajectories, "
        f"key-frame depths, metrics, plots) under `{run.out_root}/{suite.name}/`; every run's figures in long form "
        f"in `{suite.name}_long.csv`, the statistics per cell in `{suite.name}_stats.csv`, every run as a dot in "
        f"`{suite.name}_runs.png`.\n"
    )


def machines_sentence(run: SuiteRun) -> str:
    """Which machines (CPU, ISA, torch, numpy; ``timing.json``'s ``environment``) the finished runs ran on."""
    envs = [timing.get("environment") for timing in run.timings.values()]
    counts = Counter(machine_label(env) for env in envs if env)
    unknown = sum(1 for env in envs if not env)
    if not counts:
        return "Machine: not recorded (runs from before `timing.json` recorded it)." if unknown else ""
    parts = [f"{label}: {n} run(s)" for label, n in sorted(counts.items())]
    if unknown:
        parts.append(f"not recorded: {unknown} run(s)")
    return "Machines: " + "; ".join(parts) + "."


def status_markdown(run: SuiteRun) -> str:
    """Runs done / failed, methods skipped with their reasons, failed runs with their errors."""
    counts = run.counts()
    lines = [
        "## Runs\n",
        f"{len(run.specs)} runs: {counts.get('done', 0)} run now, {counts.get('cached', 0)} reused from earlier, "
        f"{counts.get('failed', 0)} failed"
        + (f", {counts['not_run']} not run (--report-only: no finished run in the output folder)"
           if counts.get("not_run") else "") + f". {machines_sentence(run)}",
    ]
    failures = failure_frame(run)
    if failures.empty:
        lines.append("")
    else:
        per_method = failures.groupby("method", sort=False)[["runs", "crashed", "lost"]].sum()
        lines += [
            f"\nFailure rate per method (crashed or timed out, or failed by the rule: never initialised or tracked "
            f"less than {round(100 * MIN_TRACKED_SHARE)} % of its frames; a failed run counts in no median):\n",
            "| method | runs | crashed | lost | failure rate |",
            "|---|---:|---:|---:|---:|",
        ]
        for method, row in per_method.iterrows():
            rate = (row["crashed"] + row["lost"]) / row["runs"] if row["runs"] else 0.0
            lines.append(f"| {method} | {row['runs']} | {row['crashed']} | {row['lost']} | {rate:.0%} |")
    if run.skipped_methods:
        lines.append("\nMethods skipped (they cannot run here):\n")
        lines += [f"- **{name}**: {one_line(reason)}" for name, reason in run.skipped_methods.items()]
    if run.suite.skipped:
        lines.append("\nSequences skipped (listed, but not here):\n")
        lines += [f"- **{name}**: {one_line(reason)}" for name, reason in run.suite.skipped]
    if run.failed:
        lines.append("\nFailed runs (rerun the same command to retry them):\n")
        lines += [f"- `{o.key}`: {one_line(o.error or '')}" for o in run.failed]
    not_run = [o for o in run.outcomes.values() if o.status == "not_run"]
    if not_run:
        per_method: dict[str, int] = {}
        for spec in run.specs:
            if run.outcomes.get(spec.key) is not None and run.outcomes[spec.key].status == "not_run":
                per_method[spec.method.name] = per_method.get(spec.method.name, 0) + 1
        lines.append("\nNot run (the tables were written from the finished runs only; each cell says how many it "
                     "has): " + ", ".join(f"{m} {n}" for m, n in per_method.items()) + ".\n")  # fmt: skip
    return "\n".join(lines) + "\n"


def methods_markdown(run: SuiteRun) -> str:
    """The methods that are not plain monocular ones: another sensor, or ground truth received (declared by an
    agent's ``uses_ground_truth`` or an external folder's ``method.toml``), so no reader takes them for peers."""
    fed = {}
    for rec in run.records:
        if rec.uses_ground_truth:
            fed.setdefault(rec.method, set()).update(rec.ground_truth_used or ["declared by the agent"])
    lines = []
    for m in run.methods:
        notes = [f"sensor {m.sensor}"] if m.sensor != "mono" else []
        if m.name in fed:
            notes.append("receives ground truth (" + ", ".join(sorted(fed[m.name])) + ")")
        if notes:
            lines.append(f"- **{m.name}**: " + "; ".join(notes))
    return ("\nNot plain monocular methods:\n\n" + "\n".join(lines) + "\n") if lines else ""


def alignment_markdown(run: SuiteRun, frame: pd.DataFrame) -> str:
    """Which alignment each cell's ATE actually used, where it is not the suite's plain Umeyama fit: methods with
    their own ``align``, and cells whose fit fell back to rotation-only or was poorly conditioned (flags of
    :mod:`eval.metrics.trajectory_metrics`), with how many of their runs."""
    lines = [f"- **{m.name}**: ATE after {m.align.upper()} alignment (the method's own)" for m in run.methods
             if m.align and m.align != run.suite.alignment]  # fmt: skip
    flags = (frame[frame["metric"].isin([ATE_ALIGNMENT_FALLBACK.key, ATE_ALIGNMENT_DEGENERATE.key])] if len(frame)
             else frame)  # fmt: skip
    if len(flags):
        counts = flags.groupby(["sequence", "method", "metric"], sort=False)["value"].agg(["sum", "count"])
        for (seq, method, metric), row in counts.iterrows():
            if row["sum"] > 0:
                fallback = metric == ATE_ALIGNMENT_FALLBACK.key
                what = ("rotation-only fallback (evo cannot fit: positions one point)" if fallback
                        else "poorly conditioned fit (positions nearly collinear or tiny), kept and flagged")
                lines.append(f"- {seq} / {method}: {what} in {int(row['sum'])} of {int(row['count'])} runs")
    if not lines:
        return ""
    return ("\nAlignment, where a cell's ATE is not a well-conditioned Umeyama fit of the suite's kind (evo's "
            "`evo_ape -a` figure):\n\n" + "\n".join(lines) + "\n")


def failure_frame(run: SuiteRun) -> pd.DataFrame:
    """Per (sequence, method) planned: ``runs``, ``crashed`` (failed or timed out: no record), ``lost`` (finished, a
    failure by :func:`eval.metrics.results.failure_of`: never initialised, or tracked share below
    :data:`LOST_BELOW_TRACKED_SHARE`), ``failure_rate``."""
    lost = {rec.run for rec in run.records if failure_of(rec.metrics) is not None}
    rows: dict[tuple[str, str], dict[str, int]] = {}
    for spec in run.specs:
        outcome = run.outcomes.get(spec.key)
        if outcome is not None and outcome.status == "not_run":
            continue  # neither a result nor a failure
        row = rows.setdefault((spec.sequence.name, spec.method.name), {"runs": 0, "crashed": 0, "lost": 0})
        row["runs"] += 1
        if outcome is None or outcome.status == "failed":
            row["crashed"] += 1
        elif spec.key in lost:
            row["lost"] += 1
    frame = pd.DataFrame([{"sequence": k[0], "method": k[1], **v} for k, v in rows.items()],
                         columns=["sequence", "method", "runs", "crashed", "lost"])  # fmt: skip
    frame["failure_rate"] = (frame["crashed"] + frame["lost"]) / frame["runs"].where(frame["runs"] > 0)
    return frame


def one_line(text: str, limit: int = 300) -> str:
    """``text`` on one line (runs of white space made one space), cut to ``limit`` characters with ``...``."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def with_relative_errors(frame: pd.DataFrame) -> pd.DataFrame:
    """The long frame plus two rows per run: :data:`~eval.metrics.catalogue.ATE_PERCENT_LENGTH` = 100 ATE RMSE /
    ground-truth path length (the drift figure of odometry papers; none for a zero-length path) and
    :data:`~eval.metrics.catalogue.SCALE_ERROR_PERCENT` = 100 scale error."""
    if frame.empty:
        return frame
    wide = frame.pivot_table(index=["run", "sequence", "method"], columns="metric", values="value", aggfunc="first")
    extra = []
    if {ATE_RMSE.key, LENGTH_GT_M.key} <= set(wide.columns):
        length = wide[LENGTH_GT_M.key].where(wide[LENGTH_GT_M.key] > 0)
        extra.append((100.0 * wide[ATE_RMSE.key] / length).rename("value").reset_index()
                     .assign(metric=ATE_PERCENT_LENGTH.key))  # fmt: skip
    if SCALE_ERROR.key in wide.columns:
        extra.append((100.0 * wide[SCALE_ERROR.key]).rename("value").reset_index()
                     .assign(metric=SCALE_ERROR_PERCENT.key))  # fmt: skip
    extra = [rows.dropna(subset=["value"]) for rows in extra]
    return pd.concat([frame, *extra], ignore_index=True) if extra else frame


def suite_table(run: SuiteRun, blocks: Sequence[tuple[str, str]],
                frame: pd.DataFrame | None = None) -> tuple[pd.DataFrame, Spread]:
    """The suite's table of ``blocks`` (cell medians) and its spread (the min and max tables: the range of each
    cell's runs; the partial cells), from ``frame`` (default: the run's long frame, built once for both)."""
    frame = long_frame(run) if frame is None else frame
    if frame.empty:
        frame = pd.DataFrame(columns=["sequence", "method", "metric", "value"])
    shape = {"methods": list(run.suite.methods), "sequences": [s.name for s in run.suite.sequences],
             "blocks": blocks}  # fmt: skip
    return table1(frame, **shape), spread_of(frame, **shape)


def write_tables(table: pd.DataFrame, stem: Path, caption: str, digits: int = 3, spread: Spread | None = None,
                 blocks: Sequence[tuple[str, str]] = (), run: SuiteRun | None = None) -> list[Path]:
    """``stem``.csv and ``stem``.tex; the LaTeX with the best value of each row of ``blocks`` in bold among the
    methods of ``run`` that receive no ground truth (:func:`eval.reports.tables.best_cells`)."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    csv, tex = stem.with_suffix(".csv"), stem.with_suffix(".tex")
    csv.write_text(table_to_csv(table, spread))
    fed = sorted({r.method for r in run.records if r.uses_ground_truth}) if run is not None else []
    if blocks:
        caption = (caption or "") + (" Bold: the best of each row" + (f" (not counting {', '.join(fed)}, which "
                                                                      "receive ground truth)" if fed else "") + ".")
    tex.write_text(table_to_latex(table, digits, caption, spread=spread, blocks=blocks, exclude=fed))
    return [csv, tex]



def markdown_image(path: Path, caption: str, results_dir: Path) -> str:
    """A figure in a report's Markdown, its path relative to ``results_dir``; a PDF shows its PNG twin
    (:func:`eval.reports.plots.save_figure`) and links the PDF."""
    rel = path.relative_to(results_dir) if path.is_relative_to(results_dir) else path
    if rel.suffix.lower() == ".pdf":
        return f"![{caption}]({rel.with_suffix('.png').as_posix()})\n\n(PDF: [{rel.name}]({rel.as_posix()}))\n"
    return f"![{caption}]({rel.as_posix()})\n"


def write_suite_report(run: SuiteRun, results_dir: Path, name: str, text: list[str], artifacts: list[Path], *,
                       blocks: Sequence[tuple[str, str]] = TABLE1_BLOCKS, figure_format: str = DEFAULT_FIGURE_FORMAT,
                       paper: bool = False) -> list[Path]:
    """Write ``<name>.md`` (``text``, then the runs figure, the speed and memory per method, the relative error at
    several distances, the per-sequence figures and the runs' status) and ``<name>.html`` (the same, with the main
    tables of ``blocks`` sortable, each cell opening its runs: :mod:`eval.reports.html_report`; ``paper``: the
    paper's Table 1 beside ours), ``<suite>_long.csv``, ``<suite>_stats.csv``, ``<suite>_runs.<fmt>``,
    ``<suite>_resources.<fmt>`` and the per-sequence figures (:mod:`eval.reports.paper_figures`), in
    ``figure_format``; return every file the report made: the Markdown, the HTML, ``artifacts`` (tables, figures),
    the long and statistics CSVs, the figures."""
    results_dir.mkdir(parents=True, exist_ok=True)
    base = long_frame(run)
    frame = with_relative_errors(base)
    stats = results_dir / f"{run.suite.name}_stats.csv"
    statistics_frame(frame).to_csv(stats, index=False, float_format="%.6g")
    methods = list(run.suite.methods)  # every method of the suite: one without a value says n/a and why
    missing = {metric: missing_reasons(run, metric, methods) for metric, _ in RUNS_FIGURE_METRICS}
    figure = None if frame.empty else save_runs_figure(
        frame, results_dir / f"{run.suite.name}_runs.{figure_format}", methods, [s.name for s in run.suite.sequences],
        RUNS_FIGURE_METRICS, title=f"{run.suite.name}: every run (dots) and each cell's median (bars)",
        missing=missing)  # fmt: skip
    shown = [markdown_image(figure, "every run of the suite", results_dir)] if figure is not None else []
    resources = resources_figure(run, results_dir, figure_format)
    speed = resources_markdown(run)
    if speed and resources is not None:
        speed += "\n" + markdown_image(resources.path, resources.caption, results_dir)
    tracks = suite_tracks(run)
    sequences = sequence_figures(run, tracks, results_dir, figure_format)
    per_sequence = (["## Figures per sequence\n", f"Files under `{figures_dir(results_dir, run.suite.name).name}/` "
                     f"({figure_format}); every method in its own colour and marker in every figure "
                     "(`eval/reports/style.py`).\n", *(markdown_image(f.path, f.caption, results_dir)
                                                       for f in sequences)] if sequences else [])  # fmt: skip
    markdown = "\n".join([*text, *shown, speed, relative_error_markdown(run), *per_sequence, methods_markdown(run),
                          alignment_markdown(run, frame), status_markdown(run)])  # fmt: skip
    md = results_dir / f"{name}.md"
    md.write_text(markdown)
    title = next((line[2:].strip() for line in text[0].splitlines() if line.startswith("# ")), name) if text else name
    page = write_html_report(run, results_dir, name, title, run_command(text), markdown, blocks, frame, tracks,
                             paper=paper, machines=plain_text(machines_sentence(run)).removeprefix("Machines: "),
                             camera=plain_text(camera_sentence(run.suite)), figure_format=figure_format)  # fmt: skip
    figures = [f for f in (figure, resources.path if resources else None, *(f.path for f in sequences)) if f]
    return [md, page, *artifacts, write_long_csv(run, results_dir, base), stats, *figures]


def run_command(text: list[str]) -> str:
    """The command a report's header quotes (``Made by `...```), empty when it quotes none."""
    found = re.search(r"Made by `([^`]+)`", text[0]) if text else None
    return found.group(1) if found else ""


def plain_text(markdown: str) -> str:
    """A Markdown sentence as plain text (backticks and bold marks dropped)."""
    return markdown.replace("`", "").replace("**", "")
