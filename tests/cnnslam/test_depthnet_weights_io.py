"""cnnslam.depthnet.weights_io: the shipped weights match the SHA-256 their manifest records; a changed file is
refused at load with a message naming both; export writes the checksum of what it copied."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from cnnslam.depthnet.model import DepthSemanticNet, ModelConfig
from cnnslam.depthnet.weights_io import (
    DEFAULT_MANIFEST,
    DEFAULT_WEIGHTS,
    MANIFEST_FORMAT,
    check_weights_checksum,
    export_weights,
    file_sha256,
    load_weights,
    manifest_path_for,
    save_weights,
)
from cnnslam.errors import CnnSlamError

TINY = ModelConfig(base_width=8, decoder_min_channels=8, dropout=0.0)


def test_the_shipped_weights_match_their_manifest() -> None:
    manifest = json.loads(DEFAULT_MANIFEST.read_text())
    assert manifest["format"] == MANIFEST_FORMAT and manifest["weights_file"] == DEFAULT_WEIGHTS.name
    assert manifest["weights_bytes"] == DEFAULT_WEIGHTS.stat().st_size
    assert manifest["weights_sha256"] == hashlib.sha256(DEFAULT_WEIGHTS.read_bytes()).hexdigest()
    assert manifest_path_for(DEFAULT_WEIGHTS) == DEFAULT_MANIFEST
    assert check_weights_checksum(DEFAULT_WEIGHTS) == manifest["weights_sha256"]


def _shipped_copy(tmp_path: Path) -> tuple[Path, Path]:
    weights, manifest = tmp_path / "default.pt", tmp_path / "default.json"
    shutil.copyfile(DEFAULT_WEIGHTS, weights)
    shutil.copyfile(DEFAULT_MANIFEST, manifest)
    return weights, manifest


def test_a_tampered_copy_is_refused_at_load(tmp_path: Path) -> None:
    weights, manifest = _shipped_copy(tmp_path)
    assert load_weights(weights).train_size == (160, 120)  # the untouched copy loads
    data = bytearray(weights.read_bytes())
    data[len(data) // 2] ^= 0x01  # one bit of one parameter: torch would still load it
    weights.write_bytes(bytes(data))
    expected = json.loads(manifest.read_text())["weights_sha256"]
    with pytest.raises(CnnSlamError) as err:
        load_weights(weights)
    message = str(err.value)
    assert str(weights) in message and str(manifest) in message and expected in message
    assert hashlib.sha256(bytes(data)).hexdigest() in message and "\n" not in message
    with pytest.raises(CnnSlamError, match="changed after export"):
        check_weights_checksum(weights)


def test_weights_without_a_recorded_checksum_load_unchecked(tmp_path: Path) -> None:
    path = save_weights(tmp_path / "w.pt", DepthSemanticNet(TINY), 100.0, (64, 48))
    assert manifest_path_for(path) is None and check_weights_checksum(path) is None
    (tmp_path / "manifest.json").write_text(json.dumps({"format": MANIFEST_FORMAT, "steps": 1}))
    assert check_weights_checksum(path) is None  # an older manifest: nothing to compare
    (tmp_path / "w.json").write_text(json.dumps({"format": "something else", "weights_sha256": "0" * 64}))
    assert check_weights_checksum(path) is None  # not a depth-network manifest
    assert load_weights(path).config == TINY


def test_export_records_the_checksum_of_the_copy_and_refuses_a_mismatched_run(tmp_path: Path) -> None:
    run = tmp_path / "run"
    weights = save_weights(run / "weights.pt", DepthSemanticNet(TINY), 100.0, (64, 48))
    (run / "manifest.json").write_text(json.dumps({"format": MANIFEST_FORMAT, "weights_file": "weights.pt"}))
    doc = export_weights(weights, run / "manifest.json", tmp_path / "ship" / "default.pt")
    shipped = tmp_path / "ship" / "default.pt"
    on_disk = json.loads((tmp_path / "ship" / "default.json").read_text())
    assert on_disk == doc and doc["weights_file"] == "default.pt"
    assert doc["weights_sha256"] == file_sha256(weights) == hashlib.sha256(shipped.read_bytes()).hexdigest()
    assert doc["weights_bytes"] == shipped.stat().st_size
    assert load_weights(shipped).config == TINY
    (run / "manifest.json").write_text(json.dumps({"format": MANIFEST_FORMAT, "weights_sha256": "0" * 64}))
    with pytest.raises(CnnSlamError, match="records 0{64}"):
        export_weights(weights, run / "manifest.json", tmp_path / "other" / "default.pt")
    assert not (tmp_path / "other").exists()  # refused before anything was copied
    with pytest.raises(CnnSlamError, match="does not exist"):
        export_weights(run / "none.pt", run / "manifest.json", tmp_path / "other" / "default.pt")

