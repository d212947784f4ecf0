"""eval.reports.inputs: the benchmark's objects have every attribute the reports' protocols name (so a renamed field
of eval.bench fails here, not in a report halfway through a suite), and a machine description's one line."""

from dataclasses import fields

import pytest

from eval.bench import runner, suites
from eval.reports import inputs
from eval.reports.inputs import machine_label


def _members(protocol: type) -> set[str]:
    return {n for n in vars(protocol) if not n.startswith("_")}


def test_a_suite_run_of_the_benchmark_is_what_the_reports_read(folder_run):
    run = folder_run
    assert isinstance(run, runner.SuiteRun)  # the benchmark's own class, built as run_suite builds it
    assert isinstance(run, inputs.SuiteRun) and isinstance(run.suite, inputs.Suite)
    assert run.specs and all(isinstance(spec, inputs.RunSpec) for spec in run.specs)
    assert dict(run.suite.axis_titles) == dict(suites.SWEEP_AXES)


def test_the_parts_of_the_transfer_and_preprocessing_suites_are_what_their_reports_read():
    part = suites.TransferPart(None, suites.SUITES["table1"], (("office0", "sim"),))
    assert isinstance(part, inputs.TransferPart)
    assert suites.PREPROCESSING_CHOICES
    assert all(isinstance(c, inputs.PreprocessingChoice) for c in suites.PREPROCESSING_CHOICES)


@pytest.mark.parametrize("bench_class, protocol", [(runner.SuiteRun, inputs.SuiteRun), (suites.Suite, inputs.Suite),
                                                   (suites.TransferPart, inputs.TransferPart),
                                                   (suites.PreprocessingChoice, inputs.PreprocessingChoice)])
def test_each_protocol_names_only_what_its_class_has(bench_class, protocol):
    has = {f.name for f in fields(bench_class)} | {n for n in dir(bench_class) if not n.startswith("_")}
    assert _members(protocol) <= has, _members(protocol) - has


def test_machine_label_names_cpu_isa_and_versions():
    env = {"cpu": "AMD EPYC 7B13", "isa": ["avx2", "sse4_2"], "packages": {"torch": "2.13.0", "numpy": "2.4.6"}}
    assert machine_label(env) == "AMD EPYC 7B13 (avx2), torch 2.13.0, numpy 2.4.6"
    assert machine_label({}) == "? (-), torch -, numpy -"
    from eval.bench.environment import machine_label as kept

    assert kept is machine_label  # the benchmark's name for it still works
