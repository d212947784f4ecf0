"""The perf suite: every throughput figure of the project measured in one run -> ``results/perf.{md,json}``.

Probes (:file:`eval/perf.toml`, one subprocess each, ``python -m MODULE ...``): render frames per second per
renderer and output set (``sim_envs.tools.bench_render``), depth-network milliseconds per frame
(``cnnslam.depthnet.bench --json FILE``), CNN-SLAM tracking and whole-system frames per second
(``cnnslam.tools.bench_slam --json``), trajectory-metric time for 100k poses (``eval.metrics.bench_metrics``), one run
of
each Table-1 method inside a suite with where its time goes (``eval.commands.cli_profile --json``: a table, ``columns``
and ``rows``, shown as one). Modules with
a JSON output are read as JSON; the two without one (``bench_render``, ``bench_metrics``) are parsed from the figures
they print (:func:`parse_render_table`, :func:`parse_metrics_text`: a line that does not look like a figure is ignored,
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
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import KW_ONLY, asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from tqdm import tqdm

from eval.bench.executors import available_cores
from eval.errors import EvalError
from eval.metrics.results import json_ready
from slamcommon.provenance import WALL_S, shown_path

T = TypeVar("T")
PROBES_FILE: Path = Path(__file__).resolve().parents[1] / "perf.toml"  # eval/perf.toml
# before/after tables measured side by side at named revisions (hand-run, see its text), shown at the end of perf.md
PERF_HISTORY: Path = Path(__file__).resolve().parents[2] / "results" / "perf_history.md"
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
    """A probe's figures (flat name -> number or text), or its error; ``command`` as run; the wall-clock
    ``seconds`` it took (kept under :data:`slamcommon.provenance.WALL_S` in ``perf.json``)."""

    name: str
    title: str
    command: list[str]
    ok: bool
    figures: dict[str, Any] = field(default_factory=dict)
    error: str | None = None
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """The probe's entry in ``perf.json``."""
        data = asdict(self)
        data[WALL_S] = data.pop("seconds")
        return data


@dataclass(frozen=True)
class PerfReport:
    """Every probe's result and the machine they ran on."""

    probes: list[ProbeResult]
    machine: dict[str, Any]
    git_revision: str | None
    speed_gate: dict[str, Any] | None = None

    @property
    def ok(self) -> bool:
        return all(p.ok for p in self.probes) and not (self.speed_gate or {}).get("failures")

    def to_dict(self) -> dict[str, Any]:
        return json_ready(
            {
                "schema": PERF_SCHEMA,
                "machine": self.machine,
                "git_revision": self.git_revision,
                "probes": {p.name: p.to_dict() for p in self.probes},
                "speed_gate": self.speed_gate,
            }
        )


# -------------------------------------------------------------------------------------------------------- parsers
def parse_render_table(stdout: str) -> dict[str, Any]:
    """``sim_envs.tools.bench_render``'s rows ``style renderer outputs fps`` -> ``{"<style>/<renderer>/<outputs>_fps":
    fps}``; header lines, ``#`` notes and anything else are skipped."""
    figures: dict[str, Any] = {}
    for line in stdout.splitlines():
        match = _RENDER_ROW.match(line.strip())
        if match and not line.lstrip().startswith("#"):
            key = f"{match['style']}/{match['renderer']}/{match['outputs']}_fps"
            figures[key] = float(match["fps"])
    return figures


def parse_metrics_text(stdout: str) -> dict[str, Any]:
    """``eval.metrics.bench_metrics``'s lines ``label: N ms`` -> ``{"<label>_ms": N}`` (label lower-cased, spaces to
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
                               seconds=time.perf_counter() - start)  # fmt: skip
        wall = time.perf_counter() - start
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
            return ProbeResult(probe.name, probe.title, command, False,
                               error=f"exit status {done.returncode}: {' | '.join(tail)}", seconds=wall)  # fmt: skip
        parser = PARSERS[probe.output]
        figures = parser(json_path) if probe.output == "json_file" else parser(done.stdout)
    if not figures:
        return ProbeResult(probe.name, probe.title, command, False,
                           error=f"no figures found in the output ({probe.output})", seconds=wall)  # fmt: skip
    return ProbeResult(probe.name, probe.title, command, True, figures=figures, seconds=wall)


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


def format_table(table: Mapping[str, Any]) -> str:
    """A ``columns`` / ``rows`` table (:func:`eval.bench.profile.profile_table`) as Markdown."""
    columns = list(table["columns"])
    lines = ["| " + " | ".join(columns) + " |", "|" + "|".join(["---"] + ["---:"] * (len(columns) - 1)) + "|"]
    for row in table["rows"]:
        lines.append("| " + " | ".join(f"{v:.2f}" if isinstance(v, float) else str(v) for v in row) + " |")
    return "\n".join(lines)


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
        lines.append(f"`{' '.join(['python', *probe.command[1:]])}` ({probe.seconds:.0f} s)\n")
        if not probe.ok:
            lines.append(f"**failed**: {probe.error}\n")
            continue
        figures = dict(probe.figures)
        if isinstance(figures.get("columns"), list) and isinstance(figures.get("rows"), list):  # a table probe
            lines += [format_table({"columns": figures.pop("columns"), "rows": figures.pop("rows")}), ""]
        lines += ["| figure | value |", "|---|---:|"]
        for key, value in figures.items():
            text = (f"{value:.2f}" if abs(value) >= 1 or value == 0 else f"{value:.4g}") if isinstance(value, float) \
                else str(value)
            lines.append(f"| {key} | {text} |")
        lines.append("")
    gate = report.speed_gate
    if gate is not None:
        lines.append(f"## speed gate: frames per machine unit against `{shown_path(gate['baseline'])}`\n")
        if gate.get("error"):
            lines.append(f"not judged: {gate['error']}\n")
        else:
            lines += ["| figure | this run | baseline | baseline / this run | allowed |", "|---|---:|---:|---:|---:|"]
            for key, row in gate["figures"].items():
                lines.append(f"| {key} | {row['value']:.4f} | {row['baseline']:.4f} | {row['slowdown']:.2f} | "
                             f"{gate['max_slowdown']:g} |")
            lines.append("\n" + ("**failed**: " + "; ".join(gate["failures"]) if gate["failures"] else "passed") + "\n")
    if PERF_HISTORY.is_file():  # measured side by side at the revisions it names: linked, not copied
        lines.append(f"Earlier measurements, side by side at the revisions they name: `{shown_path(PERF_HISTORY)}`.\n")
    return "\n".join(lines) + "\n"


def run_perf(
    results_dir: str | Path,
    *,
    frames: int | None = None,
    probes: Sequence[Probe] | None = None,
    progress: bool = True,
    command: str = "cnnslam bench perf",
    update_speed_baseline: bool = False,
    speed_baseline: str | Path | None = None,
) -> PerfReport:
    """Run the probes one after another (they measure speed: never two at once) and write
    ``results_dir/perf.{json,md}``, with the speed gate's verdict on the ``slam`` probe (:func:`speed_regressions`).

    update_speed_baseline: run the ``slam`` probe twice more and write the median of the three as the speed
    baseline (``speed_baseline``, default :data:`SPEED_BASELINE`) before judging.
    """
    from eval.bench.runner import git_revision

    default_probes, default_frames = load_probes() if probes is None else ([], 100)
    chosen = list(probes) if probes is not None else default_probes
    n = int(frames) if frames is not None else default_frames
    results = []
    for probe in tqdm(chosen, desc="perf probes", unit="probe", disable=not progress):
        results.append(run_probe(probe, n))
    revision = git_revision()
    slam = next((r for r in results if r.name == "slam" and r.ok), None)
    baseline_path = Path(speed_baseline) if speed_baseline is not None else SPEED_BASELINE
    if update_speed_baseline:
        if slam is None:
            raise PerfError("no speed baseline written: the slam probe failed or was not run")
        probe = next(p for p in chosen if p.name == "slam")
        runs = [slam.figures] + [run_probe(probe, n).figures for _ in tqdm(range(2), desc="speed baseline runs",
                                                                           disable=not progress)]
        baseline = speed_baseline_from_runs(runs, sequence=str(slam.figures.get("sequence")), frames=n,
                                            predictor=str(slam.figures.get("predictor")), git_revision=revision)
        baseline_path.parent.mkdir(parents=True, exist_ok=True)
        baseline_path.write_text(json.dumps(baseline.to_dict(), indent=2, allow_nan=False) + "\n")
    report = PerfReport(results, machine_info(), revision, speed_gate(slam.figures if slam else None, baseline_path))
    out = Path(results_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "perf.json").write_text(json.dumps(report.to_dict(), indent=2, allow_nan=False) + "\n")
    (out / "perf.md").write_text(format_perf_markdown(report, command))
    from slamcommon.provenance import write_output_manifest  # what the figures were measured on

    shown = command + (f" --frames {n}" if frames is not None and "--frames" not in command.split() else "")
    write_output_manifest(out, "perf", ["perf.json", "perf.md"], shown,
                          ["eval.bench.perf", *(p.module for p in chosen)],
                          inputs=[PROBES_FILE] if probes is None else [], seconds=sum(r.seconds for r in results))
    return report


# ----------------------------------------------------------------------------------------------------- speed gate
SPEED_BASELINE: Path = Path(__file__).resolve().parents[2] / "results" / "baselines" / "perf.json"
SPEED_SCHEMA = "cnnslam-speed-baseline/1"
SPEED_GATED: tuple[str, ...] = ("tracking_frames_per_unit", "whole_system_frames_per_unit")
MAX_SLOWDOWN = 1.5


@dataclass(frozen=True)
class BaselineRecord:
    """What every speed baseline holds (keyword fields): the machine unit's version its figures are in, the
    figures, the allowed slowdown, the runs it was made from, the machine and the revision; :meth:`to_dict` writes
    its ``SCHEMA`` and its fields, ``runs`` as a list (the schema's reader: :func:`load_baseline_record`)."""

    SCHEMA: ClassVar[str] = ""
    _: KW_ONLY
    unit_version: str
    figures: dict[str, float]
    max_slowdown: float = MAX_SLOWDOWN
    runs: tuple[dict[str, Any], ...] = ()
    machine: dict[str, Any] = field(default_factory=dict)
    git_revision: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return json_ready({"schema": self.SCHEMA, **asdict(self), "runs": list(self.runs)})


@dataclass(frozen=True)
class SpeedBaseline(BaselineRecord):
    """What the speed gate compares with: the median frames per machine unit of ``SPEED_GATED`` over several runs
    of ``python -m cnnslam.tools.bench_slam --sequence SEQUENCE --frames FRAMES --predictor PREDICTOR``, with the unit's
    version (a figure in another unit compares with nothing), the runs themselves, the machine and revision."""

    sequence: str
    frames: int
    predictor: str
    SCHEMA: ClassVar[str] = SPEED_SCHEMA


def speed_baseline_from_runs(runs: Sequence[Mapping[str, Any]], *, sequence: str, frames: int, predictor: str,
                             git_revision: str | None = None) -> SpeedBaseline:
    """The median of each gated figure over ``runs`` (``cnnslam.tools.bench_slam`` figure dicts, one unit version)."""
    if not runs:
        raise PerfError("a speed baseline needs at least one run")
    versions = {r.get("unit_version") for r in runs}
    if len(versions) != 1 or None in versions:
        raise PerfError(f"the runs were timed in different or missing machine units: {sorted(map(str, versions))}")
    missing = [k for k in SPEED_GATED for r in runs if not isinstance(r.get(k), (int, float))]
    if missing:
        raise PerfError(f"runs without the gated figures {sorted(set(missing))}")
    figures = {k: float(statistics.median(r[k] for r in runs)) for k in SPEED_GATED}
    return SpeedBaseline(sequence, int(frames), predictor, unit_version=str(versions.pop()), figures=figures,
                         runs=tuple(dict(r) for r in runs), machine=machine_info(), git_revision=git_revision)


def load_speed_baseline(path: str | Path | None = None) -> SpeedBaseline:
    """Read a speed baseline (default :data:`SPEED_BASELINE`); one clear error when it cannot be used."""
    return load_baseline_record(Path(path) if path is not None else SPEED_BASELINE, SPEED_SCHEMA, SpeedBaseline,
                                "the speed baseline")


def load_baseline_record(path: Path, schema: str, cls: type[T], what: str) -> T:
    """The JSON record at ``path`` of schema ``schema`` as a ``cls`` (its other keys are ``cls``'s fields, ``runs``
    a list made a tuple); :class:`PerfError` naming ``what`` when it cannot be read or does not fit."""
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise PerfError(f"{path}: cannot read {what}: {exc}") from exc
    if not isinstance(data, dict) or data.get("schema") != schema:
        found = data.get("schema") if isinstance(data, dict) else None
        raise PerfError(f"{path}: schema {found!r}, expected {schema!r}")
    data.pop("schema")
    try:
        data["runs"] = tuple(data.get("runs", ()))
        return cls(**data)
    except TypeError as exc:
        raise PerfError(f"{path}: {exc}") from exc


def too_slow(value: float, reference: float, max_slowdown: float) -> bool:
    """True when ``value`` (frames per unit) is more than ``max_slowdown`` times below ``reference``; exactly at the
    limit passes (float rounding of ``reference / max_slowdown``). Both speed gates judge by it."""
    return value * max_slowdown < reference * (1.0 - 1e-9)


def speed_regressions(figures: Mapping[str, Any], baseline: SpeedBaseline) -> list[str]:
    """One line per gated figure that is more than ``baseline.max_slowdown`` times slower than the baseline, in
    frames per machine unit (empty: the gate passes). Figures in another unit version fail with that reason."""
    if figures.get("unit_version") != baseline.unit_version:
        return [f"figures timed in machine unit {figures.get('unit_version')!r}, the baseline in "
                f"{baseline.unit_version!r}: remake the baseline (cnnslam bench perf --update-baseline)"]
    failures = []
    for key in SPEED_GATED:
        value, reference = figures.get(key), baseline.figures[key]
        if not isinstance(value, (int, float)) or value <= 0:
            failures.append(f"{key}: no figure ({value!r})")
        elif too_slow(value, reference, baseline.max_slowdown):
            failures.append(f"{key} {value:.4g} is {reference / value:.2f}x slower than the baseline's {reference:.4g} "
                            f"(allowed {baseline.max_slowdown:g}x)")
    return failures


def speed_gate(figures: Mapping[str, Any] | None, baseline_path: str | Path | None = None) -> dict[str, Any]:
    """The speed gate's verdict on a ``cnnslam.tools.bench_slam`` figure dict, as a record for perf.{json,md}: per gated
    figure this run's value, the baseline's and their ratio; the failures (:func:`speed_regressions`); or the reason
    it could not judge (no figures, no baseline, another sequence, frame count or predictor)."""
    path = Path(baseline_path) if baseline_path is not None else SPEED_BASELINE
    record: dict[str, Any] = {"baseline": str(path), "figures": {}, "failures": []}
    try:
        baseline = load_speed_baseline(path)
    except PerfError as exc:
        return {**record, "error": str(exc)}
    record["max_slowdown"] = baseline.max_slowdown
    if figures is None:
        return {**record, "error": "the slam probe gave no figures"}
    setup = (figures.get("sequence"), figures.get("frames"), figures.get("predictor"))
    if setup != (baseline.sequence, baseline.frames, baseline.predictor):
        return {**record, "error": f"the run's (sequence, frames, predictor) {setup} differ from the baseline's "
                                   f"{(baseline.sequence, baseline.frames, baseline.predictor)}"}
    for key in SPEED_GATED:
        value = float(figures.get(key) or 0.0)
        record["figures"][key] = {"value": value, "baseline": baseline.figures[key],
                                  "slowdown": baseline.figures[key] / value if value > 0 else math.inf}
    record["failures"] = speed_regressions(figures, baseline)
    return record
