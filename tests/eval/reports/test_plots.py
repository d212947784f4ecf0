from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from eval.reports.plots import (
    CORRECT_RGB,
    MISSING_RGB,
    NO_GT_RGB,
    depth_error_image,
    plot_depth_error_map,
    plot_error_over_time,
    plot_runs_strip,
    plot_trajectory_top,
    save_depth_error_figure,
    save_sweep_figure,
    save_trajectory_figure,
)


def test_depth_error_colours():
    gt = np.array([[1.0, 1.0, 1.0, 0.0]])
    est = np.array([[1.05, 1.5, 0.0, 1.0]])
    img = depth_error_image(est, gt)
    assert tuple(img[0, 0]) == CORRECT_RGB and tuple(img[0, 2]) == MISSING_RGB and tuple(img[0, 3]) == NO_GT_RGB
    assert img[0, 1, 0] > img[0, 1, 2]  # wrong: red


def test_plots_draw_into_the_given_axes():
    fig = Figure()
    ax1, ax2, ax3 = fig.subplots(1, 3)
    p = np.random.default_rng(0).normal(size=(20, 3))
    plot_trajectory_top(ax1, p, p + 0.01, plane="xz")
    assert len(ax1.get_lines()) == 4 and ax1.get_xlabel() == "x [m]" and ax1.get_ylabel() == "z [m]"
    plot_error_over_time(ax2, np.arange(20.0), np.abs(p[:, 0]))
    assert "RMSE" in ax2.get_legend().get_texts()[1].get_text()
    plot_depth_error_map(ax3, np.ones((4, 4)), np.ones((4, 4)) * 1.02)
    assert "100.0% correct, 100.0% dense" in ax3.get_title()


def test_figure_files(tmp_path):
    t = np.arange(50) / 30
    p = np.stack([np.sin(t), np.cos(t), t], axis=1)
    path = save_trajectory_figure(tmp_path / "a" / "traj.png", t, p, p + 0.02, np.full(50, 0.02), title="x")
    assert path.stat().st_size > 10_000 and path.read_bytes()[:4] == b"\x89PNG"
    gt = np.full((12, 16), 2.0)
    est = gt * np.linspace(0.8, 1.2, 16)
    path = save_depth_error_figure(tmp_path / "depth.png", [est, est], [gt, gt], titles=["kf 0", "kf 1"])
    assert path.stat().st_size > 10_000


def test_matplotlib_stays_in_plots():
    import pathlib

    import eval

    root = pathlib.Path(eval.__file__).parent
    users = [p.name for p in root.rglob("*.py") if "matplotlib" in p.read_text() and p.name != "plots.py"]
    assert users == [] or pytest.fail(f"matplotlib imported outside eval/reports/plots.py: {users}")


def test_a_method_without_a_value_says_why_in_its_column(tmp_path):
    import pandas as pd

    from eval.reports.plots import plot_runs_strip

    frame = pd.DataFrame({"sequence": ["s1", "s1"], "method": ["A", "A"], "metric": ["ate_rmse"] * 2,
                          "value": [0.1, 0.2]})  # fmt: skip
    ax = Figure().subplots()
    plot_runs_strip(ax, frame, "ate_rmse", ["A", "REMODE"], ["s1"], {"REMODE": "no trajectory of its own"})
    assert [t.get_text() for t in ax.texts] == ["n/a: no trajectory of its own"]
    assert ax.texts[0].get_position()[0] == 1  # in REMODE's column


@pytest.mark.parametrize("suffix", ["png", "pdf", "svg"])
def test_a_figure_in_each_format_and_a_pdf_with_its_png_twin(tmp_path, suffix):
    from eval.reports.plots import save_figure

    def figure():
        fig = Figure()
        fig.subplots().plot([0, 1], [1, 0])
        return fig

    path = save_figure(figure(), tmp_path / f"f.{suffix}")
    head = {"png": b"\x89PNG", "pdf": b"%PDF", "svg": b"<?xml"}[suffix]
    assert path.read_bytes().startswith(head)
    assert (tmp_path / "f.png").is_file() == (suffix != "svg")  # a PDF's twin for the Markdown and the HTML
    if suffix != "png":  # no creation date: the same figure, the same bytes
        again = save_figure(figure(), tmp_path / f"g.{suffix}")
        assert again.read_bytes() == path.read_bytes()


def _runs_frame(rows):
    """A long frame from (sequence, method, run, tracked_share, ate_rmse) runs."""
    return pd.DataFrame([{"sequence": s, "method": m, "run": r, "metric": metric, "value": v}
                         for s, m, r, share, ate in rows
                         for metric, v in (("tracked_share", share), ("ate_rmse", ate))])  # fmt: skip


def test_a_failed_run_is_its_mark_and_share_not_a_dot_at_its_value():
    frame = _runs_frame([("s1", "A", "r0", 1.0, 0.1), ("s1", "A", "r1", 1.0, 0.3), ("s1", "A", "r2", 0.22, 7.0),
                         ("s2", "A", "q0", 0.0, 0.003)])  # fmt: skip
    ax = Figure().subplots()
    plot_runs_strip(ax, frame, "ate_rmse", ["A"], ["s1", "s2"])
    dots = np.concatenate([c.get_offsets()[:, 1] for c in ax.collections if hasattr(c, "get_offsets")
                           and len(c.get_offsets())])  # fmt: skip
    assert 7.0 not in dots and 0.003 not in dots and {0.1, 0.3} <= set(np.round(dots, 6))
    texts = [t.get_text() for t in ax.texts]
    assert "X\n22 %" in texts and "X\n0 %" in texts
    bars = [seg for c in ax.collections if c.__class__.__name__ == "LineCollection" for seg in c.get_segments()]
    assert [round(float(seg[0][1]), 6) for seg in bars] == [0.2]  # s1: the median of the two that did not fail


def test_the_sweep_figure_marks_a_failed_setting(tmp_path, monkeypatch):
    import eval.reports.plots as plots

    drawn = {}
    monkeypatch.setattr(plots, "_save", lambda fig, path, dpi: drawn.setdefault("fig", fig) and Path(path))
    points = pd.DataFrame({"axis": ["noise"] * 4, "x": [1.0, 1.0, 2.0, 2.0], "method": ["A"] * 4,
                           "ate_rmse": [0.1, 0.2, 5.0, 6.0], "depth_percent_correct": [10.0, 12.0, 1.0, 1.0],
                           "tracked_share": [1.0, 1.0, 0.3, 0.1]})  # fmt: skip
    save_sweep_figure(points, tmp_path / "sweep.png", ["A"], {"noise": "noise"})
    ate, depth = drawn["fig"].axes[:2]
    assert [t.get_text() for t in ate.texts] == ["X\n20 %"]  # x = 2: both runs failed, median share 20 %
    (line,) = ate.get_lines()
    assert list(line.get_xdata()) == [1.0] and list(line.get_ydata()) == [pytest.approx(0.15)]
