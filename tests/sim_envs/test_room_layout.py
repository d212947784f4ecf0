"""The floor plan of a generated room: footprints, their overlap, the layout's fit, the walls' frames, drops."""

import numpy as np
import pytest

from sim_envs.scenes import furniture as fur
from sim_envs.scenes.room_layout import Drop, Layout, Rect, inward, wall_frame, yaw_facing, yaw_pose


def test_rect_corners_and_overlap() -> None:
    a = Rect(1.0, 1.0, 0.0, 0.5, 0.25)
    np.testing.assert_allclose(a.corners(), [[0.5, 0.75], [1.5, 0.75], [1.5, 1.25], [0.5, 1.25]])
    assert a.overlaps(Rect(1.9, 1.0, 0.0, 0.5, 0.5))  # 0.1 m into each other
    assert not a.overlaps(Rect(2.1, 1.0, 0.0, 0.5, 0.5))  # 0.1 m apart ...
    assert a.overlaps(Rect(2.1, 1.0, 0.0, 0.5, 0.5), grow=0.12)  # ... closed by growing this one 12 cm
    assert not a.overlaps(Rect(2.1, 1.0, 0.0, 0.5, 0.5), grow=0.08)
    assert not Rect(1.0, 1.0, 0.0, 0.5, 0.5, z1=0.5).overlaps(Rect(1.0, 1.0, 0.0, 0.5, 0.5, z0=0.6))


def test_layout_fits_inside_and_clear_of_what_is_placed() -> None:
    layout = Layout(np.array([4.0, 3.0, 2.5]))
    r = Rect(1.0, 1.0, np.pi / 4, 0.5, 0.5)
    assert layout.fits([r])
    layout.rects.append(r)
    assert not layout.fits([Rect(1.2, 1.0, 0.0, 0.3, 0.3)])
    assert not layout.fits([Rect(3.9, 1.0, 0.0, 0.3, 0.3)])  # through the wall at x = 4


@pytest.mark.parametrize("wall", range(4))
def test_walls_run_around_the_room_with_the_inside_on_their_left(wall: int) -> None:
    size = np.array([4.0, 3.0, 2.5])
    origin, tangent, length = wall_frame(wall, size)
    mid = origin + tangent * length / 2 + inward(tangent) * 0.5
    assert 0 < mid[0] < size[0] and 0 < mid[1] < size[1]
    front = yaw_pose(0.0, 0.0, 0.0, yaw_facing(inward(tangent)))[:3, 1]  # an assembly's front is +y
    np.testing.assert_allclose(front[:2], inward(tangent), atol=1e-12)


def test_a_tilted_drop_starts_with_no_corner_below_its_resting_height() -> None:
    a = fur.Assembly("box", [], (0.1, 0.1), 0.2, fur.SMALL)
    a.add_box("body", (0, 0, 0.1), (0.1, 0.1, 0.1), None)  # type: ignore[arg-type]
    T = yaw_pose(1.0, 1.0, 0.7, 0.0)
    assert Drop(a, T, 0.004).start_pose() is T
    start = Drop(a, T, 0.004, tilt=(0.4, -0.3)).start_pose()
    corners = fur.part_corners(a.parts[0]) @ start[:3, :3].T + start[:3, 3]
    assert corners[:, 2].min() == pytest.approx(0.7)
