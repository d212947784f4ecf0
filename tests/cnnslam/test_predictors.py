"""Depth predictors by name (cnnslam/predictors.py): registered names, "module:Class" and model files."""

from __future__ import annotations

import numpy as np
import pytest

from cnnslam.agent import CnnSlamAgent
from cnnslam.depth.depth_prediction import DegradedGroundTruthPredictor
from cnnslam.errors import CnnSlamError
from cnnslam.predictors import check_predictor_spec, make_predictor, predictor_form

USER_MODULE = '''
import numpy as np


class FlatNet:
    """A user's predictor: flat depth, no classes."""

    def __init__(self, depth=2.0, train_focal=100.0):
        self.depth, self.train_focal = depth, train_focal

    def predict_raw(self, rgb):
        from types import SimpleNamespace

        return SimpleNamespace(depth=np.full(rgb.shape[:2], self.depth, np.float32), label_probs=None)


class NoFocal:
    def predict_raw(self, rgb):
        return None
'''


@pytest.fixture
def user_module(tmp_path, monkeypatch) -> str:
    (tmp_path / "my_depth_nets.py").write_text(USER_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    return "my_depth_nets"


def test_the_forms_of_a_predictor_name() -> None:
    assert predictor_form("network") == predictor_form("degraded_ground_truth") == "registered"
    assert predictor_form("models/net.onnx") == predictor_form("pkg:nets/net.PT") == "model_file"
    assert predictor_form("my.pkg.nets:FlatNet") == "class"
    for bad in ("netwerk", "my.pkg:", "a b:C", "net.bin"):
        with pytest.raises(CnnSlamError, match="valid predictors: network, degraded_ground_truth, "
                                               "'package.module:Class'"):
            predictor_form(bad)


def test_registered_names_build_as_before() -> None:
    p = make_predictor("degraded_ground_truth", seed=3)
    assert isinstance(p, DegradedGroundTruthPredictor)


def test_a_user_class_by_module_and_name(user_module: str) -> None:
    p = make_predictor(f"{user_module}:FlatNet", depth=3.0)
    assert p.predict_raw(np.zeros((4, 5, 3), np.uint8)).depth.shape == (4, 5) and p.train_focal == 100.0
    with pytest.raises(CnnSlamError, match="FlatNet.train_focal is -1.0; a depth predictor needs"):
        make_predictor(f"{user_module}:FlatNet", train_focal=-1.0)
    with pytest.raises(CnnSlamError, match="NoFocal.train_focal is None"):
        make_predictor(f"{user_module}:NoFocal")
    with pytest.raises(CnnSlamError, match="cannot be built with"):
        make_predictor(f"{user_module}:FlatNet", colour=1)
    with pytest.raises(CnnSlamError, match="has no class 'Missing'"):
        make_predictor(f"{user_module}:Missing")
    with pytest.raises(CnnSlamError, match="cannot import 'no_such_module_x'"):
        make_predictor("no_such_module_x:Net")


def test_a_user_class_runs_in_the_agent(user_module: str) -> None:
    agent = CnnSlamAgent(predictor=f"{user_module}:FlatNet", predictor_options={"depth": 2.5}, threads=False)
    h, w = 48, 64
    agent.reset(np.array([50.0, 50.0, w / 2, h / 2]), (h, w))
    agent.step({"rgb": np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8),
                "timestamp": np.zeros(1)})
    out = agent.finish()
    assert type(agent.predictor).__name__ == "FlatNet" and out.extras["predictor"] == f"{user_module}:FlatNet"


def test_the_agent_checks_its_predictor_when_built(user_module: str, tmp_path) -> None:
    with pytest.raises(CnnSlamError, match="unknown predictor 'netwerk'"):
        CnnSlamAgent(predictor="netwerk")
    with pytest.raises(CnnSlamError, match="has no class 'Missing'"):
        CnnSlamAgent(predictor=f"{user_module}:Missing")
    with pytest.raises(CnnSlamError, match="no depth model file at"):
        CnnSlamAgent(predictor=str(tmp_path / "none.onnx"), predictor_options={"train_focal": 100.0})
    (tmp_path / "net.onnx").write_bytes(b"")
    with pytest.raises(CnnSlamError, match="needs its training focal length"):
        CnnSlamAgent(predictor=str(tmp_path / "net.onnx"))
    CnnSlamAgent(preset="lsd", predictor="netwerk")  # a preset without the CNN never builds a predictor
    check_predictor_spec(object())  # an object passes as it is
    assert CnnSlamAgent()._predictor_spec == "network"  # the default is the shipped network, untouched
