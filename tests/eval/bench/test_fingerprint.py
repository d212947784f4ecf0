"""eval.bench.fingerprint: a run's fingerprint follows the files its agent imports, and only those, and says which
part of it changed."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from eval.bench import fingerprint
from eval.bench.fingerprint import (
    agent_files,
    closure_sha256,
    import_closure,
    imported_modules,
    judge_files,
    run_parts,
    world_files,
)
from eval.bench.methods import Method, load_methods
from eval.bench.run import RunSpec
from eval.bench.suites import SUITES

AGENT = "from fakepkg.shared import helper\n\n\nclass Agent{n}:\n    value = helper() + {n}\n"


def touch(path: Path, text: str) -> None:
    """Write ``text`` and move the file's time on (a coarse clock would otherwise keep it)."""
    path.write_text(text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


@pytest.fixture
def fakepkg(tmp_path, monkeypatch):
    """A package ``fakepkg`` with two agents sharing a helper, and a module neither imports; on sys.path and among
    the packages closures follow."""
    root = tmp_path / "fakepkg"
    (root / "agents").mkdir(parents=True)
    (root / "__init__.py").write_text("")
    (root / "agents" / "__init__.py").write_text("")
    (root / "shared.py").write_text("def helper():\n    from fakepkg import late  # imported inside a function\n"
                                    "    return 1\n")
    (root / "late.py").write_text("X = 1\n")
    (root / "unused.py").write_text("Y = 2\n")
    (root / "agents" / "one.py").write_text(AGENT.format(n=1))
    (root / "agents" / "two.py").write_text("from ..shared import helper  # relative\n\n\nclass Agent2:\n"
                                            "    value = helper()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(fingerprint, "PROJECT_PACKAGES", (*fingerprint.PROJECT_PACKAGES, "fakepkg"))
    return root


def test_the_closure_follows_imports_in_functions_relative_imports_and_parent_packages(fakepkg):
    closure = import_closure(["fakepkg.agents.one"])
    assert set(closure) == {"fakepkg", "fakepkg.agents", "fakepkg.agents.one", "fakepkg.shared", "fakepkg.late"}
    assert set(import_closure(["fakepkg.agents.two"])) == set(closure) - {"fakepkg.agents.one"} | {"fakepkg.agents.two"}
    assert "fakepkg.shared" in imported_modules(fakepkg / "agents" / "two.py", "fakepkg.agents.two")


def test_an_edit_inside_one_agents_closure_changes_its_fingerprint_and_not_the_others(fakepkg):
    one = Method("one", entry_point="fakepkg.agents.one:Agent1")
    two = Method("two", entry_point="fakepkg.agents.two:Agent2")
    before = {m.name: (m.source_hashes(), closure_sha256(m.entry_point.partition(":")[0])) for m in (one, two)}
    touch(fakepkg / "unused.py", "Y = 3\n")  # outside both closures
    assert {m.name: (m.source_hashes(), closure_sha256(m.entry_point.partition(":")[0])) for m in (one, two)} == before
    touch(fakepkg / "agents" / "one.py", AGENT.format(n=1) + "# edited\n")  # agent one's own file
    assert one.source_hashes() != before["one"][0] and two.source_hashes() == before["two"][0]
    touch(fakepkg / "late.py", "X = 2\n")  # imported by both (through the helper, inside a function)
    assert two.source_hashes() != before["two"][0]


def test_a_run_fingerprint_names_the_part_that_changed(fakepkg):
    ref = SUITES["quick"].sequences[0]
    spec = RunSpec("t", ref, Method("one", entry_point="fakepkg.agents.one:Agent1"), frames=3)
    other = RunSpec("t", ref, Method("two", entry_point="fakepkg.agents.two:Agent2"), frames=3)
    before, before_other = run_parts(spec), run_parts(other)
    assert spec.fingerprint() == before.fingerprint and set(before.digests) == set(fingerprint.PARTS)
    touch(fakepkg / "agents" / "one.py", AGENT.format(n=1) + "# edited\n")
    assert run_parts(spec).changed(before.digests) == ["agent"] and spec.fingerprint() != before.fingerprint
    assert run_parts(other).digests == before_other.digests
    longer = RunSpec("t", ref, spec.method, frames=4)
    assert run_parts(longer).changed(run_parts(spec).digests) == ["config"]


def test_the_projects_agents_are_narrowed_to_their_own_modules():
    methods = load_methods()
    orb, laina, cnn = (set(agent_files(methods[n])) for n in ("ORB", "Laina", "CNN-SLAM"))
    assert "cnnslam.baselines.orb" in orb and "cnnslam.baselines.laina" not in orb and "cnnslam.system" not in orb
    assert "cnnslam.baselines.laina" in laina and "cnnslam.baselines.orb" not in laina
    assert "cnnslam.track.tracking" in cnn and not any(m.startswith("cnnslam.baselines") for m in cnn)
    ref = SUITES["quick"].sequences[0]
    assert {"sim_envs.env", "sim_envs.driver", "sim_envs.sources.simsource"} <= set(world_files(ref))
    assert all(m.startswith("sim_envs") for m in world_files(ref))
    judge = set(judge_files())
    assert "eval.metrics.results" in judge and all(m.startswith(("eval.metrics", "slamcommon")) for m in judge)
