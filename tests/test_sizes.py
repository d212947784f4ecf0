"""Sizes the project keeps: no module of the five packages (``cnnslam``, ``sim_envs``, ``eval``, ``slamcommon``,
``thirdparty``) over :data:`MAX_MODULE_LINES` lines, and no function over :data:`MAX_FUNCTION_LINES` lines (its
``def`` line to its last line, decorators not counted) unless it is a numba kernel (decorated with ``njit`` or
``jit``, bare or as ``numba.njit(...)``): a kernel is one loop nest that numba compiles whole. Test modules
(``test_*.py``) are not counted. The scanner is tested on synthetic files first, so that the repository check can
fail."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("cnnslam", "sim_envs", "eval", "slamcommon", "thirdparty")
MAX_MODULE_LINES = 700
MAX_FUNCTION_LINES = 120
NUMBA_DECORATORS = frozenset({"njit", "jit"})


def _is_numba_kernel(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """True when a decorator is ``njit`` / ``jit`` (a name or ``numba.`` attribute, called or not)."""
    for decorator in function.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in NUMBA_DECORATORS:
            return True
    return False


def oversized(path: Path, max_module: int = MAX_MODULE_LINES, max_function: int = MAX_FUNCTION_LINES) -> list[str]:
    """One line per breach in the Python file ``path``: the module's line count over ``max_module``, and each
    function (nested ones too, methods included) over ``max_function`` lines that is no numba kernel."""
    text = path.read_text(encoding="utf-8")
    out = []
    lines = len(text.splitlines())
    if lines > max_module:
        out.append(f"{path}: {lines} lines (at most {max_module})")
    for node in ast.walk(ast.parse(text, str(path))):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not _is_numba_kernel(node):
            size = node.end_lineno - node.lineno + 1
            if size > max_function:
                out.append(f"{path}:{node.lineno}: function {node.name} is {size} lines (at most {max_function})")
    return out


def package_modules(root: Path = ROOT) -> list[Path]:
    """The non-test Python modules of :data:`PACKAGES` under ``root``."""
    return sorted(p for pkg in PACKAGES for p in (root / pkg).rglob("*.py") if not p.name.startswith("test_"))


def _function(name: str, body_lines: int, decorator: str = "") -> str:
    body = "".join(f"    x{n} = {n}\n" for n in range(body_lines - 3))
    return f"{decorator}def {name}():\n    x = 0\n{body}    return x\n"  # body_lines lines from def to return


def test_the_scanner_finds_a_long_module_and_a_long_function(tmp_path):
    ok = tmp_path / "ok.py"
    ok.write_text(_function("short", 120))
    assert oversized(ok) == []
    long_function = tmp_path / "long_function.py"
    long_function.write_text("import numpy\n\n\n" + _function("long", 121))
    assert oversized(long_function) == [f"{long_function}:4: function long is 121 lines (at most 120)"]
    long_module = tmp_path / "long_module.py"
    long_module.write_text("".join(f"X{n} = {n}\n" for n in range(701)))
    assert oversized(long_module) == [f"{long_module}: 701 lines (at most 700)"]
    nested = tmp_path / "nested.py"
    nested.write_text("class A:\n" + "".join("    " + line + "\n" for line in _function("method", 130).splitlines()))
    assert [m.split(": ", 1)[1] for m in oversized(nested)] == ["function method is 130 lines (at most 120)"]


@pytest.mark.parametrize("decorator", ["@njit\n", "@numba.njit(cache=True)\n", "@jit(nopython=True)\n",
                                       "@numba.jit\n"])
def test_a_numba_kernel_may_be_long_and_nothing_else(tmp_path, decorator):
    kernel = tmp_path / "kernel.py"
    kernel.write_text(_function("kernel", 200, decorator))
    assert oversized(kernel) == []
    other = tmp_path / "other.py"
    other.write_text(_function("cached", 200, "@functools.lru_cache\n"))
    assert len(oversized(other)) == 1


def test_package_modules_skip_tests(tmp_path):
    (tmp_path / "eval" / "sub").mkdir(parents=True)
    (tmp_path / "eval" / "sub" / "a.py").write_text("")
    (tmp_path / "eval" / "sub" / "test_a.py").write_text("")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "b.py").write_text("")
    assert package_modules(tmp_path) == [tmp_path / "eval" / "sub" / "a.py"]


def test_no_module_or_function_of_the_packages_is_too_long():
    modules = package_modules()
    assert len(modules) > 100  # the packages were found
    breaches = [line for path in modules for line in oversized(path)]
    assert not breaches, "split these along a real seam:\n" + "\n".join(breaches)
