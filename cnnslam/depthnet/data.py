"""Training data for the depth network: rendered once to disk from the simulator's TRAINING split, then read back
with augmentation.

Generation (:func:`generate_dataset`): rooms of ``sim_envs.scenes.scenegen.TRAIN_STYLES`` only (never the test styles
office / living), scene seeds >= ``sim_envs.sequences.TRAIN_SEED_BASE`` (test sequences use seeds below 1000), NYU
Kinect intrinsics at 320x240 (the paper's network was trained on NYU Depth v2), texture density varied per room. Per
room, camera views are sampled like a hand-held Kinect (:func:`sample_view_pose`; a share ``close_range`` of them
0.4-1.5 m from a surface, :func:`sample_close_view_pose`). One shard per room: a folder
``scene_<seed>/`` with ``rgb.npy`` (N, H, W, 3) uint8, ``depth.npy`` (N, H, W) uint16 millimetres (0 = no surface),
``labels.npy`` (N, H, W) uint8 (255 = none), ``poses.npy`` (N, 4, 4) float64 ``T_world_cam`` and ``meta.json``.
With ``GenerationConfig.focal_scale`` a room is rendered at another focal length (the shipped network's last
fine-tune: NYU's times 0.8..1.25) and read back with depth / s, the nominal camera's target for that image. A shard
is written to a temporary folder and renamed when complete, so an interrupted run resumes by skipping the finished
shards; every shard is a function of (data seed, scene seed) only, so the same seed gives the same bytes.

Reading (:class:`RenderedDataset`): memory-mapped shards, optionally at half resolution (the shipped network works at
160x120: images area-averaged exactly as the predictor does, ground truth by 2x2 blocks). Augmentation
(:func:`augment`): random crops that keep the pixel scale (images are never randomly rescaled: that would change the
focal length the network learns, which eq. 5 relies on), horizontal flips, brightness / contrast / saturation /
per-channel gain / gamma jitter, occasional channel permutation and blur, Gaussian noise.

These are training tools of the network: they use the simulator's ground truth, which the SLAM stages never see.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from cnnslam.depthnet.views import ViewConfig as ViewConfig  # re-exported: the views' home is depthnet.views
from cnnslam.depthnet.views import camera_rotation as camera_rotation
from cnnslam.depthnet.views import sample_close_view_pose as sample_close_view_pose
from cnnslam.depthnet.views import sample_view_pose as sample_view_pose
from cnnslam.depthnet.views import view_is_usable as view_is_usable
from cnnslam.errors import CnnSlamError
from sim_envs.camera import Intrinsics, preset
from sim_envs.frames import NO_LABEL

DATA_FORMAT = "cnnslam-depthnet-data-v1"
TRAIN_CAMERA = "nyu"  # NYU Depth v2's Kinect, what FCRN (and so the paper's network) was trained on
TRAIN_WIDTH, TRAIN_HEIGHT = 320, 240
SPLIT_SEED_OFFSETS: dict[str, int] = {"train": 0, "val": 500_000}  # scene seed = TRAIN_SEED_BASE + offset + i (ours)
DEPTH_SCALE = 1000.0  # stored depth units per metre (uint16 millimetres, up to 65.5 m)
EDGE_RATIO = 1.05  # a 2x2 block whose depths differ by more than 5 % straddles an edge: no ground truth there (ours)


# ------------------------------------------------------------------------------------------------- generation


@dataclass(frozen=True)
class GenerationConfig:
    """What :func:`generate_dataset` renders (ours; sized for a 2-core machine, see results/depthnet.md)."""

    n_scenes: int = 1200  # rooms of the split (the shipped weights' data)
    views_per_scene: int = 20  # camera views per room
    data_seed: int = 0  # seeds view sampling and texture densities: default_rng((data_seed, scene_seed))
    texture_density: tuple[float, float] = (0.3, 1.0)  # uniform range passed to the room generator
    camera: str = TRAIN_CAMERA
    width: int = TRAIN_WIDTH
    height: int = TRAIN_HEIGHT
    backend: str = "mujoco"
    view: ViewConfig = field(default_factory=ViewConfig)
    # Ours: each room is rendered with the focal length of ``camera`` times a factor drawn log-uniformly from this
    # range (principal point and size kept). The reader divides such a room's depth by the factor: the target is the
    # depth the nominal camera would report for the same image, which is eq. 5's premise (an image seen at a focal
    # length s f_tr must predict D / s). (1, 1): every room with the nominal camera (the first stage's data).
    focal_scale: tuple[float, float] = (1.0, 1.0)
    # Ours: the world's camera (sim_envs.sensor.camera_effects presets or "EFFECT:S"), one drawn per room: each view is
    # then
    # the sensor image a moving camera of that preset would deliver (exposure, vignetting, noise, response, motion
    # blur and rolling shutter; :func:`camera_view`). ("clean",): the renderer's bytes (the shipped stages' data).
    camera_effects: tuple[str, ...] = ("clean",)
    # Camera motion during a view's exposure (camera_effects other than clean): speed and angular speed drawn
    # uniformly up to these, in random directions; sim_envs.motion.trajectories.handheld's limits (0.6 m/s, 35 deg/s).
    max_speed: float = 0.6
    max_angular_speed_deg: float = 35.0
    # Ours: the rooms' lighting (sim_envs.scenes.scene.LIGHTINGS), one drawn per room: "flat" (the same colour from
    # every
    # view; the shipped stages' data) or "lit" (lamps with shadows, bright windows, highlights;
    # sim_envs.scenes.lighting,
    # MuJoCo renderer only). The room's geometry, textures and labels are the same either way.
    lighting: tuple[str, ...] = ("flat",)
    # Ours: the rooms' detail (sim_envs.scenes.scene.DETAILS), one drawn per room: "standard" (the shipped stages'
    # data) or
    # "rich" (the same room with clutter on its surfaces and texture detail at several scales).
    detail: tuple[str, ...] = ("standard",)
    # Ours: the share of each room's views drawn at close range (:func:`sample_close_view_pose`: a floor, table,
    # desk, wall or cupboard 0.4-1.5 m ahead), the rest as ``view`` draws them. 0: no draw at all (the shipped
    # stages' data, byte for byte).
    close_range: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.close_range <= 1.0:
            raise CnnSlamError(f"close_range must be a share in [0, 1], got {self.close_range!r}")
        lo, hi = (float(v) for v in self.focal_scale)
        if not (0 < lo <= hi):
            raise CnnSlamError(f"focal_scale must be a range 0 < lo <= hi, got {self.focal_scale!r}")
        if not self.camera_effects:
            raise CnnSlamError("camera_effects must name at least one camera preset (e.g. 'clean')")
        from sim_envs.sensor.camera_effects import camera_effects_preset

        for name in self.camera_effects:
            camera_effects_preset(name)  # one clear error for an unknown preset, before any rendering
        from sim_envs.scenes.scene import LIGHTINGS

        if not self.lighting or not set(self.lighting) <= set(LIGHTINGS):
            raise CnnSlamError(f"lighting must name one or more of {', '.join(LIGHTINGS)}, got {self.lighting!r}")
        from sim_envs.scenes.scene import DETAILS

        if not self.detail or not set(self.detail) <= set(DETAILS):
            raise CnnSlamError(f"detail must name one or more of {', '.join(DETAILS)}, got {self.detail!r}")
        if "lit" in self.lighting and self.backend != "mujoco":
            raise CnnSlamError(f"lit rooms are drawn by the mujoco renderer only, not {self.backend!r}")
        if not (self.max_speed >= 0 and self.max_angular_speed_deg >= 0):
            raise CnnSlamError(f"max_speed and max_angular_speed_deg must be >= 0, got {self.max_speed}, "
                               f"{self.max_angular_speed_deg}")  # fmt: skip

    def intrinsics(self) -> Intrinsics:
        """The training camera at ``width`` x ``height``."""
        return preset(self.camera, self.width, self.height)

    def draw_focal_scale(self, rng: np.random.Generator) -> float:
        """One room's focal-length factor (log-uniform in ``focal_scale``; 1 without a draw when the range is 1)."""
        lo, hi = (float(v) for v in self.focal_scale)
        if lo == hi == 1.0:
            return 1.0
        return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))

    def draw_camera_effects(self, scene_seed: int) -> str:
        """One room's camera preset, from its own generator (so the views drawn are those of a clean room)."""
        return self._draw_per_room(self.camera_effects, scene_seed, stream=1)

    def draw_lighting(self, scene_seed: int) -> str:
        """One room's lighting, from its own generator (so the views and camera drawn are those of a flat room)."""
        return self._draw_per_room(self.lighting, scene_seed, stream=3)

    def draw_detail(self, scene_seed: int) -> str:
        """One room's detail, from its own generator (so the views, camera and lighting drawn are unchanged)."""
        return self._draw_per_room(self.detail, scene_seed, stream=4)

    def _draw_per_room(self, options: tuple[str, ...], scene_seed: int, stream: int) -> str:
        """One of ``options`` for a room, uniformly from ``default_rng((data_seed, scene_seed, stream))``; a single
        option draws nothing."""
        if len(options) == 1:
            return options[0]
        rng = np.random.default_rng((self.data_seed, scene_seed, stream))
        return options[int(rng.integers(len(options)))]


def camera_velocity(rng: np.random.Generator, max_speed: float, max_angular_speed_deg: float) -> np.ndarray:
    """(6,) camera-frame twist (v [m/s], omega [rad/s]): speed and angular speed uniform up to the limits, each
    along a uniformly random direction (OpenCV camera axes)."""
    dirs = rng.normal(size=(2, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    v = dirs[0] * rng.uniform(0.0, max_speed)
    w = dirs[1] * np.radians(rng.uniform(0.0, max_angular_speed_deg))
    return np.concatenate([v, w])


def camera_view(
    render_rgb: Callable[[np.ndarray], np.ndarray],
    T_world_cam: np.ndarray,
    own_render: np.ndarray,
    effects: Any,
    intrinsics: Intrinsics,
    geometry: Any,
    rng: np.random.Generator,
    max_speed: float,
    max_angular_speed_deg: float,
) -> np.ndarray:
    """The (H, W, 3) uint8 image the world's camera ``effects`` (a :class:`sim_envs.sensor.camera_effects.CameraEffects`
    without lens distortion) delivers of a view whose centre of exposure is ``T_world_cam``, the camera moving at a
    constant twist drawn by :func:`camera_velocity` (motion blur, rolling shutter). The exposure is what the camera's
    auto-exposure settles at for this view, times its per-frame jitter (the exposure otherwise).

    render_rgb: a pinhole render of ``intrinsics`` at a ``T_world_cam`` (4, 4); own_render: the render at
    ``T_world_cam``; geometry: :func:`sim_envs.sensor.camera_effects.sensor_geometry` of ``intrinsics`` and ``effects``
    (one per room). Ground truth (depth, labels) stays the render's at ``T_world_cam``.
    """
    from scipy.spatial.transform import Rotation

    from sim_envs.sensor.camera_effects import auto_exposure, mean_brightness, sensor_image

    twist = camera_velocity(rng, max_speed, max_angular_speed_deg)

    def pose_at(times: np.ndarray) -> np.ndarray:
        times = np.atleast_1d(np.asarray(times, dtype=np.float64))
        delta = np.tile(np.eye(4), (len(times), 1, 1))
        delta[:, :3, :3] = Rotation.from_rotvec(times[:, None] * twist[None, 3:]).as_matrix()
        delta[:, :3, 3] = times[:, None] * twist[None, :3]
        return T_world_cam[None] @ delta

    brightness = np.array([mean_brightness(own_render, effects, geometry.vignette)])
    exposure, gain = auto_exposure(brightness, effects, rng.standard_normal(1))
    return sensor_image(render_rgb, pose_at, 0.0, effects, intrinsics, rng, exposure_s=float(exposure[0]),
                        gain=float(gain[0]), geometry=geometry, own_render=own_render)  # fmt: skip


@dataclass(frozen=True)
class ShardJob:
    """One room to render: its seed, style, texture density and the folder to write."""

    scene_seed: int
    style: str
    out_dir: str


def scene_seeds(split: str, n_scenes: int) -> list[int]:
    """Scene seeds of a split ("train" or "val"): ``TRAIN_SEED_BASE + offset + i``, all >= TRAIN_SEED_BASE."""
    from sim_envs.sequences import TRAIN_SEED_BASE

    if split not in SPLIT_SEED_OFFSETS:
        raise CnnSlamError(f"split must be one of {sorted(SPLIT_SEED_OFFSETS)}, got {split!r}")
    return [TRAIN_SEED_BASE + SPLIT_SEED_OFFSETS[split] + i for i in range(int(n_scenes))]


def shard_jobs(root: str | Path, split: str, cfg: GenerationConfig) -> list[ShardJob]:
    """Every shard of a split, styles cycling through ``TRAIN_STYLES`` so each appears equally often."""
    from sim_envs.scenes.scenegen import TRAIN_STYLES

    out = Path(root) / split
    return [
        ShardJob(seed, str(TRAIN_STYLES[i % len(TRAIN_STYLES)]), str(out / f"scene_{seed:06d}"))
        for i, seed in enumerate(scene_seeds(split, cfg.n_scenes))
    ]


def render_shard(job: ShardJob, cfg: GenerationConfig) -> dict[str, Any]:
    """Render one room's views and write its shard folder atomically; returns its meta (also in meta.json).

    Deterministic: texture density and views are drawn from ``default_rng((cfg.data_seed, job.scene_seed))``.
    """
    from sim_envs.render import make_renderer
    from sim_envs.scenes.scenegen import generate_scene
    from sim_envs.sensor.camera_effects import camera_effects_preset, sensor_geometry

    rng = np.random.default_rng((cfg.data_seed, job.scene_seed))
    density = float(rng.uniform(*cfg.texture_density))
    focal_scale = cfg.draw_focal_scale(rng)
    camera_name = cfg.draw_camera_effects(job.scene_seed)
    # The network sees the agent's undistorted images; a lens's resampling is left out (ours).
    effects = replace(camera_effects_preset(camera_name), distortion=(0.0,) * 5)
    camera_rng = np.random.default_rng((cfg.data_seed, job.scene_seed, 2))
    lighting = cfg.draw_lighting(job.scene_seed)
    detail = cfg.draw_detail(job.scene_seed)
    scene = generate_scene(job.style, job.scene_seed, texture_density=density, lighting=lighting, detail=detail)
    nominal = cfg.intrinsics()
    intr = replace(nominal, fx=nominal.fx * focal_scale, fy=nominal.fy * focal_scale)
    geometry = sensor_geometry(intr, effects) if effects.any else None
    n, h, w = cfg.views_per_scene, cfg.height, cfg.width
    rgb = np.zeros((n, h, w, 3), np.uint8)
    depth = np.zeros((n, h, w), np.uint16)
    labels = np.full((n, h, w), NO_LABEL, np.uint8)
    poses = np.zeros((n, 4, 4))
    modes: list[str] = []
    rejected = 0
    with make_renderer(scene, intr, backend=cfg.backend) as renderer:
        i, close = 0, None
        while i < n:
            if close is None:  # one draw per view slot (none at close_range 0): redraws keep the slot's kind
                close = cfg.close_range > 0 and bool(rng.random() < cfg.close_range)
            T, mode = (sample_close_view_pose if close else sample_view_pose)(scene, rng, cfg.view)
            out = renderer.render(T, outputs=("rgb", "depth", "labels"))
            if not view_is_usable(out.depth, cfg.view, mode):
                rejected += 1
                if rejected > 20 * n:
                    raise CnnSlamError(f"room {job.style}/{job.scene_seed}: too many unusable views ({rejected})")
                continue
            if effects.any:
                out_rgb = camera_view(lambda P: renderer.render(P, outputs=("rgb",)).rgb, T, out.rgb, effects,
                                      intr, geometry, camera_rng, cfg.max_speed,
                                      cfg.max_angular_speed_deg)  # fmt: skip
            else:
                out_rgb = out.rgb
            rgb[i], labels[i], poses[i] = out_rgb, out.labels, T
            depth[i] = np.clip(np.round(out.depth * DEPTH_SCALE), 0, np.iinfo(np.uint16).max).astype(np.uint16)
            modes.append(mode)
            i, close = i + 1, None
    meta = {
        "format": DATA_FORMAT,
        "scene_seed": job.scene_seed,
        "style": job.style,
        "texture_density": density,
        "n_views": n,
        "rejected_views": rejected,
        "modes": modes,
        "camera": cfg.camera,
        "intrinsics": [nominal.fx, nominal.fy, nominal.cx, nominal.cy],
        "focal_scale": focal_scale,  # rendered with fx, fy = focal_scale x the above
        "camera_effects": camera_name,
        "lighting": lighting,
        "detail": detail,
        "width": w,
        "height": h,
        "depth_scale": DEPTH_SCALE,
        "data_seed": cfg.data_seed,
    }
    final = Path(job.out_dir)
    tmp = final.with_name(final.name + ".tmp")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    for name, arr in (("rgb", rgb), ("depth", depth), ("labels", labels), ("poses", poses)):
        np.save(tmp / f"{name}.npy", arr)
    for name, arr in half_resolution_arrays(rgb, depth, labels, focal_scale).items():
        np.save(tmp / f"{name}.npy", arr)
    (tmp / "meta.json").write_text(json.dumps(meta, indent=1))
    os.replace(tmp, final)
    return meta


HALF = 2  # the shipped network's downsampling factor: its copies of a shard are stored beside the full resolution


def half_resolution_arrays(rgb: np.ndarray, depth_units: np.ndarray, labels: np.ndarray, focal_scale: float,
                           ) -> dict[str, np.ndarray]:
    """A shard at the shipped network's resolution (1 / :data:`HALF`), exactly as :class:`RenderedDataset` would
    make each frame on reading (depth in metres divided by the room's focal scale, then
    :func:`downsample_ground_truth`; images by :func:`downsample_rgb`), so that reading costs no resampling:
    ``rgb_d2`` (N, h, w, 3) uint8, ``depth_d2`` (N, h, w) float32 metres (0 = none), ``labels_d2`` (N, h, w) uint8.
    """
    scale = np.float32(DEPTH_SCALE * focal_scale)
    pairs = [downsample_ground_truth(d.astype(np.float32) / scale, lab, HALF) for d, lab in zip(depth_units, labels,
                                                                                              strict=True)]
    return {
        f"rgb_d{HALF}": np.stack([downsample_rgb(im, HALF) for im in rgb]),
        f"depth_d{HALF}": np.stack([p[0] for p in pairs]).astype(np.float32),
        f"labels_d{HALF}": np.stack([p[1] for p in pairs]).astype(np.uint8),
    }


def _render_shard_worker(job: ShardJob, cfg: GenerationConfig) -> dict[str, Any]:
    return render_shard(job, cfg)


def generate_dataset(
    root: str | Path,
    split: str,
    cfg: GenerationConfig,
    workers: int = 2,
    progress: Callable[[Iterator[Any], int], Iterator[Any]] | None = None,
) -> list[Path]:
    """Render every missing shard of ``split`` under ``root/split`` (resumable: finished shards are skipped).

    workers: processes (spawned: a process holding an OpenGL context must not fork); 0 renders in this process. On
    an interruption the rooms being rendered are finished and the others dropped (a later call renders them).
    progress: wraps the iterator of finished shards with its total (e.g. a tqdm bar). Returns all shard folders.
    """
    jobs = shard_jobs(root, split, cfg)
    todo = [j for j in jobs if not (Path(j.out_dir) / "meta.json").is_file()]
    wrap = progress or (lambda it, total: it)
    if workers <= 0:
        for _ in wrap(iter(render_shard(j, cfg) for j in todo), len(todo)):
            pass
    elif todo:
        ctx = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
        try:
            futures = [pool.submit(_render_shard_worker, j, cfg) for j in todo]
            for fut in wrap(as_completed(futures), len(futures)):
                fut.result()
        except BaseException:  # interrupted (Ctrl-C) or a room failed: the rooms not started are dropped
            pool.shutdown(wait=True, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    return [Path(j.out_dir) for j in jobs]


# ------------------------------------------------------------------------------------------------- reading


def downsample_rgb(rgb: np.ndarray, factor: int) -> np.ndarray:
    """(H, W, 3) uint8 -> (H / factor, W / factor, 3) uint8 by area averaging (``cv2.INTER_AREA``), exactly what
    :meth:`DepthNetPredictor.predict_raw` does to an image larger than the network's training size."""
    if factor == 1:
        return rgb
    import cv2

    h, w = rgb.shape[:2]
    return cv2.resize(rgb, (w // factor, h // factor), interpolation=cv2.INTER_AREA)


def downsample_ground_truth(depth: np.ndarray, labels: np.ndarray, factor: int) -> tuple[np.ndarray, np.ndarray]:
    """Ground truth at 1 / factor resolution by factor x factor blocks (pixel centres stay consistent with area
    averaging of the image).

    depth (H, W) float32 metres -> block mean where every depth of the block is valid and max / min <= EDGE_RATIO,
    else 0 (no ground truth across depth edges). labels (H, W) uint8 -> the block's label where the block agrees,
    else 255. H and W must be multiples of ``factor``.
    """
    if factor == 1:
        return depth, labels
    h, w = depth.shape
    if h % factor or w % factor:
        raise CnnSlamError(f"image {w}x{h} is not a multiple of the downsampling factor {factor}")
    blocks = depth.reshape(h // factor, factor, w // factor, factor)
    lo, hi = blocks.min(axis=(1, 3)), blocks.max(axis=(1, 3))
    ok = (lo > 0) & (hi <= EDGE_RATIO * lo)
    d = np.where(ok, blocks.mean(axis=(1, 3)), 0.0).astype(np.float32)
    lab = labels.reshape(h // factor, factor, w // factor, factor)
    first = lab[:, 0, :, 0]
    same = (lab == first[:, None, :, None]).all(axis=(1, 3))
    return d, np.where(same, first, NO_LABEL).astype(np.uint8)



@dataclass(frozen=True)
class Sample:
    """One training frame: rgb (H, W, 3) uint8; depth (H, W) float32 metres (0 = none); labels (H, W) uint8."""

    rgb: np.ndarray
    depth: np.ndarray
    labels: np.ndarray


class RenderedDataset(Dataset):
    """The shards of ``root/split`` (every finished ``scene_*`` folder), memory-mapped, as a torch Dataset.

    ``dataset[i]`` is a :class:`Sample` at 1 / ``downsample`` of the stored resolution (:func:`downsample_rgb`,
    :func:`downsample_ground_truth`). ``intrinsics``: the (common) nominal camera of every shard at that resolution;
    ``train_focal`` its ``(fx + fy) / 2`` in pixels at that resolution. A shard rendered with ``focal_scale`` s != 1
    (:class:`GenerationConfig`) gives depth / s: the network's target for the nominal camera (eq. 5's premise).
    """

    def __init__(self, root: str | Path, split: str, max_shards: int | None = None, downsample: int = 1) -> None:
        if downsample not in (1, 2, 4):
            raise CnnSlamError(f"downsample must be 1, 2 or 4, got {downsample!r}")
        self.downsample = int(downsample)
        folder = Path(root) / split
        shards = sorted(p for p in folder.glob("scene_*") if (p / "meta.json").is_file() and p.suffix != ".tmp")
        if max_shards is not None:
            shards = shards[:max_shards]
        if not shards:
            raise CnnSlamError(f"no finished shards under {folder}; generate them with 'cnnslam train generate-data'")
        self.shards = shards
        self.metas = [json.loads((p / "meta.json").read_text()) for p in shards]
        cams = {(tuple(m["intrinsics"]), m["width"], m["height"]) for m in self.metas}
        if len(cams) != 1:
            raise CnnSlamError(f"shards under {folder} mix cameras: {sorted(cams)}")
        (fx, fy, cx, cy), w, h = cams.pop()
        self.stored_intrinsics = Intrinsics(fx, fy, cx, cy, int(w), int(h))
        self.intrinsics = self.stored_intrinsics.scaled(int(w) // self.downsample, int(h) // self.downsample)
        self._arrays = [
            {name: np.load(p / f"{name}.npy", mmap_mode="r") for name in ("rgb", "depth", "labels")} for p in shards
        ]
        # shards that hold their copies at the network's resolution are read from them (the same arrays, made once)
        self._half = [
            {name: np.load(p / f"{name}_d{HALF}.npy", mmap_mode="r") for name in ("rgb", "depth", "labels")}
            if self.downsample == HALF and (p / f"labels_d{HALF}.npy").is_file() else None
            for p in shards
        ]
        self.focal_scales = np.array([float(m.get("focal_scale", 1.0)) for m in self.metas])
        counts = np.array([len(a["rgb"]) for a in self._arrays])
        self._offsets = np.concatenate([[0], np.cumsum(counts)])
        self.depth_scale = float(self.metas[0]["depth_scale"])

    @property
    def train_focal(self) -> float:
        """f_tr = (fx + fy) / 2 of the training camera, pixels at its resolution."""
        return (self.intrinsics.fx + self.intrinsics.fy) / 2.0

    @property
    def image_size(self) -> tuple[int, int]:
        """(W, H) of the stored images."""
        return self.intrinsics.width, self.intrinsics.height

    def __len__(self) -> int:
        return int(self._offsets[-1])

    def __getitem__(self, index: int) -> Sample:
        if not 0 <= index < len(self):
            raise IndexError(f"index {index} out of range for {len(self)} frames")
        s = int(np.searchsorted(self._offsets, index, side="right") - 1)
        j = index - int(self._offsets[s])
        half = self._half[s]
        if half is not None:
            return Sample(np.array(half["rgb"][j]), np.array(half["depth"][j]), np.array(half["labels"][j]))
        arr = self._arrays[s]
        depth = np.asarray(arr["depth"][j], dtype=np.float32) / np.float32(self.depth_scale * self.focal_scales[s])
        rgb, labels = np.array(arr["rgb"][j]), np.array(arr["labels"][j])
        if self.downsample > 1:
            rgb = downsample_rgb(rgb, self.downsample)
            depth, labels = downsample_ground_truth(depth, labels, self.downsample)
        return Sample(rgb, depth, labels)

    def summary(self) -> dict[str, Any]:
        """Counts for the manifest: shards, frames, styles, texture densities, seeds."""
        styles: dict[str, int] = {}
        for m in self.metas:
            styles[m["style"]] = styles.get(m["style"], 0) + m["n_views"]
        seeds = [m["scene_seed"] for m in self.metas]
        dens = [m["texture_density"] for m in self.metas]
        return {
            "shards": len(self.shards),
            "frames": len(self),
            "frames_per_style": styles,
            "scene_seeds": [min(seeds), max(seeds)],
            "texture_density": [min(dens), max(dens)],
            "focal_scale": [float(self.focal_scales.min()), float(self.focal_scales.max())],
            "data_seed": self.metas[0]["data_seed"],
            "camera": self.metas[0]["camera"],
            "stored_intrinsics": list(self.metas[0]["intrinsics"]),
            "stored_size": [self.stored_intrinsics.width, self.stored_intrinsics.height],
            "downsample": self.downsample,
            "image_size": list(self.image_size),
        }


# ------------------------------------------------------------------------------------------------- augmentation


@dataclass(frozen=True)
class AugmentConfig:
    """Training-time augmentation (ours). Crops keep the pixel scale; nothing is ever resized."""

    crop: tuple[int, int] = (96, 128)  # (h, w) of the random crop (of 120 x 160 images at downsample 2)
    p_flip: float = 0.5  # horizontal flip
    brightness: tuple[float, float] = (0.6, 1.4)  # multiplicative gain
    contrast: tuple[float, float] = (0.6, 1.4)  # scaling about the image mean
    saturation: tuple[float, float] = (0.5, 1.5)  # blend with the grey image
    channel_gain: tuple[float, float] = (0.85, 1.15)  # per-channel gain (white balance)
    gamma: tuple[float, float] = (0.7, 1.45)
    p_channel_shuffle: float = 0.15
    noise_std: tuple[float, float] = (0.0, 6.0)  # Gaussian noise std, 8-bit intensity levels
    p_blur: float = 0.15  # a 3x3 box blur (defocus / motion)
    # A real camera's pipeline on top of the jitter above (ours; :func:`camera_pipeline`), applied to a share
    # ``p_camera`` of the samples (0: off, the first shipped networks' augmentation): vignetting (relative fall-off v
    # at the corners), linear motion blur of a random direction (length in pixels at the network's resolution), shot
    # noise (std = k sqrt(intensity), intensities in [0, 1]), and JPEG compression at a random quality.
    p_camera: float = 0.0
    vignetting: tuple[float, float] = (0.0, 0.45)
    p_motion_blur: float = 0.5
    motion_blur_px: tuple[float, float] = (1.0, 5.0)
    shot_noise: tuple[float, float] = (0.0, 0.04)
    p_jpeg: float = 0.6
    jpeg_quality: tuple[int, int] = (35, 95)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form for the manifest."""
        return asdict(self)


def augment(sample: Sample, rng: np.random.Generator, cfg: AugmentConfig) -> Sample:
    """A random crop (pixel scale kept), flip and photometric jitter of ``sample``; geometry of depth and labels
    follows the crop and flip exactly. Returns a new :class:`Sample` of size ``cfg.crop``."""
    h, w = sample.depth.shape
    ch, cw = min(cfg.crop[0], h), min(cfg.crop[1], w)
    y0, x0 = int(rng.integers(0, h - ch + 1)), int(rng.integers(0, w - cw + 1))
    rgb = sample.rgb[y0 : y0 + ch, x0 : x0 + cw].astype(np.float32) / 255.0
    depth = sample.depth[y0 : y0 + ch, x0 : x0 + cw]
    labels = sample.labels[y0 : y0 + ch, x0 : x0 + cw]
    if rng.random() < cfg.p_flip:
        rgb, depth, labels = rgb[:, ::-1], depth[:, ::-1], labels[:, ::-1]
    rgb = rgb * np.float32(rng.uniform(*cfg.brightness))
    mean = rgb.mean()
    rgb = (rgb - mean) * np.float32(rng.uniform(*cfg.contrast)) + mean
    grey = rgb @ np.array([0.299, 0.587, 0.114], np.float32)
    s = np.float32(rng.uniform(*cfg.saturation))
    rgb = grey[..., None] + (rgb - grey[..., None]) * s
    rgb = rgb * rng.uniform(*cfg.channel_gain, size=3).astype(np.float32)
    rgb = np.clip(rgb, 0.0, 1.0) ** np.float32(rng.uniform(*cfg.gamma))
    if rng.random() < cfg.p_channel_shuffle:
        rgb = rgb[..., rng.permutation(3)]
    if rng.random() < cfg.p_blur:
        import cv2

        rgb = cv2.blur(np.ascontiguousarray(rgb), (3, 3))
    if cfg.p_camera > 0 and rng.random() < cfg.p_camera:
        rgb = camera_pipeline(np.ascontiguousarray(rgb), rng, cfg)
    sigma = rng.uniform(*cfg.noise_std) / 255.0
    if sigma > 0:
        rgb = rgb + rng.normal(0.0, sigma, rgb.shape).astype(np.float32)
    out = np.clip(np.round(rgb * 255.0), 0, 255).astype(np.uint8)
    if cfg.p_camera > 0 and rng.random() < cfg.p_camera * cfg.p_jpeg:
        out = jpeg_roundtrip(out, int(rng.integers(cfg.jpeg_quality[0], cfg.jpeg_quality[1] + 1)))
    return Sample(np.ascontiguousarray(out), np.ascontiguousarray(depth), np.ascontiguousarray(labels))


def camera_pipeline(rgb: np.ndarray, rng: np.random.Generator, cfg: AugmentConfig) -> np.ndarray:
    """A real camera's effects on an (H, W, 3) float32 image in [0, 1] (ours, after ``sim_envs.sensor.camera_effects``
    but cheap enough for every training sample): vignetting ``1 - v q`` (q = 0 at the centre, 1 at the corners: the
    squared distance from the centre in half-widths and half-heights, halved), a linear motion
    blur of length ``motion_blur_px`` at a uniform angle (with probability ``p_motion_blur``), and shot noise of std
    ``k sqrt(I)``. Geometry is unchanged (ground truth stays valid)."""
    import cv2

    h, w = rgb.shape[:2]
    v = np.float32(rng.uniform(*cfg.vignetting))
    if v > 0:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((xx - (w - 1) / 2) / ((w - 1) / 2)) ** 2 + ((yy - (h - 1) / 2) / ((h - 1) / 2)) ** 2
        rgb = rgb * (1.0 - v * r2 / 2.0)[..., None]
    if rng.random() < cfg.p_motion_blur:
        length = float(rng.uniform(*cfg.motion_blur_px))
        angle = float(rng.uniform(0.0, np.pi))
        size = int(np.ceil(length)) | 1
        kernel = np.zeros((size, size), np.float32)
        c = size // 2
        for t in np.linspace(-length / 2, length / 2, 4 * size):
            kernel[int(round(c + t * np.sin(angle))), int(round(c + t * np.cos(angle)))] += 1.0
        rgb = cv2.filter2D(np.ascontiguousarray(rgb), -1, kernel / kernel.sum(), borderType=cv2.BORDER_REFLECT)
    k = np.float32(rng.uniform(*cfg.shot_noise))
    if k > 0:
        rgb = rgb + (k * np.sqrt(np.clip(rgb, 0.0, 1.0))) * rng.standard_normal(rgb.shape).astype(np.float32)
    return rgb.astype(np.float32)


def jpeg_roundtrip(rgb: np.ndarray, quality: int) -> np.ndarray:
    """(H, W, 3) uint8 RGB compressed as JPEG at ``quality`` (1..100) and decoded again (OpenCV)."""
    import cv2

    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise CnnSlamError("JPEG encoding failed")
    return np.ascontiguousarray(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])


def collate(samples: Sequence[Sample]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Stack samples of one size into tensors: rgb (B, 3, H, W) uint8, depth (B, 1, H, W) float32 metres,
    labels (B, H, W) int64 (255 = none)."""
    rgb = torch.from_numpy(np.stack([s.rgb for s in samples])).permute(0, 3, 1, 2).contiguous()
    depth = torch.from_numpy(np.stack([s.depth for s in samples]))[:, None]
    labels = torch.from_numpy(np.stack([s.labels for s in samples]).astype(np.int64))
    return rgb, depth, labels


def training_batch(
    dataset: Dataset, rng: np.random.Generator, batch_size: int, cfg: AugmentConfig
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``batch_size`` frames drawn uniformly with replacement from ``dataset`` and augmented (see :func:`collate`)."""
    idx = rng.integers(0, len(dataset), size=batch_size)
    return collate([augment(dataset[int(i)], rng, cfg) for i in idx])
