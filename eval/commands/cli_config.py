"""``cnnslam config METHOD [--set KEY=VALUE ...]``: the exact configuration a method's runs use.

The method is looked up in the method table (``eval/methods.toml``, plus ``--method-file``); ``--set`` overrides
are merged into its agent's ``config`` keyword exactly as ``cnnslam bench --set`` merges them (and so enter the run
fingerprints); the agent is built (no network is loaded: the predictor is made on first use) and its configuration
printed as TOML sections, or as JSON with ``--json``. An agent without a ``config`` attribute prints its keyword
arguments alone.

Exit status 0, or 2 with one line naming the bad value and what is valid: an unknown method, an unreadable or
malformed ``--method-file``, a ``--set`` that is no ``KEY=VALUE``, names a key the agent does not have, gives a value
of the wrong type or range, or sets the key the run's seed goes to (``--seed`` sets that); an agent that cannot be
imported or built with its keyword arguments.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from eval.bench.method_settings import parse_setting, with_settings
from eval.bench.methods import Method, load_methods, merge_methods
from eval.errors import EvalError, InputError
from slamcommon.errors import ProjectError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("method", help="a method of the method table (cnnslam bench --list)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override one field (repeatable), e.g. --set refinement.enabled=false")
    parser.add_argument("--seed", type=int, default=0, help="the run's seed, put where the method says (default 0)")
    parser.add_argument("--method-file", default=None, help="a method file to add to the table")
    parser.add_argument("--json", action="store_true", help="print JSON instead of TOML sections")


def _toml_value(value: Any) -> str:
    return json.dumps(value) if not isinstance(value, bool) else ("true" if value else "false")


def format_toml(sections: dict[str, Any]) -> str:
    """A nested dict of sections (``{"tracking": {"min_gradient": 5.0, ...}, ...}``) as TOML text; top-level
    scalars first. Tuples print as arrays; a value TOML cannot hold (None) prints as a comment."""
    lines = []
    for key, value in sections.items():
        if not isinstance(value, dict):
            lines.append(f"{key} = {_toml_value(value)}" if value is not None else f"# {key}: unset")
    for name, fields in sections.items():
        if isinstance(fields, dict):
            lines.append(f"\n[{name}]")
            for key, value in fields.items():
                value = list(value) if isinstance(value, tuple) else value
                lines.append(f"{key} = {_toml_value(value)}" if value is not None else f"# {key}: unset")
    return "\n".join(lines).lstrip("\n") + "\n"


def check_settings(method: Method, settings: list[tuple[str, Any]]) -> None:
    """Refuse a ``--set`` of the key the run's seed is put into (the seed would silently replace it): that key is
    set with ``--seed``."""
    seeded = {key for keyword, _, key in (t.partition(".") for t in method.seed_targets) if keyword == "config"}
    for key, value in settings:
        if key in seeded:
            raise InputError(f"--set {key}={value}: {method.name}'s run seed goes into {key!r}; set it with --seed")


def _one_line(text: str) -> str:
    return " ".join(line.strip() for line in str(text).splitlines() if line.strip())


def run(args: argparse.Namespace) -> int:
    from sim_envs.agent import load_agent

    method = None
    try:
        methods = load_methods()
        if args.method_file is not None:
            methods = merge_methods(methods, load_methods(args.method_file), str(args.method_file))
        if args.method not in methods:
            raise EvalError(f"unknown method {args.method!r}; valid methods: {', '.join(methods)}")
        settings = [parse_setting(s) for s in args.set]
        check_settings(methods[args.method], settings)
        method = with_settings(methods[args.method], settings)
        if method.kind != "agent" or not method.entry_point:
            raise EvalError(f"method {method.name!r} is {method.kind}: it has no agent configuration")
        kwargs = method.agent_kwargs(args.seed)
        agent = load_agent(method.entry_point, **kwargs)
    except ProjectError as exc:  # a bad method, method file or --set; an agent that refuses a value
        print(f"cnnslam config: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - an agent whose module or constructor fails (a keyword it does not take)
        where = f"method {method.name!r} ({method.entry_point}): " if method is not None else ""
        print(f"cnnslam config: error: {where}{type(exc).__name__}: {_one_line(exc)}", file=sys.stderr)
        return 2
    config = getattr(agent, "config", None)
    described = config.to_dict() if hasattr(config, "to_dict") else None
    if args.json:
        print(json.dumps({"method": method.name, "entry_point": method.entry_point, "kwargs": kwargs,
                          "config": described}, indent=2, default=str))
        return 0
    print(f"# {method.name}: {method.entry_point}, seed {args.seed}")
    print(f"# keyword arguments: {json.dumps(kwargs, default=str)}")
    print(format_toml(described) if described is not None else "# this agent exposes no configuration")
    return 0
