"""Lit rooms: a generated room relit with lamps that cast shadows, bright windows and glossy surfaces.

A ``flat`` room (:mod:`sim_envs.scenes.scene`) is lit the same everywhere and looks the same from every view; a real
room is
not: it is bright by the windows and dark in the corners, objects cast shadows, polished surfaces show highlights that
move with the camera, and a camera turning from a wall to a window sees its brightness jump, which is what
auto-exposure (:mod:`sim_envs.sensor.camera_effects`) reacts to. :func:`light_room` turns a flat room into such a
``lit`` one:

- the flat model's ambient and directional lights at half strength (the fill light of a room);
- one spot lamp in front of every window, pointing into the room and down (daylight: the main light near the
  windows, falling off with the square of the distance), and one ceiling lamp pointing down;
- shadows from the ceiling lamp and the first window's lamp (shadow maps; each costs a render pass per frame);
- window panes that glow (emission), and a share of furniture and object materials, and maybe the floor, made glossy
  (Phong specular highlights).

All draws come from ``default_rng((scene.seed, LIGHTING_STREAM))``, so the same room gets the same lights, and the
room's geometry, textures and labels are untouched. Only the MuJoCo renderer draws lamps, shadows and highlights (its
OpenGL pipeline has them); the pyrender backend bakes the flat model into vertex colours and refuses a lit scene.

Magnitudes are ours, chosen for what the room should show, not fitted to any result: a wall 1 m from a window
about 4x brighter than one 4 m away (inverse-square fall-off with a near-field floor), highlights at most a third of
full scale.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sim_envs.scenes.scene import Lamp, Light, Material, Primitive, Scene

LIGHTING_STREAM = 17  # stream of the scene seed the lighting draws from (ours; the generator uses the plain seed)
FILL_SCALE = 0.5  # the flat model's ambient and directional lights are kept at this share (ours)
WINDOW_ATTENUATION = (0.5, 0.0, 0.3)  # 1 / (c + l d + q d^2): 1.25 at 1 m, 0.59 at 2 m, 0.19 at 4 m (ours)
CEILING_ATTENUATION = (0.4, 0.0, 0.12)  # 0.87 at 2.5 m below the lamp (ours)
WINDOW_EMISSION = 0.6  # a pane's own light: a window is the brightest thing in the room (ours)
GLOSSY_SHARE = 0.35  # share of furniture/object materials made glossy (ours)
STRUCTURE = frozenset({"floor", "ceiling", "wall", "window", "door"})


def _unit(v: np.ndarray) -> tuple[float, float, float]:
    v = np.asarray(v, dtype=np.float64)
    return tuple(float(x) for x in v / np.linalg.norm(v))  # type: ignore[return-value]


def window_panes(scene: Scene) -> list[tuple[np.ndarray, np.ndarray, Primitive]]:
    """The window panes of ``scene``: ``(centre (3,), inward unit normal (3,), primitive)`` per pane, in scene order.

    The inward normal is the pane's thin axis, signed to point into the room (towards the room's centre).
    """
    centre = np.asarray(scene.room_size, dtype=np.float64) / 2
    out = []
    for p in scene.primitives:
        if p.instance_kind != "window" or not p.name.endswith("/pane"):
            continue
        T = np.asarray(p.T_world_obj, dtype=np.float64)
        thin = int(np.argmin(p.size))
        n = T[:3, thin].copy()
        n[2] = 0.0
        n /= np.linalg.norm(n)
        if np.dot(n, centre - T[:3, 3]) < 0:
            n = -n
        out.append((T[:3, 3].copy(), n, p))
    return out


def window_lamp(centre: np.ndarray, inward: np.ndarray, intensity: float, shadows: bool) -> Lamp:
    """Daylight through a window: a spot 0.25 m in front of the pane at ``centre``, aimed into the room and down
    (35 deg below the horizontal), a 70 deg cone, the :data:`WINDOW_ATTENUATION` fall-off."""
    position = np.asarray(centre, dtype=np.float64) + 0.25 * np.asarray(inward, dtype=np.float64)
    direction = np.asarray(inward, dtype=np.float64) + np.array([0.0, 0.0, -np.tan(np.radians(35.0))])
    return Lamp(tuple(float(x) for x in position), _unit(direction), 70.0, 1.0, float(intensity),  # type: ignore[arg-type]
                WINDOW_ATTENUATION, shadows)  # fmt: skip


def light_room(scene: Scene) -> Scene:
    """``scene`` relit (module docstring): a ``lit`` scene with the same primitives' geometry, classes and instances.

    Returns ``scene`` itself when it is already lit. Deterministic in ``scene.seed``.
    """
    if scene.lighting == "lit":
        return scene
    rng = np.random.default_rng((int(scene.seed), LIGHTING_STREAM))
    size = np.asarray(scene.room_size, dtype=np.float64)
    lamps = []
    ceiling = np.array([rng.uniform(0.35, 0.65) * size[0], rng.uniform(0.35, 0.65) * size[1], size[2] - 0.1])
    lamps.append(Lamp(tuple(float(x) for x in ceiling), (0.0, 0.0, -1.0), 80.0, 1.0,  # type: ignore[arg-type]
                      float(rng.uniform(0.5, 0.7)), CEILING_ATTENUATION, True))  # fmt: skip
    panes = window_panes(scene)
    for k, (centre, inward, _) in enumerate(panes):
        lamps.append(window_lamp(centre, inward, float(rng.uniform(0.8, 1.1)), shadows=k == 0))

    # materials: panes glow, some furniture/object materials and maybe the floor turn glossy (drawn in scene order)
    kinds: dict[int, set[str]] = {}
    for p in scene.primitives:
        kinds.setdefault(id(p.material), set()).add(p.instance_kind)
    pane_materials = {id(p.material) for _, _, p in panes}
    glossy_floor = bool(rng.random() < 0.5)
    new: dict[int, Material] = {}
    for mat in scene.materials():
        used_by = kinds[id(mat)]
        if id(mat) in pane_materials:
            new[id(mat)] = replace(mat, emission=WINDOW_EMISSION)
        elif used_by <= {"floor"}:
            draw = (rng.uniform(0.15, 0.3), rng.uniform(0.5, 0.8))
            new[id(mat)] = replace(mat, specular=float(draw[0]), shininess=float(draw[1])) if glossy_floor else mat
        elif not used_by & STRUCTURE:
            glossy, spec, shine = rng.random() < GLOSSY_SHARE, rng.uniform(0.2, 0.35), rng.uniform(0.4, 0.8)
            new[id(mat)] = replace(mat, specular=float(spec), shininess=float(shine)) if glossy else mat
        else:
            new[id(mat)] = mat
    primitives = tuple(p if new[id(p.material)] is p.material else replace(p, material=new[id(p.material)])
                       for p in scene.primitives)  # fmt: skip
    fill = tuple(Light(light.direction, light.intensity * FILL_SCALE) for light in scene.lights)
    return Scene(scene.style, scene.seed, scene.room_size, primitives, fill, scene.ambient * FILL_SCALE,
                 scene.texture_density, "lit", tuple(lamps), scene.detail)  # fmt: skip
