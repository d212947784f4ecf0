"""The network on a real folder's frames: pooled depth metrics and the scale statistic, with known answers from a
stub predictor on a written fixture folder (no network needed)."""

import numpy as np
import pytest

from cnnslam.depthnet.predict import Prediction
from cnnslam.depthnet.validate import folder_validation_markdown, scale_stability, validate_folder
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
    assert result.to_dict()["depth_scale_error"] == pytest.approx(abs(1.0 / factor - 1.0), rel=1e-5)
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
    assert manifest["outputs"] == ["depthnet_real.json", "depthnet_real.md", "depthnet_real_scale.png"]
    assert list(manifest["inputs"].values()) == [hashlib.sha256(b"stub weights").hexdigest()]
    assert list(manifest["folders"].values()) == [folder_fingerprint(folder)["sha256"]]
    assert "cnnslam.depthnet.validate" in manifest["code"]["modules"]
    doc = json.loads((results / "depthnet_real.json").read_text())
    assert doc[0]["spread"]["indices"] == [0, 2, 4] and doc[0]["window"]["indices"] == [0, 1, 2, 3, 4]
    assert doc[0]["window"]["stability"]["change_median_pct"] == pytest.approx(0.0, abs=1e-6)  # a constant scale
    assert "## The network's scale over time" in (results / "depthnet_real.md").read_text()
    assert main(["train", "validate-folder", str(folder), "--weights", str(weights), "--window", "-1",
                 "--results", str(results)]) == 2  # fmt: skip


def test_scale_stability_of_a_constant_series() -> None:
    st = scale_stability([1.2] * 6)
    assert st.frames == 6 and st.pairs == 5 and st.median == pytest.approx(1.2)
    assert st.change_median_pct == 0.0 and st.change_p95_pct == 0.0 and st.cv == pytest.approx(0.0, abs=1e-12)
    assert st.iqr == pytest.approx((1.2, 1.2)) and st.range_5_95 == pytest.approx((1.2, 1.2)) and st.gap_frames == 1


def test_scale_stability_of_a_geometric_ramp() -> None:
    """s_t = 0.9 x 1.05^t every 10th frame at 30 Hz: every change is 100 ln 1.05 % over 10 frames, 1/3 s."""
    scales = [0.9 * 1.05**t for t in range(7)]
    st = scale_stability(scales, indices=[10 * t for t in range(7)], times=[t / 3 for t in range(7)])
    assert st.change_median_pct == pytest.approx(100 * np.log(1.05)) == pytest.approx(4.879, abs=1e-3)
    assert st.change_p95_pct == pytest.approx(100 * np.log(1.05))
    assert st.median == pytest.approx(0.9 * 1.05**3) and st.pairs == 6
    assert st.gap_frames == 10 and st.gap_s == pytest.approx(1 / 3)
    falling = scale_stability(scales[::-1])
    assert falling.change_median_pct == pytest.approx(st.change_median_pct)  # |log|: direction does not count
    assert falling.cv == pytest.approx(st.cv) and st.cv > 0.05


def test_a_frame_without_scale_breaks_the_series() -> None:
    """nan, 0 and negative scales are holes: out of the level statistics, and no change is taken across them."""
    st = scale_stability([1.0, 1.1, float("nan"), 2.0, 2.2, 0.0, 5.0])
    assert st.frames == 5 and st.pairs == 2  # (1.0, 1.1) and (2.0, 2.2): the 10 % steps, never 1.1 -> 2.0
    assert st.change_median_pct == pytest.approx(100 * np.log(1.1)) and st.median == pytest.approx(2.0)
    for empty in ([], [float("nan")] * 3):
        st = scale_stability(empty)
        assert st.frames == 0 and st.pairs == 0
        assert np.isnan(st.median) and np.isnan(st.change_median_pct) and np.isnan(st.gap_frames)
    one = scale_stability([1.3])
    assert one.frames == 1 and one.median == pytest.approx(1.3) and one.pairs == 0 and np.isnan(one.change_p95_pct)
    with pytest.raises(ValueError, match="one entry per scale"):
        scale_stability([1.0, 1.0], indices=[0])


@pytest.fixture(scope="module")
def ramp_folder(tmp_path_factory):
    """Five frames whose sensor depth grows by 10 % a frame (2 m x 1.1^k) at 30 Hz."""
    rng = np.random.default_rng(1)
    frames = [Frame(k, k / 30.0, rng.integers(0, 256, (48, 64, 3), dtype=np.uint8),
                    np.full((48, 64), 2.0 * 1.1**k, np.float32), np.eye(4)) for k in range(5)]  # fmt: skip
    source = FrameListSource("ramp", preset("icl", 64, 48), frames)
    return write_folder(source, tmp_path_factory.mktemp("real") / "ramp_7scenes", "7scenes")


def test_the_scale_series_of_evenly_spaced_and_consecutive_frames(ramp_folder):
    """Against a constant prediction the scale follows the sensor: 10 % a frame over the consecutive frames, 21 %
    over the evenly spaced ones two frames apart; the window is taken from the middle and only adds a series."""
    source = load_rgbd_folder(ramp_folder, size=None)
    result = validate_folder(StubPredictor(1.0), source, frames=3, window=3)
    spread, window = result.spread, result.window
    assert spread.indices == (0, 2, 4) and window.indices == (1, 2, 3) and result.frames == 3
    assert spread.scales == pytest.approx([1.1**k for k in (0, 2, 4)], rel=1e-3)  # depth stored in mm
    assert window.stability.change_median_pct == pytest.approx(100 * np.log(1.1), abs=0.02)
    assert spread.stability.change_median_pct == pytest.approx(100 * np.log(1.21), abs=0.02)
    assert spread.stability.gap_frames == 2 and window.stability.gap_s == pytest.approx(1 / 30, abs=1e-4)
    assert result.scale_median == pytest.approx(spread.stability.median)
    assert validate_folder(StubPredictor(1.0), source, frames=3).window.indices == ()
    whole = validate_folder(StubPredictor(1.0), source, frames=2, window=50).window
    assert whole.indices == (0, 1, 2, 3, 4) and whole.stability.pairs == 4
    md = folder_validation_markdown([result])
    assert "| ramp_7scenes (consecutive, frames 1-3) | 3 |" in md and "| 2 / 0.067 |" in md


def test_the_scale_plot_draws_both_series(ramp_folder):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cnnslam.depthnet.plots import plot_scale_over_frames

    result = validate_folder(StubPredictor(1.0), load_rgbd_folder(ramp_folder, size=None), frames=3, window=3)
    fig, ax = plt.subplots()
    plot_scale_over_frames(ax, result)
    xs = [tuple(line.get_xdata()) for line in ax.get_lines()]
    assert (0, 2, 4) in xs and (1, 2, 3) in xs
    plt.close(fig)
