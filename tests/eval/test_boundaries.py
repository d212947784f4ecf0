"""The judge never imports the agent package (CONTRIBUTING: agents are named by "module:Class" strings).

The import arrow is also an import-linter contract (pyproject.toml's ``flow``: eval, cnnslam and thirdparty
independent; run by ``lint-imports`` in ``make lint`` and by tests/test_layering.py); this file keeps its quick check
beside what import-linter cannot see: an agent module named in a string, and argparse outside the command lines."""

import ast
import pathlib

import eval

EVAL_ROOT = pathlib.Path(eval.__file__).parent


def imported_modules(path: pathlib.Path) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_eval_never_imports_cnnslam():
    files = sorted(EVAL_ROOT.rglob("*.py"))
    assert len(files) > 10
    offenders = {
        str(p.relative_to(EVAL_ROOT)): sorted(m for m in imported_modules(p) if m.split(".")[0] == "cnnslam")
        for p in files
    }
    assert {k: v for k, v in offenders.items() if v} == {}
    # and not through a string either (importlib.import_module("cnnslam..."))
    assert [p.name for p in files if '"cnnslam.' in p.read_text() or "'cnnslam." in p.read_text()] == []


def test_argparse_only_in_command_lines():
    users = [p.name for p in EVAL_ROOT.rglob("*.py") if "argparse" in imported_modules(p)]
    assert all(name.startswith("cli_") for name in users) and users
