"""Open3D's RGB-D odometry (Steinbruecker et al. 2011 / Park et al. 2017, ``open3d.pipelines.odometry``) as a
``sim_envs`` agent: ``"thirdparty.open3d_odometry:Open3dOdometryAgent"``. Open3D is MIT-licensed and runs in
process (``pip install -e '.[open3d]'``; on Debian it also needs ``libusb-1.0-0``). Importing this module imports
``open3d``, so where it is missing the benchmark skips the method with the ImportError.

An RGB-D method: it needs each frame's depth, which the env does not put in the observation. The agent therefore
declares ``uses_ground_truth = True`` and reads from ``info`` ONLY the depth an RGB-D camera measures:
``info["sensor_depth"]`` (the simulated Kinect-like depth, noisy and with holes) where the camera has a depth sensor,
else ``info["gt_depth"]`` (a real folder's depth images; the rendered exact depth through the ``clean`` camera,
which has no depth sensor). It never reads the ground-truth pose. ``extras["depth_source"]`` counts which it used.

Configuration (defaults): ``compute_rgbd_odometry`` with the HYBRID Jacobian (``RGBDOdometryJacobianFromHybridTerm``:
photometric and depth residuals), ``OdometryOption(iteration_number_per_pyramid_level=[20, 10, 5],
depth_diff_max=0.07, depth_min=0.1, depth_max=4.0)`` (metres; Open3D's reconstruction-system values, its default
depth_diff_max 0.03 being tight for Kinect-like noise); depth beyond ``depth_max`` truncated; RGB converted to
intensity. Frame-to-KEYFRAME: each frame is registered to the current key-frame, starting from the constant-velocity
prediction; a frame becomes the new key-frame when it is more than ``keyframe_translation`` (0.10 m) or
``keyframe_rotation_deg`` (10 deg) from the key-frame. A registration succeeds when Open3D says so AND at least
``min_correspondence_share`` (5 %) of the pixels are in correspondence. When the key-frame registration fails, the
frame is registered to the previous frame instead (and becomes the key-frame); when that fails too it is LOST.

Answers (:mod:`sim_envs.agent`): ``T_world_cam`` camera-to-world, OpenCV camera axes (Open3D's pinhole camera has
the same axes), metres (metric scale: the depth's), the world = the first frame's camera. A lost frame answers the
last pose with ``tracked = 0`` and becomes the key-frame at that pose (the chain goes on from there). No key-frame
depth is returned (the method has the trajectory metrics only).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import open3d as o3d

from slamcommon.agent_keys import FRAMES, T_WORLD_CAM, TRACKED, TRACKED_SHARE

JACOBIANS = ("hybrid", "color")


def _angle_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


class Open3dOdometryAgent:
    """Open3D RGB-D odometry, frame to key-frame (see the module docstring for the configuration and answers).

    depth_min, depth_max, depth_diff_max: Open3D's ``OdometryOption`` (metres); iterations: per pyramid level,
    coarse to fine; jacobian: ``hybrid`` (default) or ``color``; keyframe_translation (m), keyframe_rotation_deg: when
    a frame becomes the key-frame (0 and 0: every frame, i.e. frame-to-frame odometry); min_correspondence_share:
    the share of pixels in correspondence below which a registration counts as failed.
    """

    uses_ground_truth = True  # for the depth image only (module docstring)
    name = "open3d_odometry"

    def __init__(self, depth_min: float = 0.1, depth_max: float = 4.0, depth_diff_max: float = 0.07,
                 iterations: tuple[int, ...] | list[int] = (20, 10, 5), jacobian: str = "hybrid",
                 keyframe_translation: float = 0.10, keyframe_rotation_deg: float = 10.0,
                 min_correspondence_share: float = 0.05) -> None:
        if jacobian not in JACOBIANS:
            raise ValueError(f"jacobian must be one of {JACOBIANS}, got {jacobian!r}")
        if not 0.0 <= depth_min < depth_max or depth_diff_max <= 0:
            raise ValueError(f"need 0 <= depth_min < depth_max and depth_diff_max > 0, got {depth_min}, "
                             f"{depth_max}, {depth_diff_max}")
        self.depth_min, self.depth_max, self.depth_diff_max = float(depth_min), float(depth_max), float(depth_diff_max)
        self.iterations = tuple(int(i) for i in iterations)
        self.jacobian = jacobian
        self.keyframe_translation = float(keyframe_translation)
        self.keyframe_rotation_deg = float(keyframe_rotation_deg)
        self.min_correspondence_share = float(min_correspondence_share)
        self._option = o3d.pipelines.odometry.OdometryOption(
            iteration_number_per_pyramid_level=o3d.utility.IntVector(list(self.iterations)),
            depth_diff_max=self.depth_diff_max, depth_min=self.depth_min, depth_max=self.depth_max)
        self._jacobian = (o3d.pipelines.odometry.RGBDOdometryJacobianFromHybridTerm() if jacobian == "hybrid"
                          else o3d.pipelines.odometry.RGBDOdometryJacobianFromColorTerm())
        self._intrinsic: Any = None
        self._clear()

    def _clear(self) -> None:
        self._kf: Any = None  # (RGBDImage, T_world_kf)
        self._prev: Any = None  # (RGBDImage, T_world_prev)
        self._velocity = np.eye(4)  # T_prev_cur of the last tracked motion
        self._tracked: list[bool] = []
        self._seconds: list[float] = []
        self._keyframes = 0
        self._fallbacks = 0
        self._depth_source: dict[str, int] = {}
        self._shares: list[float] = []

    def reset(self, intrinsics: np.ndarray, image_size: tuple[int, int]) -> None:
        """A new episode: ``intrinsics`` [fx, fy, cx, cy] pixels (OpenCV convention), ``image_size`` (H, W)."""
        fx, fy, cx, cy = (float(v) for v in np.asarray(intrinsics, dtype=np.float64).reshape(4))
        h, w = (int(v) for v in image_size)
        self._intrinsic = o3d.camera.PinholeCameraIntrinsic(w, h, fx, fy, cx, cy)
        self._clear()

    def _rgbd(self, rgb: np.ndarray, depth: np.ndarray) -> Any:
        depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
        return o3d.geometry.RGBDImage.create_from_color_and_depth(
            o3d.geometry.Image(np.ascontiguousarray(rgb, dtype=np.uint8)), o3d.geometry.Image(depth),
            depth_scale=1.0, depth_trunc=self.depth_max, convert_rgb_to_intensity=True)

    def _register(self, source: Any, target: Any, init: np.ndarray) -> tuple[bool, np.ndarray]:
        """(success, T_target_source): the motion taking points of ``source``'s camera into ``target``'s. Success:
        Open3D's, with at least ``min_correspondence_share`` of the pixels in correspondence (the information
        matrix's last diagonal entry counts them; Open3D reports success even with none)."""
        ok, T, info = o3d.pipelines.odometry.compute_rgbd_odometry(source, target, self._intrinsic, init,
                                                                   self._jacobian, self._option)
        share = float(np.asarray(info)[5, 5]) / (self._intrinsic.width * self._intrinsic.height)
        self._shares.append(share)
        return bool(ok) and share >= self.min_correspondence_share, np.asarray(T, dtype=np.float64)

    def step(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> dict[str, Any]:
        """Register this frame (its RGB and the measured depth of ``info``); ``{"T_world_cam", "tracked"}``."""
        if self._intrinsic is None:
            raise RuntimeError("call reset(intrinsics, image_size) before step()")
        key = "sensor_depth" if info.get("sensor_depth") is not None else "gt_depth"
        if info.get(key) is None:
            raise RuntimeError("Open3D odometry needs the frame's depth: info['sensor_depth'] or info['gt_depth'] "
                               "(an agent with uses_ground_truth = True gets full ground truth from the driver)")
        self._depth_source[key] = self._depth_source.get(key, 0) + 1
        t0 = time.perf_counter()
        cur = self._rgbd(observation["rgb"], np.asarray(info[key], dtype=np.float32))
        if self._kf is None:  # the first frame: the world
            pose, tracked = np.eye(4), True
            self._kf = (cur, pose)
            self._keyframes = 1
        else:
            kf_img, T_world_kf = self._kf
            prev_img, T_world_prev = self._prev
            predicted = T_world_prev @ self._velocity
            ok, T_kf_cur = self._register(cur, kf_img, np.linalg.inv(T_world_kf) @ predicted)
            fell_back = not ok
            if ok:
                pose = T_world_kf @ T_kf_cur
            else:
                self._fallbacks += 1
                ok, T_prev_cur = self._register(cur, prev_img, self._velocity)
                pose = T_world_prev @ T_prev_cur if ok else T_world_prev
            tracked = ok
            if ok:
                self._velocity = np.linalg.inv(T_world_prev) @ pose
                rel = np.linalg.inv(T_world_kf) @ pose
                new_kf = (fell_back or np.linalg.norm(rel[:3, 3]) > self.keyframe_translation
                          or _angle_deg(rel[:3, :3]) > self.keyframe_rotation_deg)
            else:
                self._velocity = np.eye(4)
                new_kf = True
            if new_kf:
                self._kf = (cur, pose)
                self._keyframes += 1
        self._prev = (cur, pose)
        self._seconds.append(time.perf_counter() - t0)
        self._tracked.append(bool(tracked))
        return {T_WORLD_CAM: pose.copy(), TRACKED: int(tracked)}

    def finish(self) -> Any:
        """An ``AgentOutput`` without key-frame depth; counts and the configuration in ``extras``."""
        from sim_envs.agent import AgentOutput

        n = len(self._tracked)
        secs = np.asarray(self._seconds)
        extras: dict[str, Any] = {
            FRAMES: n,
            TRACKED_SHARE: float(np.mean(self._tracked)) if n else 0.0,
            "keyframes": self._keyframes,
            "fallbacks_to_previous_frame": self._fallbacks,
            "depth_source": dict(self._depth_source),
            "correspondence_share_median": float(np.median(self._shares)) if self._shares else 0.0,
            "config": {"jacobian": self.jacobian, "depth_min": self.depth_min, "depth_max": self.depth_max,
                       "depth_diff_max": self.depth_diff_max, "iterations": list(self.iterations),
                       "keyframe_translation": self.keyframe_translation,
                       "keyframe_rotation_deg": self.keyframe_rotation_deg,
                       "min_correspondence_share": self.min_correspondence_share, "open3d": o3d.__version__},
            "mean_step_seconds": float(secs.mean()) if n else 0.0,
        }
        return AgentOutput(keyframes=[], extras=extras)
