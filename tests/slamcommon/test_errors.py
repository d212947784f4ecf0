"""slamcommon.errors: one exception base for the whole project; every package's errors derive from it."""

from __future__ import annotations

import ast
import importlib
import pathlib

from slamcommon.errors import ConfigError, MetricError, ProjectError

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_the_package_bases_share_one_root():
    from cnnslam.errors import CnnSlamError
    from eval.errors import BrokenRunError, EvalError, InputError, RunnerError, SuiteError
    from sim_envs.errors import SimEnvError

    for base in (CnnSlamError, EvalError, SimEnvError, MetricError, ConfigError):
        assert issubclass(base, ProjectError) and issubclass(base, ValueError)
    assert issubclass(SuiteError, InputError) and not issubclass(RunnerError, InputError)
    assert issubclass(BrokenRunError, EvalError)


def test_every_exception_class_of_the_project_derives_from_the_root():
    """Every class named ...Error defined in the project's packages is a ProjectError."""
    outside = []
    for package in ("slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty"):
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text())
            names = [n.name for n in tree.body if isinstance(n, ast.ClassDef) and n.name.endswith("Error")]
            if not names:
                continue
            module = importlib.import_module(".".join(path.relative_to(ROOT).with_suffix("").parts))
            outside += [f"{module.__name__}.{n}" for n in names if not issubclass(getattr(module, n), ProjectError)]
    assert outside == []
