"""Where the runs of a suite execute: in this process, in a local process pool, or on a Ray cluster.

Every executor maps a picklable function over picklable items and yields ``(item, result)`` pairs as runs finish,
in completion order; ``result`` is the function's return value, or the exception that stopped the run (a worker
process that died, a Ray task error). Executors never raise for one bad item: the others go on.

- ``serial``: in this process, one item after another (debugging; per-run progress bars).
- ``local`` (default): :class:`concurrent.futures.ProcessPoolExecutor` whose workers are clean interpreters (a
  process that made an EGL context must not fork). By default they are forked from a *fork server* that has
  imported the run function's module and the ``preload`` modules (numpy, torch, the agents: 2-3 s a run otherwise)
  and done nothing else: no renderer, no thread, no math; each run still gets a worker of its own, in the state a
  fresh interpreter has after those imports, so its bytes are those of a ``spawn`` worker
  (``tests/eval/bench/test_executors.py`` compares a CNN-SLAM run both ways). The server starts with the environment
  the pool's workers get (the thread limits below, and whatever else the caller set): a pool whose environment or
  preload differs from the running server's restarts it. ``start_method="spawn"`` starts each worker from scratch.
  Each worker limits its math libraries (OpenMP, MKL, OpenBLAS, numba, OpenCV, torch through ``OMP_NUM_THREADS``) and
  the software rasteriser (Mesa's llvmpipe) to ``threads`` threads (:func:`slamcommon.threads.thread_environment`), so
  ``jobs`` workers share the cores instead of oversubscribing them. By default every run
  gets a fresh worker process (``fresh_workers``): a run's result then never depends on which runs its worker did
  before (some agents' floating-point results do, slightly, through process-wide state), at the price of a
  process start and imports per run. When a worker dies (a crash in native code), the pool is rebuilt for the runs
  that had not finished; a run that was unfinished in :data:`MAX_POOL_BREAKS` broken pools is reported failed.
  At most ``jobs`` runs are handed to the pool at a time, so a run's clock starts when it is handed over (its
  worker's start included). Workers ignore SIGINT and die with the process that started them
  (:func:`die_with_parent`), so a ``kill -9`` of the parent leaves no orphan holding memory. When the consumer stops
  early (Ctrl-C, an exception while it handles a result, ``close()``), the workers are killed at once, unfinished
  runs are dropped and the exception goes on to the caller: nothing waits for runs whose results nobody takes.
  Workers of both start methods import the caller's main module again (a script run as ``python FILE`` or
  ``python -m MODULE``) before their first item: a pool started from its top-level code outside
  ``if __name__ == "__main__":`` would be started again in every worker, which then dies. Such a call is refused
  before any worker starts (:class:`MainModuleError`, with the fix), as is a main module read from standard input,
  which no worker can import; ``python -c``, an interactive session and a Jupyter kernel have no file to import.
- ``ray``: the same runs as Ray tasks, on the cluster at ``address`` (``"auto"``, ``"ray://host:10001"``,
  ``"local"`` for a new local one) or, without an address, on the Ray instance already initialised in this process,
  else on a new local one with ``jobs`` CPUs. Ray is an optional dependency (``pip install -e '.[ray]'``), imported
  only here and only when asked; its worker nodes need this package installed (the same ``pip install``).

A time limit per run (``timeout_s``) stops a run still unfinished after that many seconds and yields it as
:class:`RunTimedOut`. ``local`` kills its pool (a process pool cannot lose one worker without breaking) and restarts
the pool's other unfinished runs in a new one, with fresh clocks and without counting it against them. ``ray``
cancels the task with ``ray.cancel(force=True)``, which kills its worker, and then keeps at most as many tasks in
flight as the cluster has CPU slots for, so that a task's clock starts about when the task does. ``serial`` sets a
SIGALRM timer around each run (:func:`time_limit`) and stops it at the next Python bytecode after the limit: from the
main thread only (refused elsewhere), and native code that never returns to the interpreter (a deadlock in C) is not
stopped: ``local`` with one job stops anything.
"""

from __future__ import annotations

import ast
import contextlib
import ctypes
import linecache
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Literal, NamedTuple, Protocol, TypeVar, get_args

from eval.errors import EvalError, InputError
from slamcommon.threads import limit_threads, thread_environment

ExecutorName = Literal["local", "serial", "ray"]
EXECUTORS: tuple[str, ...] = get_args(ExecutorName)
MAX_POOL_BREAKS = 2  # broken pools a run may be unfinished in before it is reported failed (ours)
RAY_INSTALL_HINT = "pip install -c constraints.txt -e '.[ray]'"
PARENT_POLL_S = 0.5  # how often a worker's watchdog thread checks that its parent still lives
KILL_WAIT_S = 1.0  # how long stopping a pool waits for its manager thread and each killed worker
PR_SET_PDEATHSIG = 1  # linux/prctl.h

T = TypeVar("T")
R = TypeVar("R")


class ExecutorError(EvalError):
    """An executor that cannot be used (unknown name, bad job count, Ray missing or unreachable)."""


class WorkerDied(ExecutorError, RuntimeError):
    """The process running an item died (or its pool broke too often) before returning a result."""


class MainModuleError(ExecutorError, InputError):
    """Worker processes that would die before their first item, for the main module that each of them imports again:
    its top-level code starts them without ``if __name__ == "__main__":`` around the call (each worker would start
    the runs again instead of its own), or it is no file (standard input)."""


class RunTimedOut(ExecutorError):
    """A run was still unfinished after the executor's per-run time limit; it was stopped."""

    def __init__(self, timeout_s: float) -> None:
        super().__init__(f"run exceeded its time limit of {timeout_s:g} s")
        self.timeout_s = timeout_s

    def __reduce__(self) -> tuple[type, tuple[float]]:  # pickled with its limit, not its message
        return type(self), (self.timeout_s,)


class Executor(Protocol):
    """Maps ``fn`` over ``items``, yielding ``(item, result or exception)`` as each finishes."""

    name: str

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]: ...


def available_cores() -> int:
    """CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def threads_per_job(jobs: int) -> int:
    """Math-library threads per worker so that ``jobs`` workers fill the cores without oversubscribing them."""
    return max(1, available_cores() // max(1, int(jobs)))


def die_with_parent(parent: int, kernel: bool = True, poll_s: float = PARENT_POLL_S) -> None:
    """Make this process exit as soon as process ``parent`` (its parent, by pid) is gone, even by ``kill -9``.

    ``kernel``: on Linux, ask the kernel to send SIGKILL when the parent goes (``PR_SET_PDEATHSIG``): at once, and
    even while native code holds the GIL. The kernel ties that signal to the parent *thread* that started this
    process: CPython 3.11's pool starts the first workers from the thread that calls ``submit`` but the replacement
    of a worker that finished its runs (``max_tasks_per_child``) from its manager thread, which ends only after the
    pool's workers have ended, so the signal never comes early. A daemon thread that polls ``os.getppid()`` every
    ``poll_s`` seconds covers the rest: other systems, and a parent that died before the ``prctl`` call (``kernel``
    off leaves only this thread, for tests).
    """
    if kernel and sys.platform == "linux":
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)  # reparented: the parent is gone and nobody will collect this process's result

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def init_worker(threads: int, parent: int | None) -> None:
    """Set up a local pool worker: die with ``parent``, leave Ctrl-C to it, limit math threads to ``threads``.

    ``parent`` None: the worker's parent is the fork server, which exits when the process that started it does,
    so dying with the fork server is dying with the pool's owner. Ignoring SIGINT keeps a terminal's Ctrl-C (sent
    to the whole process group) from printing one traceback per worker; the parent kills its workers itself.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent is None:
        # A forked child inherits the server's "alive" pipe, which keeps the server running while any child holds
        # it; a worker starts no process of its own, so it lets go: the server then exits with the pool's owner.
        from multiprocessing import forkserver

        alive = forkserver._forkserver._forkserver_alive_fd
        if alive is not None:
            with contextlib.suppress(OSError):
                os.close(alive)
            forkserver._forkserver._forkserver_alive_fd = None
        parent = os.getppid()
    die_with_parent(parent)
    limit_threads(threads)


GUARD_FIX = 'put the call under `if __name__ == "__main__":`'


def _reimported_main() -> tuple[dict[str, Any], str] | None:
    """The main module's namespace and source file when ``spawn`` and ``forkserver`` workers run it again as
    ``__mp_main__`` before their first item (CPython's ``multiprocessing.spawn`` rules: a script or a ``-m`` module;
    not a package's ``__main__``, an IPython shell, ``python -c``, standard input or a Jupyter kernel, which have no
    file to import); None when they do not."""
    main = sys.modules.get("__main__")
    if main is None:
        return None
    name = getattr(getattr(main, "__spec__", None), "name", None)
    if name is not None:
        if name == "__main__" or name.endswith(".__main__"):
            return None
        path = getattr(main.__spec__, "origin", None)
    else:
        path = getattr(main, "__file__", None)
        if path is not None and os.path.splitext(os.path.basename(path))[0] == "ipython":
            return None
    return (vars(main), str(path)) if path else None


def _main_top_level_frame(namespace: dict[str, Any]) -> Any:
    """The outermost frame on this thread's stack that runs the main module's top-level code (namespace
    ``namespace``), or None: then the main module has finished importing, or this thread did not start from it."""
    frame, found = sys._getframe(1), None
    while frame is not None:
        if frame.f_globals is namespace and frame.f_code.co_name == "<module>":
            found = frame
        frame = frame.f_back
    return found


def _guarded(source: str, line: int) -> bool | None:
    """Whether line ``line`` of module ``source`` lies in the body of an ``if`` whose test reads ``__name__`` (the
    ``if __name__ == "__main__":`` idiom), outside any function or class; None when the source does not parse."""
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError):
        return None
    todo: list[ast.AST] = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef | ast.Lambda):
            continue  # another scope: never the main module's top-level code
        if (isinstance(node, ast.If)
                and any(st.lineno <= line <= (st.end_lineno or st.lineno) for st in (*node.body, *node.orelse))
                and any(isinstance(n, ast.Name) and n.id == "__name__" for n in ast.walk(node.test))):
            return True
        todo.extend(ast.iter_child_nodes(node))
    return False


class MainCall(NamedTuple):
    """A call that runs in the top-level code of a main module which new workers import again: its ``file`` (base
    name), the ``line`` of the top-level code running, and whether that line is under an ``if __name__`` test
    (``guarded``; None: the source cannot be read)."""

    file: str
    line: int
    guarded: bool | None


def main_module_call() -> MainCall | None:
    """Where this call comes from when it runs in the top-level code of a main module that new workers import again
    (see :func:`_reimported_main`); None when workers would not run this call again: the main module has no file,
    has finished importing, or this call does not come from its top-level code."""
    main = _reimported_main()
    if main is None:
        return None
    namespace, path = main
    frame = _main_top_level_frame(namespace)
    if frame is None:
        return None
    filename, line = frame.f_code.co_filename, frame.f_lineno
    lines = linecache.getlines(filename, namespace)
    guarded = _guarded("".join(lines), line) if lines else None
    return MainCall(os.path.basename(filename) or path, line, guarded)


def check_main_guarded() -> MainCall | None:
    """Refuse to start worker processes from the unguarded top-level code of a main module that they import again,
    or when the main module is no file they can import (:class:`MainModuleError`, one line with the fix): each
    worker would die before its own item. Returns :func:`main_module_call`'s answer otherwise (a ``WorkerDied``
    message names it where it cannot tell)."""
    main = _reimported_main()
    if main is not None and not os.path.isfile(os.path.join(multiprocessing.process.ORIGINAL_DIR or "", main[1])):
        raise MainModuleError(
            f"the main module {main[1]} is no file that worker processes can import, as each of them does before "
            "its first item: save the code as a file, run it with python -c, or use the serial executor"
        )
    call = main_module_call()
    if call is not None and call.guarded is False:
        raise MainModuleError(
            f"{call.file} line {call.line} starts worker processes in the top-level code of the main module, "
            f"which each worker runs again when it imports it: {GUARD_FIX} (or use the serial executor)"
        )
    return call


_FORK_SERVER_STATE: list[Any] = [None]  # (thread limit, preload, environment) the running fork server started with


def _function_modules(fn: Callable[..., Any] | None) -> tuple[str, ...]:
    """The module that defines ``fn`` (through ``functools.partial``), when it is an importable one."""
    fn = getattr(fn, "func", fn)
    module = getattr(fn, "__module__", None)
    return (module,) if module and module not in ("__main__", "builtins") else ()


def ensure_fork_server(threads: int, preload: Iterable[str]) -> None:
    """Have multiprocessing's fork server running with ``preload`` imported, under this process's environment with
    the math libraries limited to ``threads`` threads (the environment its children inherit). A server started
    with another environment or preload is stopped and started anew; this process's own environment is left as
    it was."""
    from multiprocessing import forkserver

    env = dict(os.environ)
    env.update(thread_environment(threads))
    state = (int(threads), tuple(dict.fromkeys(preload)), env)
    server = forkserver._forkserver
    if _FORK_SERVER_STATE[0] == state and server._forkserver_pid is not None:
        server.ensure_running()  # starts it again, with the same preload, if it died
        return
    server._stop()
    server.set_forkserver_preload(list(state[1]))
    saved = dict(os.environ)
    try:
        os.environ.clear()
        os.environ.update(env)
        server.ensure_running()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    _FORK_SERVER_STATE[0] = state


def kill_pool(pool: ProcessPoolExecutor) -> None:
    """Stop ``pool`` now: cancel its queued work and kill its workers (SIGKILL), where ``shutdown`` would wait for
    their runs to end. The public API cannot stop a running call, so this uses the pool's process table and manager
    thread (``_processes``, ``_executor_manager_thread``, the same in CPython 3.9-3.13)."""
    processes = pool._processes or {}  # the live table, which the manager thread also adds to
    for process in list(processes.values()):
        process.kill()
    if pool._executor_manager_thread is not None:
        pool._executor_manager_thread.join(KILL_WAIT_S)  # it sees a worker gone, fails the pool's futures and ends
    for process in list(processes.values()):  # a worker the manager started meanwhile (a replacement) as well
        process.kill()
        process.join(KILL_WAIT_S)
    # Only now: a manager thread still running after shutdown() may replace a worker and fail on the dropped table
    pool.shutdown(wait=False, cancel_futures=True)


def check_timeout(timeout_s: float | None) -> float | None:
    """``timeout_s`` as a float, if given; :class:`ExecutorError` unless it is positive."""
    if timeout_s is None:
        return None
    if not float(timeout_s) > 0:
        raise ExecutorError(f"the time limit of a run must be positive, got {timeout_s}")
    return float(timeout_s)


def _finished(future: Future) -> bool:
    """Whether ``future`` holds the run's own outcome (not a cancellation, not a pool that broke under it)."""
    return future.done() and not future.cancelled() and not isinstance(future.exception(), BrokenProcessPool)


class _Overtime(BaseException):
    """Raised in this process's main thread by SIGALRM when a serial run is past its time limit (a BaseException, so
    that a run's own ``except Exception`` does not swallow it)."""


def check_alarm() -> None:
    """:class:`ExecutorError` unless a serial run can be stopped by a timer signal here: a platform with
    ``signal.setitimer`` and the main thread (the only one Python delivers signals to)."""
    if not hasattr(signal, "setitimer"):
        raise ExecutorError("--executor serial stops a run past its time limit with SIGALRM, which this platform "
                            "lacks: use --executor local --jobs 1")  # fmt: skip
    if threading.current_thread() is not threading.main_thread():
        raise ExecutorError(f"--executor serial stops a run past its time limit with a signal, which only the main "
                            f"thread receives, and runs in thread {threading.current_thread().name!r}: use "
                            "--executor local --jobs 1")  # fmt: skip


@contextlib.contextmanager
def time_limit(timeout_s: float) -> Iterator[None]:
    """Raise :class:`_Overtime` in the code inside after ``timeout_s`` seconds (a SIGALRM timer; main thread only).
    Python runs the handler between bytecodes, so Python code, ``time.sleep`` and blocking I/O are stopped, native
    code only when it returns to the interpreter. The previous handler, and a timer the caller had set (less the
    time spent here), are put back."""

    def overtime(signum: int, frame: Any) -> None:
        raise _Overtime

    started = time.monotonic()
    previous = signal.signal(signal.SIGALRM, overtime)
    try:
        earlier, interval = signal.setitimer(signal.ITIMER_REAL, timeout_s)
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        if earlier > 0:  # the caller's own timer: what is left of it
            signal.setitimer(signal.ITIMER_REAL, max(1e-3, earlier - (time.monotonic() - started)), interval)


class SerialExecutor:
    """Runs every item in this process, in order; ``timeout_s``: a run's time limit, enforced by a SIGALRM timer
    (:func:`time_limit`: from the main thread only, and native code that never returns to the interpreter is not
    stopped; ``local`` with one job stops anything)."""

    name = "serial"

    def __init__(self, timeout_s: float | None = None) -> None:
        self.timeout_s = check_timeout(timeout_s)
        if self.timeout_s is not None:
            check_alarm()

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        if self.timeout_s is not None:
            check_alarm()
        for item in items:
            try:
                if self.timeout_s is None:
                    result: R | BaseException = fn(item)
                else:
                    with time_limit(self.timeout_s):
                        result = fn(item)
            except _Overtime:
                result = RunTimedOut(self.timeout_s or 0.0)
            except Exception as exc:  # noqa: BLE001 - one bad item never stops the others
                result = exc
            yield item, result  # outside the limit: the consumer's time is not the run's


class LocalExecutor:
    """A local process pool of ``jobs`` workers with ``threads`` math threads each; ``fresh_workers``: one worker
    process per item; ``timeout_s``: the time limit of a run; ``start_method``: ``forkserver`` (default where the
    platform has it: workers forked from a server that imported ``fn``'s module and ``preload``) or ``spawn`` (see
    the module docstring)."""

    name = "local"

    def __init__(
        self,
        jobs: int = 2,
        threads: int | None = None,
        start_method: str | None = None,
        fresh_workers: bool = True,
        timeout_s: float | None = None,
        preload: Iterable[str] = (),
    ) -> None:
        if int(jobs) < 1:
            raise ExecutorError(f"jobs must be >= 1, got {jobs}")
        self.jobs = int(jobs)
        if threads is not None and int(threads) < 1:
            raise ExecutorError(f"threads must be >= 1 (math threads per worker) or None, got {threads}")
        self.threads = int(threads) if threads is not None else threads_per_job(self.jobs)
        if start_method is None:
            start_method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
        if start_method not in ("forkserver", "spawn"):
            raise ExecutorError(f"start_method must be forkserver or spawn (clean interpreters), got {start_method!r}")
        self.start_method = start_method
        self.preload = tuple(preload)
        self.fresh_workers = bool(fresh_workers)
        self.timeout_s = check_timeout(timeout_s)
        self._main_call: MainCall | None = None  # where map was last called from (check_main_guarded)

    def _pool(self, fn: Callable[..., Any] | None = None) -> ProcessPoolExecutor:
        if self.start_method == "forkserver":
            ensure_fork_server(self.threads, (*_function_modules(fn), *self.preload))
        return ProcessPoolExecutor(
            max_workers=self.jobs,
            mp_context=multiprocessing.get_context(self.start_method),
            initializer=init_worker,
            initargs=(self.threads, None if self.start_method == "forkserver" else os.getpid()),
            max_tasks_per_child=1 if self.fresh_workers else None,
        )

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        """``fn`` over ``items`` in worker processes; :class:`MainModuleError` before any worker starts when this is
        called from the unguarded top-level code of a main module the workers import again
        (:func:`check_main_guarded`)."""
        self._main_call = check_main_guarded()
        todo = list(items)
        breaks = [0] * len(todo)
        waiting = deque(range(len(todo)))  # runs not handed to a pool yet, by index, in order
        while waiting:
            pool = self._pool(fn)
            complete = False
            try:
                yield from self._run_in(pool, fn, todo, waiting, breaks)
                complete = True
            finally:
                if complete:
                    pool.shutdown(wait=True)
                else:  # Ctrl-C, an exception in the consumer, close(): nobody takes the unfinished runs' results
                    kill_pool(pool)

    def _run_in(
        self, pool: ProcessPoolExecutor, fn: Callable[[T], R], todo: list[T], waiting: deque[int], breaks: list[int]
    ) -> Iterator[tuple[T, R | BaseException]]:
        """Hand the ``waiting`` runs to ``pool``, ``jobs`` at a time, and yield them as they finish. Returns when
        none is left, or early, with the pool killed and its unfinished runs back at the front of ``waiting``, when
        a worker died or a run went past its time limit."""
        limit = self.timeout_s if self.timeout_s is not None else math.inf
        running: dict[Future, tuple[int, float]] = {}  # -> (run index, deadline on the monotonic clock)
        while waiting or running:
            broken = False
            try:
                while waiting and len(running) < self.jobs:
                    running[pool.submit(fn, todo[waiting[0]])] = (waiting[0], time.monotonic() + limit)
                    waiting.popleft()
            except BrokenProcessPool:  # a worker died since the last wait
                broken = True
            done: set[Future] = set()
            if not broken:
                deadline = min(d for _, d in running.values())
                timeout = None if deadline == math.inf else max(0.0, deadline - time.monotonic())
                done, _ = wait(running, timeout=timeout, return_when=FIRST_COMPLETED)
            if broken or any(not _finished(f) for f in done):
                # A worker died, and the pool with it (which worker is unknown): charge every unfinished run
                kill_pool(pool)
                yield from self._settle(running, set(), todo, waiting, breaks)
                return
            for future in done:
                k, _ = running.pop(future)
                exc = future.exception()
                yield todo[k], (exc if exc is not None else future.result())
            now = time.monotonic()
            late = {f for f, (_, d) in running.items() if d <= now}
            if late:
                kill_pool(pool)  # the only way to stop a run; the others start again in the next pool
                yield from self._settle(running, late, todo, waiting, breaks)
                return

    def _settle(
        self,
        running: dict[Future, tuple[int, float]],
        late: set[Future],
        todo: list[T],
        waiting: deque[int],
        breaks: list[int],
    ) -> Iterator[tuple[T, R | BaseException]]:
        """Sort out the runs of a killed pool: yield those that finished all the same and the ``late`` ones (timed
        out); put the others back in front of ``waiting``, each charged a break unless the pool was killed for a
        late run; yield a run that has had :data:`MAX_POOL_BREAKS` breaks as failed."""
        wait(running, timeout=KILL_WAIT_S)  # a killed pool fails its futures from its manager thread
        again = []
        for future, (k, _) in sorted(running.items(), key=lambda entry: entry[1][0]):
            if _finished(future):
                exc = future.exception()
                yield todo[k], (exc if exc is not None else future.result())
            elif future in late:
                yield todo[k], RunTimedOut(self.timeout_s or 0.0)
            elif late:
                again.append(k)
            else:
                breaks[k] += 1
                if breaks[k] < MAX_POOL_BREAKS:
                    again.append(k)
                    continue
                yield todo[k], WorkerDied(died_message(breaks[k], self._main_call))
        waiting.extendleft(reversed(again))


def died_message(times: int, main_call: MainCall | None = None) -> str:
    """What a run whose worker died ``times`` times failed of; ``main_call``: the pool was started from the top-level
    code of a main module that the workers import again (:func:`main_module_call`), where any line that starts
    workers outside ``if __name__ == "__main__":`` kills every worker before its run."""
    cause = "a crash in native code, or killed for memory?"
    if main_call is not None:
        cause = (f"a crash in native code, killed for memory, or top-level code of the main module {main_call.file} "
                 f"that starts worker processes, which each worker runs again when it imports it: {GUARD_FIX}?")
    return (f"the worker process died {times} times while this run was unfinished ({cause}); "
            "rerun with --executor serial to see the crash")


def import_ray() -> Any:
    """The ``ray`` module, or :class:`ExecutorError` saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise ExecutorError(
            f"--executor ray needs Ray, which is not installed ({exc}); install the optional extra: {RAY_INSTALL_HINT}"
        ) from exc
    return ray


def _call(fn: Callable[[T], R], item: T) -> R:
    """What a Ray task runs (``ray.remote`` needs a plain function)."""
    return fn(item)


class RayExecutor:
    """Ray tasks of ``cpus_per_task`` CPUs each on the cluster at ``address``, ``timeout_s`` the time limit of each
    (see the module docstring)."""

    name = "ray"

    def __init__(
        self,
        address: str | None = None,
        jobs: int = 2,
        cpus_per_task: float = 1.0,
        timeout_s: float | None = None,
    ) -> None:
        if int(jobs) < 1:
            raise ExecutorError(f"jobs must be >= 1, got {jobs}")
        if not cpus_per_task > 0:
            raise ExecutorError(f"cpus_per_task must be positive, got {cpus_per_task}")
        self.address = address
        self.jobs = int(jobs)
        self.cpus_per_task = float(cpus_per_task)
        self.timeout_s = check_timeout(timeout_s)

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        ray = import_ray()
        waiting = deque(items)
        started = False
        if not ray.is_initialized():
            threads = max(1, int(self.cpus_per_task))
            options: dict[str, Any] = {
                "runtime_env": {"env_vars": thread_environment(threads)},
                "include_dashboard": False,
                "log_to_driver": False,
            }
            if self.address:
                options["address"] = self.address
            else:
                options["num_cpus"] = self.jobs
            try:
                ray.init(**options)
            except Exception as exc:  # noqa: BLE001 - Ray raises several types for an unreachable cluster
                where = f"the Ray cluster at {self.address!r}" if self.address else "a local Ray instance"
                raise ExecutorError(f"cannot start or reach {where}: {type(exc).__name__}: {exc}") from exc
            started = True
        limit = self.timeout_s if self.timeout_s is not None else math.inf
        slots = len(waiting)
        if self.timeout_s is not None:  # only tasks that can start at once, so that a clock starts with its task
            slots = max(1, int(ray.cluster_resources().get("CPU", self.jobs) // self.cpus_per_task))
        pending: dict[Any, tuple[T, float]] = {}  # object ref -> (item, deadline on the monotonic clock)
        try:
            task = ray.remote(num_cpus=self.cpus_per_task, max_retries=0)(_call)
            while waiting or pending:
                while waiting and len(pending) < slots:
                    item = waiting.popleft()
                    pending[task.remote(fn, item)] = (item, time.monotonic() + limit)
                deadline = min(d for _, d in pending.values())
                timeout = None if deadline == math.inf else max(0.0, deadline - time.monotonic())
                done, _ = ray.wait(list(pending), num_returns=1, timeout=timeout)
                for ref in done:
                    item, _ = pending.pop(ref)
                    try:
                        yield item, ray.get(ref)
                    except Exception as exc:  # noqa: BLE001 - a task error or a dead worker: this run failed
                        yield item, exc
                now = time.monotonic()
                for ref in [ref for ref, (_, d) in pending.items() if d <= now]:
                    item, _ = pending.pop(ref)
                    ray.cancel(ref, force=True)  # kills the worker process that runs it
                    yield item, RunTimedOut(limit)
        finally:
            for ref in pending:  # stopped early (Ctrl-C, an exception in the consumer): nobody takes these results
                with contextlib.suppress(Exception):  # a Ray already gone must not hide the exception that stopped us
                    ray.cancel(ref, force=True)
            if started:
                ray.shutdown()


def make_executor(
    name: str,
    jobs: int = 2,
    address: str | None = None,
    fresh_workers: bool = True,
    timeout_s: float | None = None,
    preload: Iterable[str] = (),
    threads: int | None = None,
) -> Executor:
    """An executor by name (``local``, ``serial``, ``ray``); ``address`` only for ``ray``; ``fresh_workers``,
    ``preload`` (modules the fork server imports for its workers) and ``threads`` (math threads per worker; None:
    the cores shared among the jobs) only for ``local``; ``timeout_s``, the time limit of a run, for every kind
    (``serial``: from the main thread, see :func:`time_limit`)."""
    if name not in EXECUTORS:
        raise ExecutorError(f"unknown executor {name!r}; valid executors: {', '.join(EXECUTORS)}")
    if address and name != "ray":
        raise ExecutorError(f"--address is for --executor ray, not {name!r}")
    timeout_s = check_timeout(timeout_s)
    if name == "serial":
        return SerialExecutor(timeout_s)
    if name == "local":
        check_main_guarded()  # now, before the suite is planned further, rather than at its first run
        return LocalExecutor(jobs, threads, fresh_workers=fresh_workers, timeout_s=timeout_s, preload=preload)
    import_ray()  # fail now, with the install hint, not after the suite is planned
    return RayExecutor(address, jobs, timeout_s=timeout_s)
