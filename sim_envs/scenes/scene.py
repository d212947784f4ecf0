"""One renderer-independent description of an indoor scene: primitives, materials, lights.

Conventions: world frame z up (MuJoCo's gravity is -z), metres. A room spans ``[0, Lx] x [0, Ly] x [0, H]``; the
floor's top face is ``z = 0``. Primitives use MuJoCo's half sizes. Every primitive carries a
:class:`~sim_envs.frames.SemanticClass` and an instance id (``0 .. n_instances - 1``; several primitives may share one
instance, e.g. the top and legs of a desk).

Lighting, two models (``Scene.lighting``):

- ``flat`` (every registered sequence; both renderers): matte (Lambertian) surfaces, no specular, no shadows, static
  directional lights plus an ambient term, so a surface point has the same colour from every view (the photometric
  consistency direct SLAM assumes). The colour of a point with unit normal ``n`` is
  ``albedo * (ambient + sum_i intensity_i * max(0, -n . direction_i))`` with ``albedo = material.rgb * texture``, see
  :meth:`Scene.shade`.
- ``lit`` (:mod:`sim_envs.scenes.lighting`; MuJoCo renderer only): the flat model dimmed, plus :class:`Lamp` spot lights
  with distance fall-off and shadow maps (light through the windows, a ceiling lamp), glowing window panes and
  specular highlights on some materials: brightness changes across the room and with the view, as in a real room.

Detail, two levels (``Scene.detail``, :data:`DETAILS`; either lighting, both renderers):

- ``standard`` (every registered sequence): the room as :func:`sim_envs.scenes.scenegen.generate_scene` lays it out.
- ``rich``: the same room (same layout, furniture, objects, lights) with clutter added on every support, on the
  floor along the walls and on the walls (frames, notes, clocks), and every material given texture detail at
  several scales (:func:`sim_envs.scenes.materials.enrich_material`), as cluttered as a lived-in room.

Texture coordinates (:class:`TriMesh`) follow OpenGL: ``v = 0`` is the BOTTOM row of a texture image, and on the side
faces of a box the image appears upright and unmirrored to a viewer outside the face.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from sim_envs.errors import SimEnvError
from sim_envs.frames import SemanticClass

PrimitiveKind = Literal["box", "cylinder", "sphere"]
PRIMITIVE_KINDS: tuple[str, ...] = ("box", "cylinder", "sphere")
CYLINDER_SEGMENTS = 24  # sides of a cylinder's mesh (ours; fine enough at 320x240 for objects of a few cm)
SPHERE_STACKS, SPHERE_SLICES = 10, 20  # latitude / longitude bands of a sphere's mesh (ours)
# Instance kinds (the part of a primitive's name before "/") that are room structure, not worth looking at.
STRUCTURE_KINDS: frozenset[str] = frozenset({"floor", "ceiling", "wall"})


@dataclass(frozen=True, eq=False)
class Material:
    """A matte material.

    name: unique within a scene; rgb: base colour, 3 floats in [0, 1] multiplying the texture (linear, no gamma);
    texture: (h, w, 3) uint8 image or None for a plain colour; tile_m: metres covered by one repeat of the texture
    along each surface axis, or None to stretch the image exactly once over each face (posters, screens);
    specular, shininess, emission: in [0, 1], MuJoCo's material terms (Phong highlight strength, its sharpness, light
    the surface gives off itself); 0 in ``flat`` scenes, set by :mod:`sim_envs.scenes.lighting` in ``lit`` ones.
    """

    name: str
    rgb: tuple[float, float, float] = (0.8, 0.8, 0.8)
    texture: np.ndarray | None = None
    tile_m: float | None = 1.0
    specular: float = 0.0
    shininess: float = 0.0
    emission: float = 0.0

    def __post_init__(self) -> None:
        if len(self.rgb) != 3 or not all(0.0 <= c <= 1.0 for c in self.rgb):
            raise SimEnvError(f"material {self.name!r}: rgb must be 3 values in [0, 1], got {self.rgb}")
        for key in ("specular", "shininess", "emission"):
            if not 0.0 <= float(getattr(self, key)) <= 1.0:
                raise SimEnvError(f"material {self.name!r}: {key} must be in [0, 1], got {getattr(self, key)}")
        if self.texture is not None:
            tex = self.texture
            if tex.dtype != np.uint8 or tex.ndim != 3 or tex.shape[2] != 3 or min(tex.shape[:2]) < 2:
                raise SimEnvError(
                    f"material {self.name!r}: texture must be (h, w, 3) uint8, got {tex.shape} {tex.dtype}"
                )
        if self.tile_m is not None and not self.tile_m > 0:
            raise SimEnvError(f"material {self.name!r}: tile_m must be positive or None, got {self.tile_m}")


@dataclass(frozen=True, eq=False)
class TriMesh:
    """A triangle mesh with per-vertex normals and texture coordinates.

    vertices: (N, 3) float64 metres; normals: (N, 3) float64 unit; uv: (N, 2) float64 texture coordinates (repeat
    outside [0, 1], OpenGL convention v = 0 at the image's bottom row); faces: (M, 3) int32, counter-clockwise seen from
    outside (the normal's side).
    """

    vertices: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    faces: np.ndarray

    def transformed(self, T: np.ndarray) -> TriMesh:
        """The mesh moved by the rigid transform ``T`` (4, 4): points p -> R p + t, normals n -> R n."""
        R, t = T[:3, :3], T[:3, 3]
        return TriMesh(self.vertices @ R.T + t, self.normals @ R.T, self.uv, self.faces)

    @staticmethod
    def concatenate(meshes: list[TriMesh]) -> TriMesh:
        """One mesh holding all of ``meshes`` (face indices renumbered)."""
        offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
        return TriMesh(
            np.concatenate([m.vertices for m in meshes]),
            np.concatenate([m.normals for m in meshes]),
            np.concatenate([m.uv for m in meshes]),
            np.concatenate([m.faces + o for m, o in zip(meshes, offsets, strict=True)]).astype(np.int32),
        )

    def subdivided(self, max_edge: float) -> TriMesh:
        """The same surface with every triangle split in four (at its edge midpoints) until the longest edge is at
        most ``max_edge`` metres; every triangle is split the same number of times, so an edge two triangles share is
        split at the same points in both (no cracks). Normals are interpolated and renormalised, uv interpolated.

        Why: MuJoCo lights per vertex (fixed-function OpenGL), so a spot lamp's fall-off across a 5 m wall is only
        seen at vertices that are close enough together.
        """
        v, n, uv, f = self.vertices, self.normals, self.uv, self.faces
        while len(f):
            edges = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], 1).reshape(-1, 2)  # (3M, 2)
            if np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1).max() <= max_edge:
                break
            key = np.sort(edges, axis=1)
            unique, inverse = np.unique(key, axis=0, return_inverse=True)
            mid = len(v) + inverse.reshape(-1, 3)  # index of the midpoint of each face's edges 01, 12, 20
            normals = n[unique[:, 0]] + n[unique[:, 1]]
            v = np.concatenate([v, (v[unique[:, 0]] + v[unique[:, 1]]) / 2])
            n = np.concatenate([n, normals / np.linalg.norm(normals, axis=1, keepdims=True)])
            uv = np.concatenate([uv, (uv[unique[:, 0]] + uv[unique[:, 1]]) / 2])
            a, b, c, ab, bc, ca = f[:, 0], f[:, 1], f[:, 2], mid[:, 0], mid[:, 1], mid[:, 2]
            f = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        return TriMesh(v, n, uv, f.astype(np.int32))


def _uv_scale(extent: float, tile_m: float | None) -> float:
    """Texture coordinate per metre along a surface axis of length ``extent`` metres."""
    return 1.0 / extent if tile_m is None else 1.0 / tile_m


def box_mesh(half: np.ndarray, tile_m: float | None = 1.0) -> TriMesh:
    """A box centred at the origin with half sizes ``half`` (3,) metres: 6 faces of 4 vertices each (flat normals).

    Side faces: u runs to the right as seen from outside (``z x n``), v upward (+z). Top: u = +x, v = +y; bottom:
    u = +x, v = -y. With ``tile_m`` None each face holds the texture exactly once.
    """
    h = np.asarray(half, dtype=np.float64)
    ex, ey, ez = np.eye(3)
    # (outward normal, u direction, v direction) per face
    frames = [
        (ex, ey, ez), (-ex, -ey, ez), (ey, -ex, ez), (-ey, ex, ez), (ez, ex, ey), (-ez, ex, -ey),
    ]  # fmt: skip
    verts, norms, uvs, faces = [], [], [], []
    for k, (n, u, v) in enumerate(frames):
        centre = n * (h @ np.abs(n))
        hu, hv = h @ np.abs(u), h @ np.abs(v)
        su, sv = _uv_scale(2 * hu, tile_m), _uv_scale(2 * hv, tile_m)
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):  # counter-clockwise seen from outside: u x v = n
            verts.append(centre + a * hu * u + b * hv * v)
            norms.append(n)
            uvs.append(((a + 1) * hu * su, (b + 1) * hv * sv))
        faces += [(4 * k, 4 * k + 1, 4 * k + 2), (4 * k, 4 * k + 2, 4 * k + 3)]
    return TriMesh(np.array(verts), np.array(norms), np.array(uvs), np.array(faces, dtype=np.int32))


def cylinder_mesh(radius: float, half_height: float, tile_m: float | None = 1.0,
                  segments: int = CYLINDER_SEGMENTS) -> TriMesh:  # fmt: skip
    """A closed cylinder along z centred at the origin: smooth side (seam duplicated for u) and two flat caps."""
    theta = np.linspace(0.0, 2 * np.pi, segments + 1)
    c, s = np.cos(theta), np.sin(theta)
    su, sv = _uv_scale(2 * np.pi * radius, tile_m), _uv_scale(2 * half_height, tile_m)
    n_ring = segments + 1
    side_v = np.concatenate(
        [np.stack([radius * c, radius * s, np.full_like(c, z)], 1) for z in (-half_height, half_height)]
    )
    side_n = np.concatenate([np.stack([c, s, np.zeros_like(c)], 1)] * 2)
    side_uv = np.concatenate(
        [np.stack([theta * radius * su, np.full_like(c, z)], 1) for z in (0.0, 2 * half_height * sv)]
    )
    i = np.arange(segments)
    side_f = np.concatenate([np.stack([i, i + 1, i + 1 + n_ring], 1), np.stack([i, i + 1 + n_ring, i + n_ring], 1)])
    parts = [TriMesh(side_v, side_n, side_uv, side_f.astype(np.int32))]
    cu = _uv_scale(2 * radius, tile_m)
    for sign in (-1.0, 1.0):
        ring = np.stack([radius * c[:-1], radius * s[:-1], np.full(segments, sign * half_height)], 1)
        v = np.concatenate([[[0.0, 0.0, sign * half_height]], ring])
        n = np.tile([0.0, 0.0, sign], (segments + 1, 1))
        uv = (v[:, :2] + radius) * cu
        j = np.arange(segments)
        f = np.stack([np.zeros(segments, int), 1 + j, 1 + (j + 1) % segments], 1)
        if sign < 0:
            f = f[:, [0, 2, 1]]
        parts.append(TriMesh(v, n, uv, f.astype(np.int32)))
    return TriMesh.concatenate(parts)


def sphere_mesh(radius: float, tile_m: float | None = 1.0, stacks: int = SPHERE_STACKS,
                slices: int = SPHERE_SLICES) -> TriMesh:  # fmt: skip
    """A UV sphere centred at the origin (smooth normals; u along longitude, v along latitude)."""
    phi = np.linspace(0.0, np.pi, stacks + 1)  # from the south pole (-z) to the north pole
    theta = np.linspace(0.0, 2 * np.pi, slices + 1)
    P, T = np.meshgrid(phi, theta, indexing="ij")
    n = np.stack([np.sin(P) * np.cos(T), np.sin(P) * np.sin(T), -np.cos(P)], -1).reshape(-1, 3)
    su, sv = _uv_scale(2 * np.pi * radius, tile_m), _uv_scale(np.pi * radius, tile_m)
    uv = np.stack([T * radius * su, P * radius * sv], -1).reshape(-1, 2)
    i, j = np.meshgrid(np.arange(stacks), np.arange(slices), indexing="ij")
    a = (i * (slices + 1) + j).ravel()
    b, c, d = a + 1, a + slices + 1, a + slices + 2
    faces = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    v = n * radius  # the degenerate triangles at the poles are dropped below
    area = np.linalg.norm(np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]]), axis=1)
    return TriMesh(v, n, uv, faces[area > 1e-12].astype(np.int32))


@dataclass(frozen=True, eq=False)
class Primitive:
    """One solid shape of the scene.

    kind: "box" | "cylinder" | "sphere"; size: MuJoCo half sizes in metres, box (hx, hy, hz), cylinder (radius,
    half height, 0) along the object's z, sphere (radius, 0, 0); T_world_obj: (4, 4) float64 object-to-world;
    material: how it looks; semantic: its class; instance: the object it belongs to; name: ``"<kind>_<n>/<part>"``
    (e.g. ``"desk_2/leg_0"``), the kind before "/" naming what the instance is.
    """

    kind: PrimitiveKind
    size: tuple[float, float, float]
    T_world_obj: np.ndarray
    material: Material
    semantic: SemanticClass
    instance: int
    name: str

    def __post_init__(self) -> None:
        if self.kind not in PRIMITIVE_KINDS:
            raise SimEnvError(f"primitive {self.name!r}: kind must be one of {PRIMITIVE_KINDS}, got {self.kind!r}")
        needed = {"box": 3, "cylinder": 2, "sphere": 1}[self.kind]
        if len(self.size) != 3 or not all(s > 0 for s in self.size[:needed]):
            raise SimEnvError(
                f"primitive {self.name!r}: {self.kind} needs {needed} positive half sizes, got {self.size}"
            )
        if np.shape(self.T_world_obj) != (4, 4):
            raise SimEnvError(f"primitive {self.name!r}: T_world_obj must be (4, 4)")

    @property
    def instance_kind(self) -> str:
        """What the instance is (``"desk"``, ``"wall"``, ``"book"``...): the name before "/" without its ``_<n>``."""
        return self.name.split("/", 1)[0].rsplit("_", 1)[0]

    def local_mesh(self) -> TriMesh:
        """The triangle mesh in the object frame."""
        tile = self.material.tile_m
        if self.kind == "box":
            return box_mesh(np.array(self.size), tile)
        if self.kind == "cylinder":
            return cylinder_mesh(self.size[0], self.size[1], tile)
        return sphere_mesh(self.size[0], tile)

    def mesh(self) -> TriMesh:
        """The triangle mesh in the world frame."""
        return self.local_mesh().transformed(np.asarray(self.T_world_obj, dtype=np.float64))

    def local_corners(self) -> np.ndarray:
        """(8, 3) corners of the object-frame bounding box of the shape (metres)."""
        if self.kind == "box":
            h = np.array(self.size)
        elif self.kind == "cylinder":
            h = np.array([self.size[0], self.size[0], self.size[1]])
        else:
            h = np.full(3, self.size[0])
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
        return signs * h

    def aabb(self) -> np.ndarray:
        """(2, 3) world-axis-aligned bounds [min, max] in metres (exact for boxes, tight for upright cylinders)."""
        T = np.asarray(self.T_world_obj)
        if self.kind == "sphere":
            r = self.size[0]
            return np.stack([T[:3, 3] - r, T[:3, 3] + r])
        if self.kind == "cylinder":
            # exact extent of a disc of radius r with axis a: r * sqrt(1 - a_i^2) per world axis
            r, hh = self.size[0], self.size[1]
            axis = T[:3, 2]
            ext = np.abs(axis) * hh + r * np.sqrt(np.clip(1.0 - axis**2, 0.0, None))
            return np.stack([T[:3, 3] - ext, T[:3, 3] + ext])
        p = self.local_corners() @ T[:3, :3].T + T[:3, 3]
        return np.stack([p.min(0), p.max(0)])


@dataclass(frozen=True)
class Light:
    """A static directional light.

    direction: (3,) unit vector along which the light travels (world frame); intensity: diffuse gain in [0, 1].
    """

    direction: tuple[float, float, float]
    intensity: float


LIGHTINGS: tuple[str, ...] = ("flat", "lit")
DETAILS: tuple[str, ...] = ("standard", "rich")  # room detail levels (module docstring)


@dataclass(frozen=True)
class Lamp:
    """A static spot light in the room (``lit`` scenes; rendered by the MuJoCo backend).

    position: (3,) world metres; direction: (3,) unit vector of the cone's axis; cutoff_deg: the cone's half angle;
    exponent: how fast light falls off from the axis to the cone's edge (MuJoCo's spot exponent); intensity: diffuse
    gain (grey); attenuation: ``(c, l, q)``, the light is divided by ``c + l d + q d^2`` at distance ``d`` metres;
    shadows: the lamp casts shadows (a shadow map per lamp and frame: the cost of ``lit``).
    """

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    cutoff_deg: float
    exponent: float
    intensity: float
    attenuation: tuple[float, float, float] = (1.0, 0.0, 0.0)
    shadows: bool = True

    def __post_init__(self) -> None:
        if not 0.0 < self.cutoff_deg < 90.0:
            raise SimEnvError(f"lamp cutoff_deg must be in (0, 90), got {self.cutoff_deg}")
        if not self.intensity >= 0.0 or min(self.attenuation) < 0.0 or sum(self.attenuation) <= 0.0:
            raise SimEnvError(
                f"lamp intensity must be >= 0 and attenuation (c, l, q) >= 0 with a positive sum, got "
                f"{self.intensity}, {self.attenuation}"
            )
        if abs(float(np.linalg.norm(self.direction)) - 1.0) > 1e-6:
            raise SimEnvError(f"lamp direction must be a unit vector, got {self.direction}")


@dataclass(frozen=True, eq=False)
class Scene:
    """A generated room.

    style: room style name; seed: generator seed; room_size: (3,) float64 (Lx, Ly, H) metres, the room's interior
    spans ``[0, Lx] x [0, Ly] x [0, H]``; primitives: every shape; lights: static directional lights; ambient:
    ambient gain (``ambient + sum of intensities <= 1`` so colours never clip); texture_density: what the generator
    was asked for, in [0, 1]; lighting: ``flat`` or ``lit`` (module docstring); lamps: the spot lights of a ``lit``
    scene; detail: ``standard`` or ``rich`` (module docstring, :data:`DETAILS`).
    """

    style: str
    seed: int
    room_size: np.ndarray
    primitives: tuple[Primitive, ...]
    lights: tuple[Light, ...] = ()
    ambient: float = 0.4
    texture_density: float = 1.0
    lighting: str = "flat"
    lamps: tuple[Lamp, ...] = ()
    detail: str = "standard"
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)  # derived arrays (bounds)

    def __post_init__(self) -> None:
        if self.lighting not in LIGHTINGS:
            raise SimEnvError(f"scene lighting must be one of {', '.join(LIGHTINGS)}, got {self.lighting!r}")
        if self.detail not in DETAILS:
            raise SimEnvError(f"scene detail must be one of {', '.join(DETAILS)}, got {self.detail!r}")
        glossy = any(p.material.specular or p.material.emission for p in self.primitives)
        if self.lighting == "flat" and (self.lamps or glossy):
            raise SimEnvError("a flat scene has no lamps, specular or emissive materials (make it lighting='lit')")
        ids = sorted({p.instance for p in self.primitives})
        if ids != list(range(len(ids))):
            raise SimEnvError(f"scene instance ids must be 0..n-1 without gaps, got {ids[:10]}...")
        classes: dict[int, SemanticClass] = {}
        for p in self.primitives:
            if classes.setdefault(p.instance, p.semantic) != p.semantic:
                raise SimEnvError(f"instance {p.instance} ({p.name}) mixes semantic classes")

    @property
    def n_instances(self) -> int:
        """Number of instances (ids are 0 .. n_instances - 1)."""
        return 1 + max(p.instance for p in self.primitives)

    def instance_classes(self) -> np.ndarray:
        """(n_instances,) uint8: the :class:`SemanticClass` of each instance id."""
        out = np.zeros(self.n_instances, dtype=np.uint8)
        for p in self.primitives:
            out[p.instance] = int(p.semantic)
        return out

    def instance_names(self) -> list[str]:
        """Name of each instance id (the part of its primitives' names before "/")."""
        out = [""] * self.n_instances
        for p in self.primitives:
            out[p.instance] = p.name.split("/", 1)[0]
        return out

    def instance_aabbs(self) -> np.ndarray:
        """(n_instances, 2, 3) float64 world-axis-aligned [min, max] bounds of each instance (metres)."""
        if "instance_aabbs" not in self._cache:
            out = np.empty((self.n_instances, 2, 3))
            out[:, 0], out[:, 1] = np.inf, -np.inf
            for p in self.primitives:
                box = p.aabb()
                out[p.instance, 0] = np.minimum(out[p.instance, 0], box[0])
                out[p.instance, 1] = np.maximum(out[p.instance, 1], box[1])
            self._cache["instance_aabbs"] = out
        return self._cache["instance_aabbs"]

    def bounds(self) -> np.ndarray:
        """(2, 3) float64 [min, max] corners of everything in the scene, walls included (metres)."""
        boxes = self.instance_aabbs()
        return np.stack([boxes[:, 0].min(0), boxes[:, 1].max(0)])

    def interest_points(self) -> np.ndarray:
        """(N, 3) float64 world points worth looking at: tops of furniture, centres of objects, posters, doors, windows.

        One point per instance that is not floor, wall or ceiling: the top centre of a furniture instance's bounds, the
        centre of the bounds otherwise. Sorted by instance id.
        """
        classes = self.instance_classes()
        names = self.instance_names()
        boxes = self.instance_aabbs()
        points = []
        for i, (name, cls) in enumerate(zip(names, classes, strict=True)):
            if name.rsplit("_", 1)[0] in STRUCTURE_KINDS:
                continue
            centre = boxes[i].mean(0)
            if cls == SemanticClass.LARGE_STRUCTURE:
                centre[2] = boxes[i, 1, 2]
            points.append(centre)
        return np.array(points, dtype=np.float64).reshape(-1, 3)

    def free_space(self, points: np.ndarray, margin: float = 0.3) -> np.ndarray:
        """Which points are free for a camera: (N, 3) metres -> (N,) bool.

        True where a point is inside the room at least ``margin`` metres from the walls, floor and ceiling, and at
        least ``margin`` (per axis) outside the axis-aligned bounds of every furniture and object instance.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        size = np.asarray(self.room_size, dtype=np.float64)
        free = np.all((pts >= margin) & (pts <= size - margin), axis=1)
        classes = self.instance_classes()
        boxes = self.instance_aabbs()[
            (classes == SemanticClass.LARGE_STRUCTURE) | (classes == SemanticClass.SMALL_STRUCTURE)
        ]
        if len(boxes):
            lo, hi = boxes[:, 0] - margin, boxes[:, 1] + margin  # (M, 3)
            inside = np.all((pts[:, None] > lo[None]) & (pts[:, None] < hi[None]), axis=2)  # (N, M)
            free &= ~inside.any(1)
        return free

    def shade(self, normals: np.ndarray) -> np.ndarray:
        """Lighting gain of surfaces with unit world ``normals`` (N, 3): (N,) float64 in [0, 1], the ``flat`` model's
        (module docstring; a ``lit`` scene's lamps, shadows and highlights are the renderer's)."""
        gain = np.full(len(normals), float(self.ambient))
        for light in self.lights:
            gain += light.intensity * np.clip(-(normals @ np.asarray(light.direction)), 0.0, None)
        return np.clip(gain, 0.0, 1.0)

    def materials(self) -> list[Material]:
        """The distinct materials (by identity) in order of first use."""
        seen: dict[int, Material] = {}
        for p in self.primitives:
            seen.setdefault(id(p.material), p.material)
        return list(seen.values())
