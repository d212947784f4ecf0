"""eval.bench.plan: the benchmark's options and its checks before any run (prepare plans, runs nothing)."""

import pytest

from eval.bench import benchmark, plan
from eval.bench.plan import BenchOptions, ExecutorOptions, prepare
from eval.bench.suites import SuiteKind
from eval.errors import InputError


def _options(tmp_path, **changes) -> BenchOptions:
    base = {"sequences": ("office0",), "frames": 4, "runs": 1, "out": tmp_path / "runs", "results": tmp_path / "rep",
            "executor": ExecutorOptions("serial", 1), "progress": False, "plots": False}
    return BenchOptions(**{**base, **changes})


def test_prepare_plans_the_selection_and_writes_nothing(tmp_path):
    planned = prepare("table1", ["oracle"], _options(tmp_path))
    assert planned.suite.name == "table1"
    assert [s.name for s in planned.suite.sequences] == ["office0@kinect"]  # table1's camera: kinect
    assert [p.label for p in planned.parts] == ["table1"] and list(planned.methods) == ["oracle"]
    assert planned.suite.frames == 4 and planned.results_dir == tmp_path / "rep"
    assert planned.command.startswith("cnnslam bench table1 --frames 4")
    assert planned.timeout_s == plan.TIMEOUT_MIN_S  # 4 frames: the floor of the default time limit
    assert not (tmp_path / "runs").exists() and not (tmp_path / "rep").exists()


@pytest.mark.parametrize("changes, message", [({"frames": 1}, "--frames"), ({"runs": 0}, "--runs"),
                                              ({"figure_format": "gif"}, "figure format"),
                                              ({"lengths": (10,)}, "--lengths")])
def test_bad_options_are_one_line_before_anything(tmp_path, changes, message):
    with pytest.raises(InputError, match=message) as err:
        prepare("table1", ["oracle"], _options(tmp_path, **changes))
    assert "\n" not in str(err.value)


def test_every_kind_of_suite_with_parts_has_its_report_writer():
    assert set(plan.KINDS) == set(SuiteKind) - {SuiteKind.PERF}
    assert all(callable(k.parts) and callable(k.report) for k in plan.KINDS.values())


def test_the_benchmark_keeps_the_names_that_moved_here():
    """``from eval.bench.benchmark import BenchOptions, prepare, KINDS`` (and ``from eval.bench import ...``) still
    give these very objects."""
    import eval.bench as bench

    for name in ("BenchOptions", "ExecutorOptions", "BenchPlan", "Part", "KindSpec", "KINDS", "Skip", "prepare",
                 "check_writable", "command_line", "COMMITTED_RESULTS", "TIMEOUT_PER_FRAME_S", "DEFAULT_JOBS"):
        assert getattr(benchmark, name) is getattr(plan, name), name
    assert bench.BenchOptions is plan.BenchOptions and bench.prepare is plan.prepare


def test_a_committed_variant_is_remade_in_its_folder_by_its_own_command_only(tmp_path, monkeypatch):
    committed = tmp_path / "results"
    monkeypatch.setattr(plan, "COMMITTED_RESULTS", committed.resolve())
    variant = committed / "camera_clean"
    variant.mkdir(parents=True)
    options = _options(tmp_path, results=variant, command="cnnslam bench table1 --frames 4 --sequences office0")
    with pytest.raises(InputError, match="the committed results hold suite table1 as defined"):
        prepare("table1", ["oracle"], options)  # an empty folder below results/: refused
    (variant / "table1.md").write_text("Made by `cnnslam bench table1 --frames 4 --sequences office0`: ...\n")
    assert prepare("table1", ["oracle"], options).results_dir == variant
    other = _options(tmp_path, results=variant, command="cnnslam bench table1 --frames 8 --sequences office0")
    with pytest.raises(InputError, match="the committed results hold suite table1 as defined"):
        prepare("table1", ["oracle"], other)  # another selection would overwrite the variant with part of it
    with pytest.raises(InputError, match="the committed results hold suite table1 as defined"):
        prepare("table1", ["oracle"], _options(tmp_path, results=committed, command=options.command))
    (variant / "table1.md").unlink()
    (variant / "table1.provenance.json").write_text(
        '{"command": "cnnslam bench table1 --frames 4 --sequences office0 --timeout 900"}')
    assert plan.made_here(variant, "table1", options.command)
    assert prepare("table1", ["oracle"], options).results_dir == variant
