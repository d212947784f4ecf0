import json

import cv2
import numpy as np
import pytest

from sim_envs.camera import Intrinsics, preset
from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.folders.datasets import (
    SIDE_FILE,
    RgbdFolder,
    convert_pose_convention,
    depth_consistency,
    export_tum_rgbd,
    load_tum_rgbd_folder,
    ray_length_to_z,
)
from sim_envs.folders.formats import write_tum_trajectory
from sim_envs.frames import NO_INSTANCE, Frame
from sim_envs.source import FrameSource

ROOM = np.array([4.0, 3.0, 2.5])  # an axis-aligned box [0, 4] x [0, 3] x [0, 2.5], z up


def look(position, yaw_deg, pitch_deg):
    """T_world_cam of an OpenCV camera at ``position`` looking along yaw/pitch, world z up."""
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    z = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), np.sin(pitch)])
    down = np.array([0.0, 0.0, -1.0])
    y = down - down @ z * z
    y /= np.linalg.norm(y)
    T = np.eye(4)
    T[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
    T[:3, 3] = position
    return T


class BoxRoomSource:
    """Analytic ray casting inside a box: exact depth, a checker texture, labels (floor 0, rest 1), plane ids."""

    def __init__(self, n: int = 6, intrinsics: Intrinsics | None = None, far_wall: float | None = None):
        self.name = "boxroom"
        self.intrinsics = intrinsics or preset("icl", 64, 48)
        self.timestamps = 100.0 + np.arange(n) / 30.0
        self.room = ROOM.copy() if far_wall is None else np.array([far_wall, 3.0, 2.5])
        self.poses = np.stack(
            [look([1.0 + 0.08 * k, 1.2 + 0.05 * k, 1.1 + 0.02 * k], 10.0 + 4.0 * k, -5.0 + 2.0 * k) for k in range(n)]
        )

    def __len__(self):
        return len(self.timestamps)

    def frame(self, index):
        K, T = self.intrinsics, self.poses[index]
        v, u = np.mgrid[0 : K.height, 0 : K.width]
        rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones(u.shape)], axis=-1) @ T[:3, :3].T
        origin = T[:3, 3]
        best = np.full(u.shape, np.inf)
        plane = np.zeros(u.shape, dtype=np.int32)
        with np.errstate(divide="ignore", invalid="ignore"):
            for axis in range(3):
                for side, bound in enumerate((0.0, self.room[axis])):
                    t = (bound - origin[axis]) / rays[..., axis]
                    hit = (t > 0) & (t < best)
                    best[hit] = t[hit]
                    plane[hit] = 2 * axis + side
        depth = best.astype(np.float32)  # camera-space rays have z = 1, so the ray parameter is the depth
        point = origin + rays * best[..., None]
        checker = (np.floor(point * 3).sum(axis=-1) % 2).astype(np.uint8)
        rgb = np.stack([60 + 150 * checker, 20 * plane + 40, 200 - 120 * checker], axis=-1).astype(np.uint8)
        labels = np.where(plane == 4, 0, 1).astype(np.uint8)
        return Frame(index, float(self.timestamps[index]), rgb, depth, T.copy(), labels, plane)

    def close(self):
        pass


def test_box_room_is_a_frame_source_with_consistent_geometry():
    source = BoxRoomSource()
    assert isinstance(source, FrameSource)
    a, b = source.frame(0), source.frame(4)
    assert depth_consistency(a.depth, a.T_world_cam, b.depth, b.T_world_cam, source.intrinsics) > 0.97
    moved = b.T_world_cam.copy()
    moved[:3, 3] += [0.3, -0.3, 0.2]
    assert depth_consistency(a.depth, a.T_world_cam, b.depth, moved, source.intrinsics) < 0.6


def test_export_then_load_round_trip(tmp_path):
    source = BoxRoomSource()
    folder = export_tum_rgbd(source, tmp_path / "seq", progress=False)
    for name in ("rgb.txt", "depth.txt", "groundtruth.txt", SIDE_FILE):
        assert (folder / name).is_file()
    assert len(list((folder / "rgb").glob("*.png"))) == 6 and (folder / "rgb" / "100.000000.png").is_file()
    raw = cv2.imread(str(folder / "depth" / "100.000000.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    np.testing.assert_allclose(raw / 5000.0, source.frame(0).depth, atol=0.5 / 5000 + 1e-6)
    side = json.loads((folder / SIDE_FILE).read_text())
    assert side["depth_scale"] == 5000.0 and side["intrinsics"]["fx"] == pytest.approx(source.intrinsics.fx)
    assert side["labels"]["no_label"] == 255 and side["labels"]["classes"]["0"] == "floor"

    loaded = load_tum_rgbd_folder(folder)
    assert isinstance(loaded, FrameSource) and len(loaded) == 6
    assert loaded.intrinsics == source.intrinsics and loaded.pose_convention_used == "opencv"
    np.testing.assert_array_equal(loaded.timestamps, source.timestamps)
    np.testing.assert_allclose(loaded.poses, source.poses, atol=1e-8)
    for i in (0, 5):
        got, want = loaded.frame(i), source.frame(i)
        np.testing.assert_array_equal(got.rgb, want.rgb)
        np.testing.assert_allclose(got.depth, want.depth, atol=0.5 / 5000 + 1e-6)
        np.testing.assert_array_equal(got.labels, want.labels)
        np.testing.assert_array_equal(got.instances, want.instances)
        assert got.timestamp == want.timestamp and got.index == i


def test_export_refuses_a_non_empty_folder_and_counts_clipped_depth(tmp_path):
    (tmp_path / "keep.txt").write_text("x")
    with pytest.raises(SimEnvError, match="not empty"):
        export_tum_rgbd(BoxRoomSource(2), tmp_path, progress=False)
    source = BoxRoomSource(2, far_wall=20.0)  # a wall 20 m away: beyond 65535 / 5000 m
    folder = export_tum_rgbd(source, tmp_path, progress=False, overwrite=True, max_frames=1)
    side = json.loads((folder / SIDE_FILE).read_text())
    far = source.frame(0).depth > 65535 / 5000
    assert side["frames"] == 1 and side["depth_clipped_pixels"] == int(far.sum()) > 0
    loaded = RgbdFolder(folder)
    assert len(loaded) == 1 and np.all(loaded.frame(0).depth[far] == 0)


def write_tum_style_folder(root, source, name="rgbd_dataset_freiburg1_test"):
    """A folder as the TUM benchmark ships it: no side file, depth 5 ms after RGB, ground truth at 100 Hz."""
    folder = root / name
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    rgb_lines, depth_lines = [], []
    for i in range(len(source)):
        f = source.frame(i)
        t = f.timestamp
        cv2.imwrite(str(folder / "rgb" / f"{t:.6f}.png"), cv2.cvtColor(f.rgb, cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(folder / "depth" / f"{t + 0.005:.6f}.png"), np.rint(f.depth * 5000).astype(np.uint16))
        rgb_lines.append(f"{t:.6f} rgb/{t:.6f}.png")
        depth_lines.append(f"{t + 0.005:.6f} depth/{t + 0.005:.6f}.png")
    (folder / "rgb.txt").write_text("# color images\n" + "\n".join(rgb_lines) + "\n")
    (folder / "depth.txt").write_text("# depth maps\n" + "\n".join(depth_lines) + "\n")
    # ground truth at 100 Hz, offset so that each RGB frame has one pose 3 ms away; the true pose is there
    gt_t = np.sort(np.concatenate([source.timestamps + 0.003, source.timestamps + 0.013, source.timestamps - 0.007]))
    gt_T = np.tile(np.eye(4), (gt_t.size, 1, 1))
    gt_T[:, 0, 3] = 99.0  # decoys
    gt_T[np.searchsorted(gt_t, source.timestamps + 0.003)] = source.poses
    write_tum_trajectory(folder / "groundtruth.txt", gt_t, gt_T)
    return folder


def test_load_a_tum_benchmark_folder(tmp_path):
    source = BoxRoomSource(5, intrinsics=preset("tum_fr1", 64, 48))
    folder = write_tum_style_folder(tmp_path, source)
    loaded = RgbdFolder(folder)
    assert loaded.camera.intrinsics == preset("tum_fr1", 64, 48)  # guessed from "freiburg1" and scaled to 64x48
    assert loaded.intrinsics == loaded.camera.rectified()  # delivered undistorted: the crop to what the lens saw
    np.testing.assert_allclose(loaded.timestamps, source.timestamps, atol=1e-6)
    np.testing.assert_allclose(loaded.poses, source.poses, atol=1e-8)
    assert loaded.camera.distorted and any("undistorted" in c for c in loaded.conversions())  # fr1 RGB is distorted
    assert loaded.frame(2).labels is None and loaded.frame(2).instances is None
    fr3 = RgbdFolder(folder, "tum_fr3")  # fr3 images are not distorted: delivered as they are
    assert fr3.intrinsics == preset("tum_fr3", 64, 48) and not fr3.camera.distorted
    np.testing.assert_array_equal(fr3.frame(2).rgb, source.frame(2).rgb)
    with pytest.raises(SimEnvError, match="intrinsics for 640x480 but the images are 64x48"):
        RgbdFolder(folder, Intrinsics(517.3, 516.5, 318.6, 255.3, 640, 480))


def test_the_three_undistortions_of_a_distorted_folder(tmp_path):
    source = BoxRoomSource(3, intrinsics=preset("tum_fr1", 64, 48))
    folder = write_tum_style_folder(tmp_path, source)
    crop, full, none = (RgbdFolder(folder, undistort=m) for m in ("crop", "full", "none"))
    K = preset("tum_fr1", 64, 48)
    assert crop.intrinsics == crop.camera.rectified() and crop.intrinsics.fx > K.fx  # zoomed in: no border
    assert full.intrinsics == K and none.intrinsics == K
    np.testing.assert_array_equal(none.frame(1).rgb, source.frame(1).rgb)  # as on disk
    f = full.frame(1)
    border = f.depth == 0  # the lens never saw the corners of K's frame: black, no depth
    assert border[0, 0] and border[-1, -1] and not border[24, 32]
    assert (f.rgb[0, 0] == 0).all() and (f.rgb[-1, -1] == 0).all()
    assert crop.frame(1).depth.min() > 0  # the crop sees through the lens everywhere
    assert any("undistort='full'" in c for c in full.conversions()) and full.describe()["undistort"] == "full"
    assert any("not undistorted" in c for c in none.conversions())
    with pytest.raises(SimEnvError, match="unknown undistortion 'half'; valid: crop, full, none"):
        RgbdFolder(folder, undistort="half")


def test_unknown_camera_and_not_a_dataset(tmp_path):
    folder = write_tum_style_folder(tmp_path, BoxRoomSource(3), name="my_recording")
    with pytest.raises(UnknownNameError, match="tum_fr1"):
        RgbdFolder(folder)
    (tmp_path / "empty").mkdir()
    with pytest.raises(SimEnvError, match="not an RGB-D folder of a known layout; expected one of: TUM RGB-D"):
        RgbdFolder(tmp_path / "empty")


def write_icl_folder(root, source, flip: bool):
    """An ICL-NUIM TUM-compatible folder: associations.txt and traj0.gt.freiburg indexed by frame number."""
    folder = root / ("icl_flipped" if flip else "icl_plain")
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    lines = []
    for i in range(len(source)):
        f = source.frame(i)
        cv2.imwrite(str(folder / "rgb" / f"{i}.png"), cv2.cvtColor(f.rgb, cv2.COLOR_RGB2BGR))
        cv2.imwrite(str(folder / "depth" / f"{i}.png"), np.rint(f.depth * 5000).astype(np.uint16))
        lines.append(f"{i} depth/{i}.png {i} rgb/{i}.png")
    (folder / "associations.txt").write_text("\n".join(lines) + "\n")
    poses = convert_pose_convention(source.poses, "icl") if flip else source.poses
    write_tum_trajectory(folder / "traj0.gt.freiburg", np.arange(len(source), dtype=float), poses)
    return folder


@pytest.mark.parametrize("flip", [True, False])
def test_icl_folder_pose_convention_is_detected_from_the_depth(tmp_path, flip):
    source = BoxRoomSource(8)
    loaded = RgbdFolder(write_icl_folder(tmp_path, source, flip))
    assert loaded.layout == "icl" and loaded.intrinsics == preset("icl", 64, 48)
    assert loaded.intrinsics.fy > 0  # ICL-NUIM's fy = -480 becomes +480 (scaled) in the OpenCV convention
    assert loaded.pose_convention_used == ("icl" if flip else "opencv")
    right, wrong = ("icl", "opencv") if flip else ("opencv", "icl")
    assert loaded.pose_convention_scores[right] > 0.95 > loaded.pose_convention_scores[wrong]
    np.testing.assert_allclose(loaded.poses, source.poses, atol=1e-8)
    np.testing.assert_allclose(loaded.timestamps, np.arange(8) / 30.0)
    forced = RgbdFolder(write_icl_folder(tmp_path / "again", source, flip), pose_convention="icl")
    assert forced.pose_convention_used == "icl" and forced.pose_convention_scores == {}


def test_convert_pose_convention_keeps_rotations_proper_and_is_an_involution():
    T = BoxRoomSource(3).poses
    flipped = convert_pose_convention(T, "icl")
    assert np.allclose(np.linalg.det(flipped[:, :3, :3]), 1.0)
    np.testing.assert_allclose(convert_pose_convention(flipped, "icl"), T)
    np.testing.assert_allclose(flipped[:, 1, 3], -T[:, 1, 3])
    with pytest.raises(SimEnvError, match="valid: opencv, icl"):
        convert_pose_convention(T, "opengl")


def test_ray_length_to_z():
    K = Intrinsics(100.0, 100.0, 2.0, 1.0, 5, 3)
    z = ray_length_to_z(np.full((3, 5), 2.0, dtype=np.float32), K)
    assert z[1, 2] == pytest.approx(2.0)  # at the principal point ray length = z
    assert z[0, 0] == pytest.approx(2.0 / np.sqrt(0.02**2 + 0.01**2 + 1.0))


def test_frame_index_out_of_range(tmp_path):
    loaded = RgbdFolder(export_tum_rgbd(BoxRoomSource(2), tmp_path / "s", progress=False))
    with pytest.raises(SimEnvError, match="out of range 0..1"):
        loaded.frame(2)
    assert NO_INSTANCE == -1 and loaded.frame(1).instances.min() >= 0
