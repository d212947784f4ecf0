"""The layering as import-linter contracts (pyproject.toml's ``[tool.importlinter]``; ``make lint`` runs
``lint-imports``): every contract kept, none excused, every package and every part of eval placed."""

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty"}


def _config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]


def test_the_contracts_hold():
    """No arrow up and no circle: what lint-imports reports, run here on the working tree."""
    pytest.importorskip("importlinter", reason="import-linter is in the dev extra: pip install -c constraints.txt "
                                               "-e '.[dev]'")  # fmt: skip
    code = "import sys; from importlinter.cli import lint_imports; sys.exit(lint_imports(no_cache=True, no_logo=True))"
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


def test_no_contract_is_excused_and_every_package_is_covered():
    config = _config()
    contracts = config["contracts"]
    assert set(config["root_packages"]) == PACKAGES == {p.parent.name for p in ROOT.glob("*/__init__.py")} - {"tests"}
    assert not [c["id"] for c in contracts if "ignore_imports" in c or "unmatched_ignore_imports_alerting" in c]
    by_id = {c["id"]: c for c in contracts}
    assert set(by_id["acyclic"]["ancestors"]) == PACKAGES and by_id["acyclic"]["type"] == "acyclic_siblings"
    assert by_id["flow"]["layers"] == ["eval | cnnslam | thirdparty", "sim_envs", "slamcommon"]
    inside = by_id["eval"]
    assert inside["exhaustive"] and inside["containers"] == ["eval"]
    children = {p.stem for p in (ROOT / "eval").glob("*.py") if p.stem != "__init__"}
    children |= {p.parent.name for p in (ROOT / "eval").glob("*/__init__.py")}
    assert set(inside["layers"]) == children  # a new part of eval has to be given its place
