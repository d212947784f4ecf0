"""Configurations as frozen dataclasses, changed by dotted keys: the one ``with_overrides`` of every method's
configuration (CNN-SLAM's, the baselines', the third-party systems', the reference agents').

A configuration is a frozen dataclass whose fields are values or sections (nested frozen dataclasses). A key names a
field by its path, ``"field"`` or ``"section.field"`` (any depth); a value is checked against the field's annotation
before it replaces the field, so a wrong type is named here, with the key and what is valid, instead of failing
somewhere inside the method:

- ``bool``: ``True`` / ``False`` only (the text ``maybe`` is no bool);
- ``int``: an integer, not a bool; ``float``: a number, not a bool (an integer becomes a float);
- ``str``: a string; ``Literal[...]``: one of its values;
- ``tuple[X, ...]`` / ``tuple[X, Y]``: a list or tuple of such values (of that length);
- ``X | None``: ``None`` or an ``X``; any other annotation: taken as given.

Value ranges are the configuration's own business (its ``__post_init__`` / ``validate``), which
:func:`dataclasses.replace` runs again on the result. :class:`Configurable` gives a dataclass the method forms
(``cfg.with_overrides({...})``, ``cfg.to_dict()``); :func:`configure` builds a method's configuration from what its
constructor was given (an instance, or a mapping of overrides on its defaults).
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Mapping
from typing import Any, Literal, TypeVar, Union, get_args, get_origin, get_type_hints

from slamcommon.errors import ConfigError

C = TypeVar("C")


class Configurable:
    """Mixin of a frozen dataclass configuration: :meth:`with_overrides` and :meth:`to_dict`."""

    def with_overrides(self: C, overrides: Mapping[str, Any] | None = None, **keywords: Any) -> C:
        """A copy with ``{"section.field": value}`` entries (or ``section__field=value`` keywords) replaced; see
        :func:`with_overrides`."""
        return with_overrides(self, overrides, **keywords)

    def to_dict(self) -> dict[str, Any]:
        """Nested plain dict (JSON-serialisable) of every field, for run records and ``cnnslam config``."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]


def configure(defaults: C, given: C | Mapping[str, Any] | None) -> C:
    """A method's configuration from what its constructor was given: ``given`` itself when it is already of the
    configuration's type, else ``defaults`` with ``given`` (a mapping of dotted overrides, or None) applied."""
    if isinstance(given, type(defaults)):
        return given
    if given is not None and not isinstance(given, Mapping):
        raise ConfigError(f"{type(defaults).__name__} or a mapping of 'section.field' overrides is expected, got "
                          f"{type(given).__name__}")  # fmt: skip
    return with_overrides(defaults, given)


def with_overrides(config: C, overrides: Mapping[str, Any] | None = None, **keywords: Any) -> C:
    """A copy of the frozen dataclass ``config`` with the fields named by dotted keys replaced (``keywords``:
    ``section__field=value``, the same keys). Each value is checked against its field's annotation (module
    docstring). Raises :class:`ConfigError` naming an unknown key (and the valid ones) or a value of the wrong type."""
    items = dict(overrides or {})
    items.update({k.replace("__", "."): v for k, v in keywords.items()})
    return _apply(config, items, "")


def config_keys(config: Any) -> list[str]:
    """Every dotted key of ``config`` (a dataclass instance), sections expanded, in field order."""
    keys: list[str] = []
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            keys += [f"{f.name}.{k}" for k in config_keys(value)]
        else:
            keys.append(f.name)
    return keys


def has_key(config: Any, key: str) -> bool:
    """Whether the dotted ``key`` names a value field of ``config`` (a dataclass instance)."""
    return key in config_keys(config)


def _apply(config: Any, items: Mapping[str, Any], prefix: str) -> Any:
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise ConfigError(f"{prefix.rstrip('.') or 'the configuration'} is not a configuration dataclass")
    names = [f.name for f in dataclasses.fields(config)]
    hints = get_type_hints(type(config))
    sections: dict[str, dict[str, Any]] = {}
    changes: dict[str, Any] = {}
    for key, value in items.items():
        head, dot, rest = key.partition(".")
        if head not in names:
            raise ConfigError(f"unknown config key {prefix + key!r}; {_valid(config, prefix)}")
        current = getattr(config, head)
        is_section = dataclasses.is_dataclass(current) and not isinstance(current, type)
        if dot and not is_section:
            raise ConfigError(f"unknown config key {prefix + key!r}: {prefix + head} is a value, not a section; "
                              f"{_valid(config, prefix)}")  # fmt: skip
        if is_section and not dot:
            raise ConfigError(f"config key {prefix + key!r} is a section: set its fields as "
                              f"'{prefix + head}.<field>' ({_valid(current, prefix + head + '.')})")  # fmt: skip
        if dot:
            sections.setdefault(head, {})[rest] = value
        else:
            changes[head] = check_value(prefix + key, value, hints.get(head, Any))
    for head, sub in sections.items():
        changes[head] = _apply(getattr(config, head), sub, f"{prefix}{head}.")
    return dataclasses.replace(config, **changes)


def _valid(config: Any, prefix: str) -> str:
    """The keys valid at this level of ``config``: its value fields, and its sections as ``section.*``."""
    names = []
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        section = dataclasses.is_dataclass(value) and not isinstance(value, type)
        names.append(f"{f.name}.*" if section else f.name)
    where = f" of {prefix.rstrip('.')} (as {prefix}<key>)" if prefix else ""
    return f"valid keys{where}: {', '.join(names)}"


def check_value(key: str, value: Any, annotation: Any) -> Any:
    """``value`` as the field ``key`` of type ``annotation`` takes it (a list becomes a tuple, an int a float where
    a float is due), or :class:`ConfigError` naming the key, the value and the type it must have."""
    ok, out = _convert(value, annotation)
    if not ok:
        raise ConfigError(f"config key {key!r} must be {_describe(annotation)}, got {value!r}")
    return out


def _convert(value: Any, annotation: Any) -> tuple[bool, Any]:
    if annotation is Any or annotation is object:
        return True, value
    origin = get_origin(annotation)
    if origin is Literal:
        return value in get_args(annotation) and not isinstance(value, bool | list), value
    if origin in (Union, types.UnionType):
        for arm in get_args(annotation):
            ok, out = (value is None, value) if arm is type(None) else _convert(value, arm)
            if ok:
                return True, out
        return False, value
    if origin is tuple:
        args = get_args(annotation)
        if not isinstance(value, list | tuple):
            return False, value
        arms = [args[0]] * len(value) if len(args) == 2 and args[1] is Ellipsis else list(args)
        if len(arms) != len(value):
            return False, value
        converted = [_convert(v, a) for v, a in zip(value, arms, strict=True)]
        return all(ok for ok, _ in converted), tuple(out for _, out in converted)
    if annotation is bool:
        return isinstance(value, bool), value
    if annotation is int:
        return isinstance(value, int) and not isinstance(value, bool), value
    if annotation is float:
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        return ok, float(value) if ok else value
    if annotation is str:
        return isinstance(value, str), value
    if isinstance(annotation, type):
        return isinstance(value, annotation), value
    return True, value  # an annotation this checker does not read: taken as given


def _describe(annotation: Any) -> str:
    origin = get_origin(annotation)
    if origin is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(annotation))
    if origin in (Union, types.UnionType):
        return " or ".join(_describe(a) for a in get_args(annotation))
    if origin is tuple:
        args = get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis:
            plural = {bool: "bools", int: "integers", float: "numbers", str: "strings"}
            return f"a list of {plural.get(args[0], _describe(args[0]) + ' values')}"
        return f"a list of {len(args)} values ({', '.join(_describe(a) for a in args)})"
    words = {bool: "a bool (true or false)", int: "an integer", float: "a number", str: "a string",
             type(None): "None"}  # fmt: skip
    return words.get(annotation, getattr(annotation, "__name__", str(annotation)))

