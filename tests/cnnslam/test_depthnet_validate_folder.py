"""The network on a real folder's frames: pooled depth metrics and the scale statistic, with known answers from a
stub predictor on a written fixture folder (no network needed)."""

import numpy as np
import pytest

from cnnslam.depthnet.predict import Prediction
from cnnslam.depthnet.validate import folder_validation_markdown, validate_folder
from sim_envs.camera import preset
from sim_envs.folders.datasets import load_rgbd_folder, write_folder
from sim_envs.frames import Frame
from sim_envs.sources.simsource import FrameListSource


class StubPredictor:
    """Predicts ``factor x`` the truth (2 m everywhere) as the raw output for a camera of focal ``train_focal``."""

    train_focal = 100.0

    def __init__(self, factor: float) -> None:
        self.factor = factor

    def current_focal(self, intrinsics, image_size):
        return 150.0

    def predict_raw(self, rgb):
        h, w = rgb.shape[:2]
        depth = np.full((h, w), 2.0 * self.factor * self.train_focal / 150.0, np.float32)  # eq. 5 undoes f_cur/f_tr
        return Prediction(depth, np.full((h, w, 4), 0.25, np.float32))


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    rng = np.random.default_rng(0)
    frames = [Frame(k, k / 30.0, rng.integers(0, 256, (48, 64, 3), dtype=np.uint8),
                    np.full((48, 64), 2.0, np.float32), np.eye(4)) for k in range(5)]  # fmt: skip
    source = FrameListSource("tiny", preset("icl", 64, 48), frames)
    return write_folder(source, tmp_path_factory.mktemp("real") / "tiny_7scenes", "7scenes")


@pytest.mark.parametrize("factor", [1.0, 1.25])
def test_depth_metrics_and_scale_on_a_folder(folder, factor):
    result = validate_folder(StubPredictor(factor), load_rgbd_folder(folder, size=None), frames=3)
    assert result.frames == 3 and result.f_cur / result.f_tr == pytest.approx(1.5)
    assert result.adjusted.abs_rel == pytest.approx(factor - 1.0, abs=1e-5)  # eq. 5 gives factor x 2 m
    assert result.scale_median == pytest.approx(1.0 / factor, rel=1e-5)
    assert result.adjusted.percent_correct == (100.0 if factor == 1.0 else 0.0)
    assert result.to_dict()["scale_error"] == pytest.approx(abs(1.0 / factor - 1.0), rel=1e-5)
    assert result.gradient_scale_median == pytest.approx(1.0 / factor, rel=1e-5)  # a uniform error: the same there
    assert np.isnan(result.slope_median)  # the fixture's depth is flat: no range to compress
    assert "| tiny_7scenes (real) | 3 |" in folder_validation_markdown([result])


class RecordingPredictor(StubPredictor):
    """The stub, remembering every image it was given; ``model.config.num_classes`` as the network's."""

    class model:  # noqa: N801 - mirrors DepthNetPredictor.model.config
        class config:  # noqa: N801
            num_classes = 4

    def __init__(self) -> None:
        super().__init__(1.0)
        self.images: list[np.ndarray] = []

    def predict_raw(self, rgb):
        self.images.append(rgb.copy())
        return super().predict_raw(rgb)


def test_simulated_validation_through_a_camera_preset():
    from cnnslam.depthnet.report import report_markdown
    from cnnslam.depthnet.validate import validate_sequences

    seen = {}
    for camera in ("clean", "kinect"):
        stub = RecordingPredictor()
        report = validate_sequences(stub, names=("office0",), frames_per_sequence=1, camera_effects=camera)
        assert report.camera_effects == camera and report.to_dict()["camera_effects"] == camera
        assert report.overall.frames == 1
        seen[camera] = stub.images[0].astype(np.float32)
    assert np.abs(seen["clean"] - seen["kinect"]).mean() > 1.0  # the kinect camera's noise, exposure, vignetting
    assert "seen through the world's `kinect` camera" in report_markdown(report, None, None, "stub")


def test_the_command_writes_a_manifest_of_the_weights_and_the_folder(folder, tmp_path, monkeypatch):
    """``cnnslam train validate-folder``: its files and, beside them, the weights' SHA-256 and the folder's content
    fingerprint they were made from."""
    import hashlib
    import json

    import cnnslam.depthnet.predict as predict
    from cnnslam.cli import main
    from sim_envs.folders.folder_layouts import folder_fingerprint

    weights = tmp_path / "w.pt"
    weights.write_bytes(b"stub weights")
    monkeypatch.setattr(predict, "load_predictor", lambda path, num_threads=2: StubPredictor(1.0))
    results = tmp_path / "results"
    assert main(["train", "validate-folder", str(folder), "--weights", str(weights), "--frames", "3",
                 "--results", str(results)]) == 0  # fmt: skip
    manifest = json.loads((results / "depthnet_real.provenance.json").read_text())
    assert manifest["outputs"] == ["depthnet_real.json", "depthnet_real.md"]
    assert list(manifest["inputs"].values()) == [hashlib.sha256(b"stub weights").hexdigest()]
    assert list(manifest["folders"].values()) == [folder_fingerprint(folder)["sha256"]]
    assert "cnnslam.depthnet.validate" in manifest["code"]["modules"]
