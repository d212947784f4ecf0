"""Render throughput benchmark: frames per second per renderer and output set, for furnished test rooms.

``python -m sim_envs.tools.bench_render`` (or ``cnnslam bench-render``) prints one row per (style, renderer, outputs)
with
frames per second at 320x240 (ICL-NUIM intrinsics) over a camera path circling inside the room, and the scene
generation time. Figures only: nothing is asserted. The target of the project is RGB + depth >= 60 fps on 2 CPU
cores per renderer (Mesa llvmpipe, EGL).
"""

from __future__ import annotations

import argparse
import json
import re
import time
from collections.abc import Sequence

import numpy as np

from sim_envs.camera import preset
from sim_envs.scenes.scene import DETAILS, LIGHTINGS, Scene

OUTPUT_SETS: dict[str, tuple[str, ...]] = {
    "rgb": ("rgb",),
    "depth": ("depth",),
    "rgb+depth": ("rgb", "depth"),
    "labels": ("labels",),
    "all": ("rgb", "depth", "labels", "instances"),
}


def circling_poses(scene: Scene, n: int) -> np.ndarray:
    """(n, 4, 4) T_world_cam (OpenCV axes) circling the room's centre at 1.5 m, looking outwards and 15 deg down."""
    centre = np.asarray(scene.room_size, dtype=float) / 2
    radius = 0.2 * float(min(scene.room_size[:2]))
    poses = np.tile(np.eye(4), (n, 1, 1))
    for k, angle in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False)):
        out = np.array([np.cos(angle), np.sin(angle), 0.0])
        eye = np.array([centre[0], centre[1], 1.5]) + radius * out
        forward = out * np.cos(np.radians(15)) - np.array([0, 0, np.sin(np.radians(15))])
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        poses[k, :3, :3] = np.stack([right, np.cross(forward, right), forward], axis=1)
        poses[k, :3, 3] = eye
    return poses


def measure(scene: Scene, backend: str, outputs: tuple[str, ...], poses: np.ndarray, width: int, height: int,
            warmup: int = 5) -> float:  # fmt: skip
    """Frames per second rendering ``outputs`` of ``scene`` along ``poses`` (after ``warmup`` frames, context made)."""
    from sim_envs.render import make_renderer

    intrinsics = preset("icl", width, height)
    with make_renderer(scene, intrinsics, backend) as renderer:
        for T in poses[:warmup]:
            renderer.render(T, outputs)
        start = time.perf_counter()
        for T in poses:
            renderer.render(T, outputs)
        return len(poses) / (time.perf_counter() - start)


def camera_variants() -> dict[str, object]:
    """The camera presets and each ``kinect`` effect alone (on the clean camera), for :func:`camera_throughput`."""
    from sim_envs.camera import preset_distortion
    from sim_envs.sensor.camera_effects import CameraEffects, camera_effect_presets, camera_effects_preset

    kinect = camera_effects_preset("kinect")
    alone = {
        "noise only": CameraEffects(name="noise", shot_noise=kinect.shot_noise, read_noise=kinect.read_noise,
                                    sensor_width=kinect.sensor_width),
        "response+vignette only": CameraEffects(name="vignette", vignette_corner=kinect.vignette_corner),
        "auto-exposure only": CameraEffects(
            name="ae", auto_exposure=True, ae_target=kinect.ae_target, ae_rate=kinect.ae_rate,
            exposure_jitter=kinect.exposure_jitter, reference_exposure_s=kinect.reference_exposure_s,
            ae_min_s=kinect.ae_min_s, ae_max_s=kinect.ae_max_s, max_gain=kinect.max_gain),
        "blur+rolling shutter only": CameraEffects(name="blur", blur_subframes=kinect.blur_subframes,
                                                   readout_s=kinect.readout_s),
        "distortion only (tum_fr1)": CameraEffects(name="dist", distortion=preset_distortion("tum_fr1")),
        "depth noise only": CameraEffects(name="depth", depth_noise=True),
    }  # fmt: skip
    return {**{p: p for p in camera_effect_presets()}, **alone}


def camera_throughput(
    sequence: str = "office0",
    frames: int = 100,
    width: int = 320,
    height: int = 240,
    renderer: str = "mujoco",
    variants: dict[str, object] | None = None,
    lighting: str = "flat",
    first: int = 0,
    detail: str = "standard",
) -> dict[str, float]:
    """Frames per second of RGB + depth through each camera variant (name -> preset name or ``CameraEffects``;
    default :func:`camera_variants`) along the first ``frames`` frames of ``sequence`` at ``width`` x ``height``,
    after one warm-up frame (context made, room generated; the auto-exposure brightness pass of the frames is
    included in the time), the room lit ``lighting`` (``flat`` or ``lit``) at ``detail`` (``standard`` or ``rich``:
    :mod:`sim_envs.scenes.scenegen`). ``first`` > 0: the warm-up frame is
    frame ``first`` of a sequence that long and the timed frames follow it (what a frame costs late in a long
    sequence). Prints one line per variant and returns name -> fps."""
    from dataclasses import replace

    from sim_envs.sequences import get_sequence, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    if first < 0:
        raise ValueError(f"first must be >= 0, got {first}")
    spec = replace(get_sequence(sequence).with_frames(first + frames + 1), width=width, height=height,
                   lighting=lighting, detail=detail)  # fmt: skip
    out = {}
    for name, camera in (variants or camera_variants()).items():
        with SimulatedSequence(with_camera(spec, camera), renderer) as seq:  # type: ignore[arg-type]
            seq._render(first, ("rgb", "depth"))
            start = time.perf_counter()
            for i in range(first + 1, first + frames + 1):
                seq._render(i, ("rgb", "depth"))
            out[name] = frames / (time.perf_counter() - start)
        print(f"{name:<28} {out[name]:8.1f} fps", flush=True)
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of the benchmark."""
    parser.add_argument("--styles", nargs="+", default=["office", "living"], help="room styles (default: test styles)")
    parser.add_argument("--seed", type=int, default=0, help="scene seed")
    parser.add_argument("--backends", nargs="+", default=["mujoco", "pyrender"], help="renderers to measure")
    parser.add_argument("--outputs", nargs="+", default=list(OUTPUT_SETS), choices=list(OUTPUT_SETS))
    parser.add_argument("--frames", type=int, default=200, help="frames timed per row")
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument(
        "--cameras", action="store_true", help="instead: RGB+depth fps of office0 through each camera and effect alone"
    )
    parser.add_argument("--json", action="store_true", help="with --cameras: also print the figures as one JSON object")
    parser.add_argument("--first", type=int, default=0,
                        help="with --cameras: time the frames after frame FIRST of a sequence that long (default 0)")
    parser.add_argument("--lighting", default="flat", choices=LIGHTINGS,
                        help="flat (default) or lit: lamps with shadows, bright windows, highlights (mujoco only)")
    parser.add_argument("--detail", default="standard", choices=DETAILS,
                        help="standard (default) or rich: the rooms with clutter and texture detail")
    parser.add_argument("--sequence", default="office0", help="with --cameras: the sequence (default office0)")


def run(args: argparse.Namespace) -> int:
    """Print the benchmark table; returns 0."""
    from sim_envs.scenes.scenegen import generate_scene

    if args.cameras:
        print(f"camera throughput, RGB + depth at {args.width}x{args.height}, {args.sequence} ({args.lighting}, "
              f"{args.detail}), {args.frames} frames after frame {args.first}")  # fmt: skip
        variants = None if args.first == 0 else {"kinect": "kinect", "hard": "hard"}  # late frames: the presets
        fps = camera_throughput(args.sequence, args.frames, args.width, args.height, args.backends[0], variants,
                                lighting=args.lighting, first=args.first, detail=args.detail)  # fmt: skip
        if args.json:  # one object, keys "<variant>_fps" (words joined by "_"), for `cnnslam bench perf`
            print(json.dumps({re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_") + "_fps": round(value, 2)
                              for name, value in fps.items()}))  # fmt: skip
        return 0

    print(f"render throughput at {args.width}x{args.height}, {args.frames} frames per row (frames per second)")
    print(f"{'style':<10} {'renderer':<10} {'outputs':<10} {'fps':>8}")
    for style in args.styles:
        start = time.perf_counter()
        scene = generate_scene(style, args.seed, lighting=args.lighting, detail=args.detail)
        gen_s = time.perf_counter() - start
        start = time.perf_counter()
        generate_scene(style, args.seed, settle=False)
        gen_nophys_s = time.perf_counter() - start
        print(
            f"# {style} seed {args.seed}: {len(scene.primitives)} primitives, {scene.n_instances} instances; "
            f"generated in {gen_s:.2f} s with physics, {gen_nophys_s:.2f} s without"
        )
        poses = circling_poses(scene, args.frames)
        for backend in args.backends:
            if scene.lighting != "flat" and backend != "mujoco":
                print(f"{style:<10} {backend:<10} (draws flat lighting only: skipped)")
                continue
            for name in args.outputs:
                fps = measure(scene, backend, OUTPUT_SETS[name], poses, args.width, args.height)
                print(f"{style:<10} {backend:<10} {name:<10} {fps:8.1f}", flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m sim_envs.tools.bench_render``."""
    parser = argparse.ArgumentParser(prog="python -m sim_envs.tools.bench_render", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
