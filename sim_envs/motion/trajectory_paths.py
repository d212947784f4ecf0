"""The steps the trajectory generators of :mod:`sim_envs.motion.trajectories` build camera paths from: scene queries
(the
room's box, its interest points, free points and segments), target picking, the acceptance check and :func:`drive`
(the camera driven through waypoints, slowed down until it keeps the limits), waypoint walks and rings, and the
floor grid of the close-to-a-plane path. Same generator state, same path.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from sim_envs.errors import SimEnvError
from sim_envs.motion.trajectory_core import MAX_ATTEMPTS, SceneLike, Trajectory, look_at, poses_from

# --------------------------------------------------------------------------------------------------------------------
# Scene queries


def room_box(scene: SceneLike) -> tuple[np.ndarray, np.ndarray]:
    """The room's interior box ``[0, room_size]`` (scene convention; ``bounds()`` also holds the walls' thickness)."""
    size = np.asarray(scene.room_size, dtype=np.float64)
    return np.zeros(3), size


def interest(scene: SceneLike) -> np.ndarray:
    pts = np.asarray(scene.interest_points(), dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 0:
        raise SimEnvError("the scene has no interest points: nothing for a camera to look at")
    return pts


def segment_free(scene: SceneLike, a: np.ndarray, b: np.ndarray, margin: float, step: float = 0.1) -> bool:
    n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    return bool(np.all(scene.free_space(pts, margin=margin)))


def random_free_point(
    scene: SceneLike, rng: np.random.Generator, z_range: tuple[float, float], margin: float, tries: int = 400
) -> np.ndarray | None:
    lo, hi = room_box(scene)
    pts = np.column_stack(
        [
            rng.uniform(lo[0] + margin, hi[0] - margin, tries),
            rng.uniform(lo[1] + margin, hi[1] - margin, tries),
            rng.uniform(z_range[0], z_range[1], tries),
        ]
    )
    ok = np.flatnonzero(scene.free_space(pts, margin=margin))
    return None if ok.size == 0 else pts[ok[0]]


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in radians between direction vectors a and b (..., 3)."""
    return np.arccos(np.clip(np.sum(unit(a) * unit(b), axis=-1), -1.0, 1.0))


def pick_target(
    rng: np.random.Generator,
    eye: np.ndarray,
    points: np.ndarray,
    distance: tuple[float, float],
    prev_dir: np.ndarray | None,
    max_turn_rad: float,
    preferred_dir: np.ndarray | None = None,
    max_off_preferred_rad: float = np.pi,
    max_pitch_rad: float = np.radians(55.0),
) -> np.ndarray | None:
    """A random interest point in the distance band, not steeper than ``max_pitch_rad``, within ``max_turn_rad`` of
    the previous viewing direction and ``max_off_preferred_rad`` of a preferred one (each where given)."""
    d = points - eye
    dist = np.linalg.norm(d, axis=1)
    ok = (dist >= distance[0]) & (dist <= distance[1])
    pitch = np.arcsin(np.clip(d[:, 2] / np.maximum(dist, 1e-9), -1.0, 1.0))
    ok &= np.abs(pitch) <= max_pitch_rad
    if prev_dir is not None:
        ok &= angle_between(d, prev_dir[None, :]) <= max_turn_rad
    if preferred_dir is not None:
        ok &= angle_between(d, preferred_dir[None, :]) <= max_off_preferred_rad
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None
    return points[rng.choice(idx)]


def accept(
    scene: SceneLike,
    eye: np.ndarray,
    rot: Rotation,
    times: np.ndarray,
    margin: float,
    max_speed: float,
    max_angular_speed_deg: float,
    z_range: tuple[float, float] | None,
) -> tuple[bool, bool]:
    """(path is free and within heights, speeds are within limits) for sampled eye positions and rotations."""
    free = bool(np.all(scene.free_space(eye, margin=margin)))
    if z_range is not None:
        free &= bool(np.all((eye[:, 2] >= z_range[0] - 1e-9) & (eye[:, 2] <= z_range[1] + 1e-9)))
    dt = np.diff(times)
    lin = np.linalg.norm(np.diff(eye, axis=0), axis=1) / dt
    ang = np.degrees((rot[:-1].inv() * rot[1:]).magnitude()) / dt
    return free, bool(lin.max() <= max_speed and ang.max() <= max_angular_speed_deg)


SLOW_DOWNS = (1.0, 1.3, 1.7, 2.2, 3.0)  # factors on a hand-held walk's segment durations, tried in turn (ours)


@dataclass(frozen=True)
class Limits:
    """What a driven path must keep to: ``margin`` (m) from every surface, heights within ``height_range`` (m, None:
    any), speeds within ``max_speed`` (m/s) and ``max_angular_speed_deg`` (deg/s)."""

    margin: float
    max_speed: float
    max_angular_speed_deg: float
    height_range: tuple[float, float] | None


def drive(
    scene: SceneLike,
    times: np.ndarray,
    eyes: np.ndarray,
    targets: np.ndarray,
    durations: np.ndarray,
    roll: np.ndarray,
    limits: Limits,
    kind: str,
    *,
    slow_downs: Sequence[float] = (1.0,),
    lap: float | None = None,
) -> Trajectory | None:
    """The camera driven through waypoints ``eyes`` (K, 3) while aiming at ``targets`` (K, 3), with roll ``roll``
    (N,) radians, sampled at ``times`` (N,), if it is accepted (:func:`accept` under ``limits``); else None.

    ``durations`` (K-1,): seconds per segment. Open paths (``lap`` None): natural cubic splines through knots at
    ``durations * slow_down`` for each factor of ``slow_downs`` in turn, until the speeds are within the limits;
    None as soon as the path is blocked, or the knots end before the last frame (the walk is too short). Closed
    loops (``lap`` seconds per lap; the last waypoint repeats the first): periodic splines through knots spread
    over one lap in proportion to ``durations``, the last frame set to the first pose exactly.
    """
    for slow_down in slow_downs:
        if lap is None:
            knots = times[0] + np.concatenate([[0.0], np.cumsum(durations * slow_down)])
            if knots[-1] < times[-1]:
                return None  # the walk is too short for this duration: draw a longer one
            eye = CubicSpline(knots, eyes, bc_type="natural")(times)
            tgt = CubicSpline(knots, targets, bc_type="natural")(times)
        else:
            knots = np.concatenate([[0.0], np.cumsum(durations)]) * (lap / durations.sum())
            phase = np.mod(times - times[0], lap)
            phase[-1] = knots[-1]  # the last frame closes the loop exactly
            eye = CubicSpline(knots, eyes, bc_type="periodic")(phase)
            tgt = CubicSpline(knots, targets, bc_type="periodic")(phase)
            eye[-1], tgt[-1] = eye[0], tgt[0]
        rot = look_at(eye, tgt, roll_rad=roll)
        free, slow = accept(scene, eye, rot, times, limits.margin, limits.max_speed, limits.max_angular_speed_deg,
                             limits.height_range)
        if not free:
            return None
        if slow:
            return Trajectory(times, poses_from(eye, rot), kind=kind, targets=tgt)
    return None


# --------------------------------------------------------------------------------------------------------------------
# Internals of the generators


def check_speed(speed: float, max_speed: float) -> None:
    if not 0 < speed < max_speed:
        raise SimEnvError(f"need 0 < speed < max_speed (m/s), got speed={speed}, max_speed={max_speed}")


def gave_up(kind: str, scene: SceneLike) -> str:
    size = np.round(np.asarray(scene.room_size, dtype=float), 2).tolist()
    return (
        f"could not generate a {kind!r} trajectory in a room of size {size} m after {MAX_ATTEMPTS} attempts "
        "(too little free space for the requested margins and speeds); try another seed or relax the parameters"
    )


def waypoint_walk(
    scene: SceneLike, rng: np.random.Generator, length: float, z_range: tuple[float, float], margin: float
) -> np.ndarray | None:
    """(K, 3) random walk of free waypoints 0.5-1.2 m apart, joined by free straight segments, of total length
    >= ``length`` m; headings change by at most 100 degrees per step, or (when that gets stuck, in small rooms)
    turn around with steps of 0.3-0.8 m. None when the walk gets stuck altogether."""
    start = random_free_point(scene, rng, z_range, margin)
    if start is None:
        return None
    walk = [start]
    heading = rng.uniform(0, 2 * np.pi)
    total = 0.0
    while total < length:
        for attempt in range(60):
            wide = attempt >= 30
            h = heading + rng.uniform(-1.0, 1.0) * np.radians(180.0 if wide else 100.0)
            step = rng.uniform(0.3, 0.8) if wide else rng.uniform(0.5, 1.2)
            nxt = walk[-1] + np.array([step * np.cos(h), step * np.sin(h), 0.0])
            nxt[2] = rng.uniform(*z_range)
            if scene.free_space(nxt[None, :], margin=margin)[0] and segment_free(scene, walk[-1], nxt, margin):
                walk.append(nxt)
                heading = h
                total += float(np.linalg.norm(nxt - walk[-2]))
                break
        else:
            return None
    return np.asarray(walk)


def targets_for(
    rng: np.random.Generator, eyes: np.ndarray, points: np.ndarray, distance: tuple[float, float]
) -> np.ndarray | None:
    """One interest point per eye waypoint, turning at most 60 degrees from one to the next."""
    targets: list[np.ndarray] = []
    prev_dir = None
    for eye in eyes:
        tgt = pick_target(rng, eye, points, distance, prev_dir, np.radians(60.0))
        if tgt is None:
            return None
        targets.append(tgt)
        prev_dir = tgt - eye
    return np.asarray(targets)


def segment_durations(eyes: np.ndarray, targets: np.ndarray, speed: float, mean_ang_rate: float) -> np.ndarray:
    """(K-1,) seconds per waypoint segment: enough for the translation at ``speed`` (m/s) and for the change of
    viewing direction at ``mean_ang_rate`` (rad/s)."""
    lengths = np.linalg.norm(np.diff(eyes, axis=0), axis=1)
    dirs = targets - eyes
    turns = angle_between(dirs[:-1], dirs[1:])
    return np.maximum(np.maximum(lengths / speed, turns / mean_ang_rate), 0.2)


def ring(
    scene: SceneLike,
    rng: np.random.Generator,
    centre: np.ndarray,
    n: int,
    z_range: tuple[float, float],
    margin: float,
    radius: float,
) -> np.ndarray | None:
    """(n, 3) free waypoints around ``centre`` at evenly spaced angles (jittered), each at a random free distance
    of 0.6-1.4 x ``radius`` (m, within 30-90 % of the way to the wall) and a free height in ``z_range``, joined to
    the previous one (and the last to the first) by a free straight segment; None when none is found in this draw."""
    lo, hi = room_box(scene)
    theta0 = rng.uniform(0, 2 * np.pi)
    eyes: list[np.ndarray] = []
    for k in range(n):
        chosen = None
        for _ in range(4):  # a few jittered rays per waypoint
            th = theta0 + 2 * np.pi * (k + rng.uniform(-0.3, 0.3)) / n
            d = np.array([np.cos(th), np.sin(th)])
            with np.errstate(divide="ignore"):
                t_wall = np.min(
                    np.where(d > 0, (hi[:2] - centre[:2]) / d, np.where(d < 0, (lo[:2] - centre[:2]) / d, np.inf))
                )
            r_lo, r_hi = max(0.3 * t_wall, 0.6 * radius), min(0.9 * t_wall, 1.4 * radius)
            if r_lo > r_hi:
                r_lo = r_hi = min(max(radius, 0.3 * t_wall), 0.9 * t_wall)
            dists, zs = np.meshgrid(np.linspace(r_lo, r_hi, 9), np.linspace(z_range[0], z_range[1], 4))
            order = rng.permutation(dists.size)
            dists, zs = dists.ravel()[order], zs.ravel()[order]
            cands = np.column_stack([centre[0] + dists * d[0], centre[1] + dists * d[1], zs])
            for idx in np.flatnonzero(scene.free_space(cands, margin=margin)):
                if not eyes or segment_free(scene, eyes[-1], cands[idx], margin):
                    chosen = cands[idx]
                    break
            if chosen is not None:
                break
        if chosen is None:
            return None
        eyes.append(chosen)
    if not segment_free(scene, eyes[-1], eyes[0], margin):
        return None
    return np.asarray(eyes)


def ring_targets(
    rng: np.random.Generator,
    eyes: np.ndarray,
    centre: np.ndarray,
    focus: np.ndarray | None,
    points: np.ndarray,
    distance: tuple[float, float],
) -> np.ndarray:
    """One look-at point per ring waypoint: an interest point within 70 degrees of the inward direction (towards
    ``centre``), or 45 degrees of the direction to ``focus`` when given, preferably within 40 degrees of the previous
    viewing direction; where no interest point qualifies, the anchor (centre or focus) at table height."""
    targets: list[np.ndarray] = []
    prev_dir = None
    anchor = np.array(centre if focus is None else focus, dtype=np.float64)
    anchor[2] = 0.8
    off = np.radians(70.0 if focus is None else 45.0)
    for eye in eyes:
        preferred = anchor - eye
        preferred[2] = 0.0
        tgt = pick_target(rng, eye, points, distance, prev_dir, np.radians(40.0), preferred, off)
        if tgt is None:
            tgt = pick_target(rng, eye, points, distance, None, np.pi, preferred, off)
        if tgt is None:
            tgt = anchor
        targets.append(tgt)
        prev_dir = tgt - eye
    return np.asarray(targets)


def free_point_near(scene: SceneLike, rng: np.random.Generator, point: np.ndarray, margin: float) -> np.ndarray | None:
    """The free point (at ``point``'s height) nearest to ``point`` among random candidates, or None."""
    lo, hi = room_box(scene)
    cands = np.column_stack(
        [
            rng.uniform(lo[0] + margin, hi[0] - margin, 300),
            rng.uniform(lo[1] + margin, hi[1] - margin, 300),
            np.full(300, point[2]),
        ]
    )
    ok = np.flatnonzero(scene.free_space(cands, margin=margin))
    if ok.size == 0:
        return None
    dist = np.linalg.norm(cands[ok, :2] - point[:2], axis=1)
    return cands[ok[np.argmin(dist)]]


class FloorGrid:
    """Which floor cells (``res`` m squares) have nothing but air above them from 0.15 m up to ``z_top`` (checked
    with ``free_space`` at a 0.1 m margin, so walls and furniture edges count as blocked)."""

    def __init__(self, scene: SceneLike, z_top: float, res: float = 0.1) -> None:
        size = np.asarray(scene.room_size, dtype=np.float64)
        self.res = res
        self.xs = np.arange(res / 2, size[0], res)
        self.ys = np.arange(res / 2, size[1], res)
        zs = np.arange(0.15, z_top + 1e-9, 0.15)
        gx, gy, gz = np.meshgrid(self.xs, self.ys, zs, indexing="ij")
        free = scene.free_space(np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()]), margin=0.1)
        self.clear = free.reshape(gx.shape).all(axis=2)

    def rectangles(
        self, u_range: tuple[float, float], v_range: tuple[float, float], headings: np.ndarray
    ) -> list[tuple[np.ndarray, float]]:
        """Every (centre (2,), heading) on a 0.2 m grid for which the rectangle ``u_range`` x ``v_range`` (m, u along
        the heading, v to its left) lies on clear floor cells."""
        uu, vv = np.meshgrid(
            np.arange(u_range[0], u_range[1] + 1e-9, self.res), np.arange(v_range[0], v_range[1] + 1e-9, self.res)
        )
        cx, cy = np.meshgrid(self.xs[1::2], self.ys[1::2], indexing="ij")
        centres = np.column_stack([cx.ravel(), cy.ravel()])
        found: list[tuple[np.ndarray, float]] = []
        for heading in headings:
            cu, su = np.cos(heading), np.sin(heading)
            off = np.column_stack([uu.ravel() * cu - vv.ravel() * su, uu.ravel() * su + vv.ravel() * cu])
            pts = centres[:, None, :] + off[None, :, :]  # (C, P, 2)
            ix = np.floor(pts[..., 0] / self.res).astype(int)
            iy = np.floor(pts[..., 1] / self.res).astype(int)
            inside = (ix >= 0) & (ix < self.xs.size) & (iy >= 0) & (iy < self.ys.size)
            ok = inside.all(axis=1)
            ok[ok] = self.clear[ix[ok], iy[ok]].all(axis=1)
            found += [(centres[k], float(heading)) for k in np.flatnonzero(ok)]
        return found


def ellipse_length(a: float, b: float) -> float:
    """Perimeter of an ellipse with semi-axes a, b (Ramanujan's approximation), metres."""
    return float(np.pi * (3 * (a + b) - np.sqrt((3 * a + b) * (a + 3 * b))))
