"""A suite's report as one self-contained HTML page, ``<results>/<suite>.html`` beside ``<suite>.md`` (the pieces:
:mod:`eval.reports.html`). It holds, in this order:

- **Provenance**: the command, the git revision(s) and machine(s) of the runs, the camera, frames, seeds, how the
  runs ended, the alignment, where the run folders are, the failure rule (:data:`eval.metrics.results.FAILURE_RULE`);
- **Results**: the suite's main tables (the blocks of its Markdown's main table), one sortable table per metric:
  rows the sequences (the Avg. row kept last), columns the methods; each cell the median of its runs with their range,
  the paper's value beside ours where the suite quotes the paper (``table1``), the best value of each row in bold
  among the methods that receive no ground truth, ``n/a`` with the reason (on hover) where a method has no value,
  ``X (22 %)`` (the reason on hover) where a cell is a failure (:mod:`eval.reports.tables`), never a figure;
  **each cell opens the runs behind it**;
- **Report**: the Markdown report rendered, every table sortable, its figures inline (a PDF figure through its PNG
  twin);
- **Runs**: per sequence and method, every run: its figures (ATE, Sim(3) ATE, correct depth, tracked share, relative
  error, speed and memory), its trajectory overlaid on the ground truth (top view, aligned as scored, inline SVG),
  its depth samples (its ``depth.png``, shrunk), its aligned TUM files, its failure (error and traceback) if it
  failed.

Opens from disk and fetches nothing: every image is inline; a Content Security Policy forbids any request.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from eval.metrics import catalogue
from eval.metrics.aligned import ALIGNED_FILES
from eval.metrics.results import FAILURE_RULE, RunRecord, failure_of
from eval.metrics.runs import FAILED_FILE
from eval.reports.html import Cell, image_data_uri, markdown_to_html, page, sortable_table, svg_track, text_cell
from eval.reports.inputs import RunSpec, SuiteRun
from eval.reports.paper_figures import file_slug
from eval.reports.paper_table1 import covers_paper_sequences, paper_value
from eval.reports.run_data import RunTrack, missing_reasons
from eval.reports.style import method_style
from eval.reports.tables import AVG_LABEL, avg_coverage, best_cells, cell_text, spread_of, table1

DEPTH_THUMBNAIL_WIDTH = 320  # px: a run's depth.png shrunk for the page (JPEG, quality below: about 17 kB)
DEPTH_THUMBNAIL_QUALITY = 70
TRACEBACK_LINES = 25  # a failed run's traceback: its last lines


def cell_anchor(sequence: str, method: str) -> str:
    """The id of a cell's runs on the page (what a table cell links to)."""
    return f"runs-{file_slug(sequence)}--{file_slug(method)}"


def _definition_list(items: Sequence[tuple[str, str]]) -> str:
    return ('<dl class="provenance">' + "".join(f"<dt>{html.escape(k)}</dt><dd>{v}</dd>" for k, v in items if v)
            + "</dl>")  # fmt: skip


def provenance_html(run: SuiteRun, command: str, machines: str, camera: str, figure_format: str) -> str:
    """What the runs are and where they came from (module docstring)."""
    suite = run.suite
    revisions = sorted({str(r.metadata.get("git_revision")) for r in run.records}) or ["-"]
    counts = run.counts()
    note = suite.selection_note()
    ended = ", ".join(f"{n} {status}" for status, n in sorted(counts.items()))
    return _definition_list([
        ("suite", html.escape(f"{suite.name}: " + (f"a selection ({note})" if note else suite.description))),
        ("command", f"<code>{html.escape(command)}</code>"),
        ("git revision", html.escape(", ".join(revisions))),
        ("machines", html.escape(machines or "not recorded")),
        ("camera", html.escape(camera) or "-"),
        ("frames", "whole sequences" if suite.frames is None else f"the first {suite.frames} of each sequence"),
        ("seeds", html.escape(", ".join(map(str, suite.seeds)) + " (a method that takes no seed runs once)")),
        ("sequences", html.escape(", ".join(s.name for s in suite.sequences))),
        ("methods", html.escape(", ".join(suite.methods))),
        ("runs", html.escape(f"{len(run.specs)}: {ended}")),
        ("ATE alignment", html.escape(f"{suite.alignment.upper()} unless a method says otherwise")),
        ("run folders", f"<code>{html.escape(str(run.out_root / suite.name))}</code>"),
        ("figure format", html.escape(figure_format)),
        ("failures", html.escape(FAILURE_RULE)),
    ])  # fmt: skip


def results_table_html(run: SuiteRun, frame: pd.DataFrame, title: str, metric: str, paper: bool,
                       digits: int = 3) -> str:
    """One metric of the suite as a sortable table (module docstring): rows sequences, the Avg. row last, columns
    the methods; empty when no method has a value."""
    methods = list(run.suite.methods)
    sequences = [s.name for s in run.suite.sequences]
    shape = {"methods": methods, "sequences": sequences, "blocks": [(title, metric)]}
    table = table1(frame, **shape)
    spread = spread_of(frame, **shape)
    if table.empty or (table.isna().all().all() and not any(f.is_failure for f in spread.failures.values())):
        return ""
    fed = sorted({r.method for r in run.records if r.uses_ground_truth})
    bold = best_cells(table, [(title, metric)], digits, fed)
    all_nine = covers_paper_sequences(sequences)
    missing_any = missing_reasons(run, metric, methods)

    def cell(label: object, method: str) -> Cell:
        value = table.at[label, (title, method)]
        failure = spread.failures.get((str(label), method))
        covers = avg_coverage(spread, method) if label == AVG_LABEL else None
        if (failure is not None and failure.is_failure) or (pd.isna(value) and covers is not None and not covers[0]):
            text = cell_text(value, label, (title, method), spread, digits)
            why = (f"a failure: {failure.failed} of {failure.runs} run(s) failed (never initialised, or tracked too "
                   "little of the sequence)" if failure is not None else "every sequence a failure")
            inner = f'<span class="failure">{html.escape(text)}</span>'
            if label != AVG_LABEL:
                inner = f'<a class="cell" href="#{cell_anchor(str(label), method)}">{inner}</a>'
            return Cell(inner, None, True, why)
        if pd.isna(value):
            why = (missing_reasons(run, metric, [method], sequence=str(label)).get(method)
                   if label != AVG_LABEL else missing_any.get(method))  # fmt: skip
            why = why or ("not every sequence has a whole run" if label == AVG_LABEL else "no value")
            return Cell('<span class="na">n/a</span>', None, True, why)
        text = cell_text(value, label, (title, method), spread, digits)
        median, _, rest = text.partition(" ")
        inner = f'<span class="{"best" if (label, (title, method)) in bold else ""}">{html.escape(median)}</span>'
        if rest:
            inner += f' <span class="range">{html.escape(rest)}</span>'
        quoted = paper_value(label, method, metric, all_nine) if paper and covers is None else math.nan
        if not math.isnan(quoted):
            inner += f' <span class="paper" title="the paper\'s Table 1">({quoted:.{digits}f})</span>'
        if label != AVG_LABEL:
            inner = f'<a class="cell" href="#{cell_anchor(str(label), method)}">{inner}</a>'
        return Cell(inner, float(value), True)

    rows = [[text_cell(str(label)), *(cell(label, m) for m in methods)] for label in table.index if label != AVG_LABEL]
    footer = [[text_cell(AVG_LABEL), *(cell(AVG_LABEL, m) for m in methods)]]
    legend = ("bold: the best of the row among the methods that receive no ground truth"
              + (f" ({', '.join(fed)} do)" if fed else "") + "; [min, max]: the range of the cell's runs"
              + ("; (x): the paper's Table 1" if paper else "") + "; n/a: hover for why; X (22 %): a failure "
              "(its tracked share), no figure; (7/9): an average over the sequences that are not failures; "
              "a cell opens its runs")
    return (f"<h3>{html.escape(title)}</h3>\n" + sortable_table(["sequence", *methods], rows, footer)
            + f'\n<p class="range">{html.escape(legend)}</p>')


def _fmt(value: float | None, digits: int, unit: str = "") -> str:
    if value is None or not isinstance(value, int | float) or not math.isfinite(value):
        return "-"
    return f"{value:.{digits}f}{unit}"


RUN_FACTS: tuple[tuple[str, str, int, str], ...] = tuple(  # (label, metric or resource, decimals, unit)
    (s.label_at(catalogue.RUN_FACTS), s.key, s.digits, s.unit_suffix) for s in catalogue.shown_at(catalogue.RUN_FACTS))


def run_html(spec: RunSpec, run: SuiteRun, record: RunRecord | None, track: RunTrack | None) -> str:
    """One run (module docstring): its facts, trajectory overlay, depth samples, aligned files or its failure."""
    outcome = run.outcomes.get(spec.key)
    status = outcome.status if outcome is not None else "not planned"
    folder = outcome.folder if outcome is not None else run.out_root / spec.key
    head = (f"<strong>seed {spec.seed}</strong> &middot; {html.escape(status)} &middot; "
            f"<code>{html.escape(spec.key)}</code>")
    if record is None:
        body = f"<p>{html.escape(outcome.error or 'no record') if outcome is not None else 'not run'}</p>"
        failed = folder / FAILED_FILE
        if failed.is_file():
            try:
                info = json.loads(failed.read_text())
            except (OSError, json.JSONDecodeError):
                info = {}
            tail = "\n".join(str(info.get("traceback") or "").splitlines()[-TRACEBACK_LINES:])
            body += f"<pre>{html.escape(str(info.get('error') or ''))}\n\n{html.escape(tail)}</pre>"
        return f'<div class="run"><div class="facts">{head}{body}</div></div>'
    values = {**record.metrics, **record.resources}
    failure = failure_of(record.metrics)
    if failure is not None:
        head += f' &middot; <strong class="failure">failure: {html.escape(failure)}</strong>'
    facts = [f"<tr><td>{html.escape(label)}</td><td class='num'>{_fmt(values.get(key), d, unit)}</td></tr>"
             for label, key, d, unit in RUN_FACTS if key in values]  # fmt: skip
    for share in (10, 30, 50):
        distance, translation, rotation = catalogue.relative_keys(share)
        t, q = values.get(translation), values.get(rotation)
        if t is not None:
            facts.append(f"<tr><td>relative error at {share} % ({_fmt(values.get(distance), 2, ' m')})"
                         f"</td><td class='num'>{_fmt(t, 4, ' m')}, {_fmt(q, 2, ' deg')}</td></tr>")
    files = [name for name in ALIGNED_FILES.values() if (folder / name).is_file()]
    notes = "".join(f"<li>{html.escape(w)}</li>" for w in record.warnings)
    parts = [f'<div class="facts">{head}<table>{"".join(facts)}</table>',
             f"<p>aligned TUM files (evo_traj tum FILE): "
             f"{', '.join(f'<code>{f}</code>' for f in files) or 'none'}</p>",
             f"<ul>{notes}</ul>" if notes else "", "</div>"]  # fmt: skip
    if track is not None:
        title = f"{spec.method.name} on {spec.sequence.name}, seed {spec.seed}: top view, aligned ({track.alignment})"
        svg = svg_track(track.gt[:, :2], track.est[:, :2], method_style(spec.method.name).color, title=title)
        parts.append(f"<figure>{svg}<figcaption>trajectory (colour) on the ground truth (dashed), x-y [m], "
                     f"{html.escape(track.alignment)}</figcaption></figure>")
    depth = image_data_uri(folder / "depth.png", DEPTH_THUMBNAIL_WIDTH, DEPTH_THUMBNAIL_QUALITY)
    if depth is not None:
        parts.append(f'<figure><img alt="depth samples" src="{depth}"><figcaption>key-frame depth: ground truth, '
                     "estimate, error (blue: within 10 %, red: wrong, grey: none)</figcaption></figure>")
    elif "depth" in spec.method.metrics:
        parts.append("<p class='na'>no depth figure (plots off, or no key-frame)</p>")
    return f'<div class="run">{"".join(parts)}</div>'


def runs_html(run: SuiteRun, tracks: dict[str, dict[str, list[RunTrack]]]) -> str:
    """Every run, grouped by sequence and method (each group a ``<details>`` a table cell opens)."""
    records = {r.run: r for r in run.records}
    by_key = {t.key: t for methods in tracks.values() for ts in methods.values() for t in ts}
    out = []
    for ref in run.suite.sequences:
        out.append(f"<h3>{html.escape(ref.name)}</h3>")
        for method in run.suite.methods:
            specs = [s for s in run.specs if s.sequence.name == ref.name and s.method.name == method]
            if not specs:
                why = missing_reasons(run, "frames", [method], sequence=ref.name).get(method, "not run")
                out.append(f'<details id="{cell_anchor(ref.name, method)}"><summary>{html.escape(method)}: '
                           f"no run ({html.escape(why)})</summary></details>")  # fmt: skip
                continue
            ended = [run.outcomes[s.key].status for s in specs if s.key in run.outcomes]
            summary = (f"{method}: {len(specs)} run(s), "
                       + ", ".join(f"{ended.count(k)} {k}" for k in sorted(set(ended))))
            colour = method_style(method).color
            body = "".join(run_html(s, run, records.get(s.key), by_key.get(s.key)) for s in specs)
            out.append(f'<details id="{cell_anchor(ref.name, method)}"><summary><span style="color:{colour}">'
                       f"&#9632;</span> {html.escape(summary)}</summary>{body}</details>")  # fmt: skip
    return "\n".join(out)


def resolve_in(folder: Path):
    """An image resolver for :func:`eval.reports.html.markdown_to_html`: a path relative to ``folder`` -> its data
    URI (a PDF through its PNG twin)."""
    def resolve(src: str) -> str | None:
        path = folder / src
        if path.suffix.lower() == ".pdf":
            path = path.with_suffix(".png")
        return image_data_uri(path)

    return resolve


def write_html_report(run: SuiteRun, results_dir: str | Path, name: str, title: str, command: str, markdown: str,
                      blocks: Sequence[tuple[str, str]], frame: pd.DataFrame,
                      tracks: dict[str, dict[str, list[RunTrack]]], *, paper: bool = False, machines: str = "",
                      camera: str = "", figure_format: str = "png") -> Path:
    """Write ``<results_dir>/<name>.html`` (module docstring): ``markdown`` the report's text (its images relative
    to ``results_dir``), ``blocks`` the (title, metric) pairs of its main tables, ``frame`` the runs' long frame,
    ``tracks`` their trajectories (:func:`eval.reports.run_data.suite_tracks`), ``paper``: quote the paper's Table
    1 beside ours. Returns the path."""
    results_dir = Path(results_dir)
    tables = [t for t in (results_table_html(run, frame, t, m, paper) for t, m in blocks) if t]
    body = [
        '<section id="provenance"><h2>Provenance</h2>',
        provenance_html(run, command, machines, camera, figure_format), "</section>",
        '<section id="results"><h2>Results</h2>', *(tables or ["<p>No finished run.</p>"]),
        "</section>",
        '<section id="report"><h2>Report</h2>', markdown_to_html(markdown, resolve_in(results_dir)), "</section>",
        '<section id="runs"><h2>Runs</h2><p>Every run of every cell; a cell of the results opens its runs.</p>',
        runs_html(run, tracks), "</section>",
    ]  # fmt: skip
    nav = [("provenance", "Provenance"), ("results", "Results"), ("report", "Report"), ("runs", "Runs")]
    path = results_dir / f"{name}.html"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page(title, "\n".join(body), nav))
    return path


def markdown_page(markdown: str, results_dir: str | Path, name: str, title: str) -> Path:
    """``<results_dir>/<name>.html`` from a report's Markdown alone (the reports made of several suites: transfer,
    lengths, preprocessing): rendered, tables sortable, figures inline."""
    results_dir = Path(results_dir)
    path = results_dir / f"{name}.html"
    path.write_text(page(title, markdown_to_html(markdown, resolve_in(results_dir))))
    return path

