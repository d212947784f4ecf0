"""Sim-to-real transfer of a benchmark's verdicts: do the simulated sequences rank the methods as real ones do?

The question every user of a synthetic benchmark should ask (``cnnslam bench transfer``). Runs are grouped into
**domains**: the simulated Table-1 analogues under one camera preset (``sim:clean``, ``sim:kinect``, ...), and each
real RGB-D folder (``real:<name>``). Per domain, metric and method:

- **score** (:func:`domain_scores`): the median over a cell's runs (its seeds), then the mean over the domain's
  sequences (the Avg. row of Table 1); a method missing a sequence of the domain gets no score there; a **failed**
  cell (at least half its runs failures by the one rule, :func:`eval.metrics.results.failure_of`: never
  initialised, or tracked less than 90 % of its frames; :func:`eval.reports.tables.cell_failures`) makes the
  method *failed* in that domain, and a failed run counts in no median;
- **rank** (:func:`rank_methods`): 1 = best, in the metric's direction (:data:`TRANSFER_METRICS`), ties share the
  mean rank (``scipy.stats.rankdata``), over the methods that have a score or failed in every domain compared; a
  method failed in a domain ranks last there, below every scored method, the failed methods tied (sharing the
  mean of the last ranks), so a simulator whose failures are the real ones' agrees with it; the resampled and
  held-out rankings below rank a failed cell last the same way (:func:`failures_ranked_last`);
- **agreement** (:func:`rank_correlations`): Spearman's rho and Kendall's tau-b (``scipy.stats``) between each
  simulated domain's ranks and each real domain's, with the number of methods n and the two-sided p-values (with
  n = 5 methods, scipy's p is below 0.05 only for rho >= 0.9: read the figures as agreement, not significance);
- **which camera predicts real data best** (:func:`best_predictor`): the simulated domain with the highest mean
  Spearman rho over the metrics and real domains;
- **the null distribution** (:func:`null_agreement`): what one more simulated recording scores against the
  simulator, like for like with a real one: the ranking on one simulated sequence's windows (as many windows of that
  length as the real recording gives; domain ``win:<preset>``) against the simulated domain's ranking over all its
  sequences, for every simulated sequence in turn. A sim-to-real rho is read against it as a percentile: near 0, a gap
  beyond the sampling of one recording; the observed rho may lie above it (a null distribution, not a ceiling);
- **how many recordings a target needs** (:func:`holdout_agreement`): the simulator against itself, k of its
  sequences held out against the others, for k = 1, 2, ...: the share of splits reaching a target, for every metric
  at once too.

Methods fed ground truth (the oracle) are left out of the rankings: they win by construction. The numeric core
does no I/O; :mod:`eval.reports.suite_reports` writes ``transfer.{md,csv,png}``.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from eval.errors import EvalError
from eval.metrics import catalogue
from eval.reports.tables import cell_failures, without_failures

SIM_PREFIX, REAL_PREFIX, WINDOW_PREFIX = "sim:", "real:", "win:"
_WINDOW_SUFFIX = re.compile(r"\.from\d+$")


def recording_of(sequence: str) -> str:
    """The recording a window belongs to: ``office0.from200`` -> ``office0`` (a sequence is its own first window)."""
    return _WINDOW_SUFFIX.sub("", str(sequence))


@dataclass(frozen=True)
class TransferMetric:
    """A metric whose ranking is compared: its long-frame name, a label, and whether higher is better."""

    name: str
    label: str
    higher_is_better: bool


def transfer_metrics(place: str) -> tuple[TransferMetric, ...]:
    """The metrics the catalogue shows at ``place`` (:mod:`eval.metrics.catalogue`), as :class:`TransferMetric`."""
    return tuple(TransferMetric(s.key, s.label_at(place), s.higher_is_better) for s in catalogue.shown_at(place))


TRANSFER_METRICS: tuple[TransferMetric, ...] = transfer_metrics(catalogue.TRANSFER)


FRAME_COLUMNS = ("domain", "sequence", "method", "metric", "value")  # a transfer frame: one row per run and metric


def _check_frame(frame: pd.DataFrame) -> None:
    """One clear error when ``frame`` lacks a column of :data:`FRAME_COLUMNS`."""
    if missing := set(FRAME_COLUMNS) - set(frame.columns):
        raise EvalError(f"a transfer frame needs columns {sorted(FRAME_COLUMNS)}; missing {sorted(missing)}")


def domain_scores(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS) -> pd.DataFrame:
    """Scores per (domain, metric, method) from a long frame of runs.

    frame: columns ``domain``, ``sequence``, ``method``, ``metric``, ``value`` (one row per run and metric, as
    :func:`eval.metrics.results.runs_frame` gives, plus the domain; with a ``run`` column and the runs' tracked
    share / pose-pair rows, failures are told). Returns columns domain, metric, method, score, sequences (how many
    the score averages), runs, failed: the median over each cell's runs that did not fail, then the mean over the
    domain's sequences; a method lacking a finite value on one of the domain's sequences gets no row, unless that
    cell failed (:func:`eval.reports.tables.cell_failures`): then its row says ``failed`` True, score NaN (it ranks
    last, :func:`rank_methods`).
    """
    _check_frame(frame)
    names = [m.name for m in metrics]
    failed_cells: set[tuple[str, str, str]] = set()
    if "run" in frame.columns and not frame.empty:
        for domain, part in frame.groupby("domain", sort=False):
            failures = cell_failures(part)
            failed_cells |= {(str(domain), s, m) for (s, m), f in failures.items() if f.is_failure}
        frame = pd.concat([without_failures(part) for _, part in frame.groupby("domain", sort=False)])
    sub = frame[frame["metric"].isin(names)]
    cells = (sub.groupby(["domain", "metric", "method", "sequence"])["value"]
             .agg(median="median", runs="count").reset_index())  # fmt: skip
    cells = cells[np.isfinite(cells["median"])]
    n_seq = sub.groupby("domain")["sequence"].nunique()
    out = cells.groupby(["domain", "metric", "method"]).agg(
        score=("median", "mean"), sequences=("sequence", "nunique"), runs=("runs", "sum")
    ).reset_index()
    out = out[out["sequences"] == out["domain"].map(n_seq)].assign(failed=False)
    if failed_cells:
        pairs = sorted({(d, method) for d, _, method in failed_cells})
        failed = pd.DataFrame([{"domain": d, "metric": m.name, "method": method, "score": math.nan,
                                "sequences": sum(1 for c in failed_cells if c[0] == d and c[2] == method),
                                "runs": 0, "failed": True} for d, method in pairs for m in metrics])  # fmt: skip
        keep = out.merge(failed[["domain", "metric", "method"]], how="left", indicator=True)
        out = pd.concat([keep[keep["_merge"] == "left_only"].drop(columns="_merge"), failed], ignore_index=True)
        out["sequences"] = out["sequences"].astype(int)
        out["runs"] = out["runs"].astype(int)
    return out.sort_values(["metric", "domain", "method"], ignore_index=True)


FAILED_RUN = "failed"  # the run id of the rows :func:`failures_ranked_last` puts in place of a failed cell's runs


def failures_ranked_last(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS) -> pd.DataFrame:
    """``frame`` (as :func:`domain_scores` takes it) for the resampling and held-out rankings: failed runs removed
    (:func:`eval.reports.tables.without_failures`, per domain) and each failed cell (:func:`eval.reports.tables.
    cell_failures`) one run per metric of ``metrics`` (run :data:`FAILED_RUN`) with a value worse than any finite one
    of that metric in ``frame`` by more than ``(1 + 10 x the largest magnitude) x the most sequences of a domain``,
    so that any mean over sequences that includes a failed cell ranks after every mean that does not. Without a
    ``run`` column, ``frame`` as it is."""
    if "run" not in frame.columns or frame.empty:
        return frame
    kept, added = [], []
    most = int(frame.groupby("domain")["sequence"].nunique().max())
    for domain, part in frame.groupby("domain", sort=False):
        failures = cell_failures(part)
        kept.append(without_failures(part, failures))
        for (sequence, method), info in failures.items():
            if info.is_failure:
                added += [{"domain": domain, "sequence": sequence, "method": method, "run": FAILED_RUN,
                           "metric": m.name} for m in metrics]  # fmt: skip
    out = pd.concat(kept, ignore_index=True)
    if not added:
        return out
    worse = {}
    for m in metrics:
        values = pd.to_numeric(frame.loc[frame["metric"] == m.name, "value"], errors="coerce").to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        big = float(np.abs(values).max()) if values.size else 1.0
        step = (1.0 + 10.0 * big) * max(most, 1)
        worse[m.name] = (float(values.min()) - step if values.size else -step) if m.higher_is_better \
            else (float(values.max()) + step if values.size else step)  # fmt: skip
    failed = pd.DataFrame(added).assign(value=lambda f: f["metric"].map(worse))
    return pd.concat([out, failed], ignore_index=True)


def failed_cells(frame: pd.DataFrame) -> pd.Series:
    """(domain, metric, method, sequence) -> whether that cell failed, for the cells of ``frame`` as
    :func:`failures_ranked_last` returns it (its stand-in rows, run :data:`FAILED_RUN`; all False without a ``run``
    column). A mean over sequences that holds a failed cell fails the method there: it ranks last, tied with the
    other failures, as :func:`rank_methods` ranks a domain's failures."""
    flag = frame["run"] == FAILED_RUN if "run" in frame.columns else pd.Series(False, index=frame.index)
    return flag.groupby([frame[c] for c in ("domain", "metric", "method", "sequence")]).any()


def rank_methods(scores: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS,
                 domains: Sequence[str] | None = None) -> pd.DataFrame:
    """``scores`` (:func:`domain_scores`) with a ``rank`` column: 1 = best in each (domain, metric), ties sharing
    their mean rank, over the methods scored or failed in every one of ``domains`` (default: all domains) for that
    metric, so that every domain ranks the same set; a failed method (``failed`` True) ranks after every scored one,
    the failed methods of a domain tied. Rows of other methods are dropped."""
    direction = {m.name: m.higher_is_better for m in metrics}
    domains = list(domains) if domains is not None else sorted(scores["domain"].unique())
    if "failed" not in scores.columns:
        scores = scores.assign(failed=False)
    parts = []
    for metric, group in scores[scores["domain"].isin(domains)].groupby("metric"):
        per_method = group.groupby("method")["domain"].nunique()
        common = set(per_method[per_method == len(domains)].index)
        group = group[group["method"].isin(common)].copy()
        sign = -1.0 if direction.get(str(metric), False) else 1.0
        key = np.where(group["failed"].to_numpy(dtype=bool), np.inf, sign * group["score"].to_numpy(dtype=float))
        group["rank"] = pd.Series(key, index=group.index).groupby(group["domain"]).transform(
            lambda s: stats.rankdata(s.to_numpy()))  # fmt: skip
        parts.append(group)
    if not parts:
        return scores.iloc[0:0].assign(rank=pd.Series(dtype=float))
    return pd.concat(parts, ignore_index=True).sort_values(["metric", "domain", "rank"], ignore_index=True)


def _correlation(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float]:
    """Spearman rho and p, Kendall tau-b and p of two rankings (NaN where undefined, e.g. a constant ranking)."""
    if len(a) < 3 or np.ptp(a) == 0 or np.ptp(b) == 0:
        return math.nan, math.nan, math.nan, math.nan
    rho, p_rho = stats.spearmanr(a, b)
    tau, p_tau = stats.kendalltau(a, b)
    return float(rho), float(p_rho), float(tau), float(p_tau)


def rank_correlations(ranks: pd.DataFrame) -> pd.DataFrame:
    """Spearman and Kendall agreement between every simulated domain (``sim:...``) and every real one (``real:...``)
    per metric, over the methods both rank. Columns: sim, real, metric, n (methods), spearman, spearman_p, kendall,
    kendall_p, methods (comma-separated)."""
    rows = []
    sims = sorted(d for d in ranks["domain"].unique() if d.startswith(SIM_PREFIX))
    reals = sorted(d for d in ranks["domain"].unique() if d.startswith(REAL_PREFIX))
    for metric, group in ranks.groupby("metric", sort=True):
        wide = group.pivot_table(index="method", columns="domain", values="rank")
        for sim in sims:
            for real in reals:
                if sim not in wide or real not in wide:
                    continue
                both = wide[[sim, real]].dropna()
                rho, p_rho, tau, p_tau = _correlation(both[sim].to_numpy(), both[real].to_numpy())
                rows.append({"sim": sim, "real": real, "metric": metric, "n": len(both), "spearman": rho,
                             "spearman_p": p_rho, "kendall": tau, "kendall_p": p_tau,
                             "methods": ", ".join(both.index)})  # fmt: skip
    return pd.DataFrame(rows, columns=["sim", "real", "metric", "n", "spearman", "spearman_p", "kendall",
                                       "kendall_p", "methods"])  # fmt: skip


def ranking_agreement(ranks: pd.DataFrame, by: str, reference: str,
                      order: Callable[[Sequence[str]], list[str]] = sorted) -> pd.DataFrame:
    """How each condition's ranking agrees with the ``reference`` condition's, per metric: ``ranks`` has columns
    metric, method, rank and ``by`` (the condition: a length, a preprocessing choice, ...). Per (metric, condition,
    in ``order``): n (methods ranked in both), Kendall's tau-b and Spearman's rho against the reference's ranks (NaN
    where undefined: fewer than 3 methods, or all tied), and ``same``: identical ranks. Columns: metric, ``by``, n,
    kendall, spearman, same."""
    rows = []
    for metric, group in ranks.groupby("metric", sort=False):
        wide = group.pivot_table(index="method", columns=by, values="rank")
        if reference not in wide:
            continue
        for condition in order(list(wide.columns)):
            both = wide[list(dict.fromkeys([condition, reference]))].dropna()
            a, b = both[condition].to_numpy(), both[reference].to_numpy()
            _rho, _p, _tau, _q = _correlation(a, b)
            rows.append({"metric": metric, by: condition, "n": len(both), "kendall": _tau, "spearman": _rho,
                         "same": bool(len(both) > 0 and np.array_equal(a, b))})  # fmt: skip
    return pd.DataFrame(rows, columns=["metric", by, "n", "kendall", "spearman", "same"])


def best_predictor(correlations: pd.DataFrame) -> tuple[str, float] | None:
    """The simulated domain whose rankings agree best with the real ones: ``(domain, mean Spearman rho over
    metrics and real domains)``, or None when no correlation is defined."""
    finite = correlations[np.isfinite(correlations["spearman"].astype(float))]
    if finite.empty:
        return None
    mean = finite.groupby("sim")["spearman"].mean().sort_values(ascending=False, kind="stable")
    return str(mean.index[0]), float(mean.iloc[0])


TRANSFER_TARGET = 0.8  # the Spearman rho the transfer target asks of every metric (issue [transfer])
HOLDOUT_MAX_SPLITS = 5000  # above this many k-of-n splits, holdout_agreement draws this many at random
ALL_METRICS = "all"  # holdout_agreement's row for every metric at once


def holdout_agreement(frame: pd.DataFrame, held_out: Sequence[int] = (1, 2, 3, 4),
                      metrics: Sequence[TransferMetric] = TRANSFER_METRICS, target: float = TRANSFER_TARGET,
                      observed: pd.DataFrame | None = None, max_splits: int = HOLDOUT_MAX_SPLITS,
                      seed: int = 0) -> pd.DataFrame:
    """How many recordings a target needs: the simulator against itself, k of its sequences held out.

    If the real world were the simulator, a real recording would be one more simulated sequence: its ranking of the
    methods would differ from the simulator's average ranking only by the methods' sequence-to-sequence spread. So,
    per simulated domain of ``frame`` (as :func:`domain_scores` takes it), metric and k in ``held_out``: every way
    (at most ``max_splits``, drawn at random with ``seed`` beyond that) of holding out k of the domain's sequences;
    each method's score on the held-out ones and on the rest (mean of the cells' medians over runs, as
    :func:`domain_scores`); Spearman's rho between the two rankings, over the methods with a finite score on every
    sequence. Its distribution is what k independent real recordings would score if the world were the simulator
    (a null distribution): a ``target`` whose median split misses it cannot be met reliably with k real recordings,
    however good the simulator. For the like-for-like null against a real recording cut into windows, see
    :func:`null_agreement`.

    Columns: sim, metric, held_out (k), n (methods), splits, rho_median, rho_q25, rho_q75, share_target (share of
    splits with rho >= ``target``); where several metrics are ranked, a row with metric :data:`ALL_METRICS` gives
    the share of splits (the same splits for every metric) where every metric reaches ``target`` at once (a split
    undefined for a metric counts as missing it). With ``observed`` (:func:`rank_correlations`' columns sim,
    metric, spearman, one row per (sim, metric), e.g. for one real domain) also ``observed`` and
    ``observed_percentile``: the share of splits below the observed rho, ties counting half (50: as typical as a
    held-out simulated sequence). A k that leaves no sequence on either side is skipped; splits where a side ranks
    all methods equal are left out of a metric's figures.
    """
    _check_frame(frame)
    frame = failures_ranked_last(frame, metrics)
    if any(int(k) < 1 for k in held_out) or max_splits < 1:
        raise EvalError(f"holdout_agreement: held_out must be >= 1 and max_splits >= 1, got {list(held_out)}, "
                        f"{max_splits}")  # fmt: skip
    sims = frame[frame["domain"].astype(str).str.startswith(SIM_PREFIX)]
    sims = sims[sims["metric"].isin([m.name for m in metrics])]
    cells = sims.groupby(["domain", "metric", "method", "sequence"])["value"].median()
    fails = failed_cells(sims)
    seen = {(str(r.sim), str(r.metric)): float(r.spearman) for r in observed.itertuples()} \
        if observed is not None else {}  # fmt: skip
    rows = []
    for sim in sorted(sims["domain"].unique()):
        sequences = sorted(sims.loc[sims["domain"] == sim, "sequence"].unique())
        tables = {}
        for metric in metrics:
            try:
                table = cells.loc[(sim, metric.name)].unstack("sequence").reindex(columns=sequences)
            except KeyError:
                continue
            table = table[np.isfinite(table.to_numpy()).all(axis=1)]
            if len(table) >= 3:
                tables[metric] = table
        for k in (int(k) for k in held_out):
            if k >= len(sequences) or not tables:
                continue
            held = _split_masks(len(sequences), k, max_splits, np.random.default_rng([seed, k]))
            reached = np.ones(len(held), dtype=bool)
            for metric, table in tables.items():
                values = (-1.0 if metric.higher_is_better else 1.0) * table.to_numpy(dtype=float)  # lower is better
                failed = fails.loc[(sim, metric.name)].unstack("sequence").reindex(index=table.index,
                                                                                   columns=sequences)  # fmt: skip
                all_rho = _holdout_rhos(values, held, failed.fillna(False).to_numpy(dtype=float))
                reached &= np.nan_to_num(all_rho, nan=-np.inf) >= target - 1e-12
                rho = all_rho[np.isfinite(all_rho)]
                row = {"sim": sim, "metric": metric.name, "held_out": k, "n": len(table), "splits": len(rho),
                       "rho_median": math.nan, "rho_q25": math.nan, "rho_q75": math.nan,
                       "share_target": math.nan}  # fmt: skip
                if len(rho):
                    row["rho_median"], row["rho_q25"], row["rho_q75"] = (float(x) for x in
                                                                         np.percentile(rho, [50, 25, 75]))
                    row["share_target"] = float(np.mean(rho >= target - 1e-12))
                if observed is not None:
                    obs = seen.get((sim, metric.name), math.nan)
                    row["observed"] = obs
                    row["observed_percentile"] = (100.0 * (np.mean(rho < obs - 1e-12)
                                                           + 0.5 * np.mean(np.abs(rho - obs) <= 1e-12))
                                                  if len(rho) and np.isfinite(obs) else math.nan)  # fmt: skip
                rows.append(row)
            if len(tables) > 1:  # the same splits for every metric: the share where all of them reach the target
                rows.append({"sim": sim, "metric": ALL_METRICS, "held_out": k, "n": min(len(t) for t in
                             tables.values()), "splits": len(held), "rho_median": math.nan, "rho_q25": math.nan,
                             "rho_q75": math.nan, "share_target": float(reached.mean())})  # fmt: skip
    columns = ["sim", "metric", "held_out", "n", "splits", "rho_median", "rho_q25", "rho_q75", "share_target"]
    return pd.DataFrame(rows, columns=columns + (["observed", "observed_percentile"] if observed is not None else []))


def _split_masks(n: int, k: int, max_splits: int, rng: np.random.Generator) -> np.ndarray:
    """(splits, n) bool masks of k held-out sequences among n: every k-subset in lexicographic order, or
    ``max_splits`` drawn at random (with ``rng``) when there are more."""
    if math.comb(n, k) <= max_splits:
        held = np.zeros((math.comb(n, k), n), dtype=bool)
        for i, subset in enumerate(itertools.combinations(range(n), k)):
            held[i, list(subset)] = True
        return held
    return np.argsort(rng.random((max_splits, n)), axis=1) < k


def _holdout_rhos(values: np.ndarray, held: np.ndarray, failed: np.ndarray | None = None) -> np.ndarray:
    """Spearman's rho, per split (a row of ``held``, :func:`_split_masks`), between the methods' mean over the
    held-out columns (sequences) of ``values`` (methods, sequences; lower is better) and their mean over the other
    columns (NaN where a side ranks all methods equal); a side holding a cell of ``failed`` (methods x sequences, 1
    where it failed) ranks that method last, tied with the other failures."""
    failed = np.zeros_like(values) if failed is None else failed
    k = held.sum(axis=1, keepdims=True)
    mean_held = np.where(held @ failed.T > 0, np.inf, held @ values.T / k)  # (splits, methods)
    mean_rest = np.where(~held @ failed.T > 0, np.inf, ~held @ values.T / (held.shape[1] - k))
    return _rowwise_pearson(stats.rankdata(mean_held, axis=1), stats.rankdata(mean_rest, axis=1))


def null_agreement(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS,
                   target: float = TRANSFER_TARGET, observed: pd.DataFrame | None = None) -> pd.DataFrame:
    """The null distribution of a sim-to-real rho, like for like: one more simulated recording against the simulator.

    A real domain of ``frame`` is one recording, whole or cut into w windows of a length, ranked on the mean over its
    windows and compared with a simulated domain ranked over all its sequences. Here, per simulated domain
    ``sim:<p>`` and metric, each of its sequences in turn plays the real recording: its ranking (the mean over its
    windows of each cell's median over runs, the windows being the sequences of domain ``win:<p>`` that belong to it
    (:func:`recording_of`), or the sequence itself where no ``win:<p>`` domain is in ``frame``, as for whole
    sequences) against the domain's ranking over all its sequences (:func:`domain_scores`), Spearman's rho over the
    methods with a finite score on both sides (at least 3). If the world were the simulator, a real recording's rho
    would be one draw of this distribution.

    Columns: sim, metric, recordings (simulated sequences that played the recording), windows (per recording, the
    most), n (methods), rho_median, rho_q10, rho_q25, rho_q75, rho_min, rho_max, share_target (share of recordings
    with rho >= ``target``); with ``observed`` (:func:`rank_correlations`' columns sim, metric, spearman, one row per
    (sim, metric)) also ``observed`` and ``observed_percentile`` (share of the null below the observed rho, ties
    counting half; 50: as typical as one more simulated recording; above 100 cannot be, but the observed rho may
    exceed every draw).
    """
    _check_frame(frame)
    frame = failures_ranked_last(frame, metrics)
    names = [m.name for m in metrics]
    sub = frame[frame["metric"].isin(names)]
    cells = (sub.groupby(["domain", "metric", "method", "sequence"])["value"].median()
             .rename("median").reset_index())  # fmt: skip
    cells = cells.merge(failed_cells(sub).rename("failed").reset_index(), how="left")
    cells = cells[np.isfinite(cells["median"])]
    seen = {(str(r.sim), str(r.metric)): float(r.spearman) for r in observed.itertuples()} \
        if observed is not None else {}  # fmt: skip
    direction = {m.name: m.higher_is_better for m in metrics}
    rows = []
    sims = sorted(d for d in sub["domain"].astype(str).unique() if d.startswith(SIM_PREFIX))
    for sim in sims:
        window_domain = WINDOW_PREFIX + sim.removeprefix(SIM_PREFIX)
        sequences = sorted(sub.loc[sub["domain"] == sim, "sequence"].unique())
        held_domain = window_domain if (sub["domain"] == window_domain).any() else sim
        for metric in names:
            ref_cells = cells[(cells["domain"] == sim) & (cells["metric"] == metric)]
            table = ref_cells.pivot_table(index="method", columns="sequence", values="median").reindex(
                columns=sequences)  # fmt: skip
            sign = -1.0 if direction[metric] else 1.0
            reference = _failed_last(table, ref_cells, sign)
            held = cells[(cells["domain"] == held_domain) & (cells["metric"] == metric)].assign(
                recording=lambda c: c["sequence"].map(recording_of))  # fmt: skip
            rhos, windows, n = [], 0, 0
            for recording in sequences:
                own = held[held["recording"] == recording]
                if own.empty:
                    continue
                per_window = own.pivot_table(index="method", columns="sequence", values="median")
                score = _failed_last(per_window, own, sign)
                both = pd.concat([reference.rename("ref"), score.rename("held")], axis=1).dropna()
                windows = max(windows, per_window.shape[1])
                rho = _correlation(stats.rankdata(both["held"].to_numpy()), stats.rankdata(both["ref"].to_numpy()))[0]
                if np.isfinite(rho):
                    rhos.append(rho)
                    n = max(n, len(both))
            r = np.asarray(rhos, dtype=float)
            row = {"sim": sim, "metric": metric, "recordings": len(r), "windows": windows, "n": n}
            quant = np.percentile(r, [50, 10, 25, 75]) if len(r) else [math.nan] * 4
            row.update(rho_median=float(quant[0]), rho_q10=float(quant[1]), rho_q25=float(quant[2]),
                       rho_q75=float(quant[3]), rho_min=float(r.min()) if len(r) else math.nan,
                       rho_max=float(r.max()) if len(r) else math.nan,
                       share_target=float(np.mean(r >= target - 1e-12)) if len(r) else math.nan)  # fmt: skip
            if observed is not None:
                obs = seen.get((sim, metric), math.nan)
                row["observed"] = obs
                row["observed_percentile"] = (100.0 * (np.mean(r < obs - 1e-12) + 0.5 * np.mean(np.abs(r - obs)
                                                                                               <= 1e-12))
                                              if len(r) and np.isfinite(obs) else math.nan)  # fmt: skip
            rows.append(row)
    columns = ["sim", "metric", "recordings", "windows", "n", "rho_median", "rho_q10", "rho_q25", "rho_q75",
               "rho_min", "rho_max", "share_target"]
    return pd.DataFrame(rows, columns=columns + (["observed", "observed_percentile"] if observed is not None else []))


def _failed_last(table: pd.DataFrame, cells: pd.DataFrame, sign: float) -> pd.Series:
    """Per method (row of ``table``: methods x sequences of cell medians), the ranking key of its mean over the
    sequences, ``sign`` x mean (lower is better), +inf where one of its ``cells`` (rows with method, failed) failed;
    methods without a finite median on every sequence left out."""
    key = sign * table[np.isfinite(table.to_numpy()).all(axis=1)].mean(axis=1)
    failed = set(cells.loc[cells["failed"].fillna(False).astype(bool), "method"])
    return key.where(~key.index.isin(failed), np.inf)


BOOTSTRAP_DRAWS = 2000  # resamples of a bootstrap interval (percentile method; its 2.5 % tails rest on 50 draws)


def bootstrap_correlations(frame: pd.DataFrame, metrics: Sequence[TransferMetric] = TRANSFER_METRICS,
                           draws: int = BOOTSTRAP_DRAWS, level: float = 0.95, seed: int = 0) -> pd.DataFrame:
    """Percentile bootstrap interval of Spearman's rho between each simulated and each real domain, per metric.

    frame: as :func:`domain_scores` takes it. Each draw resamples, with replacement and independently, the
    sequences of the simulated domain and the samples of the real one (its sequences, or the windows a real
    sequence was cut into), recomputes both domains' scores (mean of the drawn cells' medians, a cell drawn twice
    counting twice), ranks the methods both domains score, and takes rho. A domain with one sample is not
    resampled (its interval is the simulated side's alone). Columns: sim, real, metric, n (methods), sim_samples,
    real_samples, rho_low, rho_high (NaN when fewer than 3 methods, or no draw defines rho), defined (share of draws
    where rho is defined: not all ranks tied). ``seed`` fixes the draws: the same frame gives the same interval.
    """
    _check_frame(frame)
    frame = failures_ranked_last(frame, metrics)
    if not 0 < level < 1 or draws < 1:
        raise EvalError(f"bootstrap: level must be in (0, 1) and draws >= 1, got {level}, {draws}")
    sub = frame[frame["metric"].isin([m.name for m in metrics])]
    cells = sub.groupby(["metric", "domain", "method", "sequence"])["value"].median().unstack("sequence")
    fails = failed_cells(sub).reorder_levels(["metric", "domain", "method", "sequence"]).unstack("sequence")
    rows = []
    tail = 100.0 * (1.0 - level) / 2.0
    for metric in metrics:
        if metric.name not in cells.index.get_level_values("metric"):
            continue
        by_domain = {d: t.droplevel("domain").dropna(axis=1, how="all")
                     for d, t in cells.loc[metric.name].groupby(level="domain")}  # fmt: skip
        sims = sorted(d for d in by_domain if d.startswith(SIM_PREFIX))
        reals = sorted(d for d in by_domain if d.startswith(REAL_PREFIX))
        for sim in sims:
            for real in reals:
                a, b = by_domain[sim], by_domain[real]
                methods = sorted(set(a.index[a.notna().all(axis=1)]) & set(b.index[b.notna().all(axis=1)]))
                row = {"sim": sim, "real": real, "metric": metric.name, "n": len(methods),
                       "sim_samples": a.shape[1], "real_samples": b.shape[1], "rho_low": math.nan,
                       "rho_high": math.nan, "defined": 0.0}  # fmt: skip
                if len(methods) >= 3:
                    rng = np.random.default_rng([seed, len(rows)])
                    sign = -1.0 if metric.higher_is_better else 1.0
                    keys = []
                    for domain, table in ((sim, a), (real, b)):
                        failed = fails.loc[(metric.name, domain)].reindex(index=methods, columns=table.columns)
                        scores, failed = _resampled_scores(table.loc[methods].to_numpy(), draws, rng,
                                                           failed.fillna(False).to_numpy(dtype=float))  # fmt: skip
                        keys.append(np.where(failed, np.inf, sign * scores))  # failed: last, tied, as rank_methods
                    ra, rb = (stats.rankdata(k, axis=1) for k in keys)
                    rho = _rowwise_pearson(ra, rb)
                    ok = np.isfinite(rho)
                    row["defined"] = float(ok.mean())
                    if ok.any():
                        row["rho_low"], row["rho_high"] = (float(x) for x in np.percentile(rho[ok], [tail, 100 - tail]))
                rows.append(row)
    return pd.DataFrame(rows, columns=["sim", "real", "metric", "n", "sim_samples", "real_samples", "rho_low",
                                       "rho_high", "defined"])  # fmt: skip


def _resampled_scores(values: np.ndarray, draws: int, rng: np.random.Generator,
                      failed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(draws, methods) means over a resample (with replacement) of the columns (samples) of ``values``
    (methods, samples), and whether each draw holds a failed cell of the method (``failed``: methods x samples, 1
    where the cell failed); one sample: the same in every draw."""
    k = values.shape[1]
    if k == 1:
        return np.repeat(values.T, draws, axis=0), np.repeat(failed.T > 0, draws, axis=0)
    counts = rng.multinomial(k, np.full(k, 1.0 / k), size=draws)  # (draws, k): how often each sample is drawn
    return counts @ values.T / k, counts @ failed.T > 0


def _rowwise_pearson(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pearson correlation of each row of ``a`` with the same row of ``b`` (of ranks: Spearman's rho); NaN where a
    row is constant."""
    a = a - a.mean(axis=1, keepdims=True)
    b = b - b.mean(axis=1, keepdims=True)
    den = np.sqrt((a * a).sum(axis=1) * (b * b).sum(axis=1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, (a * b).sum(axis=1) / np.where(den > 0, den, 1.0), np.nan)
