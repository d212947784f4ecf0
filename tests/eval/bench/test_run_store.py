"""Runs shared between suites by fingerprint: a run two suites plan is made once and found by the second through the
output root's index; a run whose code or configuration differs is made again; runs made before the index are found
by its first scan."""

import json
import os
import sys
from dataclasses import replace

import pytest

from eval.bench.methods import Method
from eval.bench.run import DONE_FILE
from eval.bench.run_store import (
    INDEX_DIR,
    build_index,
    indexed_folders,
    is_finished,
    reuse_finished,
    run_folder,
    shared_run,
)
from eval.bench.runner import plan_runs, run_suite
from eval.bench.suites import get_suite

pytestmark = pytest.mark.slow  # each test makes one to three runs of a few frames (about 10 s each)

AGENT = '''"""An oracle that counts its episodes (one line per reset) in the file COUNT names."""
import os

from sim_envs.agents import OracleAgent


class CountingAgent(OracleAgent):
    def reset(self, intrinsics, image_size):
        with open(os.environ["COUNT"], "a") as fh:
            fh.write("run\\n")
        super().reset(intrinsics, image_size)
'''


@pytest.fixture
def counting(tmp_path, monkeypatch):
    """A method whose agent (a module outside the project, so its file is its code fingerprint) counts its runs."""
    code = tmp_path / "code"
    code.mkdir()
    (code / "counting_agent.py").write_text(AGENT)
    monkeypatch.syspath_prepend(str(code))
    monkeypatch.setenv("COUNT", str(tmp_path / "count.txt"))
    yield Method("counting", entry_point="counting_agent:CountingAgent", kwargs=(("keyframe_every", 10),))
    sys.modules.pop("counting_agent", None)


def made(tmp_path):
    path = tmp_path / "count.txt"
    return len(path.read_text().splitlines()) if path.is_file() else 0


def suite(name, frames=6):
    return replace(get_suite("quick").select(["office0@clean"], ["counting"], frames=frames, runs=1), name=name)


def run(name, method, out, frames=6):
    return run_suite(suite(name, frames), {"counting": method}, out, plots=False, progress=False, check=False,
                     revision="r")  # fmt: skip


def test_two_suites_sharing_a_run_make_it_once(tmp_path, counting):
    out = tmp_path / "runs"
    first = run("one", counting, out)
    assert first.counts() == {"done": 1} and made(tmp_path) == 1
    (spec,) = first.specs
    assert indexed_folders(out, spec.fingerprint()) == [spec.relpath]
    second = run("two", counting, out)
    assert made(tmp_path) == 1  # the agent ran once for both suites
    assert second.counts() == {"cached": 1}
    (other,) = second.specs
    assert other.fingerprint() == spec.fingerprint() and other.relpath != spec.relpath
    folder = run_folder(out, other)
    assert folder.is_dir() and not folder.is_symlink()  # the second suite's own folder, in the layout reports read
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in run_folder(out, spec).iterdir())
    assert (folder / "trajectory.tum").read_bytes() == (run_folder(out, spec) / "trajectory.tum").read_bytes()
    assert second.records[0].run == other.key and second.records[0].metrics == first.records[0].metrics
    assert indexed_folders(out, spec.fingerprint()) == [other.relpath, spec.relpath]
    assert run("two", counting, out).counts() == {"cached": 1} and made(tmp_path) == 1


def test_a_run_whose_code_differs_is_not_reused(tmp_path, counting):
    out = tmp_path / "runs"
    before = run("one", counting, out).specs[0].fingerprint()
    agent = tmp_path / "code" / "counting_agent.py"
    agent.write_text(agent.read_text() + "# an edit\n")
    os.utime(agent, (1, 1))  # another modification time: the fingerprint's file cache reads it again
    second = run("two", counting, out)
    assert second.specs[0].fingerprint() != before
    assert second.counts() == {"done": 1} and made(tmp_path) == 2


def test_a_run_of_other_frames_or_configuration_is_not_reused(tmp_path, counting):
    out = tmp_path / "runs"
    run("one", counting, out, frames=8)
    assert run("two", counting, out, frames=6).counts() == {"done": 1}  # the first 6 of 8 frames are another run
    changed = replace(counting, kwargs=(("keyframe_every", 5),))
    assert run("three", changed, out, frames=8).counts() == {"done": 1}
    assert made(tmp_path) == 3


def test_shared_run_only_reads_and_passes_over_a_folder_remade_since(tmp_path, counting):
    out = tmp_path / "runs"
    (spec,) = run("one", counting, out).specs
    (other,) = plan_runs(suite("two"), [counting], plots=False)
    assert shared_run(out, other) == run_folder(out, spec)
    assert not run_folder(out, other).exists()  # found, not taken
    record = json.loads((run_folder(out, spec) / DONE_FILE).read_text())
    record["metadata"]["fingerprint"] = "0123456789abcdef"  # the folder now holds a run other code made
    (run_folder(out, spec) / DONE_FILE).write_text(json.dumps(record))
    assert shared_run(out, other) is None and not reuse_finished(out, other)


def test_runs_made_before_the_index_are_found_by_its_first_scan(tmp_path, counting):
    out = tmp_path / "runs"
    (spec,) = run("one", counting, out).specs
    for path in (out / INDEX_DIR).iterdir():
        path.unlink()
    (out / INDEX_DIR).rmdir()
    (other,) = plan_runs(suite("two"), [counting], plots=False)
    assert reuse_finished(out, other) and is_finished(out, other)
    assert indexed_folders(out, spec.fingerprint()) == [other.relpath, spec.relpath]
    assert build_index(out) == 0  # scanned once
    assert made(tmp_path) == 1
