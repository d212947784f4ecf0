"""The parts of every suite report (:mod:`eval.reports.report_parts`): the runs' status and machines, the relative
errors added to the long form, and the small text helpers of the header and the HTML twin."""

from pathlib import Path

import pandas as pd
import pytest

from eval.reports.report_parts import (
    markdown_image,
    one_line,
    plain_text,
    run_command,
    status_markdown,
    with_relative_errors,
)
from tests.eval.reports.test_suite_reports import fake_run, table1_values


def test_status_lists_skips_and_failures():
    suite, values = table1_values()
    text = status_markdown(fake_run(suite, values, skipped={"Laina": "no weights\nat all"}))
    assert "8 runs: 8 run now, 0 reused from earlier, 0 failed." in text and "**Laina**: no weights at all" in text
    assert "Machine: not recorded" in text  # the fake runs' timing.json has no environment


def test_status_names_the_machines_runs_came_from():
    suite, values = table1_values()
    run = fake_run(suite, values)
    env = {"cpu": "Test CPU", "isa": ["avx512f", "avx2"], "packages": {"torch": "9.9", "numpy": "1.0"}}
    keys = sorted(run.timings)
    for key in keys[:5]:
        run.timings[key]["environment"] = env
    text = status_markdown(run)
    assert "Machines: Test CPU (avx512f), torch 9.9, numpy 1.0: 5 run(s); not recorded: 3 run(s)." in text


def test_relative_errors_are_per_run_percentages():
    frame = pd.DataFrame({
        "run": ["a", "a", "a", "b", "b"], "sequence": ["s", "s", "s", "t", "t"], "method": ["m"] * 5,
        "metric": ["ate_rmse", "length_gt_m", "scale_error", "ate_rmse", "length_gt_m"],
        "value": [0.2, 10.0, 0.05, 0.1, 0.0],
    })  # fmt: skip
    out = with_relative_errors(frame).set_index(["run", "metric"])["value"]
    assert out[("a", "ate_percent_length")] == pytest.approx(2.0)  # 0.2 m over 10 m
    assert out[("a", "scale_error_percent")] == pytest.approx(5.0)
    assert ("b", "ate_percent_length") not in out.index  # zero-length path: no percentage
    assert ("b", "scale_error_percent") not in out.index  # no scale error, no row
    assert with_relative_errors(frame.iloc[:0]).empty


def test_text_helpers_of_the_header():
    assert one_line("no weights\n  at all") == "no weights at all"
    assert len(one_line("x" * 500, limit=20)) <= 20
    assert plain_text("Machines: **Test CPU**, `torch` 9.9") == "Machines: Test CPU, torch 9.9"
    assert run_command(["# Title\n\nMade by `cnnslam bench quick --frames 6` at rev abc."]) == \
        "cnnslam bench quick --frames 6"
    assert run_command(["# Title without a command"]) == "" and run_command([]) == ""


def test_markdown_image_is_relative_and_a_pdf_shows_its_png_twin(tmp_path):
    results = Path(tmp_path)
    assert markdown_image(results / "figs" / "a.png", "cap", results) == "![cap](figs/a.png)\n"
    pdf = markdown_image(results / "b.pdf", "cap", results)
    assert pdf.startswith("![cap](b.png)") and "(PDF: [b.pdf](b.pdf))" in pdf
    outside = Path("/elsewhere/c.png")
    assert markdown_image(outside, "c", results) == f"![c]({outside.as_posix()})\n"
