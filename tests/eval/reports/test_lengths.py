"""The length sweep: ranks per length, agreement with the whole sequences, where ranks settle, the bench length."""

import numpy as np
import pandas as pd
import pytest

from eval.errors import EvalError
from eval.reports.lengths import (
    length_agreement,
    length_order,
    length_ranks,
    settling_lengths,
    shortest_agreeing_length,
)


def _frame(table: dict[str, dict[str, float]], metric: str = "ate_se3_rmse") -> pd.DataFrame:
    """length -> method -> value, the same on two sequences (offset by the sequence's index)."""
    return pd.DataFrame([{"length": length, "sequence": f"s{k}", "method": m, "metric": metric, "value": v + k}
                         for length, row in table.items() for m, v in row.items() for k in range(2)])  # fmt: skip


# a drifting method B: as good as A over short runs, far worse over whole sequences (scale drift)
ATE = {
    "200": {"A": 0.05, "B": 0.04, "C": 0.30, "D": 0.50},
    "400": {"A": 0.08, "B": 0.09, "C": 0.35, "D": 0.30},
    "800": {"A": 0.12, "B": 0.25, "C": 0.40, "D": 0.60},
    "whole": {"A": 0.20, "B": 0.45, "C": 0.50, "D": 0.90},
}
DEPTH = {length: {"A": 50.0, "B": 20.0, "C": 1.0, "D": 0.0} for length in ATE}


def test_lengths_are_ordered_with_whole_last():
    assert length_order(["whole", "800", "200", "400"]) == ["200", "400", "800", "whole"]


def test_agreement_with_known_rankings():
    ranks = length_ranks(_frame(ATE))
    agree = length_agreement(ranks).set_index("length")
    # 200: B A C D vs A B C D: one discordant pair of 6 -> tau = (5 - 1) / 6
    assert agree.loc["200", "kendall"] == pytest.approx(4 / 6) and not agree.loc["200", "same"]
    # 400: A B D C vs A B C D: one swap
    assert agree.loc["400", "kendall"] == pytest.approx(4 / 6) and agree.loc["400", "n"] == 4
    assert agree.loc["800", "same"] and agree.loc["800", "kendall"] == pytest.approx(1.0)
    assert agree.loc["whole", "same"]
    settle = settling_lengths(ranks).set_index("method")
    assert settle.loc["A", "settles_at"] == "400"  # rank 2 at 200, then 1 from 400 on
    assert settle.loc["C", "settles_at"] == "800" and settle.loc["D", "settles_at"] == "800"
    assert settle.loc["B", ["rank_200", "rank_whole"]].tolist() == [1.0, 2.0]


def test_the_bench_length_needs_every_decisive_metric():
    frame = pd.concat([_frame(ATE), _frame(DEPTH, "depth_percent_correct")])
    agree = length_agreement(length_ranks(frame))
    assert shortest_agreeing_length(agree) == "800"
    assert shortest_agreeing_length(agree, ["depth_percent_correct"]) == "200"  # depth ranks the same everywhere
    assert shortest_agreeing_length(agree, ["rot_deg_orient_rmse"]) is None  # a metric not there disagrees


def test_methods_missing_a_length_are_not_ranked_and_a_frame_needs_lengths():
    table = {k: dict(v) for k, v in ATE.items()}
    del table["400"]["D"]
    ranks = length_ranks(_frame(table))
    assert set(ranks["method"]) == {"A", "B", "C"}
    assert np.isfinite(length_agreement(ranks)["kendall"]).all()
    with pytest.raises(EvalError, match="'length' column"):
        length_ranks(_frame(ATE).drop(columns="length"))


def test_the_length_sweep_end_to_end(tmp_path, monkeypatch):
    """``cnnslam bench lengths`` on one 8-frame sequence: its runs are table1's (one folder per length), and the
    report ranks three methods per length against the whole sequence."""
    from dataclasses import replace

    from cnnslam.cli import main
    from eval.bench import sequence_ref, suites

    short = sequence_ref.SequenceRef("office0", base="office0", overrides={"n_frames": 8})
    monkeypatch.setitem(suites.SUITES, "lengths", replace(suites.SUITES["lengths"], sequences=(short,)))
    methods = tmp_path / "methods.toml"
    methods.write_text('[methods.yawed]\nentry_point = "sim_envs.agents:BiasedPoseAgent"\n'
                       'kwargs = { agent = "sim_envs.agents:OracleAgent", yaw_deg = 3.0 }\n'
                       'metrics = ["trajectory"]\n')  # fmt: skip
    code = main(["bench", "lengths", "--lengths", "3", "5", "all", "--methods", "oracle", "constant-pose", "yawed",
                 "--method-file", str(methods), "--executor", "serial", "--no-plots", "--no-progress", "--no-check",
                 "--out", str(tmp_path / "runs"), "--results", str(tmp_path / "res")])  # fmt: skip
    assert code == 0
    for frames in ("3", "5", "all"):
        assert (tmp_path / "runs" / "table1" / "office0" / "yawed" / f"seed0-frames{frames}").is_dir()
    ranks = pd.read_csv(tmp_path / "res" / "lengths.csv", dtype={"length": str})
    assert set(ranks["length"]) == {"3", "5", "whole"}
    ate = ranks[ranks["metric"] == "ate_se3_rmse"].set_index(["length", "method"])["rank"]
    assert ate["whole", "constant-pose"] == 3 and ate["3", "oracle"] in (1, 1.5)
    agree = pd.read_csv(tmp_path / "res" / "lengths_agreement.csv", dtype={"length": str})
    assert set(agree["length"]) == {"3", "5", "whole"}
    md = (tmp_path / "res" / "lengths.md").read_text()
    assert "## Verdict" in md and "## Where each method's rank settles" in md and "| settles at |" in md
    assert (tmp_path / "res" / "lengths.png").is_file()


def test_a_length_that_agrees_by_chance_is_not_the_bench_length():
    table = {
        "200": {"A": 0.1, "B": 0.2, "C": 0.3},  # agrees with whole
        "400": {"A": 0.2, "B": 0.1, "C": 0.3},  # does not
        "whole": {"A": 0.1, "B": 0.2, "C": 0.3},
    }
    agree = length_agreement(length_ranks(_frame(table)))
    assert shortest_agreeing_length(agree, ["ate_se3_rmse"]) == "whole"
