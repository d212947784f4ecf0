"""Shared test machinery: :func:`fuzz_reader`, the property-based check of a file reader (hypothesis), used by the
``tests/**/test_*_fuzz.py`` files; :func:`shared_data` and :func:`tum_dir`, the shared data found from the repository
(``../shared`` beside it, or ``$CNNSLAM_SHARED``), the test skipped with what is missing where it is absent; and
:func:`reference_facts`, the reference figures the tests assert, with their sources
(``tests/reference_facts.toml``); :func:`check_pinned`, a computation's byte digest against the ones recorded on each
CPU (:func:`cpu_label`), which skips on a CPU whose bytes no table holds.

A fuzzed input is a valid file (one of the reader's seeds) changed by up to three mutations drawn by hypothesis
(:data:`MUTATIONS`): lines dropped, repeated, swapped or inserted (blank, comment, unicode, junk), tokens dropped,
repeated, swapped or replaced (by nan, inf, huge, negative, text, unicode, brackets, quotes: :data:`REPLACEMENTS`),
numbers changed a little or a lot, separators changed, the text cut short, a byte that is not UTF-8. The property: the
reader returns a result that passes the test's check, or raises the project's error
(:class:`slamcommon.errors.ProjectError`) with one line that names the file; anything else (a traceback, or a
numpy RuntimeWarning such as an overflow the reader did not expect) fails.
"""

from __future__ import annotations

import math
import os
import time
import tomllib
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

# weights by repetition: the benign mutations (a comment, a blank line, a small change of a number) come more often,
# so that about half of the inputs are still valid files and the reader's checks past the first line are reached
MUTATIONS: tuple[str, ...] = (
    "insert_blank", "insert_blank", "insert_comment", "insert_comment", "insert_comment",
    "tweak_number", "tweak_number", "tweak_number", "tweak_number", "tweak_number", "tweak_number", "tweak_number",
    "tweak_number", "insert_blank",
    "drop_line", "dup_line", "swap_lines", "insert_unicode", "insert_junk", "truncate",
    "drop_token", "dup_token", "swap_tokens", "replace_token", "replace_token", "add_token", "scale_number",
    "crlf", "tabs", "bad_byte",
)  # fmt: skip
REPLACEMENTS: tuple[str, ...] = (
    "nan", "NaN", "inf", "-inf", "1e400", "-1e400", "1e308", "-1", "-0.0", "0", "1e-320", "99999999999999999999",
    "abc", "", "1,5", "0x10", "1_0", "\uff11", "\u00e9", "+", "-", ".", "e5", "true", "[]", "{}", '"x"', "'", "=",
    ":", "#", "\t", "\u2028", "\x0c", "\ufeff", "[1, 2]", "{a = 1}", '"\u00e9t\u00e9 0"', "-5", "0.5", "3", "~",
    '"~nobody_q/x"', '"/"', '""',
)  # fmt: skip
TWEAKS: tuple[float, ...] = (1.0 + 1e-9, 1.0 - 1e-9, 1.0 + 1e-6, 1.0 - 1e-7)
SCALES: tuple[float, ...] = (-1.0, 0.0, 10.0, 1e6, 1e-6, 1e300)


def _as_number(token: str) -> float | None:
    try:
        return float(token)
    except ValueError:
        return None


def _tokens(line: str) -> list[str]:
    return line.split(" ")


def mutate(text: str, mutations: Sequence[tuple[str, int, int, str]]) -> bytes:
    """``text`` changed by ``mutations`` ((kind, a, b, replacement): line and token positions are taken modulo the
    current number of lines / tokens, character positions (truncate, bad_byte) as b / 255 of the text), as UTF-8
    bytes (``bad_byte`` inserts one that is not UTF-8)."""
    lines = text.split("\n")
    bad_at: int | None = None
    crlf = False
    for kind, a, b, replacement in mutations:
        k = a % len(lines) if lines else 0
        if kind == "insert_blank":
            lines.insert(k, " " * (b % 3))
        elif kind == "insert_comment":
            lines.insert(k, "# " + replacement + " comment")
        elif kind == "insert_unicode":
            lines.insert(k, "\u00e9\u00e8 \u4e2d\u6587 \U0001f600 " + replacement)
        elif kind == "insert_junk":
            lines.insert(k, " ".join(REPLACEMENTS[(b + i) % len(REPLACEMENTS)] for i in range(1 + b % 9)))
        elif not lines:
            continue
        elif kind == "drop_line":
            del lines[k]
        elif kind == "dup_line":
            lines.insert(k, lines[k])
        elif kind == "swap_lines":
            j = b % len(lines)
            lines[k], lines[j] = lines[j], lines[k]
        elif kind == "truncate":
            joined = "\n".join(lines)
            lines = joined[: b * len(joined) // 255].split("\n")
        elif kind == "crlf":
            crlf = True
        elif kind == "tabs":
            lines[k] = lines[k].replace(" ", "\t")
        elif kind == "bad_byte":
            bad_at = b
        else:
            tokens = _tokens(lines[k])
            t = b % len(tokens)
            if kind == "drop_token":
                del tokens[t]
            elif kind == "dup_token":
                tokens.insert(t, tokens[t])
            elif kind == "swap_tokens":
                j = (t + 1) % len(tokens)
                tokens[t], tokens[j] = tokens[j], tokens[t]
            elif kind == "replace_token":
                tokens[t] = replacement
            elif kind == "add_token":
                tokens.insert(t, replacement)
            elif kind in ("tweak_number", "scale_number"):
                numbers = [i for i, tok in enumerate(tokens) if _as_number(tok.strip(",[]")) is not None]
                if numbers:
                    i = numbers[b % len(numbers)]
                    token = tokens[i]
                    stripped = token.strip(",[]")
                    factors = TWEAKS if kind == "tweak_number" else SCALES
                    value = float(stripped) * factors[(a // 7) % len(factors)]
                    keep_int = math.isfinite(value) and not any(c in stripped.lower() for c in ".en")
                    new = str(int(value)) if keep_int else repr(value)
                    tokens[i] = token.replace(stripped, new, 1)
            lines[k] = " ".join(tokens)
    data = ("\r\n" if crlf else "\n").join(lines).encode("utf-8")
    if bad_at is not None:
        at = bad_at * len(data) // 255
        data = data[:at] + b"\xff" + data[at:]
    return data


def decode(plan: bytes, n_seeds: int) -> tuple[int, list[tuple[str, int, int, str]]]:
    """A mutation plan from hypothesis' bytes: byte 0 picks the seed and the number of mutations (0-3), each next
    4 bytes one mutation (kind, position, position, replacement; positions 0-255, taken modulo the lines, tokens or
    characters there are). One draw a file: hypothesis' per-draw cost, not the reader's, bounds how many files a
    second are tried. All-zero bytes (where hypothesis shrinks to) are the first seed unchanged."""
    seed, count = divmod(plan[0], 4)
    mutations = [
        (MUTATIONS[kind % len(MUTATIONS)], a, b, REPLACEMENTS[r % len(REPLACEMENTS)])
        for kind, a, b, r in (plan[1 + 4 * i : 5 + 4 * i] for i in range(count))
    ]
    return seed % n_seeds, mutations


PLAN_BYTES = 13


@dataclass
class FuzzReport:
    """What one fuzz run saw: inputs tried (distinct among them), results, refusals (one line naming the file)."""

    examples: int = 0
    parsed: int = 0
    refused: int = 0
    seconds: float = 0.0  # wall clock
    cpu_seconds: float = 0.0  # this process's CPU time (what the 2 cores of CI give, whatever else runs here)
    distinct: set[bytes] = field(default_factory=set, repr=False)

    @property
    def parse_share(self) -> float:
        return self.parsed / max(self.examples, 1)

    def __str__(self) -> str:
        return (f"{self.examples} inputs ({len(self.distinct)} distinct), {self.parsed} parsed "
                f"({100 * self.parse_share:.1f} %), {self.refused} refused, {self.seconds:.1f} s, "
                f"{self.cpu_seconds:.1f} s CPU")


FUZZ_EXAMPLES = 10_000  # inputs per reader
MIN_PARSE_SHARE = 0.5  # at least half of the inputs are valid files (the mutations are no random bytes)


def _overwrite(path: Path, data: bytes) -> None:
    """``path`` holds ``data``, written over what it held and then cut to length: opening with truncation makes ext4
    flush the file (its auto_da_alloc), 3.5 ms an input instead of 5 us."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        os.write(fd, data)
        os.ftruncate(fd, len(data))
    finally:
        os.close(fd)


def run_fuzz(
    path: Path | Callable[[int], Path],
    seeds: Sequence[str],
    read: Callable[[Path], Any],
    check: Callable[[Any], None] | None = None,
    *,
    names: Sequence[str] = (),
    examples: int = FUZZ_EXAMPLES,
) -> FuzzReport:
    """Write each mutated seed to ``path`` (or ``path(seed_index)``: a seed's own file name), call ``read(path)``;
    a result must pass ``check``, an error must be a :class:`ProjectError` whose message is one line naming the file
    (its path or name, or one of ``names``: the file a reader says is at fault, e.g. a list's entry). Anything else
    fails the test, with the input that raised it. Returns the counts, which the caller asserts (examples, parse
    share); prints them."""
    from hypothesis import HealthCheck, given, note, settings
    from hypothesis import strategies as st

    from slamcommon.errors import ProjectError

    report = FuzzReport()
    where = path if callable(path) else (lambda _: path)

    @settings(
        max_examples=examples,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.binary(min_size=PLAN_BYTES, max_size=PLAN_BYTES))
    def property_(plan: bytes) -> None:
        index, mutations = decode(plan, len(seeds))
        data = mutate(seeds[index], mutations)
        note(f"seed {index}, mutations {mutations}: {data!r}")
        file = where(index)
        _overwrite(file, data)
        report.examples += 1
        report.distinct.add(data)
        try:
            result = read(file)
        except ProjectError as exc:
            message = str(exc)
            assert "\n" not in message.strip(), f"a refusal of more than one line: {message!r}"
            accepted = (str(file), file.name, *names)
            assert any(n in message for n in accepted), f"a refusal that names no file ({accepted}): {message!r}"
            report.refused += 1
            return
        if check is not None:
            check(result)
        report.parsed += 1

    start, cpu = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy's overflow, say: a value the reader did not look at
        property_()
    report.seconds, report.cpu_seconds = time.perf_counter() - start, time.process_time() - cpu
    print(f"fuzz {read!r}: {report}")
    return report


@pytest.fixture
def fuzz_reader() -> Callable[..., FuzzReport]:
    """:func:`run_fuzz`, for the ``test_*_fuzz.py`` files (skipped where hypothesis is not installed)."""
    pytest.importorskip("hypothesis", reason="hypothesis is not installed (pip install -c constraints.txt -e "
                                             "'.[test]')")
    return run_fuzz


# ----------------------------------------------------------------------------------- shared data, reference facts
REPOSITORY = Path(__file__).resolve().parents[1]
SHARED_ENV = "CNNSLAM_SHARED"  # overrides where the shared data folder is
REFERENCE_FACTS = REPOSITORY / "tests" / "reference_facts.toml"


def shared_root() -> Path:
    """The shared data folder: ``$CNNSLAM_SHARED`` when set, else ``../shared`` beside the repository."""
    value = os.environ.get(SHARED_ENV)
    return Path(value).expanduser().resolve() if value else (REPOSITORY.parent / "shared").resolve()


def find_shared(relative: str, *names: str) -> Path:
    """``relative`` inside the shared data folder (:func:`shared_root`), which must hold ``names`` too; skips the
    calling test, with what is missing and how to provide it, where it is absent."""
    path = shared_root() / relative
    missing = [n for n in names if not (path / n).is_file()] if path.is_dir() else [""]
    if missing:
        what = path if missing == [""] else ", ".join(str(path / n) for n in missing)
        pytest.skip(f"shared data not found: {what} (the folder ../shared beside the repository, or set {SHARED_ENV} "
                    "to a copy of it)")
    return path


@pytest.fixture(scope="session")
def shared_data() -> Callable[..., Path]:
    """:func:`find_shared`: ``shared_data("data/real/x", "rgb.txt")`` -> the folder, or the test skipped."""
    return find_shared


@pytest.fixture(scope="session")
def reference_facts() -> dict[str, Any]:
    """The reference figures the tests assert, with their sources (``tests/reference_facts.toml``)."""
    return tomllib.loads(REFERENCE_FACTS.read_text())


@pytest.fixture(scope="session")
def tum_dir(reference_facts: dict[str, Any]) -> Path:
    """The shared TUM trajectory files (``data/tum``: the reference cases' ground truths and estimates); the test is
    skipped where they are absent."""
    cases = reference_facts["trajectory"]["cases"]
    names = [name for case in cases for name in (case["groundtruth"], case["estimate"])]
    return find_shared(reference_facts["trajectory"]["folder"], *names)


def cpu_label() -> str:
    """This CPU as the pinned-digest tables name it: its model name and its widest SIMD extension of
    :data:`eval.bench.environment.ISA_FLAGS` (e.g. ``AMD EPYC, avx2``): what decides numpy's and OpenCV's kernels."""
    from eval.bench.environment import machine_description

    machine = machine_description()
    return f"{machine['cpu']}, {machine['isa'][0] if machine['isa'] else 'none'}"


def check_pinned(got: Any, recorded: Mapping[str, Any], checked_by: str) -> Any:
    """The digests ``got`` (a digest, or a mapping of them) must equal on this CPU: ``recorded`` maps a
    :func:`cpu_label` (or a name such as ``unrecorded`` for a machine whose CPU was not written down) to the digests
    measured there. On a recorded CPU, its own; on another, ``got`` itself where it is one of the recorded ones; else
    the test is skipped with this CPU's label and the test that checks the same computation's figures within
    tolerance there (``checked_by``): the last bits of vectorised float kernels differ between instruction sets, so
    bytes are pinned per CPU and never across. Use: ``assert got == pinned_bytes(got, recorded, "test_x")``."""
    label = cpu_label()
    if label in recorded:
        return recorded[label]
    if any(got == want for want in recorded.values()):
        return got
    pytest.skip(f"this CPU ({label}) gives other bytes than the CPUs recorded ({', '.join(recorded)}): none pinned "
                f"here; {checked_by} checks the figures within tolerance; record this CPU's digests to pin its bytes")


@pytest.fixture(scope="session")
def pinned_bytes() -> Callable[[Any, Mapping[str, Any], str], Any]:
    """:func:`check_pinned`: ``assert digest == pinned_bytes(digest, {cpu label: digest}, "test_x_figures")``."""
    return check_pinned
