"""What a run's figures depend on, as digests: the source files each part of a run really executes, found by the
import statements of its modules (a static import closure), and the run's configuration.

A run's fingerprint (:meth:`eval.bench.run.RunSpec.fingerprint`) is the SHA-256 of its parts (:func:`run_parts`):

- ``agent``: the method's own code: the import closure of its entry point's module (and of every ``"module:Class"``
  string among its keyword arguments: a wrapping agent names the agent it wraps), less the files counted as world or
  judge below (so an edit to the camera model is reported as the world's, once);
- ``world``: the frame source's code: the closure of the environment and episode loop (:data:`WORLD_ROOTS`) and of
  the sequence's source (:func:`world_roots`: a simulated sequence's renderer and scene generator, a variant's, a
  folder's reader), kept to the world's package (``sim_envs``);
- ``judge``: the metric code: the closure of the ``eval.metrics`` modules :mod:`eval.bench.run` imports, kept to
  ``eval/metrics`` and ``slamcommon``;
- ``weights``: the SHA-256 of the method's input files (:meth:`eval.bench.methods.Method.input_hashes`);
- ``config``: the method's and sequence's definitions, seed, frames, alignment, renderer.

The closure of a module (:func:`import_closure`) follows, within the project's packages (:data:`PROJECT_PACKAGES`),
every ``import`` and ``from ... import`` statement of its file, including those inside functions, the packages'
``__init__`` files that importing a module runs, and ``importlib.import_module("literal")`` calls; it never imports
anything (files are located from the top-level packages' folders and parsed with :mod:`ast`). Modules outside the
project's packages (numpy, torch, ...) are not followed: their versions are the machine's (a run's ``timing.json``
names them). Parsed files and closures are cached per process by each file's size and modification time, so a suite
of hundreds of runs parses each file once.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# the packages whose files a closure follows (and hashes); modules of any other package are left out
PROJECT_PACKAGES: tuple[str, ...] = ("cnnslam", "sim_envs", "slamcommon", "thirdparty", "eval")
WORLD_PACKAGES: tuple[str, ...] = ("sim_envs",)
JUDGE_PREFIXES: tuple[str, ...] = ("eval.metrics", "slamcommon")
# the world every run of an agent goes through: the environments and the episode loop
WORLD_ROOTS: tuple[str, ...] = ("sim_envs.env", "sim_envs.driver")
RUN_MODULE = "eval.bench.run"  # whose eval.metrics imports are the judge's roots
PARTS: tuple[str, ...] = ("agent", "world", "judge", "weights", "config")

_Stamp = tuple[int, int]
_PARSED: dict[tuple[str, _Stamp], tuple[str, ...]] = {}
_CLOSURES: dict[tuple[str, tuple[str, ...]], tuple[dict[str, Path], tuple[tuple[str, _Stamp], ...]]] = {}
_DIGESTS: dict[tuple[str, _Stamp], str] = {}
_ROOTS: dict[tuple[str, tuple[str, ...]], Path | None] = {}


def _stamp(path: Path | str) -> _Stamp:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def project_packages() -> tuple[str, ...]:
    """The packages closures follow now (:data:`PROJECT_PACKAGES`, read at each call so a test may add one)."""
    return tuple(PROJECT_PACKAGES)


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


def module_file(module: str, packages: Sequence[str] | None = None) -> Path | None:
    """The source file of ``module`` (``a/b.py`` or ``a/b/__init__.py`` below its top-level package's folder) when
    its top-level package is one of ``packages``; None otherwise or when there is no such file."""
    packages = project_packages() if packages is None else tuple(packages)
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


def import_closure(modules: Iterable[str], packages: Sequence[str] | None = None) -> dict[str, Path]:
    """``{module: file}`` of ``modules`` and everything they import, transitively, within ``packages`` (module
    docstring); names that are no module file of those packages (a class imported by ``from a import Class``, a
    third-party module) are left out. Cached per process and checked against the files' sizes and times."""
    packages = project_packages() if packages is None else tuple(packages)
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


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes, cached per process by (path, size, modification time)."""
    key = (str(path), _stamp(path))
    if key not in _DIGESTS:
        _DIGESTS[key] = hashlib.sha256(path.read_bytes()).hexdigest()
    return _DIGESTS[key]


def files_digest(files: dict[str, Path]) -> str:
    """SHA-256 over ``files`` (module -> file), by module name and content, in sorted order."""
    digest = hashlib.sha256()
    for name in sorted(files):
        digest.update(name.encode() + b"\0" + file_sha256(files[name]).encode() + b"\n")
    return digest.hexdigest()


def closure_sha256(module: str, packages: Sequence[str] | None = None) -> str | None:
    """SHA-256 of the import closure of ``module`` (:func:`import_closure`), None when ``module`` is no module file
    of ``packages``."""
    files = import_closure([module], packages)
    return files_digest(files) if module in files else None


def _within(files: dict[str, Path], prefixes: Sequence[str]) -> dict[str, Path]:
    return {m: p for m, p in files.items() if any(m == x or m.startswith(x + ".") for x in prefixes)}


def judge_files(packages: Sequence[str] | None = None) -> dict[str, Path]:
    """The judge's metric code: the closure of the ``eval.metrics`` modules :data:`RUN_MODULE` imports, kept to
    :data:`JUDGE_PREFIXES`."""
    run_file = module_file(RUN_MODULE, packages)
    if run_file is None:
        return {}
    roots = [m for m in imported_modules(run_file, RUN_MODULE) if m.startswith("eval.metrics.")]
    return _within(import_closure(roots, packages), JUDGE_PREFIXES)


def world_roots(sequence: Any) -> tuple[str, ...]:
    """The world modules a run of ``sequence`` (a :class:`~eval.bench.sequence_ref.SequenceRef`) goes through:
    :data:`WORLD_ROOTS` and its source's module (a folder's reader; a simulated sequence's renderer and scene, a
    variant's, the frame cache; a window's)."""
    roots = list(WORLD_ROOTS)
    if getattr(sequence, "folder", None) is not None:
        roots.append("sim_envs.datasets")
    else:
        roots += ["sim_envs.simsource", "sim_envs.frame_cache"]
        if getattr(sequence, "focal_ratio", None) is not None or getattr(sequence, "added_pan_deg_s", 0.0):
            roots.append("sim_envs.variants")
    if getattr(sequence, "start", 0):
        roots.append("sim_envs.source")
    return tuple(roots)


def world_files(sequence: Any, packages: Sequence[str] | None = None) -> dict[str, Path]:
    """The world's code a run of ``sequence`` goes through (:func:`world_roots`), kept to :data:`WORLD_PACKAGES`."""
    return _within(import_closure(world_roots(sequence), packages), WORLD_PACKAGES)


def agent_modules(method: Any) -> list[str]:
    """The modules a method's agent is built from: its entry point's and those of the ``"module:Class"`` strings
    among its keyword arguments (none for an external method)."""
    if getattr(method, "kind", "agent") != "agent" or not method.entry_point:
        return []
    names = [method.entry_point, *(v for _, v in method.kwargs if isinstance(v, str) and _is_entry(v))]
    return list(dict.fromkeys(n.partition(":")[0] for n in names))


def _is_entry(text: str) -> bool:
    module, sep, attr = text.partition(":")
    return bool(sep) and attr.isidentifier() and all(p.isidentifier() for p in module.split("."))


def agent_files(method: Any, packages: Sequence[str] | None = None) -> dict[str, Path]:
    """The import closure of the method's agent (:func:`agent_modules`) within ``packages``."""
    modules = agent_modules(method)
    return import_closure(modules, packages) if modules else {}


@dataclass(frozen=True)
class RunParts:
    """The digests of what a run's figures depend on (module docstring), part name -> SHA-256 hex."""

    digests: dict[str, str]

    @property
    def fingerprint(self) -> str:
        """The run's fingerprint: 16 hex digits of the SHA-256 over its parts."""
        text = json.dumps(self.digests, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def changed(self, other: dict[str, str]) -> list[str]:
        """The parts whose digest differs from ``other``'s (a part missing on either side counts as changed)."""
        return [p for p in sorted(set(self.digests) | set(other)) if self.digests.get(p) != other.get(p)]


def _outside_sources(method: Any, packages: Sequence[str]) -> dict[str, str | None]:
    """``{module: sha256}`` of the agent's modules outside ``packages`` (a user's agent package: all its files,
    :func:`eval.bench.methods.source_sha256`)."""
    from eval.bench.methods import source_sha256

    return {m: source_sha256(m) for m in agent_modules(method) if m.split(".")[0] not in packages}


def _json_digest(data: Any) -> str:
    from eval.metrics.results import json_ready

    return hashlib.sha256(json.dumps(json_ready(data), sort_keys=True).encode()).hexdigest()


def run_parts(spec: Any, packages: Sequence[str] | None = None) -> RunParts:
    """The parts of a run's fingerprint (module docstring) for ``spec`` (a :class:`eval.bench.run.RunSpec`); renders
    and runs nothing. An external method's agent part is empty (its output folder is read afresh each run) and its
    world is only its ground truth's source."""
    method = spec.method
    world = world_files(spec.sequence, packages)
    judge = judge_files(packages)
    agent = {m: p for m, p in agent_files(method, packages).items() if m not in world and m not in judge}
    outside = _outside_sources(method, project_packages() if packages is None else tuple(packages))
    config = {
        "sequence": spec.sequence.describe(),
        "method": method.describe(),
        "seed": spec.seed,
        "frames": spec.frames,
        "alignment": spec.alignment,
        "renderer": spec.renderer,
    }
    return RunParts({
        "agent": files_digest(agent) if not outside else _json_digest([files_digest(agent), outside]),
        "world": files_digest(world),
        "judge": files_digest(judge),
        "weights": _json_digest(method.input_hashes()),
        "config": _json_digest(config),
    })
