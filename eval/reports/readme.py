"""The README's figures, rendered from the committed results: every figure or table the README quotes sits in a
generated block, made here from the files under ``results/`` (and the depth network's manifest), with the revision
the figures were made at.

A block is delimited in the Markdown by two HTML comments that Markdown viewers do not show::

    <!-- generated: table1 (python -m eval.commands.cli_readme) -->
    ... what :data:`BLOCKS` ``["table1"]`` renders ...
    <!-- end generated -->

:func:`render_readme` replaces every block's body with what the files give now; ``python -m eval.commands.cli_readme``
rewrites ``README.md`` and ``--check`` exits 1 when a block differs from the files (``make test`` runs the check,
``tests/eval/reports/test_readme_blocks.py``). The figures are quoted from the reports the suites wrote (their tables'
cells, verbatim), so the README shows exactly what the report shows, failure marks included. Staleness (whether the
current code would give the same figures) is the business of ``cnnslam results status``; a block names the
revisions its figures were made at.
"""

from __future__ import annotations

import csv
import json
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from eval.errors import InputError

ROOT = Path(__file__).resolve().parents[2]  # the repository (results/, README.md, cnnslam/ beside eval/)
BEGIN = re.compile(r"^<!-- generated: (?P<name>[a-z0-9_]+) \(python -m eval\.commands\.cli_readme\) -->$")
END = "<!-- end generated -->"


class ReadmeError(InputError):
    """A README block or a results file it is rendered from is missing or malformed."""


# --------------------------------------------------------------------------------------- reading the reports
@dataclass(frozen=True)
class MarkdownTable:
    """One pipe table of a Markdown report: the ``section`` heading above it (without ``#``), its ``header`` cells
    and its ``rows`` (lists of cell strings, as written)."""

    section: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]

    def row(self, label: str) -> dict[str, str]:
        """The row whose first cell is ``label``, as ``{header: cell}``."""
        for row in self.rows:
            if row and row[0] == label:
                return dict(zip(self.header, row, strict=False))
        raise ReadmeError(f"table '{self.section}' has no row {label!r}; rows: {', '.join(r[0] for r in self.rows)}")


def _cells(line: str) -> tuple[str, ...]:
    return tuple(c.strip() for c in line.strip().strip("|").split("|"))


def markdown_tables(text: str) -> Iterator[MarkdownTable]:
    """Every pipe table of a Markdown text, with the heading of the section it is in."""
    section = ""
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("#"):
            section = line.lstrip("#").strip()
        elif line.startswith("|") and i + 1 < len(lines) and re.match(r"^\|[\s:|-]+\|$", lines[i + 1].strip()):
            header = _cells(line)
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(_cells(lines[i]))
                i += 1
            yield MarkdownTable(section, header, tuple(rows))
            continue
        i += 1


def report_table(path: Path, section: str) -> MarkdownTable:
    """The first table under the heading ``section`` of the report at ``path``."""
    if not path.is_file():
        raise ReadmeError(f"results file {path} is missing (the README quotes it; make it with its suite)")
    for table in markdown_tables(path.read_text(encoding="utf-8")):
        if table.section == section:
            return table
    raise ReadmeError(f"{path}: no table under the heading {section!r}")


def run_revisions(long_csv: Path) -> list[str]:
    """The git revisions a suite's runs were made at (``git_revision`` of its ``*_long.csv``), sorted, each once;
    a revision made from an uncommitted tree ends in ``-dirty``."""
    if not long_csv.is_file():
        raise ReadmeError(f"results file {long_csv} is missing (the README quotes its revisions)")
    with long_csv.open(newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        if reader.fieldnames is None or "git_revision" not in reader.fieldnames:
            return []
        return sorted({row["git_revision"] for row in reader if row.get("git_revision")})


def run_count(long_csv: Path) -> int:
    """How many runs a suite's ``*_long.csv`` holds (distinct ``run`` values)."""
    with long_csv.open(newline="", encoding="utf-8") as handle:
        return len({row["run"] for row in csv.DictReader(handle) if row.get("run")})


def _method(header: str) -> str:
    """A method's column name: ``CNN-SLAM`` or ``ATE after Sim(3) alignment [m]: CNN-SLAM`` -> ``CNN-SLAM``."""
    return header.rsplit(": ", 1)[-1]


def _made_at(long_csv: Path, root: Path) -> str:
    revisions = run_revisions(long_csv)
    where = long_csv.relative_to(root).as_posix()
    made = ", ".join(f"`{r}`" for r in revisions) if revisions else "an unrecorded revision"
    return f"{run_count(long_csv)} runs made at {made} (`{where}`; `cnnslam results status` says whether current)"


# ------------------------------------------------------------------------------------------------ the blocks
def _avg_table(report: Path, long_csv: Path, sections: Sequence[tuple[str, str]], root: Path) -> str:
    """The ``Avg.`` row of each of ``sections`` (heading, label) of a suite report, one table, methods as columns."""
    tables = [(label, report_table(report, heading)) for heading, label in sections]
    methods = [_method(h) for h in tables[0][1].header[1:] if _method(h) != "oracle"]
    lines = ["| | " + " | ".join(methods) + " |", "|---|" + "---:|" * len(methods)]
    for label, table in tables:
        avg = {_method(h): cell for h, cell in table.row("Avg.").items()}
        lines.append(f"| {label} | " + " | ".join(avg.get(m, "-") for m in methods) + " |")
    lines += ["", _made_at(long_csv, root) + "."]  # a blank line ends the table
    return "\n".join(lines)


TABLE1_SECTIONS = (("Abs. Trajectory Error [m]", "ATE, SE(3) [m]"),
                   ("Scale-aligned ATE, Sim(3) [m]", "ATE, Sim(3) [m]"),
                   ("Perc. Correct Depth [%]", "Correct depth [%]"))  # fmt: skip


def block_table1(root: Path) -> str:
    """The committed Table 1 (``results/table1.md``): its Avg. rows, median [min, max] (the paper's value)."""
    return _avg_table(root / "results/table1.md", root / "results/table1_long.csv", TABLE1_SECTIONS, root)


def block_bench(root: Path) -> str:
    """``make bench``'s last committed output (``results/bench/table1.md``): its Avg. rows."""
    return _avg_table(root / "results/bench/table1.md", root / "results/bench/table1_long.csv", TABLE1_SECTIONS,
                      root)


REAL_COLUMNS = (("Abs. Trajectory Error [m]", "ATE, SE(3) [m]"),
                ("ATE after Sim(3) alignment [m]", "ATE, Sim(3) [m]"),
                ("Perc. Correct Depth [%]", "Correct depth [%]"))  # fmt: skip


def block_real(root: Path) -> str:
    """The real suite (``results/real/real.md``): one table, methods as columns, a row per (folder, figure)."""
    report = root / "results/real/real.md"
    if not report.is_file():
        raise ReadmeError(f"results file {report} is missing (the README quotes it; make it with its suite)")
    table = next(iter(markdown_tables(report.read_text(encoding="utf-8"))), None)
    if table is None:
        raise ReadmeError(f"{report}: no table")
    folders = [r[0] for r in table.rows if r[0] != "Avg."]
    methods = list(dict.fromkeys(h.split(": ", 1)[1] for h in table.header[1:] if ": " in h))
    methods = [m for m in methods if m != "oracle"]
    lines = ["| | " + " | ".join(methods) + " |", "|---|" + "---:|" * len(methods)]
    for folder in folders:
        row = table.row(folder)
        for column, label in REAL_COLUMNS:
            lines.append(f"| {folder}: {label} | " + " | ".join(row.get(f"{column}: {m}", "-") for m in methods) + " |")
    lines += ["", _made_at(root / "results/real/real_long.csv", root) + "."]  # a blank line ends the table
    return "\n".join(lines)


def _perf_value(table: MarkdownTable, figure: str) -> str:
    return table.row(figure)["value"]


def block_speed(root: Path) -> str:
    """CNN-SLAM's speed (``results/perf.md``): tracking and the whole two-thread system, and the machine."""
    path = root / "results/perf.md"
    table = report_table(path, "CNN-SLAM tracking and whole-system frames per second (office0)")
    text = path.read_text(encoding="utf-8")
    made = re.search(r"^Made by `cnnslam bench perf` on (?P<machine>.+?), 1-min load.*?git revision (?P<rev>\S+?)\.",
                     text, re.MULTILINE)
    if made is None:
        raise ReadmeError(f"{path}: no 'Made by `cnnslam bench perf` on ...' line")
    return (f"CNN-SLAM at 320x240 on office0 with the network: tracking {_perf_value(table, 'tracking_fps')} fps, "
            f"the whole two-thread system {_perf_value(table, 'whole_system_fps')} fps "
            f"({made['machine']}; `results/perf.md`, made at `{made['rev']}`).")


def block_depthnet(root: Path) -> str:
    """The shipped network on simulated test rooms (``results/depthnet.md``) and on real frames
    (``results/depthnet_real.md``): share of pixels within 10 % after eq. 5, AbsRel, the real frames' scale."""
    sim = report_table(root / "results/depthnet.md", "Depth + semantic network: validation on the test sequences")
    real = report_table(root / "results/depthnet_real.md", "Depth network on real frames")
    lines = ["| frames | within 10 % (eq. 5) [%] | AbsRel (eq. 5) | scale (sensor / eq. 5) |", "|---|---:|---:|---|"]
    overall = sim.row("**all**")
    lines.append(f"| simulated test rooms (`results/depthnet.md`) | {overall['within 10 % eq. 5 [%]']} | "
                 f"{overall['AbsRel eq. 5']} | - |")
    for row in real.rows:
        if row[0].endswith("(real)"):
            cells = dict(zip(real.header, row, strict=False))
            lines.append(f"| {row[0]} (`results/depthnet_real.md`) | {cells['within 10 % eq. 5 [%]']} | "
                         f"{cells['AbsRel eq. 5']} | {cells['scale (sensor / eq. 5)']} |")
    return "\n".join(lines)


def block_training(root: Path) -> str:
    """How the shipped weights were made (``cnnslam/depthnet/weights/default.json``): where and how long."""
    path = root / "cnnslam/depthnet/weights/default.json"
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ReadmeError(f"the weights' manifest {path} cannot be read: {exc}") from None
    data, training = manifest.get("data", {}), manifest.get("training", {})
    render_s = data.get("generation", {}).get("wall_time_s")
    train_s = manifest.get("wall_time_s", training.get("wall_time_s"))
    device = next((v for v in _find_key(manifest, "device") if v not in ("cuda", "cpu")), None)
    frames = data.get("generation", {}).get("train_frames")
    parts = [f"{frames} training frames" if frames else None,
             f"rendered in {render_s:.0f} s" if isinstance(render_s, int | float) else None,
             f"trained in {train_s:.0f} s" if isinstance(train_s, int | float) else None,
             f"on {device}" if device else None]  # fmt: skip
    return "The shipped weights: " + ", ".join(p for p in parts if p) + " (`cnnslam/depthnet/weights/default.json`)."


def _find_key(data: object, key: str) -> Iterator[object]:
    if isinstance(data, dict):
        for k, v in data.items():
            if k == key:
                yield v
            yield from _find_key(v, key)
    elif isinstance(data, list):
        for v in data:
            yield from _find_key(v, key)


def block_failure_rule(root: Path) -> str:
    """The failure rule every report states (:data:`eval.metrics.results.FAILURE_RULE`, its threshold the code's)."""
    from eval.metrics.results import FAILURE_RULE

    return FAILURE_RULE + " (`eval/metrics/results.py`)"


BLOCKS: dict[str, Callable[[Path], str]] = {
    "failure_rule": block_failure_rule,
    "table1": block_table1,
    "bench": block_bench,
    "real": block_real,
    "speed": block_speed,
    "depthnet": block_depthnet,
    "training": block_training,
}


# ------------------------------------------------------------------------------------------------ the README
def changed_blocks(text: str, root: Path = ROOT) -> list[str]:
    """The names of the README text's generated blocks whose body differs from what the files under ``root`` give."""
    lines = text.splitlines()
    return [name for name, start, end in blocks_of(text) if lines[start:end] != BLOCKS[name](root).splitlines()]


def blocks_of(text: str) -> list[tuple[str, int, int]]:
    """The generated blocks of a README text: (name, first body line, end line) as 0-based line indices."""
    lines = text.splitlines()
    found, start, name = [], None, ""
    for i, line in enumerate(lines):
        begin = BEGIN.match(line)
        if begin:
            if start is not None:
                raise ReadmeError(f"README line {i + 1}: block {begin['name']!r} opens inside block {name!r}")
            start, name = i + 1, begin["name"]
            if name not in BLOCKS:
                raise ReadmeError(f"README line {i + 1}: unknown block {name!r}; valid: {', '.join(BLOCKS)}")
        elif line == END:
            if start is None:
                raise ReadmeError(f"README line {i + 1}: '{END}' without a block")
            found.append((name, start, i))
            start = None
    if start is not None:
        raise ReadmeError(f"README: block {name!r} is not closed by '{END}'")
    return found


def render_readme(text: str, root: Path = ROOT) -> str:
    """``text`` with every generated block's body rendered anew from the files under ``root``."""
    lines = text.splitlines()
    out, previous = [], 0
    for name, start, end in blocks_of(text):
        out += lines[previous:start]
        out += BLOCKS[name](root).splitlines()
        previous = end
    out += lines[previous:]
    return "\n".join(out) + ("\n" if text.endswith("\n") else "")


def outside_blocks(text: str) -> str:
    """The README text with the generated blocks' bodies (and fenced code) left out: what a person wrote."""
    lines = text.splitlines()
    keep = [True] * len(lines)
    for _, start, end in blocks_of(text):
        keep[start:end] = [False] * (end - start)
    fenced = False
    for i, line in enumerate(lines):
        if line.startswith("```"):
            fenced = not fenced
            keep[i] = False
        elif fenced:
            keep[i] = False
    return "\n".join(line for line, k in zip(lines, keep, strict=True) if k)
