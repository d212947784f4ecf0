"""The recipe "a new baseline" (CONTRIBUTING.md), run: in a copy of the tree, one module subclassing
:class:`cnnslam.baselines.base.BaselineAgent` plus one ``[methods."X"]`` table in ``eval/methods.toml``; the copy
differs from the tree in those two files only, the new method is a Table-1 method and warmed up, and a tiny suite runs
it and scores it."""

from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
COPIED = ("cnnslam", "eval")  # the packages a new baseline edits; the others are linked into the copy
LINKED = ("sim_envs", "slamcommon", "thirdparty")

MODULE = '''"""A constant-depth baseline: the identity pose every frame, a key-frame every 2nd frame, 2 m everywhere."""

from typing import Any

import numpy as np

from cnnslam.baselines.base import BaselineAgent


class ConstantDepthAgent(BaselineAgent):
    name = "constant_depth"

    def __init__(self, depth: float = 2.0, seed: int = 0) -> None:
        super().__init__()
        self.depth = float(depth)

    def _start(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        self._keyframes: list[Any] = []

    def _track(self, observation: dict[str, np.ndarray], timestamp: float,
               info: dict[str, Any] | None) -> tuple[np.ndarray, bool]:
        from sim_envs.agent import KeyframeDepth

        if len(self._tracked) % 2 == 0:
            depth = np.full(self._size, self.depth, np.float32)
            self._keyframes.append(KeyframeDepth(timestamp=timestamp, depth=depth, T_world_cam=np.eye(4)))
        return np.eye(4), True

    def _finish(self) -> Any:
        from sim_envs.agent import AgentOutput

        return AgentOutput(keyframes=self._keyframes, extras=self.episode_extras())
'''

TABLE = '''
[methods."Const-depth"]
entry_point = "cnnslam.baselines.constant_depth:ConstantDepthAgent"
kwargs = { depth = 2.0 }
seed = "seed"
metrics = ["trajectory", "depth"]
table1 = true
warmup = "baselines"
description = "recipe test: identity poses, 2 m depth everywhere"
'''


def _copy_tree(dst: Path) -> None:
    for name in COPIED:
        shutil.copytree(ROOT / name, dst / name, symlinks=True,
                        ignore=shutil.ignore_patterns("__pycache__", "weights", "*.pyc"))
    weights = ROOT / "cnnslam" / "depthnet" / "weights"
    if weights.is_dir():
        (dst / "cnnslam" / "depthnet" / "weights").symlink_to(weights)
    for name in LINKED:
        (dst / name).symlink_to(ROOT / name)


def _touched(copy: Path) -> set[str]:
    """Files of the copied packages that differ from the tree's or are new (caches left out)."""
    out = set()
    for name in COPIED:
        for path in (copy / name).rglob("*"):
            rel = path.relative_to(copy)
            if path.is_symlink() or path.is_dir() or "__pycache__" in rel.parts or path.suffix == ".pyc":
                continue
            original = ROOT / rel
            if not original.is_file() or not filecmp.cmp(path, original, shallow=False):
                out.add(rel.as_posix())
    return out


def _python(copy: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(copy)}
    return subprocess.run([sys.executable, *args], cwd=copy, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False)


@pytest.mark.slow
def test_a_new_baseline_is_one_module_and_one_table(tmp_path: Path) -> None:
    copy = tmp_path / "tree"
    copy.mkdir()
    _copy_tree(copy)
    assert _touched(copy) == set()
    (copy / "cnnslam" / "baselines" / "constant_depth.py").write_text(MODULE)
    with (copy / "eval" / "methods.toml").open("a") as f:
        f.write(TABLE)
    assert _touched(copy) == {"cnnslam/baselines/constant_depth.py", "eval/methods.toml"}

    # the Table-1 suite and the warm-up take it from its table
    probe = _python(copy, "-c", "import json; from eval.bench.suites import TABLE1_METHODS; "
                                "from cnnslam.tools.warmup import warmup_agents; "
                                "print(json.dumps([TABLE1_METHODS, warmup_agents()['baselines']]))")
    assert probe.returncode == 0, probe.stderr
    table1, warmed = json.loads(probe.stdout)
    assert table1[-1] == "Const-depth" and "ORB" in table1
    assert ["cnnslam.baselines.constant_depth:ConstantDepthAgent", {"depth": 2.0}] in warmed

    # a tiny Table-1 suite runs it and scores it
    out, results = tmp_path / "out", tmp_path / "results"
    run = _python(copy, "-m", "cnnslam.cli", "bench", "table1", "--sequences", "office0", "--methods", "Const-depth",
                  "--frames", "4", "--runs", "1", "--jobs", "1", "--no-plots", "--no-progress", "--no-gate",
                  "--out", str(out), "--results", str(results))
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    [folder] = (out / "table1").glob("office0*/Const-depth/seed0-frames4")
    record = json.loads((folder / "metrics.json").read_text())
    assert record["agent"] == "constant_depth" and record["metrics"]["frames"] == 4
    assert record["metrics"]["tracked_share"] == 1.0 and record["metrics"]["depth_keyframes"] == 2
    assert len((folder / "trajectory.tum").read_text().split("\n# ")[-1].strip().splitlines()) >= 4
    assert "Const-depth" in (results / "table1.md").read_text()
