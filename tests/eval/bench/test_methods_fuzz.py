"""Property-based tests of the method readers of :mod:`eval.bench.methods` (``fuzz_reader``: tests/conftest.py): a
method table (``--method-file``, :func:`load_methods`) and an external system's ``method.toml``
(:func:`external_method`). Mutated valid files give methods, or one :class:`MethodError` line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from eval.bench.methods import Method, external_method, load_methods

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

METHOD_TABLE_SEEDS = (
    '[methods."CNN-SLAM"]\nentry_point = "cnnslam.agent:CnnSlamAgent"\nkwargs = { preset = "cnn_slam", threads = '
    'false }\nseed = ["config.system.seed", "predictor_options.jitter_seed"]\nmetrics = ["trajectory", "depth"]\n'
    'description = "CNN-SLAM"\ncost = 30\n\n[methods.mine]\nentry_point = "my.module:Agent"\nseed = "seed"\n'
    'align = "sim3"\nsensor = "rgbd"\n',
    '# a third-party system\n[methods.orb]\nkind = "external"\nfolder = "out/orb"\nmetrics = ["trajectory"]\n'
    'uses_ground_truth = ["scale"]\npreload = ["torch"]\ninputs = ["weights.pt"]\npaper = "ORB-SLAM"\n',
)
EXTERNAL_SEEDS = (
    'sensor = "rgbd"\nuses_ground_truth = ["depth"]\nalign = "sim3"\ndescription = "ORB-SLAM3 RGB-D"\n',
    '# what the system is\nsensor = "mono"\n',
)


def _check_methods(methods: dict[str, Method]) -> None:
    assert methods and all(isinstance(m, Method) and m.name == name for name, m in methods.items())


def test_method_table_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(tmp_path / "my_methods.toml", METHOD_TABLE_SEEDS, load_methods, _check_methods)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)


def _check_external(method: Method) -> None:
    assert isinstance(method, Method) and method.kind == "external" and method.name == "orb"
    assert isinstance(method.description, str)


def test_external_method_file_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    report = fuzz_reader(tmp_path / "method.toml", EXTERNAL_SEEDS, lambda p: external_method("orb", p.parent),
                         _check_external)  # fmt: skip
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
