"""Sim-to-real transfer: scores, ranks in each metric's direction, and rank correlations with known answers."""

import math

import numpy as np
import pandas as pd
import pytest

from eval.errors import EvalError
from eval.transfer import TransferMetric, best_predictor, domain_scores, rank_correlations, rank_methods

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
    """``cnnslam bench transfer`` end to end on tiny data: the simulated part cut to one 5-frame sequence, the real
    part a 6-frame 7-Scenes-layout folder listed in a dataset list; three methods, the identity pose the worst on
    ATE in both domains."""
    from dataclasses import replace

    from cnnslam.cli import main
    from eval import suites
    from sim_envs.datasets import write_folder
    from tests.eval.test_real_sequences import tiny_source

    folder = write_folder(tiny_source(), tmp_path / "tiny_7scenes", "7scenes")
    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets.tiny]\npath = "{folder}"\n')
    monkeypatch.setenv(suites.DATASETS_ENV, str(listing))
    small_table1 = replace(suites.SUITES["table1"], sequences=(suites.SequenceRef("office0", base="office0"),),
                           frames=5)  # fmt: skip
    monkeypatch.setitem(suites.SUITES, "table1", small_table1)
    methods = tmp_path / "methods.toml"
    methods.write_text('[methods.yawed]\nentry_point = "sim_envs.agents:BiasedPoseAgent"\n'
                       'kwargs = { agent = "sim_envs.agents:OracleAgent", yaw_deg = 3.0 }\n'
                       'metrics = ["trajectory"]\n')  # fmt: skip
    code = main(["bench", "transfer", "--methods", "oracle", "constant-pose", "yawed", "--method-file", str(methods),
                 "--frames", "5", "--executor", "serial", "--no-plots", "--no-progress", "--no-check",
                 "--out", str(tmp_path / "runs"), "--results", str(tmp_path / "res")])  # fmt: skip
    assert code == 0
    assert (tmp_path / "runs" / "table1" / "office0" / "oracle").is_dir()  # the sim part's runs are table1's
    assert (tmp_path / "runs" / "real" / "tiny" / "yawed").is_dir()  # the real part's are the real suite's
    ranks = pd.read_csv(tmp_path / "res" / "transfer.csv")
    assert set(ranks["domain"]) == {"sim:clean", "sim:kinect", "sim:hard", "real:tiny"}  # every camera preset
    assert (tmp_path / "runs" / "table1" / "office0@kinect" / "constant-pose").is_dir()
    ate = ranks[ranks["metric"] == "ate_se3_rmse"].set_index(["domain", "method"])["rank"]
    assert ate["sim:clean", "constant-pose"] == ate["real:tiny", "constant-pose"] == 3  # the worst in both
    assert ate["sim:clean", "oracle"] == 1.5 or ate["sim:clean", "oracle"] == 1  # exact poses: best (or tied)
    corr = pd.read_csv(tmp_path / "res" / "transfer_correlations.csv")
    assert len(corr) == 3 * 4  # every simulated domain against the real one, per metric
    corr = corr[corr["sim"] == "sim:clean"].set_index("metric")
    sim_r = ranks[(ranks["metric"] == "ate_se3_rmse") & (ranks["domain"] == "sim:clean")].set_index("method")["rank"]
    real_r = ranks[(ranks["metric"] == "ate_se3_rmse") & (ranks["domain"] == "real:tiny")].set_index("method")["rank"]
    expected = np.corrcoef(sim_r.sort_index(), real_r.sort_index())[0, 1]  # Spearman = Pearson of the ranks
    assert corr.loc["ate_se3_rmse", "n"] == 3 and corr.loc["ate_se3_rmse", "spearman"] == pytest.approx(expected)
    text = (tmp_path / "res" / "transfer.md").read_text()
    assert "## Verdict" in text and "| sim:clean | real:tiny |" in text and "| sim:hard | real:tiny |" in text
    assert (tmp_path / "res" / "transfer.png").is_file()
