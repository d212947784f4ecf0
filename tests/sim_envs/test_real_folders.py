"""Real RGB-D folders as frame sources: every layout (written at test time from an analytic scene by
``write_folder``), layout detection and its errors, depth scales, 7-Scenes poses, camera files and presets,
undistortion (against ``cv2.undistortPoints``), resizing to the processing resolution, the content fingerprint, and
the 7-Scenes folder in ``../shared/data/real`` when it is there."""

import json
import shutil
from pathlib import Path

import cv2
import gymnasium as gym
import numpy as np
import pytest

import sim_envs  # noqa: F401 - registers the environments
from sim_envs.camera import CameraModel, Intrinsics, camera_model, preset
from sim_envs.errors import FormatError, SimEnvError, UnknownNameError
from sim_envs.folders.datasets import (
    LAYOUTS,
    PROCESSING_SIZE,
    SEVEN_SCENES_COLOUR_SOURCE,
    SEVEN_SCENES_T_COLOUR_DEPTH,
    SIDE_FILE,
    RgbdFolder,
    detect_layout,
    folder_fingerprint,
    load_rgbd_folder,
    read_camera_file,
    read_pose_matrix,
    register_depth,
    write_folder,
)
from sim_envs.folders.folder_layouts import index_folder
from sim_envs.folders.formats import read_tum_image_list, read_tum_trajectory
from sim_envs.frames import Frame
from sim_envs.sensor.camera_calibration import depth_edge_alignment
from sim_envs.sources.simsource import FrameListSource


def look(position, yaw_deg, pitch_deg):
    """T_world_cam of an OpenCV camera at ``position`` looking along yaw/pitch, world z up."""
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    z = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    y = np.array([0.0, 0.0, -1.0]) - (-z[2]) * z
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    T[:3, 3] = position
    return T


def box_room(n: int = 4, intrinsics: Intrinsics | None = None) -> FrameListSource:
    """Frames ray-cast exactly inside the box [0, 4] x [0, 3] x [0, 2.5] m (checker texture), at k / 30 s."""
    K = intrinsics or preset("icl", 64, 48)
    room = np.array([4.0, 3.0, 2.5])
    frames = []
    for k in range(n):
        T = look([1.0 + 0.08 * k, 1.2 + 0.05 * k, 1.1], 10.0 + 4.0 * k, -5.0 + 2.0 * k)
        v, u = np.mgrid[0 : K.height, 0 : K.width]
        rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones(u.shape)], axis=-1) @ T[:3, :3].T
        best = np.full(u.shape, np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            for axis in range(3):
                for bound in (0.0, room[axis]):
                    t = (bound - T[axis, 3]) / rays[..., axis]
                    best = np.where((t > 0) & (t < best), t, best)
        point = T[:3, 3] + rays * best[..., None]
        checker = (np.floor(point * 3).sum(axis=-1) % 2).astype(np.uint8)
        rgb = np.stack([60 + 150 * checker, 90 + 0 * checker, 200 - 120 * checker], axis=-1).astype(np.uint8)
        frames.append(Frame(k, k / 30.0, rgb, best.astype(np.float32), T))
    return FrameListSource("boxroom", K, frames)


# ------------------------------------------------------------------------------------------------------ layouts
@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_every_layout_round_trips(tmp_path, layout):
    source = box_room()
    folder = write_folder(source, tmp_path / layout, layout)
    assert detect_layout(folder) == layout
    loaded = RgbdFolder(folder)  # at the images' own size
    assert loaded.layout == layout and len(loaded) == 4 and loaded.size == loaded.original_size == (64, 48)
    assert loaded.intrinsics == source.intrinsics and loaded.camera_source == "camera file camera.toml"
    np.testing.assert_allclose(loaded.timestamps, np.arange(4) / 30.0, atol=1e-6)
    np.testing.assert_allclose(loaded.poses, source.poses, atol=1e-8)
    scale = 1000.0 if layout.startswith("7scenes") else 5000.0
    for i in (0, 3):
        got, want = loaded.frame(i), source.frame(i)
        np.testing.assert_array_equal(got.rgb, want.rgb)
        np.testing.assert_array_equal(loaded.rgb(i), want.rgb)
        if layout == "rgb_only":
            assert got.depth.shape == (48, 64) and not got.depth.any()  # no depth: all 0 = no measurement
        else:
            np.testing.assert_allclose(got.depth, want.depth, atol=0.5 / scale + 1e-6)
    info = loaded.describe()
    json.dumps(info)  # JSON-ready, for the run record
    assert info["layout"] == layout and info["original_size"] == [64, 48]
    assert info["has_depth"] == (layout != "rgb_only")
    assert info["depth_scale"] == (None if layout == "rgb_only" else scale)


def test_detection_errors_are_one_line_and_list_the_layouts(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SimEnvError) as err:
        detect_layout(tmp_path / "empty")
    message = str(err.value)
    assert "\n" not in message and all(text in message for text in LAYOUTS.values())
    with pytest.raises(SimEnvError, match="is not a folder"):
        RgbdFolder(tmp_path / "missing")
    folder = write_folder(box_room(2), tmp_path / "rgb_only", "rgb_only")
    (folder / "groundtruth.txt").unlink()
    with pytest.raises(SimEnvError, match="no ground truth"):
        RgbdFolder(folder)
    folder = write_folder(box_room(2), tmp_path / "my_recording", "tum", camera_file=False)
    with pytest.raises(UnknownNameError, match="tum_fr1.*camera.toml"):
        RgbdFolder(folder)  # no camera file, no side file, no freiburg in the name
    with pytest.raises(SimEnvError, match="unknown layout 'kitti'; valid layouts: tum, icl"):
        write_folder(box_room(2), tmp_path / "x", "kitti")


def test_seven_scenes_depth_in_millimetres_invalid_values_and_dropped_frames(tmp_path):
    folder = write_folder(box_room(4), tmp_path / "seven", "7scenes", image_format="jpg", camera_file=False)
    raw = np.zeros((48, 64), np.uint16)
    raw[0, :4] = [1500, 65535, 0, 1]
    cv2.imwrite(str(folder / "frame-000001.depth.png"), raw)
    (folder / "frame-000002.pose.txt").write_text("\n".join(["-inf -inf -inf -inf"] * 3 + ["0 0 0 1"]) + "\n")
    (folder / "frame-000003.depth.png").unlink()
    loaded = RgbdFolder(folder, camera="7scenes")  # a camera given: depth and poses taken as that camera's
    assert len(loaded) == 2 and loaded.describe()["frames_dropped"] == 2  # no pose, no depth
    np.testing.assert_allclose(loaded.timestamps, [0.0, 1 / 30])  # frame number / 30 s
    assert loaded.depth_scale == 1000.0 and loaded.depth_scale_source == "layout 7scenes"
    np.testing.assert_allclose(loaded.depth(1)[0, :4], [1.5, 0.0, 0.0, 0.001])  # mm; 65535 and 0 = none
    assert loaded.depth_rig is None and loaded.describe()["depth_registration"] is None
    steps = loaded.describe()["conversions"]  # the layout's timestamps are recorded whether registered or not
    assert any(step.startswith("timestamps: frame number") for step in steps)
    assert not any("T_world_colour" in step for step in steps)
    own = RgbdFolder(folder)  # no camera anywhere: 7-Scenes' colour camera, depth registered to it
    assert own.camera_source == SEVEN_SCENES_COLOUR_SOURCE and own.intrinsics == preset("7scenes_rgb", 64, 48)
    assert own.depth_rig is not None and own.depth_rig.depth_intrinsics == preset("7scenes", 64, 48)
    jpeg, png = loaded.frame(0).rgb, box_room(1).frame(0).rgb  # JPEG is lossy: the colours on average
    np.testing.assert_allclose(jpeg.reshape(-1, 3).mean(axis=0), png.reshape(-1, 3).mean(axis=0), atol=4)
    (folder / SIDE_FILE).write_text(json.dumps({"depth_scale": 500}))
    given = {"camera": "7scenes"}  # depth as the files have it
    assert RgbdFolder(folder, **given).depth(1)[0, 0] == pytest.approx(3.0)  # the side file's scale over the layout's
    assert RgbdFolder(folder, depth_scale=3000, **given).depth(1)[0, 0] == pytest.approx(0.5)  # the argument over both
    split = write_folder(box_room(4), tmp_path / "split", "7scenes_split")
    assert RgbdFolder(split).depth_scale == 1000.0
    assert RgbdFolder(write_folder(box_room(2), tmp_path / "tum", "tum")).depth_scale == 5000.0  # TUM's default


def test_read_pose_matrix_projects_the_rotation_and_keeps_the_translation(tmp_path):
    T = look([0.5, -1.0, 2.0], 30.0, 10.0)
    M = T.copy()
    M[:3, :3] *= 1.0004  # as non-orthonormal as 7-Scenes' KinectFusion matrices
    path = tmp_path / "frame-000000.pose.txt"
    np.savetxt(path, M)
    got = read_pose_matrix(path)
    np.testing.assert_allclose(got, T, atol=1e-12)  # the nearest rotation to s R is R
    np.testing.assert_allclose(got[:3, :3] @ got[:3, :3].T, np.eye(3), atol=1e-12)
    path.write_text("1 0 0\n0 1 0\n0 0 1\n")
    with pytest.raises(FormatError, match="4 rows of 4 numbers"):
        read_pose_matrix(path)
    np.savetxt(path, np.diag([1.0, 1.0, -1.0, 1.0]))
    with pytest.raises(FormatError, match="reflection"):
        read_pose_matrix(path)


@pytest.mark.parametrize("block", [np.diag([0.0, 0.0, 1.0]), np.diag([10.0, 10.0, 10.0]), np.diag([1.0, 1.0, 1.02])])
def test_read_pose_matrix_refuses_a_block_far_from_any_rotation(tmp_path, block):
    """Projected onto SO(3), a zero or scaled block would be some rotation: it is refused, naming the file."""
    M = np.eye(4)
    M[:3, :3] = block
    path = tmp_path / "frame-000007.pose.txt"
    np.savetxt(path, M)
    with pytest.raises(FormatError, match=r"frame-000007.pose.txt: the 3x3 block is .* from the nearest rotation"):
        read_pose_matrix(path)
    M[:3, :3] = np.eye(3) * 1.0004  # within KinectFusion's 4e-4: taken
    np.savetxt(path, M)
    np.testing.assert_allclose(read_pose_matrix(path), np.eye(4), atol=1e-12)


def test_icl_associations_are_read_strictly(tmp_path):
    """ICL-NUIM's associations.txt: a frame index that is not a finite number, a wrong column count or a file that is
    not UTF-8 is one FormatError line naming the file and line (the TUM readers' comment rules)."""
    source = box_room(3)
    folder = write_folder(source, tmp_path / "icl", "icl")
    path = folder / "associations.txt"
    good = path.read_text()
    assert len(index_folder(folder, "icl").rgb_files) == 3
    path.write_text("# index depth index rgb\n" + good.replace("\n", "  # a comment\n", 1))
    assert len(index_folder(folder, "icl").rgb_files) == 3
    cases = [(good.replace("1 ", "nan ", 1), "column 1 is 'nan', not a frame index"),
             (good.replace(" 2 ", " inf ", 1), "column 3 is 'inf', not a frame index"),
             ("0 depth/0.png 0\n", "expected 4 columns")]  # fmt: skip
    for text, message in cases:
        path.write_text(text)
        with pytest.raises(FormatError, match=rf"associations.txt:\d+: {message}"):
            index_folder(folder, "icl")
    path.write_bytes(b"\xff" + good.encode())
    with pytest.raises(FormatError, match="associations.txt: not a text file"):
        index_folder(folder, "icl")


# ------------------------------------------------------------------------------------------------------- camera
def test_camera_files_toml_and_yaml(tmp_path):
    toml = tmp_path / "camera.toml"
    toml.write_text("fx = 517.3\nfy = 516.5\ncx = 318.6\ncy = 255.3\nwidth = 640\nheight = 480\n"
                    "k1 = 0.2624\nk2 = -0.9531\np1 = -0.0054\np2 = 0.0026\nk3 = 1.1633\n")  # fmt: skip
    model = read_camera_file(toml)
    assert model == camera_model("tum_fr1", 640, 480) == read_camera_file(toml, 640, 480)
    yaml = tmp_path / "camera.yaml"
    yaml.write_text("%YAML:1.0\n# TUM fr3\nfx: 535.4\nfy: 539.2\ncx: 320.1\ncy: 247.6\n")
    assert read_camera_file(yaml, 640, 480) == CameraModel(Intrinsics(535.4, 539.2, 320.1, 247.6, 640, 480))
    (tmp_path / "preset.toml").write_text('preset = "tum_fr2"\n')
    assert read_camera_file(tmp_path / "preset.toml", 64, 48) == camera_model("tum_fr2", 64, 48)
    (tmp_path / "bad.toml").write_text("fx = 1\nfy = 1\ncx = 0\ncy = 0\nk4 = 0.1\n")
    with pytest.raises(FormatError, match="unknown key.*'k4'; valid: preset, fx"):
        read_camera_file(tmp_path / "bad.toml", 64, 48)
    (tmp_path / "icl.toml").write_text("fx = 481.2\nfy = -480\ncx = 319.5\ncy = 239.5\n")
    with pytest.raises(FormatError, match="negative fy"):
        read_camera_file(tmp_path / "icl.toml", 640, 480)
    (tmp_path / "nested.yaml").write_text("camera:\n  fx: 1\n")
    with pytest.raises(FormatError, match="flat 'key: value'"):
        read_camera_file(tmp_path / "nested.yaml", 64, 48)


def test_a_camera_file_for_other_images_is_refused_not_rescaled(tmp_path):
    """A camera.toml for 160x120 images beside 64x48 ones is refused, naming the file and both sizes (rescaled, its
    fx 600 would have become fx 240 silently); without width and height it is taken at the images' size."""
    folder = write_folder(box_room(2), tmp_path / "seq", "tum", camera_file=False)
    camera = folder / "camera.toml"
    camera.write_text("fx = 600.0\nfy = 600.0\ncx = 79.5\ncy = 59.5\nwidth = 160\nheight = 120\n")
    with pytest.raises(FormatError, match=r"camera.toml: the camera is for 160x120 images but the images are 64x48"):
        RgbdFolder(folder)
    camera.write_text("fx = 60.0\nfy = 60.0\ncx = 31.5\ncy = 23.5\n")
    assert RgbdFolder(folder).camera.intrinsics == Intrinsics(60.0, 60.0, 31.5, 23.5, 64, 48)
    for text, message in [("fx = 60.0\nfy = 60.0\ncx = 31.5\ncy = 23.5\nwidth = 64.5\nheight = 48\n", "width = 64.5"),
                          ("fx = 60.0\nfy = 60.0\ncx = 31.5\ncy = 23.5\nwidth = inf\nheight = 48\n", "width = inf"),
                          ('fx = "60"\nfy = 60.0\ncx = 31.5\ncy = 23.5\n', "fx = '60'; it must be a finite number"),
                          ('preset = "tum_fr9"\n', "unknown camera preset 'tum_fr9'")]:  # fmt: skip
        camera.write_text(text)
        with pytest.raises(FormatError, match=f"camera.toml: {message}"):
            RgbdFolder(folder)
    camera.write_bytes(b"fx = 60.0\xff\n")
    with pytest.raises(FormatError, match="camera.toml: not a text file"):
        RgbdFolder(folder)


def test_camera_order_argument_file_side_file_name(tmp_path):
    source = box_room(2)
    folder = write_folder(source, tmp_path / "rgbd_dataset_freiburg3_x", "tum", camera_file=False)
    assert RgbdFolder(folder).camera_source == "preset tum_fr3 (folder name)"
    (folder / SIDE_FILE).write_text(json.dumps({"intrinsics": {"fx": 50, "fy": 50, "cx": 31.5, "cy": 23.5,
                                                               "width": 64, "height": 48}}))  # fmt: skip
    assert RgbdFolder(folder).camera_source == SIDE_FILE and RgbdFolder(folder).intrinsics.fx == 50
    (folder / "camera.yaml").write_text("fx: 40\nfy: 40\ncx: 31.5\ncy: 23.5\n")
    assert RgbdFolder(folder).intrinsics.fx == 40  # the folder's camera file over the side file
    assert RgbdFolder(folder, "tum_fr1").camera == camera_model("tum_fr1", 64, 48)  # the argument over all
    other = tmp_path / "elsewhere.toml"
    other.write_text("fx = 30\nfy = 30\ncx = 31.5\ncy = 23.5\n")
    assert RgbdFolder(folder, str(other)).intrinsics.fx == 30
    with pytest.raises(UnknownNameError, match="neither a preset"):
        RgbdFolder(folder, "tum_fr9")


def test_undistortion_agrees_with_cv2_undistort_points():
    model = camera_model("tum_fr1", 640, 480)
    K, D = model.intrinsics.K, np.asarray(model.distortion)
    map_u, map_v = model.undistort_maps()
    rng = np.random.default_rng(0)
    u = rng.integers(20, 620, 200)
    v = rng.integers(20, 460, 200)
    distorted = np.stack([map_u[v, u], map_v[v, u]], axis=-1).astype(np.float64)  # where pixel (u, v) reads
    back = cv2.undistortPoints(distorted.reshape(-1, 1, 2), K, D, P=model.rectified().K).reshape(-1, 2)
    np.testing.assert_allclose(back, np.stack([u, v], axis=-1), atol=0.02)
    assert np.abs(distorted - np.stack([u, v], axis=-1)).max() > 5  # fr1's distortion moves corner pixels


@pytest.mark.parametrize("name, distorted", [("freiburg1", True), ("freiburg2", True), ("freiburg3", False)])
def test_a_distorted_folder_is_delivered_undistorted(tmp_path, name, distorted):
    """Blobs drawn at known positions of a distorted 640x480 image land where cv2.undistortPoints puts them."""
    K0 = preset(f"tum_fr{name[-1]}", 640, 480)
    points = np.array([[100.0, 80.0], [540.0, 90.0], [320.0, 240.0], [90.0, 400.0], [560.0, 410.0]])
    v, u = np.mgrid[0:480, 0:640]
    blob = sum(np.exp(-((u - x) ** 2 + (v - y) ** 2) / (2 * 3.0**2)) for x, y in points)
    rgb = np.repeat((40 + 200 * blob).clip(0, 255).astype(np.uint8)[..., None], 3, axis=-1)
    depth = np.where(blob > 0.5, 1.0, 2.0).astype(np.float32)
    frames = [Frame(k, k / 30.0, rgb, depth, np.eye(4)) for k in range(2)]
    folder = write_folder(FrameListSource("blobs", K0, frames), tmp_path / f"rgbd_dataset_{name}_blobs", "tum",
                          camera_file=False)  # fmt: skip
    loaded = RgbdFolder(folder)
    assert loaded.camera.distorted == distorted and loaded.camera.intrinsics == K0
    K1 = loaded.intrinsics  # new camera matrix: the crop to what the lens saw (K itself without distortion)
    assert (K1.fx > K0.fx) == distorted and (K1 == K0) != distorted
    frame = loaded.frame(0)
    expected = cv2.undistortPoints(points.reshape(-1, 1, 2), K0.K, np.asarray(loaded.camera.distortion), P=K1.K)
    weight = frame.rgb[..., 0].astype(np.float64) - 40
    for (x, y) in expected.reshape(-1, 2):
        window = (np.abs(u - x) < 12) & (np.abs(v - y) < 12)
        w = np.where(window, weight, 0.0)
        centre = (float((w * u).sum() / w.sum()), float((w * v).sum() / w.sum()))
        assert centre == pytest.approx((x, y), abs=0.1)
        near = window & (frame.depth > 0)
        assert set(np.unique(frame.depth[near])) <= {1.0, 2.0}  # nearest neighbour: no depth of no surface
        inner = np.hypot(u - x, v - y) < 2.0
        assert (frame.depth[inner] == 1.0).all()  # the blob's depth moved with its colour
    if distorted:
        assert any("undistorted" in c for c in loaded.conversions())
        assert loaded.describe()["undistorted_intrinsics"]["fx"] == K1.fx
    assert frame.depth.all()  # fr1/fr2 too: every delivered pixel comes from inside the original image


# ------------------------------------------------------------------------------------------------------- resize
def test_resize_to_the_processing_resolution(tmp_path):
    source = box_room(2, preset("tum_fr3", 64, 48))
    labels = [(np.arange(64 * 48).reshape(48, 64) % 4).astype(np.uint8) for _ in range(2)]
    folder = write_folder(source, tmp_path / "seq", "tum")
    side = {"labels": {"folder": "labels"}}
    (folder / SIDE_FILE).write_text(json.dumps(side))
    (folder / "labels").mkdir()
    for k, name in enumerate(read_tum_image_list(folder / "rgb.txt")[1]):
        cv2.imwrite(str(folder / "labels" / Path(name).name), labels[k])
    assert load_rgbd_folder(folder).size == PROCESSING_SIZE == (320, 240)  # the default of load_rgbd_folder
    half = RgbdFolder(folder, size=(32, 24))
    K0, K = source.intrinsics, half.intrinsics
    assert (K.fx, K.fy) == pytest.approx((K0.fx / 2, K0.fy / 2))
    assert (K.cx, K.cy) == pytest.approx(((K0.cx + 0.5) / 2 - 0.5, (K0.cy + 0.5) / 2 - 0.5))  # centres at integers
    frame, want = half.frame(1), source.frame(1)
    blocks = want.rgb.astype(np.float64).reshape(24, 2, 32, 2, 3).mean(axis=(1, 3))
    assert np.abs(frame.rgb - blocks).max() <= 0.5 + 1e-9  # area averaging of each 2x2 block
    np.testing.assert_allclose(frame.depth, half.depth(1))
    depth_in = np.rint(want.depth * 5000) / 5000
    np.testing.assert_allclose(frame.depth, depth_in[1::2, 1::2], atol=1e-6)  # nearest: one input pixel, no mean
    np.testing.assert_array_equal(frame.labels, labels[1][1::2, 1::2])
    odd = RgbdFolder(folder, size=(40, 30))  # not a whole factor: still f s and (c + 0.5) s - 0.5
    assert odd.intrinsics.cx == pytest.approx((K0.cx + 0.5) * 40 / 64 - 0.5)
    assert odd.frame(0).rgb.shape == (30, 40, 3) and odd.frame(0).depth.shape == (30, 40)
    assert set(np.unique(odd.frame(0).labels)) <= {0, 1, 2, 3}
    assert any(c.startswith("resized 64x48 -> 40x30") for c in odd.describe()["conversions"])
    with pytest.raises(SimEnvError, match="size must be positive"):
        RgbdFolder(folder, size=(0, 24))


def test_replay_env_delivers_a_folder_at_the_size_asked(tmp_path):
    folder = write_folder(box_room(3), tmp_path / "seq", "7scenes")
    env = gym.make("sim_envs/Replay-v0", source=str(folder), size=(32, 24))
    obs, info = env.reset()
    assert obs["rgb"].shape == (24, 32, 3) and obs["intrinsics"][0] == pytest.approx(preset("icl", 32, 24).fx)
    env.close()
    with pytest.raises(SimEnvError, match="apply to a folder path"):
        gym.make("sim_envs/Replay-v0", source=box_room(2), size=(32, 24))


# -------------------------------------------------------------------------------------------------- fingerprint
def test_folder_fingerprint_follows_the_content_not_the_place(tmp_path):
    folder = write_folder(box_room(3), tmp_path / "a" / "seq", "tum")
    first = folder_fingerprint(folder)
    assert first["files"] == 10 and first["bytes"] > 0  # 3 RGB, 3 depth, 3 index files, camera.toml
    copy = shutil.copytree(folder, tmp_path / "b" / "seq")
    assert folder_fingerprint(copy) == first
    gt = copy / "groundtruth.txt"
    gt.write_text(gt.read_text().replace("0.0", "0.1", 1))
    assert folder_fingerprint(copy)["sha256"] != first["sha256"]
    (folder / "rgb" / "extra.png").write_bytes(b"x")
    assert folder_fingerprint(folder)["files"] == 11


# ------------------------------------------------------------------------------------ depth-to-colour registration
KD = Intrinsics(585.0, 585.0, 320.0, 240.0, 640, 480)
KC = Intrinsics(525.0, 525.0, 320.0, 240.0, 640, 480)


def test_registering_a_plane_seen_from_a_shifted_colour_camera():
    T = np.eye(4)
    T[0, 3] = 0.05  # the colour camera 5 cm to the left of the depth camera: points move +5 cm in x
    out = register_depth(np.full((480, 640), 2.0, np.float32), KD, KC, T)
    assert out.shape == (480, 640) and out.dtype == np.float32
    assert out[240, 333] == pytest.approx(2.0)  # the depth camera's centre: 525 * 0.05 / 2 + 320 = 333.1
    # the depth camera's left edge: 525 * ((0 - 320) / 585 * 2 + 0.05) / 2 + 320 = 45.97 -> column 46
    assert not out[:, :46].any() and (out[100:380, 46:600] == np.float32(2.0)).all()
    assert not register_depth(np.zeros((480, 640)), KD, KC, T).any()  # no measurement: nothing lands
    np.testing.assert_array_equal(register_depth(np.full((480, 640), 2.0), KD, KD, np.eye(4)),
                                  np.full((480, 640), 2.0, np.float32))  # one camera: the same map  # fmt: skip
    with pytest.raises(SimEnvError, match="depth of shape"):
        register_depth(np.ones((48, 64)), KD, KC, T)


def test_registration_keeps_the_nearest_surface():
    depth = np.tile(np.array([[2.0, 3.0], [4.0, 5.0]]), (240, 320))  # every 2x2 block: 2, 3, 4, 5 m
    out = register_depth(depth, KD, KD.scaled(320, 240), np.eye(4))  # half the resolution: 4 pixels onto one
    assert out.shape == (240, 320) and (out == np.float32(2.0)).all()


def test_a_seven_scenes_folder_gets_its_colour_camera_poses(tmp_path):
    source = box_room(3)
    folder = write_folder(source, tmp_path / "seven", "7scenes", camera_file=False)
    loaded = RgbdFolder(folder)
    T_cd = SEVEN_SCENES_T_COLOUR_DEPTH
    np.testing.assert_allclose(loaded.poses, source.poses @ np.linalg.inv(T_cd), atol=1e-8)
    centres = loaded.poses[:, :3, 3] - source.poses[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(centres, axis=1), np.linalg.norm(T_cd[:3, 3]), rtol=1e-6)  # 2.6 cm
    info = loaded.describe()
    json.dumps(info)
    assert info["loader"].endswith("/5") and info["depth_registration"]["T_colour_depth"] == T_cd.tolist()
    assert any(step.startswith("depth: registered") for step in info["conversions"])
    assert any("T_world_colour" in step for step in info["conversions"])
    depth = loaded.depth(0)
    assert depth.shape == (48, 64) and (depth > 0).mean() > 0.5  # most of the view has a registered measurement
    expected = register_depth(source.frame(0).depth, preset("7scenes", 64, 48), preset("7scenes_rgb", 64, 48),
                              T_cd)  # fmt: skip
    np.testing.assert_allclose(depth, expected, atol=0.0006)  # the millimetre PNG's rounding


# ----------------------------------------------------------------------------------------- the real 7-Scenes data
def test_the_shared_7scenes_redkitchen_folder(shared_data):
    redkitchen = shared_data("data/real/7scenes_redkitchen", "rgb.txt", "groundtruth.txt")
    folder = load_rgbd_folder(redkitchen)
    assert folder.layout == "7scenes_split" and len(folder) == 1000 and folder.original_size == (640, 480)
    assert folder.depth_scale == 1000.0 and folder.camera_source == SEVEN_SCENES_COLOUR_SOURCE
    K = folder.intrinsics  # the colour camera's 525 px, not camera-intrinsics.txt's 585 (the depth camera's)
    assert (K.width, K.height, K.fx, K.fy, K.cx, K.cy) == (320, 240, 262.5, 262.5, 159.75, 119.75)
    assert folder.depth_rig.depth_intrinsics.fx == 585.0 and "camera-intrinsics.txt" in folder.depth_rig.source
    stamps, _ = read_tum_image_list(redkitchen / "rgb.txt")
    np.testing.assert_allclose(folder.timestamps, stamps, atol=1e-6)
    gt_t, gt_T = read_tum_trajectory(redkitchen / "groundtruth.txt")  # the depth camera's poses
    np.testing.assert_allclose(folder.poses, gt_T @ np.linalg.inv(SEVEN_SCENES_T_COLOUR_DEPTH), atol=1e-4)
    as_given = RgbdFolder(redkitchen, camera="7scenes", size=(320, 240))  # a camera given: depth as the files have it
    np.testing.assert_allclose(as_given.poses, gt_T, atol=1e-4)  # the index files were made from the same matrices
    raw = cv2.imread(str(redkitchen / "depth" / "frame-000500.depth.png"), cv2.IMREAD_UNCHANGED)
    expected = raw[1::2, 1::2].astype(np.float32) / 1000.0
    expected[raw[1::2, 1::2] == 65535] = 0.0
    np.testing.assert_allclose(as_given.frame(500).depth, expected)
    frame = folder.frame(500)
    assert (frame.depth > 0).mean() > 0.6  # registered: the depth camera's narrower view covers most of the image
    # registered, the depth edges fall on the colour edges better than as the files have them
    scores = [(depth_edge_alignment(folder.frame(i).rgb, folder.frame(i).depth),
               depth_edge_alignment(as_given.frame(i).rgb, as_given.frame(i).depth)) for i in (0, 500, 999)]
    assert all(registered > given + 0.2 for registered, given in scores), scores
    assert frame.rgb.shape == (240, 320, 3) and 0 < frame.depth.max() <= 3.975
    assert folder_fingerprint(redkitchen)["files"] >= 3000
