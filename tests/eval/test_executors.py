"""Executors: serial, local process pool (spawn, thread limits, dead workers), Ray (optional, local instance)."""

import json
import math
import os
import sys
import textwrap

import pytest

from eval.executors import (
    ExecutorError,
    LocalExecutor,
    RayExecutor,
    SerialExecutor,
    WorkerDied,
    import_ray,
    make_executor,
    threads_per_job,
)
from eval.methods import load_methods
from eval.runner import RunSpec, execute_run, run_suite
from eval.suites import SequenceRef, get_suite


def results(executor, fn, items):
    return {item: result for item, result in executor.map(fn, items)}


def test_serial_executor_returns_errors_instead_of_raising():
    out = results(SerialExecutor(), math.sqrt, [4.0, -1.0, 9.0])
    assert out[4.0] == 2.0 and out[9.0] == 3.0 and isinstance(out[-1.0], ValueError)


def test_local_pool_runs_in_spawned_workers_with_limited_threads():
    pool = LocalExecutor(jobs=2, threads=1)
    assert results(pool, os.getenv, ["OMP_NUM_THREADS", "NUMBA_NUM_THREADS"]) == {
        "OMP_NUM_THREADS": "1",
        "NUMBA_NUM_THREADS": "1",
    }
    out = results(pool, math.sqrt, [16.0, -4.0])
    assert out[16.0] == 4.0 and isinstance(out[-4.0], ValueError)
    assert threads_per_job(1) >= threads_per_job(64) == 1


def test_fresh_workers_give_every_run_its_own_process(tmp_path, monkeypatch):
    (tmp_path / "pid_work.py").write_text("import os\n\ndef pid(item):\n    return os.getpid()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import pid_work

    fresh = set(results(LocalExecutor(jobs=1), pid_work.pid, range(3)).values())
    reused = set(results(LocalExecutor(jobs=1, fresh_workers=False), pid_work.pid, range(3)).values())
    assert len(fresh) == 3 and len(reused) == 1 and os.getpid() not in fresh | reused


def test_a_dead_worker_fails_its_run_only(tmp_path, monkeypatch):
    (tmp_path / "crashy_work.py").write_text(
        textwrap.dedent(
            """
            import os, time

            def work(item):
                if item == "crash":
                    time.sleep(1.0)  # the other items finish first
                    os._exit(3)      # dies like a segfault in native code would
                return item * 2
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))  # spawned workers inherit sys.path
    import crashy_work

    out = results(LocalExecutor(jobs=2, threads=1), crashy_work.work, [1, "crash", 2])
    assert out[1] == 2 and out[2] == 4
    assert isinstance(out["crash"], WorkerDied) and "died 2 times" in str(out["crash"])


def test_choosing_an_executor():
    assert isinstance(make_executor("serial"), SerialExecutor)
    local = make_executor("local", jobs=3)
    assert isinstance(local, LocalExecutor) and local.jobs == 3
    with pytest.raises(ExecutorError, match="valid executors: local, serial, ray"):
        make_executor("dask")
    with pytest.raises(ExecutorError, match="--address is for --executor ray"):
        make_executor("local", address="auto")
    with pytest.raises(ExecutorError, match="jobs must be >= 1"):
        LocalExecutor(jobs=0)


def test_ray_missing_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if not installed
    with pytest.raises(ExecutorError, match=r"pip install -c constraints.txt -e '.\[ray\]'"):
        import_ray()
    with pytest.raises(ExecutorError, match="needs Ray"):
        make_executor("ray")


def test_ray_runs_the_same_runs_as_the_local_executors(tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        out = results(RayExecutor(), math.sqrt, [25.0, -1.0])
        assert out[25.0] == 5.0 and isinstance(out[-1.0], Exception)
        methods = load_methods()
        suite = get_suite("quick").select(["office0"], ["oracle"], frames=5)
        run = run_suite(suite, methods, tmp_path, executor=RayExecutor(), plots=False, progress=False,
                        check=False, revision="r")  # fmt: skip
        assert run.counts() == {"done": 1}
    finally:
        ray.shutdown()
    serial = execute_run(RunSpec("quick", SequenceRef("office0", base="office0"), methods["oracle"], frames=5,
                                 plots=False, git_revision="r"))  # fmt: skip
    on_ray = (tmp_path / "quick" / "office0" / "oracle" / "seed0-frames5" / "metrics.json").read_bytes()
    assert on_ray == serial.files["metrics.json"]
    assert json.loads(on_ray)["metrics"]["ate_rmse"] == 0.0
