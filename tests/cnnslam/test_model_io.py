"""PLY export of the global model (read back by our reader and by trimesh), the pictures, and `cnnslam map` end to
end on a few frames."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cnnslam.model.global_model import SurfelCloud
from cnnslam.model.model_io import VERTEX_DTYPE, PlyFormatError, read_ply, write_ply
from cnnslam.model.model_render import (
    PALETTE,
    label_colours,
    overview_camera,
    project,
    render_map_views,
    save_map_figure,
)


def _cloud(n: int = 500, seed: int = 0) -> SurfelCloud:
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(n, 3)).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    labels = rng.integers(0, 4, n).astype(np.uint8)
    labels[:5] = 255
    probs = np.eye(4, dtype=np.float32)[np.minimum(labels, 3)]
    return SurfelCloud(
        positions=rng.uniform(-3, 3, (n, 3)).astype(np.float32), normals=normals,
        colours=rng.integers(0, 256, (n, 3)).astype(np.uint8), labels=labels, label_probs=probs,
        confidence=rng.uniform(0, 20, n).astype(np.float32), radius=np.full(n, 0.01, np.float32),
        observations=np.ones(n, np.uint32), anchors=np.zeros(n, np.int32))


def test_ply_round_trip_with_our_reader(tmp_path):
    cloud = _cloud()
    path = write_ply(tmp_path / "m.ply", cloud, comments=["sequence office0", "two\nlines"])
    props, comments = read_ply(path)
    assert list(props) == list(VERTEX_DTYPE.names)
    assert list(props)[:9] == ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"]
    assert np.array_equal(np.stack([props["x"], props["y"], props["z"]], 1), cloud.positions)
    assert np.array_equal(np.stack([props["nx"], props["ny"], props["nz"]], 1), cloud.normals)
    assert np.array_equal(np.stack([props["red"], props["green"], props["blue"]], 1), cloud.colours)
    assert np.array_equal(props["label"], cloud.labels) and np.array_equal(props["confidence"], cloud.confidence)
    assert "sequence office0" in comments and "two lines" in comments
    header = path.read_bytes()[:600].decode("ascii", errors="replace")
    assert header.startswith("ply\nformat binary_little_endian 1.0\n") and "element vertex 500\n" in header
    assert not (tmp_path / "m.ply.part").exists()


def test_ply_is_read_by_trimesh(tmp_path):
    trimesh = pytest.importorskip("trimesh", reason="trimesh is not installed (a core dependency: "
                                                    "pip install -c constraints.txt -e '.[dev]')")
    cloud = _cloud(200, seed=1)
    loaded = trimesh.load(write_ply(tmp_path / "m.ply", cloud))
    assert isinstance(loaded, trimesh.PointCloud)
    assert np.allclose(loaded.vertices, cloud.positions)
    assert np.array_equal(np.asarray(loaded.colors)[:, :3], cloud.colours)
    raw = loaded.metadata["_ply_raw"]["vertex"]["data"]
    assert np.array_equal(raw["label"], cloud.labels) and np.allclose(raw["confidence"], cloud.confidence)


def test_reader_rejects_what_it_does_not_read(tmp_path):
    (tmp_path / "a.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n")
    with pytest.raises(PlyFormatError, match="ascii"):
        read_ply(tmp_path / "a.ply")
    (tmp_path / "b.ply").write_bytes(b"not a ply\n")
    with pytest.raises(PlyFormatError, match="magic"):
        read_ply(tmp_path / "b.ply")


def test_overview_picture_shows_the_model_and_the_trajectory(tmp_path):
    # a floor (label 0) and a wall (label 1) in the first camera's frame (y down), the camera path along x
    g = np.linspace(-2, 2, 81)
    X, Z = np.meshgrid(g, g + 3.0)
    floor = np.stack([X.ravel(), np.full(X.size, 1.5), Z.ravel()], 1)
    Xw, Yw = np.meshgrid(g, np.linspace(-1.0, 1.5, 51))
    wall = np.stack([Xw.ravel(), Yw.ravel(), np.full(Xw.size, 5.0)], 1)
    n = len(floor) + len(wall)
    normals = np.concatenate([np.tile([0, -1, 0], (len(floor), 1)), np.tile([0, 0, -1], (len(wall), 1))])
    labels = np.concatenate([np.zeros(len(floor)), np.ones(len(wall))]).astype(np.uint8)
    cloud = SurfelCloud(np.concatenate([floor, wall]).astype(np.float32), normals.astype(np.float32),
                        np.full((n, 3), 120, np.uint8), labels, np.eye(4, dtype=np.float32)[labels],
                        np.ones(n, np.float32), np.full(n, 0.03, np.float32), np.ones(n, np.uint32),
                        np.zeros(n, np.int32))
    traj = np.tile(np.eye(4), (20, 1, 1))
    traj[:, 0, 3] = np.linspace(-1, 1, 20)
    views = render_map_views(cloud, traj, size=(240, 320), keyframes=traj[::5])
    assert views.rgb.shape == views.labels.shape == (240, 320, 3)
    assert views.keyframe_uv.shape == (4, 2, 2) and np.isfinite(views.keyframe_uv).all()
    assert (views.keyframe_uv[:, 1, 1] < views.keyframe_uv[:, 0, 1]).all()  # looking away from the viewer: upwards
    drawn = (views.labels != 255).any(axis=2)
    assert 0.1 < drawn.mean() < 0.95
    # both palette colours appear (shaded), and the trajectory projects inside the picture
    for c in (0, 1):
        close = np.abs(views.labels[drawn].astype(int) - PALETTE[c].astype(int) * 0.75).max(axis=1) < 80
        assert close.any()
    assert np.isfinite(views.trajectory_uv).all()
    assert (views.trajectory_uv >= -1).all() and (views.trajectory_uv[:, 0] <= 320).all()
    uv, z = project(traj[:, :3, 3], views.camera)
    assert (z > 0).all() and np.allclose(uv, views.trajectory_uv)
    # the virtual camera is above the trajectory (up = -y of the cameras) and looks down at the model
    cam = overview_camera(traj, cloud.positions, (240, 320))
    assert cam.T_world_cam[1, 3] < traj[:, 1, 3].min() and cam.T_world_cam[1, 2] > 0
    assert (label_colours(np.array([255, 7], np.uint8)) == 170).all()
    path = save_map_figure(tmp_path / "map.png", views, "test")
    assert path.stat().st_size > 10_000


def test_map_command_end_to_end(tmp_path):
    """`cnnslam map` on 8 frames with the Laina baseline's development variant: PLY, picture and metrics."""
    from cnnslam.cli import main

    out = tmp_path / "run"
    code = main(["map", "office0", "--agent", "cnnslam.baselines.laina:GroundTruthAidedLainaAgent",
                 "--agent-options", '{"config": {"keyframe_every": 4}}', "--frames", "8", "--out", str(out),
                 "--gt-spacing", "0.05", "--no-progress", "--figure", str(tmp_path / "fig.png")])
    assert code == 0
    record = json.loads((out / "metrics.json").read_text())
    assert record["frames"] == 8 and record["keyframes"] == 2
    assert record["model"]["surfels"] > 1000 and record["peak_rss_mb"] > 0
    recon = record["metrics"]["reconstruction"]
    assert 0 < recon["accuracy_mean"] < 0.5 and 0 < recon["completeness_within"] <= 1
    assert record["metrics"]["semantic"]["n_points"] > 0
    for key in ("semantic_measurements", "semantic_measurements_exact_geometry"):
        scores = record["metrics"][key]  # every fused measurement scored; one label per surfel cannot beat purity
        assert scores["n_elements"] > 1000 and 0 < scores["fused_accuracy"] <= scores["purity"] <= 1
    props, _ = read_ply(out / "model.ply")
    assert len(props["x"]) == record["model"]["surfels"]
    assert (tmp_path / "fig.png").exists() and (out / "map.png").exists()
    assert json.loads((tmp_path / "fig.json").read_text())["frames"] == 8  # the picture's metrics beside it
    manifest = json.loads((tmp_path / "fig.provenance.json").read_text())  # and what made both
    assert manifest["outputs"] == ["fig.json", "fig.png"] and manifest["command"].startswith("cnnslam map")
    assert "cnnslam.baselines.laina" in manifest["code"]["modules"] and manifest["inputs"] == {}
    assert main(["map", "office0", "--agent-options", "[1]", "--out", str(out)]) == 2  # refused before the run


def test_evidence_maps_hold_the_ground_truth_one_hot_and_whether_the_cnn_was_right():
    from types import SimpleNamespace

    from cnnslam.tools.map_replay import evidence_maps

    probs = np.zeros((2, 2, 4), np.float32)
    probs[..., 1] = 1.0  # the CNN says class 1 everywhere
    gt = np.array([[1, 2], [255, 1]], np.uint8)  # 255: no ground-truth label
    (maps,) = evidence_maps([SimpleNamespace(labels=probs)], [SimpleNamespace(labels=gt)], 4)
    assert maps.shape == (2, 2, 6)
    assert maps[0, 0].tolist() == [0, 1, 0, 0, 1, 0] and maps[0, 1].tolist() == [0, 0, 1, 0, 0, 1]
    assert maps[1, 0].tolist() == [0] * 6 and maps[1, 1].tolist() == [0, 1, 0, 0, 1, 0]


def test_map_command_takes_the_agents_live_model(tmp_path):
    """The paper's agent hands back the model its key-frame thread fused: `cnnslam map` fuses nothing itself."""
    from cnnslam.cli import main

    out = tmp_path / "live"
    code = main(["map", "office0", "--agent", "cnnslam.agent:GroundTruthAidedAgent", "--frames", "12", "--out",
                 str(out), "--gt-spacing", "0.05", "--no-progress"])
    assert code == 0
    record = json.loads((out / "metrics.json").read_text())
    assert record["fusion"]["source"].startswith("live") and record["model"]["surfels"] > 1000
    assert 0 < record["metrics"]["reconstruction"]["completeness_within"] <= 1
