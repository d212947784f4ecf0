"""One run -> a folder of artifacts (deterministic metrics, atomic writes, failures recorded), suite runs (resume,
skip, failure isolation), and external systems' outputs scored like agents."""

import json
import os
import shutil
from dataclasses import replace

import numpy as np
import pytest

from eval.bench.methods import Method, external_method, load_methods
from eval.bench.run import DONE_FILE, FAILED_FILE, RunResult, RunSpec, execute_run
from eval.bench.run_store import is_finished, remove_stale_temporaries, run_folder, store_result
from eval.bench.runner import frames_jobs, plan_runs, run_order, run_suite
from eval.bench.sequence_ref import SequenceRef
from eval.bench.suites import get_suite
from sim_envs.folders.datasets import export_tum_rgbd
from sim_envs.folders.formats import read_tum_trajectory, write_tum_trajectory

METHODS = load_methods()
ORACLE, CONSTANT = METHODS["oracle"], METHODS["constant-pose"]
OFFICE0 = SequenceRef("office0", base="office0")
FRAMES = 8


def spec_of(method, frames=FRAMES, **kwargs):
    return RunSpec("test", kwargs.pop("sequence", OFFICE0), method, frames=frames, plots=False,
                   git_revision="abc123", **kwargs)  # fmt: skip


@pytest.fixture(scope="module")
def oracle_run():
    return execute_run(spec_of(ORACLE))


def test_an_oracle_run_is_scored_and_packaged(oracle_run, tmp_path):
    assert oracle_run.status == "done", oracle_run.error
    assert set(oracle_run.files) == {
        "metrics.json", "timing.json", "agent_extras.json", "trajectory.tum", "groundtruth.tum", "keyframes.npz",
        "trajectory_aligned_se3.tum", "trajectory_aligned_sim3.tum",  # the oracle is a monocular method
    }  # fmt: skip
    folder = store_result(tmp_path, oracle_run)
    assert folder == tmp_path / "test" / "office0" / "oracle" / f"seed0-frames{FRAMES}"
    record = json.loads((folder / "metrics.json").read_text())
    m = record["metrics"]
    assert record["sequence"] == "office0" and record["method"] == "oracle"
    assert m["ate_rmse"] == pytest.approx(0.0, abs=1e-9)
    assert m["depth_percent_correct"] == 100.0 and m["frames"] == FRAMES
    assert m["depth_keyframes"] == 1.0  # key-frames every 10 frames: frame 0 only
    assert "fps" not in m and "step_ms_mean" not in m  # wall-clock figures live in timing.json
    meta = record["metadata"]
    assert meta["entry_point"] == "sim_envs.agents:OracleAgent" and meta["env_id"] == "sim_envs/office0-v0"
    assert meta["git_revision"] == "abc123" and meta["seed"] == 0 and meta["frames_requested"] == FRAMES
    assert meta["fingerprint"] == spec_of(ORACLE).fingerprint() and 0.0 <= meta["rotation_share"] <= 1.0
    timing = json.loads((folder / "timing.json").read_text())
    assert timing["wall_s"] > 0 and timing["fps"] > 0
    assert timing["frames"] == FRAMES and timing["fps_end_to_end"] == pytest.approx(FRAMES / timing["wall_s"])
    assert timing["peak_rss_mib"] > 50  # this process: numpy, the renderer...
    from eval.metrics.results import load_run

    assert load_run(folder / "metrics.json").resources["peak_rss_mib"] == timing["peak_rss_mib"]
    assert m["rpe_dist_m_p10"] > 0 and "rpe_trans_rmse_p50" in m  # the relative error at 10-50 % of the path
    assert timing["environment"]["packages"]["numpy"] == np.__version__ and timing["environment"]["python"]
    stamps, est = read_tum_trajectory(folder / "trajectory.tum")
    _, gt = read_tum_trajectory(folder / "groundtruth.tum")
    assert stamps.shape == (FRAMES,) and np.allclose(est, gt, atol=1e-8)
    for name in ("trajectory_aligned_se3.tum", "trajectory_aligned_sim3.tum"):
        aligned_stamps, aligned = read_tum_trajectory(folder / name)
        assert np.array_equal(aligned_stamps, stamps) and np.allclose(aligned, gt, atol=1e-8)
    with np.load(folder / "keyframes.npz") as kf:
        assert kf["depth"].shape == (1, 240, 320) and kf["T_world_cam"].shape == (1, 4, 4)
        assert kf["timestamps"][0] == 0.0 and kf["depth"].dtype == np.float32
    assert is_finished(tmp_path, spec_of(ORACLE))
    assert not is_finished(tmp_path, spec_of(replace(ORACLE, kwargs={"keyframe_every": 5})))  # other fingerprint


def test_fingerprint_follows_input_files(tmp_path):
    weights = tmp_path / "weights.pt"
    weights.write_bytes(b"one")
    method = replace(ORACLE, inputs=(str(weights),))
    before = spec_of(method).fingerprint()
    assert spec_of(method).fingerprint() == before  # same bytes, same fingerprint
    weights.write_bytes(b"two")
    assert spec_of(method).fingerprint() != before  # new weights: finished runs are not reused


def test_same_run_same_bytes(oracle_run):
    again = execute_run(spec_of(ORACLE))
    assert again.files["metrics.json"] == oracle_run.files["metrics.json"]
    assert again.files["trajectory.tum"] == oracle_run.files["trajectory.tum"]


def test_metric_groups_and_a_run_with_no_depth():
    constant = execute_run(spec_of(CONSTANT))
    m = json.loads(constant.files["metrics.json"])["metrics"]
    assert m["ate_rmse"] > 0 and m["depth_keyframes"] == 0.0 and m["depth_percent_correct"] is None
    depth_only = execute_run(spec_of(replace(ORACLE, name="depth-only", metrics=("depth",))))
    m = json.loads(depth_only.files["metrics.json"])["metrics"]
    assert "ate_rmse" not in m and "tracked_share" not in m and m["depth_percent_correct"] == 100.0


def test_a_failing_run_is_recorded_not_raised(tmp_path):
    bad = replace(ORACLE, name="bad", kwargs={"keyframe_every": 0})
    result = execute_run(spec_of(bad))
    assert result.status == "failed" and "keyframe_every must be >= 1" in result.error
    assert "Traceback" in result.traceback and not result.files
    folder = store_result(tmp_path, result)
    assert [p.name for p in folder.iterdir()] == [FAILED_FILE]
    failure = json.loads((folder / FAILED_FILE).read_text())
    assert failure["status"] == "failed" and "keyframe_every" in failure["error"]
    assert not is_finished(tmp_path, spec_of(bad))


def test_writes_are_atomic_and_stale_temporaries_are_cleaned(tmp_path, oracle_run, monkeypatch):
    spec = oracle_run.spec
    failed = RunResult(spec, "failed", error="boom")
    store_result(tmp_path, failed)
    real_rename = os.rename

    def interrupted(src, dst):  # the process dies just before the final rename
        if ".tmp-" in str(src):
            raise KeyboardInterrupt
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", interrupted)
    with pytest.raises(KeyboardInterrupt):
        store_result(tmp_path, oracle_run)
    monkeypatch.setattr(os, "rename", real_rename)
    folder = run_folder(tmp_path, spec)
    assert [p.name for p in folder.iterdir()] == [FAILED_FILE]  # the old result is intact, nothing half-written
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".")]
    store_result(tmp_path, oracle_run)  # a done run replaces the failed one
    assert (folder / DONE_FILE).is_file() and not (folder / FAILED_FILE).exists()
    dead = folder.parent / f".{folder.name}.tmp-999999999-deadbeef"
    alive = folder.parent / f".{folder.name}.tmp-{os.getpid()}-cafecafe"
    dead.mkdir()
    alive.mkdir()
    moved_aside = folder.parent / f".{folder.name}.old-999999999-deadbeef"  # killed between the two renames
    os.rename(folder, moved_aside)
    assert remove_stale_temporaries([folder.parent]) == 2
    assert not dead.exists() and alive.exists() and (folder / DONE_FILE).is_file() and not moved_aside.exists()


def test_a_suite_run_resumes_skips_and_isolates_failures(tmp_path):
    table = dict(METHODS)
    table["bad"] = replace(ORACLE, name="bad", kwargs={"keyframe_every": 0})
    table["missing"] = Method("missing", entry_point="no_such_module:Agent")
    suite = get_suite("quick").select(["office0@clean"], ["oracle", "constant-pose", "bad", "missing"], frames=6,
                                      runs=1)
    seen = []
    first = run_suite(suite, table, tmp_path, plots=False, progress=False, check=False, revision="r1",
                      on_result=seen.append)  # fmt: skip
    assert first.counts() == {"done": 2, "failed": 1}
    assert list(first.skipped_methods) == ["missing"] and "no_such_module" in first.skipped_methods["missing"]
    assert [r.method for r in first.records] == ["oracle", "constant-pose"]
    assert len(seen) == 3 and "keyframe_every" in first.failed[0].error
    second = run_suite(suite, table, tmp_path, plots=False, progress=False, check=False, revision="r2")
    assert second.counts() == {"cached": 2, "failed": 1}  # finished runs are kept, the failed one is retried
    assert second.records[0].metadata["git_revision"] == "r1"
    table["constant-pose"] = replace(CONSTANT, kwargs={"tracked": False})  # a changed method runs again
    third = run_suite(suite, table, tmp_path, plots=False, progress=False, check=False)
    assert third.outcomes["quick/office0/constant-pose/seed0-frames6"].status == "done"
    assert third.records[1].metrics["tracked_share"] == 0.0


def test_plots_are_written(tmp_path):
    result = execute_run(replace(spec_of(ORACLE, frames=11), plots=True))
    assert result.status == "done", result.error
    assert result.files["trajectory.png"][:4] == b"\x89PNG" and result.files["depth.png"][:4] == b"\x89PNG"


def test_an_external_systems_output_is_scored_like_an_agent(tmp_path):
    ref = SequenceRef("rot_yaw_30", base="rot_yaw_30")
    source = ref.make_source()
    try:
        export = export_tum_rgbd(source, tmp_path / "export", progress=False, max_frames=10)
    finally:
        source.close()
    out = tmp_path / "myslam" / "rot_yaw_30"
    (out / "depth").mkdir(parents=True)
    stamps, T = read_tum_trajectory(export / "groundtruth.txt")
    moved = np.eye(4)
    moved[:3, 3] = [1.0, -2.0, 0.5]  # another world frame: the alignment takes it out
    write_tum_trajectory(out / "trajectory.txt", stamps[::2], moved @ T[::2])  # every other frame only
    depth_png = sorted((export / "depth").glob("*.png"))[4]
    shutil.copy(depth_png, out / "depth" / depth_png.name)
    (tmp_path / "myslam" / "method.toml").write_text('sensor = "rgbd"\nuses_ground_truth = ["depth"]\n')
    (out / "run.toml").write_text("wall_s = 12.5\n")
    method = external_method("MySLAM", tmp_path / "myslam")
    result = execute_run(spec_of(method, frames=10, sequence=ref))
    assert result.status == "done", result.error
    record = json.loads(result.files["metrics.json"])
    assert record["association"]["rule"] == "tum"  # matched by timestamp, and recorded so
    assert record["sensor"] == "rgbd" and record["uses_ground_truth"] and record["ground_truth_used"] == ["depth"]
    timing = json.loads(result.files["timing.json"])
    assert timing["method_wall_s"] == 12.5  # its own run time: the speed tables' wall time and frames per second
    assert timing["wall_s"] == 12.5 and timing["fps_end_to_end"] == pytest.approx(10 / 12.5)
    assert timing["scoring_wall_s"] > 0  # the judge's own seconds, apart
    m = record["metrics"]
    assert m["frames"] == 10 and m["ate_pairs"] == 5 and m["tracked_share"] == 0.5
    assert m["ate_rmse"] < 1e-6 and m["depth_keyframes"] == 1 and m["depth_percent_correct"] > 99.9
    (out / "run.toml").unlink()  # no declared run time: no speed figures, never the judge's time in their place
    timing = json.loads(execute_run(spec_of(method, frames=10, sequence=ref)).files["timing.json"])
    assert "wall_s" not in timing and "fps_end_to_end" not in timing and timing["scoring_wall_s"] > 0
    missing = execute_run(spec_of(method, frames=10))  # no output for office0
    assert missing.status == "failed" and "no trajectory for 'office0'" in missing.error


@pytest.mark.slow  # > 5 s: the full lane only
def test_a_run_past_its_time_limit_is_recorded_as_failed(tmp_path, monkeypatch):
    from eval.bench.executors import LocalExecutor

    (tmp_path / "slowagent.py").write_text(
        "import time\n"
        "class Slow:\n"
        "    def reset(self, intrinsics, image_size): pass\n"
        "    def step(self, observation):\n"
        "        time.sleep(60)\n"
        "    def finish(self): pass\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]))
    methods = {"slow": Method("slow", entry_point="slowagent:Slow"), "oracle": ORACLE}
    suite = get_suite("quick").select(["office0@clean"], ["slow", "oracle"], frames=4, runs=1)
    run = run_suite(suite, methods, tmp_path / "runs", executor=LocalExecutor(jobs=1, timeout_s=8), plots=False,
                    progress=False, check=False)  # fmt: skip
    assert run.counts() == {"done": 1, "failed": 1}
    failed = run.failed[0]
    assert failed.key.endswith("slow/seed0-frames4") and "exceeded its time limit of 8 s" in failed.error
    stored = json.loads((tmp_path / "runs" / failed.key / FAILED_FILE).read_text())
    assert "RunTimedOut" in stored["error"]


def test_report_only_takes_finished_runs_whatever_made_them(tmp_path):
    suite = get_suite("quick").select(["office0@clean"], ["oracle", "constant-pose"], frames=6, runs=1)
    methods = load_methods()
    run_suite(suite, {"oracle": methods["oracle"]} | {"constant-pose": methods["constant-pose"]}, tmp_path,
              plots=False, progress=False, check=False)  # fmt: skip
    changed = {"oracle": replace(methods["oracle"], kwargs={"keyframe_every": 3}), "constant-pose": CONSTANT}
    shutil.rmtree(tmp_path / "quick" / "office0" / "constant-pose")
    again = run_suite(suite, changed, tmp_path, plots=False, progress=False, check=False, report_only=True)
    assert again.counts() == {"cached": 1, "not_run": 1}  # the oracle's old run taken as is; nothing was run
    assert not again.failed and [r.method for r in again.records] == ["oracle"]
    from eval.reports.report_parts import failure_frame, status_markdown

    assert "1 not run (--report-only" in status_markdown(again) and "Not run (" in status_markdown(again)
    assert set(failure_frame(again)["method"]) == {"oracle"}  # a run not run is no failure


def test_a_folder_an_earlier_judge_wrote_is_completed_without_running_it(tmp_path):
    """A finished run from before the aligned files and the relative errors: report-only writes the files into its
    folder and adds the figures to its record, from its trajectory.tum and groundtruth.tum."""
    suite = get_suite("quick").select(["office0@clean"], ["oracle"], frames=12, runs=1)
    first = run_suite(suite, {"oracle": ORACLE}, tmp_path, plots=False, progress=False, check=False)
    folder = first.outcomes[first.specs[0].key].folder
    complete = first.records[0].metrics
    old = json.loads((folder / "metrics.json").read_text())
    old["metrics"] = {k: v for k, v in old["metrics"].items() if "_p" not in k or not k.startswith("rpe_")}
    (folder / "metrics.json").write_text(json.dumps(old))
    for name in ("trajectory_aligned_se3.tum", "trajectory_aligned_sim3.tum"):
        (folder / name).unlink()
    again = run_suite(suite, {"oracle": ORACLE}, tmp_path, plots=False, progress=False, check=False,
                      report_only=True)  # fmt: skip
    assert again.counts() == {"cached": 1}
    assert again.records[0].metrics["rpe_dist_m_p30"] == complete["rpe_dist_m_p30"]
    assert "rpe_dist_m_p30" not in json.loads((folder / "metrics.json").read_text())["metrics"]  # left as it was
    assert (folder / "trajectory_aligned_se3.tum").read_bytes() == first_bytes(first, "trajectory_aligned_se3.tum")


def first_bytes(run, name):
    """What a fresh run wrote as ``name``: the same run executed again (its files are deterministic)."""
    return execute_run(run.specs[0]).files[name]


METHODS_SEEN = ("oracle", "LSD-BS", "CNN-SLAM")


def test_a_method_without_a_seed_runs_once_per_cell():
    suite = replace(get_suite("quick"), seeds=(0, 1, 2))
    specs = plan_runs(suite, [ORACLE, METHODS["LSD-BS"], METHODS["CNN-SLAM"]])
    per_method = {name: sorted({s.seed for s in specs if s.method.name == name}) for name in METHODS_SEEN}
    # the oracle is exact: its other runs would be copies; LSD-BS's seeds perturb its bootstrap in the last bits
    assert per_method == {"oracle": [0], "LSD-BS": [0, 1, 2], "CNN-SLAM": [0, 1, 2]}
    assert len(specs) == len(suite.sequences) * (1 + 3 + 3)


def test_the_frame_cache_changes_no_byte_of_a_run(tmp_path):
    """The same runs without the cache, with it cold (frames rendered and stored) and warm (frames read back):
    every file but the wall times the same (LSD-BS reads the sensor depth too; the oracle scores depth and labels;
    LSD sees the images alone, read without the rest of the frame)."""
    methods = load_methods()
    ref = SequenceRef("office0@kinect", base="office0", overrides={"camera_effects": "kinect"})
    cache = str(tmp_path / ".frames")
    for name in ("LSD-BS", "oracle", "LSD"):
        spec = RunSpec("quick", ref, methods[name], frames=15, plots=False, git_revision="r")
        plain, cold, warm = (execute_run(replace(spec, frame_cache=c)) for c in (None, cache, cache))
        for result in (plain, cold, warm):
            assert result.status == "done", result.error
        for name_ in set(plain.files) - {"timing.json", "agent_extras.json"}:
            assert plain.files[name_] == cold.files[name_] == warm.files[name_], (name, name_)
    assert len(list((tmp_path / ".frames").rglob("*.frame"))) == 15  # one folder, rendered once


def test_runs_start_longest_first_and_frames_are_rendered_once_before_them(tmp_path):
    kinect = SequenceRef("office0@kinect", base="office0", overrides={"camera_effects": "kinect"})
    window = replace(kinect, name="office0@kinect~5", start=5)
    slow, fast = replace(CONSTANT, name="slow", cost=50.0), replace(ORACLE, name="fast", cost=2.0)
    specs = [spec_of(fast, 40, sequence=kinect), spec_of(slow, 10, sequence=kinect), spec_of(slow, 30),
             spec_of(fast, 6, sequence=window)]
    # frames x cost: 80, 500, 1500 and 12: the registered office0 run first, the window's last
    assert [(s.method.name, s.frames) for s in run_order(specs)] == [("slow", 30), ("slow", 10), ("fast", 40),
                                                                     ("fast", 6)]
    # one job per cached sequence, the most frames any run reads (a window: its start too, from its whole
    # sequence's frames), longest first; none for office0 (registered: never cached)
    jobs = frames_jobs([*specs, spec_of(slow, 20, sequence=kinect)], tmp_path)
    assert [(j.sequence.name, j.frames, j.sequence.start) for j in jobs] == [("office0@kinect", 40, 0),
                                                                            ("office0@kinect~5", 11, 0)]
    suite = get_suite("table1").select(["office0@kinect"], ["oracle", "constant-pose"], frames=4, runs=1)
    done = run_suite(suite, METHODS, tmp_path, plots=False, progress=False, check=False, revision="r")
    assert done.counts() == {"done": 2}
    assert len(list((tmp_path / ".frames").rglob("*.frame"))) == 4
    for key, timing in done.timings.items():  # every frame read from the cache, none rendered by the runs
        assert timing["frame_renders"] == 0 and timing["frame_reads"] >= 4, key
        assert set(timing["stages"]) >= {"setup", "frames", "agent", "finish", "env_driver", "trajectory_metrics",
                                         "keyframe_metrics", "files", "other"}
        assert sum(timing["stages"].values()) == pytest.approx(timing["wall_s"], rel=1e-6)


def test_rendering_and_runs_go_to_the_executor_as_one_queue(tmp_path):
    """The rendering jobs (longest first) and then the runs (longest first) are one queue on the executor, so that a
    core with no sequence left to render starts a run of a rendered one instead of waiting for the last."""
    from eval.bench.executors import SerialExecutor

    seen = []

    class Recording(SerialExecutor):
        def map(self, fn, items):
            items = list(items)
            seen.append([type(item).__name__ for item in items])
            yield from super().map(fn, items)

    suite = get_suite("table1").select(["office0@kinect"], ["oracle", "constant-pose"], frames=4, runs=1)
    done = run_suite(suite, METHODS, tmp_path, executor=Recording(), plots=False, progress=False, check=False,
                     revision="r")
    assert done.counts() == {"done": 2}
    assert seen == [["FramesJob", "RunSpec", "RunSpec"]]
    assert all(timing["frame_renders"] == 0 for timing in done.timings.values())


def test_a_run_waits_for_its_sequence_rendering_outside_its_clocks(tmp_path):
    """A run whose sequence another task is still rendering (the writer lock of its frame cache folder) waits for
    it before its clocks start: the wait is neither in its wall time nor in its frames per second."""
    import threading
    import time

    from sim_envs.sources.frame_cache import CachedFrames

    ref = SequenceRef("office0@kinect", base="office0", overrides={"camera_effects": "kinect"})
    spec = replace(spec_of(ORACLE, 4, sequence=ref), frame_cache=str(tmp_path / ".frames"))
    writer = replace(ref, start=0).make_source(spec.renderer, spec.frame_cache)
    assert isinstance(writer, CachedFrames)
    holding = threading.Event()

    def fill():
        with writer.filling():
            holding.set()
            for i in range(4):
                writer.frame(i)
            time.sleep(1.0)

    thread = threading.Thread(target=fill)
    thread.start()
    try:
        assert holding.wait(30)
        start = time.perf_counter()
        result = execute_run(spec)
        elapsed = time.perf_counter() - start
    finally:
        thread.join()
        writer.close()
    assert result.status == "done", result.error
    timing = json.loads(result.files["timing.json"])
    assert timing["frame_renders"] == 0  # it read the writer's frames
    assert elapsed >= 0.9 and result.seconds < elapsed - 0.5


def test_a_run_is_fingerprinted_once_in_the_parent_not_again_in_its_worker(tmp_path, monkeypatch):
    """The planner hands each run its fingerprint (RunSpec.known_fingerprint): the worker records it without parsing
    the agent's import closure again, and the record's fingerprint is the planner's."""
    import eval.bench.fingerprint as fingerprint

    calls = []
    real = fingerprint.run_parts
    monkeypatch.setattr(fingerprint, "run_parts", lambda spec, *a, **k: calls.append(spec.key) or real(spec, *a, **k))
    suite = get_suite("quick").select(["office0@clean"], ["oracle", "constant-pose"], frames=6, runs=1)
    run = run_suite(suite, dict(METHODS), tmp_path, plots=False, progress=False, check=False)
    assert run.counts() == {"done": 2} and sorted(calls) == sorted(s.key for s in run.specs)  # once a run
    for spec in run.specs:
        record = json.loads((run_folder(tmp_path, spec) / "metrics.json").read_text())
        assert record["metadata"]["fingerprint"] == spec.fingerprint()
    assert replace(run.specs[0], known_fingerprint="abc").fingerprint() == "abc"


def test_git_revision_is_dirty_for_code_changes_not_for_results(tmp_path):
    """A run's revision says ``-dirty`` as the provenance manifests do: for a changed tracked file outside
    ``results/`` only (a suite rewrites ``results/`` itself)."""
    import subprocess

    from eval.bench.runner import git_revision

    def git(*args):
        subprocess.run(["git", *args], cwd=tmp_path, check=True, capture_output=True)

    git("init", "-q")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "table1.md").write_text("a\n")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("add", ".")
    git("-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "c")
    head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=tmp_path, check=True, capture_output=True,
                          text=True).stdout.strip()
    assert git_revision(tmp_path) == head
    (tmp_path / "results" / "table1.md").write_text("b\n")
    assert git_revision(tmp_path) == head
    (tmp_path / "code.py").write_text("x = 2\n")
    assert git_revision(tmp_path) == head + "-dirty"
    assert git_revision(tmp_path.parent / "nowhere") is None
