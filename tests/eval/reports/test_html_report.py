"""A suite's HTML report: one self-contained page with provenance, sortable result tables whose cells open the runs
behind them, the Markdown report rendered, and every run's figures, overlay, depth samples or failure; checked as
written and in a real headless Chromium (it renders, no uncaught script error, no request but the file itself, a
click on a header sorts the table, a click on a cell opens its runs)."""

import re

import pytest

from eval.reports.html_report import cell_anchor, markdown_page
from eval.reports.suite_reports import report_table1


@pytest.fixture(scope="module")
def report(folder_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("results")
    paths = report_table1(folder_run, out, "cnnslam bench table1 --sequences office0 living1 --frames 60")
    return out / "table1.html", paths


def test_the_page_holds_provenance_tables_report_and_runs(report, folder_run):
    path, paths = report
    assert path in paths
    text = path.read_text()
    for section in ("provenance", "results", "report", "runs"):
        assert f'<section id="{section}">' in text
    assert "<code>cnnslam bench table1 --sequences office0 living1 --frames 60</code>" in text
    assert "abc123" in text and "Test CPU (avx2)" in text and "the first 60 of each sequence" in text
    # a cell: median, range, the paper's value, a link to its runs; the best of the row in bold
    assert re.search(r'<a class="cell" href="#runs-office0--CNN-SLAM"><span class="best">0\.01\d</span> '
                     r'<span class="range">\[0\.01\d, 0\.01\d\]</span> <span class="paper"[^>]*>\(0\.266\)</span>',
                     text)  # fmt: skip
    assert f'id="{cell_anchor("office0", "CNN-SLAM")}"' in text
    assert 'title="no trajectory of its own"><span class="na">n/a</span>' in text  # REMODE's ATE
    assert 'title="skipped: cannot import pyorb here"><span class="na">n/a</span>' in text
    assert "RuntimeError: tracking lost for good" in text and "<pre>" in text  # the failed run and its traceback
    assert text.count("<svg") == 9  # one overlay per run with a trajectory (not REMODE's)
    assert "data:image/jpeg;base64," in text  # depth samples
    assert 'data:image/png;base64,' in text  # the report's figures inline
    assert not re.search(r'(src|href)="(https?:)?//', text) and "<script src" not in text


def test_a_report_made_of_several_suites_is_a_page_too(tmp_path):
    path = markdown_page("Some text.\n\n| a | b |\n|---|---:|\n| x | 1 |\n", tmp_path, "transfer", "Transfer")
    text = path.read_text()
    assert path.name == "transfer.html" and '<table class="sortable">' in text and "<h1>Transfer</h1>" in text


@pytest.mark.slow  # a browser starts (a few seconds)
def test_the_page_in_a_headless_browser(report, browser_page):
    path, _ = report
    page = browser_page
    page.open(path)
    assert page.errors == []
    assert [u for u in page.requests if not u.startswith("data:")] == [path.resolve().as_uri()]
    assert page.evaluate("document.querySelectorAll('table.sortable').length") >= 8
    first = "document.querySelector('#results table.sortable')"
    order = f"Array.from({first}.tBodies[0].rows).map(r => r.cells[0].textContent)"
    assert page.evaluate(order) == ["office0", "living1"]
    page.click("#results table.sortable thead th:nth-child(1)")  # by sequence name, ascending
    assert page.evaluate(order) == ["living1", "office0"]
    page.click("#results table.sortable thead th:nth-child(1)")  # again: descending
    assert page.evaluate(order) == ["office0", "living1"]
    page.click("#results table.sortable thead th:nth-child(3)")  # LSD's ATE: office0 0.180 above living1 0.177
    assert page.evaluate(order) == ["living1", "office0"]
    assert page.evaluate(f"{first}.tFoot.rows[0].cells[0].textContent") == "Avg."  # the Avg. row stays last
    details = "document.getElementById('runs-office0--CNN-SLAM')"
    assert page.evaluate(f"{details}.open") is False
    page.click("#results a.cell[href='#runs-office0--CNN-SLAM']")
    assert page.evaluate(f"{details}.open") is True
    assert page.evaluate(f"{details}.querySelectorAll('.run').length") == 2  # its two seeds
    assert page.errors == []
