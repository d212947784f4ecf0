"""``transfer.{md,html,csv,png}``: the transfer suite's report (the numbers come from :mod:`eval.reports.transfer`).

Like for like: each length (the bench length, whole sequences) is compared within itself, the simulated sequences
against the real ones cut into windows of that length (:func:`eval.bench.suites.transfer_parts`).

- ``transfer.md``: per length and metric, each method's score and rank in every domain side by side; the rank
  correlations (Spearman, Kendall, n methods, p, the samples on each side and a bootstrap interval of rho) of every
  simulated domain with every real one; which camera preset predicts the real rankings best; how each part was
  made and the state of its runs;
- ``transfer.csv``: domain, metric, method, score, rank, sequences, runs, length;
- ``transfer_correlations.csv``: the correlation table, with where each coefficient falls in the like-for-like
  null distribution (``null_*``, ``null_percentile``; :func:`eval.reports.transfer.null_agreement`);
- ``transfer_null.csv``: that null distribution per length, simulated domain and metric;
- ``transfer_recordings.csv``: how many real recordings a target needs
  (:func:`eval.reports.transfer.holdout_agreement`), per length, simulated domain, metric and k;
- ``transfer_runs.csv``: every run behind the figures (length, domain, sequence, method, seed, metric, value), so
  that anyone can recompute them from the committed file;
- ``transfer.png``: per metric, each method's rank in every domain and length (a bump chart; the report's figure
  format, ``--figure-format``);
- ``transfer.html``: the Markdown rendered as one self-contained page, tables sortable, figure inline.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from eval.reports.html_report import markdown_page
from eval.reports.inputs import SuiteRun, TransferPart
from eval.reports.plots import save_transfer_figure
from eval.reports.report_parts import long_frame, markdown_image, status_markdown
from eval.reports.style import DEFAULT_FIGURE_FORMAT
from eval.reports.tables import FAILURE_EVIDENCE
from eval.reports.transfer import (
    ALL_METRICS,
    BOOTSTRAP_DRAWS,
    REAL_PREFIX,
    TRANSFER_METRICS,
    TRANSFER_TARGET,
    WINDOW_PREFIX,
    best_predictor,
    bootstrap_correlations,
    domain_scores,
    holdout_agreement,
    null_agreement,
    rank_correlations,
    rank_methods,
)


def transfer_frame(parts: Sequence[tuple[TransferPart, SuiteRun]]) -> pd.DataFrame:
    """The long frames of the parts' runs with a ``domain`` column (each sequence's, :class:`TransferPart`) and a
    ``length`` column (``"whole"`` or the number of frames, as text)."""
    frames = []
    for part, run in parts:
        frame = long_frame(run)
        if frame.empty:
            continue
        domains = dict(part.domains)
        frame = frame.assign(domain=frame["sequence"].map(domains), length=_length_label(part.length))
        frames.append(frame[frame["domain"].notna()])
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _length_label(length: int | None) -> str:
    return "whole" if length is None else str(int(length))


def fmt_score(value: float) -> str:
    """A score as the ranking reports print it: 3 significant digits, whole numbers from 100, ``-`` when not finite."""
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
                cells.append("-" if row.empty else f"{fmt_score(row['score'].iloc[0])} ({row['rank'].iloc[0]:g})")
            out.append(f"| {method} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def correlations_markdown(corr: pd.DataFrame) -> str:
    """The correlation table, one row per (length, simulated domain, real domain, metric): n methods, the samples
    on each side, Spearman's rho with p and its bootstrap interval, Kendall's tau with p."""
    labels = {m.name: m.label for m in TRANSFER_METRICS}
    lines = ["| length | simulated | real | metric | n | samples sim / real | Spearman rho (p) | 95 % interval | "
             "Kendall tau (p) | null: one more simulated recording, median [10th pct, quartiles] | percentile |",
             "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    for row in corr.itertuples():
        rho = "-" if not np.isfinite(row.spearman) else f"{row.spearman:+.2f} ({row.spearman_p:.2f})"
        tau = "-" if not np.isfinite(row.kendall) else f"{row.kendall:+.2f} ({row.kendall_p:.2f})"
        ci = "-" if not np.isfinite(row.rho_low) else f"[{row.rho_low:+.2f}, {row.rho_high:+.2f}]"
        samples = f"{row.sim_samples:.0f} / {row.real_samples:.0f}" if np.isfinite(row.sim_samples) else "-"
        med = getattr(row, "null_median", np.nan)
        null = "-" if not np.isfinite(med) else (f"{med:+.2f} [{row.null_q10:+.2f}; {row.null_q25:+.2f}, "
                                                 f"{row.null_q75:+.2f}]")  # fmt: skip
        pct = getattr(row, "null_percentile", np.nan)
        pct = "-" if not np.isfinite(pct) else f"{pct:.0f}"
        lines.append(f"| {row.length} | {row.sim} | {row.real} | {labels.get(row.metric, row.metric)} | {row.n} | "
                     f"{samples} | {rho} | {ci} | {tau} | {null} | {pct} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def _part_line(part: TransferPart, run: SuiteRun) -> str:
    suite = run.suite
    frames = "whole sequences" if suite.frames is None else f"first {suite.frames} frames"
    revisions = sorted({str(r.metadata.get("git_revision")) for r in run.records}) or ["-"]
    domains: dict[str, list[str]] = {}
    for name, domain in part.domains:
        domains.setdefault(domain, []).append(name)
    seqs = "; ".join(f"`{d}`: {', '.join(names)}" for d, names in domains.items()) or "none"
    return (f"- suite `{suite.name}`, {frames}, {len(suite.seeds)} run(s) per cell (one for a method without a "
            f"seed), runs under `{run.out_root}/{suite.name}/`, revision {', '.join(revisions)}; {seqs}")


HELD_OUT = (1, 2, 3, 4)  # real recordings the table of what a target needs considers


def correlations_with_intervals(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per length of ``frame`` (:func:`transfer_frame`): the ranks (:func:`eval.reports.transfer.rank_methods` over that
    length's domains) and the rank correlations with their bootstrap interval
    (:func:`eval.reports.transfer.bootstrap_correlations`) and their place in the like-for-like null distribution
    (:func:`eval.reports.transfer.null_agreement`: columns null_median, null_q10, null_q25, null_q75,
    null_percentile), each with a ``length`` column. A real domain is one recording (one folder), cut into windows
    or not, so it is compared with one simulated recording cut the same way."""
    ranks, corr, _, _ = transfer_tables(frame)
    return ranks, corr


def transfer_tables(frame: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """:func:`correlations_with_intervals`' ranks and correlations, the null distribution per length
    (:func:`eval.reports.transfer.null_agreement`) and what a target needs per length
    (:func:`eval.reports.transfer.holdout_agreement` for k in :data:`HELD_OUT`), each with a ``length`` column.
    The windows of the null (domains ``win:...``) are not ranked as domains of their own."""
    all_ranks, all_corr, all_null, all_needs = [], [], [], []
    for length, sub in frame.groupby("length", sort=False):
        plain = sub[~sub["domain"].astype(str).str.startswith(WINDOW_PREFIX)]
        scores = domain_scores(plain)
        if scores.empty:
            continue
        domains = list(dict.fromkeys(plain["domain"]))
        ranks = rank_methods(scores, domains=domains)
        pairs = ranks[["metric", "method"]].drop_duplicates()
        evidence = sub[sub["metric"].isin(FAILURE_EVIDENCE) & sub["method"].isin(pairs["method"])]
        # the same set of methods, with the rows that tell their failures (a failed cell ranks last there too)
        ranked = pd.concat([sub.merge(pairs, on=["metric", "method"]), evidence], ignore_index=True)
        plain_ranked = ranked[~ranked["domain"].astype(str).str.startswith(WINDOW_PREFIX)]
        corr = rank_correlations(ranks).merge(bootstrap_correlations(plain_ranked).drop(columns="n"),
                                              on=["sim", "real", "metric"], how="left")  # fmt: skip
        corr = corr.merge(_null_columns(ranked, corr), on=["sim", "real", "metric"], how="left")
        all_null.append(null_agreement(ranked, target=TRANSFER_TARGET).assign(length=length))
        all_needs.append(holdout_agreement(plain_ranked, HELD_OUT, target=TRANSFER_TARGET).assign(length=length))
        all_ranks.append(ranks.assign(length=length))
        all_corr.append(corr.assign(length=length))
    ranks = pd.concat(all_ranks, ignore_index=True) if all_ranks else pd.DataFrame(
        columns=["domain", "metric", "method", "score", "sequences", "runs", "rank", "length"])  # fmt: skip
    corr = pd.concat(all_corr, ignore_index=True) if all_corr else pd.DataFrame(
        columns=["sim", "real", "metric", "n", "spearman", "spearman_p", "kendall", "kendall_p", "methods",
                 "sim_samples", "real_samples", "rho_low", "rho_high", "defined", *_NULL_COLUMNS,
                 "length"])  # fmt: skip
    null = pd.concat(all_null, ignore_index=True) if all_null else pd.DataFrame(
        columns=["sim", "metric", "recordings", "windows", "n", "rho_median", "rho_q10", "rho_q25", "rho_q75",
                 "rho_min", "rho_max", "share_target", "length"])  # fmt: skip
    needs = pd.concat(all_needs, ignore_index=True) if all_needs else pd.DataFrame(
        columns=["sim", "metric", "held_out", "n", "splits", "rho_median", "rho_q25", "rho_q75", "share_target",
                 "length"])  # fmt: skip
    return ranks, corr, null, needs


_NULL_COLUMNS = ["null_median", "null_q10", "null_q25", "null_q75", "null_percentile"]


def _null_columns(ranked: pd.DataFrame, corr: pd.DataFrame) -> pd.DataFrame:
    """Per (sim, real, metric) of ``corr``: the like-for-like null distribution (median, 10th percentile,
    quartiles) and the percentile of the observed rho in it."""
    parts = []
    for real, observed in corr.groupby("real"):
        table = null_agreement(ranked, target=TRANSFER_TARGET, observed=observed)
        parts.append(table.assign(real=real).rename(columns={
            "rho_median": "null_median", "rho_q10": "null_q10", "rho_q25": "null_q25", "rho_q75": "null_q75",
            "observed_percentile": "null_percentile"}))  # fmt: skip
    if not parts:
        return pd.DataFrame(columns=["sim", "real", "metric", *_NULL_COLUMNS])
    return pd.concat(parts, ignore_index=True)[["sim", "real", "metric", *_NULL_COLUMNS]]


def null_markdown(null: pd.DataFrame) -> str:
    """The null distribution table: per (length, simulated domain, metric), how many simulated recordings played the
    real one and with how many windows, then rho's median [10th percentile; quartiles] (min .. max)."""
    if null.empty:
        return "No simulated domain has enough sequences for a null distribution.\n"
    labels = {m.name: m.label for m in TRANSFER_METRICS}
    lines = ["| length | simulated | metric | recordings x windows | n | rho: median [10th pct; quartiles] | range |",
             "|---|---|---|---:|---:|---:|---:|"]
    for row in null.itertuples():
        if not np.isfinite(row.rho_median):
            continue
        lines.append(f"| {row.length} | {row.sim} | {labels.get(row.metric, row.metric)} | {row.recordings} x "
                     f"{row.windows} | {row.n} | {row.rho_median:+.2f} [{row.rho_q10:+.2f}; {row.rho_q25:+.2f}, "
                     f"{row.rho_q75:+.2f}] | {row.rho_min:+.2f} .. {row.rho_max:+.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def recordings_markdown(needs: pd.DataFrame, target: float = TRANSFER_TARGET) -> str:
    """What a target needs: per (length, simulated domain, metric), the median [quartiles] of rho with k held-out
    sequences for each k, the share of splits reaching ``target``, and the fewest recordings whose median reaches
    it."""
    if needs.empty:
        return "No simulated domain has enough sequences to hold any out.\n"
    labels = {m.name: m.label for m in TRANSFER_METRICS}
    ks = sorted(int(k) for k in needs["held_out"].unique())
    lines = ["| length | simulated | metric | n | " + " | ".join(f"k = {k}" for k in ks)
             + f" | recordings for a median >= {target:g} |", "|---|---|---|---:|" + "---:|" * (len(ks) + 1)]
    for (length, sim, metric), sub in needs.groupby(["length", "sim", "metric"], sort=False):
        sub = sub.set_index("held_out")
        if metric == ALL_METRICS:  # only the share of splits where every metric reaches the target
            cells = [f"({100 * sub.loc[k, 'share_target']:.0f} %)" if k in sub.index else "-" for k in ks]
            reach = [k for k in ks if k in sub.index and sub.loc[k, "share_target"] >= 0.5]
            lines.append(f"| {length} | {sim} | every metric at once | {int(sub['n'].iloc[0])} | " + " | ".join(cells)
                         + f" | {reach[0] if reach else f'more than {max(ks)}'} (in half the splits) |")  # fmt: skip
            continue
        cells = []
        for k in ks:
            if k not in sub.index or not np.isfinite(sub.loc[k, "rho_median"]):
                cells.append("-")
                continue
            r = sub.loc[k]
            cells.append(f"{r.rho_median:+.2f} [{r.rho_q25:+.2f}, {r.rho_q75:+.2f}] ({100 * r.share_target:.0f} %)")
        reach = [k for k in ks if k in sub.index and sub.loc[k, "rho_median"] >= target - 1e-12]
        need = str(reach[0]) if reach else f"more than {max(ks)}"
        lines.append(f"| {length} | {sim} | {labels.get(metric, metric)} | {int(sub['n'].iloc[0])} | "
                     + " | ".join(cells) + f" | {need} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def _dropped_line(frame: pd.DataFrame, ranks: pd.DataFrame) -> str:
    """Which methods a length's rankings leave out (no finite score on some sequence or window of a domain, and no
    failure there: a failed run ranks last instead)."""
    if frame.empty:
        return ""
    out = []
    for length, sub in frame.groupby("length", sort=False):
        ranked = set(ranks.loc[ranks["length"] == length, "method"]) if not ranks.empty else set()
        dropped = sorted(set(sub["method"]) - ranked)
        if dropped:
            out.append(f"at length {length}: {', '.join(dropped)}")
    return ("Left out of the rankings (a sequence or window without a finite score that is no failure, e.g. a figure "
            "the method does not report; a failed run ranks last instead): "
            + "; ".join(out) + ".\n") if out else ""


def report_transfer(parts: Sequence[tuple[TransferPart, SuiteRun]], results_dir: str | Path,
                    command: str, figure_format: str = DEFAULT_FIGURE_FORMAT) -> list[Path]:
    """Write the transfer report (module docstring) into ``results_dir``; returns the files written."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    frame = transfer_frame(parts)
    ranks, corr, null, needs = transfer_tables(frame if not frame.empty else pd.DataFrame(
        columns=["domain", "sequence", "method", "metric", "value", "length"]))  # fmt: skip
    best = best_predictor(corr)
    csv = results_dir / "transfer.csv"
    ranks.to_csv(csv, index=False, float_format="%.6g")
    corr_csv = results_dir / "transfer_correlations.csv"
    corr.to_csv(corr_csv, index=False, float_format="%.6g")
    null_csv = results_dir / "transfer_null.csv"
    null.to_csv(null_csv, index=False, float_format="%.6g")
    needs_csv = results_dir / "transfer_recordings.csv"
    needs.to_csv(needs_csv, index=False, float_format="%.6g")
    runs_csv = results_dir / "transfer_runs.csv"
    run_columns = [c for c in ("length", "domain", "sequence", "method", "seed", "metric", "value") if c in frame]
    runs = frame[frame["metric"].isin([m.name for m in TRANSFER_METRICS])][run_columns] if not frame.empty \
        else pd.DataFrame(columns=run_columns)  # fmt: skip
    runs.to_csv(runs_csv, index=False, float_format="%.6g")
    columns = [f"{d} ({length})" for length, d in dict.fromkeys(zip(ranks["length"], ranks["domain"], strict=True))]
    wide = ranks.assign(domain=ranks["domain"] + " (" + ranks["length"] + ")")
    figure = save_transfer_figure(wide, results_dir / f"transfer.{figure_format}", columns, TRANSFER_METRICS) \
        if not ranks.empty else None  # fmt: skip
    reals = [d for d in ranks["domain"].unique() if str(d).startswith(REAL_PREFIX)] if not ranks.empty else []
    verdict = ("No real sequence was available (list folders in datasets.toml or $CNNSLAM_DATASETS): there is "
               "nothing to compare the simulated rankings with." if not reals else
               "No rank correlation is defined (fewer than 3 methods ranked in both domains)." if best is None else
               f"The simulated domain whose rankings agree best with the real ones: **{best[0]}** (mean Spearman "
               f"rho {best[1]:+.2f} over the metrics, lengths and real sequences).")  # fmt: skip
    text = [
        "# Sim-to-real transfer: do the simulated sequences rank the methods as real ones do?\n",
        f"Made by `{command}`. Like for like: whole simulated sequences against whole real ones, and the bench "
        "length against real sequences cut into non-overlapping windows of that length (each window a sample). "
        "Per domain and length, a method's score is the median over each cell's runs, then the mean over the "
        "domain's sequences (or windows); rank 1 is best; only methods scored in every domain of a length are "
        "ranked (the suite's default methods leave out the oracle, which is fed ground truth and would win every "
        "ranking). Spearman's rho and Kendall's tau-b compare each simulated domain's ranking with each real one "
        "(`eval/reports/transfer.py`): +1 the same order, -1 the reverse; n is the number of methods ranked, and p "
        "scipy's two-sided value (below 0.05 only for rho >= 0.9 at n = 5). The interval is a 95 % percentile "
        f"bootstrap over the simulated sequences and the real windows, {BOOTSTRAP_DRAWS} draws, each side "
        "resampled with replacement (a side with one sample, such as one whole real sequence, is not "
        "resampled); windows cut from one recording share its room, camera and operator, so they are not "
        "independent samples and the interval is narrower than one over independent sequences would be.\n",
        _dropped_line(frame, ranks),
        "Parts:\n",
        *[_part_line(part, run) for part, run in parts],
        "\n## Verdict\n",
        verdict + "\n",
        "## Rank correlation, simulated against real\n",
        "The last two columns read each coefficient against the null distribution (next section): what one more "
        "simulated recording, cut as the real one is, scores against the simulator, and the percentile of the "
        "observed rho in it (50: the real recording ranks the methods as typically as one more simulated recording "
        "would; near 0: a sim-to-real gap beyond the sampling of one recording; an observed rho may lie above the "
        "whole null: it is a null distribution, not a ceiling).\n",
        correlations_markdown(corr),
        "## The null distribution: one more simulated recording\n",
        "If the real world were the simulator, a real recording would be one more simulated sequence, and its "
        "ranking would differ from the simulator's only by the methods' spread from sequence to sequence. Like for "
        "like with the real side: each simulated sequence in turn is cut into as many windows of the length as the "
        "real recording gives (domain `win:...`; whole sequences: the sequence itself) and its ranking (the mean "
        "over its windows) is compared with the simulated domain's ranking over all its sequences "
        "(`eval.reports.transfer.null_agreement`). Spearman's rho over the simulated recordings: median [10th "
        "percentile; quartiles] and range. The per-run figures behind it are in `transfer_runs.csv`.\n",
        null_markdown(null),
        "## How many real recordings a target needs\n",
        "The simulator against itself: the ranking on k held-out simulated sequences against the ranking on the "
        "others, over every split (`eval.reports.transfer.holdout_agreement`), as median [quartiles] (share of "
        f"splits reaching {TRANSFER_TARGET:g}); the last column is the fewest recordings whose median rho reaches "
        f"{TRANSFER_TARGET:g}. The row 'every metric at once' gives the share of splits in which all the metrics "
        f"reach {TRANSFER_TARGET:g} together. Windows cut from one recording are one recording here: they share "
        "its room, camera and operator.\n",
        recordings_markdown(needs),
        "## Scores and ranks per metric: score (rank)\n",
        *[f"\n### Length: {length}\n" + ranks_markdown(sub, list(dict.fromkeys(sub["domain"])))
          for length, sub in ranks.groupby("length", sort=False)],  # fmt: skip
        *([markdown_image(figure, "ranks per domain", results_dir)] if figure is not None else []),
        *[f"## Runs of `{run.suite.name}`, {_length_label(part.length)}\n"
          + status_markdown(run).removeprefix("## Runs\n") for part, run in parts],  # fmt: skip
    ]
    md = results_dir / "transfer.md"
    md.write_text("\n".join(text))
    page = markdown_page("\n".join(text[1:]), results_dir, "transfer", text[0].strip("# \n"))
    return [md, page, csv, corr_csv, null_csv, needs_csv, runs_csv, *([figure] if figure is not None else [])]
