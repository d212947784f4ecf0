"""Where each committed result came from, and whether the current code would give the same.

A suite's report is written with a provenance manifest beside it, ``<results>/<suite>.provenance.json``
(:func:`write_manifest`): the suite, the command, the selection that shaped its runs (methods, sequences, frames,
seeds, ...), the git revision and whether the tree had uncommitted changes in tracked files outside ``results/``
(then the result is marked and counts as stale), the definitions of methods that are not in the built-in table, the
methods skipped, per run key its fingerprint and the digests of the fingerprint's parts (agent, world, judge,
weights, config: :mod:`eval.bench.fingerprint`), and the files its reports score the runs against besides their own
ground truth (``inputs``: a dataset list's second references, path -> sha256; :func:`scoring_inputs`).

:func:`results_status` lists every result under a results folder: each suite's files (grouped by the suite names
of :data:`eval.bench.suites.SUITES`) and every other group of files, and judges each: a suite's result with a
manifest is planned again as :func:`eval.bench.benchmark.run_bench` plans it (:func:`eval.bench.benchmark.prepare`
with the recorded selection, then :func:`eval.bench.runner.plan_runs` per part; nothing runs, renders or builds an
agent) and every run's fingerprint parts recomputed and compared, timings excluded, and its scoring inputs
compared with the files the current plan would score against. A result whose files the output
manifests of its folder list (:func:`slamcommon.provenance.write_output_manifest`: perf, the depth network's reports,
maps, camera calibration, contact sheet, SfM references) is judged by them (:func:`judge_outputs`). A result without a
manifest is stale: its revisions (read from its long table or run file) are shown, never judged current.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval.bench.fingerprint import PARTS, run_parts
from eval.errors import InputError
from slamcommon.provenance import (
    DIRTY_LISTED,
    MANIFEST_SUFFIX,
    OUTPUT_KIND,
    REPOSITORY,
    SCHEMA,
    TreeState,
    code_digest,
    file_sha256,
    found_path,
    package_root,
    shown_path,
    tree_state,
)

__all__ = ["MANIFEST_SUFFIX", "RESULTS_ROOT", "SCHEMA", "ResultStatus", "TreeState", "format_status", "judge_result",
           "result_groups", "results_status", "tree_state", "write_manifest"]
RESULTS_ROOT = REPOSITORY / "results"  # the committed results
NOT_RESULTS: tuple[str, ...] = ("baselines",)  # folders under results/ that hold the gate's inputs, not results
KEPT_BY_HAND: tuple[str, ...] = ("perf_history.md",)  # records written by people, not made by a command
FIGURES_SUFFIX = "_figures"  # a report's folder of figures (<suite>_figures/)


# ------------------------------------------------------------------------------------------------ the manifest
def manifest_path(results_dir: Path, suite: str) -> Path:
    """Where the manifest of ``suite``'s report in ``results_dir`` goes."""
    return Path(results_dir) / f"{suite}{MANIFEST_SUFFIX}"


def selection_of(options: Any) -> dict[str, Any]:
    """The options of a :class:`~eval.bench.benchmark.BenchOptions` that shape a suite's runs, JSON-ready."""
    from eval.bench.method_settings import parse_setting

    settings = [list(parse_setting(s)) if isinstance(s, str) else list(s) for s in options.settings]
    size = options.image_size
    return {
        "sequences": list(options.sequences) if options.sequences is not None else None,
        "frames": options.frames,
        "seeds": list(options.seeds) if options.seeds is not None else None,
        "runs": options.runs,
        "lengths": list(options.lengths) if options.lengths is not None else None,
        "motions": [str(m) for m in options.motions],
        "sim_sequences": list(options.sim_sequences) if options.sim_sequences is not None else None,
        "camera": options.camera,
        "image_size": list(size) if isinstance(size, tuple) else size,
        "undistort": options.undistort,
        "align": options.align,
        "settings": settings,
        "renderer": options.renderer,
    }


def scoring_inputs(suite: str, suites: Sequence[Any]) -> dict[str, str]:
    """The files the report of suite ``suite`` (its parts' selected :class:`~eval.bench.suites.Suite` objects
    ``suites``) scores runs against besides each run's own ground truth: for a suite with the generic report (the
    one that scores them, :func:`eval.reports.suite_reports.report_generic`), the dataset list's second reference of
    each sequence that has one (:meth:`~eval.bench.suites.Suite.second_references`); path as a manifest shows it
    (:func:`slamcommon.provenance.shown_path`) -> its sha256, or ``"missing"``."""
    from eval.bench.suites import SUITES, SuiteKind
    from eval.errors import SuiteError

    defined = SUITES.get(suite)
    if defined is None or defined.kind is not SuiteKind.RUNS or defined.report != "generic":
        return {}
    found: dict[str, str] = {}
    for suite in suites:
        try:
            references = suite.second_references()
        except SuiteError:
            continue
        for ref in suite.sequences:
            path = references.get(ref.name)
            if path is not None:
                found[shown_path(path)] = file_sha256(Path(path).resolve()) if Path(path).is_file() else "missing"
    return dict(sorted(found.items()))


def build_manifest(suite: str, command: str, selection: Mapping[str, Any], methods: Mapping[str, Any],
                   parts: Sequence[Any], state: TreeState) -> dict[str, Any]:
    """The manifest (module docstring) of ``parts`` (the :class:`~eval.bench.runner.SuiteRun` of each part),
    run with ``methods`` (name -> Method, as run) and ``selection`` (:func:`selection_of`)."""
    from eval.bench.methods import load_methods

    builtin = load_methods()
    runs: dict[str, Any] = {}
    skipped: dict[str, str] = {}
    for run in parts:
        skipped.update(run.skipped_methods)
        stored = {r.run: r.metadata.get("fingerprint") for r in run.records}
        for spec in run.specs:
            digests = run_parts(spec)
            status = run.outcomes[spec.key].status if spec.key in run.outcomes else "not_run"
            entry: dict[str, Any] = {"fingerprint": digests.fingerprint, "parts": digests.digests, "status": status}
            if stored.get(spec.key) not in (None, digests.fingerprint):  # reported from a run other code made
                entry = {"fingerprint": stored[spec.key], "parts": None, "status": status}
            runs[spec.key] = entry
    return {
        "schema": SCHEMA,
        "kind": "suite",
        "suite": suite,
        "command": command,
        "git_revision": state.revision,
        "dirty": bool(state.dirty),
        "dirty_files": len(state.dirty),
        "dirty_listed": list(state.dirty[:DIRTY_LISTED]),
        "selection": dict(selection),
        "methods": list(methods),
        "method_definitions": {n: m.describe() for n, m in methods.items() if n not in builtin},
        "skipped": skipped,
        "runs": runs,
        "inputs": scoring_inputs(suite, [run.suite for run in parts]),
    }


def write_manifest(results_dir: Path, suite: str, command: str, options: Any, methods: Mapping[str, Any],
                   parts: Sequence[Any], state: TreeState | None = None) -> Path:
    """Write the manifest of a suite's report into ``results_dir`` (:func:`build_manifest`; ``state`` default: this
    checkout's, :func:`tree_state`); returns its path."""
    state = tree_state() if state is None else state
    data = build_manifest(suite, command, selection_of(options), methods, parts, state)
    path = manifest_path(results_dir, suite)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, sort_keys=True, default=str) + "\n")
    return path


# ------------------------------------------------------------------------------------------------- the status
@dataclass(frozen=True)
class ResultStatus:
    """One committed result: its ``name`` (folder and stem below the results root, e.g. ``table1``,
    ``bench/table1``), the ``suite`` that makes it (None: no suite), its ``files``, the revisions it was made at
    (``made_at``), how many runs it holds (None: unknown), whether the current code gives the same (``current``),
    ``why`` not (one line), and per part of the fingerprint the run keys whose part changed (``changed``)."""

    name: str
    suite: str | None
    files: tuple[str, ...]
    made_at: tuple[str, ...]
    runs: int | None
    current: bool
    why: str
    changed: dict[str, tuple[str, ...]] = field(default_factory=dict)

    @property
    def status(self) -> str:
        return "current" if self.current else "stale"

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "suite": self.suite, "files": list(self.files), "made_at": list(self.made_at),
                "runs": self.runs, "status": self.status, "why": self.why,
                "changed": {k: list(v) for k, v in self.changed.items()}}  # fmt: skip


def result_groups(root: Path, suites: Sequence[str]) -> dict[str, list[Path]]:
    """The results under ``root``: per folder, its files grouped by stem: a suite's name with everything named
    ``<suite>.*`` or ``<suite>_*`` (its ``<suite>_figures/`` folder included), then every other stem with the stems
    that extend it (``depthnet``, ``depthnet_real``); name -> files, a name being ``<folder>/<stem>`` below
    ``root``. Manifests are not results; :data:`NOT_RESULTS` folders are left out."""
    groups: dict[str, list[Path]] = {}
    for folder in sorted([root, *(p for p in root.rglob("*") if p.is_dir())]):
        rel = folder.relative_to(root)
        if rel.parts and (rel.parts[0] in NOT_RESULTS or any(p.endswith(FIGURES_SUFFIX) for p in rel.parts)):
            continue
        entries = [p for p in folder.iterdir() if (p.is_file() and not p.name.endswith(MANIFEST_SUFFIX)
                                                   and p.name not in KEPT_BY_HAND)
                   or (p.is_dir() and p.name.endswith(FIGURES_SUFFIX))]  # fmt: skip
        stems = sorted({_stem(p) for p in entries}, key=lambda s: (len(s), s))
        heads: list[str] = [s for s in suites if any(_belongs(st, s) for st in stems)]
        for stem in stems:
            if not any(_belongs(stem, h) for h in heads):
                heads.append(stem)
        for entry in sorted(entries):
            stem = _stem(entry)
            head = min((h for h in heads if _belongs(stem, h)), key=len)
            name = (rel / head).as_posix()
            groups.setdefault(name, []).append(entry)
    return groups


def _stem(path: Path) -> str:
    name = path.name
    if path.is_dir():
        return name[: -len(FIGURES_SUFFIX)] + "_figures" if name.endswith(FIGURES_SUFFIX) else name
    return name.split(".")[0]


def _belongs(stem: str, head: str) -> bool:
    return stem == head or stem.startswith(head + "_")


def results_status(root: Path = RESULTS_ROOT, names: Sequence[str] | None = None,
                   table: Mapping[str, Any] | None = None) -> list[ResultStatus]:
    """Every result under ``root`` (:func:`result_groups`), or those named in ``names``, judged (module docstring).
    ``table``: the method table names are looked up in (default the built-in one). :class:`InputError` for a name
    that is no result there, naming the valid ones; nothing is run."""
    from eval.bench.suites import SUITES

    root = Path(root)
    if not root.is_dir():
        raise InputError(f"results folder {root} does not exist; give the folder holding the committed results")
    groups = result_groups(root, list(SUITES))
    if names:
        unknown = [n for n in names if n not in groups]
        if unknown:
            raise InputError(f"unknown result(s) {', '.join(unknown)}; results under {root}: {', '.join(groups)}")
        groups = {n: groups[n] for n in names}
    return [judge_result(root, name, files, table) for name, files in groups.items()]


def judge_result(root: Path, name: str, files: Sequence[Path], table: Mapping[str, Any] | None = None
                 ) -> ResultStatus:
    """One result's :class:`ResultStatus` (module docstring): by its suite's manifest, else by the output manifests
    in its folder that list its files (:func:`judge_outputs`), else stale without provenance."""
    from eval.bench.suites import SUITES

    stem = name.rsplit("/", 1)[-1]
    suite = stem if stem in SUITES else None
    rels = tuple(p.relative_to(root).as_posix() + ("/" if p.is_dir() else "") for p in files)
    folder = (root / name).parent
    manifest = manifest_path(folder, stem) if suite else None
    data: dict[str, Any] | None = None
    if manifest is not None and manifest.is_file():
        try:
            data = json.loads(manifest.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            return ResultStatus(name, suite, rels, (), None, False, f"unreadable manifest {manifest.name}: {exc}")
    if data is not None and data.get("kind") != OUTPUT_KIND:
        return judge_manifest(name, rels, data, table)
    covering = covering_manifests(folder, files)
    if covering:
        return judge_outputs(name, suite, rels, files, covering)
    if suite is None:
        return ResultStatus(name, None, rels, (), None, False, "no provenance: no manifest lists its files")
    made, runs = recorded_revisions(files)
    return ResultStatus(name, suite, rels, made, runs, False, "no provenance (made before manifests)")


def output_manifests(folder: Path) -> dict[Path, dict[str, Any]]:
    """The output manifests (:func:`slamcommon.provenance.write_output_manifest`) in ``folder``: path -> content;
    unreadable ones and suites' manifests left out."""
    found: dict[Path, dict[str, Any]] = {}
    for path in sorted(Path(folder).glob(f"*{MANIFEST_SUFFIX}")):
        try:
            data = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        if isinstance(data, dict) and data.get("kind") == OUTPUT_KIND:
            found[path] = data
    return found


def covering_manifests(folder: Path, files: Sequence[Path]) -> dict[Path, dict[str, Any]]:
    """The output manifests in ``folder`` that list any of ``files`` (a figures folder counts by its name)."""
    names = {p.name for p in files}
    return {p: d for p, d in output_manifests(folder).items()
            if names & {str(o).split("/")[0] for o in d.get("outputs") or ()}}  # fmt: skip


def output_changes(data: Mapping[str, Any]) -> dict[str, list[str]]:
    """What differs now from what an output manifest recorded, per part: ``code`` (the import closure of its
    modules), ``inputs`` (a file's SHA-256, or the file gone), ``folders`` (a data folder's content fingerprint,
    :func:`sim_envs.folders.folder_layouts.folder_fingerprint`, or the folder gone); part -> the names that changed."""
    from sim_envs.folders.folder_layouts import folder_fingerprint

    changed: dict[str, list[str]] = {}
    code = data.get("code") or {}
    packages = [p for p in code.get("packages") or () if package_root(p) is not None]
    if code_digest(list(code.get("modules") or ()), packages) != code.get("sha256"):
        changed.setdefault("code", []).extend(code.get("modules") or ["?"])
    for text, digest in (data.get("inputs") or {}).items():
        path = found_path(text)
        if not path.is_file() or file_sha256(path.resolve()) != digest:
            changed.setdefault("inputs", []).append(text + ("" if path.is_file() else " (gone)"))
    for text, digest in (data.get("folders") or {}).items():
        path = found_path(text)
        if not path.is_dir() or folder_fingerprint(path)["sha256"] != digest:
            changed.setdefault("folders", []).append(text + ("" if path.is_dir() else " (gone)"))
    return changed


def judge_outputs(name: str, suite: str | None, rels: tuple[str, ...], files: Sequence[Path],
                  manifests: Mapping[Path, Mapping[str, Any]]) -> ResultStatus:
    """A result whose files output manifests list: stale when a file is listed by none, a manifest was written from
    an uncommitted tree, or its code, inputs or data folders differ now (:func:`output_changes`)."""
    listed = {str(o).split("/")[0] for d in manifests.values() for o in d.get("outputs") or ()}
    reasons: list[str] = []
    unlisted = [p.name for p in files if p.name not in listed]
    if unlisted:
        reasons.append(f"no provenance for {', '.join(unlisted)}")
    changed: dict[str, list[str]] = {}
    made: list[str] = []
    for path, data in manifests.items():
        made.append(str(data.get("git_revision") or "?") + ("-dirty" if data.get("dirty") else ""))
        if data.get("schema") != SCHEMA:
            reasons.append(f"{path.name}: schema {data.get('schema')!r}, not {SCHEMA}")
        if data.get("dirty"):
            listed_dirty = ", ".join(data.get("dirty_listed") or [])
            reasons.append(f"{path.name}: made from an uncommitted tree ({data.get('dirty_files')} changed file(s): "
                           f"{listed_dirty})")  # fmt: skip
        for part, names in output_changes(data).items():
            changed.setdefault(part, []).extend(names)
            reasons.append(f"{part} changed: {', '.join(names)} ({path.name})")
    why = "; ".join(reasons) or f"{len(manifests)} manifest(s): code, inputs and data as recorded"
    return ResultStatus(name, suite, rels, tuple(dict.fromkeys(made)), None, not reasons, why,
                        {k: tuple(v) for k, v in changed.items()})  # fmt: skip


def recorded_revisions(files: Sequence[Path]) -> tuple[tuple[str, ...], int | None]:
    """The git revisions a result's runs name (its ``*_long.csv`` or ``*_runs.json``), and how many runs it holds;
    ``((), None)`` when it has neither."""
    revisions: dict[str, None] = {}
    runs: set[str] = set()
    for path in files:
        if path.name.endswith("_long.csv"):
            with path.open(newline="") as fh:
                for row in csv.DictReader(fh):
                    if row.get("git_revision"):
                        revisions[row["git_revision"]] = None
                    if row.get("run"):
                        runs.add(row["run"])
        elif path.name.endswith("_runs.json"):
            try:
                records = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError):
                continue
            for record in records if isinstance(records, list) else []:
                meta = record.get("metadata") or {}
                if meta.get("git_revision"):
                    revisions[str(meta["git_revision"])] = None
                if record.get("run"):
                    runs.add(record["run"])
    return tuple(sorted(revisions)), (len(runs) if runs else None)


def planned_specs(data: Mapping[str, Any], table: Mapping[str, Any] | None = None,
                  inputs: dict[str, str] | None = None) -> dict[str, Any]:
    """The run specs the current code plans for a manifest's suite and selection (key -> RunSpec), as
    :func:`eval.bench.benchmark.run_bench` plans them; methods the manifest records as skipped are left out.
    ``inputs``, where given, receives the plan's :func:`scoring_inputs`.
    Raises :class:`InputError` when the selection cannot be planned any more (a suite or sequence gone)."""
    from eval.bench.methods import Method, load_methods
    from eval.bench.plan import BenchOptions, ExecutorOptions, prepare
    from eval.bench.runner import plan_runs

    sel = dict(data.get("selection") or {})
    methods = {**(load_methods() if table is None else dict(table))}
    for name, definition in (data.get("method_definitions") or {}).items():
        if name not in methods:
            methods[name] = Method(**definition)
    size = sel.get("image_size")
    options = BenchOptions(
        sequences=tuple(sel["sequences"]) if sel.get("sequences") is not None else None,
        frames=sel.get("frames"),
        seeds=tuple(sel["seeds"]) if sel.get("seeds") is not None else None,
        runs=sel.get("runs"),
        lengths=tuple(sel["lengths"]) if sel.get("lengths") is not None else None,
        motions=tuple(Path(m) for m in sel.get("motions") or ()),
        sim_sequences=tuple(sel["sim_sequences"]) if sel.get("sim_sequences") is not None else None,
        camera=sel.get("camera"),
        image_size=tuple(size) if isinstance(size, list) else size,
        undistort=sel.get("undistort"),
        align=sel.get("align"),
        settings=tuple(tuple(s) for s in sel.get("settings") or ()),
        executor=ExecutorOptions("serial"), check=False, plots=False, progress=False,
    )  # fmt: skip
    plan = prepare(str(data.get("suite")), list(data.get("methods") or []) or None, options, methods)
    if inputs is not None:  # the files the current plan's reports would score against
        inputs.update(scoring_inputs(str(data.get("suite")), [part.suite for part in plan.parts]))
    skipped = set(data.get("skipped") or {})
    specs: dict[str, Any] = {}
    for part in plan.parts:
        chosen = [plan.methods[m] for m in part.suite.methods if m in plan.methods and m not in skipped]
        for spec in plan_runs(part.suite, chosen, renderer=str(sel.get("renderer") or "mujoco"), plots=False):
            specs[spec.key] = spec
    return specs


def judge_manifest(name: str, files: tuple[str, ...], data: Mapping[str, Any],
                   table: Mapping[str, Any] | None = None) -> ResultStatus:
    """A result with a manifest, judged: stale when made from an uncommitted tree, when the suite now plans runs it
    lacks or no longer plans runs it holds, or when any run's fingerprint parts differ from the current code's."""
    suite = str(data.get("suite"))
    revision = str(data.get("git_revision") or "?") + ("-dirty" if data.get("dirty") else "")
    recorded: dict[str, Any] = dict(data.get("runs") or {})
    reasons: list[str] = []
    if data.get("schema") != SCHEMA:
        reasons.append(f"manifest schema {data.get('schema')!r}, not {SCHEMA}")
    if data.get("dirty"):
        listed = ", ".join(data.get("dirty_listed") or [])
        reasons.append(f"made from an uncommitted tree ({data.get('dirty_files')} changed file(s): {listed})")
    inputs: dict[str, str] = {}
    try:
        specs = planned_specs(data, table, inputs)
    except InputError as exc:
        reasons.append(f"cannot be planned now: {exc}")
        return ResultStatus(name, suite, files, (revision,), len(recorded), False, "; ".join(reasons))
    changed: dict[str, list[str]] = {}
    missing = [k for k in specs if k not in recorded]
    extra = [k for k in recorded if k not in specs]
    for key, spec in specs.items():
        entry = recorded.get(key)
        if entry is None:
            continue
        if not entry.get("parts"):
            changed.setdefault("made by other code", []).append(key)
            continue
        for part in run_parts(spec).changed(entry["parts"]):
            changed.setdefault(part, []).append(key)
    recorded_inputs = dict(data.get("inputs") or {})
    moved = [p for p in sorted({*inputs, *recorded_inputs}) if inputs.get(p) != recorded_inputs.get(p)]
    if moved:
        reasons.append(f"scoring inputs changed: {', '.join(moved)}")
    if missing:
        reasons.append(f"{len(missing)} planned run(s) missing (e.g. {missing[0]})")
    if extra:
        reasons.append(f"{len(extra)} run(s) no longer planned (e.g. {extra[0]})")
    for part in [*PARTS, "made by other code"]:
        keys = changed.get(part)
        if keys:
            reasons.append(f"{part} changed: {_runs_by_method(keys, specs)}")
    why = "; ".join(reasons) or f"all {len(specs)} runs' fingerprints equal"
    return ResultStatus(name, suite, files, (revision,), len(recorded), not reasons, why,
                        {k: tuple(v) for k, v in changed.items()})  # fmt: skip


def _runs_by_method(keys: Sequence[str], specs: Mapping[str, Any]) -> str:
    """``ORB (9 runs), LSD (3 runs)``: the runs of ``keys`` counted per method."""
    counts: dict[str, int] = {}
    for key in keys:
        method = specs[key].method.name
        counts[method] = counts.get(method, 0) + 1
    return ", ".join(f"{m} ({n} run{'s' if n != 1 else ''})" for m, n in counts.items())


def format_status(rows: Sequence[ResultStatus]) -> str:
    """The status as a table a person reads at a glance (result, suite, made at, runs, status, why) and a summary
    line."""
    head = ("result", "suite", "made at", "runs", "status", "why")
    body = [(r.name, r.suite or "-", _made(r.made_at), "-" if r.runs is None else str(r.runs), r.status, r.why)
            for r in rows]  # fmt: skip
    widths = [max(len(row[i]) for row in [head, *body]) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row[:5], widths, strict=True)) + "  " + row[5]
             for row in [head, *body]]  # fmt: skip
    current = sum(r.current for r in rows)
    lines.append(f"{current} of {len(rows)} result(s) current, {len(rows) - current} stale")
    return "\n".join(lines)


def _made(revisions: Sequence[str]) -> str:
    if not revisions:
        return "?"
    return revisions[0] + (f" +{len(revisions) - 1}" if len(revisions) > 1 else "")
