"""The README's recipes are code: each runs here as written, with only its length cut (named in each test)."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def blocks(language: str) -> list[str]:
    """The README's fenced code blocks of ``language``, in order."""
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(), flags=re.S)


def block_with(language: str, needle: str) -> str:
    found = [b for b in blocks(language) if needle in b]
    assert len(found) == 1, f"one README {language} block with {needle!r}, found {len(found)}"
    return found[0]


@pytest.mark.slow
def test_the_quick_start_runs_as_written(capsys):
    """Quick start: CNN-SLAM on office0 scored by evaluate_episode (30 frames here instead of 300)."""
    code = block_with("python", "evaluate_episode")
    assert "max_frames=300" in code
    exec(compile(code.replace("max_frames=300", "max_frames=30"), "README quick start", "exec"), {})
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert re.fullmatch(r"ATE \d+\.\d{3} m, correct depth \d+\.\d %", line), line


MAIN_GUARD = 'if __name__ == "__main__":'


def library_call_script() -> str:
    """The README's run_bench block as written, the oracle alone on 6 frames of office0 (its runs and report land
    in ``runs/`` of the working folder)."""
    code = block_with("python", "run_bench")
    assert '["CNN-SLAM", "LSD"]' in code and "frames=300" in code
    return code.replace('["CNN-SLAM", "LSD"]', '["oracle"]').replace("frames=300", "frames=6, progress=False")


@pytest.mark.slow
def test_the_library_call_runs_as_written(tmp_path, monkeypatch, capsys):
    """The benchmark as a library call (run_bench), beside its command: here the oracle alone on 6 frames, so the
    runs and the subset's report land under tmp_path/runs/."""
    monkeypatch.chdir(tmp_path)
    exec(compile(library_call_script(), "README library call", "exec"), {"__name__": "__main__"})  # as a script
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("table1/office0@kinect/oracle/seed0-frames6 done")
    assert lines[-1].startswith("exit status 0 report runs/reports/table1-") and lines[-1].endswith("table1.md")


def without_guard(code: str) -> str:
    """``code`` with the block of its ``if __name__ == "__main__":`` (the last lines) moved to the top level."""
    lines = code.splitlines()
    at = [i for i, line in enumerate(lines) if line.startswith(MAIN_GUARD)]
    assert len(at) == 1, f"one {MAIN_GUARD!r} in {code!r}"
    body = lines[at[0] + 1:]
    assert all(not line.strip() or line.startswith("    ") for line in body), "the guard's block ends the code"
    return "\n".join([*lines[:at[0]], *(line[4:] for line in body)]) + "\n"


def run_script(path: Path) -> subprocess.CompletedProcess[str]:
    """``python path`` in its folder with this interpreter, as a user runs a saved snippet."""
    return subprocess.run([sys.executable, path.name], cwd=path.parent, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_the_library_call_runs_as_a_saved_script(tmp_path):
    """The README's run_bench block saved as a file and run with ``python FILE``, as written: its runs' worker
    processes import the file again, and the block's guard keeps them from starting the runs again (without it,
    every run failed as WorkerDied, "a crash in native code, or killed for memory?")."""
    script = tmp_path / "snippet.py"
    script.write_text(library_call_script())
    assert MAIN_GUARD in script.read_text(), "the README's block puts its calls under the main guard"
    done = run_script(script)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stdout.strip().splitlines()
    assert lines[0].startswith("table1/office0@kinect/oracle/seed0-frames6 done"), done.stdout
    assert lines[-1].startswith("exit status 0 report runs/reports/table1-"), done.stdout
    assert "WorkerDied" not in done.stdout + done.stderr


def test_the_library_call_without_its_guard_is_refused_before_any_run(tmp_path):
    """The same block with its calls at the top level of the script: refused at once (InputError, one line naming
    the script's line and the fix), before any run or folder, never the workers' death reported per run."""
    script = tmp_path / "snippet.py"
    script.write_text(without_guard(library_call_script()))
    assert MAIN_GUARD not in script.read_text()
    done = run_script(script)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("eval.bench.executors.MainModuleError: snippet.py line 3 starts worker processes"), last
    assert last.endswith(f"put the call under `{MAIN_GUARD}` (or use the serial executor)"), last
    assert "WorkerDied" not in done.stdout + done.stderr and done.stdout == ""
    assert not (tmp_path / "runs").exists()  # nothing rendered, run or reported


def test_the_dataset_list_format_is_the_one_the_code_reads(tmp_path):
    """README: one ``name = "path"`` line each under the ``[datasets]`` table, as datasets.toml and the loader have
    it (the README once said a line per name without the table, which the loader refuses)."""
    from eval.bench.sequence_resolve import load_dataset_list

    text = block_with("toml", "[datasets]")
    path = tmp_path / "datasets.toml"
    path.write_text(text)
    entries = load_dataset_list(path)
    assert list(entries) == ["fr1_desk"] and entries["fr1_desk"].path == (
        Path("~/data/rgbd_dataset_freiburg1_desk").expanduser().resolve())
    assert tomllib.loads(text) == {"datasets": {"fr1_desk": "~/data/rgbd_dataset_freiburg1_desk"}}
    shipped = tomllib.loads((README.parent / "datasets.toml").read_text())
    assert set(shipped) == {"datasets"}


def test_the_commands_section_names_every_command_and_developer_tool():
    from cnnslam.cli import DEVELOPER_TOOLS, GROUPS, SUBCOMMANDS

    section = README.read_text().split("## Commands", 1)[1]
    for name in SUBCOMMANDS:
        assert f"`{name}`" in section
    for group in GROUPS:
        assert group in section
    assert "python -m NAME" in section  # the developer tools run as modules
    for module, _ in DEVELOPER_TOOLS:
        assert f"`{module}`" in section


def test_the_network_recipe_is_the_shipped_one():
    """README: ``cnnslam train recipe`` retrains the shipped network; its commands parse as written and the counts
    it states are the recipe's (a tiny run of the same recipe end to end: tests/cnnslam/test_depthnet_recipe.py)."""
    import argparse
    import shlex

    from cnnslam.depthnet.cli_train import add_arguments
    from cnnslam.depthnet.recipe import SHIPPED

    code = block_with("bash", "cnnslam train recipe")
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    lines = [line.split("#")[0].strip() for line in code.splitlines() if line.strip()]
    parsed = [parser.parse_args(shlex.split(line)[2:]) for line in lines]
    assert [a.action for a in parsed] == ["recipe", "recipe"] and all(a.export for a in parsed)
    assert parsed[1].device == "cuda" and parsed[0].device == "cpu"
    g, f = SHIPPED.generation, SHIPPED.fit
    def spaced(n: int) -> str:  # 28000 -> "28 000", as the README writes numbers
        return f"{n:,}".replace(",", " ")

    frames = g.n_scenes * g.views_per_scene
    stated = f"{spaced(frames)} frames of {spaced(g.n_scenes)} rooms, then {spaced(f.steps)} steps of {f.batch_size}"
    assert stated in code
