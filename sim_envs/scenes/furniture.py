"""Furniture and small objects built from primitives, in their own frames, ready to be placed in a room.

Every builder takes a ``numpy.random.Generator`` (sizes and variants) and a
:class:`~sim_envs.scenes.materials.MaterialBank`
and returns an :class:`Assembly`. Local frame: origin at the centre of the footprint on the floor (or, for small
objects, at the centre of the bottom), z up, the FRONT facing +y (a desk's user sits on its +y side, a shelf opens
towards +y, a monitor's screen faces +y); the back is at -y, the side placed against a wall.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from sim_envs.frames import SemanticClass
from sim_envs.scenes.materials import MaterialBank
from sim_envs.scenes.scene import Material


def pose(t: tuple[float, float, float] | np.ndarray, rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 4) float64 transform: rotation from roll-pitch-yaw (radians, extrinsic x-y-z) then translation ``t``."""
    T = np.eye(4)
    if any(rpy):
        T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:3, 3] = t
    return T


@dataclass
class Part:
    """A primitive in its assembly's frame. kind/size as :class:`~sim_envs.scenes.scene.Primitive`; T: (4, 4) local
    pose."""

    kind: str
    size: tuple[float, float, float]
    T: np.ndarray
    material: Material
    name: str


@dataclass
class Support:
    """A horizontal rectangle on which objects can rest: centre (x, y), half sizes (hx, hy), height z (local, m)."""

    centre: tuple[float, float]
    half: tuple[float, float]
    z: float
    kind: str = "top"  # "top" (desks, tables, counters), "shelf" (between boards: limited headroom), "seat"
    headroom: float = 1.0  # metres free above the surface


@dataclass
class Assembly:
    """A piece of furniture or a small object: parts in its frame, footprint half sizes (hx, hy), height, supports."""

    kind: str
    parts: list[Part]
    half: tuple[float, float]
    height: float
    semantic: SemanticClass
    supports: list[Support] = field(default_factory=list)

    def add_box(self, name: str, centre: tuple[float, float, float], half: tuple[float, float, float],
                material: Material, rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:  # fmt: skip
        """Add a box with half sizes ``half`` centred at ``centre`` (local metres)."""
        self.parts.append(Part("box", tuple(float(h) for h in half), pose(centre, rpy), material, name))

    def add_cylinder(self, name: str, centre: tuple[float, float, float], radius: float, half_height: float,
                     material: Material, rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:  # fmt: skip
        """Add a cylinder (axis along local z unless rotated by ``rpy``)."""
        self.parts.append(Part("cylinder", (float(radius), float(half_height), 0.0), pose(centre, rpy), material, name))

    def add_sphere(self, name: str, centre: tuple[float, float, float], radius: float, material: Material) -> None:
        """Add a sphere."""
        self.parts.append(Part("sphere", (float(radius), 0.0, 0.0), pose(centre), material, name))


Builder = Callable[[np.random.Generator, MaterialBank], Assembly]
LARGE, SMALL = SemanticClass.LARGE_STRUCTURE, SemanticClass.SMALL_STRUCTURE


def _solid_box(kind: str, hx: float, hy: float, hz: float, material: Material) -> Assembly:
    """A small object that is one box ("body") of half sizes (hx, hy, hz) (m) standing on its bottom."""
    a = Assembly(kind, [], (hx, hy), 2 * hz, SMALL)
    a.add_box("body", (0, 0, hz), (hx, hy, hz), material)
    return a


def _solid_cylinder(kind: str, r: float, h: float, material: Material) -> Assembly:
    """A small object that is one upright cylinder ("body") of radius ``r`` and height ``h`` (m) standing on its
    bottom."""
    a = Assembly(kind, [], (r, r), h, SMALL)
    a.add_cylinder("body", (0, 0, h / 2), r, h / 2, material)
    return a


def _variant(base: Callable[..., Assembly], name: str, doc: str, **options: object) -> Builder:
    """The builder ``base(rng, bank, **options)`` under its own name and docstring (a variant of a piece)."""

    def build(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
        return base(rng, bank, **options)

    build.__name__ = build.__qualname__ = name
    build.__doc__ = doc
    return build


# ---------------------------------------------------------------------------------------------------------- furniture
def _legs(a: Assembly, hx: float, hy: float, height: float, t: float, mat: Material, inset: float = 0.03) -> None:
    """Four square legs of half thickness ``t`` under a top whose underside is at ``height``."""
    for i, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
        a.add_box(f"leg_{i}", (sx * (hx - inset - t), sy * (hy - inset - t), height / 2), (t, t, height / 2), mat)


def desk(rng: np.random.Generator, bank: MaterialBank, small: bool = False) -> Assembly:
    """A desk: top, legs or side panels, sometimes a drawer pedestal and a modesty panel."""
    w = rng.uniform(0.6, 0.75) if small else rng.uniform(1.2, 1.7)
    d = rng.uniform(0.45, 0.55) if small else rng.uniform(0.65, 0.8)
    h = rng.uniform(0.72, 0.76)
    hx, hy, th = w / 2, d / 2, 0.015
    top = bank.shared("wood" if rng.random() < 0.6 else "laminate")
    frame = bank.shared("metal") if rng.random() < 0.5 else top
    a = Assembly("desk", [], (hx, hy), h, LARGE)
    a.add_box("top", (0, 0, h - th), (hx, hy, th), top)
    if small or rng.random() < 0.5:
        _legs(a, hx, hy, h - 2 * th, 0.02, frame)
    else:
        for i, sx in enumerate((-1, 1)):
            a.add_box(f"side_{i}", (sx * (hx - 0.02), 0, (h - 2 * th) / 2), (0.015, hy - 0.02, (h - 2 * th) / 2), frame)
        a.add_box("modesty", (0, -hy + 0.05, h * 0.6), (hx - 0.04, 0.01, h * 0.25), frame)
    if not small and rng.random() < 0.6:
        side = rng.choice([-1, 1])
        a.add_box(
            "drawers",
            (side * (hx - 0.25), 0.0, (h - 2 * th) / 2 - 0.01),
            (0.2, hy - 0.06, (h - 2 * th) / 2 - 0.02),
            top,
        )
    a.supports.append(Support((0, 0), (hx - 0.04, hy - 0.04), h))
    return a



def table(rng: np.random.Generator, bank: MaterialBank, coffee: bool = False) -> Assembly:
    """A dining table (rectangular on legs, or round on a pedestal) or a low coffee table."""
    h = rng.uniform(0.38, 0.46) if coffee else rng.uniform(0.72, 0.77)
    mat = bank.shared("wood" if rng.random() < 0.7 else "laminate")
    th = 0.02
    if not coffee and rng.random() < 0.3:
        r = rng.uniform(0.45, 0.6)
        a = Assembly("table", [], (r, r), h, LARGE)
        a.add_cylinder("top", (0, 0, h - th), r, th, mat)
        a.add_cylinder("pedestal", (0, 0, (h - 2 * th) / 2), 0.05, (h - 2 * th) / 2, bank.shared("metal"))
        a.add_cylinder("base", (0, 0, 0.015), r * 0.55, 0.015, bank.shared("metal"))
        a.supports.append(Support((0, 0), (r * 0.65, r * 0.65), h))
        return a
    w = rng.uniform(0.9, 1.3) if coffee else rng.uniform(1.2, 1.8)
    d = rng.uniform(0.5, 0.7) if coffee else rng.uniform(0.75, 0.95)
    a = Assembly("coffee_table" if coffee else "table", [], (w / 2, d / 2), h, LARGE)
    a.add_box("top", (0, 0, h - th), (w / 2, d / 2, th), mat)
    _legs(a, w / 2, d / 2, h - 2 * th, 0.025, mat)
    if coffee and rng.random() < 0.5:
        a.add_box("shelf", (0, 0, 0.1), (w / 2 - 0.06, d / 2 - 0.06, 0.01), mat)
    a.supports.append(Support((0, 0), (w / 2 - 0.05, d / 2 - 0.05), h))
    return a



def chair(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A chair facing +y (its backrest at -y): four legs, or an office chair on a column and a star-like base."""
    seat_h = rng.uniform(0.43, 0.48)
    s = rng.uniform(0.21, 0.25)
    if rng.random() < 0.4:  # office chair
        fab = bank.shared("fabric")
        a = Assembly("chair", [], (0.3, 0.3), seat_h + 0.5, LARGE)
        a.add_cylinder("base", (0, 0, 0.03), 0.3, 0.03, bank.shared("dark"))
        a.add_cylinder("column", (0, 0, (seat_h - 0.06) / 2 + 0.03), 0.025, (seat_h - 0.06) / 2, bank.shared("metal"))
        a.add_box("seat", (0, 0, seat_h - 0.04), (s, s, 0.04), fab)
        a.add_box("back", (0, -s + 0.03, seat_h + 0.3), (s * 0.9, 0.03, 0.22), fab, rpy=(-0.1, 0, 0))
        return a
    mat = bank.shared("wood")
    a = Assembly("chair", [], (s, s), seat_h + 0.45, LARGE)
    a.add_box("seat", (0, 0, seat_h - 0.02), (s, s, 0.02), bank.shared("cushion") if rng.random() < 0.5 else mat)
    _legs(a, s, s, seat_h - 0.04, 0.018, mat, inset=0.0)
    a.add_box("back", (0, -s + 0.018, seat_h + 0.25), (s, 0.018, 0.2), mat)
    for i, sx in enumerate((-1, 1)):
        a.add_box(f"post_{i}", (sx * (s - 0.018), -s + 0.018, seat_h + 0.02), (0.018, 0.018, 0.06), mat)
    return a


def sofa(rng: np.random.Generator, bank: MaterialBank, seats: int | None = None) -> Assembly:
    """A sofa (2-3 seats) or an armchair (1 seat): base, backrest, arms, seat cushions."""
    n = int(rng.integers(2, 4)) if seats is None else seats
    w = 0.6 * n + 0.3
    d = rng.uniform(0.82, 0.95)
    fab = bank.shared("fabric")
    cush = bank.shared("cushion")
    a = Assembly("sofa" if n > 1 else "armchair", [], (w / 2, d / 2), 0.85, LARGE)
    a.add_box("base", (0, 0.05, 0.16), (w / 2 - 0.15, d / 2 - 0.05, 0.14), fab)
    a.add_box("back", (0, -d / 2 + 0.1, 0.5), (w / 2, 0.1, 0.35), fab)
    for i, sx in enumerate((-1, 1)):
        a.add_box(f"arm_{i}", (sx * (w / 2 - 0.075), 0.0, 0.31), (0.075, d / 2, 0.31), fab)
    cw = (w - 0.3) / n
    for k in range(n):
        x = -w / 2 + 0.15 + cw * (k + 0.5)
        a.add_box(f"cushion_{k}", (x, 0.1, 0.36), (cw / 2 - 0.005, d / 2 - 0.2, 0.06), cush)
    a.supports.append(Support((0, 0.1), (w / 2 - 0.2, d / 2 - 0.28), 0.42, "seat"))
    return a



def bookshelf(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """An open shelf unit: sides, back, top, bottom and 2-5 boards; each board is a support for books."""
    w = rng.uniform(0.7, 1.2)
    d = rng.uniform(0.3, 0.4)
    h = rng.uniform(1.1, 2.0)
    mat = bank.shared("wood" if rng.random() < 0.6 else "laminate")
    t = 0.012
    a = Assembly("bookshelf", [], (w / 2, d / 2), h, LARGE)
    for i, sx in enumerate((-1, 1)):
        a.add_box(f"side_{i}", (sx * (w / 2 - t), 0, h / 2), (t, d / 2, h / 2), mat)
    a.add_box("back", (0, -d / 2 + 0.005, h / 2), (w / 2 - 2 * t, 0.005, h / 2), mat)
    a.add_box("top", (0, 0, h - t), (w / 2 - 2 * t, d / 2, t), mat)
    a.add_box("plinth", (0, 0, 0.04), (w / 2 - 2 * t, d / 2, 0.04), mat)
    n = max(2, int(round((h - 0.1) / 0.36)))
    gap = (h - 0.08 - t) / n
    for k in range(n):
        z = 0.08 + k * gap
        if k > 0:
            a.add_box(f"board_{k}", (0, 0, z - t), (w / 2 - 2 * t, d / 2 - 0.01, t), mat)
        a.supports.append(Support((0, 0.005), (w / 2 - 2 * t - 0.01, d / 2 - 0.03), z, "shelf", gap - 2 * t))
    return a


def cabinet(rng: np.random.Generator, bank: MaterialBank, tall: bool = False) -> Assembly:
    """A low sideboard (its top a support) or a tall wardrobe; doors and handles on the front (+y)."""
    w = rng.uniform(0.8, 1.2) if tall else rng.uniform(0.8, 1.6)
    d = rng.uniform(0.5, 0.6) if tall else rng.uniform(0.4, 0.5)
    h = rng.uniform(1.8, 2.1) if tall else rng.uniform(0.7, 0.95)
    body = bank.shared("wood" if rng.random() < 0.5 else "laminate")
    door = bank.shared("wood_dark") if rng.random() < 0.4 else body
    a = Assembly("wardrobe" if tall else "cabinet", [], (w / 2, d / 2), h, LARGE)
    a.add_box("body", (0, -0.01, h / 2), (w / 2, d / 2 - 0.01, h / 2), body)
    n = max(2, int(round(w / 0.5)))
    dw = w / n
    for k in range(n):
        x = -w / 2 + dw * (k + 0.5)
        a.add_box(f"door_{k}", (x, d / 2 - 0.01, h / 2 + 0.02), (dw / 2 - 0.006, 0.01, h / 2 - 0.04), door)
        hx = x + (dw / 2 - 0.06) * (1 if k % 2 == 0 else -1)
        a.add_cylinder(
            f"handle_{k}", (hx, d / 2 + 0.02, h * (0.5 if tall else 0.75)), 0.008, 0.06, bank.shared("metal")
        )
    if not tall:
        a.supports.append(Support((0, -0.01), (w / 2 - 0.03, d / 2 - 0.04), h))
    return a



def nightstand(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A small bedside cabinet with a drawer."""
    w, d, h = rng.uniform(0.4, 0.5), rng.uniform(0.35, 0.42), rng.uniform(0.5, 0.6)
    mat = bank.shared("wood")
    a = Assembly("nightstand", [], (w / 2, d / 2), h, LARGE)
    a.add_box("body", (0, 0, h / 2), (w / 2, d / 2, h / 2), mat)
    a.add_box("drawer", (0, d / 2 + 0.008, h * 0.75), (w / 2 - 0.03, 0.008, h * 0.15), bank.shared("wood_dark"))
    a.supports.append(Support((0, 0), (w / 2 - 0.04, d / 2 - 0.04), h))
    return a


def bed(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A single or double bed with its headboard at -y (against the wall): frame, mattress, duvet, pillows."""
    w = rng.choice([0.95, 1.45, 1.65])
    length = rng.uniform(2.0, 2.15)
    frame = bank.shared("wood")
    a = Assembly("bed", [], (w / 2, length / 2), 1.0, LARGE)
    a.add_box("frame", (0, 0, 0.17), (w / 2, length / 2, 0.13), frame)
    a.add_box("mattress", (0, 0.02, 0.39), (w / 2 - 0.03, length / 2 - 0.05, 0.09), bank.shared("bedding"))
    a.add_box("duvet", (0, 0.25, 0.5), (w / 2 - 0.02, length / 2 - 0.3, 0.03), bank.shared("cushion"))
    a.add_box("headboard", (0, -length / 2 + 0.03, 0.55), (w / 2, 0.03, 0.45), frame)
    n = 1 if w < 1.2 else 2
    for k in range(n):
        x = 0.0 if n == 1 else (k - 0.5) * w / 2
        a.add_box(
            f"pillow_{k}",
            (x, -length / 2 + 0.25, 0.52),
            (min(0.3, w / 2 / n + 0.05), 0.16, 0.05),
            bank.shared("bedding"),
        )
    return a


def kitchen_counter(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A run of base cabinets with a countertop (a support) and, sometimes, wall cabinets above."""
    w = rng.uniform(1.6, 3.0)
    d, h = 0.6, 0.9
    body = bank.shared("laminate")
    a = Assembly("counter", [], (w / 2, d / 2), h, LARGE)
    a.add_box("base", (0, -0.02, (h - 0.04) / 2 + 0.05), (w / 2, d / 2 - 0.04, (h - 0.04) / 2 - 0.05), body)
    a.add_box("plinth", (0, -0.05, 0.05), (w / 2, d / 2 - 0.08, 0.05), bank.shared("dark"))
    a.add_box("countertop", (0, 0, h - 0.02), (w / 2, d / 2, 0.02), bank.shared("countertop"))
    n = max(2, int(round(w / 0.6)))
    dw = w / n
    for k in range(n):
        x = -w / 2 + dw * (k + 0.5)
        a.add_box(f"door_{k}", (x, d / 2 - 0.03, h / 2 + 0.02), (dw / 2 - 0.005, 0.01, h / 2 - 0.12), body)
        a.add_box(f"handle_{k}", (x, d / 2 - 0.01, h - 0.15), (0.07, 0.01, 0.008), bank.shared("metal"))
    if rng.random() < 0.7:
        a.add_box("wall_cabinets", (0, -d / 2 + 0.18, 1.85), (w / 2, 0.17, 0.35), body)
        a.height = 2.2
    a.supports.append(Support((0, 0.02), (w / 2 - 0.05, d / 2 - 0.08), h, "top", 0.5))
    return a


def fridge(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A tall fridge: body, two doors and handles."""
    w, d, h = rng.uniform(0.6, 0.75), 0.65, rng.uniform(1.7, 1.95)
    mat = bank.shared("appliance")
    a = Assembly("fridge", [], (w / 2, d / 2), h, LARGE)
    a.add_box("body", (0, -0.01, h / 2), (w / 2, d / 2 - 0.01, h / 2), mat)
    split = h * 0.62
    a.add_box("door_low", (0, d / 2 - 0.01, split / 2), (w / 2 - 0.005, 0.012, split / 2 - 0.01), mat)
    a.add_box("door_high", (0, d / 2 - 0.01, (split + h) / 2), (w / 2 - 0.005, 0.012, (h - split) / 2 - 0.01), mat)
    for i, z in enumerate((split - 0.25, split + 0.2)):
        a.add_box(f"handle_{i}", (w / 2 - 0.06, d / 2 + 0.02, z), (0.012, 0.012, 0.15), bank.shared("metal"))
    return a


def tv_stand(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A low, wide media cabinet (a TV is placed on it as an object)."""
    w, d, h = rng.uniform(1.2, 1.8), rng.uniform(0.4, 0.5), rng.uniform(0.45, 0.6)
    mat = bank.shared("wood_dark" if rng.random() < 0.5 else "laminate")
    a = Assembly("tv_stand", [], (w / 2, d / 2), h, LARGE)
    a.add_box("body", (0, 0, h / 2 + 0.03), (w / 2, d / 2, h / 2 - 0.03), mat)
    for i, sx in enumerate((-1, 1)):
        a.add_box(f"foot_{i}", (sx * (w / 2 - 0.05), 0, 0.015), (0.03, d / 2 - 0.03, 0.015), bank.shared("metal"))
    a.supports.append(Support((0, 0), (w / 2 - 0.05, d / 2 - 0.05), h, "tv"))
    return a



# ------------------------------------------------------------------------------------------------------ small objects
def book(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A book lying flat (x: width, y: depth, z: thickness); its cover is unique."""
    w, d, t = rng.uniform(0.13, 0.22), rng.uniform(0.18, 0.28), rng.uniform(0.015, 0.05)
    return _solid_box("book", w / 2, d / 2, t / 2, bank.unique("book_cover"))


def standing_book(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A book standing upright on a shelf, its spine to the front (+y)."""
    t, d, h = rng.uniform(0.02, 0.05), rng.uniform(0.15, 0.24), rng.uniform(0.18, 0.28)
    return _solid_box("book", t / 2, d / 2, h / 2, bank.unique("book_cover"))


def box(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A cardboard or plastic box."""
    hx, hy, hz = rng.uniform(0.06, 0.2), rng.uniform(0.06, 0.15), rng.uniform(0.04, 0.15)
    mat = bank.shared("cardboard") if rng.random() < 0.6 else bank.shared("plastic")
    return _solid_box("box", hx, hy, hz, mat)


def cup(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A mug: a cylinder with a handle."""
    r, h = rng.uniform(0.035, 0.045), rng.uniform(0.08, 0.11)
    mat = bank.shared("ceramic")
    a = Assembly("cup", [], (r + 0.02, r), h, SMALL)
    a.add_cylinder("body", (0, 0, h / 2), r, h / 2, mat)
    a.add_box("handle", (r + 0.012, 0, h / 2), (0.012, 0.006, h / 3), mat)
    return a


def bottle(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A bottle: body and neck cylinders."""
    r, h = rng.uniform(0.03, 0.045), rng.uniform(0.18, 0.28)
    mat = bank.shared("glass")
    a = Assembly("bottle", [], (r, r), h + 0.06, SMALL)
    a.add_cylinder("body", (0, 0, h / 2), r, h / 2, mat)
    a.add_cylinder("neck", (0, 0, h + 0.03), r * 0.35, 0.03, mat)
    return a


def monitor(rng: np.random.Generator, bank: MaterialBank, tv: bool = False) -> Assembly:
    """A flat screen on a stand, facing +y (a TV when ``tv``)."""
    w = rng.uniform(0.9, 1.3) if tv else rng.uniform(0.5, 0.65)
    h = w * rng.uniform(0.56, 0.62)
    dark = bank.shared("dark")
    a = Assembly("tv" if tv else "monitor", [], (max(w / 2, 0.12), 0.12), h + 0.12, SMALL)
    a.add_box("foot", (0, 0, 0.01), (min(0.15 + 0.1 * tv, w / 2), 0.1, 0.01), dark)
    a.add_box("neck", (0, -0.03, 0.07), (0.025, 0.015, 0.06), dark)
    a.add_box("panel", (0, 0, 0.1 + h / 2), (w / 2, 0.02, h / 2), dark)
    a.add_box("screen", (0, 0.021, 0.1 + h / 2), (w / 2 - 0.015, 0.002, h / 2 - 0.015), bank.unique("screen"))
    return a



def laptop(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A closed laptop."""
    return _solid_box("laptop", 0.17, 0.12, 0.01, bank.shared("metal"))


def keyboard(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A keyboard (a flat box) in front of a monitor."""
    return _solid_box("keyboard", 0.22, 0.07, 0.0125, bank.shared("dark"))


def plant(rng: np.random.Generator, bank: MaterialBank, large: bool = False) -> Assembly:
    """A potted plant: pot, soil and one to three spheres of foliage (a large one stands on the floor)."""
    s = rng.uniform(2.0, 3.0) if large else rng.uniform(0.8, 1.2)
    r, h = 0.07 * s, 0.12 * s
    a = Assembly("plant", [], (r, r), h + 0.25 * s, SMALL)
    a.add_cylinder("pot", (0, 0, h / 2), r, h / 2, bank.shared("soil_pot"))
    leaves = bank.shared("leaves")
    for k in range(int(rng.integers(1, 4))):
        off = rng.uniform(-0.3, 0.3, 2) * r
        a.add_sphere(f"leaves_{k}", (off[0], off[1], h + 0.09 * s + 0.04 * s * k), 0.1 * s - 0.015 * s * k, leaves)
    return a



def lamp(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A desk lamp: base, stem and a shade (unlit: lights are the scene's static lights)."""
    h = rng.uniform(0.3, 0.45)
    mat = bank.shared("metal")
    a = Assembly("lamp", [], (0.08, 0.08), h + 0.1, SMALL)
    a.add_cylinder("base", (0, 0, 0.012), 0.08, 0.012, mat)
    a.add_cylinder("stem", (0, 0, h / 2 + 0.02), 0.01, h / 2, mat)
    a.add_cylinder("shade", (0, 0, h + 0.05), 0.09, 0.07, bank.shared("bedding"))
    return a


def vase(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A vase or pot-like ornament."""
    r, h = rng.uniform(0.04, 0.08), rng.uniform(0.12, 0.3)
    return _solid_cylinder("vase", r, h, bank.shared("ceramic"))


def bowl(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A flat bowl or plate."""
    r, h = rng.uniform(0.08, 0.14), rng.uniform(0.02, 0.07)
    return _solid_cylinder("bowl", r, h, bank.shared("ceramic"))


def pillow(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A cushion for a sofa or bed."""
    hx, hy, hz = rng.uniform(0.18, 0.25), rng.uniform(0.18, 0.25), rng.uniform(0.04, 0.07)
    return _solid_box("pillow", hx, hy, hz, bank.shared("cushion") if rng.random() < 0.5 else bank.unique("rug"))


def bin_(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A waste bin standing on the floor."""
    r, h = rng.uniform(0.12, 0.16), rng.uniform(0.3, 0.4)
    return _solid_cylinder("bin", r, h, bank.shared("plastic"))


def papers(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A stack of 1-5 loose sheets (A4 or A5, 2 mm each), each turned a little; the top sheet's page is unique."""
    w, d = (0.21, 0.297) if rng.random() < 0.7 else (0.148, 0.21)
    if rng.random() < 0.5:
        w, d = d, w
    a = Assembly("papers", [], (w / 2, d / 2), 0.0, SMALL)
    n = int(rng.integers(1, 6))
    for k in range(n):
        off = rng.uniform(-0.012, 0.012, 2)
        mat = bank.unique("paper") if k == n - 1 else bank.shared("paper")
        a.add_box(f"sheet_{k}", (off[0], off[1], 0.001 + 0.002 * k), (w / 2, d / 2, 0.001), mat,
                  rpy=(0.0, 0.0, float(rng.uniform(-0.08, 0.08))))  # fmt: skip
    return a


def tin(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A labelled tin, jar or can: a cylinder whose label wraps once around it."""
    r, h = rng.uniform(0.03, 0.055), rng.uniform(0.07, 0.18)
    return _solid_cylinder("tin", r, h, bank.unique("label"))


def carton(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A printed carton (cereal, tissues, a parcel): a box with its own label on every face."""
    hx, hy, hz = rng.uniform(0.04, 0.13), rng.uniform(0.025, 0.08), rng.uniform(0.03, 0.13)
    return _solid_box("carton", hx, hy, hz, bank.unique("label"))


def pen_holder(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A pot with 3-6 pens standing in it at small angles."""
    r, h = rng.uniform(0.03, 0.04), rng.uniform(0.08, 0.11)
    a = Assembly("pen_holder", [], (r, r), h, SMALL)
    a.add_cylinder("pot", (0, 0, h / 2), r, h / 2, bank.shared("ceramic" if rng.random() < 0.5 else "metal"))
    for k in range(int(rng.integers(3, 7))):
        off = rng.uniform(-0.5, 0.5, 2) * r
        tilt = rng.uniform(-0.2, 0.2, 2)
        a.add_cylinder(f"pen_{k}", (off[0], off[1], h * 0.55 + 0.06), 0.004, 0.07, bank.shared("plastic"),
                       rpy=(float(tilt[0]), float(tilt[1]), 0.0))  # fmt: skip
    return a


def bush(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A potted plant as a cluster of 4-8 leafy balls and blades (boxes) of two greens, over a pot."""
    s = rng.uniform(0.8, 1.4)
    r, h = 0.06 * s, 0.09 * s
    a = Assembly("plant", [], (r, r), h, SMALL)
    a.add_cylinder("pot", (0, 0, h / 2), r, h / 2, bank.shared("soil_pot"))
    greens = (bank.shared("leaves"), bank.unique("leaves"))
    for k in range(int(rng.integers(4, 9))):
        off = rng.normal(0.0, 0.6, 3) * r
        z = h + abs(off[2]) + 0.03 * s
        if rng.random() < 0.6:
            a.add_sphere(f"leaves_{k}", (off[0], off[1], z), float(rng.uniform(0.025, 0.05) * s), greens[k % 2])
        else:
            a.add_box(f"blade_{k}", (off[0], off[1], z + 0.03 * s), (0.012 * s, 0.004, 0.06 * s), greens[k % 2],
                      rpy=(float(rng.uniform(-0.5, 0.5)), float(rng.uniform(-0.5, 0.5)), float(rng.uniform(0, np.pi))))
    return a


# ------------------------------------------------------------------------------------------------ wall decorations
# Local frame of a wall decoration: origin at the bottom centre of its back, which touches the wall; its front faces
# +y (into the room); x along the wall. ``half`` is (half width, depth / 2), ``height`` its height.


def picture_frame(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A framed picture or photo: a frame board and the picture 4 mm in front of it, inset by the frame's width."""
    w = rng.uniform(0.18, 0.6)
    h = w * rng.uniform(0.7, 1.4)
    border = rng.uniform(0.015, 0.05)
    a = Assembly("frame", [], (w / 2, 0.0125), h, SMALL)
    a.add_box("board", (0, 0.01, h / 2), (w / 2, 0.01, h / 2), bank.shared("frame"))
    a.add_box("picture", (0, 0.0225, h / 2), (w / 2 - border, 0.0025, h / 2 - border), bank.unique("poster"))
    return a


def pinboard(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A cork board with 3-8 notes and printouts pinned on it, a little crooked."""
    w, h = rng.uniform(0.5, 1.0), rng.uniform(0.4, 0.7)
    a = Assembly("pinboard", [], (w / 2, 0.01), h, SMALL)
    a.add_box("cork", (0, 0.008, h / 2), (w / 2, 0.008, h / 2), bank.shared("cork"))
    for k in range(int(rng.integers(3, 9))):
        nw, nh = rng.uniform(0.06, 0.15), rng.uniform(0.06, 0.2)
        x, z = rng.uniform(-w / 2 + nw, w / 2 - nw), rng.uniform(nh, h - nh)
        a.add_box(f"note_{k}", (x, 0.017 + 0.0005 * k, z), (nw / 2, 0.0005, nh / 2), bank.unique("paper"),
                  rpy=(0.0, float(rng.uniform(-0.15, 0.15)), 0.0))  # fmt: skip
    return a


def wall_clock(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A round clock: a short cylinder whose axis points into the room, its face on the front cap."""
    r = rng.uniform(0.11, 0.18)
    a = Assembly("clock", [], (r, 0.02), 2 * r, SMALL)
    a.add_cylinder("body", (0, 0.02, r), r, 0.02, bank.unique("clock"), rpy=(-np.pi / 2, 0.0, 0.0))
    return a


def calendar(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A hanging calendar or notice: a picture over a printed page."""
    w = rng.uniform(0.22, 0.35)
    a = Assembly("calendar", [], (w / 2, 0.002), 1.5 * w, SMALL)
    a.add_box("picture", (0, 0.002, 1.1 * w), (w / 2, 0.002, 0.4 * w), bank.unique("poster"))
    a.add_box("page", (0, 0.002, 0.35 * w), (w / 2, 0.002, 0.35 * w), bank.unique("paper"))
    return a


def switch_plate(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
    """A light switch or socket plate, or a thermostat: a small flat box."""
    w, h = rng.uniform(0.07, 0.12), rng.uniform(0.07, 0.12)
    a = Assembly("switch", [], (w / 2, 0.006), h, SMALL)
    mat = bank.shared("plastic" if rng.random() < 0.3 else "appliance")
    a.add_box("plate", (0, 0.006, h / 2), (w / 2, 0.006, h / 2), mat)
    return a


# --------------------------------------------------------------------------------------------------------- variants
# One piece's builder with fixed options, under its own name (the registries below list them like the others).
small_desk = _variant(desk, "small_desk", "A pupil's desk (classroom).", small=True)
coffee_table = _variant(table, "coffee_table", "A low table in front of a sofa.", coffee=True)
armchair = _variant(sofa, "armchair", "A one-seat sofa.", seats=1)
wardrobe = _variant(cabinet, "wardrobe", "A tall cabinet with doors (no support: too high for objects).", tall=True)
teacher_desk = _variant(desk, "teacher_desk", "A big desk (the classroom's front).")
tv = _variant(monitor, "tv", "A television on its foot.", tv=True)
large_plant = _variant(plant, "large_plant", "A floor-standing plant.", large=True)


def part_corners(part: Part) -> np.ndarray:
    """(8, 3) corners of a part's bounding box in its assembly's frame (cylinders and spheres: their boxes)."""
    r = part.size[0]
    half = {"box": np.array(part.size), "cylinder": np.array([r, r, part.size[1]]), "sphere": np.full(3, r)}[part.kind]
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    return (signs * half) @ part.T[:3, :3].T + part.T[:3, 3]


def fitted(builder: Builder) -> Builder:
    """A builder whose assemblies get footprint half sizes and height that bound every part (handles included).

    The footprint stays centred on the assembly's origin: ``half = max |x|, max |y|`` over all part corners.
    """

    def build(rng: np.random.Generator, bank: MaterialBank) -> Assembly:
        a = builder(rng, bank)
        corners = np.concatenate([part_corners(p) for p in a.parts])
        a.half = (float(np.abs(corners[:, 0]).max()), float(np.abs(corners[:, 1]).max()))
        a.height = float(corners[:, 2].max())
        return a

    build.__doc__ = builder.__doc__
    build.__name__ = builder.__name__
    return build


_FURNITURE: dict[str, Builder] = {
    "desk": desk, "small_desk": small_desk, "teacher_desk": teacher_desk, "table": table,
    "coffee_table": coffee_table, "chair": chair, "sofa": sofa, "armchair": armchair, "bookshelf": bookshelf,
    "cabinet": cabinet, "wardrobe": wardrobe, "nightstand": nightstand, "bed": bed, "counter": kitchen_counter,
    "fridge": fridge, "tv_stand": tv_stand,
}  # fmt: skip
_OBJECTS: dict[str, Builder] = {
    "book": book, "standing_book": standing_book, "box": box, "cup": cup, "bottle": bottle, "monitor": monitor,
    "tv": tv, "laptop": laptop, "keyboard": keyboard, "plant": plant, "large_plant": large_plant, "lamp": lamp,
    "vase": vase, "bowl": bowl, "pillow": pillow, "bin": bin_, "papers": papers, "tin": tin, "carton": carton,
    "pen_holder": pen_holder, "bush": bush,
}  # fmt: skip
FURNITURE: dict[str, Builder] = {name: fitted(f) for name, f in _FURNITURE.items()}
OBJECTS: dict[str, Builder] = {name: fitted(f) for name, f in _OBJECTS.items()}
WALL_DECORATIONS: dict[str, Builder] = {
    "frame": picture_frame, "pinboard": pinboard, "clock": wall_clock, "calendar": calendar, "switch": switch_plate,
}  # fmt: skip
