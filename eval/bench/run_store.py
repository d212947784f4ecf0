"""The run folders of a benchmark: where a run's artifacts live (``OUT/<suite>/<sequence>/<method>/seed<S>-frames<N>/``,
:mod:`eval.bench.run`), whether a run is finished (same fingerprint), storing a run's files atomically (a temporary
folder renamed into place; what a killed process left behind is cleaned up by :func:`remove_stale_temporaries`), and
bringing a folder an earlier judge wrote up to the current one (:func:`complete_run`)."""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Sequence
from pathlib import Path

from eval.bench.run import DONE_FILE, FAILED_FILE, RunResult, RunSpec, run_title, run_trajectory_metrics, write_json
from eval.errors import EvalError, RunnerError
from eval.metrics.aligned import ALIGNED_FILES, aligned_alignments, aligned_files
from eval.metrics.results import ResultsError, RunRecord, load_run
from eval.metrics.trajectory import PoseTrajectory


# ------------------------------------------------------------------------------------------------ the folders
def run_folder(out_root: str | Path, spec: RunSpec) -> Path:
    """Where a run's artifacts live."""
    return Path(out_root) / spec.relpath


def is_finished(out_root: str | Path, spec: RunSpec) -> bool:
    """True when the run's folder holds a readable ``metrics.json`` (:func:`eval.metrics.results.load_run`) with this
    run's fingerprint."""
    path = run_folder(out_root, spec) / DONE_FILE
    if not path.is_file():
        return False
    try:
        record = load_run(path)
    except ResultsError:
        return False
    return record.metadata.get("fingerprint") == spec.fingerprint()


def store_result(out_root: str | Path, result: RunResult) -> Path:
    """Write a run's files (or ``failed.json``) into its folder atomically (temporary folder, then rename)."""
    final = run_folder(out_root, result.spec)
    final.parent.mkdir(parents=True, exist_ok=True)
    tag = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
    tmp = final.parent / f".{final.name}.tmp-{tag}"
    tmp.mkdir()
    try:
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
                "wall_s": result.wall_s,
                "fingerprint": result.spec.fingerprint(),
                "git_revision": result.spec.git_revision,
            }
            write_json(tmp / FAILED_FILE, failure)
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
