"""Where the runs of a suite execute: in this process, in a local process pool, or on a Ray cluster.

Every executor maps a picklable function over picklable items and yields ``(item, result)`` pairs as runs finish,
in completion order; ``result`` is the function's return value, or the exception that stopped the run (a worker
process that died, a Ray task error). Executors never raise for one bad item: the others go on.

- ``serial``: in this process, one item after another (debugging; per-run progress bars).
- ``local`` (default): :class:`concurrent.futures.ProcessPoolExecutor` with the ``spawn`` start method (a process
  that made an EGL context must not fork; ``spawn`` starts clean interpreters that build their renderers lazily).
  Each worker limits its math libraries (OpenMP, MKL, OpenBLAS, numba, OpenCV, torch through ``OMP_NUM_THREADS``) to
  ``threads`` threads, so ``jobs`` workers share the cores instead of oversubscribing them. By default every run
  gets a fresh worker process (``fresh_workers``): a run's result then never depends on which runs its worker did
  before (some agents' floating-point results do, slightly, through process-wide state), at the price of a
  process start and imports per run. When a worker dies (a crash in native code), the pool is rebuilt for the runs
  that had not finished; a run that was unfinished in :data:`MAX_POOL_BREAKS` broken pools is reported failed.
- ``ray``: the same runs as Ray tasks, on the cluster at ``address`` (``"auto"``, ``"ray://host:10001"``,
  ``"local"`` for a new local one) or, without an address, on the Ray instance already initialised in this process,
  else on a new local one with ``jobs`` CPUs. Ray is an optional dependency (``pip install -e '.[ray]'``), imported
  only here and only when asked; its worker nodes need this package installed (the same ``pip install``).
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Literal, Protocol, TypeVar, get_args

from eval.errors import EvalError

ExecutorName = Literal["local", "serial", "ray"]
EXECUTORS: tuple[str, ...] = get_args(ExecutorName)
MAX_POOL_BREAKS = 2  # broken pools a run may be unfinished in before it is reported failed (ours)
THREAD_VARIABLES: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "NUMBA_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)
RAY_INSTALL_HINT = "pip install -c constraints.txt -e '.[ray]'"

T = TypeVar("T")
R = TypeVar("R")


class ExecutorError(EvalError):
    """An executor that cannot be used (unknown name, bad job count, Ray missing or unreachable)."""


class WorkerDied(ExecutorError, RuntimeError):
    """The process running an item died (or its pool broke too often) before returning a result."""


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


def limit_threads(threads: int) -> None:
    """Limit this process's math libraries to ``threads`` threads (call before they are imported: a pool's
    initializer). OpenCV, when already imported, is limited directly."""
    for name in THREAD_VARIABLES:
        os.environ[name] = str(int(threads))
    try:
        import cv2

        cv2.setNumThreads(int(threads))
    except ImportError:  # OpenCV is a dependency; without it there is nothing to limit
        pass


class SerialExecutor:
    """Runs every item in this process, in order."""

    name = "serial"

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        for item in items:
            try:
                yield item, fn(item)
            except Exception as exc:  # noqa: BLE001 - one bad item never stops the others
                yield item, exc


class LocalExecutor:
    """A local process pool (``spawn``) of ``jobs`` workers with ``threads`` math threads each; ``fresh_workers``:
    one worker process per item (see the module docstring)."""

    name = "local"

    def __init__(
        self, jobs: int = 2, threads: int | None = None, start_method: str = "spawn", fresh_workers: bool = True
    ) -> None:
        if int(jobs) < 1:
            raise ExecutorError(f"jobs must be >= 1, got {jobs}")
        self.jobs = int(jobs)
        self.threads = int(threads) if threads is not None else threads_per_job(self.jobs)
        self.start_method = start_method
        self.fresh_workers = bool(fresh_workers)

    def _pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.jobs,
            mp_context=multiprocessing.get_context(self.start_method),
            initializer=limit_threads,
            initargs=(self.threads,),
            max_tasks_per_child=1 if self.fresh_workers else None,
        )

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        todo = list(items)
        breaks = [0] * len(todo)
        remaining = list(range(len(todo)))
        while remaining:
            pool = self._pool()
            futures: dict[Future, int] = {}
            broken = False
            try:
                for k in remaining:
                    futures[pool.submit(fn, todo[k])] = k
                pending = set(futures)
                while pending:
                    done, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for future in done:
                        k = futures[future]
                        exc = future.exception()
                        if isinstance(exc, BrokenProcessPool):
                            broken = True
                            continue
                        remaining.remove(k)
                        yield todo[k], (exc if exc is not None else future.result())
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            if broken:
                for k in list(remaining):
                    breaks[k] += 1
                    if breaks[k] >= MAX_POOL_BREAKS:
                        remaining.remove(k)
                        yield todo[k], WorkerDied(
                            f"the worker process died {breaks[k]} times while this run was unfinished (a crash in "
                            "native code, or killed for memory?); rerun with --executor serial to see the crash"
                        )


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
    """Ray tasks of ``cpus_per_task`` CPUs each on the cluster at ``address`` (see the module docstring)."""

    name = "ray"

    def __init__(self, address: str | None = None, jobs: int = 2, cpus_per_task: float = 1.0) -> None:
        if int(jobs) < 1:
            raise ExecutorError(f"jobs must be >= 1, got {jobs}")
        if not cpus_per_task > 0:
            raise ExecutorError(f"cpus_per_task must be positive, got {cpus_per_task}")
        self.address = address
        self.jobs = int(jobs)
        self.cpus_per_task = float(cpus_per_task)

    def map(self, fn: Callable[[T], R], items: Iterable[T]) -> Iterator[tuple[T, R | BaseException]]:
        ray = import_ray()
        todo = list(items)
        started = False
        if not ray.is_initialized():
            threads = str(max(1, int(self.cpus_per_task)))
            options: dict[str, Any] = {
                "runtime_env": {"env_vars": dict.fromkeys(THREAD_VARIABLES, threads)},
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
        try:
            task = ray.remote(num_cpus=self.cpus_per_task, max_retries=0)(_call)
            pending = {task.remote(fn, item): item for item in todo}
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    item = pending.pop(ref)
                    try:
                        yield item, ray.get(ref)
                    except Exception as exc:  # noqa: BLE001 - a task error or a dead worker: this run failed
                        yield item, exc
        finally:
            if started:
                ray.shutdown()


def make_executor(name: str, jobs: int = 2, address: str | None = None, fresh_workers: bool = True) -> Executor:
    """An executor by name (``local``, ``serial``, ``ray``); ``address`` only for ``ray``; ``fresh_workers`` only
    for ``local``."""
    if name not in EXECUTORS:
        raise ExecutorError(f"unknown executor {name!r}; valid executors: {', '.join(EXECUTORS)}")
    if address and name != "ray":
        raise ExecutorError(f"--address is for --executor ray, not {name!r}")
    if name == "serial":
        return SerialExecutor()
    if name == "local":
        return LocalExecutor(jobs, fresh_workers=fresh_workers)
    import_ray()  # fail now, with the install hint, not after the suite is planned
    return RayExecutor(address, jobs)
