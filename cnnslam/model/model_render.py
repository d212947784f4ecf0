"""Pictures of the global model like the paper's Fig. 6: the reconstruction coloured by RGB and by semantic label,
with the estimated camera trajectory drawn in green, seen from above and behind the trajectory.

Rendering is ours and needs no OpenGL: the surfels are splatted as discs into a virtual pinhole camera with a
z-buffer (the numba kernel :func:`cnnslam.model.surfel_kernels.splat_index_map`), shaded by their normals for the label
view.
The virtual camera (:func:`overview_camera`) looks at the model's median point from ``elevation_deg`` above the
horizon, from the side opposite to the trajectory's mean viewing direction ("behind" the camera), and its focal
length is set so that 98 % of the points fill the image. A cut-away makes the room readable from there: surfels
higher than the trajectory's highest camera plus ``ceiling_margin`` metres (the ceiling) and surfels facing away from
the virtual camera (the back of the near walls) are not drawn.

"Up" is the mean of the trajectory cameras' -y axes (a hand-held camera is held upright; OpenCV y points down).

The numpy part (:func:`render_map_views`) returns images and the projected trajectory; matplotlib is imported only
by :func:`draw_map_views` (draws into axes the caller passes) and :func:`save_map_figure` (writes a PNG).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnnslam.errors import CnnSlamError
from cnnslam.geometry import se3_inverse
from cnnslam.model.global_model import SurfelCloud
from cnnslam.model.surfel_kernels import splat_index_map
from sim_envs.motion.trajectories import look_at, poses_from

CLASS_LABELS: tuple[str, ...] = ("floor", "vertical structure", "large structure / furniture", "small structure")
# Fixed palette of the 4 classes (RGB), and the colour of an element without label evidence.
PALETTE: np.ndarray = np.array([[176, 128, 78], [126, 172, 214], [238, 152, 44], [206, 52, 126]], dtype=np.uint8)
NO_LABEL_COLOUR: tuple[int, int, int] = (170, 170, 170)
TRAJECTORY_COLOUR: str = "#10c010"
BACKGROUND: int = 255


@dataclass(frozen=True)
class ViewCamera:
    """A virtual pinhole camera: T_world_cam (4, 4) float64 (OpenCV axes), intrinsics [fx, fy, cx, cy] pixels,
    size (H, W)."""

    T_world_cam: np.ndarray
    intrinsics: np.ndarray
    size: tuple[int, int]


@dataclass(frozen=True)
class MapViews:
    """The two pictures of one model: rgb, labels (H, W, 3) uint8; trajectory_uv (N, 2) float64 pixel positions of
    the trajectory's camera centres (NaN behind the virtual camera); keyframe_uv (K, 2, 2) float64 pixel segments
    from each key-frame's centre along its viewing direction (``view_tick`` metres); camera: the
    :class:`ViewCamera`; drawn: how many surfels passed the cut-away."""

    rgb: np.ndarray
    labels: np.ndarray
    trajectory_uv: np.ndarray
    keyframe_uv: np.ndarray
    camera: ViewCamera
    drawn: int


def up_direction(T_world_cam: np.ndarray) -> np.ndarray:
    """(3,) unit "up" of a trajectory (N, 4, 4): the normalised mean of the cameras' -y axes."""
    T = np.asarray(T_world_cam, dtype=np.float64).reshape(-1, 4, 4)
    up = -T[:, :3, 1].mean(axis=0)
    n = np.linalg.norm(up)
    if n < 1e-6:
        raise CnnSlamError("cannot tell 'up' from the trajectory: its cameras' y axes cancel out")
    return up / n


def project(points: np.ndarray, camera: ViewCamera) -> tuple[np.ndarray, np.ndarray]:
    """Pixel positions (N, 2) float64 and camera depths (N,) of world points (N, 3) (NaN pixels behind the camera)."""
    T = se3_inverse(camera.T_world_cam)
    q = np.asarray(points, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
    fx, fy, cx, cy = camera.intrinsics
    z = q[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.stack([fx * q[:, 0] / z + cx, fy * q[:, 1] / z + cy], axis=1)
    uv[z <= 1e-6] = np.nan
    return uv, z


def overview_camera(T_world_cam_traj: np.ndarray, points: np.ndarray, size: tuple[int, int] = (720, 960),
                    elevation_deg: float = 50.0, up: np.ndarray | None = None, fill: float = 0.92) -> ViewCamera:
    """The virtual camera of the module docstring for a trajectory (N, 4, 4) and the points to show (M, 3): 98 % of
    the points and the whole trajectory fill ``fill`` of the image."""
    traj = np.asarray(T_world_cam_traj, dtype=np.float64).reshape(-1, 4, 4)
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape[0] == 0 or traj.shape[0] == 0:
        raise CnnSlamError("an overview needs at least one point and one trajectory pose")
    up = up_direction(traj) if up is None else np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    forward = traj[:, :3, 2].mean(axis=0)
    forward -= up * (forward @ up)
    if np.linalg.norm(forward) < 1e-3:  # a full turn: use the first camera's view
        forward = traj[0, :3, 2] - up * (traj[0, :3, 2] @ up)
    if np.linalg.norm(forward) < 1e-6:
        forward = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    forward /= np.linalg.norm(forward)
    target = np.median(pts, axis=0)
    radius = float(np.percentile(np.linalg.norm(pts - target, axis=1), 90)) + 0.5
    e = math.radians(elevation_deg)
    position = target + (-forward * math.cos(e) + up * math.sin(e)) * 2.5 * radius
    T = poses_from(position, look_at(position, target, up))[0]  # elevation > 0: never along up
    h, w = size
    unit = ViewCamera(T, np.array([1.0, 1.0, 0.0, 0.0]), size)
    uv, z = project(pts, unit)
    uv = uv[z > 1e-6]
    lo, hi = np.percentile(uv, 1, axis=0), np.percentile(uv, 99, axis=0)
    uv_traj, z_traj = project(traj[:, :3, 3], unit)
    uv_traj = uv_traj[z_traj > 1e-6]
    if uv_traj.shape[0]:  # the whole trajectory is in the picture
        lo, hi = np.minimum(lo, uv_traj.min(axis=0)), np.maximum(hi, uv_traj.max(axis=0))
    span = np.maximum(hi - lo, 1e-6)
    f = fill * min(w / span[0], h / span[1])
    centre = 0.5 * (lo + hi)
    intrinsics = np.array([f, f, (w - 1) / 2 - f * centre[0], (h - 1) / 2 - f * centre[1]])
    return ViewCamera(T, intrinsics, (h, w))


def cutaway_mask(cloud: SurfelCloud, camera: ViewCamera, T_world_cam_traj: np.ndarray, up: np.ndarray,
                 ceiling_margin: float = 0.3) -> np.ndarray:
    """(N,) bool: surfels below the highest trajectory camera + ``ceiling_margin`` (along ``up``) that face the
    virtual camera."""
    p = cloud.positions.astype(np.float64)
    top = float((np.asarray(T_world_cam_traj)[:, :3, 3] @ up).max()) + ceiling_margin
    facing = np.einsum("ij,ij->i", cloud.normals.astype(np.float64), camera.T_world_cam[:3, 3] - p) > 0
    return (p @ up <= top) & facing


def splat_image(points: np.ndarray, colours: np.ndarray, radius: np.ndarray, camera: ViewCamera,
                normals: np.ndarray | None = None, shading: float = 0.0, min_radius_px: float = 1.0,
                max_radius_px: float = 8.0) -> np.ndarray:
    """Render points (N, 3) with colours (N, 3) uint8 and radii (N,) metres as discs: (H, W, 3) uint8, white where
    nothing is drawn. ``shading`` in [0, 1] darkens surfels seen at a grazing angle: colour x (1 - shading +
    shading |cos|) (needs ``normals``)."""
    h, w = camera.size
    uv, z = project(points, camera)
    ok = np.isfinite(uv).all(axis=1) & (z > 1e-6)
    fx = camera.intrinsics[0]
    r_px = np.clip(fx * np.asarray(radius, dtype=np.float64)[ok] / z[ok], min_radius_px, max_radius_px)
    index, _ = splat_index_map(uv[ok, 0], uv[ok, 1], z[ok], r_px, h, w)
    out = np.full((h, w, 3), BACKGROUND, np.uint8)
    hit = index >= 0
    ids = np.flatnonzero(ok)[index[hit]]
    col = np.asarray(colours, dtype=np.float64)[ids]
    if shading > 0 and normals is not None:
        view = camera.T_world_cam[:3, 3] - np.asarray(points, dtype=np.float64)[ids]
        view /= np.maximum(np.linalg.norm(view, axis=1, keepdims=True), 1e-12)
        cos = np.abs(np.einsum("ij,ij->i", np.asarray(normals, dtype=np.float64)[ids], view))
        col *= (1.0 - shading + shading * cos)[:, None]
    out[hit] = np.clip(np.rint(col), 0, 255).astype(np.uint8)
    return out


def label_colours(labels: np.ndarray) -> np.ndarray:
    """(N, 3) uint8 palette colours of labels (N,) (``NO_LABEL`` and unknown classes grey)."""
    labels = np.asarray(labels)
    out = np.tile(np.array(NO_LABEL_COLOUR, np.uint8), (labels.shape[0], 1))
    known = labels < PALETTE.shape[0]
    out[known] = PALETTE[labels[known]]
    return out


def render_map_views(cloud: SurfelCloud, T_world_cam_traj: np.ndarray, size: tuple[int, int] = (720, 960),
                     elevation_deg: float = 50.0, ceiling_margin: float = 0.3, keyframes: np.ndarray | None = None,
                     view_tick: float = 0.3) -> MapViews:
    """Both pictures of the module docstring for a model and its trajectory (N, 4, 4), in the model's frame;
    ``keyframes`` (K, 4, 4): poses whose viewing directions are drawn as short ticks (what a pure rotation shows)."""
    traj = np.asarray(T_world_cam_traj, dtype=np.float64).reshape(-1, 4, 4)
    if len(cloud) == 0:
        raise CnnSlamError("the model is empty: nothing to draw")
    up = up_direction(traj)
    top = float((traj[:, :3, 3] @ up).max()) + ceiling_margin
    below = cloud.positions.astype(np.float64) @ up <= top
    camera = overview_camera(traj, cloud.positions[below] if below.any() else cloud.positions, size, elevation_deg, up)
    keep = cutaway_mask(cloud, camera, traj, up, ceiling_margin)
    part = cloud.subset(keep)
    # grazing measurements have long footprints: draw every disc at most twice the median radius
    radius = np.minimum(part.radius, 2.0 * float(np.median(part.radius))) if len(part) else part.radius
    rgb = splat_image(part.positions, part.colours, radius, camera, part.normals, shading=0.25)
    labels = splat_image(part.positions, label_colours(part.labels), radius, camera, part.normals, shading=0.55)
    uv, _ = project(traj[:, :3, 3], camera)
    kf = np.zeros((0, 4, 4)) if keyframes is None else np.asarray(keyframes, dtype=np.float64).reshape(-1, 4, 4)
    ends = np.stack([kf[:, :3, 3], kf[:, :3, 3] + view_tick * kf[:, :3, 2]], axis=1).reshape(-1, 3)
    kf_uv = project(ends, camera)[0].reshape(-1, 2, 2) if len(kf) else np.zeros((0, 2, 2))
    return MapViews(rgb, labels, uv, kf_uv, camera, int(keep.sum()))


def draw_map_views(ax_rgb: Any, ax_labels: Any, views: MapViews, title: str = "") -> None:
    """Draw both pictures with the trajectory (green) into two matplotlib axes; a class legend on the label view."""
    from matplotlib.patches import Patch

    for ax, image, name in ((ax_rgb, views.rgb, "colour"), (ax_labels, views.labels, "semantic labels")):
        ax.imshow(image, interpolation="nearest")
        uv = views.trajectory_uv
        ax.plot(uv[:, 0], uv[:, 1], color=TRAJECTORY_COLOUR, linewidth=2.0, solid_capstyle="round")
        for seg in views.keyframe_uv:  # key-frames: centre and viewing direction
            ax.plot(seg[:, 0], seg[:, 1], color=TRAJECTORY_COLOUR, linewidth=1.2)
            ax.plot(*seg[0], marker=".", color="black", markersize=3)
        first = np.flatnonzero(np.isfinite(uv).all(axis=1))
        if first.size:
            ax.plot(*uv[first[0]], marker="o", color=TRAJECTORY_COLOUR, markersize=7, markeredgecolor="black")
        h, w = image.shape[:2]
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
        ax.set_axis_off()
        ax.set_title(f"{title}: {name}" if title else name, fontsize=12)
    handles = [Patch(facecolor=PALETTE[i] / 255.0, edgecolor="black", label=CLASS_LABELS[i])
               for i in range(len(CLASS_LABELS))]
    handles.append(Patch(facecolor=np.array(NO_LABEL_COLOUR) / 255.0, edgecolor="black", label="no label"))
    handles.append(Patch(facecolor=TRAJECTORY_COLOUR, edgecolor="black",
                         label="estimated trajectory (ticks: key-frames' view directions)"))
    ax_labels.legend(handles=handles, loc="lower right", fontsize=9, framealpha=0.9)


def save_map_figure(path: str | os.PathLike[str], views: MapViews, title: str = "", dpi: int = 100) -> Path:
    """Write both views side by side as a PNG (matplotlib, Agg backend); returns the path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    h, w = views.rgb.shape[:2]
    fig, axes = plt.subplots(1, 2, figsize=(2 * w / dpi, h / dpi + 0.5), dpi=dpi)
    try:
        draw_map_views(axes[0], axes[1], views, title)
        fig.subplots_adjust(left=0.005, right=0.995, bottom=0.005, top=0.94, wspace=0.01)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)
    return path
