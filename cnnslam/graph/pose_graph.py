"""The key-frame pose graph (CNN-SLAM Sec. 3.3): nodes are key-frame poses ``T_world_kf``; edges are relative poses
measured by direct alignment between key-frames; the whole graph is re-optimised at each new key-frame.

Edges: every new key-frame gets one to the key-frame it was tracked from (the tracking result of its frame), and
one to each older key-frame "that share[s] a similar field of view (i.e., having a small relative pose)": LSD-SLAM's
candidate search (position difference scaled by the mean inverse depth, viewing directions within 0.75 of the field
of view), each candidate confirmed by direct image alignment in both directions (:func:`align_keyframes`) whose
results must agree. A candidate far back in creation order closes a loop: when the camera returns to a place, the
edge to the key-frames made there the first time pulls the accumulated drift out at the next optimisation.

Each edge (i, j) measures T_i_j with an information matrix, the Gauss-Newton Hessian of the photometric alignment
(6x6, for a left perturbation of T_j_i, the tracker's parameterisation). The optimisation minimises
sum_edges |L^T log(T_j_i(x) T_j_i_meas^-1)|^2 with H = L L^T over left twists x_k of every key-frame pose but the
first (held fixed: the gauge of the world frame).

Solver: ``scipy.optimize.least_squares`` (trust-region reflective, LSMR) with a sparse Jacobian. Why this one:
each edge's 6 residuals depend on 12 of the 6 N unknowns, so the Jacobian is block-sparse; we hand it over as a
scipy sparse matrix (the blocks are adjoints of the poses, first order in the residual, as in g2o's SE(3) edges) and
the trust-region steps are solved by the sparse iterative LSMR, so the cost grows with the number of edges, not with
N^2 or N^3, and the robust trust region tolerates poor initial poses after a loop closure.
It is the well-kept solver already in the dependency set (g2o's and GTSAM's Python packages would add compiled
dependencies for graphs of tens to hundreds of key-frames, which this solves in tens of milliseconds).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from cnnslam.config import PoseGraphConfig, TrackingConfig
from cnnslam.errors import CnnSlamError
from cnnslam.geometry import adjoint, rotation_angle_deg, se3_exp, se3_inverse, se3_log
from cnnslam.track.tracking import ImagePyramid, TrackingReference, TrackingResult, track_frame

EdgeKind = Literal["sequential", "neighbour", "loop"]


@dataclass(frozen=True)
class PoseGraphEdge:
    """A relative-pose constraint between key-frames i and j.

    T_i_j: (4, 4) float64 measured, maps j-coordinates into i's; information: (6, 6) float64 for the twist
    delta with T_j_i = exp(delta) T_j_i_meas (translation first); kind: "sequential" (tracking), "neighbour" or
    "loop" (direct alignment).
    """

    i: int
    j: int
    T_i_j: np.ndarray
    information: np.ndarray
    kind: EdgeKind


@dataclass(frozen=True)
class PoseGraphResult:
    """One optimisation: optimised ``T_world_kf`` per key-frame index, costs before and after, solver status."""

    poses: dict[int, np.ndarray]
    cost_before: float
    cost_after: float
    n_edges: int
    n_evaluations: int
    success: bool


def _sqrt_information(information: np.ndarray) -> np.ndarray:
    """L^T with H = L L^T (H regularised by 1e-9 of its trace so that the Cholesky factor exists)."""
    H = 0.5 * (np.asarray(information, dtype=np.float64) + np.asarray(information, dtype=np.float64).T)
    ridge = 1e-9 * max(float(np.trace(H)), 1e-12)
    return np.linalg.cholesky(H + ridge * np.eye(6)).T


def edge_residuals(T_world_i: np.ndarray, T_world_j: np.ndarray, T_i_j_meas: np.ndarray,
                   sqrt_information: np.ndarray) -> np.ndarray:
    """Whitened residuals of edges: L^T log(T_j_i T_j_i_meas^-1) with T_j_i = T_world_j^-1 T_world_i.

    All arguments batched over edges: (E, 4, 4) poses and measurements, (E, 6, 6) L^T. Returns (E, 6).
    """
    T_j_i = se3_inverse(T_world_j) @ T_world_i
    delta = se3_log(T_j_i @ T_i_j_meas)  # T_i_j_meas = (T_j_i_meas)^-1
    return np.einsum("eab,eb->ea", sqrt_information, delta)


class PoseGraph:
    """Key-frames and edges; :meth:`optimise` returns new poses without changing the stored ones.

    Owned by the key-frame thread (the frame thread never touches it).
    """

    def __init__(self) -> None:
        self.poses: dict[int, np.ndarray] = {}
        self.edges: list[PoseGraphEdge] = []

    def add_keyframe(self, index: int, T_world_kf: np.ndarray) -> None:
        """Add (or move) node ``index`` with its current pose estimate."""
        self.poses[int(index)] = np.array(T_world_kf, dtype=np.float64)

    def add_edge(self, edge: PoseGraphEdge) -> None:
        """Add a constraint between two existing nodes."""
        if edge.i not in self.poses or edge.j not in self.poses or edge.i == edge.j:
            raise CnnSlamError(f"edge ({edge.i}, {edge.j}) needs two different existing key-frames; "
                               f"known: {sorted(self.poses)}")
        self.edges.append(edge)

    def set_poses(self, poses: dict[int, np.ndarray]) -> None:
        for k, T in poses.items():
            self.poses[k] = np.array(T, dtype=np.float64)

    def optimise(self, config: PoseGraphConfig, fixed: int | None = None) -> PoseGraphResult:
        """Global optimisation of every pose but ``fixed`` (default: the smallest index) over all edges."""
        if not self.poses:
            return PoseGraphResult({}, 0.0, 0.0, 0, 0, True)
        order = sorted(self.poses)
        fixed = order[0] if fixed is None else int(fixed)
        free = [k for k in order if k != fixed]
        if not free or not self.edges:
            return PoseGraphResult(dict(self.poses), 0.0, 0.0, len(self.edges), 0, True)
        column = {k: 6 * n for n, k in enumerate(free)}
        base = np.stack([self.poses[k] for k in order])
        slot = {k: n for n, k in enumerate(order)}
        ei = np.array([slot[e.i] for e in self.edges])
        ej = np.array([slot[e.j] for e in self.edges])
        meas = np.stack([e.T_i_j for e in self.edges])
        sqrt_info = np.stack([_sqrt_information(e.information) for e in self.edges])
        free_slots = np.array([slot[k] for k in free])

        def poses_of(x: np.ndarray) -> np.ndarray:
            T = base.copy()
            T[free_slots] = se3_exp(x.reshape(-1, 6)) @ base[free_slots]
            return T

        def fun(x: np.ndarray) -> np.ndarray:
            T = poses_of(x)
            return edge_residuals(T[ei], T[ej], meas, sqrt_info).ravel()

        # Jacobian blocks of edge (i, j): d delta / d x_i = Ad(T_world_j^-1), d delta / d x_j = -Ad(T_world_j^-1)
        # (first order in delta, the usual pose-graph approximation), whitened by L^T.
        n_e = len(self.edges)
        col_i = np.array([column.get(e.i, -1) for e in self.edges])
        col_j = np.array([column.get(e.j, -1) for e in self.edges])
        rows = (6 * np.arange(n_e))[:, None, None] + np.arange(6)[None, :, None] + np.zeros((1, 1, 6), np.intp)

        def jac(x: np.ndarray) -> csr_matrix:
            T = poses_of(x)
            block = np.einsum("eab,ebc->eac", sqrt_info, adjoint(se3_inverse(T[ej])))
            data, r_idx, c_idx = [], [], []
            for cols, sign in ((col_i, 1.0), (col_j, -1.0)):
                has = cols >= 0
                data.append((sign * block[has]).ravel())
                r_idx.append(rows[has].ravel())
                c_idx.append((cols[has][:, None, None] + np.arange(6)[None, None, :] + np.zeros((1, 6, 1), np.intp))
                             .ravel())
            return csr_matrix((np.concatenate(data), (np.concatenate(r_idx), np.concatenate(c_idx))),
                              shape=(6 * n_e, 6 * len(free)))

        x0 = np.zeros(6 * len(free))
        r0 = fun(x0)
        sol = least_squares(fun, x0, jac=jac, method="trf", tr_solver="lsmr", x_scale="jac",
                            max_nfev=config.max_iterations, xtol=1e-10, ftol=1e-10)
        T = poses_of(sol.x)
        poses = {k: T[slot[k]] for k in order}
        return PoseGraphResult(poses, float(0.5 * r0 @ r0), float(sol.cost), len(self.edges), int(sol.nfev),
                               bool(sol.success))


# ------------------------------------------------------------------------------------------ candidate search


def field_of_view(intrinsics: np.ndarray, image_size: tuple[int, int]) -> tuple[float, float]:
    """(horizontal, vertical) field of view in radians of a pinhole camera (LSD-SLAM's fowX, fowY)."""
    h, w = image_size
    fx, fy = float(intrinsics[0]), float(intrinsics[1])
    return 2.0 * np.arctan(w / fx / 2.0), 2.0 * np.arctan(h / fy / 2.0)


def neighbour_candidates(
    T_world_new: np.ndarray, mean_idepth_new: float, others: dict[int, tuple[np.ndarray, float]],
    fov: tuple[float, float], config: PoseGraphConfig, exclude: set[int] | None = None,
) -> list[int]:
    """Key-frames with a similar view of the new one (LSD-SLAM's findEuclideanOverlapFrames with both scales).

    others: index -> (T_world_kf, mean inverse depth 1/m). A key-frame qualifies when |p_new - p_k|^2 times the
    smaller mean inverse depth squared is below ``neighbour_distance_squared`` and the optical axes differ by less
    than ``neighbour_angle_fov_fraction`` of the mean field of view. Returns indices, nearest first, at most
    ``max_candidates``.
    """
    exclude = exclude or set()
    cos_th = np.cos(config.neighbour_angle_fov_fraction * 0.5 * (fov[0] + fov[1]))
    pos = T_world_new[:3, 3]
    view = T_world_new[:3, 2]
    scored = []
    for k, (T, mean_idepth) in others.items():
        if k in exclude:
            continue
        fac = min(mean_idepth, mean_idepth_new)
        dist = (pos - T[:3, 3]) * fac
        d2 = float(dist @ dist)
        if d2 > config.neighbour_distance_squared or float(T[:3, 2] @ view) < cos_th:
            continue
        scored.append((d2, k))
    scored.sort()
    return [k for _, k in scored[: config.max_candidates]]


@dataclass(frozen=True)
class AlignmentResult:
    """Direct alignment of two key-frames: the edge when accepted (None otherwise), and why."""

    edge: PoseGraphEdge | None
    reason: str
    forward: TrackingResult | None = None
    backward: TrackingResult | None = None


def align_keyframes(
    index_a: int, reference_a: TrackingReference, pyramid_a: ImagePyramid, mean_depth_a: float,
    index_b: int, reference_b: TrackingReference, pyramid_b: ImagePyramid,
    T_a_b_init: np.ndarray, tracking: TrackingConfig, config: PoseGraphConfig, kind: EdgeKind,
) -> AlignmentResult:
    """Constraint between key-frames a and b by direct alignment in both directions (eq. 1-4 between key-frames).

    b's image is tracked against a's depth (giving T_a_b) and a's image against b's depth (giving T_b_a), both
    from ``T_a_b_init`` (4, 4), down to ``config.alignment_finest_level``. The edge (a, b) is accepted when both
    track and T_a_b T_b_a is within ``consistency_translation_relative * mean_depth_a`` metres and
    ``consistency_rotation_deg`` of identity (LSD-SLAM also demands reciprocal agreement).
    """
    level = config.alignment_finest_level
    fwd = track_frame(reference_a, pyramid_b, T_a_b_init, tracking, finest_level=level)
    if not fwd.tracked:
        return AlignmentResult(None, "forward alignment lost", fwd)
    bwd = track_frame(reference_b, pyramid_a, se3_inverse(fwd.T_kf_cur), tracking, finest_level=level)
    if not bwd.tracked:
        return AlignmentResult(None, "backward alignment lost", fwd, bwd)
    loop = fwd.T_kf_cur @ bwd.T_kf_cur
    trans = float(np.linalg.norm(loop[:3, 3]))
    rot = rotation_angle_deg(loop)
    if trans > config.consistency_translation_relative * mean_depth_a or rot > config.consistency_rotation_deg:
        return AlignmentResult(None, f"inconsistent: {trans:.3f} m, {rot:.2f} deg", fwd, bwd)
    edge = PoseGraphEdge(index_a, index_b, fwd.T_kf_cur, fwd.hessian, kind)
    return AlignmentResult(edge, "accepted", fwd, bwd)

