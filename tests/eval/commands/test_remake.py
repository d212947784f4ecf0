"""``cnnslam results make``: a stale result is remade by the command its manifest records, with the runs whose
fingerprint is current reused; ``--dry-run`` plans and runs nothing; results of other commands are remade by theirs."""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import textwrap
from pathlib import Path

import pytest

from eval.bench import fingerprint, provenance
from eval.bench.provenance import MANIFEST_SUFFIX, TreeState
from eval.commands import remake
from slamcommon import provenance as shared

FIRST = "from fakemake.shared import OracleAgent\n\n\nclass First(OracleAgent):\n    pass\n"
SECOND = "from fakemake.shared import ConstantPoseAgent\n\n\nclass Second(ConstantPoseAgent):\n    pass\n"
CLEAN = TreeState("0123456789ab", ())


def touch(path: Path, text: str) -> None:
    """Write ``text`` and move the file's time on (a coarse clock would otherwise keep it)."""
    path.write_text(text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


def cli(*args: str) -> tuple[int, str]:
    """``cnnslam ARGS``: exit status and what it printed."""
    from cnnslam.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(list(args))
    return code, out.getvalue()


@pytest.fixture
def clean_tree(monkeypatch):
    """Manifests written as from a committed tree."""
    monkeypatch.setattr(provenance, "tree_state", lambda root=None: CLEAN)
    monkeypatch.setattr(shared, "tree_state", lambda root=None: CLEAN)


@pytest.fixture
def fakemake(tmp_path, monkeypatch, clean_tree):
    """Two copied agents in a package of their own, ``fakemake`` (``first``, ``second``), on sys.path and among the
    packages fingerprints follow, and a method file naming them."""
    root = tmp_path / "pkg" / "fakemake"
    root.mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "shared.py").write_text("from sim_envs.agents import ConstantPoseAgent, OracleAgent\n\n"
                                    "__all__ = ['ConstantPoseAgent', 'OracleAgent']\n")
    (root / "first.py").write_text(FIRST)
    (root / "second.py").write_text(SECOND)
    monkeypatch.syspath_prepend(str(tmp_path / "pkg"))
    monkeypatch.setattr(fingerprint, "PROJECT_PACKAGES", (*fingerprint.PROJECT_PACKAGES, "fakemake"))
    (tmp_path / "methods.toml").write_text(textwrap.dedent("""
        [methods.First]
        entry_point = "fakemake.first:First"
        metrics = ["trajectory", "depth"]
        [methods.Second]
        entry_point = "fakemake.second:Second"
        metrics = ["trajectory", "depth"]
        """))
    return root


@pytest.mark.slow
def test_make_remakes_a_stale_result_reusing_the_runs_that_are_current(tmp_path, fakemake):
    results, runs = tmp_path / "results", tmp_path / "runs"
    code, _ = cli("bench", "table1", "--sequences", "office0", "--frames", "4", "--seeds", "0", "--methods", "First",
                  "Second", "--method-file", str(tmp_path / "methods.toml"), "--executor", "serial", "--no-plots",
                  "--no-progress", "--out", str(runs), "--results", str(results))  # fmt: skip
    assert code == 0
    manifest = json.loads((results / f"table1{MANIFEST_SUFFIX}").read_text())
    assert "--method-file" in manifest["command"] and len(manifest["runs"]) == 2
    make = ("results", "make", "--results", str(results), "--out", str(runs), "--executor", "serial")
    assert cli(*make, "--dry-run") == (0, "0 result(s) to remake (0 of them not remade), about 0 s with 2 run(s) in "
                                          "parallel\n")  # all current: nothing to do
    first_run = next(runs.rglob("First/*/metrics.json"))
    second_run = next(runs.rglob("Second/*/metrics.json"))
    second_before = second_run.stat().st_mtime_ns

    touch(fakemake / "first.py", FIRST + "# an edit\n")  # stale: First's run only
    assert cli("results", "status", "--results", str(results))[0] == 1
    code, plan = cli(*make, "--dry-run")
    assert code == 0 and plan.splitlines()[0].startswith("table1: 2 runs: 1 reused, 1 to make; about ")
    assert plan.splitlines()[1].strip() == manifest["command"]
    assert cli("results", "status", "--results", str(results))[0] == 1  # a dry run changes nothing

    code, out = cli(*make)
    assert code == 0, out
    assert "table1: 2 runs (1 run now, 1 reused, 0 failed)" in out
    assert out.rstrip().endswith("1 of 1 result(s) current, 0 stale")
    assert second_run.stat().st_mtime_ns == second_before and first_run.is_file()
    assert cli("results", "status", "--results", str(results))[0] == 0


def test_an_output_manifest_judges_its_files_and_make_runs_its_command(tmp_path, clean_tree):
    results = tmp_path / "results"
    results.mkdir()
    weights = tmp_path / "weights.bin"
    weights.write_bytes(b"w1")
    (results / "thing.md").write_text("made\n")
    (results / "thing_extra.png").write_bytes(b"")
    script = f"import pathlib; pathlib.Path({str(results / 'thing.md')!r}).write_text('again')"
    shared.write_output_manifest(results, "thing", ["thing.md"], f"python -c {json.dumps(script)}",
                                 ["slamcommon.se3"], inputs=[weights], seconds=90.0)  # fmt: skip
    rows = provenance.results_status(results)
    assert [(r.name, r.current) for r in rows] == [("thing", False)]
    assert rows[0].why == "no provenance for thing_extra.png"  # a file no manifest lists
    (results / "thing_extra.png").unlink()
    assert provenance.results_status(results)[0].current
    touch(weights, "w2")
    (row,) = provenance.results_status(results)
    assert not row.current and row.changed == {"inputs": (shared.shown_path(weights),)}
    assert row.why == f"inputs changed: {shared.shown_path(weights)} (thing{MANIFEST_SUFFIX})"

    code, plan = cli("results", "make", "--results", str(results), "--dry-run")
    assert code == 0 and plan.splitlines()[:2] == ["thing: about 2 min", f"    python -c {json.dumps(script)}"]
    assert (results / "thing.md").read_text() == "made\n"
    code, out = cli("results", "make", "--results", str(results))
    assert (results / "thing.md").read_text() == "again"  # its command ran (it writes no new manifest: still stale)
    assert code == 1 and "inputs changed" in out


def test_bad_input_exits_2_in_one_line(tmp_path, capsys):
    from cnnslam.cli import main

    (tmp_path / "table1.md").write_text("")
    assert main(["results", "make", "--results", str(tmp_path), "table9", "--dry-run"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"cnnslam results: error: unknown result(s) table9; results under {tmp_path}: table1"]
    assert main(["results", "make", "--results", str(tmp_path), "--jobs", "0"]) == 2
    assert "--jobs takes a number of runs in parallel >= 1, got 0" in capsys.readouterr().err


def test_a_result_without_manifest_is_remade_by_the_command_its_report_quotes(tmp_path):
    results = tmp_path / "results"
    (results / "camera_clean").mkdir(parents=True)
    (results / "camera_clean" / "table1.md").write_text(
        "Made by `cnnslam bench table1 --frames 6 --sequences office0 --methods oracle --seeds 0`: the first ...\n")
    (results / "map_office0.png").write_bytes(b"")
    (results / "map_office0.json").write_text(json.dumps({"run_seconds": 30.0}))
    plans = {p.name: p for p in remake.plan_remakes(results, out=tmp_path / "runs")}
    table = plans["camera_clean/table1"]
    assert table.commands == ("cnnslam bench table1 --frames 6 --sequences office0 --methods oracle --seeds 0",)
    assert (table.runs, table.reused, table.to_make) == (1, 0, 1) and table.possible
    shown = shared.shown_path(results)
    assert plans["map_office0"].commands == (f"cnnslam map office0 --figure {shown}/map_office0.png",)
    assert plans["map_office0"].estimate_s == 30.0 and not plans["map_office0"].bench
    assert remake.command_argv("python -m x --y")[:2] == [sys.executable, "-m"]


def test_the_estimate_takes_a_runs_recorded_time_else_its_methods_seconds_per_frame():
    from types import SimpleNamespace

    def spec(key: str, method: str, frames: int) -> SimpleNamespace:
        ref = SimpleNamespace(folder=None, start=0, spec=lambda: SimpleNamespace(n_frames=1000))
        return SimpleNamespace(key=key, sequence=ref, frames=frames, method=SimpleNamespace(name=method))

    walls = {"s/a/A/seed0": ("A", 30.0), "s/b/A/seed0": ("A", 50.0)}
    rates = {"A": 0.5, "B": 0.1}
    specs = [spec("s/a/A/seed0", "A", 10), spec("s/c/A/seed0", "A", 10), spec("s/c/B/seed0", "B", 100),
             spec("s/c/C/seed0", "C", 100)]  # C: no rate of its own, the median method's (0.3 s a frame)
    assert remake.estimate_runs(specs, walls, rates) == pytest.approx(30.0 + 5.0 + 10.0 + 30.0)
    assert remake.estimate_runs(specs[1:2], walls, {}) == pytest.approx(40.0)  # its method's median wall
    assert remake.estimate_runs(specs[1:2], {}, {}) is None


def test_a_run_two_results_plan_is_made_once_and_a_prefix_run_is_not_shared(tmp_path):
    results = tmp_path / "results"
    line = "cnnslam bench table1 --frames {n} --sequences office0 --methods oracle constant-pose --seeds 0"
    for folder, frames in (("a", 6), ("b", 6), ("c", 8)):
        (results / folder).mkdir(parents=True)
        (results / folder / "table1.md").write_text(f"Made by `{line.format(n=frames)}`: ...\n")
    plans = {p.name: p for p in remake.plan_remakes(results, out=tmp_path / "runs")}
    a, b, c = plans["a/table1"], plans["b/table1"], plans["c/table1"]
    assert (a.runs, a.reused, a.shared, a.to_make) == (2, 0, 0, 2)
    assert (b.runs, b.reused, b.shared, b.to_make) == (2, 0, 2, 0) and b.shared_with == (("a/table1", 2),)
    assert b.estimate_s in (0.0, None) and b.made == frozenset()
    assert (c.runs, c.shared, c.to_make) == (2, 0, 2)  # the first 6 of 8 frames are another run: not shared
    assert a.made == {s.fingerprint() for s in b.specs} and not a.made & c.made
    text = remake.format_plan(list(plans.values()), 2)
    assert "b/table1: 2 runs: 0 reused, 2 made by a/table1, 0 to make" in text
    assert "2 run(s) shared between results (same fingerprint, made once)" in text
