"""Settling small objects with MuJoCo physics: known drops, and every object of generated rooms at rest on a surface."""

import numpy as np
import pytest

from sim_envs.frames import SemanticClass
from sim_envs.scenes.physics import FreeBody, settle_bodies
from sim_envs.scenes.scene import Material, Primitive
from sim_envs.scenes.scenegen import generate_scene

PLAIN = Material("plain", (0.5, 0.5, 0.5))
HUNG = {"poster", "whiteboard"}  # small-structure instances fixed to walls, never dropped


def _pose(t, rpy=(0.0, 0.0, 0.0)):
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T[:3, 3] = t
    return T


def _floor():
    return Primitive("box", (2.0, 2.0, 0.05), _pose([0, 0, -0.05]), PLAIN, SemanticClass.FLOOR, 0, "floor_0/slab")


def test_dropped_box_lands_flat_on_the_floor():
    body = FreeBody([("box", (0.1, 0.05, 0.03), np.eye(4))], _pose([0.2, -0.1, 0.3], (0.0, 0.0, 0.4)))
    result = settle_bodies([_floor()], [body])
    assert result.rested and result.valid.all()
    T = result.T_world_body[0]
    assert T[2, 3] == pytest.approx(0.03, abs=0.002)  # its half height above z = 0
    np.testing.assert_allclose(T[:3, 2], [0, 0, 1], atol=1e-3)  # still upright
    np.testing.assert_allclose(T[:2, 3], [0.2, -0.1], atol=1e-3)  # fell straight down


def test_tilted_cylinder_falls_over_and_stops_rolling():
    # a tall thin cylinder tilted by 30 degrees cannot stand: it ends lying on its side, at rest, radius above the floor
    body = FreeBody([("cylinder", (0.03, 0.15, 0.0), np.eye(4))], _pose([0, 0, 0.2], (0.52, 0.0, 0.0)))
    result = settle_bodies([_floor()], [body])
    assert result.rested and result.valid.all()
    T = result.T_world_body[0]
    assert abs(T[2, 2]) < 0.05  # axis horizontal
    assert T[2, 3] == pytest.approx(0.03, abs=0.003)
    assert np.linalg.norm(T[:2, 3]) < 0.5  # rolling friction stopped it


def test_object_that_leaves_the_room_is_invalid():
    body = FreeBody([("sphere", (0.05, 0.0, 0.0), np.eye(4))], _pose([5.0, 5.0, 0.5]))  # nothing below it
    result = settle_bodies([_floor()], [body], max_time=1.0)
    assert not result.valid[0]


def _objects(scene):
    """instance id -> primitives of the dropped small objects of a scene."""
    out = {}
    for p in scene.primitives:
        if p.semantic == SemanticClass.SMALL_STRUCTURE and p.instance_kind not in HUNG:
            out.setdefault(p.instance, []).append(p)
    return out


@pytest.fixture(scope="module", params=["office", "living"])
def settled(request):
    return generate_scene(request.param, 0)


def test_every_object_rests_on_a_surface_below_it(settled):
    boxes = np.array([p.aabb() for p in settled.primitives])
    instances = np.array([p.instance for p in settled.primitives])
    objects = _objects(settled)
    assert len(objects) >= 8
    bad = []
    for inst, prims in objects.items():
        verts = np.concatenate([p.mesh().vertices for p in prims])
        lo, hi = verts.min(0), verts.max(0)
        # surfaces under the object: anything else under its footprint whose top is not above its lowest point
        under = (
            (instances != inst)
            & (boxes[:, 0, 0] <= hi[0]) & (boxes[:, 1, 0] >= lo[0])
            & (boxes[:, 0, 1] <= hi[1]) & (boxes[:, 1, 1] >= lo[1])
            & (boxes[:, 1, 2] <= lo[2] + 0.006)
        )  # fmt: skip
        gap = lo[2] - boxes[under, 1, 2].max() if under.any() else np.inf
        if not -0.006 <= gap <= 0.015:  # not floating by more than 1.5 cm, not sunk by more than 6 mm
            bad.append((prims[0].name, float(gap)))
    assert not bad


def test_settled_objects_stay_put(settled):
    objects = _objects(settled)
    static = [p for p in settled.primitives if p.instance not in objects]
    bodies = []
    for prims in objects.values():
        T0 = prims[0].T_world_obj
        inv = np.linalg.inv(T0)
        bodies.append(FreeBody([(p.kind, p.size, inv @ p.T_world_obj) for p in prims], T0))
    result = settle_bodies(static, bodies, max_time=0.5)
    start = np.array([b.T_world_body[:3, 3] for b in bodies])
    moved = np.linalg.norm(result.T_world_body[:, :3, 3] - start, axis=1)
    assert moved.max() < 0.005
    assert result.valid.all()
