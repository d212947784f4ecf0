"""The scene description: primitive meshes (geometry, normals, texture coordinates), bounds, free space."""

import numpy as np
import pytest

from sim_envs.errors import SimEnvError
from sim_envs.frames import SemanticClass
from sim_envs.scenes.scene import Light, Material, Primitive, Scene, box_mesh, cylinder_mesh, sphere_mesh

PLAIN = Material("plain", (0.5, 0.5, 0.5))


def _pose(t, yaw=0.0):
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = t
    return T


def _outward_and_ccw(mesh):
    v, f = mesh.vertices, mesh.faces
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    tri_centre = v[f].mean(1)
    return (np.einsum("ij,ij->i", cross, tri_centre) > 0).all()  # meshes are centred on the origin


@pytest.mark.parametrize(
    "mesh, extent",
    [
        (box_mesh(np.array([0.5, 1.0, 1.5])), [0.5, 1.0, 1.5]),
        (cylinder_mesh(0.3, 0.7), [0.3, 0.3, 0.7]),
        (sphere_mesh(0.4), [0.4, 0.4, 0.4]),
    ],
)
def test_meshes_have_the_right_extent_unit_normals_and_outward_faces(mesh, extent):
    np.testing.assert_allclose(mesh.vertices.max(0), extent, atol=1e-9)
    np.testing.assert_allclose(mesh.vertices.min(0), -np.array(extent), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-9)
    assert _outward_and_ccw(mesh)
    assert mesh.faces.dtype == np.int32 and mesh.faces.max() < len(mesh.vertices)


def test_box_texture_runs_upright_and_unmirrored_on_side_faces():
    mesh = box_mesh(np.array([1.0, 0.5, 0.75]), tile_m=None)
    # the face seen from -y (normal -y): u grows to the viewer's right (+x), v grows upward (+z), 0..1 over the face
    on_face = np.isclose(mesh.normals @ [0, -1, 0], 1.0)
    v, uv = mesh.vertices[on_face], mesh.uv[on_face]
    np.testing.assert_allclose(uv[:, 0], (v[:, 0] + 1.0) / 2.0)
    np.testing.assert_allclose(uv[:, 1], (v[:, 2] + 0.75) / 1.5)
    # the face seen from +x: the viewer's right is +y
    on_face = np.isclose(mesh.normals @ [1, 0, 0], 1.0)
    np.testing.assert_allclose(mesh.uv[on_face][:, 0], (mesh.vertices[on_face][:, 1] + 0.5) / 1.0)


def test_tile_size_sets_texture_repeats_per_metre():
    mesh = box_mesh(np.array([1.0, 0.5, 0.75]), tile_m=0.5)
    on_face = np.isclose(mesh.normals @ [0, -1, 0], 1.0)
    assert np.ptp(mesh.uv[on_face][:, 0]) == pytest.approx(2.0 / 0.5)
    assert np.ptp(mesh.uv[on_face][:, 1]) == pytest.approx(1.5 / 0.5)


def test_primitive_mesh_and_aabb_follow_the_pose():
    box = Primitive(
        "box", (0.5, 0.2, 0.1), _pose([1.0, 2.0, 3.0], np.pi / 2), PLAIN, SemanticClass.SMALL_STRUCTURE, 0, "box_0/b"
    )
    np.testing.assert_allclose(box.aabb(), [[0.8, 1.5, 2.9], [1.2, 2.5, 3.1]], atol=1e-12)
    mesh = box.mesh()
    np.testing.assert_allclose(mesh.vertices.min(0), [0.8, 1.5, 2.9], atol=1e-12)
    cyl = Primitive(
        "cylinder", (0.1, 0.3, 0.0), _pose([0.0, 0.0, 1.0]), PLAIN, SemanticClass.SMALL_STRUCTURE, 0, "c_0/c"
    )
    np.testing.assert_allclose(cyl.aabb(), [[-0.1, -0.1, 0.7], [0.1, 0.1, 1.3]], atol=1e-12)
    assert box.instance_kind == "box"


def test_bad_primitives_and_materials_are_rejected():
    with pytest.raises(SimEnvError, match="kind"):
        Primitive("cone", (1, 1, 1), np.eye(4), PLAIN, SemanticClass.FLOOR, 0, "x_0/x")
    with pytest.raises(SimEnvError, match="positive half sizes"):
        Primitive("box", (1, 0, 1), np.eye(4), PLAIN, SemanticClass.FLOOR, 0, "x_0/x")
    with pytest.raises(SimEnvError, match="rgb"):
        Material("bad", (1.5, 0, 0))
    with pytest.raises(SimEnvError, match="uint8"):
        Material("bad", texture=np.zeros((4, 4, 3), np.float32))


def _tiny_scene():
    prims = (
        Primitive("box", (2.0, 2.0, 0.05), _pose([2, 2, -0.05]), PLAIN, SemanticClass.FLOOR, 0, "floor_0/slab"),
        Primitive(
            "box", (0.5, 0.3, 0.4), _pose([1.0, 1.0, 0.4]), PLAIN, SemanticClass.LARGE_STRUCTURE, 1, "cabinet_0/b"
        ),
        Primitive(
            "box", (0.05, 0.05, 0.05), _pose([1.0, 1.0, 0.85]), PLAIN, SemanticClass.SMALL_STRUCTURE, 2, "box_0/b"
        ),
    )
    return Scene("tiny", 0, np.array([4.0, 4.0, 2.5]), prims, (Light((0.0, 0.0, -1.0), 0.4),), 0.5)


def test_scene_queries():
    scene = _tiny_scene()
    np.testing.assert_array_equal(scene.instance_classes(), [0, 2, 3])
    assert scene.instance_names() == ["floor_0", "cabinet_0", "box_0"]
    np.testing.assert_allclose(scene.bounds(), [[0, 0, -0.1], [4, 4, 0.9]])
    # one point per non-structure instance: top centre of furniture, centre of objects
    np.testing.assert_allclose(scene.interest_points(), [[1.0, 1.0, 0.8], [1.0, 1.0, 0.85]])


def test_free_space_keeps_margins_from_room_and_furniture():
    scene = _tiny_scene()
    pts = np.array(
        [
            [3.0, 3.0, 1.5],  # open space
            [0.1, 3.0, 1.5],  # too close to a wall
            [3.0, 3.0, 2.4],  # too close to the ceiling
            [1.0, 1.0, 1.0],  # above the cabinet, within the margin of the object on it
            [1.0, 1.0, 1.4],  # above the cabinet, clear
            [5.0, 1.0, 1.0],  # outside the room
        ]
    )
    np.testing.assert_array_equal(scene.free_space(pts, margin=0.3), [True, False, False, False, True, False])


def test_shade_is_ambient_plus_lambert():
    scene = _tiny_scene()
    np.testing.assert_allclose(scene.shade(np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 0, -1.0]])), [0.9, 0.5, 0.5])


def test_instance_ids_must_be_contiguous_and_single_class():
    a, b, c = _tiny_scene().primitives
    with pytest.raises(SimEnvError, match="without gaps"):
        Scene("x", 0, np.ones(3), (a, c))
    bad = Primitive("box", (1, 1, 1), np.eye(4), PLAIN, SemanticClass.SMALL_STRUCTURE, 1, "cabinet_0/other")
    with pytest.raises(SimEnvError, match="mixes"):
        Scene("x", 0, np.ones(3), (a, b, bad))


@pytest.mark.parametrize("mesh", [box_mesh(np.array([2.5, 0.05, 1.4])), cylinder_mesh(0.3, 0.9)], ids=["wall", "cyl"])
def test_subdividing_a_mesh_keeps_its_surface_and_splits_shared_edges_alike(mesh):
    def area(m):
        a, b, c = (m.vertices[m.faces[:, k]] for k in range(3))
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()

    fine = mesh.subdivided(0.3)
    edges = np.concatenate([fine.faces[:, [0, 1]], fine.faces[:, [1, 2]], fine.faces[:, [2, 0]]])
    assert np.linalg.norm(fine.vertices[edges[:, 0]] - fine.vertices[edges[:, 1]], axis=1).max() <= 0.3
    assert area(fine) == pytest.approx(area(mesh), rel=1e-9)  # planar faces: the same surface
    assert np.allclose(np.linalg.norm(fine.normals, axis=1), 1.0)
    # no T-junctions: a closed mesh stays closed, every edge (by its end points) shared by exactly two triangles
    def open_edges(m):
        pairs = np.round(m.vertices[np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]])], 9)
        keys = [tuple(sorted((tuple(a), tuple(b)))) for a, b in pairs]
        counts: dict = {}
        for k in keys:
            counts[k] = counts.get(k, 0) + 1
        return sum(c != 2 for c in counts.values())

    assert open_edges(mesh) == 0 and open_edges(fine) == 0
    assert mesh.subdivided(100.0).faces.shape == mesh.faces.shape
