"""Seedable procedural rooms: ``generate_scene(style, seed)`` -> :class:`~sim_envs.scenes.scene.Scene`.

Test styles ``office`` and ``living`` (like ICL-NUIM's office and living room); training-only styles ``bedroom``,
``kitchen``, ``classroom`` and ``study`` share the same generators (rooms, openings, furniture, objects, textures), so
a network trained on them sees the same kind of world laid out differently.

A room: floor, four walls, ceiling (closed: a window is a textured pane, so every pixel hits a surface), 1-2 doors,
windows, posters or a whiteboard; furniture from :mod:`sim_envs.scenes.furniture` placed without overlaps, mostly
against
walls (front to the room), some free-standing with chairs around; small objects placed on furniture tops, shelves and
the floor, then dropped and settled with MuJoCo physics (:mod:`sim_envs.scenes.physics`) so they rest plausibly.

Determinism: one ``numpy.random.Generator`` for the layout and one for textures, both seeded from ``(seed, style)``;
nothing is cached between calls. The texture generator draws the same numbers whatever ``texture_density``, so the
same seed at another density gives the same room with fewer and fainter textures.

Detail (``detail``, :data:`sim_envs.scenes.scene.DETAILS`): a ``rich`` room is the ``standard`` room of the same
arguments
(the same draws, so the same layout, furniture, objects and lights) with more: clutter on every support
(:data:`RICH_OBJECTS_ON`: papers, books, mugs, tins, cartons, pen holders, plants as clusters of leaves), on the floor
along the walls and on the walls (frames, pinboards, clocks, calendars, switches), dropped and settled by physics
with the rest, then every material given texture detail (:func:`sim_envs.scenes.materials.enrich_material`). The rich
additions draw from their own generators, seeded from ``(seed, style, RICH_STREAM)``. The standard room's
trajectories stay valid in it: clutter stands on furniture or within half a metre of a wall, at most
:data:`RICH_FLOOR_MAX_HEIGHT` m high on the floor, and wall decorations stand out at most 5 cm.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.frames import SemanticClass
from sim_envs.scenes import furniture as fur
from sim_envs.scenes.materials import RICH_WALL_STRENGTH, MaterialBank, enrich_material
from sim_envs.scenes.physics import FreeBody, settle_bodies
from sim_envs.scenes.room_layout import (
    CLEARANCE as CLEARANCE,  # re-exported: the floor plan is sim_envs.scenes.room_layout
)
from sim_envs.scenes.room_layout import Drop, Layout, Opening, Placed, Rect
from sim_envs.scenes.room_layout import inward as _inward
from sim_envs.scenes.room_layout import wall_frame as _wall_frame
from sim_envs.scenes.room_layout import yaw_facing as _yaw_facing
from sim_envs.scenes.room_layout import yaw_pose as _T
from sim_envs.scenes.room_styles import (
    MAX_OBJECTS_PER_SUPPORT,
    OBJECTS_ON,
    RICH_CLUTTER,
    RICH_FLOOR_MAX_HEIGHT,
    RICH_FLOOR_OBJECTS,
    RICH_FLOOR_TABLE,
    RICH_MAX_PER_SEAT,
    RICH_MAX_PER_SUPPORT,
    RICH_OBJECTS_ON,
    RICH_STREAM,
    RICH_TRIES,
    RICH_WALL_ITEMS,
    RICH_WALL_TABLE,
    ROOM_STYLES,
    SHELF_OBJECTS,
    STYLES,
    TUMBLE_PROBABILITY,
    TUMBLING,
    Style,
)
from sim_envs.scenes.room_styles import (
    TEST_STYLES as TEST_STYLES,  # re-exported: the styles' data is sim_envs.scenes.room_styles
)
from sim_envs.scenes.room_styles import TRAIN_STYLES as TRAIN_STYLES
from sim_envs.scenes.room_styles import Item as Item
from sim_envs.scenes.scene import DETAILS, LIGHTINGS, Light, Material, Primitive, Scene

WALL_THICKNESS = 0.1  # metres (ours)
DROP_HEIGHT = 0.004  # metres above its support an object starts falling from (ours)
VERT, FLOOR = SemanticClass.VERTICAL_STRUCTURE, SemanticClass.FLOOR




class _Builder:
    """Builds one scene; holds the generators, the material bank, the layout and the primitives made so far."""

    def __init__(self, style: Style, seed: int, texture_density: float) -> None:
        key = zlib.crc32(style.name.encode())
        layout_seq, texture_seq = np.random.SeedSequence([int(seed), key]).spawn(2)
        self.rng = np.random.default_rng(layout_seq)
        self.bank = MaterialBank(np.random.default_rng(texture_seq), texture_density)
        self.style = style
        self.size = np.array(
            [self.rng.uniform(*style.size_xy), self.rng.uniform(*style.size_xy), self.rng.uniform(*style.height)]
        )
        self.layout = Layout(self.size)
        self.primitives: list[Primitive] = []
        self.counts: dict[str, int] = {}
        self.n_instances = 0
        self.openings: list[Opening] = []
        self.placed: list[Placed] = []
        self.wall_items: list[tuple[int, float, float, float]] = []  # (wall, s0, s1, top height) of furniture
        self.occupancy: dict[int, list[Rect]] = {}  # id(support) -> footprints of the objects set on it
        self.opening_zones: list[Rect] = []  # kept clear in front of doors, and above the height of window sills

    # ------------------------------------------------------------------------------------------------ primitives
    def _instance(self, kind: str) -> tuple[int, str]:
        """A new instance id and its name ``<kind>_<n>`` (n counts instances of that kind)."""
        n = self.counts.get(kind, 0)
        self.counts[kind] = n + 1
        self.n_instances += 1
        return self.n_instances - 1, f"{kind}_{n}"

    def add_box(self, kind: str, parts: list[tuple[str, np.ndarray, tuple[float, float, float], Material]],
                semantic: SemanticClass) -> None:  # fmt: skip
        """One new instance made of boxes ``(part name, T_world_obj, half sizes, material)``."""
        inst, name = self._instance(kind)
        for part, T, half, mat in parts:
            self.primitives.append(Primitive("box", half, T, mat, semantic, inst, f"{name}/{part}"))

    def add_assembly(self, a: fur.Assembly, T_world: np.ndarray) -> None:
        """One new instance holding the parts of ``a`` placed at ``T_world``."""
        inst, name = self._instance(a.kind)
        for part in a.parts:
            self.primitives.append(
                Primitive(
                    part.kind, part.size, T_world @ part.T, part.material, a.semantic, inst, f"{name}/{part.name}"
                )
            )

    # ------------------------------------------------------------------------------------------------ structure
    def structure(self) -> None:
        """Floor, ceiling, walls."""
        Lx, Ly, H = self.size
        t = WALL_THICKNESS
        floor = self.bank.shared(self.rng.choice(self.style.floors))
        wall = self.bank.shared(self.rng.choice(self.style.walls))
        self.add_box("floor", [("slab", _T(Lx / 2, Ly / 2, -t / 2, 0), (Lx / 2 + t, Ly / 2 + t, t / 2), floor)], FLOOR)
        ceiling = self.bank.shared("ceiling")
        self.add_box(
            "ceiling", [("slab", _T(Lx / 2, Ly / 2, H + t / 2, 0), (Lx / 2 + t, Ly / 2 + t, t / 2), ceiling)], VERT
        )
        for w in range(4):
            origin, tangent, length = _wall_frame(w, self.size)
            centre = origin + tangent * length / 2 - _inward(tangent) * t / 2
            yaw = float(np.arctan2(tangent[1], tangent[0]))
            self.add_box("wall", [("slab", _T(*centre, H / 2, yaw), (length / 2 + t, t / 2, H / 2), wall)], VERT)

    def openings_(self) -> None:
        """Doors and windows on the walls, apart from each other and from the corners; keep their zones clear."""
        H = self.size[2]
        wants = ["door"] * int(self.rng.integers(self.style.doors[0], self.style.doors[1] + 1))
        wants += ["window"] * int(self.rng.integers(self.style.windows[0], self.style.windows[1] + 1))
        for kind in wants:
            for _ in range(30):
                w = int(self.rng.integers(4))
                _, _, length = _wall_frame(w, self.size)
                width = self.rng.uniform(0.8, 0.95) if kind == "door" else self.rng.uniform(0.8, min(1.8, length / 2.5))
                if length < width + 0.8:
                    continue
                s = self.rng.uniform(0.4 + width / 2, length - 0.4 - width / 2)
                if kind == "door":
                    z0, z1 = 0.0, self.rng.uniform(2.0, min(2.15, H - 0.2))
                else:
                    z0 = self.rng.uniform(0.8, 1.0)
                    z1 = min(H - 0.25, z0 + self.rng.uniform(1.0, 1.5))
                if any(o.wall == w and abs(o.s - s) < (o.width + width) / 2 + 0.3 for o in self.openings):
                    continue
                self.openings.append(Opening(kind, w, s, width, z0, z1))
                break
        for o in self.openings:
            origin, tangent, _ = _wall_frame(o.wall, self.size)
            n = _inward(tangent)
            depth = 0.9 if o.kind == "door" else 0.75
            c = origin + tangent * o.s + n * depth / 2
            yaw = float(np.arctan2(tangent[1], tangent[0]))
            grow = 0.15 if o.kind == "door" else 0.0
            # a door's swing zone is blocked at every height; a window only above its sill
            z0 = 0.0 if o.kind == "door" else o.z0 - 0.08  # below the sill
            zone = Rect(c[0], c[1], yaw, o.width / 2 + grow, depth / 2, z0, np.inf)
            self.layout.rects.append(zone)
            self.opening_zones.append(zone)
            self._opening_primitives(o)

    def _opening_primitives(self, o: Opening) -> None:
        """The primitives of a door (leaf, jambs, lintel) or a window (textured pane, sill) as one instance."""
        origin, tangent, _ = _wall_frame(o.wall, self.size)
        n = _inward(tangent)
        yaw = float(np.arctan2(tangent[1], tangent[0]))
        c = origin + tangent * o.s
        h = o.z1 - o.z0
        parts: list[tuple[str, np.ndarray, tuple[float, float, float], Material]] = []
        if o.kind == "door":
            leaf = self.bank.unique("door")
            frame = self.bank.shared("door_frame")
            p = c + n * 0.02
            parts.append(("leaf", _T(*p, h / 2, yaw), (o.width / 2, 0.02, h / 2), leaf))
            for k, sgn in enumerate((-1, 1)):
                q = c + tangent * sgn * (o.width / 2 + 0.04) + n * 0.015
                parts.append((f"jamb_{k}", _T(*q, (h + 0.06) / 2, yaw), (0.04, 0.015, (h + 0.06) / 2), frame))
            q = c + n * 0.015
            parts.append(("lintel", _T(*q, h + 0.03, yaw), (o.width / 2 + 0.08, 0.015, 0.03), frame))
        else:
            pane = self.bank.unique("window")
            p = c + n * 0.01
            parts.append(("pane", _T(*p, o.z0 + h / 2, yaw), (o.width / 2, 0.01, h / 2), pane))
            q = c + n * 0.06
            parts.append(("sill", _T(*q, o.z0 - 0.02, yaw), (o.width / 2 + 0.06, 0.06, 0.02), self.bank.shared("sill")))
        self.add_box(o.kind, parts, VERT)

    # ------------------------------------------------------------------------------------------------ furniture
    def place(self, a: fur.Assembly, rect: Rect, wall: int | None = None, s: float = 0.0) -> None:
        """Put ``a`` at ``rect`` (its footprint joins the layout); ``wall``, ``s``: where it stands against a wall."""
        T = _T(rect.cx, rect.cy, 0.0, rect.yaw)
        self.layout.rects.append(rect)
        self.placed.append(Placed(a, T, rect))
        self.add_assembly(a, T)
        if wall is not None:
            self.wall_items.append((wall, s - a.half[0], s + a.half[0], a.height))

    def try_wall(self, a: fur.Assembly, tries: int = 40) -> tuple[Rect, int, float] | None:
        """A free spot against a wall for ``a`` (its back to the wall), or None."""
        hx, hy = a.half
        for _ in range(tries):
            w = int(self.rng.integers(4))
            origin, tangent, length = _wall_frame(w, self.size)
            if length < 2 * hx + 0.1:
                continue
            s = self.rng.uniform(hx + 0.02, length - hx - 0.02)
            n = _inward(tangent)
            c = origin + tangent * s + n * (hy + 0.01)
            rect = Rect(c[0], c[1], _yaw_facing(n), hx, hy, 0.0, a.height)
            if self.layout.fits([rect]):
                return rect, w, s
        return None

    def try_free(self, a: fur.Assembly, extra: list[fur.Assembly], arrange: Callable[[Rect], list[Rect]],
                 tries: int = 40) -> bool:  # fmt: skip
        """Place ``a`` free-standing with companions ``extra`` arranged by ``arrange(rect) -> [Rect]``."""
        hx, hy = a.half
        for _ in range(tries):
            yaw = float(self.rng.integers(4)) * np.pi / 2 + self.rng.uniform(-0.12, 0.12)
            cx = self.rng.uniform(0.6 + hx, self.size[0] - 0.6 - hx) if self.size[0] > 1.2 + 2 * hx else None
            cy = self.rng.uniform(0.6 + hy, self.size[1] - 0.6 - hy) if self.size[1] > 1.2 + 2 * hy else None
            if cx is None or cy is None:
                return False
            rect = Rect(cx, cy, yaw, hx, hy, 0.0, a.height)
            others = arrange(rect)
            if self.layout.fits([rect, *others]):
                self.place(a, rect)
                for b, r in zip(extra, others, strict=True):
                    self.place(b, r)
                return True
        return False

    def furniture(self) -> None:
        """Every item of the style: pieces against walls first (in the style's order), then free-standing groups."""
        items = sorted(self.style.items, key=lambda it: it.place != "wall")
        for item in items:
            n = int(self.rng.integers(item.count[0], item.count[1] + 1))
            if item.group == "rows":
                self.rows(n)
                continue
            for _ in range(n):
                a = fur.FURNITURE[item.builder](self.rng, self.bank)
                if item.place == "wall":
                    spot = self.try_wall(a)
                    if spot is None:
                        continue
                    rect, w, s = spot
                    companions = self.companions(a, rect, item.group)
                    if not self.layout.fits([rect] + [r for _, r in companions]):
                        companions = []
                    self.place(a, rect, w, s)
                    for b, r in companions:
                        self.place(b, r)
                else:
                    extra = self.companion_assemblies(a, item.group)
                    self.try_free(a, extra, lambda r, a=a, extra=extra, g=item.group: self.arrange(a, r, extra, g))

    def companion_assemblies(self, a: fur.Assembly, group: str) -> list[fur.Assembly]:
        """The furniture that goes with ``a`` in ``group``: a chair, 2+ chairs for a table, a coffee table."""
        if group == "chair":
            return [fur.FURNITURE["chair"](self.rng, self.bank)]
        if group == "chairs":
            long_side = 2 * a.half[0]
            per_side = max(1, int(long_side // 0.7))
            n = int(self.rng.integers(2, 2 * per_side + 1))
            return [fur.FURNITURE["chair"](self.rng, self.bank) for _ in range(n)]
        if group == "coffee":
            return [fur.FURNITURE["coffee_table"](self.rng, self.bank)]
        return []

    def arrange(self, a: fur.Assembly, rect: Rect, extra: list[fur.Assembly], group: str) -> list[Rect]:
        """Footprints of companions around ``a`` placed at ``rect``: a chair in front, chairs on both long sides."""
        c, s = np.cos(rect.yaw), np.sin(rect.yaw)
        ex, ey = np.array([c, s]), np.array([-s, c])  # the assembly's local x and y axes in the world
        centre = np.array([rect.cx, rect.cy])
        out = []
        if group == "chair":
            b = extra[0]
            p = centre + ey * (a.half[1] + b.half[1] + 2 * CLEARANCE)
            out.append(Rect(p[0], p[1], rect.yaw + np.pi, b.half[0], b.half[1], 0.0, b.height))
        elif group == "chairs":
            n = len(extra)
            sides = [1, -1] * n
            per = {1: (n + 1) // 2, -1: n // 2}
            idx = {1: 0, -1: 0}
            for b, side in zip(extra, sides, strict=False):
                k = idx[side]
                idx[side] += 1
                x = (k + 0.5) / per[side] * 2 * a.half[0] - a.half[0]
                p = centre + ex * x + ey * side * (a.half[1] + b.half[1] + 2 * CLEARANCE)
                out.append(
                    Rect(p[0], p[1], rect.yaw + (np.pi if side > 0 else 0.0), b.half[0], b.half[1], 0.0, b.height)
                )
        elif group == "coffee":
            b = extra[0]
            p = centre + ey * (a.half[1] + 0.4 + b.half[1])
            out.append(Rect(p[0], p[1], rect.yaw, b.half[0], b.half[1], 0.0, b.height))
        return out

    def companions(self, a: fur.Assembly, rect: Rect, group: str) -> list[tuple[fur.Assembly, Rect]]:
        """Companions of ``a`` placed at ``rect`` with their footprints."""
        extra = self.companion_assemblies(a, group)
        return list(zip(extra, self.arrange(a, rect, extra, group), strict=True))

    def rows(self, n: int) -> None:
        """A classroom: a grid of pupils' desks, each with a chair behind it, all facing wall 0 (y = 0)."""
        Lx, Ly = self.size[0], self.size[1]
        proto = fur.FURNITURE["small_desk"](self.rng, self.bank)
        cols = max(1, int((Lx - 1.6) // (2 * proto.half[0] + 0.5)))
        nrows = max(1, min(int(np.ceil(n / cols)), int((Ly - 2.4) // 1.3)))
        x0 = (Lx - cols * (2 * proto.half[0] + 0.5)) / 2 + proto.half[0] + 0.25
        for r in range(nrows):
            for k in range(cols):
                desk = proto if r == 0 and k == 0 else fur.FURNITURE["small_desk"](self.rng, self.bank)
                chair = fur.FURNITURE["chair"](self.rng, self.bank)
                cx = x0 + k * (2 * proto.half[0] + 0.5)
                cy = 2.0 + r * 1.3
                # desks face wall 0: their users sit on the +y side, looking towards -y
                rect = Rect(cx, cy, np.pi, desk.half[0], desk.half[1], 0.0, desk.height)
                crect = Rect(
                    cx,
                    cy + desk.half[1] + chair.half[1] + 2 * CLEARANCE,
                    np.pi,
                    chair.half[0],
                    chair.half[1],
                    0.0,
                    chair.height,
                )
                if self.layout.fits([rect, crect]):
                    self.place(desk, rect)
                    self.place(chair, crect)

    # ------------------------------------------------------------------------------------------------ wall decoration
    def _free_on_wall(self, wall: int, s0: float, s1: float, z0: float) -> bool:
        """Whether the stretch [s0, s1] of ``wall`` above height ``z0`` is clear of openings and furniture."""
        for o in self.openings:
            if o.wall == wall and s1 > o.s - o.width / 2 - 0.15 and s0 < o.s + o.width / 2 + 0.15:
                return False
        for w, a0, a1, top in self.wall_items:
            if w == wall and s1 > a0 - 0.05 and s0 < a1 + 0.05 and top > z0 - 0.05:
                return False
        return True

    def decorations(self) -> None:
        """Posters (and a whiteboard) hung on free wall space."""
        wants = ["whiteboard"] if self.style.whiteboard else []
        wants += ["poster"] * int(self.rng.integers(self.style.posters[0], self.style.posters[1] + 1))
        H = self.size[2]
        for kind in wants:
            for _ in range(40):
                if kind == "whiteboard":
                    w = self.rng.uniform(1.4, 2.2)
                    h, z0 = w / 2, self.rng.uniform(0.85, 1.0)
                    wall = 0 if self.style.name == "classroom" else int(self.rng.integers(4))
                else:
                    w = self.rng.uniform(0.35, 0.75)
                    h, z0 = w * 4 / 3, self.rng.uniform(1.1, 1.45)
                    wall = int(self.rng.integers(4))
                if z0 + h > H - 0.15:
                    continue
                origin, tangent, length = _wall_frame(wall, self.size)
                if length < w + 0.4:
                    continue
                s = self.rng.uniform(0.2 + w / 2, length - 0.2 - w / 2)
                if not self._free_on_wall(wall, s - w / 2, s + w / 2, z0):
                    continue
                self.wall_items.append((wall, s - w / 2, s + w / 2, H))
                n = _inward(tangent)
                yaw = float(np.arctan2(tangent[1], tangent[0]))
                p = origin + tangent * s + n * 0.008
                mat = self.bank.unique(kind)
                self.add_box(kind, [("board", _T(*p, z0 + h / 2, yaw), (w / 2, 0.008, h / 2), mat)],
                             SemanticClass.SMALL_STRUCTURE)  # fmt: skip
                break

    def rug(self) -> None:
        """A thin rug (floor class) near the middle of the room; furniture may stand on it."""
        if self.rng.random() >= self.style.rug:
            return
        Lx, Ly = self.size[0], self.size[1]
        hx, hy = self.rng.uniform(0.7, min(1.5, Lx / 2 - 0.6)), self.rng.uniform(0.6, min(1.2, Ly / 2 - 0.6))
        cx = self.rng.uniform(0.5 + hx, Lx - 0.5 - hx)
        cy = self.rng.uniform(0.5 + hy, Ly - 0.5 - hy)
        self.add_box("rug", [("mat", _T(cx, cy, 0.004, 0.0), (hx, hy, 0.004), self.bank.unique("rug"))], FLOOR)

    # ------------------------------------------------------------------------------------------------ small objects
    def _choose(self, table: tuple[tuple[str, float], ...]) -> str:
        """A name drawn from ``(name, weight)`` pairs."""
        names = [n for n, _ in table]
        w = np.array([w for _, w in table], dtype=float)
        return names[int(self.rng.choice(len(names), p=w / w.sum()))]

    def objects(self) -> list[Drop]:
        """Small objects with their initial world poses, a few millimetres above their supports (``Drop.lift``)."""
        out: list[Drop] = []
        for placed in self.placed:
            kind = placed.assembly.kind
            for sup in placed.assembly.supports:
                occupied = self.occupancy.setdefault(id(sup), [])
                if sup.kind == "shelf":
                    out += self._shelf(placed, sup, occupied)
                    continue
                if kind == "desk" and self.style.name in ("office", "study") and self.rng.random() < 0.8:
                    out += self._workstation(placed, sup, occupied)
                if kind == "tv_stand":
                    out += self._place_at(
                        placed, sup, fur.OBJECTS["tv"](self.rng, self.bank), (0.0, -sup.half[1] * 0.3), 0.0, occupied
                    )
                table = OBJECTS_ON.get(kind)
                if table is None:
                    continue
                area = 4 * sup.half[0] * sup.half[1]
                n = min(MAX_OBJECTS_PER_SUPPORT, int(self.rng.poisson(self.style.clutter * area)))
                if sup.kind == "seat":
                    n = min(n, 2)
                for _ in range(n):
                    name = self._choose(table)
                    if name == "book" and self.rng.random() < 0.4:
                        out += self._pile(placed, sup, occupied)
                        continue
                    a = fur.OBJECTS[name](self.rng, self.bank)
                    out += self._random_spot(placed, sup, a, occupied)
        out += self._floor_objects()
        return out

    def _fits_support(self, sup: fur.Support, r: Rect, height: float, occupied: list[Rect]) -> bool:
        """Whether footprint ``r`` (support frame) lies on ``sup``, fits under its headroom and clears ``occupied``."""
        c = r.corners()
        lo = np.array(sup.centre) - sup.half
        hi = np.array(sup.centre) + sup.half
        return bool((c >= lo).all() and (c <= hi).all() and height < sup.headroom - 0.02
                    and not any(r.overlaps(o, 0.01) for o in occupied))  # fmt: skip

    def _place_at(self, placed: Placed, sup: fur.Support, a: fur.Assembly, xy: tuple[float, float], yaw: float,
                  occupied: list[Rect], lift: float = DROP_HEIGHT) -> list[Drop]:  # fmt: skip
        """``a`` set at ``xy`` with ``yaw`` on ``sup`` of ``placed`` if it fits (else nothing), ``lift`` m above it."""
        r = Rect(xy[0], xy[1], yaw, a.half[0], a.half[1])
        if not self._fits_support(sup, r, a.height, occupied):
            return []
        # in world coordinates, clear of window sills with room to spare for a tossed object
        T = placed.T_world @ _T(xy[0], xy[1], sup.z, yaw)
        world = Rect(
            T[0, 3], T[1, 3], float(np.arctan2(T[1, 0], T[0, 0])), a.half[0], a.half[1], sup.z, sup.z + a.height + 0.2
        )
        if any(world.overlaps(z, 0.02) for z in self.opening_zones):
            return []
        occupied.append(r)
        return [Drop(a, placed.T_world @ _T(xy[0], xy[1], sup.z + lift, yaw), lift)]

    def _random_spot(self, placed: Placed, sup: fur.Support, a: fur.Assembly, occupied: list[Rect],
                     tries: int = 12) -> list[Drop]:  # fmt: skip
        """``a`` at a random free spot of ``sup`` (some objects tossed with a tilt), or nothing after ``tries``."""
        for _ in range(tries):
            xy = (
                sup.centre[0] + self.rng.uniform(-1, 1) * sup.half[0],
                sup.centre[1] + self.rng.uniform(-1, 1) * sup.half[1],
            )
            got = self._place_at(placed, sup, a, xy, float(self.rng.uniform(-np.pi, np.pi)), occupied)
            if got:
                # some objects are tossed rather than set down: they tumble and settle in varied poses
                lift, tilt = self.rng.uniform(0.03, 0.15), tuple(self.rng.uniform(-0.8, 0.8, 2))
                if a.kind in TUMBLING and self.rng.random() < TUMBLE_PROBABILITY:
                    d = got[0]
                    got = [Drop(a, d.T_world @ _T(0.0, 0.0, lift, 0.0), d.lift + lift, tilt)]
                return got
        return []

    def _pile(self, placed: Placed, sup: fur.Support, occupied: list[Rect]) -> list[Drop]:
        """2-4 books dropped on top of each other (physics settles the pile)."""
        books = [fur.OBJECTS["book"](self.rng, self.bank) for _ in range(int(self.rng.integers(2, 5)))]
        base = max(books, key=lambda b: b.half[0] * b.half[1])
        got = self._random_spot(placed, sup, base, occupied)
        if not got:
            return []
        T0, lift = got[0].T_world, got[0].lift
        z = base.height
        for b in books:
            if b is base:
                continue
            lift += 0.004
            T = T0 @ _T(*self.rng.uniform(-0.015, 0.015, 2), z + 0.004, float(self.rng.uniform(-0.3, 0.3)))
            got.append(Drop(b, T, lift))
            z += b.height + 0.004
        return got

    def _workstation(self, placed: Placed, sup: fur.Support,
                     occupied: list[Rect]) -> list[Drop]:  # fmt: skip
        """A monitor at the back of a desk facing its user, a keyboard in front of it."""
        m = fur.OBJECTS["monitor"](self.rng, self.bank)
        x = self.rng.uniform(-0.3, 0.3) * sup.half[0]
        out = self._place_at(placed, sup, m, (x, sup.centre[1] - sup.half[1] + m.half[1] + 0.02), 0.0, occupied)
        if out:
            k = fur.OBJECTS["keyboard"](self.rng, self.bank)
            out += self._place_at(placed, sup, k, (x, sup.centre[1] + sup.half[1] * 0.35), 0.0, occupied)
        return out

    def _shelf(self, placed: Placed, sup: fur.Support, occupied: list[Rect]) -> list[Drop]:
        """A row of upright books (spines to the front) and a few other objects along one shelf board; their
        footprints join ``occupied``."""
        out: list[Drop] = []
        x = sup.centre[0] - sup.half[0] + self.rng.uniform(0.0, 0.15)
        end = sup.centre[0] + sup.half[0]
        while x < end:
            if self.rng.random() < 0.75:
                a = fur.OBJECTS["standing_book"](self.rng, self.bank)
            else:
                a = fur.OBJECTS[self._choose(SHELF_OBJECTS)](self.rng, self.bank)
            w = a.half[0]
            y = sup.centre[1] - sup.half[1] + a.half[1] + 0.005
            got = self._place_at(placed, sup, a, (x + w, y), 0.0, occupied, lift=0.002)
            out += got
            x += 2 * w + (0.003 if got else 0.0) + (self.rng.uniform(0.1, 0.3) if self.rng.random() < 0.15 else 0.0)
        return out

    def _floor_objects(self, count: tuple[int, int] | None = None,
                       table: tuple[tuple[str, float], ...] | None = None) -> list[Drop]:  # fmt: skip
        """Objects standing on the floor along the walls: ``count`` (min, max; default the style's) drawn from
        ``table`` (default plants, bins, boxes)."""
        out = []
        count = count or self.style.floor_objects
        for _ in range(int(self.rng.integers(count[0], count[1] + 1))):
            a = fur.OBJECTS[self._choose(table or OBJECTS_ON["floor"])](self.rng, self.bank)
            for _ in range(30):
                # near a wall or a corner, where such things stand
                w = int(self.rng.integers(4))
                origin, tangent, length = _wall_frame(w, self.size)
                s = self.rng.uniform(a.half[0] + 0.05, length - a.half[0] - 0.05)
                c = origin + tangent * s + _inward(tangent) * (a.half[1] + 0.05)
                yaw = _yaw_facing(_inward(tangent))
                rect = Rect(c[0], c[1], yaw, a.half[0], a.half[1], 0.0, a.height)
                if self.layout.fits([rect]):
                    self.layout.rects.append(rect)
                    out.append(Drop(a, _T(c[0], c[1], DROP_HEIGHT, yaw), DROP_HEIGHT))
                    break
        return out

    # ------------------------------------------------------------------------------------------------ rich rooms
    def rich(self, rng: np.random.Generator, bank: MaterialBank) -> list[Drop]:
        """The rich pass (module docstring): wall decorations (added now, static) and the clutter to drop. From here
        on the builder draws from ``rng`` and makes materials with ``bank`` (the rich pass's own streams)."""
        self.rng, self.bank = rng, bank
        self._rich_walls()
        out: list[Drop] = []
        for placed in self.placed:
            for sup in placed.assembly.supports:
                occupied = self.occupancy.setdefault(id(sup), [])
                area = 4 * sup.half[0] * sup.half[1]
                n = min(RICH_MAX_PER_SUPPORT, int(self.rng.poisson(RICH_CLUTTER * area)))
                if sup.kind == "seat":
                    n = min(n, RICH_MAX_PER_SEAT)
                for _ in range(n):
                    name = self._choose(RICH_OBJECTS_ON[sup.kind])
                    if name == "book" and sup.kind != "shelf" and self.rng.random() < 0.4:
                        out += self._pile(placed, sup, occupied)
                        continue
                    a = fur.OBJECTS[name](self.rng, self.bank)
                    out += self._random_spot(placed, sup, a, occupied, RICH_TRIES)
        floor = self._floor_objects(RICH_FLOOR_OBJECTS, RICH_FLOOR_TABLE)
        return out + [d for d in floor if d.assembly.height <= RICH_FLOOR_MAX_HEIGHT]

    def _rich_walls(self) -> None:
        """Frames, pinboards, clocks, calendars and switches on free wall space (as :meth:`decorations`)."""
        H = self.size[2]
        for _ in range(int(self.rng.integers(RICH_WALL_ITEMS[0], RICH_WALL_ITEMS[1] + 1))):
            a = fur.WALL_DECORATIONS[self._choose(RICH_WALL_TABLE)](self.rng, self.bank)
            w = 2 * a.half[0]
            for _ in range(40):
                z0 = self.rng.uniform(1.0, 1.25) if a.kind == "switch" else self.rng.uniform(0.8, H - 0.15 - a.height)
                wall = int(self.rng.integers(4))
                origin, tangent, length = _wall_frame(wall, self.size)
                if z0 + a.height > H - 0.15 or length < w + 0.4:
                    continue
                s = self.rng.uniform(0.2 + w / 2, length - 0.2 - w / 2)
                if not self._free_on_wall(wall, s - w / 2, s + w / 2, z0):
                    continue
                # blocks the wall up to its top: a later decoration may hang above it (a gallery), not below
                self.wall_items.append((wall, s - w / 2, s + w / 2, z0 + a.height))
                p = origin + tangent * s
                self.add_assembly(a, _T(p[0], p[1], z0, _yaw_facing(_inward(tangent))))
                break

    def lights(self) -> tuple[tuple[Light, ...], float]:
        """Two static directional lights (one from above, one from a side) and an ambient term summing to <= 0.95."""
        ambient = float(self.rng.uniform(0.45, 0.55))
        d1 = np.array([*self.rng.uniform(-0.5, 0.5, 2), -1.0])
        phi = self.rng.uniform(0, 2 * np.pi)
        d2 = np.array([np.cos(phi), np.sin(phi), -self.rng.uniform(0.2, 0.5)])
        i1 = float(self.rng.uniform(0.2, 0.3))
        i2 = float(max(0.05, 0.95 - ambient - i1))
        lights = tuple(Light(tuple(float(v) for v in d / np.linalg.norm(d)), i) for d, i in ((d1, i1), (d2, i2)))
        return lights, ambient


def generate_scene(
    style: str, seed: int, texture_density: float = 1.0, settle: bool = True, lighting: str = "flat",
    detail: str = "standard",
) -> Scene:
    """A furnished room of ``style`` from ``seed``: the same arguments always give the same scene (bit for bit).

    style: one of :data:`ROOM_STYLES`; seed: any non-negative int; texture_density in [0, 1]: how many surfaces are
    textured and how strongly (0 = nearly textureless); settle: drop the small objects with MuJoCo physics until they
    rest (False: they are placed exactly on their supports, which is faster but allows no piles to topple);
    lighting: ``flat`` (the same colour from every view) or ``lit`` (the same room relit by
    :func:`sim_envs.scenes.lighting.light_room`: lamps with shadows, bright windows, highlights; MuJoCo renderer only);
    detail: ``standard`` or ``rich`` (the same room with clutter and texture detail: module docstring).
    """
    if lighting not in LIGHTINGS:
        raise SimEnvError(f"lighting must be one of {', '.join(LIGHTINGS)}, got {lighting!r}")
    if detail not in DETAILS:
        raise SimEnvError(f"detail must be one of {', '.join(DETAILS)}, got {detail!r}")
    if style not in STYLES:
        raise UnknownNameError(f"unknown room style {style!r}; valid styles: {', '.join(ROOM_STYLES)}")
    if not 0.0 <= float(texture_density) <= 1.0:
        raise SimEnvError(f"texture_density must be in [0, 1], got {texture_density}")
    if int(seed) < 0:
        raise SimEnvError(f"seed must be a non-negative integer, got {seed}")
    b = _Builder(STYLES[style], int(seed), float(texture_density))
    b.structure()
    b.openings_()
    b.furniture()
    b.decorations()
    b.rug()
    drops = b.objects()
    lights, ambient = b.lights()  # the last draws of the layout generator: a rich pass draws from its own
    if detail == "rich":
        key = zlib.crc32(STYLES[style].name.encode())
        layout_seq, texture_seq, detail_seq = np.random.SeedSequence([int(seed), key, RICH_STREAM]).spawn(3)
        drops += b.rich(np.random.default_rng(layout_seq), MaterialBank(np.random.default_rng(texture_seq),
                                                                        float(texture_density)))
    if settle and drops:
        bodies = [FreeBody([(p.kind, p.size, p.T) for p in d.assembly.parts], d.start_pose()) for d in drops]
        result = settle_bodies(list(b.primitives), bodies)
        keep = np.flatnonzero(result.valid)
        if len(keep) < len(drops):  # objects resting on a removed one fall again
            again = [FreeBody(bodies[i].parts, result.T_world_body[i]) for i in keep]
            second = settle_bodies(list(b.primitives), again, max_time=1.0)
            keep, poses = keep[second.valid], second.T_world_body[second.valid]
        else:
            poses = result.T_world_body
        placed = [(drops[i].assembly, T) for i, T in zip(keep, poses, strict=True)]
    else:  # without physics, objects are put down exactly on their supports (upright, so lowering them is enough)
        placed = [(d.assembly, _T(0.0, 0.0, -d.lift, 0.0) @ d.T_world) for d in drops]
    for a, T in placed:
        b.add_assembly(a, T)
    scene = Scene(style, int(seed), b.size, tuple(b.primitives), lights, ambient, float(texture_density),
                  detail=detail)  # fmt: skip
    if detail == "rich":  # texture detail on every material, drawn in order of first use; plaster stays plainer
        rng = np.random.default_rng(detail_seq)
        users: dict[int, set[str]] = {}
        for p in scene.primitives:
            users.setdefault(id(p.material), set()).add(p.instance_kind)
        rich = {id(m): enrich_material(m, rng, float(texture_density),
                                       RICH_WALL_STRENGTH if users[id(m)] <= {"wall", "ceiling"} else 1.0)
                for m in scene.materials()}  # fmt: skip
        scene = replace(scene, primitives=tuple(replace(p, material=rich[id(p.material)]) for p in scene.primitives))
    if lighting == "lit":
        from sim_envs.scenes.lighting import light_room

        scene = light_room(scene)
    return scene

