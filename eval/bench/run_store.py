"""The run folders of a benchmark: where a run's artifacts live (``OUT/<suite>/<sequence>/<method>/seed<S>-frames<N>/``,
:mod:`eval.bench.run`), whether a run is finished (same fingerprint), storing a run's files atomically (a temporary
folder renamed into place; what a killed process left behind is cleaned up by :func:`remove_stale_temporaries`), and
bringing a folder an earlier judge wrote up to the current one (:func:`complete_run`).

Runs are shared between suites by their fingerprint (:meth:`eval.bench.run.RunSpec.fingerprint`: the code, inputs and
configuration of the run, not the suite that asks for it): every finished run is listed in the output root's index,
``OUT/.by-fingerprint/<fingerprint>`` (the run folders, relative to ``OUT``, that hold a finished run of that
fingerprint, one a line). A suite whose own folder lacks a run finds it there (:func:`shared_run`) and takes it into
its own folder (:func:`reuse_finished`: its files hard-linked, copied where a link cannot be made), so each suite's
folder keeps its layout for the reports and the run is made once. Only identical runs are shared: a run of the first
200 frames is never taken from a longer run of the same sequence (a SLAM system's first 200 poses depend on whether
it was stopped there: its back end closes loops and optimises at the end), and a run whose fingerprint differs in any
part (an edited agent file, other weights, another seed) is made again. Runs made before the index existed are
listed by a scan of ``OUT`` the first time it is read (:func:`build_index`)."""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path

from eval.bench.run import DONE_FILE, FAILED_FILE, RunResult, RunSpec, run_title, run_trajectory_metrics, write_json
from eval.errors import EvalError, RunnerError
from eval.metrics.aligned import ALIGNED_FILES, aligned_alignments, aligned_files
from eval.metrics.catalogue import WALL_S
from eval.metrics.results import ResultsError, RunRecord, load_run
from eval.metrics.trajectory import PoseTrajectory


# ------------------------------------------------------------------------------------------------ the folders
def run_folder(out_root: str | Path, spec: RunSpec) -> Path:
    """Where a run's artifacts live."""
    return Path(out_root) / spec.relpath


def is_finished(out_root: str | Path, spec: RunSpec) -> bool:
    """True when the run's folder holds a readable ``metrics.json`` (:func:`eval.metrics.results.load_run`) with this
    run's fingerprint."""
    return _finished_with(run_folder(out_root, spec), spec.fingerprint())


def _finished_with(folder: Path, fingerprint: str) -> bool:
    """Whether ``folder`` holds a readable ``metrics.json`` recording ``fingerprint``."""
    path = folder / DONE_FILE
    if not path.is_file():
        return False
    try:
        record = load_run(path)
    except ResultsError:
        return False
    return record.metadata.get("fingerprint") == fingerprint


# ------------------------------------------------------------------------------------ runs shared by fingerprint
INDEX_DIR = ".by-fingerprint"  # under the output root: one file per fingerprint listing the folders holding it
SCANNED_FILE = ".scanned"  # in the index: the run folders made before the index have been listed
RUN_DEPTH = 4  # <suite>/<sequence>/<method>/seed<S>-frames<N>


def _index_file(out_root: str | Path, fingerprint: str) -> Path:
    if not (fingerprint and all(c in "0123456789abcdef" for c in fingerprint)):
        raise RunnerError(f"a run's fingerprint is hex digits, got {fingerprint!r}")
    return Path(out_root) / INDEX_DIR / fingerprint


def indexed_folders(out_root: str | Path, fingerprint: str) -> list[Path]:
    """The run folders the index lists for ``fingerprint`` (relative to ``out_root``), newest first; none read."""
    path = _index_file(out_root, fingerprint)
    if not path.is_file():
        return []
    lines = [line.strip() for line in path.read_text().splitlines() if line.strip()]
    return [Path(line) for line in reversed(lines) if ".." not in Path(line).parts and not Path(line).is_absolute()]


def _add_to_index(out_root: str | Path, fingerprint: str, relpath: Path) -> None:
    """List ``relpath`` under ``fingerprint`` (the index file rewritten atomically; the parent process stores every
    run, so one writer at a time)."""
    known = [p.as_posix() for p in reversed(indexed_folders(out_root, fingerprint))]
    if relpath.as_posix() in known:
        return
    path = _index_file(out_root, fingerprint)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    tmp.write_text("".join(f"{line}\n" for line in [*known, relpath.as_posix()]))
    os.replace(tmp, path)


def index_run(out_root: str | Path, spec: RunSpec) -> None:
    """List the run's folder in the index under its fingerprint (a finished run, made or taken from another)."""
    _add_to_index(out_root, spec.fingerprint(), spec.relpath)


def build_index(out_root: str | Path) -> int:
    """List every finished run folder under ``out_root`` (``<suite>/<sequence>/<method>/<run>/metrics.json``, hidden
    folders left out) under the fingerprint its ``metrics.json`` records; done once per output root (a marker file in
    the index). Returns how many folders were listed."""
    root = Path(out_root)
    marker = root / INDEX_DIR / SCANNED_FILE
    if marker.is_file() or not root.is_dir():
        return 0
    listed = 0
    for path in sorted(root.glob("/".join(["[!.]*"] * RUN_DEPTH) + f"/{DONE_FILE}")):
        try:
            fingerprint = load_run(path).metadata.get("fingerprint")
        except ResultsError:
            continue
        if isinstance(fingerprint, str) and fingerprint:
            try:
                _add_to_index(root, fingerprint, path.parent.relative_to(root))
            except RunnerError:
                continue
            listed += 1
    marker.parent.mkdir(parents=True, exist_ok=True)
    marker.write_text(f"{listed} run folder(s) listed\n")
    return listed


def shared_run(out_root: str | Path, spec: RunSpec) -> Path | None:
    """A finished run of ``spec``'s fingerprint in another folder of ``out_root`` (another suite's, found through
    the index, :func:`build_index` first), None when there is none; a folder the index lists that no longer holds
    that fingerprint (remade since by other code) is passed over. Nothing is written but the index's first scan."""
    build_index(out_root)
    fingerprint = spec.fingerprint()
    for relpath in indexed_folders(out_root, fingerprint):
        folder = Path(out_root) / relpath
        if relpath != spec.relpath and _finished_with(folder, fingerprint):
            return folder
    return None


def reuse_finished(out_root: str | Path, spec: RunSpec) -> bool:
    """True when the run is finished in its own folder (:func:`is_finished`), or was finished in another folder
    (:func:`shared_run`) and is now taken into its own: the files hard-linked (copied where a link cannot be made)
    into a temporary folder renamed into place, and the folder listed in the index. False: the run must be made."""
    if is_finished(out_root, spec):
        return True
    source = shared_run(out_root, spec)
    if source is None:
        return False
    _replace_folder(out_root, spec, lambda tmp: _link_files(source, tmp))
    index_run(out_root, spec)
    return True


def _link_files(source: Path, target: Path) -> None:
    for path in sorted(source.iterdir()):
        if not path.is_file() or path.name.startswith("."):
            continue
        try:
            os.link(path, target / path.name)
        except OSError:  # another file system, or links not allowed: a copy
            shutil.copy2(path, target / path.name)


def store_result(out_root: str | Path, result: RunResult) -> Path:
    """Write a run's files (or ``failed.json``) into its folder atomically (temporary folder, then rename); a
    finished run is listed in the index under its fingerprint (:func:`index_run`)."""
    final = _replace_folder(out_root, result.spec, lambda tmp: _write_files(tmp, result))
    if result.status == "done":
        index_run(out_root, result.spec)
    return final


def _write_files(tmp: Path, result: RunResult) -> None:
    if result.status == "done":
        for name, data in result.files.items():
            if Path(name).name != name:
                raise RunnerError(f"run {result.spec.key}: refusing to write the file name {name!r}")
            (tmp / name).write_bytes(data)
    else:
        failure = {
            "run": result.spec.key,
            "status": "failed",
            "error": result.error,
            "traceback": result.traceback,
            WALL_S.key: result.seconds,
            "fingerprint": result.spec.fingerprint(),
            "git_revision": result.spec.git_revision,
        }
        write_json(tmp / FAILED_FILE, failure)


def _replace_folder(out_root: str | Path, spec: RunSpec, fill: Callable[[Path], None]) -> Path:
    """The run's folder replaced atomically by a temporary folder ``fill`` wrote (an earlier folder moved aside,
    put back if the rename fails, removed after it)."""
    final = run_folder(out_root, spec)
    final.parent.mkdir(parents=True, exist_ok=True)
    tag = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
    tmp = final.parent / f".{final.name}.tmp-{tag}"
    tmp.mkdir()
    try:
        fill(tmp)
        old = None
        if final.exists():  # an earlier failed or outdated result: moved aside, restored if the rename fails
            old = final.parent / f".{final.name}.old-{tag}"
            os.rename(final, old)
        try:
            os.rename(tmp, final)
        except BaseException:
            if old is not None:
                os.rename(old, final)
            raise
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def complete_run(folder: str | Path, spec: RunSpec, record: RunRecord) -> RunRecord:
    """A finished run whose folder an earlier judge wrote, brought up to this one without running it again: the
    aligned trajectories it lacks (:mod:`eval.metrics.aligned`) are written into the folder (each atomically), and
    the trajectory figures its record lacks (the relative error at several distances) are computed from its
    ``trajectory.tum`` and ``groundtruth.tum`` with the run's alignment and added to the returned record (its
    ``metrics.json`` is left as it is). A folder without both files is returned as it is."""
    folder = Path(folder)
    wanted = aligned_alignments(spec.method.sensor)
    missing_files = [a for a in wanted if not (folder / ALIGNED_FILES[a]).is_file()]
    needs_metrics = spec.method.keeps("rpe_dist_m_p10") and "rpe_dist_m_p10" not in record.metrics
    gt_path, est_path = folder / "groundtruth.tum", folder / "trajectory.tum"
    if not (missing_files or needs_metrics) or not (gt_path.is_file() and est_path.is_file()):
        return record
    try:
        gt, est = PoseTrajectory.from_tum_file(gt_path), PoseTrajectory.from_tum_file(est_path)
        scored = run_trajectory_metrics(gt.timestamps, gt.T_world_cam, est.T_world_cam, spec.alignment)
    except EvalError:
        return record  # nothing to align (too few poses): the record says why the run has no trajectory figures
    for name, text in aligned_files(scored, missing_files, run_title(spec)).items():
        tmp = folder / f".{name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        tmp.write_text(text)
        os.replace(tmp, folder / name)
    if needs_metrics:
        added = {k: v for k, v in scored.flat_metrics().items() if k not in record.metrics and spec.method.keeps(k)}
        record = record.replace(metrics={**record.metrics, **added})
    return record


def remove_stale_temporaries(folders: Sequence[Path]) -> int:
    """Clean up after benchmark processes that were killed while storing a run (their pid is no longer alive):
    remove their temporary folders (``.<run>.tmp-<pid>-...``) and put a result they had moved aside
    (``.<run>.old-<pid>-...``) back where its replacement never arrived. Returns how many were handled."""
    removed = 0
    for parent in {Path(f) for f in folders}:
        if not parent.is_dir():
            continue
        for path in parent.iterdir():
            if not (path.name.startswith(".") and (".tmp-" in path.name or ".old-" in path.name)):
                continue
            pid_text = path.name.rsplit("-", 2)[-2]
            if pid_text.isdigit() and _alive(int(pid_text)):
                continue
            final = parent / path.name[1:].split(".old-")[0]
            if ".old-" in path.name and not final.exists():
                os.rename(path, final)  # killed between its two renames: the earlier result comes back
            else:
                shutil.rmtree(path, ignore_errors=True)
            removed += 1
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
