"""The transient's iteration matrix S and its band factor (`band_factor`, `factorizer`,
`IterationPlan`): assembled at the current state on a fixed pattern and factorized in the band
order of `transient_setup.band_order`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from beltdyn.config import TransientOptions
from beltdyn.model.system import System
from beltdyn.analysis.transient_setup import TransientSetup, p_to_q, transport_speed


def band_factor(S, perm: np.ndarray, u: int, *, symmetric: bool, hold: np.ndarray | None = None,
                diagonal: np.ndarray | None = None):
    """Factor S (dense or sparse; + `diagonal` (n,) if given) in RCM order with the DOFs `hold` held
    (their rows and columns replaced by the identity): band Cholesky when symmetric positive definite,
    else band LU without row exchanges (`integrator.band_lu_nopivot`: the running belt's S, whose
    symmetric part is positive definite; its U has u superdiagonals, half of what partial pivoting
    leaves, so each Newton solve costs a third less), and band LU with partial pivoting (LAPACK
    dgbtrf) when a pivot is not positive. Returns an integrator.Factor."""
    from scipy.linalg import cholesky_banded
    from scipy.linalg.lapack import dgbtrf
    from scipy.sparse import issparse

    from beltdyn.analysis.integrator import Factor

    n = S.shape[0]
    if issparse(S):
        C = S.tocoo()
        row, col, val = C.row, C.col, C.data
    else:
        row, col = np.nonzero(np.asarray(S))
        val = np.asarray(S)[row, col]
    if hold is not None and len(hold):
        held = np.zeros(n, dtype=bool)
        held[hold] = True
        keep = ~(held[row] | held[col])
        h_ = np.asarray(hold, dtype=row.dtype)
        row, col = np.concatenate([row[keep], h_]), np.concatenate([col[keep], h_])
        val = np.concatenate([val[keep], np.ones(len(h_))])
    inv = np.empty(n, dtype=np.int64)
    inv[perm] = np.arange(n)
    r, c = inv[row], inv[col]  # positions in RCM order (each (row, col) once: a CSR's or a dense array's entries)
    d = None
    if diagonal is not None:
        d = np.flatnonzero(diagonal if hold is None else np.where(np.isin(np.arange(n), hold), 0.0, diagonal))
    none = np.zeros(1, dtype=np.int64)
    if symmetric:
        ab = np.zeros((u + 1, n))
        mask = r <= c
        ab[u + r[mask] - c[mask], c[mask]] = val[mask]
        if d is not None:
            ab[u, inv[d]] += diagonal[d]
        try:
            return Factor(kind=0, ab=np.asfortranarray(cholesky_banded(ab, lower=False, check_finite=False)),
                          piv=none, perm=perm, kl=0, ku=u)
        except np.linalg.LinAlgError:
            pass
    from beltdyn.analysis.integrator import band_lu_nopivot

    ab = np.zeros((2 * u + 1, n), order="F")  # without row exchanges: U keeps the band (module docstring)
    ab[u + r - c, c] = val
    if d is not None:
        ab[u, inv[d]] += diagonal[d]
    if band_lu_nopivot(ab, u) == n:
        return Factor(kind=2, ab=ab, piv=none, perm=perm, kl=u, ku=u)
    ab = np.zeros((3 * u + 1, n))  # a pivot not positive: partial pivoting (its U has 2u superdiagonals)
    ab[2 * u + r - c, c] = val
    if d is not None:
        ab[2 * u, inv[d]] += diagonal[d]
    lu, piv, info = dgbtrf(ab, u, u, overwrite_ab=True)
    if info > 0:
        raise np.linalg.LinAlgError(f"singular iteration matrix (pivot {info})")
    # both factors column-major (the solves run down the columns), so the stepper has one signature
    return Factor(kind=1, ab=np.asfortranarray(lu), piv=piv.astype(np.int64), perm=perm, kl=u, ku=u)


def _belt_damping_matrix(system: System, setup: TransientSetup, q: np.ndarray, p: np.ndarray):
    """The belt's Kelvin-Voigt damping matrix dN_d/dq' at q (p = system.expand(q)) on the system's pattern,
    from the compiled element kernel; None without belt damping."""
    from beltdyn.model import belt_kernel as bk

    b = setup.belt
    if not (b.eta_a or b.eta_b):
        return None
    E = system.belt.element_coordinates(p)
    Ce = np.empty((E.shape[0], 8, 8))
    bk.element_damping_matrix(E, b.dS, b.d2S, b.wEA, b.wEI, b.Kb, b.curvature, b.eta_a, b.eta_b, Ce,
                              system.belt.kernel_scratch())
    return system.belt_damping_matrix(q, Ce)


def sticking(arms, q: np.ndarray) -> np.ndarray:
    """(a,) bool: the arms' bristles strictly inside their limits, -T_down < k_b (phi - z) < T_up (stepper
    `Arms`, q the state's head on the independent coordinates)."""
    tau = arms.bristle * (q[arms.dof] - arms.anchor)
    return (tau < arms.friction_up) & (tau > -arms.friction_down)


def _iteration_matrix(system: System, setup: TransientSetup, q: np.ndarray, h: float, rho_inf: float,
                      v: np.ndarray | None = None, arms=None, t: float = 0.0):
    """S = c_m M + c_c (C + C_belt(q) + c G) + (1 - alpha_f) (K_t(q) - c^2 B + c' A) on q (prescribed DOFs
    are held by `band_factor`); c, c' the belt speed and its rate at t (no transport terms at rest).
    The terms are summed on the joint coordinates p, where they share the system's pattern (their data
    added), and projected once: J^T S_p J with the arms' geometric term of (1 - alpha_f) times the loaded
    internal force (as `System.equilibrium`). Returns (S, diagonal): the arms' sticking bristles k_b as a
    diagonal (n_dof,) to add, or None."""
    from beltdyn.analysis.integrator import alpha_parameters

    am, af, beta, gamma = alpha_parameters(rho_inf)
    c_m = (1.0 - am) / (beta * h * h)
    c_c = (1.0 - af) * gamma / (beta * h)
    q = q[: system.n_dof]  # the stepper's state is on the joint coordinates: q is its head
    at_rest = system.with_speed(0.0) if system.belt_speed else system  # the transport terms: below, at t
    p = system.expand(q)
    f, K = at_rest.belt_force_and_tangent(p)  # + the components' constant stiffness
    terms = [((1.0 - af), K), (c_m, system.mass)]
    tr = setup.transport
    if tr is not None and (tr.follow or tr.speed):
        c, cd = (float(x[0]) for x in transport_speed(setup, np.array([t])))
        A, B, _, _ = system.transport_matrices()
        G = A - A.T  # (per factor: a few a run; the system is frozen, nothing is cached in it)
        terms += [(c_c * c, G), ((1.0 - af) * cd, A), (-(1.0 - af) * c * c, B)]
    C_belt = _belt_damping_matrix(system, setup, q, p)
    if C_belt is not None:
        terms.append((c_c, C_belt))
    if setup.C is not None:
        terms.append((c_c, setup.C))
    S = _weighted_sum(terms)
    if system.arms is not None:
        f_loaded = f + system.linear_force(p) - system.external_force(1.0)
        S = system.arms.project_matrix(q, S, (1.0 - af) * f_loaded, dense=system.dense)
    diagonal = None
    if arms is not None and (np.any(arms.friction_up) or np.any(arms.friction_down)):  # a sticking bristle is
        diagonal = np.zeros(system.n_dof)  # a spring k_b on the arm angle
        diagonal[arms.dof] = (1.0 - af) * np.where(sticking(arms, q), arms.bristle, 0.0)
    return S, diagonal


def stepper_system(system: System, opts: TransientOptions) -> System:
    """The system the stepper evaluates: the compiled belt kernel (thousands of evaluations, see
    system.BeltSpans) with the run's belt damping."""
    return system.with_belt(damping_axial=float(opts.damping.belt_axial),
                            damping_bending=float(opts.damping.belt_bending), compiled=True)


def factorizer(system: System, setup: TransientSetup, rho_inf: float, arms, *, plan: bool = True) -> Callable:
    """factor(q, h, v=None, t=0.0) -> integrator.Factor of the iteration matrix at the state q for the
    step h at time t: by the run's `IterationPlan` where it applies (plan=True), else (or when its
    factorization needs row exchanges) `band_factor` of `_iteration_matrix`. `system` as
    `stepper_system` gives it."""
    tr = setup.transport
    symmetric = tr is None or not (tr.follow or tr.speed)  # the gyroscopic term makes S non-symmetric: band LU
    fast = IterationPlan.build(system, setup, rho_inf, arms, symmetric=symmetric) if plan else None

    def factor(q, h, v=None, t=0.0):
        got = fast.factor(q, h, t) if fast is not None else None
        if got is not None:
            return got
        S, diagonal = _iteration_matrix(system, setup, q, h, rho_inf, v, arms, t)
        return band_factor(S, setup.perm, setup.bandwidth, symmetric=symmetric, hold=setup.constraints.dof,
                           diagonal=diagonal)

    factor.plan = fast
    return factor


@dataclass(frozen=True, kw_only=True)
class IterationPlan:
    """`_iteration_matrix` + `band_factor` for one run, assembled straight into band storage.

    Every term of S lives on the system's joint pattern (CSR slots, `system.Pattern`): the belt's
    tangent (and damping) through their assembly, the constant matrices (mass, components' damping,
    the running belt's A, G = A - A^T, B) mapped onto it once. Each pattern entry (i, j) has, once for
    the run, its place in the band of S on q: the arms' offsets folded onto their angle, the order
    `perm`, the held DOFs' rows and columns dropped. A factorization then sums the terms' data with
    their weights, scales the arm rows and columns by dc/dphi, and scatters them into the band in
    one pass (numpy), instead of summing, projecting and converting scipy matrices: ~0.15 instead of
    ~0.55 ms on the FEAD example, so the refresh rule (`integrator.run_steps`) affords more factors
    and the Newton iterations fewer. Same matrix (summed in another order: round-off).
    A dense system (a few DOFs, `system.DENSE_LIMIT`) has as its pattern the entries of its matrices that
    the band holds (the coupling graph `transient_setup.band_order` measured the band on).
    `build` returns None where it does not apply (a matrix off the pattern, an entry outside the band):
    `band_factor(_iteration_matrix(...))` then.

    The band may hold more coordinates than the system's q (`order`: the stepper's band order, e.g. the
    slipping wraps' hubs after the system's DOFs, `transient_wraps.band_order`): the system's terms go to
    their q's places, and `place` gives the places of the other entries, which `wrap_factorizer` adds to
    `band` before `factor_band`."""

    system: System  # as `stepper_system` gives it
    at_rest: System  # the same without the belt speed (the transport terms are added at their time)
    setup: TransientSetup
    arms: tuple  # integrator.Arms (their bristles' anchors: the state of the run)
    symmetric: bool  # band Cholesky (upper, u + 1 rows), else LU without row exchanges (2 u + 1 rows)
    dense: bool  # the system's matrices are dense arrays: the pattern is their entries within the band
    n: int  # DOFs of q (the system's)
    n_band: int  # columns of the band: the stepper's coordinates (the system's q first, then any wrap's hub)
    u: int  # half-bandwidth
    height: int  # rows of the band storage
    perm: np.ndarray  # (n_band,) the band order (the stepper's coordinate at each position)
    inv: np.ndarray  # (n_band,) each stepper coordinate's position in the band order
    const: dict  # name -> (nnz,) data on the joint pattern: M, C (and A, G, B when the belt runs)
    moving: bool  # the transport terms are in
    entries: np.ndarray  # (k,) the pattern entries that go into the band (held rows/columns out)
    flat: np.ndarray  # (k,) their places in the band storage, column-major, flattened
    rows_p: np.ndarray  # (nnz,) row of each pattern entry (joint coordinates)
    cols_p: np.ndarray  # (nnz,) its column
    diag: np.ndarray  # (n_band,) the flat place of each coordinate's diagonal
    held: np.ndarray  # (h,) the held (prescribed) DOFs: identity
    alpha: tuple  # (alpha_m, alpha_f, beta, gamma)

    @classmethod
    def build(cls, system: System, setup: TransientSetup, rho_inf: float, arms, *, symmetric: bool,
              order: tuple[np.ndarray, int, np.ndarray] | None = None):
        """The plan of the run, or None where it does not apply. order: (perm (n_band,), half-bandwidth,
        held DOFs) of the stepper's coordinates, the system's q (n_dof,) first (default: the system's own,
        `setup.perm`, `setup.bandwidth`, `setup.constraints.dof`)."""
        from scipy.sparse import coo_matrix, issparse

        pat = system.pattern
        n_p, n = system.n_p, system.n_dof
        to_q = p_to_q(system)
        perm, u, hold = order if order is not None else (setup.perm, setup.bandwidth, setup.constraints.dof)
        n_band = len(perm)
        inv = np.empty(n_band, dtype=np.int64)
        inv[perm] = np.arange(n_band)
        held = np.zeros(n_band, dtype=bool)
        held[hold] = True
        dense = bool(system.dense or pat.indptr is None)
        if dense:  # the entries of a dense system's matrices that the band can hold (the others: zeros)
            grid_r, grid_c = np.divmod(np.arange(n_p * n_p, dtype=np.int64), n_p)
            live = np.abs(inv[to_q[grid_r]] - inv[to_q[grid_c]]) <= u
            rows_p, cols_p = grid_r[live], grid_c[live]
            nnz = len(rows_p)
        else:
            nnz = pat.nnz
            rows_p = np.repeat(np.arange(n_p, dtype=np.int64), np.diff(pat.indptr))
            cols_p = np.asarray(pat.indices, dtype=np.int64)
        keys = rows_p * (n_p + 1) + cols_p

        def on_pattern(A):
            """A's entries as data on the pattern (None if one lies off it)."""
            if A is None:
                return np.zeros(nnz)
            if dense:
                full = A.toarray() if issparse(A) else np.asarray(A, dtype=float)
                out = full[rows_p, cols_p]
                return out if np.count_nonzero(out) == np.count_nonzero(full) else None
            C = coo_matrix(A)
            C.sum_duplicates()
            live = C.data != 0.0
            r, c, v = C.row[live].astype(np.int64), C.col[live].astype(np.int64), C.data[live]
            where = pat.slots_of(r, c)
            if np.any(where >= nnz) or not np.array_equal(keys[np.minimum(where, nnz - 1)], r * (n_p + 1) + c):
                return None
            out = np.zeros(nnz)
            np.add.at(out, where, v)
            return out

        at_rest = system.with_speed(0.0) if system.belt_speed else system
        const = {"M": on_pattern(system.mass), "C": on_pattern(setup.C)}
        tr = setup.transport
        moving = tr is not None and bool(tr.follow or tr.speed)
        if moving:
            A, B, _, _ = system.transport_matrices()
            const.update(A=on_pattern(A), G=on_pattern(A - A.T), B=on_pattern(B))
        if any(v is None for v in const.values()):
            return None
        r, c = inv[to_q[rows_p]], inv[to_q[cols_p]]
        keep = ~held[to_q[rows_p]] & ~held[to_q[cols_p]]
        if np.abs(r - c)[keep].max(initial=0) > u:
            return None
        height = u + 1 if symmetric else 2 * u + 1  # upper Cholesky band, or LU without row exchanges
        if symmetric:
            keep &= r <= c
        diag = inv * height + u  # the flat place of each q's diagonal
        from beltdyn.analysis.timestep import alpha_parameters

        return cls(system=system, at_rest=at_rest, setup=setup, arms=arms, symmetric=symmetric, dense=dense, n=n,
                   n_band=n_band,
                   u=int(u), height=height, perm=np.asarray(perm, dtype=np.int64), inv=inv, const=const,
                   moving=moving, entries=np.flatnonzero(keep), flat=(c * height + u + r - c)[keep], rows_p=rows_p,
                   cols_p=cols_p, diag=diag,
                   held=np.asarray(hold, dtype=np.int64), alpha=alpha_parameters(rho_inf))

    def factor(self, q: np.ndarray, h: float, t: float = 0.0):
        """The integrator.Factor of S at the state q (n_dof,) for the step h at time t."""
        return self.factor_band(self.band(q, h, t))

    def place(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(flat, keep) (m,): the places in `band`'s flat storage of the entries (rows, cols) (m,) on the
        stepper's coordinates, and whether each goes in (not on a held row or column; symmetric: the
        upper triangle of the band order only). Every entry must lie within the band."""
        r, c = self.inv[rows], self.inv[cols]
        if np.abs(r - c).max(initial=0) > self.u:
            raise ValueError("an entry outside the iteration matrix's band")
        held = np.zeros(self.n_band, dtype=bool)
        held[self.held] = True
        keep = ~held[rows] & ~held[cols]
        if self.symmetric:
            keep &= r <= c
        return c * self.height + self.u + r - c, keep

    def _on_pattern(self, A) -> np.ndarray:
        """(nnz,) the data of a matrix the system assembled (a CSR on its pattern, or a dense array)."""
        if self.dense:
            return A[self.rows_p, self.cols_p]
        if len(A.data) != len(self.rows_p):
            raise AssertionError("a matrix off the joint pattern")
        return A.data

    def band(self, q: np.ndarray, h: float, t: float = 0.0) -> np.ndarray:
        """S at the state q (the system's q first) for the step h at time t in band storage, flat
        (n_band * height,): column j of the band order at [j * height, (j + 1) * height), the held DOFs'
        rows and columns the identity. `factor_band` factorizes it (in place for the LU)."""
        am, af, beta, gamma = self.alpha
        c_m = (1.0 - am) / (beta * h * h)
        c_c = (1.0 - af) * gamma / (beta * h)
        system, setup, k = self.system, self.setup, self.const
        q = q[: self.n]
        p = system.expand(q)
        f, K = self.at_rest.belt_force_and_tangent(p)  # on the pattern (+ the components' constant stiffness)
        data = (1.0 - af) * self._on_pattern(K) + c_m * k["M"] + c_c * k["C"]
        if self.moving:
            c, cd = (float(x[0]) for x in transport_speed(setup, np.array([t])))
            data += (c_c * c) * k["G"] + ((1.0 - af) * cd) * k["A"] - ((1.0 - af) * c * c) * k["B"]
        C_belt = _belt_damping_matrix(system, setup, q, p)
        if C_belt is not None:
            data += c_c * self._on_pattern(C_belt)
        arms, a = self.arms, system.arms
        if a is not None:  # J^T S J: the arm offsets' rows and columns scaled by dc/dphi, folded onto the angle
            phi = a.phi(q)
            w = np.ones(system.n_p)
            dc = a.first(phi)
            w[a.slot], w[a.slot + 1] = dc[:, 0], dc[:, 1]
            data = data * w[self.rows_p] * w[self.cols_p]
        ab = np.bincount(self.flat, weights=data[self.entries], minlength=self.height * self.n_band)
        if a is not None:
            f_loaded = f + system.linear_force(p) - system.external_force(1.0)
            geo = np.einsum("kd,kd->k", a.second(phi), f_loaded[a.n_q:].reshape(len(a.dof), 2))
            np.add.at(ab, self.diag[a.dof], (1.0 - af) * geo)  # the geometric term of the loaded force
            if np.any(arms.friction_up) or np.any(arms.friction_down):  # a sticking bristle is a spring k_b
                np.add.at(ab, self.diag[arms.dof], (1.0 - af) * np.where(sticking(arms, q), arms.bristle, 0.0))
        ab[self.diag[self.held]] = 1.0  # held DOFs: identity
        return ab

    def factor_band(self, ab: np.ndarray):
        """The integrator.Factor of a flat band of `band` (the LU overwrites it), None where it needs row
        exchanges or is not positive definite (then `band_factor`)."""
        from beltdyn.analysis.integrator import Factor, band_lu_nopivot

        ab = ab.reshape(self.n_band, self.height).T  # (height, n_band), column-major
        perm, none, u = self.perm, np.zeros(1, dtype=np.int64), self.u
        if self.symmetric:
            from scipy.linalg import cholesky_banded

            try:
                return Factor(kind=0, ab=np.asfortranarray(cholesky_banded(ab, lower=False, check_finite=False)),
                              piv=none, perm=perm, kl=0, ku=u)
            except np.linalg.LinAlgError:
                return None
        ab = np.asfortranarray(ab)
        if band_lu_nopivot(ab, u) == self.n_band:
            return Factor(kind=2, ab=ab, piv=none, perm=perm, kl=u, ku=u)
        return None  # a pivot not positive: `band_factor` (partial pivoting)


def _weighted_sum(terms):
    """sum_k w_k A_k of dense arrays or CSR matrices; CSR ones on one pattern (the same indptr and
    indices, as `System.assemble` gives) by adding their data, others by scipy."""
    first = terms[0][1]
    if not hasattr(first, "tocsr"):
        out = terms[0][0] * np.asarray(first, dtype=float)
        for w, A in terms[1:]:
            out = out + w * (A.toarray() if hasattr(A, "toarray") else np.asarray(A))
        return out
    from scipy.sparse import csr_matrix

    first = csr_matrix(first)
    data = terms[0][0] * first.data
    rest = None
    for w, A in terms[1:]:
        A = csr_matrix(A)
        if A.indptr is first.indptr or (A.nnz == first.nnz and np.array_equal(A.indptr, first.indptr)
                                        and np.array_equal(A.indices, first.indices)):
            data = data + w * A.data
        else:
            rest = w * A if rest is None else rest + w * A
    S = csr_matrix((data, first.indices, first.indptr), shape=first.shape)
    return S if rest is None else S + rest


def wrap_factorizer(system: System, setup: TransientSetup, rho_inf: float, arms, slip, wraps, *, perm: np.ndarray,
                    bandwidth: int, hold: np.ndarray, plan: bool = True) -> Callable:
    """factor(q, h, v=None, t=0.0) of the stepper with slipping wraps (`transient_wraps`) at the state q
    (n_dof + k + offsets,) for the step h at time t: the system's iteration matrix S (`_iteration_matrix`) on
    the stepper's q (n_dof + k,), each pulley's inertia J and damping d moved from its wrap angle psi onto
    its own rotation theta (c_m J + c_c d), the belt on the wrap added to psi (`WrapSlip.belt_inertia`), and a sticking wrap's bristle (1 - alpha_f) k_b [[1, -1], [-1, 1]]
    on (psi, theta) (none while it slides: its torque is the constant capstan limit over the step).
    Sticking or sliding as the stepper's last evaluation found it (`Wraps.sliding`, copied into
    `Wraps.factored`; the Newton corrections follow later changes by a low-rank update of the solve,
    `friction_kernel.regime_correction`). Assembled by the run's `IterationPlan` on the stepper's band order where
    it applies (plan=True: the fast path of the runs without slip), else (or when its factorization needs row
    exchanges) by `band_factor` of the scipy sum. wraps: the stepper's `Wraps` (its state)."""
    from scipy.sparse import coo_matrix, csr_matrix

    from beltdyn.analysis.timestep import alpha_parameters

    am, af, beta, gamma = alpha_parameters(rho_inf)
    tr = setup.transport
    symmetric = tr is None or not (tr.follow or tr.speed)  # the gyroscopic term makes S non-symmetric: band LU
    n, k = system.n_dof, slip.n
    rows, cols = np.r_[slip.wrap, slip.hub, slip.wrap, slip.hub], np.r_[slip.wrap, slip.hub, slip.hub, slip.wrap]
    fast = IterationPlan.build(system, setup, rho_inf, arms, symmetric=symmetric,
                               order=(perm, bandwidth, hold)) if plan else None
    if fast is not None:
        slots, keep = fast.place(rows, cols)  # each wrap's (psi, theta) block in the band

    def factor(q, h, v=None, t=0.0):
        c_m = (1.0 - am) / (beta * h * h)
        c_c = (1.0 - af) * gamma / (beta * h)
        move = c_m * slip.inertia + c_c * slip.damping
        wraps.factored[:] = wraps.sliding  # the regime the last evaluation found (the stepper compares)
        kb = (1.0 - af) * np.where(wraps.factored > 0.0, 0.0, wraps.bristle)
        stays = c_m * slip.belt_inertia + c_c * slip.belt_damping  # the belt on the wrap stays on psi
        block = np.r_[kb - move + stays, kb + move, -kb, -kb]
        if fast is not None:
            ab = fast.band(q, h, t)
            np.add.at(ab, slots[keep], block[keep])
            got = fast.factor_band(ab)
            if got is not None:
                return got
        S, diagonal = _iteration_matrix(system, setup, q, h, rho_inf, v, arms, t)
        C = coo_matrix(S)
        S_all = csr_matrix((np.r_[C.data, block], (np.r_[C.row, rows], np.r_[C.col, cols])), shape=(n + k, n + k))
        d_all = None if diagonal is None else np.r_[diagonal, np.zeros(k)]
        return band_factor(S_all, perm, bandwidth, symmetric=symmetric, hold=hold, diagonal=d_all)

    factor.plan = fast
    return factor
