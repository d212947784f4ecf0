"""A depth network from a model file (cnnslam/depth/model_file.py): the contract on small ONNX graphs built here."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cnnslam.depth.depth_prediction import DepthPredictor, predict_keyframe_depth
from cnnslam.depth.model_file import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    MODEL_FILE_FORMAT,
    ModelFileContract,
    ModelFilePredictor,
    read_sidecar,
    resolve_model_path,
    sidecar_path,
    write_sidecar,
)
from cnnslam.errors import CnnSlamError

onnx = pytest.importorskip("onnx", reason="onnx is not installed (pip install -c constraints.txt -e '.[dev]')")
pytest.importorskip("onnxruntime", reason="onnxruntime is not installed (pip install -c constraints.txt -e '.[dev]')")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

W, H = 16, 12


def _onnx(path, *, depth_weights=(0.0, 0.0, 0.0), depth_bias=2.0, classes: int | None = 4, depth_channels=1,
          size=(W, H), two_inputs=False, out_scale=1) -> str:
    """An ONNX graph: depth = 1x1 conv of the input (``depth_weights``, ``depth_bias``), class logits = 0, 1, ..
    per pixel (``classes`` channels; None: no class output); ``out_scale`` > 1 averages the outputs down by it."""
    w, h = size
    inputs = [helper.make_tensor_value_info("rgb", TensorProto.FLOAT, [1, 3, h, w])]
    if two_inputs:
        inputs.append(helper.make_tensor_value_info("extra", TensorProto.FLOAT, [1]))
    inits = [numpy_helper.from_array(np.tile(np.asarray(depth_weights, np.float32).reshape(1, 3, 1, 1),
                                             (depth_channels, 1, 1, 1)), "wd"),
             numpy_helper.from_array(np.full(depth_channels, depth_bias, np.float32), "bd")]
    nodes = [helper.make_node("Conv", ["rgb", "wd", "bd"], ["d0"])]
    pool = {"kernel_shape": [out_scale, out_scale], "strides": [out_scale, out_scale]}
    nodes.append(helper.make_node("AveragePool", ["d0"], ["depth"], **pool) if out_scale > 1
                 else helper.make_node("Identity", ["d0"], ["depth"]))
    outputs = [helper.make_tensor_value_info("depth", TensorProto.FLOAT, None)]
    if classes is not None:
        inits += [numpy_helper.from_array(np.zeros((classes, 3, 1, 1), np.float32), "wl"),
                  numpy_helper.from_array(np.arange(classes, dtype=np.float32), "bl")]
        nodes.append(helper.make_node("Conv", ["rgb", "wl", "bl"], ["l0"]))
        nodes.append(helper.make_node("AveragePool", ["l0"], ["logits"], **pool) if out_scale > 1
                     else helper.make_node("Identity", ["l0"], ["logits"]))
        outputs.append(helper.make_tensor_value_info("logits", TensorProto.FLOAT, None))
    graph = helper.make_graph(nodes, "tiny", inputs, outputs, inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return str(path)


def _image(h: int = H, w: int = W, value: int | None = None) -> np.ndarray:
    if value is not None:
        return np.full((h, w, 3), value, np.uint8)
    return np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_sidecar_contract_and_eq5(tmp_path) -> None:
    path = _onnx(tmp_path / "net.onnx")
    write_sidecar(path, ModelFileContract(train_focal=100.0, train_size=(W, H)), {"note": "made by a test"})
    doc = json.loads(sidecar_path(path).read_text())
    assert sidecar_path(path).name == "net.onnx.json" and doc["format"] == MODEL_FILE_FORMAT
    assert read_sidecar(path) == {"train_focal": 100.0, "train_size": [W, H], "normalisation": "imagenet",
                                  "class_output": None}
    p = ModelFilePredictor(path)
    assert isinstance(p, DepthPredictor)
    assert (p.train_focal, p.train_size, p.kind, p.class_output) == (100.0, (W, H), "onnx", "logits")
    raw = p.predict_raw(_image(2 * H, 2 * W))  # a frame twice the network's size: resized both ways
    assert raw.depth.shape == (2 * H, 2 * W) and raw.depth.dtype == np.float32
    np.testing.assert_allclose(raw.depth, 2.0, rtol=1e-6)
    expected = np.exp(np.arange(4.0)) / np.exp(np.arange(4.0)).sum()
    np.testing.assert_allclose(raw.label_probs, np.broadcast_to(expected, (2 * H, 2 * W, 4)), rtol=1e-5)
    # eq. 5: fx = fy = 300 at 2x the training size is f_cur = 150 at it: depth x 150 / 100
    intrinsics = np.array([300.0, 300.0, W - 0.5, H - 0.5])
    np.testing.assert_allclose(p.predict(_image(2 * H, 2 * W), intrinsics).depth, 3.0, rtol=1e-6)
    kf = predict_keyframe_depth(p, _image(2 * H, 2 * W), intrinsics, focal_adjustment=True)
    assert kf.focal_ratio == pytest.approx(1.5) and float(kf.depth.mean()) == pytest.approx(3.0)


def test_keywords_override_the_sidecar_and_the_input_shape_gives_the_size(tmp_path) -> None:
    path = _onnx(tmp_path / "net.onnx")
    write_sidecar(path, ModelFileContract(train_focal=100.0))
    p = ModelFilePredictor(path, train_focal=80.0)
    assert p.train_focal == 80.0 and p.train_size == (W, H)  # the size from the model's fixed input shape


@pytest.mark.parametrize(("normalisation", "expected"), [
    ("none", 100.0),
    ("unit", 100.0 / 255.0),
    ("imagenet", (100.0 / 255.0 - IMAGENET_MEAN[0]) / IMAGENET_STD[0]),
])
def test_input_normalisation(tmp_path, normalisation: str, expected: float) -> None:
    path = _onnx(tmp_path / "red.onnx", depth_weights=(1.0, 0.0, 0.0), depth_bias=0.0, classes=None)
    p = ModelFilePredictor(path, train_focal=50.0, normalisation=normalisation)
    assert p.class_output == "none"
    image = _image(value=0)
    image[..., 0] = 100  # the red channel: the graph's depth is its normalised value
    out = p.predict_raw(image)
    assert out.label_probs is None
    np.testing.assert_allclose(out.depth, expected, rtol=1e-6)


def test_an_output_smaller_than_the_input_is_resized(tmp_path) -> None:
    path = _onnx(tmp_path / "half.onnx", depth_weights=(1.0, 0.0, 0.0), depth_bias=0.0, out_scale=2)
    p = ModelFilePredictor(path, train_focal=50.0, normalisation="none")
    image = _image(value=0)
    image[..., 0] = 60
    out = p.predict_raw(image)
    assert out.depth.shape == (H, W) and out.label_probs.shape == (H, W, 4)
    np.testing.assert_allclose(out.depth, 60.0, rtol=1e-6)
    np.testing.assert_allclose(out.label_probs.sum(axis=-1), 1.0, rtol=1e-6)


def test_jitter_and_output_scale_as_the_network_predictor(tmp_path) -> None:
    path = _onnx(tmp_path / "net.onnx", depth_weights=(0.01, 0.02, 0.03))
    image = _image()
    plain = ModelFilePredictor(path, train_focal=100.0).predict_raw(image)
    a = ModelFilePredictor(path, train_focal=100.0, jitter_seed=3).predict_raw(image)
    b = ModelFilePredictor(path, train_focal=100.0, jitter_seed=3).predict_raw(image)
    assert a.depth.tobytes() == b.depth.tobytes() and a.depth.tobytes() != plain.depth.tobytes()
    np.testing.assert_allclose(a.depth, plain.depth, rtol=1e-5)
    scaled = ModelFilePredictor(path, train_focal=100.0, output_scale=1.5).predict_raw(image)
    np.testing.assert_allclose(scaled.depth, 1.5 * plain.depth, rtol=1e-6)


def test_threads_follow_num_threads_or_omp_num_threads(tmp_path, monkeypatch) -> None:
    path = _onnx(tmp_path / "net.onnx")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert ModelFilePredictor(path, train_focal=100.0).num_threads == 1
    assert ModelFilePredictor(path, train_focal=100.0, num_threads=2).num_threads == 2
    monkeypatch.delenv("OMP_NUM_THREADS")
    assert ModelFilePredictor(path, train_focal=100.0).num_threads == 0  # onnxruntime's own default


BAD = [
    ("missing.onnx", {"train_focal": 100.0}, "no depth model file at"),
    ("net.bin", {"train_focal": 100.0}, "has extension '.bin'; valid: .onnx"),
    ("net.onnx", {}, "needs its training focal length: give train_focal"),
    ("net.onnx", {"train_focal": 0}, "train_focal must be a finite positive focal length"),
    ("net.onnx", {"train_focal": "129"}, "train_focal must be a finite positive focal length"),
    ("net.onnx", {"train_focal": 100.0, "train_size": [32, 24]}, "takes 16x12 images, but train_size is 32x24"),
    ("net.onnx", {"train_focal": 100.0, "train_size": [16]}, "train_size must be [W, H]"),
    ("net.onnx", {"train_focal": 100.0, "normalisation": "zscore"}, "unknown normalisation 'zscore'"),
    ("net.onnx", {"train_focal": 100.0, "class_output": "soft"}, "unknown class_output 'soft'"),
    ("two_channels.onnx", {"train_focal": 100.0}, "first output is float32 of shape (1, 2, 12, 16)"),
    ("three_classes.onnx", {"train_focal": 100.0}, "class output has shape (1, 3, 12, 16)"),
    ("depth_only.onnx", {"train_focal": 100.0, "class_output": "logits"}, "returns one output, but class_output"),
    ("two_inputs.onnx", {"train_focal": 100.0}, "has 2 inputs"),
    ("garbage.onnx", {"train_focal": 100.0}, "cannot load the ONNX depth model"),
]


@pytest.mark.parametrize(("name", "options", "message"), BAD, ids=[f"{b[0]}-{b[2][:20]}" for b in BAD])
def test_bad_model_files_are_one_line_errors_at_construction(tmp_path, name: str, options: dict, message: str
                                                             ) -> None:
    _onnx(tmp_path / "net.onnx")
    (tmp_path / "net.bin").write_bytes(b"")
    _onnx(tmp_path / "two_channels.onnx", depth_channels=2)
    _onnx(tmp_path / "three_classes.onnx", classes=3)
    _onnx(tmp_path / "depth_only.onnx", classes=None)
    _onnx(tmp_path / "two_inputs.onnx", two_inputs=True)
    (tmp_path / "garbage.onnx").write_bytes(b"not a model")
    with pytest.raises(CnnSlamError) as err:
        ModelFilePredictor(tmp_path / name, **options)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_bad_sidecar_is_refused(tmp_path) -> None:
    path = _onnx(tmp_path / "net.onnx")
    sidecar_path(path).write_text(json.dumps({"format": "other", "train_focal": 1.0}))
    with pytest.raises(CnnSlamError, match="is not a depth model sidecar"):
        ModelFilePredictor(path)
    sidecar_path(path).write_text("{")
    with pytest.raises(CnnSlamError, match="cannot read the depth model's sidecar"):
        ModelFilePredictor(path)


def test_a_package_path_names_a_file_inside_an_installed_package() -> None:
    with pytest.raises(CnnSlamError, match=r"no depth model file at .*nowhere\.onnx' \(from 'cnnslam:nowhere\.onnx'\)"):
        resolve_model_path("cnnslam:nowhere.onnx")
    with pytest.raises(CnnSlamError, match="names package 'no_such_package_x', which is not installed"):
        resolve_model_path("no_such_package_x:net.onnx")


@pytest.mark.slow  # imports torch
def test_a_torchscript_file_needs_its_input_size(tmp_path) -> None:
    torch = pytest.importorskip("torch")

    class Half(torch.nn.Module):  # depth-only, (1, h/2, w/2): the red channel averaged down
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return torch.nn.functional.avg_pool2d(x[:, :1], 2)[:, 0]

    path = tmp_path / "half.pt"
    torch.jit.save(torch.jit.script(Half()), str(path))
    with pytest.raises(CnnSlamError, match="needs its input size: give train_size"):
        ModelFilePredictor(path, train_focal=50.0)
    p = ModelFilePredictor(path, train_focal=50.0, train_size=[W, H], normalisation="none", num_threads=1)
    image = _image(value=0)
    image[..., 0] = 40
    out = p.predict_raw(image)
    assert p.kind == "torchscript" and p.class_output == "none" and out.label_probs is None
    np.testing.assert_allclose(out.depth, 40.0, rtol=1e-6)
    (tmp_path / "bad.pt").write_bytes(b"not a model")
    with pytest.raises(CnnSlamError, match="cannot load .*bad.pt as a TorchScript depth model"):
        ModelFilePredictor(tmp_path / "bad.pt", train_focal=50.0, train_size=[W, H])
