"""The shipped network as a model file (cnnslam/depthnet/export_model.py, ``cnnslam train export-onnx``), run by
CNN-SLAM through a method table as a user's network would be."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cnnslam.errors import CnnSlamError

pytest.importorskip("onnx", reason="onnx is not installed (pip install -c constraints.txt -e '.[dev]')")
pytest.importorskip("onnxruntime", reason="onnxruntime is not installed (pip install -c constraints.txt -e '.[dev]')")

REPO = Path(__file__).resolve().parents[2]
FRAMES = 40  # of office0@kinect, the quick suite's first sequence
TRAJECTORY_METRICS = ("ate_rmse", "rot_deg_rmse", "rot_deg_orient_rmse", "tracked_share")


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> dict[str, Path]:
    from cnnslam.depthnet.export_model import export_model_file

    folder = tmp_path_factory.mktemp("export")
    return {kind: export_model_file(folder / name).path for kind, name in (("onnx", "depthnet.onnx"),
                                                                          ("torchscript", "depthnet.pt"))}


def _methods_file(folder: Path, model: Path) -> Path:
    """A user's method table: CNN-SLAM with the exported network, everything else as the shipped method's."""
    path = folder / "methods.toml"
    path.write_text(textwrap.dedent(f"""\
        [methods."CNN-SLAM (ONNX)"]
        entry_point = "cnnslam.agent:CnnSlamAgent"
        kwargs = {{ preset = "cnn_slam", threads = false, predictor = {json.dumps(str(model))} }}
        seed = ["config.system.seed", "predictor_options.jitter_seed"]
        metrics = ["trajectory", "depth"]
        description = "CNN-SLAM with the shipped network exported to ONNX"
        inputs = [{json.dumps(str(model))}]
        """))
    return path


def _frames(n: int, every: int) -> list[tuple[np.ndarray, np.ndarray]]:
    import gymnasium as gym

    import sim_envs  # noqa: F401 - registers the environments

    env = gym.make("sim_envs/office0-v0", max_frames=n * every)
    obs, _ = env.reset()
    out = []
    for i in range(n * every):
        if i % every == 0:
            out.append((obs["rgb"].copy(), np.asarray(obs["intrinsics"], np.float64)))
        obs, *_ = env.step({"T_world_cam": np.eye(4), "tracked": 1})
    env.close()
    return out


@pytest.mark.slow
def test_export_writes_the_model_and_its_sidecar(exported) -> None:
    from cnnslam.depthnet.weights_io import DEFAULT_MANIFEST

    manifest = json.loads(DEFAULT_MANIFEST.read_text())
    for path in exported.values():
        doc = json.loads(path.with_name(path.name + ".json").read_text())
        assert doc["train_focal"] == manifest["train_focal"] and doc["train_size"] == manifest["train_size"]
        assert doc["normalisation"] == "imagenet" and doc["class_output"] == "logits"
        assert doc["exported_from"]["weights_sha256"] == manifest["weights_sha256"]


@pytest.mark.slow
def test_the_exported_network_predicts_what_the_torch_predictor_does(exported) -> None:
    from cnnslam.depth.model_file import ModelFilePredictor
    from cnnslam.depthnet.predict import load_predictor

    torch_net = load_predictor(num_threads=1)
    predictors = {kind: ModelFilePredictor(path, num_threads=1) for kind, path in exported.items()}
    worst = {kind: 0.0 for kind in predictors}
    for rgb, intrinsics in _frames(3, 10):
        ref = torch_net.predict(rgb, intrinsics)
        for kind, p in predictors.items():
            out = p.predict(rgb, intrinsics)
            diff = np.abs(out.depth - ref.depth)
            worst[kind] = max(worst[kind], float(diff.max()))
            assert float((diff / ref.depth).max()) < 1e-5, kind  # float32 rounding of another back-end
            np.testing.assert_allclose(out.label_probs, ref.label_probs, atol=1e-5)
    print(f"max |depth - torch's| over 3 office0 frames: {worst}")


@pytest.mark.slow
def test_a_method_table_runs_the_onnx_network_without_the_network_package(exported, tmp_path) -> None:
    methods = _methods_file(tmp_path, exported["onnx"])
    script = textwrap.dedent(f"""\
        import json, sys
        import numpy as np
        from eval.bench.methods import load_methods
        from sim_envs.agent import load_agent

        method = load_methods({str(methods)!r})["CNN-SLAM (ONNX)"]
        agent = load_agent(method.entry_point, **method.agent_kwargs(0))
        h, w = 240, 320
        agent.reset(np.array([0.75 * w, 0.75 * w, (w - 1) / 2, (h - 1) / 2]), (h, w))
        rng = np.random.default_rng(0)
        for k in range(3):
            agent.step({{"rgb": rng.integers(0, 256, (h, w, 3), dtype=np.uint8), "timestamp": np.full(1, k / 30)}})
        out = agent.finish()
        print(json.dumps({{"predictor": type(agent.predictor).__name__, "keyframes": len(out.keyframes),
                          "depthnet": sorted(m for m in sys.modules if m.startswith("cnnslam.depthnet")),
                          "torch": "torch" in sys.modules}}))
        """)
    done = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["predictor"] == "ModelFilePredictor" and report["keyframes"] >= 1
    assert report["depthnet"] == []  # the network's package (and its weights) never loaded


@pytest.mark.slow
def test_a_short_run_with_the_onnx_network_is_within_the_quick_gate(exported, tmp_path) -> None:
    from eval.bench.gate_baseline import load_baseline
    from eval.bench.methods import load_methods
    from eval.bench.regress import compare_metric
    from eval.bench.sequence_ref import SequenceRef
    from eval.metrics.results import evaluate_episode
    from sim_envs.agent import load_agent
    from sim_envs.driver import run_episode

    baseline = load_baseline(REPO / "results" / "baselines" / "quick.json")
    ref = SequenceRef("office0", base="office0").with_camera_effects("kinect")
    table = {**load_methods(), **load_methods(_methods_file(tmp_path, exported["onnx"]))}
    figures = {}
    for name in ("CNN-SLAM", "CNN-SLAM (ONNX)"):
        method = table[name]
        env = ref.make_env(max_frames=FRAMES)
        try:
            episode = run_episode(env, load_agent(method.entry_point, **method.agent_kwargs(0)), progress=False)
        finally:
            env.close()
        figures[name] = evaluate_episode(episode).metrics
    print({name: {m: round(f[m], 6) for m in TRAJECTORY_METRICS} for name, f in figures.items()})
    for metric in TRAJECTORY_METRICS:
        key = f"{ref.name}/CNN-SLAM/{metric}"
        # the change the gate allows the figure (its calibrated one: k x the spread floating point makes), the torch
        # network's run standing in for the baseline
        row = compare_metric(key, figures["CNN-SLAM"][metric], figures["CNN-SLAM (ONNX)"][metric],
                             baseline.tolerance_for(key), baseline.allowed(key))
        assert row.status == "equal", row


@pytest.mark.slow  # imports torch and the network's package
def test_export_refuses_a_bad_extension_before_writing(tmp_path) -> None:
    from cnnslam.depthnet.export_model import export_model_file

    with pytest.raises(CnnSlamError, match="has extension '.h5'"):
        export_model_file(tmp_path / "net.h5")
    assert not any(tmp_path.iterdir())


def test_the_command_refuses_a_bad_extension_before_writing(tmp_path, capsys) -> None:
    from cnnslam.cli import main

    good, bad = tmp_path / "net.onnx", tmp_path / "net.h5"
    assert main(["train", "export-onnx", "--out", str(good), "--out", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cnnslam train export-onnx: error: ") and "'.h5'" in err and "\n" not in err
    assert not any(tmp_path.iterdir())  # nothing written, not even the valid first file
