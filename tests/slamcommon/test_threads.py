"""slamcommon.threads: the math libraries' thread limit, shared by the judge's workers and the agent's warm-up."""

import os

from slamcommon.threads import THREAD_VARIABLES, limit_threads


def test_the_limit_is_set_in_every_variable(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.setenv(name, "8")
    limit_threads(1)
    assert all(os.environ[name] == "1" for name in THREAD_VARIABLES)
    assert {"OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"} <= set(THREAD_VARIABLES)
