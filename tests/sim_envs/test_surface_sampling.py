import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.errors import SimEnvError
from sim_envs.frames import SemanticClass
from sim_envs.scenes.scene import Material, Primitive, Scene
from sim_envs.scenes.surface_sampling import box_surface, cylinder_surface, sample_scene_surface, sphere_surface

MAT = Material("grey")


def _pose(t, rotvec_deg=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


def _scene() -> Scene:
    prims = (
        Primitive("box", (2.0, 1.5, 0.05), _pose((2.0, 1.5, -0.05)), MAT, SemanticClass.FLOOR, 0, "floor_0/slab"),
        Primitive("box", (0.5, 0.3, 0.4), _pose((1.0, 1.0, 0.4), (0, 0, 30)), MAT, SemanticClass.LARGE_STRUCTURE, 1,
                  "cabinet_0/body"),
        Primitive("cylinder", (0.04, 0.06, 0.0), _pose((1.0, 1.0, 0.86)), MAT, SemanticClass.SMALL_STRUCTURE, 2,
                  "cup_0/body"),
        Primitive("sphere", (0.1, 0.0, 0.0), _pose((3.0, 2.0, 0.1)), MAT, SemanticClass.SMALL_STRUCTURE, 3,
                  "ball_0/body"),
    )
    return Scene("test", 0, np.array([4.0, 3.0, 2.5]), prims)


def test_box_points_lie_on_the_faces_with_outward_normals_and_uniform_density():
    half = np.array([0.5, 0.3, 0.2])
    p, n = box_surface(half, 0.05)
    # every point is on one face: |coordinate| = half along the normal's axis, inside the face elsewhere
    axis = np.argmax(np.abs(n), axis=1)
    on_face = np.abs(np.abs(p[np.arange(len(p)), axis]) - half[axis]) < 1e-12
    assert on_face.all()
    assert np.all(np.abs(p) <= half + 1e-12)
    assert np.allclose(np.sign(p[np.arange(len(p)), axis]), n[np.arange(len(p)), axis])
    area = 8 * (half[0] * half[1] + half[1] * half[2] + half[0] * half[2])
    assert len(p) == pytest.approx(area / 0.05**2, rel=0.01)


def test_cylinder_and_sphere_points_are_on_the_analytic_surfaces():
    p, n = cylinder_surface(0.2, 0.3, 0.02)
    side = np.abs(n[:, 2]) < 0.5
    assert np.allclose(np.hypot(p[side, 0], p[side, 1]), 0.2)
    assert np.allclose(np.abs(p[~side, 2]), 0.3) and (np.hypot(p[~side, 0], p[~side, 1]) <= 0.2 + 1e-12).all()
    area = 2 * math.pi * 0.2 * 0.6 + 2 * math.pi * 0.2**2
    assert len(p) == pytest.approx(area / 0.02**2, rel=0.06)
    q, m = sphere_surface(0.1, 0.01)
    assert np.allclose(np.linalg.norm(q, axis=1), 0.1) and np.allclose(q / 0.1, m)
    assert len(q) == math.ceil(4 * math.pi * 0.01 / 0.01**2)


def test_scene_sampling_covers_every_primitive_with_its_label_and_instance():
    scene = _scene()
    s = sample_scene_surface(scene, 0.02)
    assert len(s) == s.points.shape[0] == s.labels.shape[0] == s.normals.shape[0]
    assert set(np.unique(s.primitives)) == set(range(len(scene.primitives)))
    for i, prim in enumerate(scene.primitives):
        mine = s.primitives == i
        assert (s.labels[mine] == int(prim.semantic)).all()
        assert (s.instances[mine] == prim.instance).all()
        # points within the primitive's bounds, and the rotated box's points on its rotated faces
        lo, hi = prim.aabb()
        assert (s.points[mine] >= lo - 1e-9).all() and (s.points[mine] <= hi + 1e-9).all()
    cab = s.primitives == 1
    local = (s.points[cab] - scene.primitives[1].T_world_obj[:3, 3]) @ scene.primitives[1].T_world_obj[:3, :3]
    assert np.allclose(np.max(np.abs(local) / np.array([0.5, 0.3, 0.4]), axis=1), 1.0)
    # the floor's top face is at z = 0 with normal +z
    top = (s.primitives == 0) & (s.normals[:, 2] > 0.9)
    assert np.allclose(s.points[top, 2], 0.0)
    assert np.allclose(np.linalg.norm(s.normals, axis=1), 1.0, atol=1e-6)


def test_jittered_sampling_is_reproducible_and_stays_on_the_surface():
    scene = _scene()
    a = sample_scene_surface(scene, 0.05, np.random.default_rng(3))
    b = sample_scene_surface(scene, 0.05, np.random.default_rng(3))
    c = sample_scene_surface(scene, 0.05)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)
    ball = a.primitives == 3
    assert np.allclose(np.linalg.norm(a.points[ball] - [3.0, 2.0, 0.1], axis=1), 0.1)
    sub = a.subset(a.labels == int(SemanticClass.FLOOR))
    assert len(sub) > 0 and (sub.labels == 0).all()


def test_bad_spacing_is_rejected():
    with pytest.raises(SimEnvError, match="spacing"):
        sample_scene_surface(_scene(), 0.0)
