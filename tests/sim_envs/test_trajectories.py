import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim_envs.errors import SimEnvError, UnknownNameError
from sim_envs.motion.trajectories import (
    FPS,
    TRAJECTORY_KINDS,
    Trajectory,
    look_at,
    make_trajectory,
    parse_axes,
    sweep_angles,
)
from sim_envs.sources.simsource import cached_scene

N = 450  # 15 s at 30 Hz: long enough for several waypoints, quick to generate


@pytest.fixture(scope="module", params=[("office", 1), ("living", 2)], ids=["office", "living"])
def scene(request):
    return cached_scene(*request.param)


def _gen(kind, scene, seed=0, n=N, **params):
    return make_trajectory(kind, scene, np.random.default_rng(seed), n, **params)


def _acc(traj: Trajectory) -> np.ndarray:
    p, dt = traj.positions, 1.0 / FPS
    return np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=1) / dt**2


# ------------------------------------------------------------------------------------------------ the data class


def _line(n=5):
    ts = np.arange(n) / FPS
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, 0, 3] = 0.3 * ts
    T[:, :3, :3] = Rotation.from_euler("z", 30.0 * ts[:, None], degrees=True).as_matrix()
    return Trajectory(ts, T)


def test_trajectory_validates_and_is_read_only():
    traj = _line()
    with pytest.raises(ValueError):
        traj.T_world_cam[0, 0, 3] = 1.0
    T = traj.T_world_cam.copy()
    with pytest.raises(SimEnvError, match="strictly increasing"):
        Trajectory(np.array([0.0, 0.0, 1.0, 2.0, 3.0]), T)
    bad = T.copy()
    bad[2, :3, :3] *= 1.1
    with pytest.raises(SimEnvError, match="proper rotations"):
        Trajectory(traj.timestamps, bad)
    with pytest.raises(SimEnvError, match=r"\(N, 4, 4\)"):
        Trajectory(traj.timestamps, T[:3])


def test_pose_at_interpolates_and_clamps():
    traj = _line()
    np.testing.assert_allclose(traj.pose_at(traj.timestamps), traj.T_world_cam, atol=1e-12)
    mid = traj.pose_at(0.5 / FPS)
    assert mid.shape == (4, 4)
    # constant speeds: the midpoint is half way in translation and in angle
    assert mid[0, 3] == pytest.approx(0.3 * 0.5 / FPS, abs=1e-9)
    assert Rotation.from_matrix(mid[:3, :3]).as_euler("xyz", degrees=True)[2] == pytest.approx(0.5, abs=1e-6)
    np.testing.assert_allclose(traj.pose_at(-1.0), traj.T_world_cam[0])
    np.testing.assert_allclose(traj.pose_at(99.0), traj.T_world_cam[-1], atol=1e-12)
    assert traj.linear_speeds() == pytest.approx(np.full(4, 0.3))
    assert traj.angular_speeds_deg() == pytest.approx(np.full(4, 30.0))


def test_look_at_aims_the_optical_axis_with_image_y_down():
    eye = np.array([[1.0, 2.0, 1.5], [0.0, 0.0, 1.0]])
    target = np.array([[3.0, 2.5, 1.0], [-1.0, 1.0, 0.2]])
    R = look_at(eye, target).as_matrix()
    for k in range(2):
        d = (target[k] - eye[k]) / np.linalg.norm(target[k] - eye[k])
        np.testing.assert_allclose(R[k][:, 2], d, atol=1e-12)  # camera z = viewing direction
        assert R[k][2, 0] == pytest.approx(0.0, abs=1e-12)  # x axis horizontal: no roll
        assert R[k][2, 1] < 0  # camera y (image down) points down in the world
        assert np.linalg.det(R[k]) == pytest.approx(1.0)
    rolled = look_at(eye[0], target[0], roll_rad=np.radians(10.0)).as_matrix()[0]
    np.testing.assert_allclose(rolled[:, 2], R[0][:, 2], atol=1e-12)
    # roll turns the camera about its optical axis: x towards y (clockwise as seen from behind the camera)
    np.testing.assert_allclose(Rotation.from_matrix(R[0].T @ rolled).as_rotvec(), [0, 0, np.radians(10.0)], atol=1e-12)
    with pytest.raises(SimEnvError, match="parallel"):
        look_at(np.zeros(3), np.array([0.0, 0.0, -1.0]))


def test_sweep_runs_at_the_set_speed_within_the_amplitude():
    times = np.arange(3000) / 300.0  # fine sampling
    amp, speed = np.radians(30.0), np.radians(45.0)
    theta = sweep_angles(times, amp, speed)
    assert theta[0] == pytest.approx(0.0, abs=1e-9) and theta[1] > 0
    assert np.abs(theta).max() <= amp + 1e-9 and np.abs(theta).max() > 0.99 * amp
    rate = np.abs(np.diff(theta)) / np.diff(times)
    assert rate.max() == pytest.approx(speed, rel=0.01)
    assert np.mean(rate > 0.9 * speed) > 0.6  # most of the time at the set speed; smooth reversals


def test_unknown_kind_axes_and_params_are_named():
    with pytest.raises(UnknownNameError) as err:
        make_trajectory("zigzag", None, np.random.default_rng(0), 10)
    for kind in TRAJECTORY_KINDS:
        assert kind in str(err.value)
    with pytest.raises(SimEnvError, match="valid: .*speed"):
        make_trajectory("handheld", None, np.random.default_rng(0), 10, sped=0.2)
    assert parse_axes("rpy") == ("yaw", "pitch", "roll")
    assert parse_axes("roll+yaw") == ("yaw", "roll")
    with pytest.raises(UnknownNameError, match="yaw, pitch, roll"):
        parse_axes("yaw+spin")


# ---------------------------------------------------------------------------------------------- the generators


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_handheld_is_smooth_realistic_free_and_looks_at_content(scene, seed):
    traj = _gen("handheld", scene, seed=seed)
    assert len(traj) == N and traj.kind == "handheld"
    np.testing.assert_allclose(np.diff(traj.timestamps), 1.0 / FPS)
    speed = traj.linear_speeds()
    assert 0.1 <= speed.mean() <= 0.5 and speed.max() <= 0.6
    assert traj.angular_speeds_deg().max() <= 40.0
    assert _acc(traj).max() < 1.5  # m/s^2: no jumps
    p = traj.positions
    assert p[:, 2].min() >= 1.0 and p[:, 2].max() <= 1.8
    assert scene.free_space(p, margin=0.4).all()
    # the optical axis points at the target, which follows the scene's interest points
    axis = traj.T_world_cam[:, :3, 2]
    to_target = traj.targets - p
    dist = np.linalg.norm(to_target, axis=1)
    np.testing.assert_allclose(np.sum(axis * to_target, axis=1) / dist, 1.0, atol=1e-9)
    assert dist.min() > 0.5
    # small natural roll: the image x axis stays close to horizontal
    roll = np.degrees(np.arcsin(np.abs(traj.T_world_cam[:, 2, 0])))
    assert 0.0 < roll.max() < 10.0


def test_generation_is_seeded(scene):
    a, b, c = _gen("handheld", scene, seed=3), _gen("handheld", scene, seed=3), _gen("handheld", scene, seed=4)
    np.testing.assert_array_equal(a.T_world_cam, b.T_world_cam)
    assert np.abs(a.positions - c.positions).max() > 0.1


@pytest.mark.parametrize(("n", "seed"), [(600, 0), (900, 1), (1800, 2)])  # short loops look across, long ones inwards
def test_loop_returns_to_its_start(scene, n, seed):
    traj = _gen("loop", scene, seed=seed, n=n)
    p = traj.positions
    np.testing.assert_allclose(traj.T_world_cam[-1], traj.T_world_cam[0], atol=1e-9)
    assert np.linalg.norm(p - p[0], axis=1).max() > 1.0  # it really went somewhere
    assert scene.free_space(p, margin=0.4).all()
    assert 0.1 <= traj.linear_speeds().mean() <= 0.5
    assert traj.linear_speeds().max() <= 0.6 and traj.angular_speeds_deg().max() <= 40.0
    assert _acc(traj).max() < 1.5
    # the step from the last frame to the (virtual) next one is as small as any other step
    assert np.linalg.norm(p[1] - p[-1]) < 0.6 / FPS


@pytest.mark.parametrize("axes", ["yaw", "pitch", "roll", "rpy"])
def test_rotation_keeps_the_optical_centre_fixed(scene, axes):
    traj = _gen("rotation", scene, axes=axes, speed_deg_s=30.0)
    p = traj.positions
    assert (p == p[0]).all()  # exactly zero translation of the optical centre
    assert scene.free_space(p[:1], margin=0.5).all()
    w = traj.angular_speeds_deg()
    if axes == "rpy":
        assert 20.0 < w.mean() and w.max() < 1.25 * 30.0
    else:
        assert w.max() == pytest.approx(30.0, rel=0.02) and w.mean() > 0.8 * 30.0
    R = traj.T_world_cam[:, :3, :3]
    if axes == "yaw":  # panning about the vertical: the horizon stays level
        np.testing.assert_allclose(R[:, 2, 0], 0.0, atol=1e-9)
    if axes == "roll":  # rolling about the optical axis: the axis never moves
        np.testing.assert_allclose(R[:, :, 2], np.broadcast_to(R[0, :, 2], (N, 3)), atol=1e-9)
    if axes == "pitch":  # tilting about the camera x axis: x never moves
        np.testing.assert_allclose(R[:, :, 0], np.broadcast_to(R[0, :, 0], (N, 3)), atol=1e-9)


def test_rotation_speed_is_set(scene):
    for speed in (15.0, 60.0):
        w = _gen("rotation", scene, axes="yaw", speed_deg_s=speed).angular_speeds_deg()
        assert w.max() == pytest.approx(speed, rel=0.02)


def test_plane_near_translates_close_over_the_floor(scene):
    traj = _gen("plane_near", scene, n=900)
    p = traj.positions
    axis = traj.T_world_cam[:, :3, 2]
    along_axis = p[:, 2] / -axis[:, 2]  # distance along the optical axis to the floor plane z = 0
    assert along_axis.min() >= 0.5 and along_axis.max() <= 1.0
    assert traj.angular_speeds_deg().max() < 6.0  # mostly translation
    assert 0.05 < traj.linear_speeds().mean() < 0.3
    np.testing.assert_allclose(p[-1], p[0], atol=1e-9)  # with a loop
    np.testing.assert_allclose(traj.targets[:, 2], 0.0, atol=1e-9)


def test_far_structure_looks_2_to_4_m_away(scene):
    traj = _gen("far_structure", scene)
    dist = np.linalg.norm(traj.targets - traj.positions, axis=1)
    assert dist.min() >= 2.0 and dist.max() <= 4.0
    assert scene.free_space(traj.positions, margin=0.4).all()
    assert traj.linear_speeds().max() <= 0.5 and traj.angular_speeds_deg().max() <= 40.0


def test_low_texture_faces_a_wall_from_close(scene):
    traj = _gen("low_texture", scene)
    p, axis = traj.positions, traj.T_world_cam[:, :3, 2]
    size = np.asarray(scene.room_size)
    # distance along the optical axis to the room's box: the first wall plane hit
    with np.errstate(divide="ignore"):
        hit = np.where(axis > 0, (size - p) / axis, np.where(axis < 0, -p / axis, np.inf))
    first = hit.min(axis=1)
    assert first.min() > 0.8 and first.max() < 1.5
    assert (np.argmin(hit, axis=1) < 2).all()  # a wall (x or y), not the floor or ceiling
    assert scene.free_space(p, margin=0.4).all()
