"""What the suite reports read of the benchmark's objects, as protocols, so that :mod:`eval.reports` imports nothing
of :mod:`eval.bench` (the layer above it, which calls the reports after a suite's runs; ``lint-imports`` checks the
order). Each protocol has the name of the benchmark class it describes, and the benchmark passes its own objects:
:class:`eval.bench.runner.SuiteRun`, :class:`eval.bench.suites.Suite`, :class:`eval.bench.run.RunSpec`,
:class:`eval.bench.suites.TransferPart` and :class:`eval.bench.suites.PreprocessingChoice`
(``tests/eval/reports/test_inputs.py`` checks that each still has what its protocol names). Also
:func:`machine_label`, the one line a report gives a run's machine description.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from eval.metrics.results import RunRecord


@runtime_checkable
class Suite(Protocol):
    """A suite as a report names it: its name and description, sequences (each with a ``name``), methods (names),
    frames (None: whole sequences), seeds, alignment, report layout, the sequences skipped here (name, reason), the
    titles of its sweep axes, the second references of the dataset list (name -> TUM file) and a note when the
    selection differs from the suite as defined."""

    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def sequences(self) -> Sequence[Any]: ...
    @property
    def methods(self) -> Sequence[str]: ...
    @property
    def frames(self) -> int | None: ...
    @property
    def seeds(self) -> Sequence[int]: ...
    @property
    def alignment(self) -> str: ...
    @property
    def report(self) -> str: ...
    @property
    def skipped(self) -> Sequence[tuple[str, str]]: ...
    @property
    def axis_titles(self) -> Mapping[str, str]: ...
    def second_references(self) -> Mapping[str, Path]: ...
    def selection_note(self) -> str: ...


@runtime_checkable
class RunSpec(Protocol):
    """One planned run: its ``key`` (its folder below the suite's output root), the method (``name``, ``metrics``:
    its metric groups), the sequence (``name``), the seed and the alignment its trajectory is scored with."""

    @property
    def key(self) -> str: ...
    @property
    def method(self) -> Any: ...
    @property
    def sequence(self) -> Any: ...
    @property
    def seed(self) -> int: ...
    @property
    def alignment(self) -> str: ...


@runtime_checkable
class SuiteRun(Protocol):
    """A suite's runs: the suite, the output root, the planned runs, how each ended (run key -> an outcome with
    ``key``, ``status``, ``folder``, ``error``), the methods skipped (name -> reason), the records of the finished
    runs (in plan order), each run's ``timing.json`` content (run key -> dict) and the methods run."""

    @property
    def suite(self) -> Suite: ...
    @property
    def out_root(self) -> Path: ...
    @property
    def specs(self) -> Sequence[RunSpec]: ...
    @property
    def outcomes(self) -> Mapping[str, Any]: ...
    @property
    def skipped_methods(self) -> Mapping[str, str]: ...
    @property
    def records(self) -> Sequence[RunRecord]: ...
    @property
    def timings(self) -> Mapping[str, Mapping[str, Any]]: ...
    @property
    def methods(self) -> Sequence[Any]: ...
    @property
    def failed(self) -> Sequence[Any]: ...
    def counts(self) -> dict[str, int]: ...


@runtime_checkable
class TransferPart(Protocol):
    """One suite of the transfer suite: the ``length`` of its samples (frames; None: whole sequences), the suite and
    each sequence's transfer domain, as ``(sequence name, domain)`` pairs."""

    @property
    def length(self) -> int | None: ...
    @property
    def suite(self) -> Suite: ...
    @property
    def domains(self) -> Sequence[tuple[str, str]]: ...


@runtime_checkable
class PreprocessingChoice(Protocol):
    """A preprocessing choice: its ``name``, what it does, and which folders it ``applies`` to."""

    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def applies(self) -> str: ...


def machine_label(env: Mapping[str, Any]) -> str:
    """One line naming a machine description (:func:`eval.bench.environment.machine_description`): CPU, widest ISA,
    torch and numpy versions."""
    pk = env.get("packages") or {}
    isa = (env.get("isa") or ["-"])[0]
    return f"{env.get('cpu', '?')} ({isa}), torch {pk.get('torch', '-')}, numpy {pk.get('numpy', '-')}"
