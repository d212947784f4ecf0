"""Property-based test of the dataset list reader :func:`eval.bench.sequence_resolve.load_dataset_list`
(``fuzz_reader``: tests/conftest.py): mutated valid ``datasets.toml`` files give valid entries, or one
:class:`SuiteError` line naming the list file (or the reference trajectory it names)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from eval.bench.sequence_resolve import DatasetEntry, load_dataset_list

pytestmark = pytest.mark.slow  # 10 000 inputs per reader: about 10 s of CPU each

DATASETS_SEEDS = (
    '[datasets]\noffice = "office_folder"\n\n[datasets.fr1_desk]\npath = "data/rgbd_dataset_freiburg1_desk"\n'
    'camera = "tum_fr1"\nsize = [320, 240]\ndepth_scale = 5000\nreference = "ref.tum"\n',
    '# my folders\n[datasets.kitchen]\npath = "../kitchen"\nsize = "native"\ncamera = "cam.toml"\n',
    '[datasets]\n"fr2.xyz" = "./fr2"\nlr_kt0 = "icl/lr kt0"\n',
)
REFERENCE = "# timestamp tx ty tz qx qy qz qw\n0.0 0 0 0 0 0 0 1\n0.1 0.01 0 0 0 0 0 1\n"


def _check_entries(entries: dict[str, DatasetEntry]) -> None:
    for name, entry in entries.items():
        assert isinstance(entry, DatasetEntry) and entry.name == name and entry.path.is_absolute()
        assert entry.camera is None or isinstance(entry.camera, str)
        assert entry.size == "native" or (len(entry.size) == 2 and min(entry.size) > 0)
        assert entry.depth_scale is None or (math.isfinite(entry.depth_scale) and entry.depth_scale > 0)
        assert entry.reference is None or entry.reference.is_file()
        entry.ref()  # a sequence of a suite


def test_dataset_list_reader_never_tracebacks(tmp_path: Path, fuzz_reader) -> None:
    (tmp_path / "ref.tum").write_text(REFERENCE)
    report = fuzz_reader(tmp_path / "datasets.toml", DATASETS_SEEDS, load_dataset_list, _check_entries)
    assert report.examples >= 10_000
    assert report.parse_share >= 0.5, str(report)
