"""Where an output file of the project came from: the source files of a module's import closure as a digest, the
state of the git checkout, and the provenance manifest a command writes beside what it makes.

The closure of a module (:func:`import_closure`) follows, within the packages named (default
:data:`PROJECT_PACKAGES`), every ``import`` and ``from ... import`` statement of its file, including those inside
functions, the packages' ``__init__`` files that importing a module runs, and ``importlib.import_module("literal")``
calls; it never imports anything (files are located from the top-level packages' folders and parsed with
:mod:`ast`). Modules outside those packages (numpy, torch, ...) are not followed. Parsed files and closures are
cached per process by each file's size and modification time.

An output manifest (:func:`write_output_manifest`), ``<folder>/<name>.provenance.json``, records the command line
that made the files it lists (``outputs``, names relative to its folder), the folder it ran in, the git revision and
whether tracked files outside ``results/`` had uncommitted changes, and what decides the files' content: the
SHA-256 of the import closure of the command's modules (``code``), the SHA-256 of its input files (``inputs``, e.g.
network weights) and the content fingerprints of the data folders it read (``folders``). ``cnnslam results status``
recomputes each and calls the files current while all are equal and the tree was clean.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import shlex
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

SCHEMA = "cnnslam-provenance/1"
MANIFEST_SUFFIX = ".provenance.json"
OUTPUT_KIND = "output"  # a manifest of files one command wrote (a suite's manifest has kind "suite")
REPOSITORY = Path(__file__).resolve().parents[1]
# the packages whose files a closure follows (and hashes); modules of any other package are left out
PROJECT_PACKAGES: tuple[str, ...] = ("cnnslam", "sim_envs", "slamcommon", "thirdparty", "eval")
WALL_S = "wall_s"  # the key of a command's wall-clock seconds: in a manifest, a perf probe, a tool's figures
DIRTY_LISTED = 5  # uncommitted files named in a manifest (the count is always given)

_Stamp = tuple[int, int]
_PARSED: dict[tuple[str, _Stamp], tuple[str, ...]] = {}
_CLOSURES: dict[tuple[str, tuple[str, ...]], tuple[dict[str, Path], tuple[tuple[str, _Stamp], ...]]] = {}
_DIGESTS: dict[tuple[str, _Stamp], str] = {}
_ROOTS: dict[tuple[str, tuple[str, ...]], Path | None] = {}


def _stamp(path: Path | str) -> _Stamp:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


# ----------------------------------------------------------------------------------------------- import closure
def package_root(top: str) -> Path | None:
    """The folder of top-level package ``top`` (found with :func:`importlib.util.find_spec`, which does not import
    it), or None when it is no package here. Cached per process and Python path."""
    key = (top, tuple(sys.path))
    if key not in _ROOTS:
        try:
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            spec = None
        roots = list(spec.submodule_search_locations or []) if spec is not None else []
        _ROOTS[key] = Path(roots[0]) if roots else None
    return _ROOTS[key]


def module_file(module: str, packages: Sequence[str] = PROJECT_PACKAGES) -> Path | None:
    """The source file of ``module`` (``a/b.py`` or ``a/b/__init__.py`` below its top-level package's folder) when
    its top-level package is one of ``packages``; None otherwise or when there is no such file."""
    top, *rest = module.split(".")
    if top not in packages:
        return None
    root = package_root(top)
    if root is None:
        return None
    base = root.joinpath(*rest)
    for path in (base.with_suffix(".py") if rest else None, base / "__init__.py"):
        if path is not None and path.is_file():
            return path
    return None


def _resolve_relative(module: str, is_package: bool, level: int, name: str | None) -> str:
    """The absolute module of a relative import ``from .name import x`` (``level`` dots) in ``module``."""
    parts = module.split(".")
    base = parts if is_package else parts[:-1]
    base = base[: len(base) - (level - 1)] if level > 1 else base
    return ".".join([*base, name] if name else base)


def imported_modules(path: Path, module: str) -> tuple[str, ...]:
    """Every module name the file ``path`` (module ``module``) may import: ``import a.b``, ``from a import b`` (both
    ``a`` and ``a.b``, which may be a submodule), relative imports resolved, and ``importlib.import_module("a.b")``
    with a literal name; statements inside functions and classes included. Cached by the file's size and time."""
    key = (str(path), _stamp(path))
    if key in _PARSED:
        return _PARSED[key]
    tree = ast.parse(path.read_bytes(), filename=str(path))
    is_package = path.name == "__init__.py"
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = _resolve_relative(module, is_package, node.level, node.module)
            names.append(base)
            names += [f"{base}.{alias.name}" for alias in node.names if alias.name != "*"]
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str) and _called_name(node.func) == "import_module"):
            names.append(node.args[0].value)
    out = tuple(dict.fromkeys(n for n in names if n))
    _PARSED[key] = out
    return out


def _called_name(func: ast.expr) -> str | None:
    if isinstance(func, ast.Attribute):
        return func.attr
    if isinstance(func, ast.Name):
        return func.id
    return None


def _parents(module: str) -> list[str]:
    """The packages importing ``module`` runs first: ``a``, ``a.b`` for ``a.b.c``."""
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def import_closure(modules: Iterable[str], packages: Sequence[str] = PROJECT_PACKAGES) -> dict[str, Path]:
    """``{module: file}`` of ``modules`` and everything they import, transitively, within ``packages`` (module
    docstring); names that are no module file of those packages (a class imported by ``from a import Class``, a
    third-party module) are left out. Cached per process and checked against the files' sizes and times."""
    packages = tuple(packages)
    roots = tuple(sorted(set(modules)))
    key = (",".join(roots), tuple(f"{p}={package_root(p)}" for p in packages))
    cached = _CLOSURES.get(key)
    if cached is not None:
        files, stamps = cached
        try:
            if all(_stamp(p) == s for p, s in stamps):
                return dict(files)
        except OSError:
            pass
    found: dict[str, Path] = {}
    todo = list(roots)
    while todo:
        name = todo.pop()
        if name in found:
            continue
        path = module_file(name, packages)
        if path is None:
            continue
        found[name] = path
        todo += _parents(name)
        todo += [m for m in imported_modules(path, name) if m.split(".")[0] in packages and m not in found]
    _CLOSURES[key] = (dict(found), tuple((str(p), _stamp(p)) for p in found.values()))
    return found


def file_sha256(path: Path | str) -> str:
    """SHA-256 of a file's bytes, cached per process by (path, size, modification time)."""
    key = (str(path), _stamp(path))
    if key not in _DIGESTS:
        _DIGESTS[key] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
    return _DIGESTS[key]


def files_digest(files: Mapping[str, Path]) -> str:
    """SHA-256 over ``files`` (module -> file), by module name and content, in sorted order."""
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + file_sha256(files[name]).encode() + b"\n")
    return digest.hexdigest()


def closure_sha256(module: str, packages: Sequence[str] = PROJECT_PACKAGES) -> str | None:
    """SHA-256 of the import closure of ``module`` (:func:`import_closure`), None when ``module`` is no module file
    of ``packages``."""
    files = import_closure([module], packages)
    return files_digest(files) if module in files else None


def code_digest(modules: Sequence[str], packages: Sequence[str] = PROJECT_PACKAGES) -> str:
    """SHA-256 of the import closure of all of ``modules`` together (what a command that imports them runs)."""
    return files_digest(import_closure(modules, packages))


# ------------------------------------------------------------------------------------------------ the checkout
@dataclass(frozen=True)
class TreeState:
    """The repository's ``revision`` (12 hex digits; None outside a git checkout) and the tracked files with
    uncommitted changes outside ``results/`` (``dirty``)."""

    revision: str | None
    dirty: tuple[str, ...] = ()


def tree_state(root: Path = REPOSITORY) -> TreeState:
    """The revision of the checkout at ``root`` and its tracked files changed and not committed (results excluded:
    a command rewrites them before its manifest is written)."""
    def git(*args: str) -> str | None:
        try:
            out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=30, check=True)
        except (OSError, subprocess.SubprocessError):
            return None
        return out.stdout

    head = git("rev-parse", "--short=12", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no") or ""
    dirty = sorted({line[3:].split(" -> ")[-1] for line in status.splitlines() if len(line) > 3})
    return TreeState(head.strip() if head else None, tuple(p for p in dirty if not p.startswith("results/")))


def shown_path(path: str | Path, root: Path = REPOSITORY) -> str:
    """``path`` relative to the repository when it lies in the repository or in the shared data beside it
    (``../shared/...``), so that a manifest names no machine's folder; else absolute."""
    resolved = Path(path).resolve()
    base = root.resolve()
    shared = (base.parent / "shared").resolve()  # a copy, or a link to one
    if resolved == base or base in resolved.parents:
        return Path(os.path.relpath(resolved, base)).as_posix()
    if resolved == shared or shared in resolved.parents:
        return (Path("..") / "shared" / resolved.relative_to(shared)).as_posix()
    return str(resolved)


def found_path(text: str, root: Path = REPOSITORY) -> Path:
    """The path a manifest names (:func:`shown_path`), relative ones read from the repository."""
    path = Path(text)
    return path if path.is_absolute() else root / path


def invoked_command(prog: str, argv: Sequence[str] | None = None) -> str:
    """The command line that is running, as a person types it: ``cnnslam ...`` when run through the ``cnnslam``
    command, ``python -m MODULE ...`` when run as a module of the project, else (called from other Python code,
    whose arguments are not the command's) ``prog`` alone. ``argv`` default: ``sys.argv``."""
    argv = list(sys.argv if argv is None else argv)
    head, args = (argv[0], argv[1:]) if argv else ("", [])
    if Path(head).name == "cnnslam":
        return shlex.join(["cnnslam", *args])
    main = sys.modules.get("__main__")
    spec = getattr(main, "__spec__", None)
    if spec is not None and spec.name and spec.name.split(".")[0] in PROJECT_PACKAGES:
        return shlex.join(["python", "-m", spec.name, *args])
    return prog


# ------------------------------------------------------------------------------------------------ the manifest
def manifest_path(folder: str | Path, name: str) -> Path:
    """Where the manifest of output ``name`` in ``folder`` goes."""
    return Path(folder) / f"{name}{MANIFEST_SUFFIX}"


def output_manifest(name: str, outputs: Sequence[str], command: str, modules: Sequence[str],
                    inputs: Sequence[str | Path] = (), folders: Mapping[str | Path, str] | None = None,
                    state: TreeState | None = None, cwd: str | Path | None = None,
                    seconds: float | None = None, packages: Sequence[str] = PROJECT_PACKAGES) -> dict[str, Any]:
    """The manifest (module docstring) of the files ``outputs`` (names relative to the manifest's folder) made by
    ``command`` run in ``cwd`` (default: the working folder), whose code is the import closure of ``modules``,
    reading the files ``inputs`` and the data folders ``folders`` (path -> content fingerprint); ``seconds``: how
    long the command took, when known, kept under :data:`WALL_S` (what ``cnnslam results make --dry-run`` estimates
    from)."""
    state = tree_state() if state is None else state
    return {
        "schema": SCHEMA,
        "kind": OUTPUT_KIND,
        "name": name,
        "outputs": sorted(set(outputs)),
        "command": command,
        "cwd": shown_path(Path.cwd() if cwd is None else cwd),
        "git_revision": state.revision,
        "dirty": bool(state.dirty),
        "dirty_files": len(state.dirty),
        "dirty_listed": list(state.dirty[:DIRTY_LISTED]),
        "code": {"modules": sorted(set(modules)), "packages": list(packages),
                 "sha256": code_digest(list(modules), packages)},
        "inputs": {shown_path(p): file_sha256(Path(p).resolve()) for p in inputs},
        "folders": {shown_path(p): str(f) for p, f in (folders or {}).items()},
        WALL_S: None if seconds is None else round(float(seconds), 1),
    }


def write_output_manifest(folder: str | Path, name: str, outputs: Sequence[str | Path], command: str,
                          modules: Sequence[str], inputs: Sequence[str | Path] = (),
                          folders: Mapping[str | Path, str] | None = None, state: TreeState | None = None,
                          seconds: float | None = None) -> Path:
    """Write ``<folder>/<name>.provenance.json`` (:func:`output_manifest`; ``outputs`` are files in ``folder``,
    given by path or name); returns its path."""
    folder = Path(folder)
    names = [Path(p).name if Path(p).parent in (Path("."), folder) else os.path.relpath(p, folder) for p in outputs]
    data = output_manifest(name, names, command, modules, inputs, folders, state, seconds=seconds)
    path = manifest_path(folder, name)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    return path


def record_outputs(outputs: Sequence[str | Path], prog: str, modules: Sequence[str],
                   inputs: Sequence[str | Path] = (), folders: Mapping[str | Path, str] | None = None,
                   seconds: float | None = None) -> list[Path]:
    """Write the manifest of files a command just wrote (:func:`write_output_manifest`): one per folder of
    ``outputs``, named after the first output there (``results/depthnet.json`` -> ``results/depthnet.provenance.json``),
    recording the running command (:func:`invoked_command`, ``prog`` when it is not run from a command line) and
    the inputs (files), data ``folders`` (path -> content fingerprint) and ``modules`` whose import closure decides
    the files; returns the manifests' paths. Outputs that do not exist (a figure not drawn) are left out."""
    by_folder: dict[Path, list[Path]] = {}
    for path in map(Path, outputs):
        if path.exists():
            by_folder.setdefault(path.parent, []).append(path)
    command = invoked_command(prog)
    return [write_output_manifest(folder, files[0].name.split(".")[0], files, command, modules, inputs, folders,
                                  seconds=seconds)
            for folder, files in by_folder.items()]  # fmt: skip
