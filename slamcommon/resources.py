"""What a process used: its peak resident memory, read once here for the agent's benchmarks (``cnnslam
bench-slam``, ``cnnslam map``) and the judge's run records (``timing.json``, :mod:`eval.bench.run`) alike."""

from __future__ import annotations

import resource
import sys
from typing import Literal

MIB = 1024 * 1024


def peak_rss_mib(who: Literal["self", "children"] = "self") -> float:
    """Peak resident set size in MiB (``getrusage``'s ``ru_maxrss``; Linux reports KiB, macOS bytes).

    ``who``: ``"self"``, this process's peak so far (a process forked from another counts the pages it inherited
    resident, as the kernel does); ``"children"``, the largest peak among the child processes this one has waited
    for (0 when none), e.g. a system run out of process."""
    scope = resource.RUSAGE_SELF if who == "self" else resource.RUSAGE_CHILDREN
    peak = resource.getrusage(scope).ru_maxrss
    return peak / MIB if sys.platform == "darwin" else peak / 1024
