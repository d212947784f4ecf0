"""The import graph reads world -> agent -> judge, with the shared concepts as a leaf below all three.

The arrows are also import-linter contracts (pyproject.toml's ``leaf`` and ``flow``, run by ``lint-imports`` in
``make lint`` and by tests/test_layering.py), which see every import the same way; this file keeps its own quick check
of them beside what no contract says: each shared concept defined once."""

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def imported_packages(package: str) -> dict[str, set[str]]:
    """{file: top-level packages it imports} for every module of ``package``."""
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        names = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module.split(".")[0])
        out[str(path.relative_to(ROOT))] = names
    return out


@pytest.mark.parametrize(("package", "forbidden"), [
    ("slamcommon", {"sim_envs", "cnnslam", "eval", "thirdparty"}),  # the leaf
    ("sim_envs", {"cnnslam", "eval", "thirdparty"}),  # the world knows nothing of SLAM or its judge
    ("cnnslam", {"eval"}),  # the agent never imports the judge
    ("thirdparty", {"eval"}),  # nor do the third-party systems plugged in as agents
])
def test_no_arrow_goes_back(package, forbidden):
    found = imported_packages(package)
    assert len(found) >= 4
    assert {f: sorted(names & forbidden) for f, names in found.items() if names & forbidden} == {}


def test_each_shared_concept_is_defined_once():
    """se3_inverse, relative_pose, look_at, DepthMetrics, SemanticMetrics, confusion_matrix, NO_LABEL and
    peak_resident_mib have one definition in the tree (re-exports are imports, not definitions)."""
    names = {"se3_inverse", "relative_pose", "relative_se3", "look_at", "DepthMetrics", "SemanticMetrics",
             "confusion_matrix", "NO_LABEL", "NUM_CLASSES", "SemanticClass", "peak_resident_mib"}
    where: dict[str, list[str]] = {n: [] for n in names}
    for package in ("slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty"):
        for path in (ROOT / package).rglob("*.py"):
            tree = ast.parse(path.read_text(), filename=str(path))
            for node in tree.body:
                targets = []
                if isinstance(node, ast.FunctionDef | ast.ClassDef):
                    targets = [node.name]
                elif isinstance(node, ast.Assign):
                    targets = [t.id for t in node.targets if isinstance(t, ast.Name)]
                elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                    targets = [node.target.id]
                for t in targets:
                    if t in where:
                        where[t].append(str(path.relative_to(ROOT)))
    assert {n: places for n, places in where.items() if len(places) > 1} == {}
