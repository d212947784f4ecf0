"""CONTRIBUTING.md's recipes are code: the ones not run by the test module they name are run here."""

from __future__ import annotations

from pathlib import Path

from eval.bench import BenchOptions, run_bench
from eval.bench import suites as suites_module
from eval.bench.benchmark import ExecutorOptions
from eval.bench.sequence_resolve import resolve_sequence
from eval.bench.suites import Suite

CONTRIBUTING = Path(__file__).resolve().parents[1] / "CONTRIBUTING.md"


def test_a_new_suite_is_one_entry(tmp_path, monkeypatch):
    """A Suite added to the suites' table (what one entry in ``_suites()`` does) runs by its name, writes its report
    under its name with a provenance manifest, and needed no other edit."""
    suite = Suite("mine", "two methods on office0, a few frames", sequences=(resolve_sequence("office0"),),
                  methods=("oracle", "constant-pose"), frames=6, seeds=(0,))  # fmt: skip
    monkeypatch.setitem(suites_module.SUITES, "mine", suite)
    options = BenchOptions(executor=ExecutorOptions("serial", 1), plots=False, progress=False, out=tmp_path / "runs",
                           results=tmp_path / "results")  # fmt: skip
    outcome = run_bench("mine", None, options)
    assert outcome.exit_status == 0, [(r.key, r.status, r.error) for r in outcome.runs]
    assert sorted(r.key for r in outcome.runs) == ["mine/office0/constant-pose/seed0-frames6",
                                                   "mine/office0/oracle/seed0-frames6"]  # fmt: skip
    assert (tmp_path / "results" / "mine.md").is_file() and (tmp_path / "results" / "mine.provenance.json").is_file()
    assert "`_suites()` of `eval/bench/suites.py`" in CONTRIBUTING.read_text()
