"""eval.bench.benchmark: the benchmark as a library call. Bad input is refused before any run; a broken or partial
result is never reported as a whole, successful one (the rows of issue 40's table that the call decides)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from eval.bench import BenchOptions, ExecutorOptions, GateAction, run_bench
from eval.bench.benchmark import KINDS, prepare
from eval.bench.sequence_ref import resolve_sequence
from eval.bench.suites import SuiteKind
from eval.errors import InputError
from sim_envs.formats import write_tum_trajectory

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
    from sim_envs.datasets import write_folder
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
    pytest.importorskip("thirdparty.colmap_sfm")
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
    """10 of 60 frames: the cell says so, ``(10/60 frames)``, and the column gets no Avg.; the outcome's run too."""
    from eval.bench.methods import method_table

    table = method_table(externals=[f"Mine={_external(tmp_path, slice(0, 10))}"])
    outcome = run_bench("table1", ["Mine"], options(tmp_path, frames=60), table)
    assert outcome.exit_status == 0 and [r.coverage for r in outcome.runs] == [(10, 60)]
    md = (tmp_path / "results" / "table1.md").read_text()
    assert "| office0@kinect (ICL/office0) | 0.000 (10/60 frames) |" in md
    assert "| Avg. | - |" in md.split("## Abs. Trajectory Error")[1]
    csv = (tmp_path / "results" / "table1.csv").read_text().splitlines()
    assert csv[-1].startswith("Avg.,") and csv[-1].split(",")[1] == ""  # no average over part of a sequence


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
