"""``transfer.{md,csv,png}``: the transfer suite's report (the numbers come from :mod:`eval.transfer`).

- ``transfer.md``: per metric, each method's score and rank in every domain side by side; the rank correlations
  (Spearman, Kendall, n methods, p) of every simulated domain with every real one; which camera preset predicts
  the real rankings best; how each part was made and the state of its runs;
- ``transfer.csv``: domain, metric, method, score, rank, sequences, runs;
- ``transfer_correlations.csv``: the correlation table;
- ``transfer.png``: per metric, each method's rank in every domain (a bump chart).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from eval.plots import save_transfer_figure
from eval.reports import long_frame, status_markdown
from eval.runner import SuiteRun
from eval.transfer import (
    REAL_PREFIX,
    TRANSFER_METRICS,
    best_predictor,
    domain_scores,
    rank_correlations,
    rank_methods,
)


def transfer_frame(parts: Sequence[tuple[str, SuiteRun]]) -> pd.DataFrame:
    """The long frames of the parts' runs with a ``domain`` column: the part's domain (``sim:<preset>``), or
    ``real:<sequence>`` for each sequence of the ``real`` part."""
    frames = []
    for domain, run in parts:
        frame = long_frame(run)
        if frame.empty:
            continue
        frame = frame.assign(domain=REAL_PREFIX + frame["sequence"] if domain == "real" else domain)
        frames.append(frame)
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _fmt(value: float) -> str:
    if not np.isfinite(value):
        return "-"
    return f"{value:.3g}" if abs(value) < 100 else f"{value:.0f}"


def ranks_markdown(ranks: pd.DataFrame, domains: Sequence[str]) -> str:
    """One table per metric: method x domain, cells ``score (rank)``."""
    out = []
    for metric in TRANSFER_METRICS:
        sub = ranks[ranks["metric"] == metric.name]
        if sub.empty:
            continue
        better = "higher" if metric.higher_is_better else "lower"
        out += [f"\n### {metric.label} ({better} is better)\n", "| method | " + " | ".join(domains) + " |",
                "|---|" + "---:|" * len(domains)]  # fmt: skip
        order = sub[sub["domain"] == domains[-1]].sort_values("rank")["method"].tolist()
        order += sorted(set(sub["method"]) - set(order))
        for method in order:
            cells = []
            for domain in domains:
                row = sub[(sub["method"] == method) & (sub["domain"] == domain)]
                cells.append("-" if row.empty else f"{_fmt(row['score'].iloc[0])} ({row['rank'].iloc[0]:g})")
            out.append(f"| {method} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def correlations_markdown(corr: pd.DataFrame) -> str:
    """The correlation table, one row per (simulated domain, real domain, metric)."""
    labels = {m.name: m.label for m in TRANSFER_METRICS}
    lines = ["| simulated | real | metric | n | Spearman rho (p) | Kendall tau (p) |", "|---|---|---|---:|---:|---:|"]
    for row in corr.itertuples():
        rho = "-" if not np.isfinite(row.spearman) else f"{row.spearman:+.2f} ({row.spearman_p:.2f})"
        tau = "-" if not np.isfinite(row.kendall) else f"{row.kendall:+.2f} ({row.kendall_p:.2f})"
        lines.append(f"| {row.sim} | {row.real} | {labels.get(row.metric, row.metric)} | {row.n} | {rho} | {tau} |")
    return "\n".join(lines) + "\n"


def _part_line(domain: str, run: SuiteRun) -> str:
    suite = run.suite
    frames = "whole sequences" if suite.frames is None else f"first {suite.frames} frames"
    revisions = sorted({str((r.get("metadata") or {}).get("git_revision")) for r in run.records}) or ["-"]
    seqs = ", ".join(s.name for s in suite.sequences) or "none"
    return (f"- `{domain}`: suite `{suite.name}`, {frames}, {len(suite.seeds)} run(s) per cell (one for a method "
            f"without a seed), runs under "
            f"`{run.out_root}/{suite.name}/`, revision {', '.join(revisions)}; sequences: {seqs}")  # fmt: skip


def report_transfer(parts: Sequence[tuple[str, SuiteRun]], results_dir: str | Path, command: str) -> list[Path]:
    """Write the transfer report (module docstring) into ``results_dir``; returns the files written."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    frame = transfer_frame(parts)
    scores = domain_scores(frame) if not frame.empty else pd.DataFrame(
        columns=["domain", "metric", "method", "score", "sequences", "runs"])  # fmt: skip
    domains = list(dict.fromkeys(frame["domain"])) if not frame.empty else []
    ranks = rank_methods(scores, domains=domains) if not scores.empty else scores.assign(rank=[])
    corr = rank_correlations(ranks)
    best = best_predictor(corr)
    csv = results_dir / "transfer.csv"
    ranks.to_csv(csv, index=False, float_format="%.6g")
    corr_csv = results_dir / "transfer_correlations.csv"
    corr.to_csv(corr_csv, index=False, float_format="%.6g")
    figure = save_transfer_figure(ranks, results_dir / "transfer.png", domains, TRANSFER_METRICS) \
        if not ranks.empty else None  # fmt: skip
    reals = [d for d in domains if d.startswith(REAL_PREFIX)]
    verdict = ("No real sequence was available (list folders in datasets.toml or $CNNSLAM_DATASETS): there is "
               "nothing to compare the simulated rankings with." if not reals else
               "No rank correlation is defined (fewer than 3 methods ranked in both domains)." if best is None else
               f"The simulated domain whose rankings agree best with the real ones: **{best[0]}** (mean Spearman "
               f"rho {best[1]:+.2f} over the metrics and real sequences).")  # fmt: skip
    text = [
        "# Sim-to-real transfer: do the simulated sequences rank the methods as real ones do?\n",
        f"Made by `{command}`. Per domain, a method's score is the median over each cell's runs, then the mean "
        "over the domain's sequences; rank 1 is best; only methods scored in every domain are ranked (the suite's "
        "default methods leave out the oracle, which is fed ground truth and would win every ranking). "
        "Spearman's rho and Kendall's tau-b compare each simulated domain's ranking with each real one "
        "(`eval/transfer.py`): +1 the same order, -1 the reverse. "
        "With 5 methods a ranking has only 120 orders: read the coefficients as agreement (p, scipy's two-sided, "
        "is below 0.05 only for rho >= 0.9 at n = 5).\n",
        "Parts:\n",
        *[_part_line(domain, run) for domain, run in parts],
        "\n## Verdict\n",
        verdict + "\n",
        "## Rank correlation, simulated against real\n",
        correlations_markdown(corr),
        "## Scores and ranks per metric: score (rank)\n",
        ranks_markdown(ranks, domains),
        *([f"![ranks per domain]({figure.name})\n"] if figure is not None else []),
        *[f"## Runs of `{domain}`\n" + status_markdown(run).removeprefix("## Runs\n") for domain, run in parts],
    ]
    md = results_dir / "transfer.md"
    md.write_text("\n".join(text))
    return [md, csv, corr_csv, *([figure] if figure is not None else [])]
