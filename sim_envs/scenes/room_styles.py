"""The room styles of :mod:`sim_envs.scenes.scenegen` as data: the test and training styles, what each style decides
(size,
materials, openings, furniture and its groups, clutter), and what stands on what (standard and rich rooms).
:mod:`sim_envs.scenes.scenegen` re-exports these names.
"""

from __future__ import annotations

from dataclasses import dataclass

TEST_STYLES: tuple[str, ...] = ("office", "living")
TRAIN_STYLES: tuple[str, ...] = ("bedroom", "kitchen", "classroom", "study")
ROOM_STYLES: tuple[str, ...] = TEST_STYLES + TRAIN_STYLES


@dataclass(frozen=True)
class Item:
    """A kind of furniture a style places: FURNITURE builder name, (min, max) count, "wall" or "free", and a group.

    group: "" (alone), "chair" (a chair in front, facing it), "chairs" (chairs around a table), "coffee" (a coffee
    table in front of a sofa), "rows" (a grid of pupils' desks with chairs, all facing wall 0).
    """

    builder: str
    count: tuple[int, int]
    place: str = "wall"
    group: str = ""


@dataclass(frozen=True)
class Style:
    """Everything a room style decides: size ranges (m), floor/wall material slots, openings, furniture, clutter."""

    name: str
    size_xy: tuple[float, float]
    height: tuple[float, float]
    floors: tuple[str, ...]
    walls: tuple[str, ...]
    items: tuple[Item, ...]
    windows: tuple[int, int] = (1, 2)
    doors: tuple[int, int] = (1, 2)
    posters: tuple[int, int] = (1, 3)
    whiteboard: bool = False
    rug: float = 0.0  # probability of a rug in the middle of the room
    clutter: float = 6.0  # objects per square metre of support (furniture tops), before caps
    floor_objects: tuple[int, int] = (1, 3)


_OFFICE_WALLS = ("wall_paint", "wall_paint", "wall_wallpaper")
STYLES: dict[str, Style] = {
    "office": Style(
        name="office", size_xy=(4.5, 6.0), height=(2.6, 2.8),
        floors=("floor_carpet", "floor_tiles"), walls=_OFFICE_WALLS,
        items=(
            Item("desk", (2, 4), "wall", "chair"), Item("bookshelf", (1, 2)), Item("cabinet", (1, 2)),
            Item("desk", (0, 1), "free", "chair"), Item("table", (0, 1), "free", "chairs"),
        ),
        windows=(1, 2), posters=(1, 3), whiteboard=True, clutter=7.0,
    ),
    "living": Style(
        name="living", size_xy=(4.5, 6.0), height=(2.5, 2.7),
        floors=("floor_wood", "floor_wood", "floor_carpet"), walls=("wall_paint", "wall_wallpaper"),
        items=(
            Item("sofa", (1, 1), "wall", "coffee"), Item("tv_stand", (1, 1)), Item("bookshelf", (1, 2)),
            Item("armchair", (0, 1)), Item("cabinet", (0, 1)), Item("table", (0, 1), "free", "chairs"),
        ),
        windows=(1, 3), posters=(1, 3), rug=0.7, clutter=5.0,
    ),
    "bedroom": Style(
        name="bedroom", size_xy=(3.5, 5.0), height=(2.4, 2.7),
        floors=("floor_wood", "floor_carpet"), walls=("wall_paint", "wall_wallpaper"),
        items=(
            Item("bed", (1, 1)), Item("nightstand", (1, 2)), Item("wardrobe", (1, 1)),
            Item("desk", (0, 1), "wall", "chair"), Item("bookshelf", (0, 1)), Item("cabinet", (0, 1)),
        ),
        windows=(1, 2), posters=(0, 2), rug=0.5,
    ),
    "kitchen": Style(
        name="kitchen", size_xy=(3.5, 5.0), height=(2.4, 2.7),
        floors=("floor_tiles", "floor_concrete"), walls=("wall_tiles", "wall_paint"),
        items=(
            Item("counter", (1, 2)), Item("fridge", (1, 1)), Item("table", (1, 1), "free", "chairs"),
            Item("cabinet", (0, 1)),
        ),
        windows=(1, 2), posters=(0, 1), clutter=8.0, floor_objects=(0, 2),
    ),
    "classroom": Style(
        name="classroom", size_xy=(6.0, 8.0), height=(2.8, 3.2),
        floors=("floor_tiles", "floor_concrete"), walls=("wall_paint",),
        items=(
            Item("small_desk", (6, 16), "free", "rows"), Item("teacher_desk", (1, 1), "wall", "chair"),
            Item("bookshelf", (1, 2)), Item("cabinet", (1, 2)),
        ),
        windows=(2, 3), posters=(1, 3), whiteboard=True, clutter=4.0,
    ),
    "study": Style(
        name="study", size_xy=(3.5, 5.0), height=(2.5, 2.8),
        floors=("floor_wood", "floor_carpet"), walls=("wall_wallpaper", "wall_paint"),
        items=(
            Item("bookshelf", (2, 3)), Item("desk", (1, 1), "wall", "chair"), Item("armchair", (1, 1)),
            Item("coffee_table", (0, 1), "free"), Item("cabinet", (0, 1)),
        ),
        windows=(1, 2), posters=(1, 2), rug=0.6,
    ),
}  # fmt: skip

# What stands on what: furniture kind (or "floor") -> (object builder, weight); support kind "shelf" uses SHELF_OBJECTS
OBJECTS_ON: dict[str, tuple[tuple[str, float], ...]] = {
    "desk": (("book", 3), ("cup", 2), ("lamp", 1), ("plant", 1), ("box", 1), ("laptop", 1), ("bottle", 1)),
    "table": (("cup", 3), ("bowl", 2), ("bottle", 2), ("vase", 1), ("book", 1), ("plant", 1)),
    "coffee_table": (("book", 3), ("cup", 2), ("vase", 1), ("bowl", 1), ("plant", 1)),
    "cabinet": (("vase", 2), ("plant", 2), ("book", 2), ("box", 2), ("lamp", 1)),
    "nightstand": (("lamp", 3), ("book", 2), ("cup", 1)),
    "counter": (("cup", 2), ("bottle", 3), ("bowl", 2), ("box", 1), ("plant", 1)),
    "tv_stand": (("box", 1), ("vase", 1), ("book", 1)),
    "sofa": (("pillow", 1),),
    "armchair": (("pillow", 1),),
    "floor": (("large_plant", 3), ("bin", 2), ("box", 2)),
}
SHELF_OBJECTS: tuple[tuple[str, float], ...] = (("box", 1), ("vase", 1), ("book", 1))
MAX_OBJECTS_PER_SUPPORT = 7  # (ours)
TUMBLING = frozenset({"book", "box", "pillow", "bottle", "cup", "bowl", "vase"})  # may be tossed (ours)
TUMBLE_PROBABILITY = 0.35  # share of those tossed from a few cm with a random tilt rather than set down (ours)

# Rich rooms (module docstring): what the rich pass adds, by support kind (fur.Support.kind)
RICH_STREAM = 23  # the rich pass's generators are seeded from (seed, style, RICH_STREAM) (ours)
_RICH_TOP: tuple[tuple[str, float], ...] = (
    ("papers", 4), ("book", 3), ("cup", 2), ("tin", 2), ("carton", 2), ("pen_holder", 1), ("bush", 1), ("bowl", 1),
    ("bottle", 1),
)  # fmt: skip
RICH_OBJECTS_ON: dict[str, tuple[tuple[str, float], ...]] = {
    "top": _RICH_TOP,
    "tv": _RICH_TOP,
    "shelf": (("tin", 2), ("carton", 2), ("book", 2), ("cup", 1), ("bush", 1), ("papers", 1)),
    "seat": (("pillow", 2), ("papers", 1), ("book", 1)),
}
RICH_CLUTTER = 30.0  # extra objects per square metre of support, before the caps (ours)
RICH_MAX_PER_SUPPORT = 14  # extra objects per support at most (ours)
RICH_TRIES = 30  # random spots tried per extra object (ours; the standard pass tries 12)
RICH_MAX_PER_SEAT = 2  # extra objects per seat at most (ours)
RICH_FLOOR_OBJECTS: tuple[int, int] = (3, 6)  # extra floor objects along the walls (ours)
RICH_FLOOR_TABLE: tuple[tuple[str, float], ...] = (("box", 3), ("carton", 2), ("bin", 1), ("bush", 1))
RICH_FLOOR_MAX_HEIGHT = 0.45  # metres: a rich room's floor objects are at most this high (ours: below cameras)
RICH_WALL_ITEMS: tuple[int, int] = (18, 30)  # wall decorations tried (ours, fitted: results/camera_calibration.md)
RICH_WALL_TABLE: tuple[tuple[str, float], ...] = (
    ("frame", 6), ("pinboard", 1), ("clock", 0.5), ("calendar", 1), ("switch", 1.5),
)  # fmt: skip
