"""cnnslam.cli: the commands listed by role with the developer tools, one line (no traceback) for a bad choice or
a closed pipe."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import pytest

from cnnslam.cli import DEVELOPER_TOOLS, GROUPS, SUBCOMMANDS, main


def test_help_lists_the_commands_by_role_and_the_developer_tools(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    positions = [text.index(f"\n{group}:\n") for group in GROUPS]
    assert positions == sorted(positions)  # run and score, data, the network, speed
    for name, (module, _, group) in SUBCOMMANDS.items():
        assert f"  {name} " in text.split(f"\n{group}:\n", 1)[1] and importlib.util.find_spec(module) is not None
    assert "developer tools (python -m MODULE" in text
    for module, _ in DEVELOPER_TOOLS:
        assert module in text and importlib.util.find_spec(module) is not None
    assert {g for _, _, g in SUBCOMMANDS.values()} == set(GROUPS)
    assert {"bench", "eval", "regress", "config"} <= {n for n, (_, _, g) in SUBCOMMANDS.items() if g == GROUPS[0]}
    assert {"export", "generate", "reference"} <= {n for n, (_, _, g) in SUBCOMMANDS.items() if g == GROUPS[1]}


def test_a_closed_pipe_ends_quietly():
    """``cnnslam config CNN-SLAM | head -1``: no BrokenPipeError traceback."""
    proc = subprocess.run(f"{sys.executable} -m cnnslam.cli config CNN-SLAM | head -1", shell=True,
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert proc.stdout.startswith("# CNN-SLAM:") and len(proc.stdout.splitlines()) == 1
    assert proc.stderr == ""

