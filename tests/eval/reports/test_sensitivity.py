"""Preprocessing sensitivity: ranks per choice, agreement with the defaults, the verdicts a choice changes."""

import pandas as pd
import pytest

from eval.errors import EvalError
from eval.reports.sensitivity import changed_verdicts, choice_agreement, choice_order, choice_ranks


def _frame(table: dict[tuple[str, str], dict[str, float]]) -> pd.DataFrame:
    """(choice, metric) -> method -> value, one run on one sequence of folder 'kitchen'."""
    return pd.DataFrame([{"folder": "kitchen", "choice": c, "sequence": f"kitchen~{c}", "method": m, "metric": metric,
                          "value": v} for (c, metric), row in table.items() for m, v in row.items()])  # fmt: skip


TABLE = {
    ("default", "ate_se3_rmse"): {"CNN-SLAM": 0.2, "LSD": 0.5, "ORB": 0.3},
    ("undistort_full", "ate_se3_rmse"): {"CNN-SLAM": 0.2, "LSD": 0.25, "ORB": 0.3},  # LSD moves from 3rd to 2nd
    ("default", "tracked_share"): {"CNN-SLAM": 1.0, "LSD": 0.07, "ORB": 0.95},
    ("undistort_full", "tracked_share"): {"CNN-SLAM": 1.0, "LSD": 0.92, "ORB": 0.9},  # LSD: 7 % -> 92 %
}


def test_a_choice_that_moves_a_method_is_flagged():
    ranks = choice_ranks(_frame(TABLE))
    changes = changed_verdicts(ranks).set_index(["metric", "method"])
    assert set(changes.index) == {("ate_se3_rmse", "LSD"), ("ate_se3_rmse", "ORB"), ("tracked_share", "LSD")}
    assert changes.loc[("ate_se3_rmse", "LSD"), ["default_rank", "rank"]].tolist() == [3.0, 2.0]
    assert changes.loc[("tracked_share", "LSD"), "score"] == pytest.approx(0.92)  # ORB's 5-point drop is not
    agree = choice_agreement(ranks).set_index(["metric", "choice"])
    assert agree.loc[("ate_se3_rmse", "default"), "same"] and not agree.loc[("ate_se3_rmse", "undistort_full"), "same"]
    assert agree.loc[("ate_se3_rmse", "undistort_full"), "kendall"] == pytest.approx(1 / 3)


def test_no_change_no_flag_and_the_default_comes_first():
    same = {k: v for k, v in TABLE.items() if k[0] == "default"}
    same.update({("native_size", m): row for (c, m), row in same.items()})
    assert changed_verdicts(choice_ranks(_frame(same))).empty
    assert choice_order(["undistort_none", "default", "native_size"]) == ["default", "native_size", "undistort_none"]
    with pytest.raises(EvalError, match="'folder' and 'choice'"):
        choice_ranks(_frame(TABLE).drop(columns="choice"))


def test_the_preprocessing_suite_end_to_end(tmp_path, monkeypatch):
    """``cnnslam bench preprocessing`` on a tiny 7-Scenes-layout folder with its own camera file: the choice that
    applies to it (the native size: its images are 64x48, delivered at 320x240 by default; no lens distortion, and
    its depth is its camera's own) runs as <folder>~<choice>, beside the defaults; the report names it."""
    from cnnslam.cli import main
    from eval.bench import sequence_resolve, suites
    from sim_envs.folders.datasets import write_folder
    from tests.eval.test_real_sequences import tiny_source

    folder = write_folder(tiny_source(), tmp_path / "tiny_7scenes", "7scenes")
    listing = tmp_path / "datasets.toml"
    listing.write_text(f'[datasets.tiny]\npath = "{folder}"\n')
    monkeypatch.setenv(sequence_resolve.DATASETS_ENV, str(listing))
    parts = suites.preprocessing_parts(suites.get_suite("preprocessing"))
    assert [c for c, _, _ in parts] == ["default", "native_size"]
    assert dict(parts[1][2]) == {"tiny~native_size": "tiny"} and parts[1][1].sequences[0].size == "native"
    code = main(["bench", "preprocessing", "--methods", "oracle", "constant-pose", "--frames", "4", "--executor",
                 "serial", "--no-plots", "--no-progress", "--no-check", "--out", str(tmp_path / "runs"),
                 "--results", str(tmp_path / "res")])  # fmt: skip
    assert code == 0
    assert (tmp_path / "runs" / "real" / "tiny~native_size" / "oracle" / "seed0-frames4").is_dir()
    ranks = pd.read_csv(tmp_path / "res" / "preprocessing.csv")
    assert set(ranks["choice"]) == {"default", "native_size"} and set(ranks["folder"]) == {"tiny"}
    md = (tmp_path / "res" / "preprocessing.md").read_text()
    assert "## tiny" in md and "### Verdicts that change" in md and "Choices run: default, native_size" in md
