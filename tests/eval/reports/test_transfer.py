"""Sim-to-real transfer: scores, ranks in each metric's direction, and rank correlations with known answers."""

import math

import numpy as np
import pandas as pd
import pytest

from eval.errors import EvalError
from eval.reports.transfer import (
    TransferMetric,
    best_predictor,
    bootstrap_correlations,
    domain_scores,
    holdout_agreement,
    null_agreement,
    rank_correlations,
    rank_methods,
)

ATE = TransferMetric("ate_se3_rmse", "ATE", False)
DEPTH = TransferMetric("depth_percent_correct", "depth", True)


def _frame(table: dict[tuple[str, str], list[float]], metric: str = "ate_se3_rmse",
           sequences: tuple[str, ...] = ("s1", "s2")) -> pd.DataFrame:
    """(domain, method) -> one value per run, the same on every sequence (offset by the sequence's index)."""
    rows = []
    for (domain, method), values in table.items():
        for k, seq in enumerate(sequences):
            rows += [{"domain": domain, "sequence": f"{domain}/{seq}", "method": method, "metric": metric,
                      "value": v + k} for v in values]  # fmt: skip
    return pd.DataFrame(rows)


def test_scores_are_medians_over_runs_then_means_over_sequences():
    frame = _frame({("sim:clean", "A"): [1.0, 2.0, 9.0], ("sim:clean", "B"): [3.0]})
    scores = domain_scores(frame, [ATE]).set_index("method")
    assert scores.loc["A", "score"] == pytest.approx((2.0 + 3.0) / 2)  # medians 2 and 3 on the two sequences
    assert scores.loc["A", "runs"] == 6 and scores.loc["A", "sequences"] == 2
    assert scores.loc["B", "score"] == pytest.approx(3.5)


def test_a_method_missing_a_sequence_gets_no_score():
    frame = _frame({("sim:clean", "A"): [1.0], ("sim:clean", "B"): [2.0]})
    frame.loc[(frame["method"] == "B") & frame["sequence"].str.endswith("s2"), "value"] = math.nan
    assert list(domain_scores(frame, [ATE])["method"]) == ["A"]


def test_ranks_follow_each_metrics_direction_and_share_ties():
    ate = _frame({("real:x", "A"): [0.1], ("real:x", "B"): [0.3], ("real:x", "C"): [0.2]})
    depth = _frame({("real:x", "A"): [10.0], ("real:x", "B"): [30.0], ("real:x", "C"): [30.0]},
                   metric="depth_percent_correct")  # fmt: skip
    ranks = rank_methods(domain_scores(pd.concat([ate, depth]), [ATE, DEPTH]), [ATE, DEPTH])
    by = {(r.metric, r.method): r.rank for r in ranks.itertuples()}
    assert [by["ate_se3_rmse", m] for m in "ABC"] == [1.0, 3.0, 2.0]  # lower ATE is better
    assert [by["depth_percent_correct", m] for m in "ABC"] == [3.0, 1.5, 1.5]  # higher depth is better; a tie


def test_identical_and_reversed_rankings_correlate_plus_and_minus_one():
    sim = {("sim:clean", m): [v] for m, v in zip("ABCDE", [1, 2, 3, 4, 5], strict=True)}
    same = {("real:x", m): [v] for m, v in zip("ABCDE", [10, 20, 30, 40, 50], strict=True)}
    rev = {("real:y", m): [v] for m, v in zip("ABCDE", [5, 4, 3, 2, 1], strict=True)}
    ranks = rank_methods(domain_scores(_frame({**sim, **same, **rev}), [ATE]), [ATE])
    corr = rank_correlations(ranks).set_index("real")
    assert corr.loc["real:x", ["spearman", "kendall"]].tolist() == pytest.approx([1.0, 1.0])
    assert corr.loc["real:y", ["spearman", "kendall"]].tolist() == pytest.approx([-1.0, -1.0])
    assert corr.loc["real:x", "n"] == 5 and corr.loc["real:x", "spearman_p"] < 0.05


def test_one_swap_in_five_gives_the_textbook_coefficients():
    # ranks (1 2 3 4 5) against (2 1 3 4 5): rho = 1 - 6 * 2 / (5 * 24) = 0.9, tau = (9 - 1) / 10 = 0.8
    sim = {("sim:clean", m): [v] for m, v in zip("ABCDE", [1, 2, 3, 4, 5], strict=True)}
    real = {("real:x", m): [v] for m, v in zip("ABCDE", [2, 1, 3, 4, 5], strict=True)}
    corr = rank_correlations(rank_methods(domain_scores(_frame({**sim, **real}), [ATE]), [ATE]))
    assert corr["spearman"].iloc[0] == pytest.approx(0.9) and corr["kendall"].iloc[0] == pytest.approx(0.8)


def test_only_methods_ranked_everywhere_are_compared_and_the_best_predictor_is_named():
    table = {("sim:clean", m): [v] for m, v in zip("ABCD", [4, 3, 2, 1], strict=True)}
    table |= {("sim:kinect", m): [v] for m, v in zip("ABCD", [1, 2, 4, 3], strict=True)}
    table |= {("real:x", m): [v] for m, v in zip("ABCDE", [1, 2, 3, 4, 0], strict=True)}  # E: real only
    ranks = rank_methods(domain_scores(_frame(table), [ATE]), [ATE])
    assert "E" not in set(ranks["method"])
    corr = rank_correlations(ranks)
    assert set(corr["n"]) == {4}
    name, rho = best_predictor(corr)
    assert name == "sim:kinect" and rho == pytest.approx(0.8)
    assert np.isclose(corr.set_index("sim").loc["sim:clean", "spearman"], -1.0)


def test_bad_frames_are_named():
    with pytest.raises(EvalError, match="domain"):
        domain_scores(pd.DataFrame({"sequence": [], "method": [], "metric": [], "value": []}))
    assert best_predictor(rank_correlations(rank_methods(domain_scores(_frame({("sim:a", "A"): [1.0]}), [ATE]),
                                                         [ATE]))) is None  # fmt: skip


@pytest.mark.slow  # > 5 s: the full lane only
def test_the_transfer_suite_ranks_sim_against_a_real_folder(tmp_path, monkeypatch):
    """``cnnslam bench transfer`` end to end on tiny data: the simulated part cut to one 8-frame sequence, the real
    part a 6-frame 7-Scenes-layout folder listed in a dataset list; three methods, the identity pose the worst on
    ATE in both domains; 3 frames against the real folder's two 3-frame windows, whole against whole."""
    from dataclasses import replace

    from cnnslam.cli import main
    from eval.bench import sequence_ref, sequence_resolve, suites
    from sim_envs.folders.datasets import write_folder
    from tests.eval.test_real_sequences import tiny_source

    folder = write_folder(tiny_source(), tmp_path / "tiny_7scenes", "7scenes")
    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets.tiny]\npath = "{folder}"\n')
    monkeypatch.setenv(sequence_resolve.DATASETS_ENV, str(listing))
    short = sequence_ref.SequenceRef("office0", base="office0", overrides={"n_frames": 8})
    monkeypatch.setitem(suites.SUITES, "table1", replace(suites.SUITES["table1"], sequences=(short,), frames=5))
    methods = tmp_path / "methods.toml"
    methods.write_text('[methods.yawed]\nentry_point = "sim_envs.agents:BiasedPoseAgent"\n'
                       'kwargs = { agent = "sim_envs.agents:OracleAgent", yaw_deg = 3.0 }\n'
                       'metrics = ["trajectory"]\n')  # fmt: skip
    code = main(["bench", "transfer", "--methods", "oracle", "constant-pose", "yawed", "--method-file", str(methods),
                 "--frames", "3", "--camera", "clean,kinect", "--executor", "serial", "--no-plots", "--no-progress",
                 "--no-check", "--out", str(tmp_path / "runs"), "--results", str(tmp_path / "res")])  # fmt: skip
    assert code == 0
    assert (tmp_path / "runs" / "table1" / "office0" / "oracle" / "seed0-frames3").is_dir()  # table1's runs
    assert (tmp_path / "runs" / "table1" / "office0@kinect" / "oracle" / "seed0-framesall").is_dir()
    assert (tmp_path / "runs" / "real" / "tiny.from3" / "yawed" / "seed0-frames3").is_dir()  # a real window
    assert (tmp_path / "runs" / "real" / "tiny" / "yawed" / "seed0-framesall").is_dir()  # the whole real sequence
    ranks = pd.read_csv(tmp_path / "res" / "transfer.csv", dtype={"length": str})
    assert set(ranks["domain"]) == {"sim:clean", "sim:kinect", "real:tiny"} and set(ranks["length"]) == {"3", "whole"}
    short_real = ranks[(ranks["domain"] == "real:tiny") & (ranks["length"] == "3")]
    assert set(short_real["sequences"]) == {2}  # two windows, each a sample of the real domain
    for length in ("3", "whole"):
        ate = ranks[(ranks["metric"] == "ate_se3_rmse") & (ranks["length"] == length)].set_index(["domain", "method"])
        assert ate.loc[("sim:clean", "constant-pose"), "rank"] == ate.loc[("real:tiny", "constant-pose"), "rank"] == 3
        assert ate.loc[("sim:clean", "oracle"), "rank"] in (1, 1.5)  # exact poses: best (or tied)
    corr = pd.read_csv(tmp_path / "res" / "transfer_correlations.csv", dtype={"length": str})
    assert len(corr) == 2 * 2 * 4  # per length, every simulated domain against the real one, per metric
    corr = corr[(corr["sim"] == "sim:clean") & (corr["length"] == "whole")].set_index("metric")
    sel = (ranks["metric"] == "ate_se3_rmse") & (ranks["length"] == "whole")
    sim_r = ranks[sel & (ranks["domain"] == "sim:clean")].set_index("method")["rank"]
    real_r = ranks[sel & (ranks["domain"] == "real:tiny")].set_index("method")["rank"]
    expected = np.corrcoef(sim_r.sort_index(), real_r.sort_index())[0, 1]  # Spearman = Pearson of the ranks
    assert corr.loc["ate_se3_rmse", "n"] == 3 and corr.loc["ate_se3_rmse", "spearman"] == pytest.approx(expected)
    text = (tmp_path / "res" / "transfer.md").read_text()
    assert "## Verdict" in text and "| whole | sim:clean | real:tiny |" in text
    assert "| 3 | sim:kinect | real:tiny |" in text
    assert (tmp_path / "res" / "transfer.png").is_file()


def test_bootstrap_interval_is_tight_for_agreeing_domains_and_wide_for_noise():
    from eval.reports.transfer import bootstrap_correlations

    rng = np.random.default_rng(1)
    rows = []
    for domain, n_seq in (("sim:kinect", 9), ("real:kitchen", 5)):
        for s in range(n_seq):
            for m, base in zip("ABCDE", [1.0, 2.0, 3.0, 4.0, 5.0], strict=True):
                rows.append({"domain": domain, "sequence": f"{domain}{s}", "method": m, "metric": "ate_se3_rmse",
                             "value": base + 0.1 * rng.standard_normal()})  # fmt: skip
                noise = rng.uniform(0, 10)  # no relation between the methods and the value
                rows.append({"domain": domain, "sequence": f"{domain}{s}", "method": m,
                             "metric": "depth_percent_correct", "value": noise})  # fmt: skip
    boot = bootstrap_correlations(pd.DataFrame(rows), [ATE, DEPTH], draws=500).set_index("metric")
    assert boot.loc["ate_se3_rmse", ["rho_low", "rho_high"]].tolist() == pytest.approx([1.0, 1.0])
    assert boot.loc["ate_se3_rmse", ["n", "sim_samples", "real_samples"]].tolist() == [5, 9, 5]
    low, high = boot.loc["depth_percent_correct", ["rho_low", "rho_high"]]
    assert low < 0 < high and high - low > 1.0  # noise: an interval around 0, wide
    again = bootstrap_correlations(pd.DataFrame(rows), [ATE, DEPTH], draws=500)
    assert again.equals(boot.reset_index()[again.columns])  # seeded: the same draws


def test_bootstrap_of_a_single_real_sample_resamples_the_simulated_side_only():
    from eval.reports.transfer import bootstrap_correlations

    sim = _frame({("sim:kinect", m): [v] for m, v in zip("ABCD", [1, 2, 3, 4], strict=True)},
                 sequences=("s1", "s2", "s3"))  # fmt: skip
    real = _frame({("real:x", m): [v] for m, v in zip("ABCD", [4, 3, 2, 1], strict=True)}, sequences=("w",))
    boot = bootstrap_correlations(pd.concat([sim, real]), [ATE], draws=200)
    assert boot["real_samples"].tolist() == [1] and boot["sim_samples"].tolist() == [3]
    assert boot[["rho_low", "rho_high"]].iloc[0].tolist() == pytest.approx([-1.0, -1.0])


def test_the_report_compares_each_length_within_itself(tmp_path):
    """Short simulated runs rank as the real windows do, whole ones the reverse of the whole real sequence: the
    report must give +1 for the first pair and -1 for the second, never mixing the lengths."""
    from dataclasses import replace

    from eval.bench.sequence_ref import SequenceRef
    from eval.bench.suites import TransferPart, get_suite
    from eval.reports.transfer_report import report_transfer
    from tests.eval.reports.test_suite_reports import fake_run

    methods = ("CNN-SLAM", "LSD", "ORB")
    sims = tuple(SequenceRef(f"{n}@kinect", base=n, overrides={"camera_effects": "kinect"})
                 for n in ("office0", "office1"))  # fmt: skip
    real = tuple(SequenceRef(f"kitchen.from{s}", folder="/data/kitchen", start=s) for s in (0, 10, 20))
    whole_real = (SequenceRef("kitchen", folder="/data/kitchen"),)
    table1, real_suite = get_suite("table1"), replace(get_suite("real"), methods=methods)
    parts = []
    for length, reals, order in ((10, real, (0.1, 0.2, 0.3)), (None, whole_real, (0.3, 0.2, 0.1))):
        sim = replace(table1, sequences=sims, methods=methods, frames=length)
        rs = replace(real_suite, sequences=reals, frames=length)
        sim_values = {(s.name, m): {"ate_se3_rmse": 0.1 * (k + 1)} for s in sims for k, m in enumerate(methods)}
        real_values = {(r.name, m): {"ate_se3_rmse": order[k]} for r in reals for k, m in enumerate(methods)}
        parts += [(TransferPart(length, sim, tuple((s.name, "sim:kinect") for s in sims)), fake_run(sim, sim_values)),
                  (TransferPart(length, rs, tuple((r.name, "real:kitchen") for r in reals)), fake_run(rs, real_values))]
    paths = report_transfer(parts, tmp_path, "cnnslam bench transfer")
    corr = pd.read_csv(tmp_path / "transfer_correlations.csv").set_index("length")
    assert corr.loc["10", "spearman"] == pytest.approx(1.0) and corr.loc["whole", "spearman"] == pytest.approx(-1.0)
    assert corr.loc["10", ["sim_samples", "real_samples", "n"]].tolist() == [2, 3, 3]
    assert corr.loc["whole", ["rho_low", "rho_high"]].tolist() == pytest.approx([-1.0, -1.0])
    md = (tmp_path / "transfer.md").read_text()
    assert "### Length: 10" in md and "### Length: whole" in md and "| 10 | sim:kinect | real:kitchen |" in md
    assert {p.name for p in paths} >= {"transfer.md", "transfer.html", "transfer.csv", "transfer_correlations.csv",
                                       "transfer.png", "transfer_null.csv", "transfer_recordings.csv",
                                       "transfer_runs.csv"}  # fmt: skip
    assert "<h1>Sim-to-real transfer" in (tmp_path / "transfer.html").read_text()
    # both simulated sequences rank alike, so one more simulated recording scores +1 against the simulator; the
    # windows' +1 sits in the middle of that null (percentile 50), the whole sequence's -1 below all of it (0)
    assert corr.loc["10", ["null_median", "null_percentile"]].tolist() == pytest.approx([1.0, 50.0])
    assert corr.loc["whole", ["null_median", "null_percentile"]].tolist() == pytest.approx([1.0, 0.0])
    assert "## The null distribution: one more simulated recording" in md and "perfect simulator" not in md
    needs = pd.read_csv(tmp_path / "transfer_recordings.csv", dtype={"length": str})
    assert set(needs["held_out"]) == {1} and set(needs["length"]) == {"10", "whole"}  # 2 sequences: k = 1 only
    runs = pd.read_csv(tmp_path / "transfer_runs.csv", dtype={"length": str})
    assert len(runs) == 2 * (2 * 3 + 3 * 3) - 2 * 3  # every run's ATE: 6 + 9 at length 10, 6 + 3 whole
    assert set(runs["domain"]) == {"sim:kinect", "real:kitchen"}


def test_intervals_survive_a_real_domain_that_misses_a_method(tmp_path):
    """The point estimate ranks the methods scored in every domain of a length; the interval must use the same set
    (it once merged on n and lost the interval of every pair where the counts differed)."""
    from eval.reports.transfer_report import correlations_with_intervals

    rows = []
    for domain, seqs in (("sim:kinect", ("a", "b", "c")), ("real:x", ("w0", "w1")), ("real:y", ("v0", "v1"))):
        for seq in seqs:
            for m, v in zip("ABCD", [1.0, 2.0, 3.0, 4.0], strict=True):
                if domain == "real:y" and m == "D":
                    continue  # real:y has no D: D is ranked nowhere at this length
                rows.append({"domain": domain, "sequence": f"{domain}/{seq}", "method": m, "metric": "ate_se3_rmse",
                             "value": v, "length": "200"})  # fmt: skip
    _, corr = correlations_with_intervals(pd.DataFrame(rows))
    corr = corr.set_index("real")
    assert corr.loc["real:x", "n"] == corr.loc["real:y", "n"] == 3
    assert corr.loc["real:x", ["rho_low", "rho_high"]].tolist() == pytest.approx([1.0, 1.0])
    assert corr.loc["real:y", ["rho_low", "rho_high"]].tolist() == pytest.approx([1.0, 1.0])


def _holdout_frame(per_sequence: list[tuple[float, ...]], methods: str = "ABC") -> pd.DataFrame:
    """One simulated domain; sequence i gives method j the value per_sequence[i][j] (one run per cell)."""
    return pd.DataFrame([{"domain": "sim:kinect", "sequence": f"s{i}", "method": m, "metric": "ate_se3_rmse",
                          "value": v} for i, values in enumerate(per_sequence)
                         for m, v in zip(methods, values, strict=True)])  # fmt: skip


def test_a_simulator_that_ranks_alike_everywhere_is_its_own_perfect_match():
    from eval.reports.transfer import holdout_agreement

    frame = _holdout_frame([(1.0 + s, 2.0 + s, 3.0 + s, 4.0 + s) for s in range(6)], methods="ABCD")
    table = holdout_agreement(frame, (1, 2, 3), [ATE]).set_index("held_out")
    assert table["splits"].tolist() == [6, 15, 20]  # every k-of-6 split: C(6, k)
    assert table["rho_median"].tolist() == pytest.approx([1.0, 1.0, 1.0])
    assert table["share_target"].tolist() == pytest.approx([1.0, 1.0, 1.0])


def test_holdout_agreement_of_one_swapped_sequence_has_the_hand_computed_rhos():
    """s0, s1 rank A < B < C, s2 swaps B and C. Holding out s0 (or s1): the rest's means tie B and C, ranks
    (1, 2.5, 2.5) against (1, 2, 3): rho = 1.5 / sqrt(2 * 1.5) = 0.866. Holding out s2: (1, 3, 2) against
    (1, 2, 3): rho = 0.5. An observed 0.866 is above one split and ties two: percentile (1 + 2 / 2) / 3."""
    from eval.reports.transfer import holdout_agreement

    frame = _holdout_frame([(1.0, 2.0, 3.0), (1.0, 2.0, 3.0), (1.0, 3.0, 2.0)])
    observed = pd.DataFrame([{"sim": "sim:kinect", "metric": "ate_se3_rmse", "spearman": math.sqrt(0.75)}])
    row = holdout_agreement(frame, (1,), [ATE], observed=observed).iloc[0]
    assert row["splits"] == 3 and row["rho_median"] == pytest.approx(math.sqrt(0.75))
    assert row["rho_q25"] == pytest.approx((0.5 + math.sqrt(0.75)) / 2)  # numpy's linear percentile of 3 values
    assert row["share_target"] == pytest.approx(2 / 3)
    assert row["observed_percentile"] == pytest.approx(100 * 2 / 3)
    # a higher-is-better metric reverses every ranking on both sides: the same rhos
    flipped = holdout_agreement(frame.assign(metric="depth_percent_correct"), (1,), [DEPTH]).iloc[0]
    assert flipped["rho_median"] == pytest.approx(math.sqrt(0.75))


def test_holdout_agreement_of_noise_is_near_zero_and_draws_splits_when_there_are_many():
    from eval.reports.transfer import holdout_agreement

    rng = np.random.default_rng(3)
    frame = _holdout_frame([tuple(rng.uniform(0, 1, 6)) for _ in range(12)], methods="ABCDEF")
    table = holdout_agreement(frame, (1, 6), [ATE], max_splits=300).set_index("held_out")
    assert table.loc[1, "splits"] == 12 and table.loc[6, "splits"] == 300  # C(12, 6) = 924 > 300: drawn
    assert abs(table.loc[6, "rho_median"]) < 0.4 and table.loc[6, "share_target"] < 0.1
    again = holdout_agreement(frame, (1, 6), [ATE], max_splits=300)
    assert again.equals(table.reset_index()[again.columns])  # seeded: the same draws


def test_holdout_agreement_skips_what_cannot_be_split_and_names_bad_arguments():
    from eval.reports.transfer import holdout_agreement

    frame = _holdout_frame([(1.0, 2.0, 3.0), (1.0, 2.0, 3.0)])
    assert holdout_agreement(frame, (1, 2), [ATE])["held_out"].tolist() == [1]  # k = 2 leaves no rest
    with pytest.raises(EvalError, match="held_out must be >= 1"):
        holdout_agreement(frame, (0,), [ATE])
    with pytest.raises(EvalError, match="missing"):
        holdout_agreement(frame.drop(columns="domain"), (1,), [ATE])


def test_the_joint_row_counts_the_splits_where_every_metric_reaches_the_target():
    """ATE swaps B and C on s2, depth (higher is better) on s0: ATE reaches 0.8 holding out s0 or s1 (0.866), not
    s2 (0.5); depth holding out s1 or s2, not s0. Both at once: only holding out s1, one split in three."""
    from eval.reports.transfer import ALL_METRICS, holdout_agreement

    ate = _holdout_frame([(1.0, 2.0, 3.0), (1.0, 2.0, 3.0), (1.0, 3.0, 2.0)])
    depth = _holdout_frame([(3.0, 1.0, 2.0), (3.0, 2.0, 1.0), (3.0, 2.0, 1.0)]).assign(metric="depth_percent_correct")
    table = holdout_agreement(pd.concat([ate, depth]), (1,), [ATE, DEPTH]).set_index("metric")
    assert table.loc["ate_se3_rmse", "share_target"] == pytest.approx(2 / 3)
    assert table.loc["depth_percent_correct", "share_target"] == pytest.approx(2 / 3)
    assert table.loc[ALL_METRICS, ["splits", "share_target"]].tolist() == pytest.approx([3, 1 / 3])


def _null_frame(windows: dict[str, tuple[float, float, float]], sim: dict[str, tuple[float, float, float]],
                ) -> pd.DataFrame:
    """ATE (lower is better) of methods M1..M3: ``sim`` per simulated sequence (domain sim:k), ``windows`` per
    window of a simulated recording (domain win:k; a sequence's first window is the sequence itself)."""
    rows = []
    for domain, table in (("sim:k", sim), ("win:k", windows)):
        for seq, values in table.items():
            for method, v in zip(("M1", "M2", "M3"), values, strict=True):
                rows.append({"domain": domain, "sequence": seq, "method": method, "metric": "ate_se3_rmse",
                             "value": v})
    return pd.DataFrame(rows)


def test_null_of_windows_has_the_hand_computed_rhos() -> None:
    """Reference over a, b, c: (1, 2, 3). Recording a's windows rank alike (+1), b's the reverse (-1), c's with
    one swap (+0.5)."""
    from eval.reports.transfer import null_agreement, recording_of

    assert recording_of("office0.from200") == "office0" and recording_of("office0") == "office0"
    first = {"a": (1, 2, 3), "b": (1, 2, 3), "c": (1, 2, 3)}
    windows = {**first, "a.from200": (1, 2, 3), "b.from200": (9, 5, 1), "c.from200": (1, 5, 2)}
    metric = [TransferMetric("ate_se3_rmse", "ATE", False)]
    observed = pd.DataFrame([{"sim": "sim:k", "metric": "ate_se3_rmse", "spearman": 0.75}])
    null = null_agreement(_null_frame(windows, first), metric, target=0.8, observed=observed).iloc[0]
    assert (null.recordings, null.windows, null.n) == (3, 2, 3)
    assert (null.rho_min, null.rho_median, null.rho_max) == pytest.approx((-1.0, 0.5, 1.0))
    assert null.rho_q10 == pytest.approx(-1.0 + 0.2 * 1.5)  # numpy's linear interpolation between -1 and 0.5
    assert null.share_target == pytest.approx(1 / 3)
    assert null.observed_percentile == pytest.approx(100 * 2 / 3)  # above -1 and 0.5, below 1


def test_null_of_whole_sequences_holds_each_sequence_against_all() -> None:
    """No window domain (whole sequences): each sequence against the mean over all three, (5/3, 7/3, 2) -> ranks
    (1, 3, 2): a (1, 2, 3) gives +0.5, b (3, 2, 1) gives -0.5, c (1, 3, 2) gives +1."""
    from eval.reports.transfer import null_agreement

    frame = _null_frame({}, {"a": (1, 2, 3), "b": (3, 2, 1), "c": (1, 3, 2)})
    null = null_agreement(frame, [TransferMetric("ate_se3_rmse", "ATE", False)]).iloc[0]
    assert (null.recordings, null.windows) == (3, 1)
    assert (null.rho_min, null.rho_median, null.rho_max) == pytest.approx((-0.5, 0.5, 1.0))


def _runs(table: dict[tuple[str, str, str], tuple[float, float]]) -> pd.DataFrame:
    """(domain, sequence, method) -> (ATE, tracked share) of one run each, with run ids and the tracked-share rows
    the failure rule reads."""
    from eval.metrics.catalogue import TRACKED_SHARE

    rows = []
    for (domain, seq, method), (ate, share) in table.items():
        base = {"domain": domain, "sequence": seq, "method": method, "run": f"{domain}/{seq}/{method}"}
        rows += [{**base, "metric": "ate_se3_rmse", "value": ate}, {**base, "metric": TRACKED_SHARE.key,
                                                                    "value": share}]  # fmt: skip
    return pd.DataFrame(rows)


def test_a_failed_run_ranks_last_and_failures_tie():
    # sim: A < B < C < D by ATE, nobody fails. real: A 0.1, B lost (tracked 20 %: a failure by the rule, its small
    # ATE no figure), C 0.3, D never initialised -> A 1, C 2, B and D tied last (3.5 each)
    table = {("sim:kinect", "s1", m): (v, 1.0) for m, v in zip("ABCD", [0.1, 0.2, 0.3, 0.4], strict=True)}
    table |= {("real:x", "r1", "A"): (0.1, 1.0), ("real:x", "r1", "B"): (0.05, 0.2),
              ("real:x", "r1", "C"): (0.3, 1.0), ("real:x", "r1", "D"): (math.nan, 0.0)}  # fmt: skip
    scores = domain_scores(_runs(table), [ATE])
    real = scores[scores["domain"] == "real:x"].set_index("method")
    assert real["failed"].to_dict() == {"A": False, "B": True, "C": False, "D": True}
    assert np.isnan(real.loc["B", "score"]) and real.loc["C", "score"] == pytest.approx(0.3)
    ranks = rank_methods(scores, [ATE])
    by = {(r.domain, r.method): r.rank for r in ranks.itertuples()}
    assert [by["real:x", m] for m in "ABCD"] == [1.0, 3.5, 2.0, 3.5]
    assert [by["sim:kinect", m] for m in "ABCD"] == [1.0, 2.0, 3.0, 4.0]
    # Spearman of (1 2 3 4) against (1 3.5 2 3.5): the textbook value with ties
    expected = pd.Series([1, 2, 3, 4]).corr(pd.Series([1, 3.5, 2, 3.5]))
    assert rank_correlations(ranks)["spearman"].iloc[0] == pytest.approx(expected)
    assert expected == pytest.approx(0.6324555, abs=1e-6)
    # one sample a side: the bootstrap does not resample, and ranks the failures last and tied too
    boot = bootstrap_correlations(_runs(table), [ATE], draws=20)
    assert boot[["rho_low", "rho_high"]].iloc[0].tolist() == pytest.approx([expected, expected])


def test_a_failure_on_one_sequence_fails_the_domain_and_higher_is_better_still_ranks_it_last():
    table = {("sim:fr1", s, m): (v, 1.0) for s in ("s1", "s2") for m, v in zip("ABC", [3.0, 2.0, 9.0], strict=True)}
    table[("sim:fr1", "s2", "C")] = (9.0, 0.5)  # C lost on one of two sequences: failed in the domain
    frame = _runs(table).replace({"ate_se3_rmse": "depth_percent_correct"})
    ranks = rank_methods(domain_scores(frame, [DEPTH]), [DEPTH]).set_index("method")
    assert ranks["rank"].to_dict() == {"A": 1.0, "B": 2.0, "C": 3.0}  # C's best figure does not save it


def test_the_report_intervals_rank_failures_last_as_the_point_estimate_does():
    """The report's interval is drawn from the same rows as its point estimate, the failure-telling ones included
    (they once dropped out with the unranked metrics, so a lost method's small ATE ranked it first in every draw):
    two identical simulated sequences make every draw the observed ranking, so the interval is the observed rho."""
    from eval.reports.transfer_report import transfer_tables

    table = {("sim:kinect", s, m): (v, 1.0) for s in ("s1", "s2") for m, v in zip("ABCD", [0.1, 0.2, 0.3, 0.4],
                                                                                 strict=True)}  # fmt: skip
    table |= {("real:x", "r1", "A"): (0.1, 1.0), ("real:x", "r1", "B"): (0.05, 0.2),
              ("real:x", "r1", "C"): (0.3, 1.0), ("real:x", "r1", "D"): (0.4, 1.0)}  # fmt: skip
    _, corr, null, needs = transfer_tables(_runs(table).assign(length="whole"))
    expected = pd.Series([1, 2, 3, 4]).corr(pd.Series([1, 4, 2, 3]))  # real: A 1, C 2, D 3, B (lost) last
    row = corr.iloc[0]
    assert row["spearman"] == pytest.approx(expected) == pytest.approx(0.4)
    assert [row["rho_low"], row["rho_high"]] == pytest.approx([expected, expected])


def test_a_draw_holding_a_failed_cell_ranks_the_method_last_and_tied_with_the_other_failures():
    # sim: C fails on s1 only, D on both: in the point estimate both failed, tied last (3.5). A draw of (s1, s2) or
    # (s1, s1) holds a failed cell of each: tied again (3/4 of the draws); only (s2, s2) ranks C third. So the middle
    # fifth of the draws is the observed rho (a mean of a failed and a finite cell once put C ahead of D there).
    table = {("sim:kinect", s, m): (v, 1.0) for s in ("s1", "s2") for m, v in zip("AB", [0.1, 0.2], strict=True)}
    table |= {("sim:kinect", "s1", "C"): (0.3, 0.2), ("sim:kinect", "s2", "C"): (0.3, 1.0),
              ("sim:kinect", "s1", "D"): (0.4, 0.0), ("sim:kinect", "s2", "D"): (0.4, 0.0)}  # fmt: skip
    table |= {("real:x", "r1", m): (v, 1.0) for m, v in zip("ABCD", [0.1, 0.2, 0.3, 0.4], strict=True)}
    observed = pd.Series([1, 2, 3.5, 3.5]).corr(pd.Series([1, 2, 3, 4]))
    ranks = rank_methods(domain_scores(_runs(table), [ATE]), [ATE])
    assert rank_correlations(ranks)["spearman"].iloc[0] == pytest.approx(observed)
    boot = bootstrap_correlations(_runs(table), [ATE], draws=400, level=0.2)
    assert boot[["rho_low", "rho_high"]].iloc[0].tolist() == pytest.approx([observed, observed])


def test_the_null_and_the_holdout_tie_a_mean_holding_a_failed_cell_with_the_failures():
    # C fails on s1 only, D everywhere: wherever a mean holds s1, C and D are tied last, as in the point estimate;
    # a mean of a failed and finite cells once ranked C ahead of D (rho 1 against a side where they tie)
    table = {("sim:kinect", s, m): (v, 1.0) for s in ("s1", "s2", "s3")
             for m, v in zip("ABCD", [0.1, 0.2, 0.3, 0.4], strict=True)}  # fmt: skip
    table |= {("sim:kinect", "s1", "C"): (0.3, 0.2)} | {("sim:kinect", s, "D"): (0.4, 0.0) for s in ("s1", "s2", "s3")}
    tied = pd.Series([1, 2, 3.5, 3.5]).corr(pd.Series([1, 2, 3, 4]))
    needs = holdout_agreement(_runs(table), held_out=(1,), metrics=[ATE]).set_index("metric")
    assert needs.loc["ate_se3_rmse", "rho_median"] == pytest.approx(tied)  # every split: one side ties C with D
    null = null_agreement(_runs(table), metrics=[ATE]).set_index("metric")
    # s1 against all: both sides tie C and D (rho 1); s2 and s3: C third on their own, tied in the reference
    assert [null.loc["ate_se3_rmse", c] for c in ("rho_median", "rho_max")] == pytest.approx([tied, 1.0])
