"""Lit rooms: lamps, shadows, highlights; geometry and ground truth untouched; known-answer fall-off and shadows."""

from dataclasses import replace

import numpy as np
import pytest

from sim_envs.camera import preset
from sim_envs.errors import SimEnvError
from sim_envs.frames import SemanticClass
from sim_envs.render import make_renderer
from sim_envs.scenes.lighting import light_room, window_panes
from sim_envs.scenes.scene import Lamp, Material, Primitive, Scene
from sim_envs.scenes.scenegen import generate_scene
from sim_envs.sequences import get_sequence
from sim_envs.sources.simsource import SimulatedSequence

CAM = preset("icl")  # 320 x 240


def _top_down(height: float) -> np.ndarray:
    """T_world_cam of a camera at (0, 0, height) looking straight down (image x = world x, image y = world -y)."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = (0.0, 0.0, height)
    return T


def _box(name: str, centre, half, instance: int, material: Material, semantic=SemanticClass.LARGE_STRUCTURE):
    T = np.eye(4)
    T[:3, 3] = centre
    return Primitive("box", tuple(half), T, material, semantic, instance, name)


def _floor_scene(lamps: tuple[Lamp, ...], occluder: bool = False) -> Scene:
    """A grey 6 m x 6 m floor slab (top face z = 0) centred on the origin, no ambient or directional light, ``lamps``;
    with ``occluder``, a 0.4 m cube floating 1 m above the origin."""
    grey = Material("grey", (0.5, 0.5, 0.5), None)
    prims = [_box("floor_0/slab", (0.0, 0.0, -0.05), (3.0, 3.0, 0.05), 0, grey, SemanticClass.FLOOR)]
    if occluder:
        prims.append(_box("box_0/body", (0.0, 0.0, 1.0), (0.2, 0.2, 0.2), 1, grey))
    return Scene("test", 0, np.array([6.0, 6.0, 3.0]), tuple(prims), (), 0.0, 1.0, "lit", lamps)


def _floor_xy(depth: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """World x, y of each pixel of a top-down view from ``height`` (pixels seeing the floor have depth == height)."""
    v, u = np.mgrid[0 : CAM.height, 0 : CAM.width]
    x = (u - CAM.cx) / CAM.fx * depth
    y = -(v - CAM.cy) / CAM.fy * depth
    return x, y


def test_a_spot_lamp_falls_off_with_the_inverse_square_and_the_cosine():
    # lamp 1 m above the floor pointing down, 1 / d^2 fall-off, no spot exponent: a floor point at horizontal
    # distance r gets I * cos(theta) / d^2 = I / (1 + r^2)^1.5 (Lambert's cosine is 1 / d)
    lamp = Lamp((0.0, 0.0, 1.0), (0.0, 0.0, -1.0), 85.0, 0.0, 1.0, (0.0, 0.0, 1.0), False)
    with make_renderer(_floor_scene((lamp,)), CAM, "mujoco") as renderer:
        out = renderer.render(_top_down(2.0), ("rgb", "depth"))
    grey = out.rgb.astype(float).mean(2)
    x, y = _floor_xy(out.depth, 2.0)
    r = np.hypot(x, y)
    centre = grey[r < 0.05].mean()
    assert 0.45 * 255 < centre < 0.55 * 255  # albedo 0.5 times gain 1
    for radius in (0.5, 1.0):
        ring = grey[np.abs(r - radius) < 0.03].mean()
        expected = (1 + radius**2) ** -1.5
        assert ring / centre == pytest.approx(expected, rel=0.08)


def test_an_object_between_a_lamp_and_the_floor_casts_a_shadow_where_geometry_says():
    lamp_on = Lamp((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), 80.0, 0.0, 1.0, (1.0, 0.0, 0.0), True)
    lamp_off = replace(lamp_on, shadows=False)
    # seen obliquely so the floor under the cube is visible beside it
    eye = np.array([2.0, 0.0, 1.5])
    z = -eye / np.linalg.norm(eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
    T[:3, 3] = eye
    images = {}
    for name, lamp in (("shadow", lamp_on), ("none", lamp_off)):
        with make_renderer(_floor_scene((lamp,), occluder=True), CAM, "mujoco") as renderer:
            images[name] = renderer.render(T, ("rgb", "depth", "instances"))
    out = images["shadow"]
    v, u = np.mgrid[0 : CAM.height, 0 : CAM.width]
    rays = np.stack([(u - CAM.cx) / CAM.fx, (v - CAM.cy) / CAM.fy, np.ones_like(u, float)], -1) * out.depth[..., None]
    world = rays @ T[:3, :3].T + T[:3, 3]
    floor = out.instances == 0
    # the cube's bottom (z = 0.8) and top (z = 1.2) project from the lamp at z = 2 onto the floor with half widths
    # 0.2 * 2 / 1.2 = 0.33 and 0.2 * 2 / 0.8 = 0.5: the floor within 0.3 of the origin is in shadow, beyond 0.6 lit
    inside = floor & (np.abs(world[..., 0]) < 0.3) & (np.abs(world[..., 1]) < 0.3)
    outside = floor & (np.max(np.abs(world[..., :2]), -1) > 0.6) & (np.max(np.abs(world[..., :2]), -1) < 1.5)
    assert inside.sum() > 200 and outside.sum() > 200
    shadowed, lit = out.rgb.astype(float).mean(2), images["none"].rgb.astype(float).mean(2)
    assert shadowed[inside].mean() < 0.1 * lit[inside].mean()
    assert np.abs(shadowed[outside] - lit[outside]).mean() < 2.0


@pytest.fixture(scope="module")
def rooms():
    flat = generate_scene("office", 1)
    return flat, light_room(flat)


def test_relighting_keeps_the_room_and_is_deterministic(rooms):
    flat, lit = rooms
    assert lit.lighting == "lit" and flat.lighting == "flat"
    assert len(lit.primitives) == len(flat.primitives)
    for a, b in zip(flat.primitives, lit.primitives, strict=True):
        assert (a.name, a.kind, a.size, a.instance, a.semantic) == (b.name, b.kind, b.size, b.instance, b.semantic)
        assert np.array_equal(a.T_world_obj, b.T_world_obj)
        assert a.material.rgb == b.material.rgb and a.material.texture is b.material.texture
    again = light_room(generate_scene("office", 1))
    assert again.lamps == lit.lamps
    assert [p.material.specular for p in again.primitives] == [p.material.specular for p in lit.primitives]
    assert light_room(lit) is lit
    assert generate_scene("office", 1, lighting="lit").lamps == lit.lamps


def test_every_window_gets_a_lamp_inside_the_room_aiming_in_and_down(rooms):
    flat, lit = rooms
    panes = window_panes(flat)
    assert len(panes) >= 1 and len(lit.lamps) == 1 + len(panes)
    size = np.asarray(flat.room_size)
    for lamp, (centre, inward, _) in zip(lit.lamps[1:], panes, strict=True):
        p, d = np.asarray(lamp.position), np.asarray(lamp.direction)
        assert np.all(p > 0) and np.all(p < size)
        assert np.dot(d[:2], inward[:2]) > 0.5 and d[2] < 0
        assert np.linalg.norm(p - centre) == pytest.approx(0.25)
    assert sum(lamp.shadows for lamp in lit.lamps) == 2  # the ceiling lamp and the first window's
    glowing = {p.material.name for p in lit.primitives if p.material.emission > 0}
    assert glowing == {p.material.name for _, _, p in panes}
    assert any(p.material.specular > 0 for p in lit.primitives)


def test_light_changes_colour_only(rooms):
    flat, lit = rooms
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looking along +x, level
    T[:3, 3] = (0.6, flat.room_size[1] / 2, 1.4)
    with make_renderer(flat, CAM, "mujoco") as a, make_renderer(lit, CAM, "mujoco") as b:
        fa, fb = a.render(T), b.render(T)
    # the lit meshes are split finer (MuJoCo lights per vertex): the same surfaces, depth equal to float32 rounding
    assert np.array_equal(fa.depth > 0, fb.depth > 0)
    assert np.allclose(fa.depth, fb.depth, rtol=1e-4, atol=0)
    assert np.mean(fa.instances == fb.instances) > 0.999 and np.mean(fa.labels == fb.labels) > 0.999
    assert np.abs(fa.rgb.astype(int) - fb.rgb.astype(int)).mean() > 5


def test_a_flat_scene_takes_no_lamps_and_pyrender_refuses_a_lit_one(rooms):
    flat, lit = rooms
    lamp = lit.lamps[0]
    with pytest.raises(SimEnvError, match="flat scene has no lamps"):
        Scene("test", 0, flat.room_size, flat.primitives, (), 0.4, 1.0, "flat", (lamp,))
    with pytest.raises(SimEnvError, match="lighting must be one of"):
        Scene("test", 0, flat.room_size, flat.primitives, (), 0.4, 1.0, "dim")
    with pytest.raises(SimEnvError, match="unit vector"):
        Lamp((0.0, 0.0, 1.0), (0.0, 0.0, -2.0), 45.0, 1.0, 1.0)
    with pytest.raises(SimEnvError, match="mujoco"):
        make_renderer(lit, CAM, "pyrender")
    spec = replace(get_sequence("office0"), lighting="lit", n_frames=5)
    with pytest.raises(SimEnvError, match="mujoco renderer only"):
        SimulatedSequence(spec, renderer="pyrender")
    with pytest.raises(SimEnvError, match="lighting must be one of"):
        replace(spec, lighting="dark")


def test_a_lit_sequence_is_deterministic_and_keeps_its_trajectory():
    spec = replace(get_sequence("office0"), lighting="lit", n_frames=30)
    a, b = SimulatedSequence(spec), SimulatedSequence(spec)
    assert a.rgb(7).tobytes() == b.rgb(7).tobytes()
    assert np.array_equal(a.poses, SimulatedSequence(replace(spec, lighting="flat")).poses)
