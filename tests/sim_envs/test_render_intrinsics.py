"""Known answers for both renderers: exact pinhole projection (fx != fy, off-centre principal point) and planar depth.

The scene: a fronto-parallel wall 3 m in front of the camera and a box whose front face, 2 m away, projects to a
rectangle with edges at u = 40.25 / 100.75 and v = 30.25 / 90.75 (pixel centres at integers, OpenCV). A renderer
off by half a pixel (the usual OpenGL/OpenCV pixel-centre slip) would cover column 40 or row 30, or miss 100 or 90.
"""

import numpy as np
import pytest

from sim_envs.camera import Intrinsics
from sim_envs.frames import SemanticClass
from sim_envs.render import make_renderer
from sim_envs.scenes.scene import Material, Primitive, Scene

CAM = Intrinsics(fx=150.0, fy=110.0, cx=70.3, cy=65.8, width=160, height=120)
EYE = np.array([5.0, 1.0, 5.0])
# camera looks along world +y: x_cam = +x, y_cam = -z (down), z_cam = +y
T_WORLD_CAM = np.eye(4)
T_WORLD_CAM[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
T_WORLD_CAM[:3, 3] = EYE
U_EDGES, V_EDGES = (40.25, 100.75), (30.25, 90.75)
Z_WALL, Z_BOX = 3.0, 2.0


def _pose(t):
    T = np.eye(4)
    T[:3, 3] = t
    return T


def _scene() -> Scene:
    grey = Material("grey", (0.5, 0.5, 0.5))
    red = Material("red", (0.8, 0.1, 0.1))
    # camera-frame extents of the box's front face from the pixel edges: X = (u - cx) Z / fx, Y = (v - cy) Z / fy
    x0, x1 = ((u - CAM.cx) * Z_BOX / CAM.fx for u in U_EDGES)
    y0, y1 = ((v - CAM.cy) * Z_BOX / CAM.fy for v in V_EDGES)
    centre = EYE + np.array([(x0 + x1) / 2, Z_BOX + 0.1, -(y0 + y1) / 2])
    wall = Primitive("box", (5.0, 0.05, 5.0), _pose(EYE + [0, Z_WALL + 0.05, 0]), grey,
                     SemanticClass.VERTICAL_STRUCTURE, 0, "wall_0/slab")  # fmt: skip
    box = Primitive("box", ((x1 - x0) / 2, 0.1, (y1 - y0) / 2), _pose(centre), red,
                    SemanticClass.LARGE_STRUCTURE, 1, "cabinet_0/body")  # fmt: skip
    return Scene("known", 0, np.array([10.0, 10.0, 10.0]), (wall, box), (), 0.6)


@pytest.fixture(scope="module", params=["mujoco", "pyrender"])
def rendered(request):
    with make_renderer(_scene(), CAM, request.param) as renderer:
        yield request.param, renderer.render(T_WORLD_CAM)


def test_box_edges_project_where_K_says(rendered):
    backend, out = rendered
    box = out.instances == 1
    cols = np.flatnonzero(box[int(np.mean(V_EDGES))])
    rows = np.flatnonzero(box[:, int(np.mean(U_EDGES))])
    assert (cols.min(), cols.max()) == (41, 100), backend
    assert (rows.min(), rows.max()) == (31, 90), backend
    # the covered set is exactly the rectangle of pixel centres inside the projected face
    expected = np.zeros_like(box)
    expected[31:91, 41:101] = True
    np.testing.assert_array_equal(box, expected, err_msg=backend)


def test_planar_depth_is_exact(rendered):
    backend, out = rendered
    box = out.instances == 1
    wall = out.instances == 0
    assert wall.sum() + box.sum() == CAM.width * CAM.height  # every pixel hits a surface
    np.testing.assert_allclose(out.depth[box], Z_BOX, rtol=1e-4, err_msg=backend)
    np.testing.assert_allclose(out.depth[wall], Z_WALL, rtol=1e-4, err_msg=backend)
    assert out.depth.dtype == np.float32


def test_labels_follow_instances(rendered):
    _, out = rendered
    assert out.labels.dtype == np.uint8 and out.instances.dtype == np.int32
    assert (out.labels[out.instances == 1] == SemanticClass.LARGE_STRUCTURE).all()
    assert (out.labels[out.instances == 0] == SemanticClass.VERTICAL_STRUCTURE).all()


def test_camera_facing_away_sees_nothing():
    T = T_WORLD_CAM.copy()
    T[:3, :3] = T[:3, :3] @ np.diag([-1.0, 1.0, -1.0])  # turn 180 degrees about the camera's y axis
    for backend in ("mujoco", "pyrender"):
        with make_renderer(_scene(), CAM, backend) as renderer:
            out = renderer.render(T)
        assert (out.depth == 0).all() and (out.labels == 255).all() and (out.instances == -1).all(), backend
