"""The README's recipe for gating one's own agent ("## Gating your CI on metrics"), run as written with only its length
cut (one sequence, 6 frames, in-process runs): the agent against its own baseline passes, a worse version of it fails
(exit 1). And the gate fails closed from the command line: a missing ``--baseline``, the built-in baseline against
another selection, a ``--baseline`` for a suite without a gate of runs: exit 2 in one line, before any run."""

import re
import shlex
import sys
from pathlib import Path

import pytest

from cnnslam.cli import main
from eval.metrics.results import MIN_TRACKED_SHARE

README = Path(__file__).resolve().parents[2] / "README.md"
CUT = ["--sequences", "office0", "--frames", "6", "--executor", "serial", "--no-plots", "--no-progress"]
# the agent sees observations only (rgb, timestamp, intrinsics), never ground truth: it answers the identity pose,
# or a pose drifting DRIFT metres along x per frame
AGENT = '''import numpy as np
from sim_envs.agent import AgentOutput

DRIFT = {drift}


class MySlam:
    def reset(self, intrinsics, image_size):
        self.n = 0

    def step(self, observation):
        pose = np.eye(4)
        pose[0, 3] = DRIFT * self.n
        self.n += 1
        return {{"T_world_cam": pose, "tracked": 1}}

    def finish(self):
        return AgentOutput(keyframes=[], extras={{"frames": self.n}})
'''


def _section() -> str:
    text = README.read_text()
    start = text.index("## Gating your CI on metrics")
    return text[start:text.index("\n## ", start + 1)]


def _recipe() -> list[list[str]]:
    """The recipe's ``cnnslam bench`` command lines, as argument lists without ``cnnslam`` and the comments."""
    (block,) = [b for b in re.findall(r"```bash\n(.*?)```", _section(), flags=re.S) if "--update-baseline" in b]
    lines = [line.split("  #")[0] for line in block.splitlines() if line.startswith("cnnslam bench")]
    return [shlex.split(line)[1:] for line in lines]


def _write_agent(root: Path, drift: float) -> None:
    package = root / "myslam"
    package.mkdir(exist_ok=True)
    (package / "__init__.py").write_text("")
    (package / "agent.py").write_text(AGENT.format(drift=drift))
    for name in ("myslam.agent", "myslam"):  # the edited code is imported again, as a new process would
        sys.modules.pop(name, None)


@pytest.fixture
def own_agent(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    method = '[methods.Mine]\nentry_point = "myslam.agent:MySlam"\nmetrics = ["trajectory"]\n'
    (tmp_path / "mine.toml").write_text(method)
    _write_agent(tmp_path, 0.0)
    yield tmp_path
    for name in ("myslam.agent", "myslam"):
        sys.modules.pop(name, None)


def test_the_readme_states_the_failure_threshold_of_the_code():
    assert f"less than {round(100 * MIN_TRACKED_SHARE)} % of its frames" in _section()


@pytest.mark.slow
def test_the_gate_recipe_passes_the_agent_and_fails_a_worse_one(own_agent, capsys):
    make, gate = _recipe()
    assert "--update-baseline" in make and "--update-baseline" not in gate
    assert make[:2] == ["bench", "quick"] and "--method-file" in make and "--baseline" in gate
    assert main([*make, *CUT]) == 0, capsys.readouterr()
    assert (own_agent / "mine.json").is_file() and "updated" in capsys.readouterr().out
    assert main([*gate, *CUT]) == 0  # the agent against its own baseline
    assert "PASS" in capsys.readouterr().out
    _write_agent(own_agent, 0.05)  # a worse agent: its poses drift 5 cm a frame
    assert main([*gate, *CUT]) == 1
    out = capsys.readouterr().out
    assert "office0@kinect/Mine/ate_rmse" in out and "regressed" in out and "FAIL" in out
    assert "1 run now" in out  # the edited code was run, not its old runs reused


def _bench(tmp_path, *args):
    return main(["bench", *args, "--out", str(tmp_path / "runs"), "--results", str(tmp_path / "tables"),
                 "--frames", "6", "--runs", "1", "--executor", "serial", "--no-plots", "--no-progress"])


def _refused(capsys, needle):
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and err[0].startswith("cnnslam bench: error:"), captured.err
    assert "Traceback" not in captured.err


def test_a_missing_baseline_exits_2_before_any_run(tmp_path, capsys):
    missing = tmp_path / "MISSING.json"
    assert _bench(tmp_path, "quick", "--sequences", "office0", "--methods", "oracle", "--baseline", str(missing)) == 2
    _refused(capsys, f"no baseline at {missing}")
    assert not (tmp_path / "runs").exists() and not (tmp_path / "tables").exists()  # nothing ran, nothing written
    assert not missing.exists()


def test_the_built_in_baseline_is_found_from_another_folder_and_refuses_another_selection(tmp_path, monkeypatch,
                                                                                            capsys):
    monkeypatch.chdir(tmp_path)  # no results/ here: the quick suite's baseline is still the package's
    assert _bench(tmp_path, "quick", "--sequences", "office0", "--methods", "oracle") == 2
    _refused(capsys, "quick.json: the baseline is of another suite or selection")
    assert not (tmp_path / "runs").exists()


def test_a_baseline_for_a_suite_without_a_gate_of_runs_is_refused(tmp_path, capsys):
    baseline = tmp_path / "b.json"
    baseline.write_text('{"metrics": {"x/A/ate_rmse": 0.1}}')
    code = main(["bench", "lengths", "--methods", "oracle", "--lengths", "6", "--runs", "1", "--executor", "serial",
                 "--no-plots", "--no-progress", "--out", str(tmp_path / "runs"), "--baseline", str(baseline)])
    assert code == 2
    _refused(capsys, "has no gate of runs")
    assert not (tmp_path / "runs").exists()
