"""Shared test machinery: :func:`shared_data` and :func:`tum_dir`, the shared data found from the repository
(``../shared`` beside it, or ``$CNNSLAM_SHARED``), the test skipped with what is missing where it is absent; and
:func:`reference_facts`, the reference figures the tests assert, with their sources
(``tests/reference_facts.toml``).
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

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
