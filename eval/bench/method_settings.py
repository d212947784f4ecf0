"""``--set KEY=VALUE`` for methods: a setting parsed, checked against each chosen method's configuration before any
run, and merged into the method's agent keyword arguments (``config``, ``predictor_options``), so that the runs'
fingerprints carry it. Methods themselves: :mod:`eval.bench.methods`."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

from eval.bench.methods import Method, MethodError, thaw
from slamcommon.config import config_keys, has_key
from slamcommon.errors import ProjectError


def parse_setting(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` (``--set``; CNN-SLAM's keys are ``SECTION.FIELD``, ORB's plain field names) as ``(key,
    value)``: the value read as a TOML value (``true``, ``0.5``, ``"name"``, ``[1, 2]``), else kept as the bare
    string. One clear error for text without ``=`` or a key; the agent itself names an unknown key."""
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not key or not all(part.strip() for part in key.split(".")):
        raise MethodError(f"--set takes KEY=VALUE (e.g. refinement.enabled=false), got {text!r}")
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key, value


def takes_config(method: Method) -> bool:
    """Whether the method's agent takes a ``config`` keyword (a dotted-key override dict, as CNN-SLAM's agents)."""
    if method.kind != "agent" or not method.entry_point:
        return False
    module_name, _, attr = method.entry_point.partition(":")
    try:
        factory = getattr(importlib.import_module(module_name), attr)
        return "config" in inspect.signature(factory).parameters
    except (ImportError, AttributeError, TypeError, ValueError):
        return False


def agent_configuration(method: Method) -> Any:
    """The configuration the method's agent runs with: its ``config`` attribute (a frozen dataclass,
    :mod:`slamcommon.config`), read from the agent built with the method's keyword arguments (seed 0) through
    :func:`sim_envs.agent.load_agent` (a network is loaded only when first used); None for an external method or an
    agent that has none. Raises what building raises: a :class:`~slamcommon.errors.ProjectError` for keyword
    arguments the agent refuses, an ImportError where it cannot run here."""
    if method.kind != "agent" or not method.entry_point:
        return None
    from sim_envs.agent import load_agent

    config = getattr(load_agent(method.entry_point, **method.agent_kwargs(0)), "config", None)
    return config if dataclasses.is_dataclass(config) and not isinstance(config, type) else None


def apply_settings(methods: Sequence[Method], settings: Sequence[tuple[str, Any]]
                   ) -> tuple[dict[str, Method], dict[str, tuple[str, ...]]]:
    """``settings`` (``--set``: ``(dotted key, value)``) put into each of ``methods`` whose configuration
    (:func:`agent_configuration`) has the key, checked before any run: returns the methods (name -> method, with the
    settings that apply merged into its ``config`` keyword, so its runs' fingerprints carry them) and, per key, the
    names of the methods it went to. :class:`MethodError` for a key no chosen method's configuration has, or a value
    a method's configuration refuses (a type, a range), naming the key, the method and what is valid. A method that
    cannot be built here (an import failure) is left as it is: the suite's check skips it with its reason."""
    configs: dict[str, Any] = {}
    for method in methods:
        try:
            config = agent_configuration(method)
        except ProjectError as exc:
            raise MethodError(f"method {method.name!r} refuses its own keyword arguments: {exc}") from None
        except Exception:  # noqa: BLE001 - cannot be built here: reported by the suite's check, with the reason
            continue
        if config is not None:
            configs[method.name] = config
    applied: dict[str, tuple[str, ...]] = {}
    for key, _ in settings:
        applied[key] = tuple(name for name, config in configs.items() if has_key(config, key))
        if not applied[key]:
            keys = {name: config_keys(config) for name, config in configs.items()}
            raise MethodError(f"--set {key}: no chosen method's configuration has this key; "
                              + ("; ".join(f"{n}'s keys: {', '.join(k[:6])}{', ...' if len(k) > 6 else ''}"
                                           for n, k in keys.items()) or
                                 f"none of the chosen methods ({', '.join(m.name for m in methods)}) has a "
                                 "configuration") + " (cnnslam config METHOD prints them all)")  # fmt: skip
    out: dict[str, Method] = {}
    for method in methods:
        mine = [(key, value) for key, value in settings if method.name in applied[key]]
        out[method.name] = with_settings(method, mine) if mine else method
        if mine:
            try:
                agent_configuration(out[method.name])
            except ProjectError as exc:
                raise MethodError(f"--set for {method.name}: {exc}") from None
    return out, applied


def with_settings(method: Method, settings: Sequence[tuple[str, Any]]) -> Method:
    """``method`` with ``settings`` (``(dotted key, value)``, later ones win) merged into its agent's ``config``
    keyword: a new method whose keyword arguments, and so whose run fingerprints, carry them. :class:`MethodError`
    when the agent takes no configuration."""
    if not settings:
        return method
    if not takes_config(method):
        raise MethodError(f"method {method.name!r} ({method.entry_point or method.kind}) takes no configuration to "
                          "--set")
    return _merged_into(method, "config", dict(settings))


def with_predictor_options(method: Method, options: Mapping[str, Any]) -> Method:
    """``method`` with ``options`` merged into its agent's ``predictor_options`` keyword (the network's explicit
    run parameters: ``jitter_seed_fallback``, ``onednn``, ...): a new method whose keyword arguments, and so whose run
    fingerprints, carry them."""
    return _merged_into(method, "predictor_options", dict(options)) if options else method


def _merged_into(method: Method, keyword: str, values: dict[str, Any]) -> Method:
    """A new method whose dict keyword argument ``keyword`` has ``values`` merged in (``values`` win)."""
    kwargs = {k: thaw(v) for k, v in method.kwargs}
    kwargs[keyword] = {**(kwargs.get(keyword) or {}), **values}
    return replace(method, kwargs=kwargs)
