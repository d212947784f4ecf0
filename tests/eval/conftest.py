"""Shared fixtures of the judge's tests: evo's command lines, to test our files and figures against evo itself (the
``evo`` package of the dev extra; the tests that need it are skipped where it is not installed)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path

import pytest


def _evo_tool(name: str) -> str | None:
    beside = Path(sys.executable).with_name(name)  # the venv's console scripts sit beside its interpreter
    return str(beside) if beside.is_file() else shutil.which(name)


@pytest.fixture
def evo(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., dict]:
    """``evo(tool, *args)``: run evo's ``tool`` (``evo_traj``, ``evo_ape``, ``evo_rpe``) with its own settings folder
    (``HOME`` in a temporary folder); returns ``{"stdout": ..., "stats": ...}``, ``stats`` read from the results
    file that ``--save_results`` wrote (evo_ape / evo_rpe). Fails with evo's output when evo fails."""
    if _evo_tool("evo_ape") is None:
        pytest.skip("evo is not installed (pip install -c constraints.txt -e '.[dev]')")
    home = tmp_path_factory.mktemp("evo-home")
    env = {"HOME": str(home), "PATH": str(Path(sys.executable).parent) + ":/usr/bin:/bin", "MPLBACKEND": "Agg"}

    def run(tool: str, *args: str) -> dict:
        out: dict = {}
        extra: list[str] = []
        if tool in ("evo_ape", "evo_rpe"):
            results = home / f"{tool}-{len(list(home.glob('*.zip')))}.zip"
            extra = ["--save_results", str(results)]
        done = subprocess.run([_evo_tool(tool) or tool, *args, *extra], capture_output=True, text=True, env=env,
                              timeout=120)  # fmt: skip
        assert done.returncode == 0, f"{tool} {' '.join(args)} failed:\n{done.stdout}\n{done.stderr}"
        out["stdout"] = done.stdout
        if extra:
            with zipfile.ZipFile(extra[1]) as z:
                out["stats"] = json.loads(z.read("stats.json"))
        return out

    return run
