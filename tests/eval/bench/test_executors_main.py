"""Executors and the main module that ``spawn`` and ``forkserver`` workers import again: where a call comes from
(top-level code, under ``if __name__ == "__main__":``, no file at all), the refusal of an unguarded pool before any
worker starts, and the hint of a ``WorkerDied``."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from eval.bench.executors import GUARD_FIX, MainCall, MainModuleError, check_main_guarded, died_message
from eval.errors import InputError

PROBE = textwrap.dedent(
    """\
    from eval.bench.executors import main_module_call as where
    print(where())
    if __name__ == "__main__":
        print(where())
    def through_a_function():
        return where()
    print(through_a_function())
    if __name__ == "__main__":
        print(through_a_function())
    else:
        print("imported")
    if True:
        print(where())
    """
)


def python(*args: str, cwd: Path, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    """This interpreter run with ``args`` in ``cwd``, its output captured."""
    return subprocess.run([sys.executable, *args], cwd=cwd, input=stdin, capture_output=True, text=True, timeout=120)


def test_a_script_s_top_level_calls_are_told_from_its_guarded_ones(tmp_path):
    """Run as a file (``python FILE`` or ``python -m MODULE``): every call from the file's top-level code is located,
    and guarded where it is under an ``if __name__`` test, through a function called there or not."""
    (tmp_path / "probe.py").write_text(PROBE)
    expected = [f"MainCall(file='probe.py', line={line}, guarded={guarded})"
                for line, guarded in ((2, False), (4, True), (7, False), (9, True), (13, False))]
    for args in (["probe.py"], ["-m", "probe"]):
        done = python(*args, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        assert done.stdout.splitlines() == expected, args


def test_a_main_module_without_a_file_is_never_imported_again(tmp_path):
    """``python -c`` (and so an interactive session or a Jupyter kernel, whose main module has no file) and a
    package's ``__main__``: workers do not import them again, so nothing is refused."""
    done = python("-c", PROBE, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["None"] * 5
    (tmp_path / "probe_package").mkdir()
    (tmp_path / "probe_package" / "__init__.py").write_text("")
    (tmp_path / "probe_package" / "__main__.py").write_text(PROBE)
    done = python("-m", "probe_package", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["None"] * 5


def test_code_from_standard_input_is_refused_for_a_pool(tmp_path):
    """``python - < FILE``: the main module is ``<stdin>``, which no worker can import (each died of
    FileNotFoundError, reported as WorkerDied): one line before any worker starts."""
    code = "from eval.bench.executors import LocalExecutor\nprint(list(LocalExecutor(jobs=1).map(abs, [-1])))\n"
    done = python("-", cwd=tmp_path, stdin=code)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("eval.bench.executors.MainModuleError: the main module <stdin> is no file"), last
    assert "WorkerDied" not in done.stderr


POOL_SCRIPT = textwrap.dedent(
    """\
    from eval.bench.executors import LocalExecutor, make_executor

    pool = LocalExecutor(jobs=1, threads=1)  # making one is harmless: it starts no process
    serial = make_executor("serial")
    {guard}print(sorted(result for _, result in {how}.map(abs, [-3, 4])))
    """
)


@pytest.mark.parametrize("how", ["pool", 'make_executor("local")'])
def test_a_pool_from_unguarded_top_level_code_is_refused_before_any_worker(tmp_path, how):
    """A local pool used from a script's top-level code outside its main guard: the script's workers would each run
    that line again on import and die, every run failing as WorkerDied. Refused at once, one line naming the script's
    line and the fix."""
    (tmp_path / "pool_script.py").write_text(POOL_SCRIPT.format(how=how, guard=""))
    done = python("pool_script.py", cwd=tmp_path)
    assert done.returncode != 0 and done.stdout == ""
    last = done.stderr.strip().splitlines()[-1]
    assert last == ("eval.bench.executors.MainModuleError: pool_script.py line 5 starts worker processes in the "
                    "top-level code of the main module, which each worker runs again when it imports it: "
                    f"{GUARD_FIX} (or use the serial executor)"), last  # fmt: skip
    assert "WorkerDied" not in done.stderr


def test_a_pool_under_the_main_guard_runs_in_workers_that_import_the_script(tmp_path):
    (tmp_path / "pool_script.py").write_text(POOL_SCRIPT.format(how="pool", guard='if __name__ == "__main__": '))
    done = python("pool_script.py", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["[3, 4]"]


def test_a_worker_killed_by_another_unguarded_line_is_reported_with_the_fix(tmp_path):
    """A guarded pool in a script that also starts one unguarded further down: the guarded call cannot see that
    line; its workers, importing the script, are refused there and die. Its runs' WorkerDied names the likely
    cause and the fix, and the unguarded line is refused in its turn."""
    (tmp_path / "two_pools.py").write_text(textwrap.dedent(
        """\
        from eval.bench.executors import LocalExecutor

        pool = LocalExecutor(jobs=1, threads=1)
        if __name__ == "__main__":
            for _, result in pool.map(abs, [-3, 4]):
                print(result)
        print(list(pool.map(abs, [1])))
        """
    ))  # fmt: skip
    done = python("two_pools.py", cwd=tmp_path)
    assert done.returncode != 0
    died = done.stdout.splitlines()
    assert len(died) == 2 and all(line.startswith("the worker process died 2 times") for line in died), died
    assert all("the main module two_pools.py" in line and GUARD_FIX in line for line in died), died
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("eval.bench.executors.MainModuleError: two_pools.py line 7 starts worker processes"), last


def test_the_serial_executor_runs_from_unguarded_top_level_code(tmp_path):
    (tmp_path / "serial_script.py").write_text(
        "from eval.bench.executors import make_executor\n\n"
        "print(sorted(result for _, result in make_executor('serial').map(abs, [-3, 4])))\n"
    )
    done = python("serial_script.py", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == ["[3, 4]"]


def test_the_refusal_is_bad_input_and_pytest_is_not_refused():
    assert issubclass(MainModuleError, InputError)
    call = check_main_guarded()  # python -m pytest: None; the pytest script: its guarded line
    assert call is None or call[1] is True, call


def test_a_dead_worker_s_message_names_the_main_module_where_it_may_be_the_cause():
    plain = died_message(2)
    assert plain == ("the worker process died 2 times while this run was unfinished (a crash in native code, or "
                     "killed for memory?); rerun with --executor serial to see the crash")  # fmt: skip
    hinted = died_message(2, MainCall("job.py", 5, True))
    assert "top-level code of the main module job.py that starts worker processes" in hinted and GUARD_FIX in hinted
    assert hinted.startswith("the worker process died 2 times") and "a crash in native code" in hinted
