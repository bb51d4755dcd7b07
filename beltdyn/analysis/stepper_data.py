"""The stepper's data: the named structures handed to the compiled stepper (`integrator`) and the
numpy functions that build them (band/listed split of the constant matrices, CSR, fused patterns,
placeholders, the scratch). numba reads the namedtuples by attribute; numba-free."""

from __future__ import annotations

from collections import namedtuple

import numpy as np

# Named structures handed to the compiled stepper (numba reads namedtuples by attribute).
BeltData = namedtuple("BeltData", ["e0", "T", "idx", "tsel", "dS", "d2S", "wEA", "wEI", "EA", "Kb", "curvature",
                                   "eta_a", "eta_b", "elem_span", "n_span", "springs", "n_springs"])
# springs: spring_kernel.SpringData, n_springs their number (the kernels read `springs` only where there are some:
# each read of a struct is a reference count per array it holds)
Csr = namedtuple("Csr", ["indptr", "indices", "data"])
# A constant matrix A (n, n) of the stepper (`split`): its entries within w of the diagonal as a band (band
# (2 w + 1, n), band[k, i] = A[i, i - w + k], zeros where A has none), the others as lists in row-major
# order, left of the band (columns < i - w) and right of it (> i + w). `split_matvec` adds each row's
# products in ascending column order, as a CSR product does: the same floating-point result (the band's
# zeros add nothing), with the band vectorized across rows. The belt's M and C are banded in the system's
# DOF order (half-width 6-7) but for the few entries that close the belt loop: M a + C v 3x faster.
Coo = namedtuple("Coo", ["row", "col", "val"])
Split = namedtuple("Split", ["w", "band", "left", "right"])
Linear = namedtuple("Linear", ["K", "q_ref", "C", "M"])  # constant stiffness, its reference state, damping, mass
# (K, C, M: Split)
Forcing = namedtuple("Forcing", ["constant", "load_dof", "load_coef", "load_sig", "sig_params", "tab_ptr", "tab_t",
                                 "tab_v", "nominal_mass", "nominal_rotation", "nominal_scale",
                                 "nominal_damping"])  # nominal_damping (n,): C u_nom, the damping of the nominal travel
# dof (k,), params (k, 10): the rotation law (forcing_laws.rotation_state)
Constraints = namedtuple("Constraints", ["dof", "params"])
Check = namedtuple("Check", ["group", "n_groups", "tol", "max_iter", "noise"])
# refresh: the cost of a new factor in Newton iterations (0: refactorize only when convergence slows)
StepOptions = namedtuple("StepOptions", ["am", "af", "beta", "gamma", "t_stop", "dt_out", "max_steps", "refresh"])
Factor = namedtuple("Factor", ["kind", "ab", "piv", "perm", "kl", "ku"])  # kind 0 band Cholesky, 1 band LU (partial
# pivoting, LAPACK), 2 band LU without row exchanges (`band_lu_nopivot`)
State = namedtuple("State", ["q", "v", "a", "f0", "fd0", "F0", "R0", "scal"])
Outputs = namedtuple("Outputs", ["t", "q", "v", "a", "energy", "reaction", "n", "clutch", "wrap"])  # clutch
# (B, n_dec): the decouplers' torques (`Decouplers`); wrap (B, 4, max(k, 1)): the wraps' bristle torque and
# capstan limit (N m), creep rate z' (rad/s) and rim speed ratio (1) at the output times
Events = namedtuple("Events", ["data", "n", "slack"])
# the running belt's transport terms (module docstring): A, G = A - A^T, B (Csr, per unit speed) on the joint
# coordinates, a0, b0 (n,); the belt speed c = speed (follow = 0) or the nominal speed of the prescribed
# rotation (follow = 1: c = theta_nominal' * Forcing.nominal_scale)
# mag: M, A, G, B on their union pattern (`fused`), for one pass per Newton iteration (`fused_matvec`)
Transport = namedtuple("Transport", ["A", "G", "B", "a0", "b0", "speed", "follow", "mag"])
Fused = namedtuple("Fused", ["indptr", "indices", "data"])  # data (k, nnz): k matrices on one CSR pattern
# tensioner arms: q index of the angle, p index of the centre offset x (y: + 1), arm length, angle at q = 0,
# the dry friction torque limits of the bristle torque tau = k_b (phi - z): friction_up (tau > 0, the arm sliding
# counter-clockwise) and friction_down (its magnitude for tau < 0, clockwise), the bristle stiffness k_b and the
# anchor angle z (state); n_q the independent coordinates (p[:n_q] = q)
Arms = namedtuple("Arms", ["dof", "slot", "length", "angle", "friction_up", "friction_down", "bristle", "anchor",
                           "n_q"])
# decouplers with a one-way clutch (`model.decouplers`, `friction_kernel.clutch_torques`), k of them: hub (k,) the
# pulley's rotation DOF, rotor (k,) the rotor's, stiffness k and damping c of the spring (both also in the linear
# part: the engaged decoupler), drag (k,) the overrunning clutch's torque bound (tau >= -drag), slip (2, k) the
# clutch's slip angle z (row 0 at the accepted step, row 1 at the step being solved), torque (2, k) likewise tau
Decouplers = namedtuple("Decouplers", ["hub", "rotor", "stiffness", "damping", "drag", "slip", "torque"])
# The wraps that may slip (`transient_wraps`, docs/wraps.md): pulley j's rotation split in two, the wrap angle
# psi (the old rotation DOF, which the span ends follow: `wrap`) and the pulley's own rotation theta (a DOF
# `hub` added after the system's independent coordinates, with the pulley's inertia, damping, loads and
# prescribed rotation), joined by the elasto-plastic bristle M = clip(k_b (psi - theta - z), -M_cap, M_cap)
# (`friction_kernel.bristle`, the arms' one). M_cap = R (T_max - c) capstan, capstan = 1 - exp(-mu beta), T_max the
# larger end tension of the wrap's two spans at the last accepted step, c = rho v^2 lambda(T_max): `limit`
# (state). The end tensions: the true axial force at the span end, of the element (its end node's gradient:
# in_elem the arriving span's last element, out_elem the departing span's first; -1: a spring span) or of
# the spring span (in_spring, out_spring; -1: none). anchor z, limit and torque (the bristle torque at
# the last accepted step) are the state; preload (k,) the static torque the bristle carries at the start; sliding
# (k,) 1 where the last Newton evaluation found the bristle at its limit, factored (k,) the regime the current
# iteration matrix holds (its sticking stiffness: `transient_factor.wrap_factorizer`); the Newton corrections
# follow `sliding` by a low-rank update of the factor's solve (`friction_kernel.regime_correction`): update (k, n_q)
# the factor's solves S^-1 (e_psi - e_theta), updated (k,) 1 where that solve is of the current factor, small
# (k, k + 1) the scratch of the update's small system.
# Creep (docs/wraps.md "Creep in time"): travel (k,) rad/m, the pulley's nominal rotation per metre of belt travel
# (u_nom, signed +-1/R); ref_elem, ref_spring (2,): the driver's (the pulley carrying the nominal rotation) arriving
# span's last element and leaving span's first (or their spring spans; all -1: no driver, no creep), whose
# stretch at the driver's entry is the reference lambda_e,drv; ratio (k,) lambda_e,k / lambda_e,drv and creep (k,)
# z' = c u_k (1 - ratio) (rad/s, c the belt travel speed) at the last accepted step (state): the anchor drifts
# at z' over the next step, z = anchor + creep dt; step (1,) dt of the step the last Newton evaluation solved.
Wraps = namedtuple("Wraps", ["wrap", "hub", "radius", "capstan", "rho", "bristle", "anchor", "limit", "torque",
                             "preload", "in_elem", "out_elem", "in_spring", "out_spring", "sliding", "factored",
                             "update", "updated", "small", "travel", "ref_elem", "ref_spring", "ratio", "creep",
                             "step"])
# The stepper's model, its named parts built in one place (`transient.stepper_model`): the belt (BeltData),
# the linear part (Linear), forcing (Forcing), constraints (prescribed rotations, Constraints), the convergence
# check (Check), the arms with their dry friction (Arms), the running belt's transport (Transport), the
# decouplers' clutches (Decouplers) and the wraps that may slip (Wraps).
StepperModel = namedtuple("StepperModel", ["belt", "linear", "forcing", "constraints", "check", "arms", "transport",
                                           "decouplers", "wraps"])
ARM_PRESLIDING = 1e-3  # rad (0.06 deg): presliding angle of the arm's dry friction (bristle stiffness: the larger
# of the two limits / this);
# 1e-4 rad gave the same hysteresis (0.1 %) and cost 20 % more Newton work on the FEAD example

# The stepper's scratch, allocated once per run by `workspace` and cleared at every call of `advance`:
# the compiled kernels allocate nothing, so that the cached library names no numba array module (a
# cache hit imports the modules its functions' environments name: np.empty, np.zeros, np.interp and
# np.finfo would bring numba's array modules, ~30 ms of a short command's start). Rows of:
# ext (5, n + 1): q_ext, v_ext, f_el, f_dmp, gross (the padded vectors of `belt_kernel`);
# vec (17, n): F1, q1, v1, a1, dq, Ma, Ma0, Cv, Cv0, Kd, fi, fl, tmp, tmp2, f_tr, tr_Bq, tr_Aq;
# proj (13, nq): R, dx, work and, with arms, the terms projected on q (`run_steps`);
# elem (4, n_elem, 8): E, Ed, fe, fd; elem1 (2, n_elem): U, min_elem; group (3, n_groups): res_g,
# scale_g, floor_g; worst (n_groups,) int64; sig (n_signals,); react (max(n_con, 1),) R1; span
# (max(n_span, 1),) min_span; held (nq,) int64: 1 on the prescribed DOFs (set by `run_steps`).
Work = namedtuple("Work", ["ext", "vec", "proj", "elem", "elem1", "group", "worst", "sig", "react", "span", "held"])


def no_arms(n: int) -> Arms:
    return Arms(dof=np.zeros(0, dtype=np.int64), slot=np.zeros(0, dtype=np.int64), length=np.zeros(0),
                angle=np.zeros(0), friction_up=np.zeros(0), friction_down=np.zeros(0), bristle=np.zeros(0), anchor=np.zeros(0), n_q=n)


def no_decouplers() -> Decouplers:
    """No one-way decoupler."""
    return Decouplers(hub=np.zeros(0, dtype=np.int64), rotor=np.zeros(0, dtype=np.int64), stiffness=np.zeros(0),
                      damping=np.zeros(0), drag=np.zeros(0), slip=np.zeros((2, 0)), torque=np.zeros((2, 0)))


def no_wraps() -> Wraps:
    """No wrap may slip (rigid wraps, or no friction value): the stepper as without the part."""
    i, z = np.zeros(0, dtype=np.int64), np.zeros(0)
    return Wraps(wrap=i, hub=i.copy(), radius=z, capstan=z.copy(), rho=0.0, bristle=z.copy(), anchor=z.copy(),
                 limit=z.copy(), torque=z.copy(), preload=z.copy(), in_elem=i.copy(), out_elem=i.copy(),
                 in_spring=i.copy(), out_spring=i.copy(), sliding=z.copy(), factored=z.copy(),
                 update=np.zeros((0, 0)), updated=z.copy(), small=np.zeros((0, 1)), travel=z.copy(),
                 ref_elem=np.full(2, -1, dtype=np.int64), ref_spring=np.full(2, -1, dtype=np.int64), ratio=z.copy(),
                 creep=z.copy(), step=np.zeros(1))


def no_transport(n: int) -> Transport:
    """The belt at rest (no transport terms)."""
    return Transport(A=empty_csr(n), G=empty_csr(n), B=empty_csr(n), a0=np.zeros(n), b0=np.zeros(n), speed=0.0,
                     follow=0, mag=Fused(np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                         np.zeros((4, 0))))


def no_factor() -> Factor:
    """A placeholder factor with the types of `transient.band_factor`'s (for `advance`'s START task,
    which solves nothing: one compiled signature for both tasks)."""
    return Factor(kind=0, ab=np.zeros((2, 2), order="F"), piv=np.zeros(1, dtype=np.int64),
                  perm=np.zeros(2, dtype=np.int64), kl=0, ku=1)


def workspace(n: int, belt, forcing, cons, n_groups: int, arms) -> Work:
    """The stepper's scratch (`Work`) for n joint coordinates."""
    n_elem = belt.T.shape[0]
    return Work(ext=np.zeros((5, n + 1)), vec=np.zeros((17, n)), proj=np.zeros((13, int(arms.n_q))),
                elem=np.zeros((4, n_elem, 8)), elem1=np.zeros((2, n_elem)), group=np.zeros((3, n_groups)),
                worst=np.zeros(n_groups, dtype=np.int64), sig=np.zeros(forcing.sig_params.shape[0]),
                react=np.zeros(max(cons.dof.shape[0], 1)), span=np.zeros(max(belt.n_span, 1)),
                held=np.zeros(int(arms.n_q), dtype=np.int64))


def empty_csr(n: int) -> Csr:
    return Csr(np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0))


BAND_COST = 0.2  # the cost of a band entry in `split_matvec` relative to a listed one (measured: 0.17 ns vs ~1 ns)


def split(A, n: int) -> Split:
    """A (scipy, dense or None: zero) as a `Split`, its half-width w the cheapest for `split_matvec`
    (BAND_COST; w = -1: no band), the band holding at most about 4 x A's entries (memory)."""
    C = to_csr(A) if A is not None else empty_csr(n)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(C.indptr))
    off = C.indices - rows
    nnz = len(off)
    inside = np.cumsum(np.bincount(np.abs(off), minlength=n))  # entries with |offset| <= w
    widths = np.arange(min(n, 2 * nnz // n + 1))  # (2 w + 1) n <= 4 nnz + n
    cost = BAND_COST * (2 * widths + 1) * n + (nnz - inside[widths])
    w = int(np.argmin(cost)) if nnz and cost.min() < nnz else -1
    band = np.zeros((max(2 * w + 1, 0), n))
    near = np.abs(off) <= w
    band[off[near] + w, rows[near]] = C.data[near]

    def listed(mask):
        return Coo(row=rows[mask], col=C.indices[mask], val=C.data[mask])

    return Split(w=w, band=band, left=listed(off < -max(w, 0)), right=listed(off > w))  # (w = -1: all listed)


def split_matrix(S: Split, n: int):
    """The scipy CSR matrix (sorted indices) of a `Split`."""
    from scipy.sparse import csr_matrix

    k, i = np.nonzero(S.band)
    rows = np.concatenate([S.left.row, i, S.right.row])
    cols = np.concatenate([S.left.col, i + k - S.w, S.right.col])
    vals = np.concatenate([S.left.val, S.band[k, i], S.right.val])
    A = csr_matrix((vals, (rows, cols)), shape=(n, n))
    A.sort_indices()
    return A


def to_csr(A) -> Csr:
    from scipy.sparse import csr_matrix

    A = csr_matrix(A, copy=True)
    A.eliminate_zeros()  # a system's constant matrices live on the whole pattern: the springs are few
    A.sort_indices()
    return Csr(A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data.astype(np.float64))


def fused(*mats) -> Fused:
    """The matrices (scipy or dense, one shape) on the union of their nonzero patterns: data (k, nnz), zeros
    where a matrix has no entry."""
    from scipy.sparse import coo_matrix

    coos = [coo_matrix(A) for A in mats]
    for A in coos:  # a system's matrices live on its whole pattern: only their nonzeros count
        A.eliminate_zeros()
    n_row, n_col = coos[0].shape
    keys = [A.row.astype(np.int64) * n_col + A.col for A in coos]
    union = np.unique(np.concatenate(keys))
    data = np.zeros((len(coos), len(union)))
    for k, (A, key) in enumerate(zip(coos, keys)):
        np.add.at(data[k], np.searchsorted(union, key), A.data)
    indptr = np.zeros(n_row + 1, dtype=np.int64)
    np.add.at(indptr, union // n_col + 1, 1)
    return Fused(np.cumsum(indptr), (union % n_col).astype(np.int64), data)
