import numpy as np
import pytest
from matplotlib.figure import Figure

from eval.reports.plots import (
    CORRECT_RGB,
    MISSING_RGB,
    NO_GT_RGB,
    depth_error_image,
    plot_depth_error_map,
    plot_error_over_time,
    plot_trajectory_top,
    save_depth_error_figure,
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
