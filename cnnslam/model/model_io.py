"""Export of the global model (:class:`cnnslam.model.global_model.SurfelCloud`) as a PLY point cloud, and a reader for
it.

Format: binary little-endian PLY 1.0, one ``vertex`` element per surfel with the property names Open3D, MeshLab,
CloudCompare and trimesh recognise, plus two extras that they carry along or ignore::

    property float x, y, z          position, metres, world frame of the SLAM run (its first camera)
    property float nx, ny, nz       unit normal
    property uchar red, green, blue colour
    property uchar label            semantic class (0 floor, 1 vertical structure, 2 large structure / furniture,
                                    3 small structure; 255 = none), the argmax of the fused label distribution
    property float confidence       Keller's confidence c = sum of the radial weights of the fused measurements

Comments in the header record the class names and anything the caller passes (sequence, agent, ...).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cnnslam.errors import CnnSlamError
from cnnslam.model.global_model import SurfelCloud

CLASS_NAMES: tuple[str, ...] = ("floor", "vertical_structure", "large_structure", "small_structure")
VERTEX_DTYPE = np.dtype([
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
    ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
    ("red", "u1"), ("green", "u1"), ("blue", "u1"),
    ("label", "u1"), ("confidence", "<f4"),
])
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2", "int16": "<i2",
              "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
              "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8"}
_NUMPY_TO_PLY = {"<f4": "float", "|u1": "uchar", "<f8": "double", "<i4": "int", "<u4": "uint"}


class PlyFormatError(CnnSlamError):
    """A PLY file this reader does not understand (not binary little-endian, no vertex element, list properties)."""


def write_ply(path: str | os.PathLike[str], cloud: SurfelCloud, comments: list[str] | None = None) -> Path:
    """Write ``cloud`` as a binary little-endian PLY (module docstring); returns the path. Written to a temporary
    file first and renamed, so an interrupted write leaves no half-written file."""
    path = Path(path)
    n = len(cloud)
    vertices = np.empty(n, dtype=VERTEX_DTYPE)
    for k, name in enumerate(("x", "y", "z")):
        vertices[name] = cloud.positions[:, k]
    for k, name in enumerate(("nx", "ny", "nz")):
        vertices[name] = cloud.normals[:, k]
    for k, name in enumerate(("red", "green", "blue")):
        vertices[name] = cloud.colours[:, k]
    vertices["label"] = cloud.labels
    vertices["confidence"] = cloud.confidence
    lines = ["ply", "format binary_little_endian 1.0", "comment written by cnnslam.model.model_io",
             "comment label: " + ", ".join(f"{i} {name}" for i, name in enumerate(CLASS_NAMES)) + ", 255 none"]
    for c in comments or []:
        lines.append("comment " + " ".join(str(c).split()))
    lines.append(f"element vertex {n}")
    for name in VERTEX_DTYPE.names:
        lines.append(f"property {_NUMPY_TO_PLY[VERTEX_DTYPE[name].str]} {name}")
    lines.append("end_header")
    header = ("\n".join(lines) + "\n").encode("ascii")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "wb") as fh:
        fh.write(header)
        fh.write(vertices.tobytes())
    os.replace(tmp, path)
    return path


def read_ply(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], list[str]]:
    """Read the vertex element of a binary little-endian PLY: ({property name: (N,) array}, header comments).

    Enough for the files :func:`write_ply` writes and for other point clouds with scalar vertex properties.
    """
    path = Path(path)
    with open(path, "rb") as fh:
        if fh.readline().strip() != b"ply":
            raise PlyFormatError(f"{path}: not a PLY file (no 'ply' magic line)")
        comments: list[str] = []
        elements: list[tuple[str, int, list[tuple[str, str]]]] = []
        while True:
            raw = fh.readline()
            if not raw:
                raise PlyFormatError(f"{path}: the header has no end_header line")
            words = raw.decode("ascii", errors="replace").split()
            if not words:
                continue
            if words[0] == "end_header":
                break
            if words[0] == "format" and words[1:2] != ["binary_little_endian"]:
                raise PlyFormatError(f"{path}: format {' '.join(words[1:])} is not supported (binary_little_endian)")
            if words[0] == "comment":
                comments.append(" ".join(words[1:]))
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property":
                if not elements:
                    raise PlyFormatError(f"{path}: a property before any element")
                if words[1] == "list":
                    raise PlyFormatError(f"{path}: list property {words[-1]!r} is not supported")
                if words[1] not in _PLY_TYPES:
                    raise PlyFormatError(f"{path}: unknown property type {words[1]!r}")
                elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
        offset = fh.tell()
    for name, count, props in elements:
        dtype = np.dtype(props)
        if name == "vertex":
            data = np.fromfile(path, dtype=dtype, count=count, offset=offset)
            if data.shape[0] != count:
                raise PlyFormatError(f"{path}: expected {count} vertices, found {data.shape[0]}")
            return {p: data[p].copy() for p, _ in props}, comments
        offset += count * dtype.itemsize
    raise PlyFormatError(f"{path}: no vertex element")
