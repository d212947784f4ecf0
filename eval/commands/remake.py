"""Remaking results: for each stale result under a results folder (or each one named), the command that remakes it,
how many of its runs are reused and how many made, and an estimate of the time; then running those commands.

Where a result's command comes from, first found wins:

1. its suite's manifest (:mod:`eval.bench.provenance`): the ``cnnslam bench`` line it records;
2. the output manifests that list its files (:func:`slamcommon.provenance.write_output_manifest`): each stale one's
   command, run in the folder it ran in;
3. a suite's result without a manifest: the ``cnnslam bench`` lines its reports quote ("Made by `...`"), else the
   suite as defined (``cnnslam bench SUITE``);
4. the other outputs the project's commands make (:data:`KNOWN_COMMANDS`).

A ``cnnslam bench`` line is parsed as that command parses it (:func:`eval.commands.cli_bench.bench_args`), planned
and run in this process (:func:`eval.bench.benchmark.prepare`, then
:func:`eval.commands.cli_bench.run`) with ``--results`` the result's folder and ``--out`` the runs folder, where the
runner reuses every finished run whose fingerprint is current, its own or another suite's of the same fingerprint
(:func:`eval.bench.run_store.reuse_finished`); any other command runs as a subprocess. A run one result plans that
an earlier result of the same plan makes too (same fingerprint: the same code, inputs and configuration, whichever
suite asks) is counted as shared, made once by the first. The estimate adds, per run to make, the wall seconds its
result recorded for that run (:data:`eval.metrics.catalogue.WALL_S`; else the median of its method's there, else of
all its runs), divided by the runs in parallel (``--jobs``); an output command's is the seconds its manifest records
(:data:`slamcommon.provenance.WALL_S`) or its files do.
"""

from __future__ import annotations

import csv
import json
import re
import shlex
import statistics
import subprocess
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from eval.bench.provenance import RESULTS_ROOT, ResultStatus, covering_manifests, output_changes, results_status
from eval.errors import InputError
from eval.metrics.catalogue import FRAMES, WALL_S
from slamcommon.provenance import REPOSITORY, found_path
from slamcommon.provenance import WALL_S as MANIFEST_WALL_S

# the commands that make the outputs no suite makes, for results that have no manifest yet: file stem -> command
# lines ({folder}: the result's folder, relative to the repository)
KNOWN_COMMANDS: dict[str, tuple[str, ...]] = {
    "depthnet": ("cnnslam train validate --results {folder}",),
    "depthnet_real": ("cnnslam train validate-folder ../shared/data/real/7scenes_redkitchen --results {folder}",),
    "depthnet_data": ("cnnslam train data-statistics ../shared/data/real/7scenes_redkitchen --results {folder}",),
    "contact_sheet": ("cnnslam contact-sheet --out {folder}/contact_sheet.png",),
    "camera_calibration": (
        "python -m sim_envs.tools.cli_camera_calibration --real ../shared/data/real/7scenes_redkitchen "
        "--out {folder}/camera_calibration.md --png {folder}/camera_calibration.png",),
    "reference": ("cnnslam reference {name} --step 2 --out {folder}",),
    "camera": ("cnnslam reference {name} --step 2 --out {folder}",),
}
MAP_PREFIX = "map_"  # map_<sequence>.{png,json}: cnnslam map <sequence> --figure <folder>/map_<sequence>.png
MADE_BY = re.compile(r"Made by `(cnnslam bench [^`]+)`")


@dataclass(frozen=True)
class Remake:
    """How one result is remade: its ``name``, the ``commands`` (shown as typed), whether they are ``cnnslam bench``
    lines (``bench``), the folder they run in (``cwd``), the runs planned, reused (finished under the runs folder),
    shared (made by an earlier result of the plan: ``shared_with``, result -> runs) and to make (None: not a suite or
    not planned), the estimated seconds (None: unknown; shared runs not counted, ``shared_s`` their estimate) and
    ``notes`` (why it cannot be remade, what is missing); ``specs``: every run planned, ``made``: the fingerprints
    of those it makes."""

    name: str
    commands: tuple[str, ...]
    bench: bool
    cwd: Path
    folder: Path
    runs: int | None = None
    reused: int | None = None
    to_make: int | None = None
    estimate_s: float | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)
    shared_with: tuple[tuple[str, int], ...] = ()
    shared_s: float = 0.0
    specs: tuple[Any, ...] = field(default=(), repr=False, compare=False)
    made: frozenset[str] = field(default=frozenset(), repr=False, compare=False)

    @property
    def shared(self) -> int:
        """Runs made by an earlier result of the plan."""
        return sum(n for _, n in self.shared_with)

    @property
    def possible(self) -> bool:
        """Whether there is a command to run (an unplannable bench line has a note and no runs)."""
        return bool(self.commands) and not (self.bench and self.runs is None)


def recorded_walls(files: Sequence[Path]) -> dict[str, tuple[str, float]]:
    """Run key -> (method, wall seconds) as a result's ``*_long.csv`` records them."""
    walls: dict[str, tuple[str, float]] = {}
    for path in files:
        if path.is_file() and path.name.endswith("_long.csv"):
            with path.open(newline="") as fh:
                for row in csv.DictReader(fh):
                    try:
                        walls[row["run"]] = (row.get("method") or "", float(row[WALL_S.key]))
                    except (KeyError, TypeError, ValueError):
                        continue
    return walls


_RATES: dict[str, dict[str, float]] = {}


def seconds_per_frame(root: Path) -> dict[str, float]:
    """Method -> the median over every run recorded in the ``*_long.csv`` files under ``root`` of its wall
    seconds per frame run (cached per process)."""
    key = str(Path(root).resolve())
    if key not in _RATES:
        rates: dict[str, list[float]] = {}
        for path in sorted(Path(root).rglob("*_long.csv")):
            with path.open(newline="") as fh:
                for row in csv.DictReader(fh):
                    if row.get("metric") != FRAMES.key:
                        continue
                    try:
                        frames, wall = float(row["value"]), float(row[WALL_S.key])
                    except (KeyError, TypeError, ValueError):
                        continue
                    if frames > 0 and wall > 0:
                        rates.setdefault(row.get("method") or "", []).append(wall / frames)
        _RATES[key] = {m: statistics.median(v) for m, v in rates.items()}
    return _RATES[key]


_LENGTHS: dict[str, int | None] = {}


def run_length(spec: Any) -> int | None:
    """How many frames ``spec`` runs (:func:`eval.bench.runner.run_frames`; a folder's length read once per
    process); None when a folder cannot be read."""
    from eval.bench.runner import run_frames

    ref = spec.sequence
    if ref.folder is None:
        return run_frames(spec)
    if ref.name not in _LENGTHS:
        try:
            source = ref.make_source()
            try:
                _LENGTHS[ref.name] = max(0, len(source) - int(ref.start))
            finally:
                source.close()
        except Exception:  # noqa: BLE001 - an estimate: a folder that cannot be read has no length
            _LENGTHS[ref.name] = None
    length = _LENGTHS[ref.name]
    return length if spec.frames is None or length is None else min(length, int(spec.frames))


def estimate_runs(specs: Sequence[Any], walls: Mapping[str, tuple[str, float]],
                  rates: Mapping[str, float] | None = None) -> float | None:
    """Seconds of one core for ``specs`` (module docstring): the run's recorded wall seconds, else its method's
    seconds per frame (``rates``, :func:`seconds_per_frame`; else the median method's) times its frames, else its
    method's median in ``walls``, else the median of ``walls``; None when nothing is known of any run."""
    rates = dict(rates or {})
    per_method: dict[str, list[float]] = {}
    for method, wall in walls.values():
        per_method.setdefault(method, []).append(wall)
    overall = statistics.median(w for _, w in walls.values()) if walls else None
    typical = statistics.median(rates.values()) if rates else None
    total = 0.0
    known = 0
    for spec in specs:
        frames = run_length(spec)
        rate = rates.get(spec.method.name, typical)
        if spec.key in walls:
            total += walls[spec.key][1]
        elif rate is not None and frames is not None:
            total += rate * frames
        elif spec.method.name in per_method:
            total += statistics.median(per_method[spec.method.name])
        elif overall is not None:
            total += overall
        else:
            continue
        known += 1
    return total if known or not specs else None


def plan_bench(name: str, commands: Sequence[str], folder: Path, files: Sequence[Path], out: Path, jobs: int,
               notes: Sequence[str] = (), rates_root: Path | None = None,
               made_by: Mapping[str, str] | None = None) -> Remake:
    """A suite's result remade by ``cnnslam bench`` lines: each planned now (nothing runs), its runs counted as
    reused (finished in ``out`` with the current fingerprint, in its own folder or another suite's:
    :func:`eval.bench.run_store.shared_run`), shared (their fingerprint in ``made_by``, fingerprint -> the result
    that makes it earlier in the plan) or to make, and the time of those estimated (the seconds per frame of
    ``rates_root``'s results, default ``folder``'s)."""
    rates_root = folder if rates_root is None else rates_root
    from eval.bench.benchmark import prepare
    from eval.bench.methods import method_table
    from eval.bench.run_store import is_finished, shared_run
    from eval.bench.runner import plan_runs
    from eval.commands.cli_bench import bench_args, options_of

    made_by = {} if made_by is None else made_by
    planned = reused = 0
    specs_to_make: list[Any] = []
    all_specs: list[Any] = []
    shared: dict[str, list[Any]] = {}
    made: dict[str, Any] = {}
    notes = list(notes)
    for command in commands:
        try:
            args = bench_args(command, folder, out)
            table = method_table(args.method_file, args.external, args.override)
            plan = prepare(args.suite, args.methods, options_of(args), table)
        except InputError as exc:
            notes.append(f"cannot be remade into {folder}: {exc}")
            return Remake(name, tuple(commands), True, REPOSITORY, folder, notes=tuple(notes))
        for part in plan.parts:
            chosen = [plan.methods[m] for m in part.suite.methods if m in plan.methods]
            for spec in plan_runs(part.suite, chosen, renderer=args.renderer, plots=False):
                planned += 1
                fingerprint = spec.fingerprint()
                spec = replace(spec, known_fingerprint=fingerprint)  # computed once: the checks below read it
                all_specs.append(spec)
                if is_finished(out, spec) or shared_run(out, spec) is not None:
                    reused += 1
                elif fingerprint in made_by:
                    shared.setdefault(made_by[fingerprint], []).append(spec)
                elif fingerprint in made:  # two parts of this result plan the same run: the first part makes it
                    shared.setdefault(name, []).append(spec)
                else:
                    made[fingerprint] = spec
                    specs_to_make.append(spec)
    walls, rates = recorded_walls(files), seconds_per_frame(rates_root)
    seconds = estimate_runs(specs_to_make, walls, rates)
    if not planned:  # perf: probes, no runs
        seconds = recorded_seconds(files)
    estimate = None if seconds is None else seconds / max(1, jobs) if planned else seconds
    saved = estimate_runs([s for specs in shared.values() for s in specs], walls, rates) or 0.0
    return Remake(name, tuple(commands), True, REPOSITORY, folder, planned, reused, len(specs_to_make), estimate,
                  tuple(notes), tuple((k, len(v)) for k, v in shared.items()), saved / max(1, jobs),
                  tuple(all_specs), frozenset(made))  # fmt: skip


def recorded_seconds(files: Sequence[Path]) -> float | None:
    """The seconds an output's files record of the command that made them: ``perf.json``'s probes' seconds, a
    JSON's ``run_seconds`` or ``seconds``; None when none does."""
    total = None
    for path in files:
        if not (path.is_file() and path.suffix == ".json"):
            continue
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if not isinstance(data, dict):
            continue
        if isinstance(data.get("probes"), dict):
            walls = [p.get(MANIFEST_WALL_S) for p in data["probes"].values() if isinstance(p, dict)]
            total = (total or 0.0) + sum(w for w in walls if isinstance(w, int | float))
        for key in ("run_seconds", "seconds"):
            if isinstance(data.get(key), int | float):
                total = (total or 0.0) + float(data[key])
                break
    return total


def known_commands(name: str, root: Path, files: Sequence[Path]) -> list[str]:
    """The commands of :data:`KNOWN_COMMANDS` (and ``cnnslam map``) that make a result's files."""
    folder = _shown(root / name).rsplit("/", 1)[0] if "/" in name else _shown(root)
    parent = Path(name).parent.name
    commands: list[str] = []
    for path in files:
        stem = path.name.split(".")[0]
        if stem.startswith(MAP_PREFIX):
            line = f"cnnslam map {stem[len(MAP_PREFIX):]} --figure {folder}/{stem}.png"
        else:
            line = next((c for k in (stem, *_prefixes(stem)) for c in KNOWN_COMMANDS.get(k, ())), "")
            line = line.format(folder=folder, name=parent)
        if line and line not in commands:
            commands.append(line)
    return commands


def _prefixes(stem: str) -> list[str]:
    parts = stem.split("_")
    return ["_".join(parts[:i]) for i in range(len(parts) - 1, 0, -1)]


def _shown(path: Path) -> str:
    from slamcommon.provenance import shown_path

    return shown_path(path)


def plan_result(row: ResultStatus, root: Path, out: Path, jobs: int,
                made_by: Mapping[str, str] | None = None) -> Remake:
    """How ``row`` (a result under ``root``) is remade (module docstring); ``made_by``: the runs earlier results of
    the plan make (fingerprint -> result), counted as shared (:func:`plan_bench`)."""
    files = [root / f.rstrip("/") for f in row.files]
    folder = (root / row.name).parent
    stem = row.name.rsplit("/", 1)[-1]
    manifest = folder / f"{stem}.provenance.json"
    if row.suite is not None and manifest.is_file():
        data = json.loads(manifest.read_text())
        if data.get("kind") != "output":
            return plan_bench(row.name, [str(data["command"])], folder, files, out, jobs, rates_root=root,
                              made_by=made_by)  # fmt: skip
    covering = covering_manifests(folder, files)
    if covering:
        listed = {str(o).split("/")[0] for d in covering.values() for o in d.get("outputs") or ()}
        unlisted = [p for p in files if p.name not in listed]
        if not row.current:  # a stale result: the commands of its stale manifests only
            covering = {p: d for p, d in covering.items() if d.get("dirty") or output_changes(d)}
        commands = list(dict.fromkeys(str(d["command"]) for d in covering.values()))
        extra = [c for c in known_commands(row.name, root, unlisted) if c not in commands]
        notes = tuple(f"no manifest for {p.name}: the known command" for p in unlisted if extra) or tuple(
            f"no recorded command for {p.name}" for p in unlisted)
        commands += extra
        cwd = found_path(next(iter(covering.values())).get("cwd") or ".") if covering else REPOSITORY
        walls = [d.get(MANIFEST_WALL_S) for d in covering.values()]
        if row.suite is not None and all(c.startswith("cnnslam bench ") for c in commands):
            return plan_bench(row.name, commands, folder, files, out, jobs, notes, root, made_by)
        seconds = sum(w for w in walls if isinstance(w, int | float)) if any(walls) else recorded_seconds(files)
        return Remake(row.name, tuple(commands), False, cwd, folder, estimate_s=seconds, notes=notes)
    if row.suite is not None:
        quoted: list[str] = []
        for path in files:
            if path.is_file() and path.suffix == ".md":
                quoted += [m for m in MADE_BY.findall(path.read_text()) if m not in quoted]
        commands = quoted or [f"cnnslam bench {row.suite}"]
        planned = plan_bench(row.name, commands, folder, files, out, jobs, rates_root=root, made_by=made_by)
        if planned.runs is None and quoted and folder.resolve() == Path(root).resolve():  # the suite's own place
            notes = (f"the command its report quotes cannot be planned now ({'; '.join(planned.notes)}): the suite "
                     "as defined instead",)  # fmt: skip
            return plan_bench(row.name, [f"cnnslam bench {row.suite}"], folder, files, out, jobs, notes, root,
                              made_by)  # fmt: skip
        return planned
    commands = known_commands(row.name, root, files)
    notes = () if commands else ("no manifest and no known command: remake it by hand",)
    return Remake(row.name, tuple(commands), False, REPOSITORY, folder, estimate_s=recorded_seconds(files),
                  notes=notes)  # fmt: skip


def plan_remakes(root: Path = RESULTS_ROOT, names: Sequence[str] | None = None, out: Path = Path("runs"),
                 jobs: int = 2, table: Mapping[str, Any] | None = None) -> list[Remake]:
    """The remake of every stale result under ``root``, or of each of ``names`` (stale or not), in the order they are
    remade; a run two results plan is made by the first and shared with the second (:func:`plan_bench`); nothing
    runs. :class:`InputError` for an unknown name (:func:`eval.bench.provenance.results_status`)."""
    rows = results_status(root, names, table)
    chosen = rows if names else [r for r in rows if not r.current]
    made_by: dict[str, str] = {}
    plans = []
    for row in chosen:
        plan = plan_result(row, Path(root), Path(out), jobs, made_by)
        if plan.possible:
            made_by.update({f: plan.name for f in plan.made if f not in made_by})
        plans.append(plan)
    return plans


def format_plan(plans: Sequence[Remake], jobs: int) -> str:
    """The plan as lines a person reads: per result its commands, runs reused / to make, the estimate; a total."""
    lines = []
    total = 0.0
    unknown = 0
    shared: dict[tuple[str, ...], float | None] = {}  # results one command makes together: its estimate once
    for p in plans:
        known = [q.estimate_s for q in plans if q.commands == p.commands and q.estimate_s is not None]
        shared.setdefault(p.commands, max(known) if known else None)
    seen: set[tuple[str, ...]] = set()
    for p in plans:
        others = "".join(f", {n} made by {'another part' if by == p.name else by}" for by, n in p.shared_with)
        runs = "" if p.runs is None else f"{p.runs} runs: {p.reused} reused{others}, {p.to_make} to make; "
        estimate = shared[p.commands] if p.possible else p.estimate_s
        est = "time unknown" if estimate is None else f"about {_duration(estimate)}"
        if p.possible and p.commands in seen:
            est = "made by the command above"
        elif p.possible and estimate is not None:
            total += estimate
        elif p.possible:
            unknown += 1
        seen.add(p.commands)
        lines.append(f"{p.name}: {runs}{est}" + ("" if p.possible else " (not remade)"))
        lines += [f"    {c}" for c in p.commands]
        lines += [f"    note: {n}" for n in p.notes]
    lines.append(f"{len(plans)} result(s) to remake ({sum(not p.possible for p in plans)} of them not remade), "
                 f"about {_duration(total)} with {jobs} run(s) in parallel"
                 + (f" (+ {unknown} of unknown time)" if unknown else ""))  # fmt: skip
    shared_runs = sum(p.shared for p in plans if p.possible)
    if shared_runs:
        lines.append(f"{shared_runs} run(s) shared between results (same fingerprint, made once): about "
                     f"{_duration(sum(p.shared_s for p in plans if p.possible))} not spent")  # fmt: skip
    return "\n".join(lines)


def _duration(seconds: float) -> str:
    if seconds >= 3600:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 60:.0f} min" if seconds >= 60 else f"{seconds:.0f} s"


def command_argv(command: str) -> list[str]:
    """The argv of an output command: ``cnnslam ...`` through the ``cnnslam`` script beside this Python (else the
    one on the PATH; its name is recorded again in the manifest), ``python -m ...`` with this Python."""
    words = shlex.split(command)
    if words and words[0] == "cnnslam":
        script = Path(sys.executable).parent / "cnnslam"
        return [str(script) if script.is_file() else "cnnslam", *words[1:]]  # else the one on the PATH
    if words and words[0] in ("python", "python3"):
        return [sys.executable, *words[1:]]
    return words


def remake(plan: Remake, out: Path, extra: Sequence[str] = ()) -> int:
    """Run ``plan``'s commands (module docstring); ``extra``: options added to ``cnnslam bench`` lines (``--jobs``,
    ``--executor``). Returns the worst exit status (0: all made)."""
    from eval.commands.cli_bench import bench_args, run

    status = 0
    for command in plan.commands:
        if plan.bench:
            code = run(bench_args(command, plan.folder, out, extra))
        else:
            code = subprocess.run(command_argv(command), cwd=plan.cwd, check=False).returncode
        status = max(status, code)
    return status
