"""slamcommon.threads: the math libraries' thread limit, shared by the judge's workers and the agent's warm-up."""

import os

import pytest

from slamcommon.threads import RASTERISER_THREAD_VARIABLE, THREAD_VARIABLES, limit_threads, thread_environment


def test_the_limit_is_set_in_every_variable(monkeypatch):
    for name in (*THREAD_VARIABLES, RASTERISER_THREAD_VARIABLE):
        monkeypatch.setenv(name, "8")
    limit_threads(1)
    assert all(os.environ[name] == "1" for name in THREAD_VARIABLES)
    assert {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"} <= set(THREAD_VARIABLES)
    # one thread a process: llvmpipe rasterises on the calling thread (0), it does not hand frames to one worker (1)
    assert os.environ[RASTERISER_THREAD_VARIABLE] == "0"


def test_thread_environment():
    assert thread_environment(3) == {**dict.fromkeys(THREAD_VARIABLES, "3"), RASTERISER_THREAD_VARIABLE: "3"}
    assert thread_environment(1)[RASTERISER_THREAD_VARIABLE] == "0"
    with pytest.raises(ValueError, match="threads must be >= 1"):
        thread_environment(0)
