"""COLMAP's incremental structure from motion (through pycolmap), shared by the judge and the agents.

Two users: the SfM reference of real folders (:mod:`eval.metrics.sfm_reference`, ``cnnslam reference``: self-calibrated
camera, a second reference beside a folder's ground truth) and COLMAP as a benchmark method
(:mod:`thirdparty.colmap_sfm`: the offline baseline of a monocular SLAM benchmark, with the camera given). Both run
the same pipeline, :func:`reconstruct`, and read poses with :func:`model_poses`. pycolmap is optional (the ``sfm``
extra); without it :func:`reconstruct` raises :class:`SfmError` saying how to install it.

Conventions: images are given in sequence order and numbered by that order inside COLMAP (``000123.png``), so a
registered image's name gives its index; poses are ``T_world_cam`` camera-to-world, OpenCV camera axes (COLMAP's
camera frame is OpenCV's: x right, y down, z forward), in COLMAP's world frame and units (no metric scale).
COLMAP's pixel centres are at +0.5 (:data:`COLMAP_PIXEL_OFFSET`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from slamcommon.errors import MetricError

# COLMAP camera models this pipeline accepts: a pinhole (for a camera held fixed) and those with a single radial
# polynomial OpenCV can use (k1, k2 in OpenCV's meaning)
CAMERA_MODELS: tuple[str, ...] = ("PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")
DEFAULT_CAMERA_MODEL = "RADIAL"
DEFAULT_OVERLAP = 10  # sequential matching: each image against its next 10
COLMAP_PIXEL_OFFSET = 0.5  # COLMAP's pixel centres are at +0.5 (image corner at 0), OpenCV's at integers


class SfmError(MetricError):
    """Structure from motion could not run or registered nothing (pycolmap missing, too few images, ...)."""


class SfmUnavailableError(SfmError):
    """COLMAP itself cannot run here (pycolmap missing or failing to import): a caller that turns a reconstruction
    that registered nothing into a result must not do so for this."""


def _pycolmap() -> Any:
    try:
        import pycolmap
    except ImportError as exc:  # an optional dependency (the sfm extra)
        raise SfmUnavailableError("structure from motion needs pycolmap: pip install 'cnnslam[sfm]' (or "
                                  "pycolmap>=3.12)") from exc
    return pycolmap


def reconstruct(
    image_paths: Sequence[str | Path],
    workdir: str | Path,
    *,
    camera_model: str = DEFAULT_CAMERA_MODEL,
    overlap: int = DEFAULT_OVERLAP,
    threads: int = 2,
    seed: int = 0,
    fixed_camera: Sequence[float] | None = None,
    verbose: bool = False,
    on_stage: Callable[[str], None] | None = None,
    on_image: Callable[[], None] | None = None,
) -> Any:
    """COLMAP's incremental SfM on ``image_paths`` (in sequence order), one shared camera of ``camera_model`` whose
    focal length and distortion are refined; SIFT features, sequential matching over ``overlap`` neighbours.

    Writes ``workdir/images`` (links to the images), ``workdir/database.db`` and ``workdir/sparse``. Returns the
    model (a ``pycolmap.Reconstruction``) with the most registered images. ``fixed_camera``: COLMAP parameters of
    ``camera_model`` (COLMAP's pixel convention) to hold fixed instead of self-calibrating. ``on_stage`` is called
    with each stage's name as it finishes, ``on_image`` each time the mapper registers an image (for a progress
    bar).
    """
    pycolmap = _pycolmap()
    if camera_model not in CAMERA_MODELS:
        raise SfmError(f"camera model {camera_model!r}: valid {', '.join(CAMERA_MODELS)}")
    paths = [Path(p).resolve() for p in image_paths]
    if len(paths) < 3:
        raise SfmError(f"structure from motion needs at least 3 images, got {len(paths)}")
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise SfmError(f"{len(missing)} image(s) not found, first: {missing[0]}")
    work = Path(workdir)
    images = work / "images"
    images.mkdir(parents=True, exist_ok=True)
    for i, p in enumerate(paths):  # numbered links: COLMAP sorts by name, and names must be unique
        link = images / f"{i:06d}{p.suffix.lower()}"
        if link.is_symlink() or link.exists():
            link.unlink()
        os.symlink(p, link)
    database = work / "database.db"
    if database.exists():
        database.unlink()
    pycolmap.logging.minloglevel = 0 if verbose else 2
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = camera_model
    if fixed_camera is not None:
        reader.camera_params = ",".join(repr(float(v)) for v in fixed_camera)
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = threads
    pycolmap.extract_features(
        database, images, camera_mode=pycolmap.CameraMode.SINGLE, reader_options=reader,
        extraction_options=extraction, device=pycolmap.Device.cpu,
    )  # fmt: skip
    if on_stage:
        on_stage("features")
    pairing = pycolmap.SequentialPairingOptions()
    pairing.overlap = overlap
    pycolmap.match_sequential(database, pairing_options=pairing, device=pycolmap.Device.cpu)
    if on_stage:
        on_stage("matches")
    options = pycolmap.IncrementalPipelineOptions()
    options.num_threads = threads
    options.random_seed = seed
    if fixed_camera is not None:
        options.ba_refine_focal_length = False
        options.ba_refine_extra_params = False
    models = pycolmap.incremental_mapping(
        database, images, work / "sparse", options=options, next_image_callback=on_image
    )
    if on_stage:
        on_stage("mapping")
    if not models:
        raise SfmError(f"COLMAP registered no model from {len(paths)} images (too little texture or overlap?)")
    return max(models.values(), key=lambda r: r.num_reg_images())


def model_poses(model: Any) -> list[tuple[int, np.ndarray]]:
    """The registered images of a :func:`reconstruct` model as ``(index, T_world_cam)`` pairs sorted by index:
    the image's position in the list given to :func:`reconstruct`, and its camera-to-world pose (4, 4) float64,
    OpenCV camera axes, COLMAP's world frame and units."""
    rows = []
    for image in model.images.values():
        pose = image.cam_from_world() if callable(image.cam_from_world) else image.cam_from_world
        T_cam_world = np.eye(4)
        T_cam_world[:3] = pose.matrix()
        rows.append((int(Path(image.name).stem), np.linalg.inv(T_cam_world)))
    return sorted(rows, key=lambda r: r[0])
