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

The closure of a module (:func:`import_closure`, defined in :mod:`slamcommon.provenance`) follows, within the
project's packages (:data:`PROJECT_PACKAGES`), every ``import`` and ``from ... import`` statement of its file, including
those inside functions, the packages' ``__init__`` files that importing a module runs, and
``importlib.import_module("literal")`` calls; it never imports anything. Modules outside the project's packages
(numpy, torch, ...) are not followed: their versions are the machine's (a run's ``timing.json`` names them). Parsed
files and closures are cached per process by each file's size and modification time, so a suite of hundreds of runs
parses each file once.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slamcommon import provenance as _closure
from slamcommon.provenance import file_sha256, files_digest, imported_modules, package_root

__all__ = ["PARTS", "PROJECT_PACKAGES", "RunParts", "agent_files", "agent_modules", "closure_sha256", "file_sha256",
           "files_digest", "import_closure", "imported_modules", "judge_files", "module_file", "package_root",
           "project_packages", "run_parts", "source_sha256", "world_files", "world_roots"]

# the packages whose files a closure follows (and hashes); modules of any other package are left out
PROJECT_PACKAGES: tuple[str, ...] = _closure.PROJECT_PACKAGES
WORLD_PACKAGES: tuple[str, ...] = ("sim_envs",)
JUDGE_PREFIXES: tuple[str, ...] = ("eval.metrics", "slamcommon")
# the world every run of an agent goes through: the environments and the episode loop
WORLD_ROOTS: tuple[str, ...] = ("sim_envs.env", "sim_envs.driver")
RUN_MODULE = "eval.bench.run"  # whose eval.metrics imports are the judge's roots
PARTS: tuple[str, ...] = ("agent", "world", "judge", "weights", "config")


def project_packages() -> tuple[str, ...]:
    """The packages closures follow now (:data:`PROJECT_PACKAGES`, read at each call so a test may add one)."""
    return tuple(PROJECT_PACKAGES)


def _packages(packages: Sequence[str] | None) -> tuple[str, ...]:
    return project_packages() if packages is None else tuple(packages)


def module_file(module: str, packages: Sequence[str] | None = None) -> Path | None:
    """The source file of ``module`` within ``packages`` (default :func:`project_packages`;
    :func:`slamcommon.provenance.module_file`)."""
    return _closure.module_file(module, _packages(packages))


def import_closure(modules: Iterable[str], packages: Sequence[str] | None = None) -> dict[str, Path]:
    """``{module: file}`` of ``modules`` and everything they import within ``packages`` (default
    :func:`project_packages`; :func:`slamcommon.provenance.import_closure`)."""
    return _closure.import_closure(modules, _packages(packages))


def closure_sha256(module: str, packages: Sequence[str] | None = None) -> str | None:
    """SHA-256 of the import closure of ``module``, None when it is no module file of ``packages`` (default
    :func:`project_packages`)."""
    return _closure.closure_sha256(module, _packages(packages))


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
        roots.append("sim_envs.folders.datasets")
    else:
        roots += ["sim_envs.sources.simsource", "sim_envs.sources.frame_cache"]
        if getattr(sequence, "focal_ratio", None) is not None or getattr(sequence, "added_pan_deg_s", 0.0):
            roots.append("sim_envs.sources.variants")
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


def source_sha256(module: str) -> str | None:
    """SHA-256 of the source ``module`` runs: for a module of the project's packages (:data:`PROJECT_PACKAGES`), the
    files of its import closure (:func:`closure_sha256`); for a module of any other package (a user's agent), the
    ``.py`` files of its top-level package (every file below its folder, by relative path and content, in sorted
    order) or its single file, found with :func:`importlib.util.find_spec` without importing it. None when it cannot
    be found."""
    if module.split(".")[0] in project_packages():
        return closure_sha256(module)
    module = module.split(".")[0]
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    roots = list(spec.submodule_search_locations or [])
    digest = hashlib.sha256()
    if roots:
        root = Path(roots[0])
        for path in sorted(root.rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode() + b"\0")
            digest.update(file_sha256(path).encode())
    elif spec.origin and Path(spec.origin).is_file():
        digest.update(file_sha256(Path(spec.origin)).encode())
    else:
        return None
    return digest.hexdigest()


def _outside_sources(method: Any, packages: Sequence[str]) -> dict[str, str | None]:
    """``{module: sha256}`` of the agent's modules outside ``packages`` (a user's agent package: all its files,
    :func:`source_sha256`)."""
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
