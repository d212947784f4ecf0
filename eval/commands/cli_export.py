"""``cnnslam export SEQUENCE FOLDER``: write a registered simulated sequence as a TUM RGB-D folder.

The folder layout (rgb/, depth/ 16-bit x5000, labels/, instances/, rgb.txt, depth.txt, groundtruth.txt and the
``cnnslam.json`` side file with the intrinsics) is described in :mod:`sim_envs.folders.datasets`. The sequence registry
(:mod:`sim_envs.sequences`) and the renderers are imported only when the command runs. The folder is written under a
temporary name and renamed at the end (:func:`sim_envs.folders.datasets.export_tum_rgbd`): Ctrl-C leaves nothing in the
way
of the next export. Exit status: 0 written, 1 the export failed, 2 a bad argument, refused in one line before
anything renders (an unknown sequence, camera, lighting or renderer; ``--frames`` outside 1..the sequence's length; a
file where the folder goes, a folder that cannot be written, a non-empty folder without ``--overwrite``), 130 on
Ctrl-C.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from eval.errors import InputError
from sim_envs.errors import SimEnvError
from sim_envs.folders.datasets import export_tum_rgbd
from sim_envs.sensor.camera_effects import DEFAULT_CAMERA_EFFECTS
from slamcommon.errors import ProjectError
from slamcommon.output_paths import check_output_folder


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("sequence", help="a registered sequence name (see sim_envs.sequences), maybe with the room "
                                         "marks +lit / +rich (office0+rich)")
    parser.add_argument("folder", help="output folder (must not exist or be empty, unless --overwrite)")
    parser.add_argument("--renderer", default="mujoco", help="renderer backend (default: mujoco)")
    parser.add_argument("--frames", type=int, default=None, help="export only the first N frames")
    parser.add_argument("--camera-effects", default=DEFAULT_CAMERA_EFFECTS, metavar="PRESET",
                        help=f"simulated camera (sim_envs.sensor.camera_stages): {DEFAULT_CAMERA_EFFECTS} "
                             "(default, the "
                             "one the suites score), clean (the renderer's images) or hard; a non-clean camera also "
                             "writes its photometric calibration (times.txt, pcalib.txt, vignette.png) and camera "
                             "files")  # fmt: skip
    parser.add_argument("--lighting", default="flat", metavar="LIGHTING",
                        help="flat (default) or lit: the room with lamps, shadows and highlights "
                             "(sim_envs/scenes/lighting.py; mujoco renderer only)")  # fmt: skip
    parser.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def open_sequence(name: str, renderer: str, camera_effects: str = DEFAULT_CAMERA_EFFECTS, lighting: str = "flat",
                  ) -> Any:
    """A registered sequence, maybe with room variant marks (``office0+rich``, ``office0+lit``:
    :func:`sim_envs.sequences.variant_spec`), seen through the ``camera_effects`` preset in its room lit
    ``lighting``, as a frame source (lazy imports: the registry pulls in scenes and renderers)."""
    from dataclasses import replace

    from sim_envs.sequences import variant_spec, with_camera
    from sim_envs.sources.simsource import SimulatedSequence

    spec = variant_spec(name)
    spec = with_camera(spec, camera_effects) if camera_effects != "clean" else spec
    spec = replace(spec, lighting=lighting) if lighting != "flat" else spec
    return SimulatedSequence(spec, renderer=renderer)


def check_folder(folder: Path, overwrite: bool) -> None:
    """Refuse an output ``folder`` the export cannot write: a file there, a folder this user cannot create or write
    (:func:`~slamcommon.output_paths.check_output_folder`), a non-empty folder unless ``overwrite``."""
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder} is a file; an export writes a folder: name a folder that does not exist "
                                  "yet")  # fmt: skip
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise InputError(f"{folder} exists and is not empty; name a new or empty folder, or pass --overwrite "
                                  "to write into it")  # fmt: skip
    check_output_folder(folder, "the output folder")


def check_frames(frames: int | None, source: Any) -> None:
    """Refuse a ``--frames`` outside 1..the length of ``source``."""
    if frames is not None and not 1 <= frames <= len(source):
        raise InputError(f"--frames {frames}: {source.name} has {len(source)} frames; give 1..{len(source)} "
                                  "(or leave it out for all of them)")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    folder = Path(args.folder)
    source = None
    try:  # the folder, the sequence, its camera, lighting and frames: bad arguments are found before anything renders
        if args.frames is not None and args.frames < 1:
            raise InputError(f"--frames {args.frames}: must be >= 1 (or left out for every frame)")
        check_folder(folder, args.overwrite)
        source = open_sequence(args.sequence, args.renderer, args.camera_effects, args.lighting)
        check_frames(args.frames, source)
    except ProjectError as exc:
        if source is not None:
            source.close()
        print(f"cnnslam export: error: {exc}", file=sys.stderr)
        return 2
    try:
        written = export_tum_rgbd(source, folder, overwrite=args.overwrite, progress=not args.no_progress,
                                  max_frames=args.frames)  # fmt: skip
    except SimEnvError as exc:
        print(f"cnnslam export: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"cnnslam export: interrupted; no partial export was left at {folder} (a new folder appears only "
              "when complete)", file=sys.stderr)  # fmt: skip
        return 130
    finally:
        source.close()
    print(f"exported {args.sequence} to {written}")
    return 0
