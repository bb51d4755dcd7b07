"""Spring spans: a span modelled as an axial spring between its tangent points (no DOFs of its own)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from beltdyn.config import DriveConfig
from beltdyn.model import barlaw
from beltdyn.model.belt import NORMAL_SIGNS, span_stretch_of
from beltdyn.model.dofs import DofMap
from beltdyn.model.geometry import Layout

_EYE2 = np.eye(2)
_EYE2.setflags(write=False)
_PAD = np.zeros(1)  # the padding coordinate (index n_dof) appended to p
_PAD.setflags(write=False)


@dataclass(frozen=True, kw_only=True)
class SpringSpans:
    """The spans modelled as axial springs (model = "spring"): the rotational (discrete) model of a span.

    Nomenclature, per spring span (k of them): end positions x = [r_a, r_b] (4,) = x0 + T p[idx], the
    span's tangent points on its two pulleys through the same constant-Jacobian joints as an ANCF
    span's end nodes (`joint_pairs`; T (k, 4, m), idx (k, m), padding index n_dof); chord d = r_b - r_a,
    l = |d|, u = d / l; reference length L; stretch lam = l / L; the bar law of `barlaw` (the ANCF law
    of a uniformly stretched span): Green-Lagrange strain eps = (lam^2 - 1) / 2, strain energy
    U = L EA eps^2 / 2, true axial force N = dU/dl = EA eps lam, on the ends f = dU/dx = N [-u, u]. Tangent
    K = [[K2, -K2], [-K2, K2]], K2 = k_a u u^T + (N / l) (I - u u^T), k_a = dN/dl = (dN/dlam) / L
    along the chord and N / l (the string's geometric stiffness) across it. Kelvin-Voigt damping as the
    belt's: N_d = EA eta lam^2 lam' with lam' = (u . d') / L along u. Mass: the span's rho L lumped
    at its ends, rho L / 2 on each tangent point, which moves with its pulley (no DOFs of its own, no
    transverse modes). A spring also carries compression, where a belt would go slack: the static
    analysis refuses a compressed span, the transient records it as a slack event. Evaluated in numpy
    here (static, modal: one implementation, every state shape) and by `spring_kernel` in the time
    stepper, held equal on random states by tests/test_springs.py. Immutable: what derives from the
    fields (D = dd/dp, the lumped masses, the transport blocks) is computed where it is used (a few
    small arrays).

    Running belt (`running`): the material flows through the chord at c (m/s of undeformed length), so
    each lumped end moves at x' + c d / L. Its kinetic energy's terms in c are those of the ANCF span
    on the linear interpolation between the ends: c x'^T (A x) with A = rho / 2 [[-I, I], [-I, I]]
    (gyroscopic c (A - A^T) = c rho [[0, I], [-I, 0]], the axial inertia c' A x) and the centripetal
    c^2 x^T B x / 2 with B = rho / L [[I, -I], [-I, I]]: the ends feel -c^2 B x = rho c^2 lam [u, -u],
    so a pulley receives N - rho c^2 lam from the span, as from an ANCF span (`transport_blocks`).
    """

    span: np.ndarray  # (k,) span index of each spring span
    T: np.ndarray  # (k, 4, m) end positions per joint coordinate
    idx: np.ndarray  # (k, m) joint coordinate indices (n_dof = padding)
    x0: np.ndarray  # (k, 4) end positions at p = 0
    reference_length: np.ndarray  # (k,) L, m
    reference_direction: np.ndarray  # (k, 2) chord direction at p = 0
    EA: float  # N
    rho: float  # kg/m
    n_dof: int  # joint coordinates p
    n_span: int  # spans of the drive (spring and flexible)
    damping_axial: float = 0.0  # Kelvin-Voigt retardation time (s), set by the transient options
    EI: float = 0.0  # the belt's bending stiffness (N m^2) and model.curvature: not used by the springs, only
    curvature: str = "linear"  # to name the modes of the span they leave out (`ladder.unrepresented_modes`)
    axial_law: str = "green-lagrange"  # belt.axial_law: the bar law of the springs (`barlaw.bar_law`), as the elements'

    @property
    def law(self) -> barlaw.BarLaw:
        """The functions of the springs' bar law."""
        return barlaw.bar_law(self.axial_law)

    @property
    def end_mass(self) -> np.ndarray:
        """(k,) the mass lumped on each end, rho L / 2 (kg)."""
        return 0.5 * self.rho * self.reference_length

    @property
    def Tt(self) -> np.ndarray:
        """(k, m, 4) transposed end transformation (a view)."""
        return self.T.transpose(0, 2, 1)

    def positions(self, p: np.ndarray) -> np.ndarray:
        """x (k, 4) at the joint coordinates p (n_dof,)."""
        return self.x0 + np.matmul(self.T, np.concatenate([p, _PAD])[self.idx][:, :, None])[:, :, 0]

    def positions_batch(self, P: np.ndarray, *, offset: bool = True) -> np.ndarray:
        """(B, k, 4) end positions (velocities, accelerations with offset=False) of states P (B, n_dof)."""
        Pe = np.concatenate([P, np.zeros((P.shape[0], 1))], axis=1)[:, self.idx]
        X = np.einsum("kim,bkm->bki", self.T, Pe)
        return X + self.x0 if offset else X

    @staticmethod
    def chord(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (..., k, 2), l (..., k): the chords' unit direction and length at end positions X (..., k, 4)."""
        d = X[..., 2:4] - X[..., 0:2]
        l = np.sqrt(np.einsum("...d,...d->...", d, d))
        return d / l[..., None], l

    def axial(self, X: np.ndarray):
        """u (..., k, 2), l, lam, eps, N (..., k) at end positions X (..., k, 4)."""
        u, l = self.chord(X)
        lam = l / self.reference_length
        return u, l, lam, barlaw.strain(lam), self.law.axial_force(lam, self.EA)

    def damping_force(self, X: np.ndarray, Xd: np.ndarray) -> np.ndarray:
        """N_d (..., k) of end velocities Xd."""
        u, l, lam, _, _ = self.axial(X)
        rate = np.einsum("...d,...d->...", u, Xd[..., 2:4] - Xd[..., 0:2]) / self.reference_length
        return self.law.viscous_force(lam, rate, self.EA, self.damping_axial)

    def reduce_vector(self, fe: np.ndarray) -> np.ndarray:
        """sum_k T^T fe (k, 4) -> (n_dof,)."""
        fr = np.matmul(self.Tt, fe[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def reduce_blocks(self, Ke: np.ndarray) -> np.ndarray:
        """(k, m, m) blocks T^T Ke T of (k, 4, 4) end-position blocks."""
        return np.matmul(np.matmul(self.Tt, Ke), self.T)

    @staticmethod
    def _pair(A: np.ndarray) -> np.ndarray:
        """[[A, -A], [-A, A]] (k, 4, 4) of (k, 2, 2)."""
        return np.concatenate([np.concatenate([A, -A], axis=2), np.concatenate([-A, A], axis=2)], axis=1)

    def force(self, p: np.ndarray) -> np.ndarray:
        """Reduced elastic force (n_dof,)."""
        return self._force(p)[0]

    def _force(self, p: np.ndarray):
        """The reduced elastic force (n_dof,) T^T [-N u, N u] = D^T (N u) through the chord's map D = dd/dp
        (`chord_map`), and u, l, lam, N (`axial`)."""
        u, l, lam, _, N = self.axial(self.positions(p))
        fr = np.matmul(self.chord_map_t, (N[:, None] * u)[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof], u, l, lam, N

    def force_and_blocks(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reduced elastic force (n_dof,) and the tangent blocks T^T K_e T (k, m, m), through the chord's
        map D: T^T [[K2, -K2], [-K2, K2]] T = D^T K2 D."""
        f, u, l, lam, N = self._force(p)
        k_a = self.law.axial_stiffness(lam, self.EA) / self.reference_length
        uu = u[:, :, None] * u[:, None, :]
        K2 = k_a[:, None, None] * uu + (N / l)[:, None, None] * (_EYE2 - uu)
        return f, np.matmul(np.matmul(self.chord_map_t, K2), self.chord_map)

    @property
    def chord_map(self) -> np.ndarray:
        """D = T[:, 2:4] - T[:, 0:2] (k, 2, m): the chord d = r_b - r_a per joint coordinate."""
        return self.T[:, 2:4] - self.T[:, 0:2]

    @property
    def chord_map_t(self) -> np.ndarray:
        """D^T (k, m, 2) (a view of a new `chord_map`)."""
        return self.chord_map.transpose(0, 2, 1)

    def damping_blocks(self, p: np.ndarray) -> np.ndarray:
        """(k, m, m) the damping matrix dN_d/d(x') through the joints at p (Kelvin-Voigt)."""
        u, _, lam, _, _ = self.axial(self.positions(p))
        c = self.law.viscous_force(lam, 1.0 / self.reference_length, self.EA, self.damping_axial)  # dN_d/d(u . d')
        return self.reduce_blocks(self._pair(c[:, None, None] * u[:, :, None] * u[:, None, :]))

    def mass_blocks(self) -> np.ndarray:
        """(k, m, m) T^T (rho L / 2 I4) T, constant."""
        return self.end_mass[:, None, None] * np.matmul(self.T.transpose(0, 2, 1), self.T)

    def transport_end_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(A_s, B_s) (k, 4, 4) per unit speed on the end positions (class docstring)."""
        eye = np.broadcast_to(np.eye(2), (len(self.span), 2, 2))
        half = 0.5 * self.rho * eye
        A = np.concatenate([np.concatenate([-half, half], axis=2), np.concatenate([-half, half], axis=2)], axis=1)
        return A, self._pair((self.rho / self.reference_length)[:, None, None] * eye)

    def transport_blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """As `BeltSpans.transport_blocks`: T^T A_s T, T^T B_s T (k, m, m) and the reduced A_s x0, B_s x0
        (n_dof,)."""
        A, B = self.transport_end_matrices()
        return (self.reduce_blocks(A), self.reduce_blocks(B), self.reduce_vector(np.matmul(A, self.x0[:, :, None])[:, :, 0]),
                self.reduce_vector(np.matmul(B, self.x0[:, :, None])[:, :, 0]))

    def centripetal_force(self, p: np.ndarray, speed: float) -> np.ndarray:
        """-c^2 T^T B_s x (n_dof,) at the joint coordinates p."""
        B = self.transport_end_matrices()[1]
        return -(speed * speed) * self.reduce_vector(np.matmul(B, self.positions(p)[:, :, None])[:, :, 0])

    def transport_end_forces(self, X: np.ndarray, Xd: np.ndarray | None, speed, acceleration=0.0) -> np.ndarray:
        """(B, n_span, 2, 2) as `BeltSpans.transport_end_forces` for end states X, Xd (B, k, 4):
        c (A_s - A_s^T) x' - c^2 B_s x + c' A_s x on each end (zeros for the other spans)."""
        A, Bm = self.transport_end_matrices()
        c = np.broadcast_to(np.asarray(speed, dtype=float), (X.shape[0],))[:, None, None]
        cd = np.broadcast_to(np.asarray(acceleration, dtype=float), (X.shape[0],))[:, None, None]
        f = -c * c * np.einsum("kij,bkj->bki", Bm, X) + cd * np.einsum("kij,bkj->bki", A, X)
        if Xd is not None:
            f = f + c * np.einsum("kij,bkj->bki", A - A.transpose(0, 2, 1), Xd)
        return self.scatter(f.reshape(X.shape[0], -1, 2, 2))

    def gravity_force(self, g: np.ndarray) -> np.ndarray:
        """(n_dof,) the generalized weight of the lumped masses for the gravity vector g (2,)."""
        fe = self.end_mass[:, None] * np.concatenate([g, g], dtype=float)  # (k, 4): both ends
        fr = np.matmul(fe[:, None, :], self.T)  # (k, 1, m): T^T fe
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def strain_energy(self, p: np.ndarray) -> float:
        lam = self.axial(self.positions(p))[2]
        return float((self.law.strain_energy_density(lam, self.EA) * self.reference_length).sum())

    def tension_integral(self, p: np.ndarray, *, gradient: bool = True) -> tuple[float, np.ndarray | None]:
        """sum_k N_k L_k (N m) and its gradient (n_dof,) (None without gradient): the springs' share of the
        length-weighted mean."""
        u, _, lam, _, N = self.axial(self.positions(p))
        if not gradient:
            return float((N * self.reference_length).sum()), None
        g = self.law.axial_stiffness(lam, self.EA)[:, None] * u  # d(N L)/dl = dN/dlam
        return float((N * self.reference_length).sum()), self.reduce_vector(np.concatenate([-g, g], axis=1))

    @property
    def span_rows(self) -> slice | np.ndarray:
        """Where the springs' rows go among the spans: `span`, or a slice when every span is a spring."""
        return slice(None) if len(self.span) == self.n_span else self.span  # (span: ascending, distinct)

    def scatter(self, x: np.ndarray) -> np.ndarray:
        """(B, k, ...) -> (B, n_span, ...), zeros for the other spans (x's dtype)."""
        if len(self.span) == self.n_span:
            return x
        out = np.zeros((x.shape[0], self.n_span) + x.shape[2:], dtype=x.dtype)
        out[:, self.span] = x
        return out

    def end_forces(self, X: np.ndarray, Xd: np.ndarray | None, gravity: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) force of each spring span on its end points (as `BeltSpans.end_forces`:
        internal + damping - weight of the lumped masses; zeros for the other spans), from end states
        X, Xd (B, k, 4)."""
        u, _, _, _, N = self.axial(X)
        if Xd is not None and self.damping_axial > 0.0:
            N = N + self.damping_force(X, Xd)
        return self._end_forces_of(u, N, gravity)

    def _end_forces_of(self, u: np.ndarray, N: np.ndarray, gravity: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) end forces [-N u - w, N u - w] (w: the lumped ends' weight) of chord directions
        u (B, k, 2) and axial forces N (B, k); zeros for the other spans."""
        w = self.end_mass[None, :, None] * np.asarray(gravity, dtype=float)
        Nu = N[..., None] * u
        rows = self.span_rows
        out = np.zeros((u.shape[0], self.n_span, 2, 2))
        out[:, rows, 0] = -Nu - w
        out[:, rows, 1] = Nu - w
        return out

    def end_inertia(self, Xa: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) inertia forces of the lumped masses, end accelerations Xa (B, k, 4)."""
        m = self.end_mass[None, :, None]
        return self.scatter(np.stack([m * Xa[..., 0:2], m * Xa[..., 2:4]], axis=2))

    def end_tensions(self, X: np.ndarray, F_end: np.ndarray) -> np.ndarray:
        """(B, n_span, 2) span tensions at the ends of the spring spans (zeros elsewhere) from the end
        forces F_end (B, n_span, 2, 2): N_start = -F_start . u, N_end = F_end . u."""
        return self._end_tensions_of(self.chord(X)[0], F_end)

    def _end_tensions_of(self, u: np.ndarray, F_end: np.ndarray) -> np.ndarray:
        """`end_tensions` of the chord directions u (B, k, 2)."""
        rows = self.span_rows
        F = F_end[:, rows]
        out = np.zeros((u.shape[0], self.n_span, 2))
        out[:, rows, 0] = -np.einsum("bkd,bkd->bk", F[:, :, 0], u)
        out[:, rows, 1] = np.einsum("bkd,bkd->bk", F[:, :, 1], u)
        return out

    def static_ends(self, p: np.ndarray, gravity: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """At the joint coordinates p (n_dof,), the chord evaluated once: the spring spans' end forces
        (n_span, 2, 2) (`end_forces` without damping), their end tensions (n_span, 2) (`end_tensions`),
        zeros for the other spans, and sum_k N_k L_k (N m) (`tension_integral`)."""
        u, _, _, _, N = self.axial(self.positions(p)[None])
        F = self._end_forces_of(u, N, gravity)
        return F[0], self._end_tensions_of(u, F)[0], float((N[0] * self.reference_length).sum())

    def kinetic_energy_split(self, P: np.ndarray) -> np.ndarray:
        """(k, 2, B): the lumped masses' quadratic energy form dX^T M dX along (0) and across (1) the chord
        at p = 0 for joint motions P (B, n_dof) (as the belt's share splits, `System.kinetic_energies`):
        the end motions' components along t and n = z x t straight from P through the joints
        (frame x T, (k, end x t|n, m); T is zero in the padding columns, so the padding index may take any
        coordinate of P)."""
        k, m = self.idx.shape
        t = self.reference_direction
        frame = np.concatenate([t, t[:, ::-1] * NORMAL_SIGNS], axis=1).reshape(k, 1, 2, 2)  # (k, 1, t|n, 2), n = z x t
        tn = np.matmul(frame, self.T.reshape(k, 2, 2, m)).reshape(k, 4, m)  # rows: end 0 t, n, end 1 t, n
        ab = np.matmul(tn, P.take(self.idx, axis=1, mode="clip").transpose(1, 2, 0))  # (k, 4, B)
        ab *= ab
        e = ab[:, 0:2] + ab[:, 2:4]  # (k, t|n, B): both ends
        e *= self.end_mass[:, None, None]
        return e


def spring_joints(cfg: DriveConfig, dofs: DofMap, models: tuple[str, ...] | None = None) -> tuple | None:
    """What the configuration and the DOF map fix of the spring spans' joints, whatever the layout
    (`_spring_joints` of the spring spans; None without any): one analysis's builds share it
    (`DriveFacts.spring_joints`, handed to `build_springs`). models: cfg.span_models, if at hand."""
    models = cfg.span_models if models is None else models
    spans = tuple([s for s, m in enumerate(models) if m == "spring"])
    if not spans:
        return None
    idx, T, (at, pulley) = _spring_joints(dofs, spans, len(models))
    for a in (T, at, pulley):  # (idx is already)
        a.setflags(write=False)
    return idx, T, (at, pulley)


def build_springs(cfg: DriveConfig, layout: Layout, dofs: DofMap, *,
                  prestrain_stretch: float | np.ndarray = 1.0, direction: np.ndarray | None = None,
                  reference_length: np.ndarray | None = None, joints: tuple | None = None,
                  models: tuple[str, ...] | None = None) -> SpringSpans | None:
    """The spring spans of the configuration (None without any), on the layout's tangent points.
    direction: the layout's `span_direction`; reference_length (n_span,): every span's reference length at
    this prestrain_stretch (`BeltSpans.reference_length`); joints: `spring_joints` of cfg and dofs (not
    changed here); models: cfg.span_models; each if at hand."""
    spans = tuple([s for s, m in enumerate(cfg.span_models if models is None else models) if m == "spring"])
    if not spans:
        return None
    n = layout.n
    if joints is None:
        idx, T, (at, pulley) = _spring_joints(dofs, spans, n)
    else:  # (T filled below: a copy of the shared one)
        idx, T, (at, pulley) = joints[0], joints[1].copy(), joints[2]
    direction = layout.span_direction if direction is None else direction
    if reference_length is None:
        reference_length = layout.span_length / span_stretch_of(prestrain_stretch, n)
    start, end, start_normal, end_normal = layout.span_start, layout.span_end, layout.start_normal, layout.end_normal
    sp = np.arange(n) if len(spans) == n else np.array(spans, dtype=np.int64)  # (writable: `spring_kernel`)
    if len(spans) < n:  # (every span a spring: the layout's arrays as they are)
        reference_length, direction = reference_length[sp], direction[sp]
        start, end, start_normal, end_normal = start[sp], end[sp], start_normal[sp], end_normal[sp]
    # the rotation columns R (z x n) = R (-n_y, n_x) of each end (`joint_pairs`): the layout's
    normal = np.concatenate([start_normal, end_normal])  # (2k, 2)
    T.ravel()[at] = (normal[:, ::-1] * NORMAL_SIGNS * layout.radius[pulley][:, None]).ravel()
    return SpringSpans(span=sp, T=T, idx=idx, x0=np.concatenate([start, end], axis=1),
                       reference_length=reference_length, reference_direction=direction, EA=float(cfg.belt.EA),
                       rho=float(cfg.belt.mass_per_length), n_dof=dofs.n, n_span=n, damping_axial=0.0,
                       EI=float(cfg.belt.EI), curvature=cfg.model.curvature, axial_law=cfg.belt.axial_law)


def _spring_joints(dofs: DofMap, spans: tuple[int, ...], n: int) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The parts of the spring spans' joints that the DOF map fixes (`joint_pairs`): idx (k, m) the joint
    coordinates of each span, its start's columns (rotation, then the pulley's translations) before its
    end's, padded with n_dof (read-only); T (k, 4, m) with the translations' directions and zero rotation
    columns (a new array, for the caller to fill); and where the rotation columns' entries are in T's
    flat order ((4k,): the x and y rows of each end) and their pulleys (2k,), the k starts, then the k ends."""
    k = len(spans)
    ends = [(s, (s + 1) % n) for s in spans]
    m = max(2 + len(dofs.trans_dof[a]) + len(dofs.trans_dof[b]) for a, b in ends)
    T = np.zeros((k, 4, m))
    idx = np.full((k, m), dofs.n, dtype=np.int64)
    rot_col = ([], [])  # the rotation's column of each span's start and end
    for i, pair in enumerate(ends):
        col = 0
        for side, j in enumerate(pair):
            rot_col[side].append(col)
            idx[i, col] = dofs.rot_dof[j]
            for col, (dof, v) in enumerate(zip(dofs.trans_dof[j], dofs.trans_dir[j]), start=col + 1):
                idx[i, col] = dof
                T[i, 2 * side: 2 * side + 2, col] = v
            col += 1
    idx.setflags(write=False)
    sp = np.array(spans, dtype=np.int64)
    # T's flat index of each rotation column's x and y entry: the k starts, then the k ends
    at = np.array([(4 * i + 2 * side + r) * m + rot_col[side][i] for side in (0, 1) for i in range(k) for r in (0, 1)],
                  dtype=np.intp)
    return idx, T, (at, np.concatenate([sp, (sp + 1) % n]))
