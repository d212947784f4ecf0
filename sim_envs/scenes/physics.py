"""Dropping small objects onto a static scene with MuJoCo physics until they rest.

The static scene (room structure, furniture) becomes fixed collision geoms; each object becomes a body on a free joint
made of its box / cylinder / sphere parts. Gravity is -z (9.81 m/s^2). The simulation runs until every object moves
slower than :data:`REST_SPEED` (linear, m/s) and :data:`REST_SPIN` (angular, rad/s) for :data:`REST_TIME` seconds, or
until :data:`MAX_TIME` simulated seconds. MuJoCo is deterministic: the same input gives the same poses, bit for bit.
No OpenGL is needed here.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from sim_envs.scenes.scene import Primitive

TIMESTEP = 0.004  # seconds per physics step (ours; stable with MuJoCo's implicit integrator for these masses)
MAX_TIME = 4.0  # simulated seconds at most (ours)
REST_SPEED = 0.005  # m/s below which an object counts as still (ours)
REST_SPIN = 0.05  # rad/s (ours)
REST_TIME = 0.2  # seconds every object must stay still (ours)
DENSITY = 400.0  # kg/m^3 of objects (ours: books, boxes, plastic; light objects settle with small penetration)
FRICTION = (1.0, 0.01, 0.005)  # sliding, torsional, rolling (ours: rolling friction stops cylinders rolling away)
_KIND_TO_GEOM = {"box": "mjGEOM_BOX", "cylinder": "mjGEOM_CYLINDER", "sphere": "mjGEOM_SPHERE"}


@dataclass(frozen=True)
class FreeBody:
    """An object to drop: parts ``(kind, half sizes, T_body_part (4, 4))`` and its initial ``T_world_body`` (4, 4)."""

    parts: list[tuple[str, tuple[float, float, float], np.ndarray]]
    T_world_body: np.ndarray


@dataclass(frozen=True)
class SettleResult:
    """Final poses: T_world_body (N, 4, 4) float64; valid (N,) bool (False: the object left the scene or never
    stopped); speeds (N,) float64 final linear speed m/s; sim_time: simulated seconds; rested: all were still."""

    T_world_body: np.ndarray
    valid: np.ndarray
    speeds: np.ndarray
    sim_time: float
    rested: bool


def _aabb_of_body(body: FreeBody) -> np.ndarray:
    """(2, 3) world bounds of a body's parts (a loose box: each part's bounding sphere)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for kind, size, T in body.parts:
        r = (
            float(np.linalg.norm(size))
            if kind == "box"
            else float(np.hypot(size[0], size[1] if kind == "cylinder" else 0))
        )
        c = (body.T_world_body @ T)[:3, 3]
        lo, hi = np.minimum(lo, c - r), np.maximum(hi, c + r)
    return np.stack([lo, hi])


def build_model(static: Sequence[Primitive], bodies: Sequence[FreeBody], margin: float = 0.3):  # noqa: ANN201
    """The MuJoCo model: static primitives near the bodies (within ``margin`` metres) as fixed geoms, bodies free."""
    import mujoco

    spec = mujoco.MjSpec()
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -9.81]
    if bodies:
        boxes = np.array([_aabb_of_body(b) for b in bodies])
        lo, hi = boxes[:, 0].min(0) - margin, boxes[:, 1].max(0) + margin
    for k, prim in enumerate(static):
        box = prim.aabb()
        if bodies and ((box[1] < lo).any() or (box[0] > hi).any()):
            continue
        quat = Rotation.from_matrix(prim.T_world_obj[:3, :3]).as_quat(scalar_first=True)
        spec.worldbody.add_geom(
            name=f"static{k}", type=getattr(mujoco.mjtGeom, _KIND_TO_GEOM[prim.kind]), size=list(prim.size),
            pos=list(prim.T_world_obj[:3, 3]), quat=list(quat), friction=list(FRICTION), condim=6,
        )  # fmt: skip
    for i, body in enumerate(bodies):
        T = body.T_world_body
        b = spec.worldbody.add_body(
            name=f"obj{i}", pos=list(T[:3, 3]), quat=list(Rotation.from_matrix(T[:3, :3]).as_quat(scalar_first=True))
        )
        b.add_freejoint()
        for j, (kind, size, T_part) in enumerate(body.parts):
            b.add_geom(
                name=f"obj{i}_{j}", type=getattr(mujoco.mjtGeom, _KIND_TO_GEOM[kind]), size=list(size),
                pos=list(T_part[:3, 3]), quat=list(Rotation.from_matrix(T_part[:3, :3]).as_quat(scalar_first=True)),
                density=DENSITY, friction=list(FRICTION), condim=6,
            )  # fmt: skip
    return spec.compile()


def settle_bodies(static: Sequence[Primitive], bodies: Sequence[FreeBody], max_time: float = MAX_TIME) -> SettleResult:
    """Drop ``bodies`` onto the ``static`` primitives and simulate until all rest (module docstring).

    An object is marked invalid when it ends below the floor (z < -0.05 m), moved more than 3 m, or still moves.
    """
    import mujoco

    n = len(bodies)
    if n == 0:
        return SettleResult(np.zeros((0, 4, 4)), np.zeros(0, bool), np.zeros(0), 0.0, True)
    model = build_model(static, bodies)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    body_ids = np.array([model.body(f"obj{i}").id for i in range(n)])
    dof = np.arange(6 * n).reshape(n, 6)  # free joints: (vx, vy, vz, wx, wy, wz) per body, in body order
    still_steps = int(round(REST_TIME / TIMESTEP))
    check_every = 10
    still = 0
    steps = 0
    max_steps = int(round(max_time / TIMESTEP))
    lin = np.zeros(n)
    while steps < max_steps:
        mujoco.mj_step(model, data, nstep=check_every)
        steps += check_every
        qvel = data.qvel[dof]
        lin = np.linalg.norm(qvel[:, :3], axis=1)
        ang = np.linalg.norm(qvel[:, 3:], axis=1)
        still = still + check_every if (lin.max() < REST_SPEED and ang.max() < REST_SPIN) else 0
        if still >= still_steps:
            break
    T_out = np.tile(np.eye(4), (n, 1, 1))
    T_out[:, :3, 3] = data.xpos[body_ids]
    T_out[:, :3, :3] = data.xmat[body_ids].reshape(n, 3, 3)
    start = np.array([b.T_world_body[:3, 3] for b in bodies])
    moved = np.linalg.norm(T_out[:, :3, 3] - start, axis=1)
    speeds = np.linalg.norm(data.qvel[dof][:, :3], axis=1)
    valid = (T_out[:, 2, 3] > -0.05) & (moved < 3.0) & (speeds < 10 * REST_SPEED)
    return SettleResult(T_out, valid, speeds, steps * TIMESTEP, bool(still >= still_steps))
