"""The README's figures are the committed results' (eval/reports/readme.py): every generated block is what the files
give, no figure with a unit stands outside a block, and the README says what is, not what happened."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from eval.commands import cli_readme
from eval.reports import readme
from eval.reports.readme import BLOCKS, ReadmeError, blocks_of, markdown_tables, outside_blocks, render_readme

ROOT = Path(__file__).resolve().parents[3]
README = ROOT / "README.md"

# a figure with a unit: a number, then a unit of what the project measures (lengths, shares, angles, rates, times,
# sizes); definitions that are conventions, not results, are named here one by one
UNIT = r"(?:m|cm|mm|%|deg|°|fps|Hz|s|ms|min|h|MiB|GiB|MB|GB|KB)"
FIGURE = re.compile(rf"(?<![\w.])\d[\d ]*(?:\.\d+)?\s?{UNIT}(?![\w])")
CONVENTIONS = ("5000 = 1 m", "1000 = 1 m", "within 10 %")


def test_every_block_is_what_the_results_files_give():
    text = README.read_text(encoding="utf-8")
    names = [name for name, _, _ in blocks_of(text)]
    assert {"table1", "real", "speed", "depthnet", "training"} <= set(names)
    assert render_readme(text, ROOT) == text, "run: python -m eval.commands.cli_readme"


def test_no_figure_with_a_unit_outside_the_generated_blocks():
    prose = outside_blocks(README.read_text(encoding="utf-8"))
    for phrase in CONVENTIONS:
        prose = prose.replace(phrase, "")
    prose = re.sub(r"`[^`]*`", "", prose)  # command lines and file names, e.g. `--frames 300`
    found = FIGURE.findall(prose)
    assert not found, f"figures with a unit outside the generated blocks: {found}"


def test_the_readme_says_what_is():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    prose = outside_blocks(text)
    assert not re.search(r"\bround \d+", prose, flags=re.I), "history goes to CHANGELOG.md"
    assert not re.search(r"\b[0-9a-f]{7,40}\b", re.sub(r"`[^`]*`", "", prose)), "no commit hash outside blocks"


def _copy_results(tmp_path: Path) -> Path:
    for rel in ("results/table1.md", "results/table1_long.csv", "results/bench/table1.md",
                "results/bench/table1_long.csv", "results/real/real.md", "results/real/real_long.csv",
                "results/perf.md", "results/depthnet.md", "results/depthnet_real.md",
                "cnnslam/depthnet/weights/default.json"):  # fmt: skip
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(ROOT / rel, tmp_path / rel)
    return tmp_path


def test_a_changed_figure_in_a_results_file_fails_the_check(tmp_path, capsys):
    root = _copy_results(tmp_path)
    (root / "README.md").write_text(README.read_text(encoding="utf-8"), encoding="utf-8")
    assert cli_readme.main(["--check", str(root / "README.md")]) == 0
    report = root / "results/table1.md"
    text = report.read_text(encoding="utf-8")
    avg = next(line for line in text.splitlines() if line.startswith("| Avg. |"))
    cell = avg.split("|")[2]
    changed = avg.replace(cell, cell.replace(cell.strip()[:5], "9.999", 1), 1)
    report.write_text(text.replace(avg, changed), encoding="utf-8")
    assert cli_readme.main(["--check", str(root / "README.md")]) == 1
    assert "table1" in capsys.readouterr().err
    assert cli_readme.main([str(root / "README.md")]) == 0  # rewritten from the files
    assert "9.999" in (root / "README.md").read_text(encoding="utf-8")
    assert cli_readme.main(["--check", str(root / "README.md")]) == 0


def test_a_missing_results_file_is_one_clear_error(tmp_path, capsys):
    root = _copy_results(tmp_path)
    (root / "README.md").write_text(README.read_text(encoding="utf-8"), encoding="utf-8")
    (root / "results/perf.md").unlink()
    assert cli_readme.main(["--check", str(root / "README.md")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "perf.md" in err


def test_markdown_tables_known_answer():
    text = "# A\n\n## Sec one\n\ntext\n\n| x | a | b |\n|---|---:|---:|\n| r1 | 1 | 2 |\n| Avg. | 3 | 4 |\n\n" \
           "## Sec two\n| k | v |\n|---|---|\n| z | 9 |\n"
    tables = list(markdown_tables(text))
    assert [t.section for t in tables] == ["Sec one", "Sec two"]
    assert tables[0].header == ("x", "a", "b") and tables[0].row("Avg.") == {"x": "Avg.", "a": "3", "b": "4"}
    with pytest.raises(ReadmeError, match="no row 'r9'"):
        tables[0].row("r9")


def test_blocks_are_delimited_and_named():
    begin = "<!-- generated: {} (python -m eval.commands.cli_readme) -->"
    assert blocks_of(f"a\n{begin.format('speed')}\nold\n{readme.END}\nb\n") == [("speed", 2, 3)]
    with pytest.raises(ReadmeError, match="unknown block 'nope'"):
        blocks_of(f"{begin.format('nope')}\n{readme.END}\n")
    with pytest.raises(ReadmeError, match="not closed"):
        blocks_of(f"{begin.format('speed')}\nx\n")
    assert set(BLOCKS) >= {"table1", "bench", "real", "speed", "depthnet", "training"}
