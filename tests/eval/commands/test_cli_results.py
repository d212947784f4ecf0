"""``cnnslam results status``: a table (or JSON) of every result and whether the current code gives the same; exit 0
when all are current, 1 when any is stale, 2 for bad input. Manifests here are written for planned runs without
running them: the status never runs anything either."""

from __future__ import annotations

import json
from pathlib import Path

from cnnslam.cli import main
from eval.bench import BenchOptions, ExecutorOptions, prepare
from eval.bench.provenance import MANIFEST_SUFFIX, TreeState, write_manifest
from eval.bench.runner import RunOutcome, SuiteRun, plan_runs


def planned_manifest(results: Path, methods: tuple[str, ...], state: TreeState) -> BenchOptions:
    """A manifest in ``results`` for table1's office0 (4 frames, seed 0) with ``methods``, as if run."""
    options = BenchOptions(sequences=("office0",), frames=4, seeds=(0,), executor=ExecutorOptions("serial"),
                           progress=False, results=results)  # fmt: skip
    plan = prepare("table1", list(methods), options)
    suite = plan.parts[0].suite
    specs = plan_runs(suite, [plan.methods[m] for m in methods])
    run = SuiteRun(suite, results, tuple(specs), {s.key: RunOutcome(s.key, "done", results) for s in specs}, {}, [],
                   {})  # fmt: skip
    write_manifest(results, "table1", plan.command, options, plan.methods, [run], state)
    (results / "table1.md").write_text("| table |\n")
    return options


def test_a_result_whose_runs_fingerprint_as_now_is_current(tmp_path, capsys):
    results = tmp_path / "results"
    planned_manifest(results, ("oracle", "constant-pose"), TreeState("0123456789ab"))
    assert main(["results", "status", "--results", str(results)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["result", "suite", "made", "at", "runs", "status", "why"]
    assert out[1].split()[:5] == ["table1", "table1", "0123456789ab", "2", "current"]
    assert out[-1] == "1 of 1 result(s) current, 0 stale"


def test_a_changed_part_names_the_part_and_the_methods_it_changed(tmp_path, capsys):
    results = tmp_path / "results"
    planned_manifest(results, ("oracle", "constant-pose"), TreeState("0123456789ab"))
    path = results / f"table1{MANIFEST_SUFFIX}"
    data = json.loads(path.read_text())
    oracle = next(k for k in data["runs"] if "/oracle/" in k)
    data["runs"][oracle]["parts"]["world"] = "0" * 64  # as if rendered by other world code
    path.write_text(json.dumps(data))
    assert main(["results", "status", "--json", "--results", str(results)]) == 1
    (row,) = json.loads(capsys.readouterr().out)
    assert row["status"] == "stale" and row["changed"] == {"world": [oracle]}
    assert row["why"] == "world changed: oracle (1 run)"


def test_a_result_from_an_uncommitted_tree_is_stale(tmp_path, capsys):
    results = tmp_path / "results"
    planned_manifest(results, ("oracle",), TreeState("0123456789ab", ("eval/metrics/results.py",)))
    assert main(["results", "status", "--results", str(results), "table1"]) == 1
    out = capsys.readouterr().out
    assert "0123456789ab-dirty" in out and "made from an uncommitted tree (1 changed file(s)" in out


def test_a_result_that_lacks_a_planned_run_is_stale(tmp_path, capsys):
    results = tmp_path / "results"
    planned_manifest(results, ("oracle",), TreeState("0123456789ab"))
    path = results / f"table1{MANIFEST_SUFFIX}"
    data = json.loads(path.read_text())
    data["methods"] = ["oracle", "constant-pose"]  # the selection now plans a run the result does not hold
    path.write_text(json.dumps(data))
    assert main(["results", "status", "--json", "--results", str(results)]) == 1
    assert "1 planned run(s) missing (e.g. table1/office0@kinect/constant-pose/" in json.loads(
        capsys.readouterr().out)[0]["why"]


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    (tmp_path / "table1.md").write_text("")
    assert main(["results", "status", "--results", str(tmp_path), "table9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"cnnslam results: error: unknown result(s) table9; results under {tmp_path}: table1"]
    assert main(["results", "status", "--results", str(tmp_path / "nosuch")]) == 2
    assert "does not exist" in capsys.readouterr().err
