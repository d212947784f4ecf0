import io

import numpy as np
import pandas as pd
import pytest

from eval.reports.paper_table1 import (
    PAPER_AVG_ATE,
    PAPER_AVG_CORRECT_DEPTH,
    PAPER_METHODS,
    PAPER_SEQUENCES,
    paper_table1_frame,
)
from eval.reports.tables import (
    AVG_LABEL,
    TABLE1_BLOCKS,
    format_table,
    table1,
    table_to_latex,
    table_to_markdown,
    write_table,
)


@pytest.fixture(scope="module")
def paper():
    return table1(paper_table1_frame(), methods=PAPER_METHODS, sequences=PAPER_SEQUENCES)


def test_paper_table_has_the_papers_shape_and_values(paper):
    assert paper.shape == (10, 12) and paper.index[-1] == AVG_LABEL
    assert paper.loc["ICL/office0", ("Abs. Trajectory Error [m]", "CNN-SLAM")] == 0.266
    assert paper.loc["TUM/seq3", ("Perc. Correct Depth [%]", "REMODE")] == 6.739
    assert paper[("Abs. Trajectory Error [m]", "REMODE")].isna().all()  # REMODE has no ATE


def test_avg_row_reproduces_the_papers_printed_averages(paper):
    for method in PAPER_METHODS:
        ate = paper.loc[AVG_LABEL, ("Abs. Trajectory Error [m]", method)]
        depth = paper.loc[AVG_LABEL, ("Perc. Correct Depth [%]", method)]
        if np.isnan(PAPER_AVG_ATE[method]):
            assert np.isnan(ate)
        else:
            assert ate == pytest.approx(PAPER_AVG_ATE[method], abs=5e-4)
        if method == "Laina":
            # the paper prints 18.452; its nine printed values average to 18.442
            assert f"{depth:.3f}" == "18.442" and PAPER_AVG_CORRECT_DEPTH[method] == 18.452
        else:
            assert depth == pytest.approx(PAPER_AVG_CORRECT_DEPTH[method], abs=5e-4)


def test_runs_are_averaged_and_incomplete_columns_get_no_average():
    frame = pd.DataFrame(
        [
            ("s1", "A", "ate_rmse", 0.1),
            ("s1", "A", "ate_rmse", 0.3),  # a second seed
            ("s2", "A", "ate_rmse", 0.4),
            ("s1", "B", "ate_rmse", 0.5),
            ("s1", "A", "depth_percent_correct", 20.0),
            ("s2", "A", "depth_percent_correct", 30.0),
        ],
        columns=["sequence", "method", "metric", "value"],
    )
    t = table1(frame)
    assert t.loc["s1", ("Abs. Trajectory Error [m]", "A")] == pytest.approx(0.2)
    assert t.loc[AVG_LABEL, ("Abs. Trajectory Error [m]", "A")] == pytest.approx(0.3)
    assert np.isnan(t.loc[AVG_LABEL, ("Abs. Trajectory Error [m]", "B")])  # B has no s2
    assert t.loc[AVG_LABEL, ("Perc. Correct Depth [%]", "A")] == 25.0
    text = format_table(t)
    assert text.loc["s2", ("Abs. Trajectory Error [m]", "B")] == "-"
    assert ("Perc. Correct Depth [%]", "B") not in table1(frame, drop_empty=True).columns


def test_writers(paper, tmp_path):
    md = table_to_markdown(paper)
    assert md.splitlines()[0].startswith("| sequence | Abs. Trajectory Error [m]: CNN-SLAM |")
    assert "| Avg. | 0.246 | 0.562 |" in md and "| - |" in md
    tex = table_to_latex(paper, caption="Table 1")
    assert r"\multicolumn{6}{c}{Abs. Trajectory Error [m]}" in tex and r"\toprule" in tex and " - &" in tex
    paths = write_table(paper, tmp_path / "out" / "table1")
    assert [p.suffix for p in paths] == [".csv", ".md", ".tex"] and all(p.stat().st_size > 0 for p in paths)
    back = pd.read_csv(io.StringIO(paths[0].read_text()), header=[0, 1], index_col=0)
    np.testing.assert_allclose(back.to_numpy(), paper.to_numpy(), rtol=1e-5)


def test_missing_columns_are_reported():
    from eval.errors import EvalError

    with pytest.raises(EvalError, match="metric"):
        table1(pd.DataFrame({"sequence": [], "method": [], "value": []}))


def test_cells_are_medians_with_their_range_and_the_average_is_per_seed():
    from eval.reports.tables import spread_of

    rows = [("a", 0, 1.0), ("a", 1, 2.0), ("a", 2, 9.0), ("b", 0, 3.0), ("b", 1, 3.0), ("b", 2, 3.0)]
    frame = pd.DataFrame([{"sequence": s, "method": "X", "metric": "ate_rmse", "value": v, "seed": k}
                          for s, k, v in rows])  # fmt: skip
    t = table1(frame)
    lo, hi, partial, _ = spread_of(frame)
    assert partial == {}  # no run column: no coverage to read
    col = ("Abs. Trajectory Error [m]", "X")
    assert t.at["a", col] == 2.0 and (lo.at["a", col], hi.at["a", col]) == (1.0, 9.0)  # median [min, max]
    # per-seed averages over a and b: 2.0, 2.5, 6.0 -> Avg. median 2.5 in [2.0, 6.0]
    assert t.at["Avg.", col] == 2.5 and (lo.at["Avg.", col], hi.at["Avg.", col]) == (2.0, 6.0)
    md = table_to_markdown(t, spread=spread_of(frame))
    assert "| a | 2.000 [1.000, 9.000] |" in md and "| b | 3.000 |" in md  # runs that agree: a bare number


def test_a_suite_whose_runs_all_failed_gives_empty_tables_not_an_error():
    """No run scored (every run of a crashing agent failed): the long frame is empty with a numeric value column,
    and the statistics and Table 1 come out empty instead of pandas' quantile error on an object column."""
    from eval.metrics.results import runs_frame
    from eval.reports.tables import cell_statistics

    frame = runs_frame([])
    assert frame.empty and frame["value"].dtype == float
    assert cell_statistics(frame).empty
    as_objects = pd.DataFrame({c: pd.Series(dtype=object) for c in ("sequence", "method", "metric", "value")})
    assert cell_statistics(as_objects).empty
    assert table1(frame).empty or table1(frame).isna().all().all()


def test_a_run_covering_part_of_its_sequence_shows_it_and_gets_no_average():
    """Coverage = a run's ATE pose pairs over its frames (eval.metrics.results.coverage): the cell says
    ``(10/60 frames)`` (its least covered run), and the method's Avg. is missing, not an average of part."""
    from eval.reports.tables import partial_cells, spread_of

    rows = []
    for run, (seq, pairs, ate) in enumerate((("a", 60, 0.5), ("b", 10, 0.1), ("b", 30, 0.2))):
        rows += [{"run": run, "sequence": seq, "method": "X", "metric": m, "value": v, "seed": run}
                 for m, v in (("ate_rmse", ate), ("ate_pairs", pairs), ("frames", 60.0))]
    frame = pd.DataFrame(rows)
    assert partial_cells(frame) == {("b", "X"): (10, 60)}
    t = table1(frame)
    col = ("Abs. Trajectory Error [m]", "X")
    assert t.at["b", col] == pytest.approx(0.15) and np.isnan(t.at["Avg.", col])
    md = table_to_markdown(t, spread=spread_of(frame))
    assert "| b | 0.150 [0.100, 0.200] (10/60 frames) |" in md and "| a | 0.500 |" in md and "| Avg. | - |" in md


def test_latex_sets_the_best_of_each_row_in_bold_among_the_methods_fed_no_ground_truth():
    import pandas as pd

    from eval.reports.tables import TABLE1_BLOCKS, best_cells, better_direction, table1, table_to_latex

    rows = [("s1", "A", "ate_rmse", 0.1), ("s1", "B", "ate_rmse", 0.2), ("s1", "oracle", "ate_rmse", 0.0),
            ("s1", "A", "depth_percent_correct", 10.0), ("s1", "B", "depth_percent_correct", 30.0),
            ("s1", "oracle", "depth_percent_correct", 100.0), ("s2", "A", "ate_rmse", 0.3),
            ("s2", "B", "ate_rmse", 0.3), ("s2", "A", "depth_percent_correct", 5.0),
            ("s2", "B", "depth_percent_correct", 1.0)]  # fmt: skip
    table = table1(pd.DataFrame(rows, columns=["sequence", "method", "metric", "value"]))
    best = best_cells(table, TABLE1_BLOCKS, exclude=["oracle"])
    ate, depth = (t for t, _ in TABLE1_BLOCKS)
    assert best == {("s1", (ate, "A")), ("s2", (ate, "A")), ("s2", (ate, "B")), ("s1", (depth, "B")),
                    ("s2", (depth, "A")), ("Avg.", (ate, "A")), ("Avg.", (depth, "B"))}
    # ties both bold; the oracle's 0 m and 100 % are no competitors; the Avg. row is a row too
    latex = table_to_latex(table, blocks=TABLE1_BLOCKS, exclude=["oracle"])
    assert "s1 & \\textbf{0.100} & 0.200 & 0.000 & 10.000 & \\textbf{30.000} & 100.000 \\\\" in latex
    assert "{lrrrrrr}" in latex
    assert better_direction("ate_sim3_rmse") == "lower" and better_direction("tracked_share") == "higher"
    assert better_direction("scale") is None and better_direction("rpe_trans_rmse_p10") == "lower"


# ------------------------------------------------------------------------------------------------- failures
def _runs(rows):
    """A long frame from (sequence, method, seed, tracked_share, ate_rmse) runs, one run id each."""
    out = []
    for seq, method, seed, share, ate in rows:
        run = f"{seq}/{method}/seed{seed}"
        out += [{"sequence": seq, "method": method, "metric": "tracked_share", "value": share, "seed": seed,
                 "run": run},
                {"sequence": seq, "method": method, "metric": "ate_rmse", "value": ate, "seed": seed, "run": run},
                {"sequence": seq, "method": method, "metric": "depth_percent_correct", "value": 10.0 * ate,
                 "seed": seed, "run": run}]  # fmt: skip
    return pd.DataFrame(out)


FAILED_FRAME = [
    # A never initialises on s2 (the ORB-SLAM3 case: tracked 0 on every seed, yet an ATE of its identity poses)
    *(("s1", "A", k, 1.0, 0.1 + 0.01 * k) for k in range(3)),
    *(("s2", "A", k, 0.0, 0.003) for k in range(3)),
    *(("s3", "A", k, 0.95, 0.3) for k in range(3)),
    # B: one of three seeds lost on s1 (a figure over the other two, "1/3 failed"), whole elsewhere
    ("s1", "B", 0, 0.22, 9.0), ("s1", "B", 1, 1.0, 0.2), ("s1", "B", 2, 1.0, 0.4),
    *(("s2", "B", k, 1.0, 0.5) for k in range(3)),
    *(("s3", "B", k, 1.0, 0.6) for k in range(3)),
]


def test_a_failed_cell_shows_the_mark_and_its_share_never_its_figure():
    from eval.reports.tables import cell_failures, spread_of, table_to_csv

    frame = _runs(FAILED_FRAME)
    t = table1(frame)
    spread = spread_of(frame)
    ate = ("Abs. Trajectory Error [m]", "A")
    assert np.isnan(t.loc["s2", ate])  # no figure in the numeric table
    assert cell_failures(frame)[("s2", "A")].is_failure and not cell_failures(frame)[("s1", "B")].is_failure
    md = table_to_markdown(t, spread=spread)
    row = next(line for line in md.splitlines() if line.startswith("| s2 |"))
    assert row.split(" | ")[1] == "X (0 %)" and "0.003" not in md
    assert "| s3 | 0.300 (95 %) |" in md  # below 100 % tracked, not a failure: its share beside it
    assert "0.300 [0.200, 0.400] (1/3 failed)" in md  # B on s1: median of the two runs that did not fail
    csv = table_to_csv(t, spread)
    assert "s2,X (0 %)," in csv and "0.003" not in csv
    tex = table_to_latex(t, spread=spread, blocks=TABLE1_BLOCKS)
    assert "s2 & X (0 \\%) &" in tex and "0.003" not in tex


def test_an_average_over_a_row_with_failures_says_how_many_sequences_it_covers():
    from eval.reports.tables import spread_of

    frame = _runs(FAILED_FRAME)
    t = table1(frame)
    ate = ("Abs. Trajectory Error [m]", "A")
    # A's Avg. over s1 and s3 only: per seed (0.1 + 0.3, 0.11 + 0.3, 0.12 + 0.3) / 2, median 0.205
    assert t.loc[AVG_LABEL, ate] == pytest.approx(0.205)
    md = table_to_markdown(t, spread=spread_of(frame))
    avg = next(line for line in md.splitlines() if line.startswith(f"| {AVG_LABEL} |"))
    assert avg.split(" | ")[1].startswith("0.205") and avg.split(" | ")[1].endswith("(2/3)")
    assert "(2/3)" not in avg.split(" | ")[2]  # B has no failed cell: a plain average
    # every sequence a failure: the Avg. is the mark with 0 covered
    only = _runs([("s1", "C", 0, 0.1, 1.0), ("s2", "C", 0, 0.0, 1.0)])
    md = table_to_markdown(table1(only), spread=spread_of(only))
    assert f"| {AVG_LABEL} | X (0/2) |" in md


def test_a_record_without_a_pose_is_a_failure_in_a_table():
    """An SfM run that registered none of its images: no pose scored (ate_pairs 0)."""
    from eval.reports.tables import cell_failures

    frame = pd.DataFrame([
        {"sequence": "s1", "method": "COLMAP", "metric": m, "value": v, "run": "r0"}
        for m, v in (("ate_rmse", 0.003), ("ate_pairs", 0.0), ("frames", 3.0))
    ])  # fmt: skip
    assert cell_failures(frame)[("s1", "COLMAP")].is_failure
    assert np.isnan(table1(frame).loc["s1", ("Abs. Trajectory Error [m]", "COLMAP")])
