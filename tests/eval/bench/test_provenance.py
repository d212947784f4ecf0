"""eval.bench.provenance: a suite's report carries a manifest; a result is current while every run's fingerprint
parts are the current code's, stale once a file its agent imports changes (and only that agent's runs), when made
from an uncommitted tree, or when it has no manifest."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from eval.bench import BenchOptions, ExecutorOptions, fingerprint, provenance, run_bench
from eval.bench.methods import Method
from eval.bench.provenance import (
    MANIFEST_SUFFIX,
    TreeState,
    format_status,
    result_groups,
    results_status,
    write_manifest,
)
from eval.bench.suites import SUITES
from eval.errors import InputError

FIRST = "from fakeagents.shared import OracleAgent\n\n\nclass First(OracleAgent):\n    pass\n"
SECOND = "from fakeagents.shared import ConstantPoseAgent\n\n\nclass Second(ConstantPoseAgent):\n    pass\n"
CLEAN = TreeState("0123456789ab", ())


def touch(path: Path, text: str) -> None:
    """Write ``text`` and move the file's time on (a coarse clock would otherwise keep it)."""
    path.write_text(text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


@pytest.fixture
def fakeagents(tmp_path, monkeypatch):
    """A copy of two of the project's agents in a package of their own, ``fakeagents`` (``first`` and ``second``,
    sharing ``shared``), on sys.path and among the packages fingerprints follow; the tree reads as committed."""
    root = tmp_path / "pkg" / "fakeagents"
    root.mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "shared.py").write_text("from sim_envs.agents import ConstantPoseAgent, OracleAgent\n\n"
                                    "__all__ = ['ConstantPoseAgent', 'OracleAgent']\n")
    (root / "first.py").write_text(FIRST)
    (root / "second.py").write_text(SECOND)
    monkeypatch.syspath_prepend(str(tmp_path / "pkg"))
    monkeypatch.setattr(fingerprint, "PROJECT_PACKAGES", (*fingerprint.PROJECT_PACKAGES, "fakeagents"))
    monkeypatch.setattr(provenance, "tree_state", lambda root=None: CLEAN)
    return root


def options(tmp_path: Path, results: Path) -> BenchOptions:
    return BenchOptions(sequences=("office0",), frames=4, seeds=(0,), executor=ExecutorOptions("serial"),
                        plots=False, progress=False, out=tmp_path / "runs", results=results)  # fmt: skip


def status_exit(results: Path, *names: str) -> tuple[int, list[dict]]:
    """``cnnslam results status --json --results RESULTS NAME...``: exit status and the printed rows."""
    import contextlib
    import io

    from cnnslam.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(["results", "status", "--json", "--results", str(results), *names])
    return code, json.loads(out.getvalue()) if code != 2 else []


@pytest.mark.slow
def test_an_edit_to_one_agents_file_makes_its_results_stale_and_leaves_the_others_current(tmp_path, fakeagents):
    first = Method("First", entry_point="fakeagents.first:First", metrics=("trajectory", "depth"))
    second = Method("Second", entry_point="fakeagents.second:Second", metrics=("trajectory", "depth"))
    results = tmp_path / "results"
    both = run_bench("table1", [first, second], options(tmp_path, results))
    alone = run_bench("table1", [second], options(tmp_path, results / "second"))
    assert both.exit_status == 0 and [r.status for r in alone.runs] == ["cached"]
    manifest = json.loads((results / f"table1{MANIFEST_SUFFIX}").read_text())
    assert manifest["suite"] == "table1" and manifest["git_revision"] == CLEAN.revision and not manifest["dirty"]
    assert set(manifest["method_definitions"]) == {"First", "Second"} and len(manifest["runs"]) == 2
    assert set(next(iter(manifest["runs"].values()))["parts"]) == set(fingerprint.PARTS)

    code, rows = status_exit(results)
    assert code == 0 and [(r["name"], r["status"]) for r in rows] == [("table1", "current"),
                                                                      ("second/table1", "current")]
    touch(fakeagents / "first.py", FIRST + "# an edit\n")  # a file only First imports
    code, rows = status_exit(results)
    by_name = {r["name"]: r for r in rows}
    assert code == 1 and by_name["table1"]["status"] == "stale" and by_name["second/table1"]["status"] == "current"
    assert list(by_name["table1"]["changed"]) == ["agent"]
    assert all("/First/" in key for key in by_name["table1"]["changed"]["agent"])  # Second's run unchanged
    assert "agent changed: First (1 run)" in by_name["table1"]["why"]
    assert status_exit(results, "second/table1")[0] == 0

    touch(fakeagents / "first.py", FIRST)  # back as it was, but the report written from an uncommitted tree
    assert status_exit(results, "table1")[0] == 0
    write_manifest(results, "table1", both.command, options(tmp_path, results), {"First": first, "Second": second},
                   [run for _, run in both.parts], TreeState("0123456789ab", ("cnnslam/agent.py",)))  # fmt: skip
    code, rows = status_exit(results, "table1")
    assert code == 1 and "made from an uncommitted tree (1 changed file(s): cnnslam/agent.py)" in rows[0]["why"]
    assert rows[0]["made_at"] == ["0123456789ab-dirty"]


def test_results_are_grouped_by_suite_and_those_without_a_manifest_are_stale(tmp_path):
    root = tmp_path / "results"
    (root / "table1_figures").mkdir(parents=True)
    (root / "baselines").mkdir()
    (root / "camera_clean").mkdir()
    (root / "table1.md").write_text("| x |\n")
    (root / "table1_figures" / "a.png").write_bytes(b"")
    (root / "table1_long.csv").write_text("sequence,run,git_revision\nA,table1/A/m/seed0,abc\nA,table1/A/m/seed0,abc\n"
                                          "B,table1/B/m/seed0,def\n")
    (root / "depthnet.md").write_text("")
    (root / "depthnet_real.json").write_text("{}")
    (root / "baselines" / "quick.json").write_text("{}")
    (root / "camera_clean" / "table1.md").write_text("")
    groups = result_groups(root, list(SUITES))
    assert {n: sorted(p.name for p in f) for n, f in groups.items()} == {
        "table1": ["table1.md", "table1_figures", "table1_long.csv"],
        "depthnet": ["depthnet.md", "depthnet_real.json"],
        "camera_clean/table1": ["table1.md"],
    }
    rows = {r.name: r for r in results_status(root)}
    assert rows["table1"].made_at == ("abc", "def") and rows["table1"].runs == 2 and not rows["table1"].current
    assert rows["table1"].why == "no provenance (made before manifests)"
    assert rows["depthnet"].suite is None and "no manifest lists its files" in rows["depthnet"].why
    table = format_status(list(rows.values()))
    assert re.search(r"^table1 +table1 +abc \+1 +2 +stale +no provenance", table, re.M)
    assert table.endswith("0 of 3 result(s) current, 3 stale")
    with pytest.raises(InputError, match=r"unknown result\(s\) nosuch; results under .*: .*camera_clean/table1"):
        results_status(root, ["nosuch"])
    assert status_exit(root, "nosuch")[0] == 2 and status_exit(root)[0] == 1
