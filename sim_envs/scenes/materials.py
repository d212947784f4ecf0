"""Materials of generated scenes: named slots ("floor_wood", "fabric", "book_cover"...) turned into
:class:`~sim_envs.scenes.scene.Material` objects, textured or plain according to the texture density.

A :class:`MaterialBank` draws every texture from its own generator in the order slots are first asked for, and draws
the same random numbers whatever the texture density, so a room generated with another density has the same
layout and the same texture patterns, only fewer and fainter textures (density 0: a textureless world of plain colours).

:func:`enrich_material` gives a material of a ``rich`` room (:data:`sim_envs.scenes.scene.DETAILS`) its texture detail.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from sim_envs.scenes import textures
from sim_envs.scenes.scene import Material

Rgb = tuple[float, float, float]


@dataclass(frozen=True)
class Slot:
    """How to make the material of a slot.

    texture: texture function ``(rng, rgb) -> image`` or ``(rng) -> image`` (``takes_rgb`` False), or None for a
    plain colour; colours: base colours to choose from (0-1 floats); tile_m: (min, max) metres per texture repeat, or
    None to stretch the image once per face; propensity: chance in [0, 1] that the surface is textured at texture
    density 1 (plain painted walls are often untextured even then).
    """

    texture: Callable[..., np.ndarray] | None
    colours: tuple[Rgb, ...]
    tile_m: tuple[float, float] | None = (0.8, 1.2)
    propensity: float = 1.0
    takes_rgb: bool = True


_WOODS: tuple[Rgb, ...] = ((0.55, 0.36, 0.2), (0.7, 0.52, 0.32), (0.4, 0.26, 0.16), (0.78, 0.64, 0.45))
_FABRICS: tuple[Rgb, ...] = ((0.4, 0.45, 0.6), (0.6, 0.35, 0.3), (0.45, 0.55, 0.4), (0.55, 0.5, 0.45), (0.3, 0.3, 0.35))
_PAINTS: tuple[Rgb, ...] = (
    (0.92, 0.92, 0.9),
    (0.9, 0.86, 0.78),
    (0.8, 0.86, 0.9),
    (0.86, 0.9, 0.82),
    (0.95, 0.9, 0.85),
)
_PLASTICS: tuple[Rgb, ...] = ((0.85, 0.2, 0.2), (0.2, 0.45, 0.8), (0.95, 0.8, 0.2), (0.25, 0.65, 0.3), (0.9, 0.9, 0.9))

SLOTS: dict[str, Slot] = {
    # floors
    "floor_wood": Slot(textures.planks, _WOODS, (0.9, 1.4)),
    "floor_carpet": Slot(textures.carpet, ((0.45, 0.45, 0.5), (0.4, 0.45, 0.55), (0.55, 0.45, 0.4)), (0.8, 1.2)),
    "floor_tiles": Slot(textures.tiles, ((0.85, 0.83, 0.78), (0.7, 0.7, 0.72), (0.8, 0.7, 0.6)), (0.9, 1.3)),
    "floor_concrete": Slot(textures.concrete, ((0.6, 0.6, 0.58), (0.55, 0.52, 0.5)), (1.5, 2.5)),
    "rug": Slot(textures.fabric, _FABRICS, (0.6, 1.0)),
    # walls and ceiling: painted plaster is deliberately low-texture
    "wall_paint": Slot(textures.paint, _PAINTS, (1.5, 2.5), propensity=0.7),
    "wall_wallpaper": Slot(textures.wallpaper, _PAINTS, (0.6, 1.0)),
    "wall_tiles": Slot(textures.tiles, ((0.9, 0.9, 0.92), (0.85, 0.88, 0.85)), (0.6, 0.9)),
    "ceiling": Slot(textures.paint, ((0.95, 0.95, 0.95),), (1.5, 2.5), propensity=0.5),
    "door": Slot(textures.door_panel, _WOODS, None),
    "door_frame": Slot(textures.paint, _PAINTS, (1.0, 1.0), propensity=0.3),
    "window": Slot(textures.window_view, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "sill": Slot(textures.concrete, ((0.9, 0.9, 0.88),), (0.5, 0.8)),
    "poster": Slot(textures.poster, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "whiteboard": Slot(textures.whiteboard, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    # furniture
    "wood": Slot(textures.wood, _WOODS, (0.6, 1.0)),
    "wood_dark": Slot(textures.wood, ((0.35, 0.22, 0.14), (0.3, 0.25, 0.2)), (0.6, 1.0)),
    "laminate": Slot(textures.concrete, ((0.85, 0.85, 0.82), (0.7, 0.72, 0.75), (0.9, 0.88, 0.8)), (0.6, 1.0), 0.6),
    "metal": Slot(None, ((0.55, 0.56, 0.58), (0.25, 0.25, 0.27), (0.75, 0.75, 0.76))),
    "fabric": Slot(textures.fabric, _FABRICS, (0.4, 0.7)),
    "cushion": Slot(textures.fabric, _FABRICS, (0.3, 0.5)),
    "bedding": Slot(textures.fabric, ((0.9, 0.9, 0.92), (0.7, 0.75, 0.85), (0.85, 0.75, 0.7)), (0.4, 0.7)),
    "countertop": Slot(textures.concrete, ((0.3, 0.3, 0.32), (0.85, 0.85, 0.83), (0.6, 0.55, 0.5)), (0.6, 1.0)),
    "appliance": Slot(None, ((0.92, 0.92, 0.92), (0.7, 0.71, 0.72))),
    # small objects
    "book_cover": Slot(textures.book_cover, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "screen": Slot(textures.screen, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "plastic": Slot(None, _PLASTICS),
    "ceramic": Slot(textures.paint, ((0.95, 0.95, 0.93), (0.3, 0.4, 0.6), (0.7, 0.3, 0.25)), (0.2, 0.3), 0.3),
    "cardboard": Slot(textures.concrete, ((0.7, 0.55, 0.38),), (0.3, 0.5)),
    "leaves": Slot(textures.fabric, ((0.25, 0.5, 0.2), (0.3, 0.55, 0.25), (0.2, 0.4, 0.2)), (0.15, 0.25)),
    "soil_pot": Slot(textures.concrete, ((0.6, 0.35, 0.25), (0.85, 0.85, 0.85), (0.3, 0.3, 0.3)), (0.3, 0.5)),
    "dark": Slot(None, ((0.12, 0.12, 0.13), (0.2, 0.2, 0.22))),
    "glass": Slot(None, ((0.55, 0.7, 0.65), (0.45, 0.3, 0.2), (0.6, 0.65, 0.75))),
    # the clutter of rich rooms
    "paper": Slot(textures.page, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "label": Slot(textures.book_cover, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "clock": Slot(textures.clock_face, ((1.0, 1.0, 1.0),), None, takes_rgb=False),
    "cork": Slot(textures.concrete, ((0.72, 0.55, 0.36), (0.65, 0.5, 0.32)), (0.3, 0.5)),
    "frame": Slot(textures.wood, ((0.12, 0.1, 0.09), (0.55, 0.36, 0.2), (0.85, 0.85, 0.83), (0.7, 0.6, 0.3)),
                  (0.3, 0.5)),
}


# Texture detail of rich rooms (:func:`enrich_material`). "fitted": chosen on image statistics of simulated frames
# against the real kitchen's (results/camera_calibration.md, "Rich rooms", says on which frames and how)
RICH_CONTRAST = 2.0  # a texture's deviation from its mean colour is scaled by this (ours, fitted)
RICH_MID = 0.15  # amplitude of the mid-scale blotches, +- share of the colour (ours)
RICH_FINE = 0.25  # amplitude of the fine grain (ours, fitted)
RICH_SPECKS = 0.04  # share of the surface in dark specks (ours)
RICH_SPECK_DEPTH = 0.35  # how much darker a speck is (ours)
RICH_PLAIN_SIZE = 128  # texels per side of the detail texture a plain material gets (ours)
RICH_WALL_STRENGTH = 0.35  # walls and ceilings get this share of the detail: plaster stays plainer (ours, fitted)


def enrich_material(material: Material, rng: np.random.Generator, texture_density: float = 1.0,
                    strength: float = 1.0) -> Material:  # fmt: skip
    """``material`` as a rich room has it: its texture's contrast raised by :data:`RICH_CONTRAST` and wear overlaid
    (:func:`sim_envs.scenes.textures.detailed` with :data:`RICH_MID`, :data:`RICH_FINE`, :data:`RICH_SPECKS`,
    :data:`RICH_SPECK_DEPTH`); a plain
    colour becomes a texture of that colour with the same wear (over ``tile_m``, or once per face when None).

    Every amplitude is scaled by ``strength`` (e.g. :data:`RICH_WALL_STRENGTH`) and by ``texture_density`` in
    [0, 1], as :class:`MaterialBank` scales its textures; at 0 the material is returned unchanged (a textureless
    world stays textureless). Same name, rgb (1, 1, 1) when a
    texture is made; lighting terms (specular, shininess, emission) kept. Draws from ``rng`` only.
    """
    density = float(np.clip(texture_density, 0.0, 1.0)) * float(strength)
    if density <= 0.0:
        return material
    contrast = 1.0 + (RICH_CONTRAST - 1.0) * density
    mid, fine, depth = RICH_MID * density, RICH_FINE * density, RICH_SPECK_DEPTH * density
    if material.texture is None:
        base = np.clip(np.asarray(material.rgb) * 255.0, 0, 255).astype(np.uint8)
        plain = np.broadcast_to(base, (RICH_PLAIN_SIZE, RICH_PLAIN_SIZE, 3))
        image = textures.detailed(plain, rng, 1.0, mid, fine, RICH_SPECKS, depth)
        return replace(material, rgb=(1.0, 1.0, 1.0), texture=image)
    image = textures.detailed(material.texture, rng, contrast, mid, fine, RICH_SPECKS, depth)
    return replace(material, texture=image)


class MaterialBank:
    """Makes the materials of one scene.

    rng: the scene's texture generator (used only here); texture_density in [0, 1]: at 1 a slot is textured with its
    propensity and full contrast; lower values make fewer surfaces textured (chance = propensity x density) and scale
    the contrast of the others by ``0.25 + 0.75 x density``; at 0 every material is a plain colour.
    """

    def __init__(self, rng: np.random.Generator, texture_density: float = 1.0) -> None:
        self.rng = rng
        self.texture_density = float(np.clip(texture_density, 0.0, 1.0))
        self._shared: dict[str, Material] = {}
        self._count = 0

    def shared(self, slot: str) -> Material:
        """The material of ``slot`` shared by the whole scene (all desks of an office have the same wood)."""
        if slot not in self._shared:
            self._shared[slot] = self._make(slot)
        return self._shared[slot]

    def unique(self, slot: str) -> Material:
        """A new material of ``slot`` (a poster, a book cover)."""
        return self._make(slot)

    def _make(self, slot: str) -> Material:
        """A new material of ``slot``: colour, tile size and texture drawn, then textured or plain by density."""
        spec = SLOTS[slot]
        rng = self.rng
        rgb = spec.colours[int(rng.integers(len(spec.colours)))]
        u = rng.random()  # drawn for every slot so that the stream does not depend on the density
        tile = float(rng.uniform(*spec.tile_m)) if spec.tile_m is not None else None
        self._count += 1
        name = f"{slot}_{self._count}"
        if spec.texture is None:
            return Material(name, rgb, None, tile)
        image = spec.texture(rng, rgb) if spec.takes_rgb else spec.texture(rng)
        density = self.texture_density
        if u >= spec.propensity * density:
            mean = image.reshape(-1, 3).mean(0) / 255.0
            return Material(name, tuple(float(c) for c in np.clip(mean, 0, 1)), None, tile)
        image = textures.scale_contrast(image, 0.25 + 0.75 * density)
        return Material(name, (1.0, 1.0, 1.0), image, tile)
