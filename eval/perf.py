"""The perf suite: every throughput figure of the project measured in one run -> ``results/perf.{md,json}``.

Probes (:file:`eval/perf.toml`, one subprocess each, ``python -m MODULE ...``): render frames per second per
renderer and output set (``sim_envs.bench_render``), depth-network milliseconds per frame
(``cnnslam.depthnet.bench --json FILE``), CNN-SLAM tracking and whole-system frames per second
(``cnnslam.bench_slam --json``), trajectory-metric time for 100k poses (``eval.bench_metrics``). Modules with a JSON
output are read as JSON; the two without one (``bench_render``, ``bench_metrics``) are parsed from the figures they
print (:func:`parse_render_table`, :func:`parse_metrics_text`: a line that does not look like a figure is ignored,
and a probe that yields no figure at all is reported failed). A probe that fails or times out is reported with its
error; the others are kept.

Figures are measured, never asserted. They depend on the machine and its load: ``perf.json`` records the cores,
the platform and the git revision beside them.
"""

from __future__ import annotations

import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from eval.errors import EvalError
from eval.executors import available_cores
from eval.results import json_ready

PROBES_FILE: Path = Path(__file__).with_name("perf.toml")
PERF_SCHEMA = "cnnslam-perf/1"
_RENDER_ROW = re.compile(r"^(?P<style>\S+)\s+(?P<renderer>\S+)\s+(?P<outputs>\S+)\s+(?P<fps>\d+(\.\d*)?)\s*$")
_METRIC_ROW = re.compile(r"^(?P<label>[^:#]+?):\s+(?P<value>\d+(\.\d*)?)\s*ms\s*$")
_POSES_ROW = re.compile(r"^poses:\s*(?P<poses>\d+)")


class PerfError(EvalError):
    """A probe table that cannot be used, or a probe output with no figure in it."""


@dataclass(frozen=True)
class Probe:
    """One throughput probe: ``python -m module *args``; ``output`` says how its figures are read."""

    name: str
    title: str
    module: str
    args: tuple[str, ...] = ()
    output: str = "json_stdout"
    timeout_s: float = 600.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "args", tuple(str(a) for a in self.args))
        if self.output not in PARSERS:
            raise PerfError(f"probe {self.name!r}: output must be one of {', '.join(PARSERS)}, got {self.output!r}")
        if not self.module or not re.fullmatch(r"[A-Za-z_][\w.]*", self.module):
            raise PerfError(f"probe {self.name!r}: module must be a dotted module name, got {self.module!r}")


@dataclass(frozen=True)
class ProbeResult:
    """A probe's figures (flat name -> number or text), or its error; ``command`` as run; ``wall_s``."""

    name: str
    title: str
    command: list[str]
    ok: bool
    figures: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    wall_s: float = 0.0


@dataclass(frozen=True)
class PerfReport:
    """Every probe's result and the machine they ran on."""

    probes: list[ProbeResult]
    machine: dict[str, Any]
    git_revision: str | None

    @property
    def ok(self) -> bool:
        return all(p.ok for p in self.probes)

    def to_dict(self) -> dict[str, Any]:
        return json_ready(
            {
                "schema": PERF_SCHEMA,
                "machine": self.machine,
                "git_revision": self.git_revision,
                "probes": {p.name: asdict(p) for p in self.probes},
            }
        )


# -------------------------------------------------------------------------------------------------------- parsers
def parse_render_table(stdout: str) -> dict[str, Any]:
    """``sim_envs.bench_render``'s rows ``style renderer outputs fps`` -> ``{"<style>/<renderer>/<outputs>_fps":
    fps}``; header lines, ``#`` notes and anything else are skipped."""
    figures: dict[str, Any] = {}
    for line in stdout.splitlines():
        match = _RENDER_ROW.match(line.strip())
        if match and not line.lstrip().startswith("#"):
            key = f"{match['style']}/{match['renderer']}/{match['outputs']}_fps"
            figures[key] = float(match["fps"])
    return figures


def parse_metrics_text(stdout: str) -> dict[str, Any]:
    """``eval.bench_metrics``'s lines ``label: N ms`` -> ``{"<label>_ms": N}`` (label lower-cased, spaces to
    ``_``), plus ``poses`` from its ``poses: N`` line."""
    figures: dict[str, Any] = {}
    for line in stdout.splitlines():
        text = line.strip()
        poses = _POSES_ROW.match(text)
        if poses:
            figures["poses"] = int(poses["poses"])
            continue
        match = _METRIC_ROW.match(text)
        if match:
            label = re.sub(r"[^a-z0-9]+", "_", match["label"].strip().lower()).strip("_")
            figures[f"{label}_ms"] = float(match["value"])
    return figures


def parse_json_stdout(stdout: str) -> dict[str, Any]:
    """The JSON object a module printed: the last object that starts at the beginning of a line (lines before it,
    warnings for instance, are ignored). Empty when there is none."""
    decoder = json.JSONDecoder()
    for match in reversed(list(re.finditer(r"(?m)^\{", stdout))):
        try:
            value, _ = decoder.raw_decode(stdout, match.start())
        except json.JSONDecodeError:
            continue
        if isinstance(value, dict):
            return value
    return {}


def parse_json_file(path: Path) -> dict[str, Any]:
    """The JSON object a module wrote to ``path`` (empty when there is none)."""
    try:
        value = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError):
        return {}
    return value if isinstance(value, dict) else {}


PARSERS: dict[str, Callable[..., dict[str, Any]]] = {
    "json_stdout": parse_json_stdout,
    "json_file": parse_json_file,
    "render_table": parse_render_table,
    "metrics_text": parse_metrics_text,
}


# ------------------------------------------------------------------------------------------------------- running
def load_probes(path: str | Path | None = None) -> tuple[list[Probe], int]:
    """The probes of ``path`` (default :data:`PROBES_FILE`) and its default frame count."""
    path = Path(path) if path is not None else PROBES_FILE
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise PerfError(f"{path}: cannot read the probe table: {exc}") from exc
    table = data.get("probes")
    if not isinstance(table, Mapping) or not table:
        raise PerfError(f"{path}: expected [probes.<name>] tables")
    try:
        probes = [Probe(name=name, **dict(entry)) for name, entry in table.items()]
    except TypeError as exc:
        raise PerfError(f"{path}: {exc}") from exc
    return probes, int(data.get("frames", 100))


def run_probe(probe: Probe, frames: int, python: str = sys.executable) -> ProbeResult:
    """Run one probe in a subprocess and read its figures; failures come back as ``ok=False`` with the error."""
    with tempfile.TemporaryDirectory(prefix="cnnslam-perf-") as tmp:
        json_path = Path(tmp) / "figures.json"
        args = [a.replace("{frames}", str(frames)).replace("{json}", str(json_path)) for a in probe.args]
        command = [python, "-m", probe.module, *args]
        start = time.perf_counter()
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=probe.timeout_s, check=False)
        except subprocess.TimeoutExpired:
            return ProbeResult(probe.name, probe.title, command, False, error=f"timed out after {probe.timeout_s:g} s",
                               wall_s=time.perf_counter() - start)  # fmt: skip
        wall = time.perf_counter() - start
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            return ProbeResult(probe.name, probe.title, command, False,
                               error=f"exit status {done.returncode}: {' | '.join(tail)}", wall_s=wall)  # fmt: skip
        parser = PARSERS[probe.output]
        figures = parser(json_path) if probe.output == "json_file" else parser(done.stdout)
    if not figures:
        return ProbeResult(probe.name, probe.title, command, False,
                           error=f"no figures found in the output ({probe.output})", wall_s=wall)  # fmt: skip
    return ProbeResult(probe.name, probe.title, command, True, figures=figures, wall_s=wall)


def machine_info() -> dict[str, Any]:
    """Cores available, CPU count, platform, Python version, load average (when the OS has one)."""
    info: dict[str, Any] = {
        "cores_available": available_cores(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "python": platform.python_version(),
    }
    if hasattr(os, "getloadavg"):
        info["load_average_1min"] = os.getloadavg()[0]
    return info


def format_perf_markdown(report: PerfReport, command: str = "cnnslam bench perf") -> str:
    """perf.md: the machine, then one table per probe (figure, value), then the failures."""
    m = report.machine
    lines = [
        "# Throughput figures\n",
        f"Made by `{command}` on {m.get('cores_available')} core(s) ({m.get('processor')}, {m.get('platform')}, "
        f"Python {m.get('python')}), 1-min load average {m.get('load_average_1min', math.nan):.1f} at the end, git "
        f"revision {report.git_revision or '-'}. Figures depend on the machine and on what else runs on it; they "
        "are measured, never asserted. Raw figures: `perf.json`.\n",
    ]
    for probe in report.probes:
        lines.append(f"## {probe.title}\n")
        lines.append(f"`{' '.join(['python', *probe.command[1:]])}` ({probe.wall_s:.0f} s)\n")
        if not probe.ok:
            lines.append(f"**failed**: {probe.error}\n")
            continue
        lines += ["| figure | value |", "|---|---:|"]
        for key, value in probe.figures.items():
            text = f"{value:.2f}" if isinstance(value, float) else str(value)
            lines.append(f"| {key} | {text} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def run_perf(
    results_dir: str | Path,
    *,
    frames: int | None = None,
    probes: Sequence[Probe] | None = None,
    progress: bool = True,
    command: str = "cnnslam bench perf",
) -> PerfReport:
    """Run the probes one after another (they measure speed: never two at once) and write
    ``results_dir/perf.{json,md}``."""
    from eval.runner import git_revision

    default_probes, default_frames = load_probes() if probes is None else ([], 100)
    chosen = list(probes) if probes is not None else default_probes
    n = int(frames) if frames is not None else default_frames
    results = []
    for probe in tqdm(chosen, desc="perf probes", unit="probe", disable=not progress):
        results.append(run_probe(probe, n))
    report = PerfReport(results, machine_info(), git_revision())
    out = Path(results_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "perf.json").write_text(json.dumps(report.to_dict(), indent=2, allow_nan=False) + "\n")
    (out / "perf.md").write_text(format_perf_markdown(report, command))
    return report
