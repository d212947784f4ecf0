"""Executors: serial, local process pool (spawn, thread limits, dead workers, Ctrl-C, orphans, time limits), Ray
(a local instance)."""

import json
import math
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest

from eval.bench.executors import (
    ExecutorError,
    LocalExecutor,
    RayExecutor,
    RunTimedOut,
    SerialExecutor,
    WorkerDied,
    import_ray,
    make_executor,
    threads_per_job,
)
from eval.bench.methods import load_methods
from eval.bench.run import RunSpec, execute_run
from eval.bench.runner import run_suite
from eval.bench.sequence_ref import SequenceRef
from eval.bench.suites import get_suite

linux_only = pytest.mark.skipif(sys.platform != "linux", reason="Linux only: reads worker processes from /proc")


def results(executor, fn, items):
    return {item: result for item, result in executor.map(fn, items)}


@pytest.fixture
def nap_work(tmp_path, monkeypatch):
    """A module with a picklable function that sleeps ``item`` seconds and returns ``item`` (spawned workers import
    it by name: they inherit ``sys.path``)."""
    (tmp_path / "nap_work.py").write_text(
        "import time\n\ndef nap(seconds):\n    time.sleep(seconds)\n    return seconds\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    import nap_work

    return nap_work


def _processes() -> list[tuple[int, int, str, bytes]]:
    """(pid, parent pid, state, command line) of every process, read from /proc."""
    rows = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            rows.append((int(stat.parent.name), int(fields[1]), fields[0], (stat.parent / "cmdline").read_bytes()))
        except (OSError, IndexError):  # ended meanwhile
            continue
    return rows


def pool_workers(parent: int) -> set[int]:
    """The live (not zombie) pool workers of process ``parent``, read from /proc: its spawned children, or the
    children of its fork server (a worker forked there has the server's command line, the server is the parent's
    child)."""
    rows = _processes()
    servers = {pid for pid, ppid, _, command in rows if ppid == parent and b"forkserver" in command}
    return {pid for pid, ppid, state, command in rows
            if state != "Z" and ((ppid == parent and b"spawn_main" in command) or ppid in servers)}


def alive(pid: int) -> bool:
    """Whether ``pid`` is a process that still runs (a zombie has ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


def wait_for(condition, timeout_s: float, step_s: float = 0.05):
    """Poll ``condition()`` until it is truthy (returned) or ``timeout_s`` has passed (its last value returned)."""
    end = time.monotonic() + timeout_s
    while not (value := condition()) and time.monotonic() < end:
        time.sleep(step_s)
    return value


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


@linux_only
def test_ctrl_c_kills_the_workers_at_once(nap_work):
    if threading.current_thread() is not threading.main_thread():
        pytest.skip("SIGINT raises KeyboardInterrupt in the main thread only: run pytest in its main thread")
    parent = os.getpid()
    workers: set[int] = set()
    sent: list[float] = []

    def interrupt():  # like a terminal's Ctrl-C, once both workers run their 30 s naps
        workers.update(wait_for(lambda: len(pool_workers(parent)) == 2 and pool_workers(parent), 20.0) or ())
        time.sleep(0.5)
        sent.append(time.monotonic())
        signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # a test runner may have its own
    timer = threading.Thread(target=interrupt)
    try:
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            for _ in LocalExecutor(jobs=2, threads=1).map(nap_work.nap, [30, 30, 30]):
                pass
        stopped = time.monotonic()
    finally:
        timer.join()
        signal.signal(signal.SIGINT, previous)
    assert len(workers) == 2 and stopped - sent[0] < 2.0
    assert not [pid for pid in workers if alive(pid)] and not pool_workers(parent)


@linux_only
def test_an_exception_in_the_consumer_kills_the_workers_at_once(nap_work):
    parent = os.getpid()
    with pytest.raises(KeyboardInterrupt):
        for item, _ in LocalExecutor(jobs=2, threads=1).map(nap_work.nap, [0.1, 30, 30]):
            assert item == 0.1 and wait_for(lambda: len(pool_workers(parent)) == 2, 20.0)
            workers = pool_workers(parent)
            raised = time.monotonic()
            raise KeyboardInterrupt  # while storing a result, say
    assert time.monotonic() - raised < 2.0
    assert not [pid for pid in workers if alive(pid)] and not pool_workers(parent)


PARENT_SCRIPT = """
import sys
sys.path.insert(0, {path!r})
import nap_work
from eval.bench.executors import LocalExecutor

if __name__ == "__main__":
    # the first run ends at once; its replacement worker may be started by the pool's manager thread
    for item, result in LocalExecutor(jobs=2, threads=1).map(nap_work.nap, [0.1, 60, 60]):
        print(item, flush=True)
"""


@linux_only
def test_workers_die_with_their_parent(nap_work, tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(PARENT_SCRIPT.format(path=str(tmp_path)))
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout.readline().strip() == "0.1"
        workers = wait_for(lambda: len(pool_workers(parent.pid)) == 2 and pool_workers(parent.pid), 20.0)
        assert workers
    finally:
        parent.kill()  # SIGKILL: no clean-up code runs in the parent
        parent.wait()
    assert wait_for(lambda: not any(alive(pid) for pid in workers), 5.0)


WATCHDOG_SCRIPT = """
import multiprocessing, os, sys, time
from eval.bench.executors import die_with_parent

def child(parent):
    die_with_parent(parent, kernel=False, poll_s=0.1)
    print("watching", flush=True)
    time.sleep(60)

if __name__ == "__main__":
    process = multiprocessing.get_context("spawn").Process(target=child, args=(os.getpid(),))
    process.start()
    print(process.pid, flush=True)
    time.sleep(60)
"""


@linux_only
def test_without_the_kernel_a_watchdog_thread_ends_a_worker_whose_parent_died(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(WATCHDOG_SCRIPT)
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        child = int(parent.stdout.readline())
        assert parent.stdout.readline().strip() == "watching"
    finally:
        parent.kill()
        parent.wait()
    assert wait_for(lambda: not alive(child), 5.0)


@linux_only
def test_a_run_past_its_time_limit_is_stopped_and_reported(nap_work):
    parent = os.getpid()
    started = time.monotonic()
    out = results(LocalExecutor(jobs=2, threads=1, timeout_s=2), nap_work.nap, [60, 0.2, 0.3, 0.4, 0.5, 0.6])
    assert time.monotonic() - started < 20.0
    assert isinstance(out[60], RunTimedOut) and str(out[60]) == "run exceeded its time limit of 2 s"
    assert isinstance(out[60], ExecutorError) and str(pickle.loads(pickle.dumps(out[60]))) == str(out[60])
    assert {item: result for item, result in out.items() if item != 60} == {s: s for s in (0.2, 0.3, 0.4, 0.5, 0.6)}
    assert not pool_workers(parent)


def test_time_limits_per_executor():
    assert make_executor("local", timeout_s=5).timeout_s == 5.0
    assert make_executor("local").timeout_s is None
    assert make_executor("serial", timeout_s=5).timeout_s == 5.0 and make_executor("serial").timeout_s is None
    for kind in ("local", "serial"):
        with pytest.raises(ExecutorError, match="must be positive"):
            make_executor(kind, timeout_s=0)


def overtime_work(item):
    """Sleeps ``item`` seconds, swallowing any Exception (a run that catches everything), and returns ``item``."""
    try:
        time.sleep(item)
    except Exception:  # noqa: BLE001 - what a careless agent does; the time limit must still stop it
        return "swallowed"
    return item


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the serial executor's limit is a SIGALRM timer")
def test_the_serial_executor_stops_a_run_past_its_time_limit():
    """In this process: the late run (even one that catches every Exception) is yielded as RunTimedOut, the others
    run; the SIGALRM handler and a timer the caller had set are put back."""
    def mine(signum, frame):
        raise AssertionError("the caller's timer went off during the runs")

    saved = signal.signal(signal.SIGALRM, mine)
    try:
        signal.setitimer(signal.ITIMER_REAL, 100.0)
        started = time.monotonic()
        out = list(SerialExecutor(timeout_s=0.5).map(overtime_work, [0.01, 60, 0.02]))
        assert time.monotonic() - started < 20.0
        assert [item for item, _ in out] == [0.01, 60, 0.02]
        assert out[0][1] == 0.01 and out[2][1] == 0.02
        assert isinstance(out[1][1], RunTimedOut) and str(out[1][1]) == "run exceeded its time limit of 0.5 s"
        assert signal.getsignal(signal.SIGALRM) is mine
        left, _ = signal.getitimer(signal.ITIMER_REAL)
        assert 80.0 < left < 100.0  # the caller's timer, less the time spent
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, saved)
    out = dict(SerialExecutor(timeout_s=5).map(math.sqrt, [4.0, -1.0]))  # errors are still results
    assert out[4.0] == 2.0 and isinstance(out[-1.0], ValueError)
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the serial executor's limit is a SIGALRM timer")
def test_the_serial_executor_s_time_limit_is_refused_off_the_main_thread():
    errors = []

    def make():
        try:
            make_executor("serial", timeout_s=5)
        except ExecutorError as exc:
            errors.append(str(exc))

    thread = threading.Thread(target=make, name="bench-thread")
    thread.start()
    thread.join()
    assert errors == ["--executor serial stops a run past its time limit with a signal, which only the main thread "
                      "receives, and runs in thread 'bench-thread': use --executor local --jobs 1"]  # fmt: skip
    assert isinstance(make_executor("serial"), SerialExecutor)  # no limit: any thread


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
    with pytest.raises(ExecutorError, match="threads must be >= 1"):
        LocalExecutor(jobs=1, threads=0)


def test_ray_missing_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # as if not installed
    with pytest.raises(ExecutorError, match=r"pip install -c constraints.txt -e '.\[ray\]'"):
        import_ray()
    with pytest.raises(ExecutorError, match="needs Ray"):
        make_executor("ray")


@pytest.mark.slow  # > 5 s: the full lane only
def test_ray_runs_the_same_runs_as_the_local_executors(tmp_path):
    if os.environ.get("CI"):  # make test installs Ray (the dev extra): CI must not skip the distributed path
        import ray
    else:
        ray = pytest.importorskip("ray", reason="ray is not installed (pip install -c constraints.txt -e '.[ray]')")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        items = [25.0, -1.0, 2.0]
        on_ray = results(RayExecutor(), math.sqrt, items)
        assert on_ray[25.0] == 5.0 and isinstance(on_ray[-1.0], Exception)
        local = results(LocalExecutor(jobs=2, threads=1), math.sqrt, items)
        assert on_ray[25.0] == local[25.0] and on_ray[2.0] == local[2.0] and isinstance(local[-1.0], ValueError)
        methods = load_methods()
        suite = get_suite("quick").select(["office0@clean"], ["oracle"], frames=5, seeds=[0])
        run = run_suite(suite, methods, tmp_path / "ray", executor=RayExecutor(), plots=False, progress=False,
                        check=False, revision="r")  # fmt: skip
        assert run.counts() == {"done": 1}
        timed = results(RayExecutor(timeout_s=2), time.sleep, [60, 0.1])
        assert str(timed[60]) == "run exceeded its time limit of 2 s" and timed[0.1] is None
    finally:
        ray.shutdown()
    run = run_suite(suite, methods, tmp_path / "local", executor=LocalExecutor(jobs=1), plots=False, progress=False,
                    check=False, revision="r")  # fmt: skip
    assert run.counts() == {"done": 1}
    serial = execute_run(RunSpec("quick", SequenceRef("office0", base="office0"), methods["oracle"], frames=5,
                                 plots=False, git_revision="r"))  # fmt: skip
    metrics = [tmp_path / where / "quick/office0/oracle/seed0-frames5/metrics.json" for where in ("ray", "local")]
    assert metrics[0].read_bytes() == metrics[1].read_bytes() == serial.files["metrics.json"]
    assert json.loads(serial.files["metrics.json"])["metrics"]["ate_rmse"] < 1e-9  # the oracle: exact poses


@pytest.mark.slow  # > 5 s: the full lane only
def test_fork_server_workers_give_the_bytes_of_spawned_ones():
    """A run in a worker forked from the preloaded fork server (after that server served other runs) writes the
    same bytes as in a freshly spawned interpreter: CNN-SLAM (network, numba kernels, threads) and LSD-BS; the
    server has imported what a suite's does (the agents, the network's module and torch: methods.toml's preload,
    the plots)."""
    methods = load_methods()
    ref = SequenceRef("office0", base="office0")

    def spec(name: str, seed: int = 0) -> RunSpec:
        return RunSpec("quick", ref, methods[name], seed=seed, frames=30, plots=False, git_revision="r")

    order = [spec("LSD-BS"), spec("CNN-SLAM", 1), spec("CNN-SLAM"), spec("LSD-BS", 1)]
    preload = ("cnnslam.agent", "cnnslam.baselines", "cnnslam.depthnet.predict", "eval.reports.plots")
    forked = {s.key: r for s, r in LocalExecutor(jobs=1, start_method="forkserver", preload=preload).map(execute_run,
                                                                                                          order)}
    spawned = {s.key: r for s, r in LocalExecutor(jobs=1, start_method="spawn").map(execute_run, order[2:])}
    for item in order[2:]:
        a, b = forked[item.key], spawned[item.key]
        assert a.status == b.status == "done", (a.error, b.error)
        compared = sorted(set(a.files) - {"timing.json", "agent_extras.json"})  # these two hold wall times
        assert "trajectory.tum" in compared and "metrics.json" in compared and "keyframes.npz" in compared
        assert {k: a.files[k] for k in compared} == {k: b.files[k] for k in compared}, item.key
        extras = [_without_times(json.loads(r.files["agent_extras.json"])) for r in (a, b)]
        assert extras[0] == extras[1]


def _without_times(value):
    """A JSON value without its wall-time entries (keys naming seconds or ms)."""
    if isinstance(value, dict):
        return {k: _without_times(v) for k, v in value.items() if "seconds" not in k and not k.endswith("_ms")}
    if isinstance(value, list):
        return [_without_times(v) for v in value]
    return value
