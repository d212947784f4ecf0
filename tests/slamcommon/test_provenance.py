"""slamcommon.provenance: the import closure of a module follows its imports and nothing else; an output manifest
records the command, the code, the inputs' SHA-256 and the data folders, with paths beside the repository relative."""

from __future__ import annotations

import hashlib
import json
import sys

from slamcommon import provenance
from slamcommon.provenance import (
    REPOSITORY,
    TreeState,
    code_digest,
    import_closure,
    invoked_command,
    record_outputs,
    shown_path,
    write_output_manifest,
)


def test_the_closure_follows_imports_in_functions_and_relative_ones_and_leaves_the_rest(tmp_path, monkeypatch):
    root = tmp_path / "leafpkg"
    root.mkdir()
    (root / "__init__.py").write_text("")
    (root / "a.py").write_text("from . import b\n\n\ndef f():\n    import leafpkg.c\n")
    (root / "b.py").write_text("import numpy\n")
    (root / "c.py").write_text("")
    (root / "unused.py").write_text("")
    monkeypatch.syspath_prepend(str(tmp_path))
    packages = ("leafpkg",)
    assert set(import_closure(["leafpkg.a"], packages)) == {"leafpkg", "leafpkg.a", "leafpkg.b", "leafpkg.c"}
    before = code_digest(["leafpkg.a"], packages)
    (root / "unused.py").write_text("X = 1\n")
    assert code_digest(["leafpkg.a"], packages) == before
    (root / "c.py").write_text("X = 1\n")
    assert code_digest(["leafpkg.a"], packages) != before


def test_an_output_manifest_names_its_files_code_inputs_and_folders(tmp_path):
    weights = tmp_path / "w.bin"
    weights.write_bytes(b"weights")
    (tmp_path / "out.md").write_text("x")
    path = write_output_manifest(tmp_path, "out", [tmp_path / "out.md"], "cnnslam thing --x 1", ["slamcommon.se3"],
                                 [weights], {REPOSITORY / "data": "f" * 64}, TreeState("abc", ("a.py",)))  # fmt: skip
    data = json.loads(path.read_text())
    assert path.name == "out.provenance.json" and data["outputs"] == ["out.md"] and data["kind"] == "output"
    assert data["inputs"] == {str(weights.resolve()): hashlib.sha256(b"weights").hexdigest()}
    assert data["folders"] == {"data": "f" * 64} and data["dirty"] and data["dirty_listed"] == ["a.py"]
    assert data["code"]["modules"] == ["slamcommon.se3"] and data["code"]["sha256"] == code_digest(["slamcommon.se3"])
    assert shown_path(REPOSITORY.parent / "shared" / "x") == "../shared/x"


def test_the_command_recorded_is_the_one_typed(tmp_path, monkeypatch):
    assert invoked_command("cnnslam map", ["/venv/bin/cnnslam", "map", "office0", "--figure", "a b.png"]) == (
        "cnnslam map office0 --figure 'a b.png'")
    monkeypatch.setattr(sys.modules["__main__"], "__spec__", None, raising=False)
    assert invoked_command("cnnslam contact-sheet", ["/x/pytest", "-q"]) == "cnnslam contact-sheet"
    monkeypatch.setattr(provenance, "tree_state", lambda root=None: TreeState("abc"))
    (tmp_path / "sheet.png").write_bytes(b"")
    (paths := record_outputs([tmp_path / "sheet.png", tmp_path / "not_drawn.png"], "cnnslam contact-sheet",
                             ["slamcommon.se3"]))  # fmt: skip
    assert [p.name for p in paths] == ["sheet.provenance.json"]
    assert json.loads(paths[0].read_text())["outputs"] == ["sheet.png"]
