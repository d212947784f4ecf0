"""``preprocessing.{md,csv}``: the preprocessing suite's report (the numbers come from :mod:`eval.reports.sensitivity`).

- ``preprocessing.md``: per folder, the verdicts a choice changes (a method's rank, or its tracked share by more
  than 20 points), each choice's agreement with the defaults (Kendall's tau, Spearman's rho, same ranking), every
  method's score (rank) under each choice per metric, and the state of the runs;
- ``preprocessing.csv``: folder, choice, metric, method, score, sequences, runs, rank;
- ``preprocessing_changes.csv``: the changed verdicts.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from eval.reports.html_report import markdown_page
from eval.reports.inputs import PreprocessingChoice, SuiteRun
from eval.reports.report_parts import long_frame, status_markdown
from eval.reports.sensitivity import (
    SENSITIVITY_METRICS,
    TRACKED_SHARE_CHANGE,
    changed_verdicts,
    choice_agreement,
    choice_order,
    choice_ranks,
)
from eval.reports.style import DEFAULT_FIGURE_FORMAT
from eval.reports.transfer_report import fmt_score as _fmt


def preprocessing_frame(parts: Sequence[tuple[str, SuiteRun, tuple[tuple[str, str], ...]]]) -> pd.DataFrame:
    """The long frames of each choice's runs with ``choice`` and ``folder`` (the sequence's folder name) columns."""
    frames = []
    for choice, run, domains in parts:
        frame = long_frame(run)
        if not frame.empty:
            frames.append(frame.assign(choice=choice, folder=frame["sequence"].map(dict(domains))))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(
        columns=["folder", "choice", "sequence", "method", "metric", "value"])  # fmt: skip


def report_preprocessing(parts: Sequence[tuple[str, SuiteRun, tuple[tuple[str, str], ...]]],
                         choices: Sequence[PreprocessingChoice], results_dir: str | Path, command: str,
                         figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """Write the preprocessing report (module docstring) into ``results_dir``, and ``preprocessing.html`` (the same,
    one self-contained page, tables sortable); returns the files written. ``choices``: every preprocessing choice
    (:data:`eval.bench.suites.PREPROCESSING_CHOICES`), listed with what it does. It draws no figure
    (``figure_format`` is taken for the same call as the other reports)."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    ranks = choice_ranks(preprocessing_frame(parts))
    agreement = choice_agreement(ranks)
    changes = changed_verdicts(ranks)
    csv = results_dir / "preprocessing.csv"
    ranks.to_csv(csv, index=False, float_format="%.6g")
    changes_csv = results_dir / "preprocessing_changes.csv"
    changes.to_csv(changes_csv, index=False, float_format="%.6g")
    labels = {m.name: m.label for m in SENSITIVITY_METRICS}
    described = {c.name: c.description for c in choices}
    text = [
        "# Preprocessing: does a choice of how the files become frames decide a verdict?\n",
        f"Made by `{command}`. Each folder runs under the loader's defaults (undistortion cropped to what the lens "
        "saw, 320x240, depth registered to the colour camera where the dataset's depth is another camera's) and "
        "under every other choice that changes anything for it. Per folder and choice, a method's score is the "
        "median over its runs; rank 1 is best. A verdict changes when a method's rank moves, or its tracked share "
        f"by more than {TRACKED_SHARE_CHANGE:.0%}.\n",
        "Choices:\n",
        "- `default`: the loader's defaults",
        *[f"- `{c.name}`: {c.description} (applies to a folder whose camera is {c.applies})"
          for c in choices],  # fmt: skip
    ]
    for folder in sorted(ranks["folder"].unique()):
        sub = ranks[ranks["folder"] == folder]
        choices = choice_order(list(sub["choice"].unique()))
        moved = changes[changes["folder"] == folder]
        text += [f"\n## {folder}\n", f"Choices run: {', '.join(choices)}.\n", "### Verdicts that change\n"]
        if moved.empty:
            text.append("None: every choice ranks the methods as the defaults do, and no tracked share moves by "
                        f"more than {TRACKED_SHARE_CHANGE:.0%}.\n")  # fmt: skip
        else:
            text += ["| choice | metric | method | default: score (rank) | choice: score (rank) |",
                     "|---|---|---|---:|---:|"]  # fmt: skip
            text += [f"| {r.choice} | {labels.get(r.metric, r.metric)} | {r.method} | {_fmt(r.default_score)} "
                     f"({r.default_rank:g}) | {_fmt(r.score)} ({r.rank:g}) |" for r in moved.itertuples()]  # fmt: skip
        agree = agreement[(agreement["folder"] == folder) & (agreement["choice"] != "default")]
        text += ["\n### Agreement with the defaults\n", "| choice | metric | n | Kendall tau | Spearman rho | same |",
                 "|---|---|---:|---:|---:|---|"]  # fmt: skip
        text += [f"| {r.choice} | {labels.get(r.metric, r.metric)} | {r.n} | {_fmt(r.kendall)} | {_fmt(r.spearman)} "
                 f"| {'yes' if r.same else 'no'} |" for r in agree.itertuples()]  # fmt: skip
        text.append("\n### Scores and ranks: score (rank)\n")
        for metric in SENSITIVITY_METRICS:
            m = sub[sub["metric"] == metric.name]
            if m.empty:
                continue
            text += [f"\n{metric.label} ({'higher' if metric.higher_is_better else 'lower'} is better)\n",
                     "| method | " + " | ".join(choices) + " |", "|---|" + "---:|" * len(choices)]  # fmt: skip
            for method in m[m["choice"] == "default"].sort_values("rank")["method"]:
                cells = []
                for choice in choices:
                    row = m[(m["method"] == method) & (m["choice"] == choice)]
                    cells.append("-" if row.empty else f"{_fmt(row['score'].iloc[0])} ({row['rank'].iloc[0]:g})")
                text.append(f"| {method} | " + " | ".join(cells) + " |")
    if ranks.empty:
        text.append("\nNo runs were scored (no folder in the dataset list?).\n")
    text += [f"\n## Runs: {choice} ({described.get(choice, 'the defaults')})\n"
             + status_markdown(run).removeprefix("## Runs\n") for choice, run, _ in parts]  # fmt: skip
    md = results_dir / "preprocessing.md"
    md.write_text("\n".join(text))
    page = markdown_page("\n".join(text[1:]), results_dir, "preprocessing", text[0].strip("# \n"))
    return [md, page, csv, changes_csv]
