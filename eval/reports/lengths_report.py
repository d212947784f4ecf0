"""``lengths.{md,csv,png}``: the length sweep's report (the numbers come from :mod:`eval.reports.lengths`).

- ``lengths.md``: the verdict (the shortest length that ranks the methods as whole sequences do on Table 1's
  metrics), each length's agreement with the whole sequences (Kendall's tau, Spearman's rho, n, same ranking or
  not), per metric each method's score and rank at every length, where each method's rank settles, and the state of
  the runs of each length;
- ``lengths.csv``: length, metric, method, score, sequences, runs, rank;
- ``lengths_agreement.csv``: the agreement table;
- ``lengths.png``: per metric, each method's rank at every length (a bump chart; the report's figure format);
- ``lengths.html``: the Markdown rendered as one self-contained page, tables sortable, figure inline.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from eval.reports.html_report import markdown_page
from eval.reports.inputs import SuiteRun
from eval.reports.lengths import (
    DECISIVE_METRICS,
    WHOLE,
    length_agreement,
    length_label,
    length_order,
    length_ranks,
    settling_lengths,
    shortest_agreeing_length,
)
from eval.reports.plots import save_transfer_figure
from eval.reports.report_parts import long_frame, markdown_image, status_markdown
from eval.reports.style import DEFAULT_FIGURE_FORMAT
from eval.reports.transfer import TRANSFER_METRICS
from eval.reports.transfer_report import fmt_score, ranks_markdown


def lengths_frame(parts: Sequence[tuple[int | None, SuiteRun]]) -> pd.DataFrame:
    """The long frames of each length's runs with a ``length`` column (:func:`eval.reports.lengths.length_label`)."""
    frames = [long_frame(run).assign(length=length_label(n)) for n, run in parts]
    frames = [f for f in frames if not f.empty]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _label(metric: str) -> str:
    return {m.name: m.label for m in TRANSFER_METRICS}.get(metric, metric)


def report_lengths(parts: Sequence[tuple[int | None, SuiteRun]], results_dir: str | Path, command: str,
                   figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """Write the length sweep's report (module docstring) into ``results_dir``; returns the files written."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    frame = lengths_frame(parts)
    if frame.empty:
        frame = pd.DataFrame(columns=["length", "sequence", "method", "metric", "value"])
    ranks = length_ranks(frame)
    agreement = length_agreement(ranks)
    settling = settling_lengths(ranks)
    bench = shortest_agreeing_length(agreement)
    lengths = length_order(ranks["length"].unique()) if not ranks.empty else []
    csv = results_dir / "lengths.csv"
    ranks.to_csv(csv, index=False, float_format="%.6g")
    agreement_csv = results_dir / "lengths_agreement.csv"
    agreement.to_csv(agreement_csv, index=False, float_format="%.6g")
    figure = save_transfer_figure(ranks.rename(columns={"length": "domain"}), results_dir / f"lengths.{figure_format}",
                                  lengths, TRANSFER_METRICS) if not ranks.empty else None  # fmt: skip
    decisive = " and ".join(_label(m) for m in DECISIVE_METRICS)
    if WHOLE not in lengths:
        verdict = "No whole-sequence runs: there is no reference ranking to compare the lengths with."
    elif bench is None:
        verdict = f"No length ranks the methods as whole sequences do on {decisive}."
    else:
        verdict = (f"The shortest length that ranks the methods as whole sequences do on {decisive}: **{bench}"
                   f"{' frames' if bench != WHOLE else ' sequences'}**.")  # fmt: skip
    text = [
        "# Length sweep: how long must a run be for its verdict to be the whole sequences'?\n",
        f"Made by `{command}`. Per length, a method's score is the median over each cell's runs, then the mean over "
        "the sequences (Table 1's Avg. row); rank 1 is best; only methods scored at every length are ranked. "
        "Kendall's tau-b and Spearman's rho compare each length's ranking with the whole sequences' "
        "(`eval/reports/lengths.py`): +1 the same order; 'same' means identical ranks. A sequence shorter than a "
        "length runs whole at that length.\n",
        "## Verdict\n",
        verdict + "\n",
        "## Agreement with the whole sequences\n",
        "| metric | length | n | Kendall tau | Spearman rho | same ranking |",
        "|---|---|---:|---:|---:|---|",
        *[f"| {_label(r.metric)} | {r.length} | {r.n} | {fmt_score(r.kendall)} | {fmt_score(r.spearman)} | "
          f"{'yes' if r.same else 'no'} |" for r in agreement.itertuples()],  # fmt: skip
        "\n## Where each method's rank settles\n",
        "The shortest length from which the method's rank equals its whole-sequence rank at every longer length.\n",
        *_settling_markdown(settling, lengths),
        "\n## Scores and ranks per metric: score (rank)\n",
        ranks_markdown(ranks.rename(columns={"length": "domain"}), lengths) if not ranks.empty else "",
        *([markdown_image(figure, "ranks per length", results_dir)] if figure is not None else []),
        *[f"## Runs at {length_label(n)} {'frames' if n is not None else 'sequences'}\n"
          + status_markdown(run).removeprefix("## Runs\n") for n, run in parts],  # fmt: skip
    ]
    md = results_dir / "lengths.md"
    md.write_text("\n".join(text))
    page = markdown_page("\n".join(text[1:]), results_dir, "lengths", text[0].strip("# \n"))
    return [md, page, csv, agreement_csv, *([figure] if figure is not None else [])]


def _settling_markdown(settling: pd.DataFrame, lengths: Sequence[str]) -> list[str]:
    if settling.empty:
        return ["(no ranks)"]
    out = ["| metric | method | " + " | ".join(f"rank at {x}" for x in lengths) + " | settles at |",
           "|---|---|" + "---:|" * len(lengths) + "---|"]  # fmt: skip
    for r in settling.itertuples(index=False):
        row = r._asdict()
        ranks = [f"{row.get(f'rank_{x}', np.nan):g}" for x in lengths]
        out.append(f"| {_label(row['metric'])} | {row['method']} | " + " | ".join(ranks) + f" | {row['settles_at']} |")
    return out
