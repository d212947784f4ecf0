"""The machine a run ran on: CPU, instruction sets, Python and the numeric packages' versions.

A run's ``timing.json`` carries it (``environment``) and suite reports name the machines their runs came from. The
same machine and the same versions give the same bytes; another CPU (other SIMD kernels in torch's oneDNN and in
OpenBLAS) changes the network's outputs in their last bits, which SLAM amplifies (docs/benchmarks.md, "Seeds,
determinism and what 'the same result' means", with figures measured across two hosts). It is kept out of
``metrics.json`` and out of the run fingerprint: a run from another machine is still the same run, only its figures
may differ within the measured tolerances.
"""

from __future__ import annotations

import functools
import os
import platform
from importlib import metadata
from pathlib import Path
from typing import Any

from eval.reports.inputs import machine_label  # noqa: F401  (a report's line for a description; its name kept here)

# The packages whose versions decide a run's floating-point results or its images.
PACKAGES = ("numpy", "scipy", "torch", "opencv-python-headless", "opencv-python", "mujoco", "pyrender")
# Instruction-set extensions that select different floating-point kernels (widest first).
ISA_FLAGS = ("amx_tile", "avx512_bf16", "avx512f", "avx2", "sse4_2")


def _cpuinfo(text: str) -> tuple[str, tuple[str, ...]]:
    """(model name, ISA flags of :data:`ISA_FLAGS` present) from /proc/cpuinfo's text."""
    model, flags = "", set()
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key == "model name" and not model:
            model = value.strip()
        elif key == "flags" and not flags:
            flags = set(value.split())
    return model, tuple(f for f in ISA_FLAGS if f in flags)


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=1)
def machine_description() -> dict[str, Any]:
    """This machine: ``cpu`` (model name), ``isa`` (SIMD extensions among :data:`ISA_FLAGS`), ``cores``
    (logical CPUs this process may use), ``system``, ``python``, and ``packages`` (name -> version, installed only).
    """
    cpuinfo = Path("/proc/cpuinfo")
    model, isa = _cpuinfo(cpuinfo.read_text()) if cpuinfo.is_file() else ("", ())
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    packages = {name: v for name in PACKAGES if (v := _version(name)) is not None}
    return {
        "cpu": model or platform.processor() or platform.machine(),
        "isa": list(isa),
        "cores": cores,
        "system": f"{platform.system()} {platform.machine()}",
        "python": platform.python_version(),
        "packages": packages,
    }
