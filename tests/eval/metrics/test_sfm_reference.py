"""The SfM reference: COLMAP-to-OpenCV camera conversion, metric scale, the rotation-angle ratio, and a rendered
sequence with a known camera self-calibrated and reconstructed end to end (known answers: the rendered camera, its
lens, its poses)."""

from __future__ import annotations

import json
from dataclasses import replace

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from eval.metrics.sfm_reference import SfmError, colmap_to_opencv_camera, metric_scale, nearest_depth
from eval.metrics.trajectory import PoseTrajectory
from eval.metrics.trajectory_metrics import rotation_angle_ratio


def test_colmap_cameras_become_opencv_cameras():
    cam = colmap_to_opencv_camera("RADIAL", [500.0, 320.0, 240.0, 0.1, -0.05], 640, 480)
    K = cam.intrinsics
    assert (K.fx, K.fy, K.cx, K.cy, K.width) == (500.0, 500.0, 319.5, 239.5, 640)  # COLMAP's pixel centres: +0.5
    assert cam.distortion == (0.1, -0.05, 0.0, 0.0, 0.0)
    simple = colmap_to_opencv_camera("SIMPLE_RADIAL", [400.0, 160.0, 120.0, 0.02], 320, 240)
    assert simple.distortion == (0.02, 0.0, 0.0, 0.0, 0.0) and simple.intrinsics.cx == 159.5
    opencv = colmap_to_opencv_camera("OPENCV", [500, 505, 320, 240, 0.1, -0.2, 0.001, 0.002], 640, 480)
    assert (opencv.intrinsics.fy, opencv.distortion) == (505.0, (0.1, -0.2, 0.001, 0.002, 0.0))
    with pytest.raises(SfmError, match="valid models"):
        colmap_to_opencv_camera("FOV", [500, 320, 240, 0.5], 640, 480)
    with pytest.raises(SfmError, match="5 parameters"):
        colmap_to_opencv_camera("SIMPLE_RADIAL", [500, 320, 240, 0.1, 0.0], 640, 480)


def test_the_camera_file_reads_back(tmp_path):
    from sim_envs.camera import Intrinsics
    from sim_envs.errors import FormatError
    from sim_envs.folders.datasets import camera_file_text, read_camera_file

    cam = colmap_to_opencv_camera("RADIAL", [526.5, 320.0, 240.0, 0.01, -0.05], 640, 480)
    (tmp_path / "camera.toml").write_text(camera_file_text(cam, "self-calibrated\nsecond line"))
    assert read_camera_file(tmp_path / "camera.toml") == cam  # exactly, at its own size

    model = read_camera_file(tmp_path / "camera.toml", 640, 480)
    assert model.intrinsics == Intrinsics(526.5, 526.5, 319.5, 239.5, 640, 480)
    assert model.distortion == cam.distortion
    with pytest.raises(FormatError, match="camera is for 640x480 images but the images are 320x240"):
        read_camera_file(tmp_path / "camera.toml", 320, 240)  # another resolution's camera is refused


def test_metric_scale_is_the_median_depth_ratio():
    rng = np.random.default_rng(0)
    z = rng.uniform(0.5, 4.0, 2000)
    sensor = z * 2.5 * (1 + rng.normal(0, 0.01, z.size))
    sensor[:300] = rng.uniform(0.3, 4.0, 300)  # misregistered at depth edges
    sensor[300:400] = 0.0  # no measurement
    scale, used = metric_scale(z, sensor)
    assert scale == pytest.approx(2.5, rel=0.01) and used == 1900
    with pytest.raises(SfmError, match="only 10 observations"):
        metric_scale(z[:10], sensor[400:410])
    with pytest.raises(SfmError, match="differ in length"):
        metric_scale(z, sensor[:5])


def test_nearest_depth_reads_inside_the_image_only():
    depth = np.arange(12, dtype=np.float32).reshape(3, 4)
    uv = np.array([[0.0, 0.0], [3.4, 2.4], [1.6, 0.6], [-0.6, 1.0], [4.0, 0.0]])
    np.testing.assert_array_equal(nearest_depth(depth, uv), [0.0, 11.0, 6.0, 0.0, 0.0])


def test_rotation_angle_ratio_of_a_camera_that_turns_nine_tenths_as_far():
    t = np.arange(60) / 30.0
    angles = np.radians(40.0) * np.sin(t)  # up to 40 deg about a fixed axis
    axis = np.array([0.3, -0.9, 0.3]) / np.linalg.norm([0.3, -0.9, 0.3])

    def poses(scale: float) -> np.ndarray:
        T = np.tile(np.eye(4), (t.size, 1, 1))
        T[:, :3, :3] = Rotation.from_rotvec(scale * angles[:, None] * axis).as_matrix()
        T[:, :3, 3] = np.c_[t, 0 * t, 0 * t]
        return T

    gt, est = PoseTrajectory(t, poses(1.0)), PoseTrajectory(t, poses(0.9))
    ratio, pairs = rotation_angle_ratio(gt, est, 0.5, 2.0)
    assert ratio == pytest.approx(0.9, abs=1e-9) and pairs > 20
    assert rotation_angle_ratio(gt, gt)[0] == pytest.approx(1.0)
    still = PoseTrajectory(t, np.tile(np.eye(4), (t.size, 1, 1)))
    assert np.isnan(rotation_angle_ratio(still, still)[0])


# ------------------------------------------------------------------------------- a rendered camera, end to end
pycolmap = pytest.importorskip("pycolmap", reason="pycolmap is not installed (the sfm extra: pip install -c "
                               "constraints.txt -e '.[sfm]')")
LENS = (0.12, -0.08, 0.0, 0.0, 0.0)  # a Kinect-like barrel lens COLMAP's RADIAL model can express


def _rendered(n: int, lens: tuple[float, ...]):
    from sim_envs.sensor.camera_effects import CameraEffects
    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    spec = replace(get_sequence("office0").with_frames(n), width=320, height=240)
    return SimulatedSequence(with_camera(spec, CameraEffects(name="lens", distortion=lens)))


# Self-calibration needs views that span enough motion: on office0's first 72 or 150 frames (0.6 / 1.3 m) COLMAP's
# focal length came out 2 % / 9 % off and its rotation 0.92 / 1.09 times the truth's; on 300 frames (2.6 m, every
# third) it is within 1 % and 0.975-0.986. These tests use the 300 frames.
FRAMES, STEP = 300, 3


@pytest.mark.slow  # > 5 s: the full lane only
def test_self_calibration_recovers_a_rendered_lens(tmp_path):
    from eval.metrics.sfm_reference import reconstruct, reference_trajectory
    from eval.metrics.trajectory_metrics import evaluate_trajectory

    seq = _rendered(FRAMES, LENS)
    try:
        paths = []
        for i in range(0, len(seq), STEP):
            paths.append(tmp_path / f"raw{i:03d}.png")
            cv2.imwrite(str(paths[-1]), cv2.cvtColor(seq.raw_rgb(i), cv2.COLOR_RGB2BGR))
        model = reconstruct(paths, tmp_path / "colmap")
        ref = reference_trajectory(model, seq.timestamps[::STEP])
        truth = seq.sensor_intrinsics  # the rendered (distorted) camera, not the undistorted delivered one
        gt = PoseTrajectory(ref.timestamps, seq.poses[::STEP][ref.frame_indices])
    finally:
        seq.close()
    assert ref.registered_share == 1.0 and ref.reprojection_px < 1.0
    assert ref.camera.intrinsics.fx == pytest.approx(truth.fx, rel=0.02)
    assert ref.camera.distortion[0] == pytest.approx(LENS[0], abs=0.05)
    est = PoseTrajectory(ref.timestamps, ref.T_world_cam)
    assert rotation_angle_ratio(gt, est)[0] == pytest.approx(1.0, abs=0.04)
    metrics = evaluate_trajectory(gt, est, alignment="sim3").flat_metrics()
    assert metrics["ate_sim3_rmse"] < 0.02 and metrics["rot_deg_orient_rmse"] < 1.0  # on a 2.6 m path


@pytest.mark.slow  # > 5 s: the full lane only
def test_the_reference_command_on_an_exported_folder(tmp_path, capsys):
    from cnnslam.cli import main
    from sim_envs.folders.datasets import export_tum_rgbd, read_camera_file

    seq = _rendered(FRAMES, (0.0,) * 5)
    try:
        folder = export_tum_rgbd(seq, tmp_path / "folder", progress=False)
        fx = seq.intrinsics.fx
    finally:
        seq.close()
    out = tmp_path / "ref"
    assert main(["reference", str(folder), "--step", str(STEP), "--out", str(out)]) == 0
    summary = json.loads((out / "reference.json").read_text())
    n = FRAMES // STEP
    assert summary["schema"] == "cnnslam-reference/1" and summary["reference"]["registered"] == n
    assert summary["camera"]["fx"] == pytest.approx(fx, rel=0.02) and abs(summary["camera"]["k1"]) < 0.03
    cmp = summary["ground_truth_vs_reference"]
    assert cmp["scale"] == pytest.approx(1.0, abs=0.03)  # scaled to metres by the rendered depth, not the poses
    assert cmp["ate_se3_rmse"] < 0.03 and cmp["rotation_ratio"] == pytest.approx(1.0, abs=0.04)
    assert read_camera_file(out / "camera.toml").intrinsics.fx == pytest.approx(summary["camera"]["fx"])
    assert len(np.loadtxt(out / "reference.tum")) == n and (out / "reference.png").stat().st_size > 10_000
    assert "SfM reference" in capsys.readouterr().out


def test_bad_input_gets_one_clear_error(tmp_path, capsys):
    from cnnslam.cli import main
    from eval.metrics.sfm_reference import reconstruct

    with pytest.raises(SfmError, match="at least 3 images"):
        reconstruct([tmp_path / "a.png"], tmp_path / "w")
    with pytest.raises(SfmError, match="not found"):
        reconstruct([tmp_path / f"{i}.png" for i in range(3)], tmp_path / "w")
    with pytest.raises(SfmError, match="valid PINHOLE, SIMPLE_RADIAL"):
        reconstruct([tmp_path / f"{i}.png" for i in range(3)], tmp_path / "w", camera_model="FISHEYE")
    assert main(["reference", "office0", "--out", str(tmp_path / "o")]) == 2  # refused before COLMAP
    assert "simulated sequence" in capsys.readouterr().err
