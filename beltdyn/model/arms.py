"""Tensioner arms: the kinematics of a pulley on a pivoting arm (its angle as the DOF)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from beltdyn.config import DriveConfig
from beltdyn.model.angles import unwrap_near
from beltdyn.model.assembly import sorted_unique
from beltdyn.model.dofs import DofMap
from beltdyn.model.geometry import Layout
from beltdyn.model.supports import support_of


def _last_pair(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """x and y (same shape) stacked on a new last axis of 2: np.stack(..., axis=-1) without its overhead."""
    out = np.empty(np.shape(x) + (2,))
    out[..., 0] = x
    out[..., 1] = y
    return out


def arm_offset(length: np.ndarray, angle: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """u(phi) = c(phi) - c(angle) = l (cos phi - cos angle, sin phi - sin angle) (..., a, 2): the offset of
    each arm pulley's centre from its place at the reference arm angle, arm length l (a,), reference
    angle `angle` (a,), arm angles phi (..., a) (rad)."""
    return length[:, None] * _last_pair(np.cos(phi) - np.cos(angle), np.sin(phi) - np.sin(angle))


def arm_slope(length: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """du/dphi = dc/dphi = l (-sin phi, cos phi) (..., a, 2) at arm angles phi (..., a)."""
    return length[:, None] * _last_pair(-np.sin(phi), np.cos(phi))


def arm_curvature(length: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """d2u/dphi2 = d2c/dphi2 = -l (cos phi, sin phi) (..., a, 2) at arm angles phi (..., a)."""
    return -length[:, None] * _last_pair(np.cos(phi), np.sin(phi))


@dataclass(frozen=True, kw_only=True)
class ArmJoints:
    """Exact kinematics of the tensioner arms: joint coordinates p = P(q) from the independent q.

    Arm k turns about pivot[k]; its angle is phi = angle[k] + q[dof[k]] (angle: the arm angle of the
    layout, q = 0), and its pulley's centre c(phi) = pivot + l (cos phi, sin phi). The dependent
    coordinates p[slot[k]], p[slot[k] + 1] are the centre offsets u = c(phi) - c(angle), which the belt
    joints and the pulley's mass and weight see as a bearing's translations. So the pulley's mass adds
    m l^2 to the arm's inertia through J^T M J, its weight the moment m g . c'(phi), and every force on
    the pulley the geometric stiffness F . c''(phi) (paper Eq. 24 with the constraint eliminated).

    J = dp/dq (n_p, n_q): the identity on q, and dc/dphi = l (-sin phi, cos phi) in the arm columns.
    One numpy implementation of u, u' = dc/dphi and u'' = d2c/dphi2 (`arm_offset`, `arm_slope`,
    `arm_curvature`, for any number of states); every projection is built on them.
    """

    dof: np.ndarray  # (a,) q index of each arm angle
    slot: np.ndarray  # (a,) p index of each arm pulley's x offset (y: slot + 1)
    pivot: np.ndarray  # (a, 2) m
    length: np.ndarray  # (a,) m
    angle: np.ndarray  # (a,) rad, arm angle at q = 0
    n_q: int
    n_p: int
    # (a, 2) N m, dry friction torque of each arm's pivot damper (transient) while the arm turns
    # counter-clockwise (column 0) and clockwise (column 1): `friction_by_sense`
    friction: np.ndarray | None = None
    stops: np.ndarray | None = None  # (a, 2) rad, arm_range (NaN: none)
    names: tuple[str, ...] = ()  # the arm pulleys' names
    pulleys: tuple[int, ...] = ()  # the arm pulleys' indices

    def phi(self, q: np.ndarray) -> np.ndarray:
        """(..., a) arm angles."""
        return self.angle + q[..., self.dof]

    def first(self, phi: np.ndarray) -> np.ndarray:
        """dc/dphi (..., a, 2) (`arm_slope`)."""
        return arm_slope(self.length, phi)

    def second(self, phi: np.ndarray) -> np.ndarray:
        """d2c/dphi2 (..., a, 2) (`arm_curvature`)."""
        return arm_curvature(self.length, phi)

    def expand(self, q: np.ndarray) -> np.ndarray:
        """p (..., n_p) from q (..., n_q): q, then the arm pulleys' offsets u (`arm_offset`)."""
        u = arm_offset(self.length, self.angle, self.phi(q))
        return np.concatenate([q, u.reshape(*q.shape[:-1], -1)], axis=-1)

    @property
    def reference_slopes(self) -> np.ndarray:
        """dc/dphi (a, 2) at q = 0 (`first`(angle))."""
        return self.first(self.angle)

    def expand_motion(self, q: np.ndarray, dq: np.ndarray, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J(q) dq (..., n_p): velocities, or mode shapes about q (slopes: `first` at q, if at hand)."""
        du = (self.first(self.phi(q)) if slopes is None else slopes) * dq[..., self.dof, None]
        return np.concatenate([dq, du.reshape(*dq.shape[:-1], -1)], axis=-1)

    def expand_acceleration(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """J a + (d2c/dphi2) phidot^2 (..., n_p)."""
        phi = self.phi(q)
        w = v[..., self.dof]
        du = self.first(phi) * a[..., self.dof, None] + self.second(phi) * (w * w)[..., None]
        return np.concatenate([a, du.reshape(*a.shape[:-1], -1)], axis=-1)

    def project(self, q: np.ndarray | None, f: np.ndarray) -> np.ndarray:
        """J(q)^T f: a force (..., n_p) on the joint coordinates -> (..., n_q) (q None: at q = 0)."""
        return self._project(self.reference_slopes if q is None else self.first(self.phi(q)), f)

    def _project(self, slopes: np.ndarray, f: np.ndarray) -> np.ndarray:
        """J^T f (..., n_q) for the arms' slopes dc/dphi (..., a, 2)."""
        out = f[..., : self.n_q].copy()
        fu = f[..., self.n_q:].reshape(*f.shape[:-1], len(self.dof), 2)
        out[..., self.dof] += slopes[..., 0] * fu[..., 0] + slopes[..., 1] * fu[..., 1]
        return out

    def jacobian(self, q: np.ndarray):
        """J(q) (n_p, n_q) CSR."""
        from scipy.sparse import coo_matrix

        dc = self.first(self.phi(q))
        rows = np.concatenate([np.arange(self.n_q), self.slot, self.slot + 1])
        cols = np.concatenate([np.arange(self.n_q), self.dof, self.dof])
        vals = np.concatenate([np.ones(self.n_q), dc[:, 0], dc[:, 1]])
        return coo_matrix((vals, (rows, cols)), shape=(self.n_p, self.n_q)).tocsr()

    def dense_jacobian(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J = dp/dq (n_p, n_q) dense at q: the identity on q, the arms' slopes dc/dphi in the arm columns
        (slopes: `first` (a, 2) at q, if at hand)."""
        dc = self.first(self.phi(q)) if slopes is None else slopes
        J = np.eye(self.n_p, self.n_q)
        J[self.slot, self.dof], J[self.slot + 1, self.dof] = dc[:, 0], dc[:, 1]
        return J

    def project_matrix(self, q: np.ndarray, K, f: np.ndarray | None = None, *, dense: bool,
                       folding: "ArmFolding | None" = None):
        """J^T K J (+ the geometric term sum_k (f_u,k . c''(phi_k)) on (phi_k, phi_k) for the force f
        (n_p,) on the joint coordinates whose derivative K (n_p, n_p) is; none for f = None). folding: the
        `ArmFolding` of K's CSR pattern, if at hand (`arm_folding`; derived from K where it does not match)."""
        if f is None:
            return self._project_matrix(self.first(self.phi(q)), K, None, dense=dense, folding=folding)
        return self.project_both(q, f, K, dense=dense, folding=folding)[1]

    def project_both(self, q: np.ndarray, f: np.ndarray, K, *, dense: bool, folding: "ArmFolding | None" = None):
        """(`project`(q, f), `project_matrix`(q, K, f)), the arms' angles evaluated once."""
        phi = self.phi(q)
        dc = self.first(phi)
        fu = f[self.n_q:].reshape(len(self.dof), 2)
        d2c = self.second(phi)
        geo = fu[:, 0] * d2c[:, 0] + fu[:, 1] * d2c[:, 1]  # f_u . d2c/dphi2
        return self._project(dc, f), self._project_matrix(dc, K, geo, dense=dense, folding=folding)

    def project_matrix_at(self, slopes: np.ndarray, K, *, dense: bool, folding: "ArmFolding | None" = None):
        """J^T K J with the arms' slopes dc/dphi (a, 2) at hand (`first`)."""
        return self._project_matrix(slopes, K, None, dense=dense, folding=folding)

    def _project_matrix(self, dc: np.ndarray, K, geo: np.ndarray | None, *, dense: bool,
                        folding: "ArmFolding | None" = None):
        """J^T K J + geo on the arms' diagonal, dc = dc/dphi (a, 2) (`project_matrix`); dense for a dense
        K when `dense`, else CSR (the rows and columns of the offsets folded onto their arm angle,
        `ArmFolding`: the one given where it is K's pattern's, else derived from K)."""
        if dense and not hasattr(K, "tocsr"):
            J = self.dense_jacobian(slopes=dc)
            out = J.T @ np.asarray(K) @ J
            if geo is not None:
                out[self.dof, self.dof] += geo
            return out
        from scipy.sparse import csr_matrix

        K = csr_matrix(K)
        if folding is None or not folding.holds(K.indptr, K.indices):
            folding = arm_folding(self, K.indptr, K.indices)
        w = np.ones(self.n_p)
        w[self.slot], w[self.slot + 1] = dc[:, 0], dc[:, 1]
        data = np.bincount(folding.fold, weights=K.data * w[folding.rows] * w[K.indices], minlength=len(folding.idx))
        if geo is not None:
            data[folding.diag] += geo
        return csr_matrix((data, folding.idx, folding.ptr), shape=(self.n_q, self.n_q))


@dataclass(frozen=True, kw_only=True)
class ArmFolding:
    """A CSR pattern on the joint coordinates p (indptr (n_p + 1,), indices (nnz,)) folded onto q: the rows
    and columns of the arms' dependent offsets onto their arm angle (`ArmJoints.project_matrix`). A
    pattern's, derived once where the pattern is built (`arm_folding`). rows (nnz,) the row of each entry;
    fold (nnz,) its slot in the pattern on q (ptr (n_q + 1,), idx (nnz_q,)); diag (a,) the arms' diagonal
    slots there."""

    indptr: np.ndarray
    indices: np.ndarray
    rows: np.ndarray
    fold: np.ndarray
    ptr: np.ndarray
    idx: np.ndarray
    diag: np.ndarray

    def holds(self, indptr: np.ndarray, indices: np.ndarray) -> bool:
        """Whether this is the folding of the CSR pattern (indptr, indices)."""
        return (indptr is self.indptr and indices is self.indices) or (
            len(indices) == len(self.indices) and np.array_equal(indptr, self.indptr)
            and np.array_equal(indices, self.indices))


def arm_folding(arms: ArmJoints, indptr: np.ndarray, indices: np.ndarray) -> ArmFolding:
    """The `ArmFolding` of the CSR pattern (indptr, indices) on p of the arms' joint coordinates."""
    to = np.arange(arms.n_p)
    to[arms.slot], to[arms.slot + 1] = arms.dof, arms.dof
    rows = np.repeat(np.arange(arms.n_p), np.diff(indptr))
    keys = to[rows] * arms.n_q + to[indices]
    uniq, fold = sorted_unique(keys)
    r, c = uniq // arms.n_q, uniq % arms.n_q
    ptr = np.zeros(arms.n_q + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=arms.n_q), out=ptr[1:])  # (entries per row)
    diag = np.searchsorted(uniq, arms.dof * arms.n_q + arms.dof)
    out = ArmFolding(indptr=indptr, indices=indices, rows=rows, fold=fold.ravel(), ptr=ptr, idx=c.astype(np.int64),
                     diag=diag)
    for a in (out.rows, out.fold, out.ptr, out.idx, out.diag):  # (read-only: a pattern's)
        a.setflags(write=False)
    return out


def arm_joints(cfg: DriveConfig, layout: Layout, dofs: DofMap, *, like: ArmJoints | None = None) -> ArmJoints | None:
    """The arms' kinematics about the layout's arm angles (None without arms). like: the same drive's
    arms on another layout (what the configuration fixes taken from it)."""
    if like is not None:
        length, angle = _arm_geometry(cfg, layout, like.pulleys, like.pivot.tolist())
        return ArmJoints(dof=like.dof, slot=like.slot, pivot=like.pivot, length=length, angle=angle,
                         n_q=like.n_q, n_p=like.n_p, friction=like.friction, stops=like.stops, names=like.names,
                         pulleys=like.pulleys)
    arms = [j for j, p in enumerate(cfg.pulleys) if p.support == "arm"]
    if not arms:
        return None
    ps = [cfg.pulleys[j] for j in arms]
    pivots = [p.arm_pivot for p in ps]
    length, angle = _arm_geometry(cfg, layout, arms, pivots)
    return ArmJoints(dof=dofs.arm_dof[arms],
                     slot=np.array([dofs.trans_dof[j][0] for j in arms], dtype=np.int64),
                     pivot=np.array(pivots, dtype=float), length=length, angle=angle, n_q=dofs.n_q, n_p=dofs.n,
                     friction=np.array([friction_by_sense(p, a) for p, a in zip(ps, angle.tolist())], dtype=float),
                     stops=np.array([p.arm_range or (np.nan, np.nan) for p in ps], dtype=float),
                     names=tuple(p.name for p in ps), pulleys=tuple(arms))


def friction_by_sense(pulley, angle: float) -> tuple[float, float]:
    """An arm's dry friction torques (N m) while it turns counter-clockwise and clockwise, at the working
    angle `angle` (rad). Loading is the arm turning away from its spring's free angle (winding the spring:
    the belt pushes it back), where arm_friction acts; unloading, toward it (the spring moves the arm
    toward the belt), arm_friction_unloading (not set: arm_friction). The free angle is taken as the
    spring's (`supports`): literal on the stops' branch, else the turn nearest the working angle; an arm
    at its free angle counts counter-clockwise as loading."""
    loading, unloading = pulley.arm_friction, pulley.arm_friction_unloading
    if unloading is None or pulley.arm_free_angle is None:
        return loading, loading
    free = pulley.arm_free_angle if pulley.arm_range is not None else unwrap_near(pulley.arm_free_angle, angle)
    return (loading, unloading) if angle >= free else (unloading, loading)


def _arm_geometry(cfg: DriveConfig, layout: Layout, arms, pivots: list) -> tuple[np.ndarray, np.ndarray]:
    """The arms' lengths |c - pivot| and working angles (a,) on a layout (pulley indices arms, pivots [(x, y)]),
    arm by arm on floats."""
    center = layout.center.tolist()
    length, angle = [], []
    for j, (px, py) in zip(arms, pivots):
        x, y = center[j]
        length.append(np.hypot(x - px, y - py))
        angle.append(support_of(cfg.pulleys[j]).angle_at(x, y))  # (its `working_angle`)
    return np.array(length), np.array(angle)
