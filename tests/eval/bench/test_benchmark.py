"""eval.bench.benchmark: the benchmark as a library call. Bad input is refused before any run; a broken or partial
result is never reported as a whole, successful one (the rows of issue 40's table that the call decides)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from eval.bench import BenchOptions, ExecutorOptions, GateAction, run_bench
from eval.bench.benchmark import KINDS, prepare
from eval.bench.sequence_resolve import resolve_sequence
from eval.bench.suites import SuiteKind
from eval.errors import InputError
from sim_envs.folders.formats import write_tum_trajectory

SERIAL = ExecutorOptions("serial")


def options(tmp_path: Path, **changes) -> BenchOptions:
    """A small, quiet benchmark whose runs and results stay under ``tmp_path``."""
    base = dict(sequences=("office0",), frames=6, seeds=(0,), executor=SERIAL, plots=False, progress=False,
                out=tmp_path / "runs", results=tmp_path / "results")  # fmt: skip
    return BenchOptions(**{**base, **changes})


def run_folders(tmp_path: Path) -> list[Path]:
    return sorted((tmp_path / "runs").rglob("metrics.json")) + sorted((tmp_path / "runs").rglob("failed.json"))


def test_every_suite_kind_but_perf_has_its_parts_and_report_writer():
    assert set(KINDS) == set(SuiteKind) - {SuiteKind.PERF}


def test_a_plain_suite_runs_and_the_outcome_lists_every_run(tmp_path):
    outcome = run_bench("table1", ["oracle", "constant-pose"], options(tmp_path))
    assert outcome.exit_status == 0 and outcome.failed == () and outcome.skipped == ()
    assert [(r.method, r.status, r.coverage) for r in outcome.runs] == [("oracle", "done", None),
                                                                       ("constant-pose", "done", None)]
    assert outcome.reports[0] == tmp_path / "results" / "table1.md" and outcome.results_dir == tmp_path / "results"
    again = run_bench("table1", ["oracle", "constant-pose"], options(tmp_path))
    assert [r.status for r in again.runs] == ["cached", "cached"]


@pytest.mark.parametrize(("changes", "message"), [
    (dict(settings=("tracking.pyramid_levels=abc",)), "'tracking.pyramid_levels' must be an integer, got 'abc'"),
    (dict(settings=("refinement.enabled=maybe",)), r"'refinement.enabled' must be a bool \(true or false\)"),
    (dict(settings=("tracking.pyramid_levels=20",)), "tracking.pyramid_levels must be in 1..8, got 20"),
    (dict(settings=("nosuch.key=1",)), "--set nosuch.key: no chosen method's configuration has this key"),
    (dict(seeds=(-1,)), "--seeds takes whole numbers >= 0 .*, got -1"),
    (dict(sequences=("office9",)), "unknown sequence 'office9'"),
    (dict(executor=ExecutorOptions("serial", timeout_s=0)), "--timeout must be a number of seconds > 0"),
    (dict(figure_format="jpg"), "unknown figure format 'jpg'; valid formats: png, pdf, svg"),
])
def test_bad_input_is_refused_before_any_run(tmp_path, changes, message):
    with pytest.raises(InputError, match=message):
        run_bench("table1", ["LSD", "oracle"], options(tmp_path, **changes))
    assert run_folders(tmp_path) == [] and not (tmp_path / "results").exists()


def test_settings_go_to_the_methods_whose_configuration_has_the_key(tmp_path):
    plan = prepare("table1", ["LSD", "ORB", "oracle"], options(tmp_path, settings=("refinement.enabled=false",
                                                                                   "keyframe_every=5")))
    assert dict(plan.settings) == {"refinement.enabled": ("LSD",), "keyframe_every": ("oracle",)}
    assert plan.methods["LSD"].agent_kwargs(0)["config"]["refinement.enabled"] is False
    assert plan.methods["ORB"] == prepare("table1", ["ORB"], options(tmp_path)).methods["ORB"]  # untouched


def test_an_unknown_method_or_a_missing_external_folder_is_refused_up_front(tmp_path):
    from eval.bench.methods import method_table

    with pytest.raises(InputError, match="unknown method.s. NoSuch; valid methods: CNN-SLAM"):
        run_bench("table1", ["NoSuch"], options(tmp_path))
    table = method_table(externals=[f"Bad={tmp_path / 'missing'}"])
    with pytest.raises(InputError, match=f"--external Bad={tmp_path / 'missing'}: no such folder"):
        run_bench("table1", ["oracle"], options(tmp_path), table)
    assert run_folders(tmp_path) == []


@pytest.mark.parametrize(("camera", "message"), [
    ("fx = 500.0\nfy = \n", "not a readable camera file"),
    ("fx = -5.0\nfy = 50.0\ncx = 32.0\ncy = 24.0\nwidth = 64\nheight = 48\n",
     "focal lengths must be finite and positive"),
])
def test_a_folder_whose_camera_file_is_bad_is_refused_up_front(tmp_path, camera, message):
    from sim_envs.folders.datasets import write_folder
    from tests.eval.test_real_sequences import tiny_source

    folder = write_folder(tiny_source(), tmp_path / "seq", "7scenes")
    (folder / "camera.toml").write_text(camera)
    with pytest.raises(InputError, match=message):
        run_bench("table1", ["oracle"], options(tmp_path, sequences=(str(folder),)))
    assert run_folders(tmp_path) == []


def test_a_selection_never_writes_into_the_committed_results(tmp_path, monkeypatch):
    """``--results results`` (or a folder below it) with a selection other than the suite's is refused: it would
    overwrite the committed table with part of it."""
    monkeypatch.chdir(tmp_path)
    for target in (Path("results"), Path("results") / "bench"):
        with pytest.raises(InputError, match="this selection is 1 of its 9 sequences .*leave --results out"):
            prepare("table1", ["oracle"], options(tmp_path, results=target))
    assert prepare("table1", ["oracle"], options(tmp_path, results=Path("elsewhere"))).results_dir == Path("elsewhere")
    plan = prepare("table1", ["oracle"], options(tmp_path, results=None))  # a subset's own folder
    assert plan.results_dir.parent == tmp_path / "runs" / "reports" and plan.results_dir.name.startswith("table1-")


def test_an_agent_that_raises_in_step_is_a_failed_run_in_the_failure_table(tmp_path, monkeypatch):
    from eval.bench.methods import method_table
    from tests.eval.bench.test_methods import STEP_FAILS_AGENTS

    (tmp_path / "raising_agent.py").write_text(STEP_FAILS_AGENTS)
    monkeypatch.syspath_prepend(str(tmp_path))
    methods = tmp_path / "methods.toml"
    methods.write_text('[methods.Raises]\nentry_point = "raising_agent:StepFails"\n')
    outcome = run_bench("table1", ["Raises", "oracle"], options(tmp_path), method_table(methods))
    assert outcome.exit_status == 1 and outcome.skipped == ()
    assert [(r.method, r.status) for r in outcome.failed] == [("Raises", "failed")]
    assert "RuntimeError: a bug in step" in outcome.failed[0].error
    md = (tmp_path / "results" / "table1.md").read_text()
    assert "| Raises | 1 | 1 | 0 | 100% |" in md and "Failed runs" in md and "a bug in step" in md
    assert "Methods skipped" not in md


def test_a_method_that_cannot_import_at_run_time_fails_and_is_never_cached(tmp_path, monkeypatch):
    """COLMAP whose pycolmap breaks at run time: a failed run (no identity poses scored), and a rerun tries again."""
    pytest.importorskip("thirdparty.colmap_sfm", reason="COLMAP's bindings are not installed (the sfm extra: "
                        "pip install -c constraints.txt -e '.[sfm]')")
    import slamcommon.sfm as sfm

    def broken() -> None:
        raise sfm.SfmUnavailableError("structure from motion needs pycolmap: ImportError: libcolmap.so not found")

    monkeypatch.setattr(sfm, "_pycolmap", broken)
    for _ in range(2):
        outcome = run_bench("table1", ["COLMAP"], options(tmp_path))
        assert [r.status for r in outcome.runs] == ["failed"] and outcome.exit_status == 1
        assert "SfmUnavailableError" in outcome.runs[0].error
    assert [p.name for p in run_folders(tmp_path)] == ["failed.json"]


def _external(tmp_path: Path, keep: slice) -> Path:
    """An external system's output for office0: the ground-truth poses of the frames ``keep`` of the first 60."""
    source = resolve_sequence("office0@kinect").make_source()
    stamps, poses = np.asarray(source.timestamps)[:60], np.asarray(source.poses)[:60]
    out = tmp_path / "OUT"
    (out / "office0").mkdir(parents=True)
    write_tum_trajectory(out / "office0" / "trajectory.txt", stamps[keep], poses[keep])
    return out


def test_an_external_trajectory_covering_part_of_its_sequence_shows_its_coverage(tmp_path):
    """10 of 60 frames: the outcome's run says so, and a run that posed a sixth of its frames is a failure in the
    tables (the failure rule of eval.metrics.results: its mark and tracked share, never a figure), its Avg. too."""
    from eval.bench.methods import method_table

    table = method_table(externals=[f"Mine={_external(tmp_path, slice(0, 10))}"])
    outcome = run_bench("table1", ["Mine"], options(tmp_path, frames=60), table)
    assert outcome.exit_status == 0 and [r.coverage for r in outcome.runs] == [(10, 60)]
    md = (tmp_path / "results" / "table1.md").read_text()
    assert "| office0@kinect (ICL/office0) | X (16 %) |" in md
    assert "| Avg. | X (0/1) |" in md.split("## Abs. Trajectory Error")[1]
    csv = (tmp_path / "results" / "table1.csv").read_text().splitlines()
    assert csv[-1].split(",")[:2] == ["Avg.", "X (0/1)"]  # no average over a failed sequence


def test_an_external_trajectory_with_one_pose_is_a_failed_run(tmp_path):
    from eval.bench.methods import method_table

    table = method_table(externals=[f"One={_external(tmp_path, slice(0, 1))}"])
    outcome = run_bench("table1", ["One"], options(tmp_path, frames=60), table)
    assert outcome.exit_status == 1 and [r.status for r in outcome.runs] == ["failed"]
    assert "BrokenRunError: only 1 pose(s) of the estimate" in outcome.runs[0].error


def test_the_gate_refuses_an_update_that_would_drop_gated_figures(tmp_path):
    baseline = tmp_path / "quick.json"
    both = run_bench("quick", ["oracle", "constant-pose"], options(tmp_path, gate=GateAction.UPDATE,
                                                                    baseline=baseline))  # fmt: skip
    assert both.exit_status == 0 and both.gate.passed and "updated" in both.gate.message
    written = json.loads(baseline.read_text())["metrics"]
    one = run_bench("quick", ["oracle"], options(tmp_path, gate=GateAction.UPDATE, baseline=baseline))
    assert one.exit_status == 1 and not one.gate.passed and "--replace" in one.gate.message
    assert json.loads(baseline.read_text())["metrics"] == written  # untouched
    replaced = run_bench("quick", ["oracle"], options(tmp_path, gate=GateAction.REPLACE, baseline=baseline))
    assert replaced.exit_status == 0 and set(json.loads(baseline.read_text())["metrics"]) < set(written)
    compared = run_bench("quick", ["oracle"], options(tmp_path, baseline=baseline))
    assert compared.gate.report is not None and compared.gate.passed and compared.exit_status == 0


# ------------------------------------------------------------------------------- refused before any run (issue 60)
REPO = Path(__file__).resolve().parents[3]


def _user_methods(tmp_path: Path, monkeypatch, entries: dict[str, str]):
    """A method table with the user's ``entries`` (name -> "module:Class"); ``user_slam.py`` (class UserSlam) and
    ``user_needs_dep.py`` (imports a package that is not installed) on the path."""
    from eval.bench.methods import method_table

    (tmp_path / "user_slam.py").write_text("from sim_envs.agents import OracleAgent\n\n\nclass UserSlam(OracleAgent):\n"
                                           "    pass\n")  # fmt: skip
    (tmp_path / "user_needs_dep.py").write_text("import no_such_dependency_pkg\n\n\nclass Agent:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    methods = tmp_path / "methods.toml"
    methods.write_text("".join(f'[methods.{name}]\nentry_point = "{entry}"\n' for name, entry in entries.items()))
    return method_table(methods)


@pytest.mark.parametrize(("entry", "message"), [
    ("user_slam:UserSlma", r"module 'user_slam' has no 'UserSlma' .*did you mean 'user_slam:UserSlam'\?"),
    ("user_slma:UserSlam", "no module 'user_slma' to import"),
])
def test_a_method_whose_module_or_class_is_misspelt_is_refused_before_any_run(tmp_path, monkeypatch, entry, message):
    """A typo in one's own method file is bad input (exit 2 in the command), even with allow_skips: not a skip
    after the other methods ran."""
    table = _user_methods(tmp_path, monkeypatch, {"Mine": entry})
    for allow in (False, True):
        with pytest.raises(InputError, match=message):
            run_bench("table1", ["oracle", "Mine"], options(tmp_path, allow_skips=allow), table)
    assert run_folders(tmp_path) == [] and not (tmp_path / "results").exists()


@pytest.mark.slow  # > 5 s: a suite runs
def test_a_method_lacking_a_package_is_refused_when_named_and_skipped_when_the_suite_brings_it(tmp_path,
                                                                                               monkeypatch):
    """An optional third-party method whose package is not installed: named in ``methods``, refused before any run
    (unless allow_skips); in the suite's own selection, skipped with the reason (exit status 1)."""
    table = _user_methods(tmp_path, monkeypatch, {"Mine": "user_slam:UserSlam", "Needs": "user_needs_dep:Agent"})
    with pytest.raises(InputError, match=r"method 'Needs' cannot run here \(cannot import 'user_needs_dep': "
                                         r"ModuleNotFoundError: .*no_such_dependency_pkg.*--allow-skips"):
        run_bench("table1", ["Mine", "Needs"], options(tmp_path), table)
    assert run_folders(tmp_path) == []
    assert set(prepare("table1", ["Mine", "Needs"], options(tmp_path, allow_skips=True), table).methods) == \
        {"Mine", "Needs"}  # planned: the suite's check skips it with its reason
    from eval.bench.suites import get_suite

    suite = replace(get_suite("table1"), methods=("Mine", "Needs"))  # a suite that brings the optional method
    outcome = run_bench(suite, None, options(tmp_path), table)
    assert [(r.method, r.status) for r in outcome.runs] == [("Mine", "done")] and outcome.exit_status == 1
    assert [(s.name, "no_such_dependency_pkg" in s.reason) for s in outcome.skipped] == [("Needs", True)]


def test_a_built_in_optional_method_named_without_its_package_is_refused(tmp_path):
    import importlib.util

    if importlib.util.find_spec("open3d") is not None:
        pytest.skip("open3d is installed here, so Open3D-odometry can run: this checks a checkout without it")
    with pytest.raises(InputError, match="method 'Open3D-odometry' cannot run here .*open3d"):
        prepare("table1", ["oracle", "Open3D-odometry"], options(tmp_path))


def test_unwritable_outputs_are_refused_before_any_run(tmp_path):
    """A file where --results or --out should be a folder (and, for a user who cannot bypass permissions, a
    read-only folder): refused before any run, and the check leaves no folder behind."""
    import os

    afile = tmp_path / "afile"
    afile.write_text("not a folder\n")
    in_the_way = f"{afile} is a file, not a folder"
    for changes, message in ((dict(results=afile), f"--results {afile}: a file, not a folder"),
                             (dict(results=afile / "sub"), f"--results {afile / 'sub'}: {in_the_way}"),
                             (dict(out=afile / "runs"), f"--out {afile / 'runs'}: {in_the_way}")):  # fmt: skip
        with pytest.raises(InputError, match=message):
            run_bench("table1", ["oracle"], options(tmp_path, **changes))
        assert run_folders(tmp_path) == [] and not (tmp_path / "runs").exists() and afile.is_file()
    if os.geteuid() != 0:  # root writes into read-only folders
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        with pytest.raises(InputError, match=f"--results {locked / 'r'}: cannot write in"):
            run_bench("table1", ["oracle"], options(tmp_path, results=locked / "r"))
    plan = prepare("table1", ["oracle"], options(tmp_path, results=tmp_path / "deep" / "er"))
    assert plan.results_dir == tmp_path / "deep" / "er" and not (tmp_path / "deep").exists()  # tried, then removed


@pytest.mark.slow  # > 5 s: a suite runs
def test_report_only_needs_finished_runs_of_the_selection(tmp_path):
    with pytest.raises(InputError, match=f"--out {tmp_path / 'runs'}: no such folder"):
        run_bench("table1", ["oracle"], options(tmp_path, report_only=True))
    (tmp_path / "runs").mkdir()
    with pytest.raises(InputError, match="no finished run of suite table1 for this selection"):
        run_bench("table1", ["oracle"], options(tmp_path, report_only=True))
    assert not (tmp_path / "results").exists()
    assert run_bench("table1", ["oracle"], options(tmp_path)).exit_status == 0
    again = run_bench("table1", ["oracle"], options(tmp_path, report_only=True))
    assert again.exit_status == 0 and [r.status for r in again.runs] == ["cached"]
    with pytest.raises(InputError, match="no finished run of suite table1"):  # other frames: other runs
        run_bench("table1", ["oracle"], options(tmp_path, report_only=True, frames=8))


def test_the_committed_results_guard_compares_resolved_paths_from_any_folder(tmp_path, monkeypatch):
    """From a subfolder of the repository, ``--results ../results`` (or the committed folder's absolute path, or
    a folder below it) with a selection is the repository's results/ all the same: refused."""
    if not (REPO / "results").is_dir():
        pytest.skip("no committed results/ beside this eval package: run the tests in a clone of the repository")
    monkeypatch.chdir(REPO / "eval")
    for target in (Path("../results"), Path("../results/bench"), REPO / "results", Path("../eval/../results")):
        with pytest.raises(InputError, match="this selection is 1 of its 9 sequences .*leave --results out"):
            prepare("table1", ["oracle"], options(tmp_path, results=target))


@pytest.mark.parametrize(("changes", "message"), [
    (dict(frames=0), "--frames takes a number of frames >= 2 .*got 0"),
    (dict(frames=-5), "--frames takes a number of frames >= 2 .*got -5"),
    (dict(runs=0, seeds=None), r"--runs takes a number of runs per cell >= 1 .*got 0"),
    (dict(executor=ExecutorOptions(jobs=0)), "--jobs takes a number of runs in parallel >= 1, got 0"),
    (dict(executor=ExecutorOptions(jobs=-2)), "--jobs takes a number of runs in parallel >= 1, got -2"),
    (dict(executor=ExecutorOptions(timeout_s=-1)), "--timeout must be a number of seconds > 0, got -1"),
    (dict(executor=ExecutorOptions(timeout_s=0)), "--timeout must be a number of seconds > 0, got 0"),
])
def test_numbers_out_of_range_are_refused_before_any_run(tmp_path, changes, message):
    with pytest.raises(InputError, match=message):
        run_bench("table1", ["oracle"], options(tmp_path, **changes))
    assert run_folders(tmp_path) == [] and not (tmp_path / "results").exists()


def test_a_run_gets_a_default_time_limit_sized_from_the_longest_run(tmp_path):
    """No --timeout: TIMEOUT_PER_FRAME_S per frame of the longest run, at least TIMEOUT_MIN_S, given to the
    executor and quoted in the command the reports print; a given --timeout wins; a serial executor that cannot
    stop a run (called from another thread than the main one) has none."""
    from eval.bench.benchmark import TIMEOUT_MIN_S, TIMEOUT_PER_FRAME_S

    local = ExecutorOptions("local", jobs=1)
    short = prepare("table1", ["oracle"], options(tmp_path, executor=local))
    assert short.timeout_s == TIMEOUT_MIN_S and short.executor.timeout_s == TIMEOUT_MIN_S
    assert short.command.endswith(f" --timeout {TIMEOUT_MIN_S:g}")
    n = int(resolve_sequence("office0@kinect").spec().n_frames)
    whole = prepare("table1", ["oracle"], options(tmp_path, executor=local, frames="all"))
    assert whole.timeout_s == max(TIMEOUT_MIN_S, TIMEOUT_PER_FRAME_S * n) > TIMEOUT_MIN_S
    assert f"--timeout {whole.timeout_s:g}" in whole.command
    given = prepare("table1", ["oracle"], options(tmp_path, executor=ExecutorOptions("local", timeout_s=30)))
    assert given.timeout_s == 30 and given.executor.timeout_s == 30 and given.command.endswith(" --timeout 30")
    serial = prepare("table1", ["oracle"], options(tmp_path))  # stops a run with SIGALRM from the main thread
    assert serial.timeout_s == TIMEOUT_MIN_S and serial.executor.timeout_s == TIMEOUT_MIN_S
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1) as pool:  # another thread: no signal to stop a serial run with, so no default
        threaded = pool.submit(prepare, "table1", ["oracle"], options(tmp_path)).result()
    assert threaded.timeout_s is None and "--timeout" not in threaded.command


@pytest.mark.slow  # > 5 s: a suite runs
def test_an_external_methods_speed_is_its_own_run_time(tmp_path):
    """The speed table shows an external system's run.toml wall_s (frames / it per second), not the judge's
    scoring time."""
    from eval.bench.methods import method_table

    out = _external(tmp_path, slice(0, 60))
    (out / "office0" / "run.toml").write_text("wall_s = 1.5\n")
    table = method_table(externals=[f"Mine={out}"])
    outcome = run_bench("table1", ["Mine"], options(tmp_path, frames=60), table)
    assert outcome.exit_status == 0
    timing = json.loads(next((tmp_path / "runs").rglob("timing.json")).read_text())
    assert timing["wall_s"] == 1.5 and timing["fps_end_to_end"] == pytest.approx(40.0)
    assert timing["scoring_wall_s"] > 0 and timing["method_wall_s"] == 1.5
    speed = (tmp_path / "results" / "table1.md").read_text().split("## Speed and memory")[1]
    assert "| Mine | 1 | 60 | 1.5 | 40.0 |" in speed
