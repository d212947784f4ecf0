"""The per-sequence figures (every method's trajectory in one top view, ATE over time with a band across runs,
relative-error boxplots) and the speed and memory figure, in each format; what they draw tested against evo."""

from pathlib import Path

import numpy as np
import pytest

from eval.reports import plots
from eval.reports.paper_figures import figures_dir, file_slug, resources_figure, sequence_figures
from eval.reports.run_data import suite_tracks


@pytest.mark.parametrize("fmt", ["png", "pdf", "svg"])
def test_each_sequence_gets_its_figures_in_the_format_asked(folder_run, tmp_path, fmt):
    figures = sequence_figures(folder_run, suite_tracks(folder_run), tmp_path, fmt)
    folder = figures_dir(tmp_path, "table1")
    assert [f.path for f in figures] == [folder / f"{s}_{kind}.{fmt}" for s in ("office0", "living1")
                                         for kind in ("trajectories", "relative_error")]  # fmt: skip
    assert all(f.path.stat().st_size > 5000 for f in figures)
    assert (folder / "office0_trajectories.png").is_file() == (fmt != "svg")  # a PDF's PNG twin
    resources = resources_figure(folder_run, tmp_path, fmt)
    assert resources.path == tmp_path / f"table1_resources.{fmt}" and "peak resident memory" in resources.caption
    assert file_slug("office0+lit@kinect") == "office0+lit_kinect"


def test_the_ate_drawn_over_time_is_evos(folder_run, tmp_path, monkeypatch, evo):
    """LSD on living1 has one finished run: the line drawn for it is that run's ATE per pose, which evo_ape -a
    computes from the run folder's files; the top view draws its aligned positions."""
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path, dpi=110: figures.append(fig) or Path(path))
    sequence_figures(folder_run, suite_tracks(folder_run), tmp_path)
    fig = figures[2]  # living1's trajectories figure
    assert fig.get_suptitle().startswith("living1")
    top, ate = fig.axes[:2]
    drawn = next(line for line in ate.get_lines() if line.get_label() == "LSD")
    folder = folder_run.outcomes["table1/living1/LSD/seed0-frames60"].folder
    ref = evo("evo_ape", "tum", str(folder / "groundtruth.tum"), str(folder / "trajectory.tum"), "-a")
    np.testing.assert_allclose(drawn.get_ydata(), ref["arrays"]["error_array"], atol=1e-8)
    assert ate.get_ylabel() == "ATE [m]" and ate.get_xlabel() == "time [s]"
    assert top.get_xlabel() == "x [m]" and top.get_ylabel() == "y [m]"
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "REMODE: n/a (no trajectory of its own)" in legend
    assert "ORB: n/a (skipped: cannot import pyorb here)" in legend


def test_a_failed_method_is_named_not_drawn(folder_run):
    from dataclasses import replace

    from eval.reports.paper_figures import without_failed_tracks
    from eval.reports.run_data import suite_tracks

    tracks = suite_tracks(folder_run)["office0"]
    lost = replace(folder_run, records=[r.replace(metrics={**r.metrics, "tracked_share": 0.3})
                                        if (r.sequence, r.method) == ("office0", "LSD") else r
                                        for r in folder_run.records])  # fmt: skip
    kept, failed = without_failed_tracks(lost, "office0", tracks)
    assert "LSD" not in kept and failed["LSD"].startswith("X (30 %)")
    assert set(kept) == set(tracks) - {"LSD"} and kept["CNN-SLAM"] == tracks["CNN-SLAM"]
