"""What a process used: its peak resident memory, read once here for the agent's benchmarks (``cnnslam
bench-slam``, ``cnnslam map``) and the judge's run records (``timing.json``, :mod:`eval.bench.run`) alike."""

from __future__ import annotations

import resource
import sys

MIB = 1024 * 1024


def peak_resident_mib() -> float:
    """This process's peak resident set size so far, MiB (``getrusage``'s ``ru_maxrss``; Linux reports KiB, macOS
    bytes). A process forked from another counts the pages it inherited resident, as the kernel does; the memory of
    processes it started (a system run out of process) is not in it."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / MIB if sys.platform == "darwin" else peak / 1024
