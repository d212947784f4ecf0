"""One colour and marker per method, the same in every figure: the style map, its fallback by name, and every
figure function of the judge drawing each method in its own colour whatever the order or company it is shown in."""

import pathlib

import numpy as np
import pandas as pd
import pytest
from matplotlib.colors import to_hex

import eval
from eval.bench.methods import load_methods
from eval.reports import plots
from eval.reports.style import FALLBACK_COLORS, FIGURE_FORMATS, METHOD_STYLES, method_style


def test_every_method_of_the_table_has_its_own_look():
    table = load_methods()
    assert set(table) <= set(METHOD_STYLES)
    looks = [(s.color, s.marker) for s in METHOD_STYLES.values()]
    assert len(set(looks)) == len(looks)
    assert len({s.color for s in METHOD_STYLES.values()}) == len(METHOD_STYLES)  # no two methods share a colour
    assert not set(FALLBACK_COLORS) & {s.color for s in METHOD_STYLES.values()}
    assert FIGURE_FORMATS == ("png", "pdf", "svg")


def test_a_method_not_in_the_table_gets_a_look_from_its_name_alone():
    first = method_style("MySLAM")
    assert method_style("MySLAM") == first and first.color in FALLBACK_COLORS
    assert {method_style(f"user-{k}").color for k in range(40)} > {first.color}  # spread over the palette


def test_no_figure_picks_a_colour_by_position():
    root = pathlib.Path(eval.__file__).parent
    for path in root.rglob("*.py"):
        text = path.read_text()
        assert 'color=f"C{' not in text and "cmap(i % 10)" not in text and "cmap(k % 10)" not in text, path


def _captured(monkeypatch) -> list:
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path, dpi=110: figures.append(fig) or pathlib.Path(path))
    return figures


def _colours_by_label(fig) -> dict[str, set[str]]:
    """label -> the colours of the artists (lines, dots) carrying it, over every axes of ``fig``."""
    out: dict[str, set[str]] = {}
    for ax in fig.axes:
        for line in ax.get_lines():
            out.setdefault(str(line.get_label()).split(" (")[0], set()).add(to_hex(line.get_color()))
        for coll in ax.collections:
            colours = coll.get_facecolor()
            if len(colours):
                out.setdefault(str(coll.get_label()), set()).add(to_hex(colours[0]))
    return out


@pytest.mark.parametrize("order", [["CNN-SLAM", "LSD-BS", "ORB", "MySLAM"], ["MySLAM", "ORB", "LSD-BS", "CNN-SLAM"]])
def test_every_figure_draws_a_method_in_its_own_colour(monkeypatch, tmp_path, order):
    figures = _captured(monkeypatch)
    rng = np.random.default_rng(0)
    points = pd.DataFrame([{"axis": "texture", "x": x, "method": m, "ate_rmse": rng.random(),
                            "depth_percent_correct": 50 * rng.random()} for m in order for x in (0.1, 0.5, 1.0)])
    plots.save_sweep_figure(points, tmp_path / "s.png", order, {"texture": "texture density"})
    scatter = pd.DataFrame([{"sequence": "office0@kinect", "method": m, "ate_percent_length": rng.random(),
                             "depth_percent_correct": rng.random()} for m in order])
    plots.save_accuracy_scatter(scatter, tmp_path / "a.png", order, 2.0)

    class Metric:
        name, label = "ate_rmse", "ATE [m]"

    ranks = pd.DataFrame([{"domain": d, "metric": "ate_rmse", "method": m, "rank": k + 1}
                          for d in ("sim", "real") for k, m in enumerate(order)])
    plots.save_transfer_figure(ranks, tmp_path / "t.png", ["sim", "real"], [Metric()])
    gt = np.column_stack([np.linspace(0, 1, 30), np.zeros(30), np.zeros(30)])
    t = np.linspace(0, 1, 30)
    plots.save_sequence_figure(tmp_path / "q.png", "x", gt, {m: gt + 0.01 for m in order}, t,
                               {m: (t, t, t) for m in order}, {m: 3 for m in order}, {"REMODE": "no trajectory"})
    plots.save_resources_figure(tmp_path / "r.png", order, {m: np.ones(3) for m in order},
                                {m: np.ones(3) for m in order}, {})
    for fig in figures:
        seen = _colours_by_label(fig)
        for method in order:
            if method in seen:
                assert seen[method] == {method_style(method).color}, (method, seen[method])
    drawn = [fig for fig in figures if any(m in _colours_by_label(fig) for m in order)]
    assert len(drawn) == 4  # sweep, scatter, transfer and sequence figures label their lines and dots by method
    # the strip figures colour the method's dots and its tick label
    resources = figures[-1]
    for ax in resources.axes:
        for tick, method in zip(ax.get_xticklabels(), order, strict=True):
            assert to_hex(tick.get_color()) == method_style(method).color


def test_relative_error_boxes_take_their_methods_colours(monkeypatch, tmp_path):
    figures = _captured(monkeypatch)
    errors = {m: [np.abs(np.random.default_rng(k).normal(size=50)) for k in range(3)] for m in ("ORB", "CNN-SLAM")}
    plots.save_relative_error_figure(tmp_path / "e.png", "x", ["1 m", "2 m", "3 m"], errors, errors,
                                     {"REMODE": "no trajectory of its own"})  # fmt: skip
    fig = figures[0]
    for ax in fig.axes:
        boxes = [p for p in ax.patches if p.get_facecolor()[3] > 0]
        assert {to_hex(p.get_facecolor()[:3]) for p in boxes} == {method_style("ORB").color,
                                                                    method_style("CNN-SLAM").color}
        assert "[m]" in ax.get_ylabel() or "[deg]" in ax.get_ylabel()
        assert ax.get_xlabel() == "distance travelled [m]"
    names = [t.get_text() for t in fig.legends[0].get_texts()]
    assert names == ["ORB", "CNN-SLAM", "REMODE: n/a (no trajectory of its own)"]
