"""``cnnslam generate rotation``: rotation stress sequences (pure rotation about a fixed optical centre, like TUM
fr1/rpy) at chosen axes, angular speeds and lengths; optionally exported as TUM RGB-D folders.

Each (axes, speed) pair gives the sequence ``rot_<axes>_<speed>`` of
:func:`sim_envs.sequences.rotation_stress_spec` (TUM fr1 intrinsics, the office room). The command prints one line
per sequence with the measured angular speed of its trajectory; ``--export DIR`` renders each into
``DIR/<name>/`` (``rgb/``, ``depth/``, ``groundtruth.txt``, ... see :mod:`sim_envs.folders.datasets`) and writes
``DIR/sequences.json`` with the specs, so a third-party system can run on them and be scored with
``cnnslam bench rotation --sequences <names> --external NAME=ITS_OUTPUT``. The same names work in
``cnnslam bench --sequences``. ``--camera`` picks the simulated camera (``kinect`` by default, as every suite; the
names then end in ``@kinect``, as the suites' do).

Example::

    cnnslam generate rotation --axes yaw,pitch,roll,rpy --speeds 15,30,60 --frames 300 --export data/rotation

Exit status 0; 2 with one line naming the bad value and what is valid, before anything renders (axes or speeds
that are empty, unknown or repeated, ``--frames`` < 2, an ``--export`` folder that cannot be written or a sequence
folder in it that is not empty, without ``--overwrite``); 1 when a sequence cannot be made or exported.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from eval.bench.sequence_ref import SequenceRef, rotation_ref, sim_camera_presets
from eval.errors import EvalError, InputError
from sim_envs.errors import SimEnvError
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
from slamcommon.errors import ProjectError
from slamcommon.output_paths import check_output_folder

KINDS = ("rotation",)


def speeds_option(text: str) -> list[float]:
    """``--speeds``: comma-separated positive, finite, distinct angular speeds in deg/s; :class:`InputError` naming
    the text otherwise."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--speeds {text!r}: expected comma-separated numbers of deg/s, e.g. 15,30,60") from None
    if not values or any(not (np.isfinite(v) and v > 0) for v in values):
        raise InputError(f"--speeds {text!r}: expected positive numbers of deg/s, e.g. 15,30,60")
    if len(set(values)) != len(values):
        raise InputError(f"--speeds {text!r}: a speed is given twice; give each once")
    return values


def axes_option(text: str) -> list[str]:
    """``--axes``: comma-separated, not empty (each checked, and repeats refused, by :func:`rotation_refs`);
    :class:`InputError` naming the text otherwise."""
    axes = [a.strip() for a in text.split(",") if a.strip()]
    if not axes:
        raise InputError(f"--axes {text!r}: no axes; give e.g. yaw,pitch,roll,rpy or yaw+pitch")
    return axes


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = "example: cnnslam generate rotation --axes yaw,rpy --speeds 15,30,60 --frames 300 --export out/"
    parser.add_argument("kind", choices=KINDS, help="what to generate (rotation stress sequences)")
    parser.add_argument("--axes", default="yaw,pitch,roll,rpy",
                        help="comma-separated: yaw, pitch, roll, rpy (all three), or e.g. yaw+pitch "
                             "(default: yaw,pitch,roll,rpy)")  # fmt: skip
    parser.add_argument("--speeds", default="15,30,60",
                        help="angular speeds in deg/s, comma-separated (default: 15,30,60)")  # fmt: skip
    parser.add_argument("--frames", type=int, default=300, help="frames per sequence at 30 Hz (default: 300)")
    parser.add_argument("--export", type=Path, default=None, metavar="DIR",
                        help="render each sequence into DIR/<name>/ as a TUM RGB-D folder")  # fmt: skip
    parser.add_argument("--camera", choices=sim_camera_presets(), default=DEFAULT_CAMERA_EFFECTS,
                        help="what the camera does to the images (sim_envs/sensor/camera_stages.py): kinect "
                             "(default, as "
                             "every suite), clean (the renderer's bytes) or hard; names get its @PRESET suffix as in "
                             "cnnslam bench (none for clean)")  # fmt: skip
    parser.add_argument("--renderer", choices=("mujoco", "pyrender"), default="mujoco", help="renderer backend")
    parser.add_argument("--overwrite", action="store_true", help="export into non-empty folders")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def rotation_refs(axes: list[str], speeds: list[float], frames: int, camera: str = "clean") -> list[SequenceRef]:
    """The sequences of every (axes, speed) pair, ``frames`` long (a registered one keeps its name and content,
    generated at the new length), seen through the camera preset ``camera`` (named ``<name>@<camera>`` unless
    clean, as the suites name them)."""
    if int(frames) < 2:
        raise InputError(f"--frames {frames}: must be >= 2 (frames per sequence at 30 Hz)")
    refs = []
    for axis in axes:
        for speed in speeds:
            try:
                ref = rotation_ref(axis, speed).with_camera_effects(camera)
            except SimEnvError as exc:
                raise InputError(f"--axes {axis!r}: {exc}") from None
            refs.append(replace(ref, overrides={**dict(ref.overrides), "n_frames": frames}))
    names = [ref.name for ref in refs]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise InputError(f"--axes {','.join(axes)} --speeds {','.join(f'{v:g}' for v in speeds)} give "
                         f"{', '.join(repeated)} more than once; name each sequence once")
    return refs


def check_export(folder: Path, refs: list[SequenceRef], overwrite: bool) -> None:
    """Refuse an ``--export`` folder that cannot be written (:func:`~slamcommon.output_paths.check_output_folder`),
    and, unless ``overwrite``, a sequence's folder in it that is a file or not empty: before anything renders."""
    check_output_folder(folder, "--export")
    for ref in refs:
        target = folder / ref.name
        if target.exists() and not target.is_dir():
            raise InputError(f"--export {folder}: {target} is a file; remove it or export elsewhere")
        if target.is_dir() and any(target.iterdir()) and not overwrite:
            raise InputError(f"--export {folder}: {target} exists and is not empty; export elsewhere, or pass "
                             "--overwrite to write into it")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    try:  # bad axes, speeds, frames and export folders: refused before anything renders
        refs = rotation_refs(axes_option(args.axes), speeds_option(args.speeds), args.frames, args.camera)
        if args.export is not None:
            check_export(args.export, refs, args.overwrite)
    except ProjectError as exc:
        print(f"cnnslam generate: error: {exc}", file=sys.stderr)
        return 2
    try:
        print(f"{'sequence':<22} {'axes':<16} {'deg/s':>6} {'frames':>6} {'measured deg/s (median, max)':>30}")
        manifest = []
        for ref in refs:
            source = ref.make_source(args.renderer)
            spec = source.spec
            speeds = source.trajectory.angular_speeds_deg()
            params = spec.params
            print(
                f"{ref.name:<22} {params['axes']:<16} {params['speed_deg_s']:>6g} {len(source):>6d} "
                f"{np.median(speeds):>14.1f}, {speeds.max():>6.1f}"
            )
            entry = {"name": ref.name, "spec": asdict(spec), "intrinsics": asdict(source.intrinsics)}
            if args.export is not None:
                from sim_envs.folders.datasets import export_tum_rgbd

                try:
                    folder = export_tum_rgbd(
                        source, args.export / ref.name, overwrite=args.overwrite, progress=not args.no_progress
                    )
                finally:
                    source.close()
                entry["folder"] = str(folder)
            manifest.append(entry)
        if args.export is not None:
            path = args.export / "sequences.json"
            path.write_text(json.dumps(manifest, indent=2, default=str) + "\n")
            print(f"exported {len(refs)} sequence(s) to {args.export}; specs in {path}")
    except (EvalError, SimEnvError) as exc:
        print(f"cnnslam generate: error: {exc}", file=sys.stderr)
        return 1
    return 0
