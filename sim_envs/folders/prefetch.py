"""Read the frames of a sequence ahead of the consumer, on a small pool of threads.

A :class:`Prefetcher` wraps a reader ``read(i) -> value`` (decode, undistort and resize frame i of a folder: work
done in OpenCV, which releases the GIL, so threads run it in parallel with the consumer and with each other). Once
two consecutive indices have been asked for (i, then i + 1), it keeps the next ``ahead`` indices submitted to
``workers`` threads; ``get(i)`` then hands back the value read for i. Values are those of ``read(i)`` itself,
whichever thread ran it, so what the consumer receives is the same bytes with or without prefetching, in the order
it asks. An index that was not read ahead (a jump, a new episode starting at 0) is read in the caller's thread and
the reads ahead of the old position are cancelled (one already running finishes and is dropped).

At most ``ahead`` values are held. The pool starts on the first read ahead and stops on :meth:`Prefetcher.close`
(waiting for its threads, which end), when the prefetcher is garbage, or at interpreter exit; a closed prefetcher
starts a new pool when it reads ahead again, and so does one in a process forked from the one that read ahead.
An error in a read ahead is raised by the ``get`` of its index, in the consumer's thread: a
:class:`~sim_envs.errors.SimEnvError` as it is (the reader's own one-line message naming the file), anything else
as a :class:`SimEnvError` naming the index and what ``label(i)`` says about it (its file).
"""

from __future__ import annotations

import os
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Generic, TypeVar

from sim_envs.errors import SimEnvError

T = TypeVar("T")

THREAD_PREFIX = "rgbd-prefetch"  # the pool's threads are named THREAD_PREFIX_<n> (tests count them by it)


def _stop(pool: ThreadPoolExecutor) -> None:
    pool.shutdown(wait=False, cancel_futures=True)


class Prefetcher(Generic[T]):
    """Values ``read(i)`` for i in 0 .. ``length`` - 1, read up to ``ahead`` indices ahead on ``workers`` threads.

    ``label(i)``: what index i is, for error messages (e.g. its file); default ``"frame i"``. ``ahead`` >= 1 and
    ``workers`` >= 1. One consumer thread calls :meth:`get`; the prefetcher is not shared between consumers.
    """

    def __init__(
        self,
        read: Callable[[int], T],
        length: int,
        *,
        ahead: int = 4,
        workers: int = 2,
        label: Callable[[int], str] | None = None,
    ) -> None:
        if int(ahead) < 1 or int(workers) < 1:
            raise SimEnvError(f"a prefetcher needs ahead >= 1 and workers >= 1, got ahead={ahead}, workers={workers}")
        self._read = read
        self.length = int(length)
        self.ahead = int(ahead)
        self.workers = int(workers)
        self._label = label or (lambda i: f"frame {i}")
        self._pending: dict[int, Future[T]] = {}
        self._last: int | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._pid = os.getpid()  # the process the pool's threads run in (a forked child has none of them)
        self._finalizer: weakref.finalize | None = None
        self._lock = threading.Lock()  # close() may come from another thread than get()
        self.hits = 0  # values handed back from a read ahead
        self.misses = 0  # values read in the caller's thread

    def get(self, index: int) -> T:
        """The value ``read(index)``: taken from a read ahead when there is one, else read now; then the reads of
        the next ``ahead`` indices are submitted when ``index`` continues a run (it follows the last index asked)."""
        i = int(index)
        if self._pid != os.getpid():  # in a child forked after reading ahead: the parent's threads are not here
            self._forget_parent()
        with self._lock:
            future = self._pending.pop(i, None)
            sequential = future is not None or (self._last is not None and i == self._last + 1)
            if future is None:
                self._cancel()
            self._last = i
        if future is None:
            self.misses += 1
        else:
            self.hits += 1
        value = self._result(future, i)
        if sequential:
            self._submit_after(i)
        return value

    def close(self) -> None:
        """Cancel the reads ahead and stop the pool, waiting for its threads to end (a read running finishes)."""
        with self._lock:
            self._cancel()
            pool, self._pool, self._last = self._pool, None, None
            if self._finalizer is not None:
                self._finalizer.detach()
                self._finalizer = None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    @property
    def pending(self) -> list[int]:
        """The indices read ahead and not yet asked for, in order."""
        with self._lock:
            return sorted(self._pending)

    # ------------------------------------------------------------------------------------------------- helpers
    def _submit_after(self, i: int) -> None:
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix=THREAD_PREFIX)
                self._finalizer = weakref.finalize(self, _stop, self._pool)
            for j in range(i + 1, min(i + 1 + self.ahead, self.length)):
                if j not in self._pending:
                    self._pending[j] = self._pool.submit(self._read, j)

    def _forget_parent(self) -> None:
        """Drop the pool and the reads ahead inherited from the parent process (their threads do not exist here)."""
        self._lock = threading.Lock()
        self._pending.clear()
        self._pool, self._last, self._pid = None, None, os.getpid()
        if self._finalizer is not None:
            self._finalizer.detach()
            self._finalizer = None

    def _cancel(self) -> None:
        for future in self._pending.values():
            future.cancel()
        self._pending.clear()

    def _result(self, future: Future[T] | None, i: int) -> T:
        """The value read ahead by ``future``, or read now when it is None; a failure as a one-line SimEnvError."""
        try:
            return self._read(i) if future is None else future.result()
        except SimEnvError:
            raise
        except Exception as exc:  # noqa: BLE001 - any failure of a read ahead, named by its index and file
            text = str(exc).strip().splitlines()
            detail = f"{type(exc).__name__}: {text[0]}" if text else type(exc).__name__
            raise SimEnvError(f"cannot read {self._label(i)} (frame {i}): {detail}") from exc
