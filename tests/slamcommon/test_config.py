"""slamcommon.config: the one with_overrides of every method's configuration: dotted keys, values checked against
the fields' types, unknown keys named with the valid ones."""

from __future__ import annotations

import ast
import pathlib
from dataclasses import dataclass, field
from typing import Literal

import pytest

from slamcommon.config import Configurable, check_value, config_keys, configure, has_key, with_overrides
from slamcommon.errors import ConfigError, ProjectError

ROOT = pathlib.Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Inner:
    levels: int = 4
    enabled: bool = True
    iterations: tuple[int, ...] = (20, 50)
    span: tuple[float, float] = (0.5, 1.5)

    def __post_init__(self) -> None:
        if self.levels < 1:
            raise ProjectError(f"inner.levels must be >= 1, got {self.levels}")


@dataclass(frozen=True)
class Outer(Configurable):
    rate: float = 1.0
    mode: Literal["fast", "exact"] = "fast"
    name: str | None = None
    inner: Inner = field(default_factory=Inner)


def test_dotted_keys_and_keywords_replace_fields_and_convert_values():
    cfg = Outer().with_overrides({"inner.levels": 2, "inner.iterations": [5, 6], "rate": 3}, inner__enabled=False)
    assert cfg == Outer(rate=3.0, inner=Inner(levels=2, enabled=False, iterations=(5, 6)))
    assert isinstance(cfg.rate, float) and isinstance(cfg.inner.iterations, tuple)
    assert Outer().inner.levels == 4  # frozen: the original is unchanged
    assert with_overrides(Outer(), {"mode": "exact", "name": None}).mode == "exact"


@pytest.mark.parametrize(("overrides", "message"), [
    ({"inner.levels": "abc"}, "'inner.levels' must be an integer, got 'abc'"),
    ({"inner.levels": True}, "'inner.levels' must be an integer, got True"),
    ({"inner.enabled": "maybe"}, r"'inner.enabled' must be a bool \(true or false\), got 'maybe'"),
    ({"rate": "fast"}, "'rate' must be a number"),
    ({"mode": "slow"}, "'mode' must be one of 'fast', 'exact', got 'slow'"),
    ({"inner.iterations": [1, "a"]}, "'inner.iterations' must be a list of integers"),
    ({"inner.span": [1.0]}, r"'inner.span' must be a list of 2 values \(a number, a number\)"),
    ({"name": 3}, "'name' must be a string or None"),
    ({"nosuch": 1}, r"unknown config key 'nosuch'; valid keys: rate, mode, name, inner\.\*"),
    ({"inner.nosuch": 1}, r"valid keys of inner \(as inner.<key>\): levels, enabled, iterations, span"),
    ({"rate.x": 1}, "rate is a value, not a section"),
    ({"inner": 1}, "is a section: set its fields as 'inner.<field>'"),
])
def test_a_bad_key_or_type_is_named(overrides, message):
    with pytest.raises(ConfigError, match=message):
        Outer().with_overrides(overrides)


def test_the_configuration_still_checks_its_own_ranges():
    with pytest.raises(ProjectError, match="inner.levels must be >= 1"):
        Outer().with_overrides({"inner.levels": 0})


def test_keys_configure_and_to_dict():
    assert config_keys(Outer()) == ["rate", "mode", "name", "inner.levels", "inner.enabled", "inner.iterations",
                                    "inner.span"]
    assert has_key(Outer(), "inner.levels") and not has_key(Outer(), "inner") and not has_key(Outer(), "levels")
    given = Outer(rate=2.0)
    assert configure(Outer(), given) is given
    assert configure(Outer(), {"rate": 5}) == Outer(rate=5.0) and configure(Outer(), None) == Outer()
    with pytest.raises(ConfigError, match="Outer or a mapping"):
        configure(Outer(), [1, 2])
    assert Outer().to_dict()["inner"] == {"levels": 4, "enabled": True, "iterations": (20, 50), "span": (0.5, 1.5)}
    assert check_value("k", 2, float) == 2.0


def test_with_overrides_is_written_once():
    """Every configuration derives its overrides from slamcommon.config (CNN-SLAM's, ORB's, Laina's and REMODE's
    were four copies)."""
    places = []
    for package in ("slamcommon", "sim_envs", "cnnslam", "eval", "thirdparty"):
        for path in (ROOT / package).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.FunctionDef) and node.name == "with_overrides":
                    places.append(str(path.relative_to(ROOT)))
    assert sorted(places) == ["slamcommon/config.py", "slamcommon/config.py"]  # the function and the mixin's method
