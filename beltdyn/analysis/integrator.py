"""Generalized-alpha (Chung-Hulbert 1993) stepper of a `System`, compiled with numba.

Equations of motion on the independent coordinates q (n,):
    M a + C v + f(q, v) = F(t),
f = f_belt(q) + f_damp(q, v) + K_lin (q - q_ref)  (belt elastic force of paper Eqs. 14/17 through
the joints and of the spring spans (`spring_kernel`, `BeltData.springs`), Kelvin-Voigt belt damping, the linear components' constant stiffness measured from the
reference state q_ref, usually the static equilibrium), F(t) = F_const + loads(t) - M u_nom s''(t)
with F_const = preload + weight - K_lin q_ref (the constant part; it balances f at the static
equilibrium, so no force of the size of a bearing preload ever enters a tolerance), C the constant
damping (Rayleigh + components; M, C and K_lin as `Split`: a band and the entries off it). Any number
of DOFs may be prescribed (constraint objects: the rotation law `rotation_state` per DOF); their
residual rows are dropped and their reactions recorded.

Generalized-alpha with spectral radius rho_inf:
    alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 - alpha_m + alpha_f,
    beta = (1 - alpha_m + alpha_f)^2 / 4,
    (1 - alpha_m) M a1 + alpha_m M a0 + (1 - alpha_f) (C v1 + f1 - F1) + alpha_f (C v0 + f0 - F0) = 0,
    q1 = q0 + h v0 + h^2 ((1/2 - beta) a0 + beta a1),  v1 = v0 + h ((1 - gamma) a0 + gamma a1).
Newton on q1 with a reused factorization of the iteration matrix
    S = (1 - alpha_m)/(beta h^2) M + (1 - alpha_f) gamma/(beta h) C_t + (1 - alpha_f) K_t,
given in band storage (RCM order): an upper Cholesky factor (symmetric S) or, for a non-symmetric S
(the running belt's transport terms), an LU factor without row exchanges (`band_lu_nopivot`: S's
symmetric part is positive definite, dominated by the mass term), with partial pivoting (LAPACK
dgbtrf) as the fallback when a pivot is not positive. The stepper returns
to Python when the factor is stale (slow convergence) or the step must be halved, and after an
accepted step once the factor has aged: the Newton iterations its steps took beyond what it took
fresh (the mean of its first REF_STEPS steps) add up, and when they cost more than a new factor
(StepOptions.refresh, the measured factor time over the measured time per residual evaluation) the
next step gets one (the rent-or-buy rule: never more than twice the cost of the best choice). On the
FEAD example at 6 m/s: 3.5 -> 2.7 iterations per step with ~120 factors in 10 000 steps.

Convergence per DOF group (span coordinates, rotations, translations, ...): in every group g,
    max_{i in g} |R_i| <= tol * s_g + floor_g,
s_g = max_{i in g} (|M a|_i + |C v|_i + |f_i - F_const,i| + |F_i - F_const,i|), the forces that
change in the run (constant preloads and the static belt tension excluded), and floor_g the
round-off: 1e3 machine epsilons of the largest gross force |T^T f_e| + |K (q - q_ref)| + |F_const|
in the group, plus the round-off of the Green-Lagrange strain, which loses ~eps of EA per Gauss
point whatever the force (noise = 100 eps EA sqrt(n_elem), and the linear bending force's share).

The running belt (`Transport`, see `running`): the spans' transport terms, constant CSR matrices
per unit speed on the joint coordinates scaled by the belt speed c(t) (constant, or the nominal
speed of the prescribed rotation: c = theta_nominal' / u_rot) and its rate c'(t):
    f_tr = c G v - c^2 (B q + b0) + c' (A q + a0),   G = A - A^T,
added to the internal force f; in the iteration matrix c G joins C and -c^2 B + c' A joins K_t (S is
then non-symmetric: band LU). Energy: the centripetal potential V_c = -c^2 (q.B q + 2 b0.q) / 2 joins
the strain energy; G does no work; while the speed changes, the power the drive spends on the belt's
transport, -c' (c (q.B q + 2 b0.q) + v.(A q + a0)), counts as work (trapezoid).

Energy balance at the steps (never at interpolated outputs): at each step that ends at or after an
output time, kinetic + strain (belt + linear components about q_ref) - work of the external forces
and reactions (trapezoid of the power over each step) + dissipated (belt and constant damping) -
initial = balance error.

Tensioner arms (`Arms`): the state q, v, a lives on the joint coordinates p = [q_ind, u] (see
system.ArmJoints): the independent coordinates first (n_q), then each arm pulley's centre offset u =
c(phi) - c(phi_ref), kept kinematically exact (`complete`: u, u' = c' phi', u'' = c' phi'' + c'' phi'^2).
Forces are evaluated on p and the residual projected on q by J(q)^T (`project`); the generalized-alpha
weights apply to the projected terms, each at its own time (Chung-Hulbert for nonlinear systems).
An arm's dry friction torque T_f is regularized as an elasto-plastic (bristle, Dahl-type) element: a
stiff torsion spring k_b = T_f / delta (presliding angle delta = `ARM_PRESLIDING`) from an anchor
angle z that slides when the torque reaches T_f (a return mapping after each accepted step):
torque = clip(k_b (phi - z), -T_f, T_f). It sticks exactly (no creep) and slides at exactly T_f;
its stiffness k_b enters the iteration matrix like a spring, not like a damper over the step, so the
stick-slip transitions keep the factor (a tanh(phi'/omega) law put T_f / omega / h there and forced
step halvings). Its work is dissipated, less the bristle's stored energy tau^2 / (2 k_b).

Array conventions: belt data as `belt_kernel` (T (n_elem, 8, m), idx (n_elem, m) with padding
index n, tsel, e0 (n_elem, 8), dS/d2S (n_elem, n_qp, 4), wEA/wEI (n_elem, n_qp), Kb (n_elem, 8, 8)).
"""

from __future__ import annotations

import sys
from collections import namedtuple

import numpy as np

from beltdyn import jitcache
from beltdyn.jitcache import configure, kernel_options


configure()  # where numba caches the kernels (the package folder, else a user cache folder): before numba loads
from numba import njit  # noqa: E402

from beltdyn.model import belt_kernel as bk
from beltdyn.model import spring_kernel as sk

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)

# tasks of `advance`, the stepper's one entry point from Python
START = 0  # the forces and energies of the initial state (`start_forces`)
STEP = 1  # integrate (`run_steps`)

# return codes of run_steps
DONE = 0  # reached t_stop
BUFFER_FULL = 1  # output buffer full: drain and call again
REFACTOR = 2  # convergence slowed (or the factor's extra iterations outweigh a new one): refactorize S at the
#              current state and call again
HALVE = 3  # no convergence with a fresh factor: halve the step, refactorize, call again
MAX_STEPS = 4  # step budget of this call used up (keeps Ctrl-C responsive)

# Named structures handed to the compiled stepper (numba reads namedtuples by attribute).
BeltData = namedtuple("BeltData", ["e0", "T", "idx", "tsel", "dS", "d2S", "wEA", "wEI", "EA", "Kb", "curvature",
                                   "eta_a", "eta_b", "elem_span", "n_span", "springs"])  # springs: spring_kernel.SpringData
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
                                 "tab_v", "nominal_mass", "nominal_rotation", "nominal_scale"])
Constraints = namedtuple("Constraints", ["dof", "params"])  # dof (k,), params (k, 9): rotation law (rotation_state)
Check = namedtuple("Check", ["group", "n_groups", "tol", "max_iter", "noise"])
# refresh: the cost of a new factor in Newton iterations (0: refactorize only when convergence slows)
StepOptions = namedtuple("StepOptions", ["am", "af", "beta", "gamma", "t_stop", "dt_out", "max_steps", "refresh"])
Factor = namedtuple("Factor", ["kind", "ab", "piv", "perm", "kl", "ku"])  # kind 0 band Cholesky, 1 band LU (partial
# pivoting, LAPACK), 2 band LU without row exchanges (`band_lu_nopivot`)
State = namedtuple("State", ["q", "v", "a", "f0", "fd0", "F0", "R0", "scal"])
Outputs = namedtuple("Outputs", ["t", "q", "v", "a", "energy", "reaction", "n"])
Events = namedtuple("Events", ["data", "n", "slack"])
# the running belt's transport terms (module docstring): A, G = A - A^T, B (Csr, per unit speed) on the joint
# coordinates, a0, b0 (n,); the belt speed c = speed (follow = 0) or the nominal speed of the prescribed
# rotation (follow = 1: c = theta_nominal' * Forcing.nominal_scale)
# mag: M, A, G, B on their union pattern (`fused`), for one pass per Newton iteration (`fused_matvec`)
Transport = namedtuple("Transport", ["A", "G", "B", "a0", "b0", "speed", "follow", "mag"])
Fused = namedtuple("Fused", ["indptr", "indices", "data"])  # data (k, nnz): k matrices on one CSR pattern
# tensioner arms: q index of the angle, p index of the centre offset x (y: + 1), arm length, angle at q = 0,
# dry friction torque, its bristle stiffness and anchor angle (state); n_q the independent coordinates (p[:n_q] = q)
Arms = namedtuple("Arms", ["dof", "slot", "length", "angle", "friction", "bristle", "anchor", "n_q"])
ARM_PRESLIDING = 1e-3  # rad (0.06 deg): presliding angle of the arm's dry friction (bristle stiffness T_f / this);
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
EPS = float(np.finfo(np.float64).eps)  # a constant to the compiled code (np.finfo there is numba's array module)



def no_arms(n: int) -> Arms:
    return Arms(dof=np.zeros(0, dtype=np.int64), slot=np.zeros(0, dtype=np.int64), length=np.zeros(0),
                angle=np.zeros(0), friction=np.zeros(0), bristle=np.zeros(0), anchor=np.zeros(0), n_q=n)


def no_transport(n: int) -> Transport:
    """The belt at rest (no transport terms)."""
    return Transport(A=empty_csr(n), G=empty_csr(n), B=empty_csr(n), a0=np.zeros(n), b0=np.zeros(n), speed=0.0,
                     follow=0, mag=Fused(np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                                         np.zeros((4, 0))))


# scal slots
T_NOW, H, T_OUT, WORK, DISS, STEPS, E0, WORST, MOVED, KIN0, POT0, ITERS, TR_P0, STALE, REF_SUM, REF_N = range(16)
N_SCAL = 16  # TR_P0: the transport power at the last accepted step; STALE, REF_SUM, REF_N: the factor's age
REF_STEPS = 4  # a new factor's first steps: their mean iterations are what the factor does fresh
ENERGY_TERMS = ("kinetic", "strain", "work", "dissipated", "balance_error")

from beltdyn.analysis.timestep import alpha_parameters  # noqa: E402,F401  (one definition, numba-free)


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


@njit(**KERNEL)
def csr_matvec(A, x, out):
    n = A.indptr.shape[0] - 1
    for i in range(n):
        s = 0.0
        for k in range(A.indptr[i], A.indptr[i + 1]):
            s += A.data[k] * x[A.indices[k]]
        out[i] = s


@njit(**KERNEL)
def table_value(xp, fp, a, b, x):
    """np.interp(x, xp[a:b], fp[a:b]) for one x, xp increasing (as numpy computes it: the end values
    outside, fp at a sample time, else the slope times the distance from the sample below; np.interp
    itself would make the cached stepper load numba's array modules, see `Work`)."""
    if b - a == 1 or x < xp[a]:
        return fp[a]
    if x >= xp[b - 1]:
        return fp[b - 1]
    lo, hi = a, b - 1  # xp[lo] <= x < xp[hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    if xp[lo] == x:
        return fp[lo]
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo])
    val = slope * (x - xp[lo]) + fp[lo]
    if val != val:  # NaN one way: the other (numpy's rule)
        val = slope * (x - xp[lo + 1]) + fp[lo + 1]
        if val != val and fp[lo] == fp[lo + 1]:
            val = fp[lo]
    return val


@njit(**KERNEL)
def split_matvec(S, x, out):
    """out = A x for A a `Split`: per row the left entries, the band, the right entries, in ascending
    column order (the floating-point result of `csr_matvec` on A's CSR)."""
    n = out.shape[0]
    for i in range(n):
        out[i] = 0.0
    L = S.left
    for e in range(L.row.shape[0]):
        out[L.row[e]] += L.val[e] * x[L.col[e]]
    w = S.w
    for k in range(2 * w + 1):
        off = k - w
        lo = max(0, -off)
        hi = min(n, n - off)
        ys = out[lo:hi]  # views from 0: the indices are provably >= 0 and the loop vectorizes
        xs = x[lo + off:hi + off]
        bs = S.band[k, lo:hi]
        for i in range(hi - lo):
            ys[i] += bs[i] * xs[i]
    R = S.right
    for e in range(R.row.shape[0]):
        out[R.row[e]] += R.val[e] * x[R.col[e]]


@njit(**KERNEL)
def signal_values(F, t, out):
    """out[i] = ramp_i(t) * (c + A sin(2 pi f t + phi)) or table interpolation; params (n, 5) = c, A, f, phi, T_ramp."""
    params = F.sig_params
    for i in range(params.shape[0]):
        a, b = F.tab_ptr[i], F.tab_ptr[i + 1]
        if b > a:
            val = table_value(F.tab_t, F.tab_v, a, b, t)
        else:
            val = params[i, 0] + params[i, 1] * np.sin(2.0 * np.pi * params[i, 2] * t + params[i, 3])
        tr = params[i, 4]
        if tr > 0.0 and t < tr:
            val *= t / tr
        out[i] = val


@njit(**KERNEL)
def smoothstep(t, tr):
    """C1 fade-in 3x^2 - 2x^3 over [0, tr] and its first two derivatives."""
    if tr <= 0.0 or t >= tr:
        return 1.0, 0.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    x = t / tr
    return x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x) / tr, (6.0 - 12.0 * x) / (tr * tr)


@njit(**KERNEL)
def rotation_state(rot, t):
    """Prescribed rotation: (nominal angle, speed, acceleration), (fluctuation angle, speed, acceleration).

    rot = [speed Omega, ramp T_r, angle amplitude A, speed amplitude B, frequency f, phase phi, fade T_f,
           static angle offset, engine order k] (the offset is added to the prescribed DOF by the caller).
    Nominal: speed ramps linearly to Omega over T_r. Fluctuation: w(t) * A sin(psi) for an angle
    amplitude, or the angle whose speed is w(t) * B sin(psi) (zero at t=0 for the unfaded part), w(t)
    the smoothstep fade-in over T_f. The phase psi = 2 pi f t + phi, or with an engine order k > 0
    psi = k theta_nominal(t) + phi (it follows the ramp). With an order, a speed amplitude is the
    angle (B / (k Omega)) (cos phi - cos psi): speed amplitude B at the mean speed, in proportion below.
    """
    om, tr, A, B, f, phi, tf, k = rot[0], rot[1], rot[2], rot[3], rot[4], rot[5], rot[6], rot[8]
    if tr > 0.0 and t < tr:
        th, thd, thdd = 0.5 * om * t * t / tr, om * t / tr, om / tr
    else:
        th, thd, thdd = om * (t - 0.5 * tr), om, 0.0
    if k > 0.0:
        psi, psid, psidd = k * th + phi, k * thd, k * thdd
    else:
        psi, psid, psidd = 2.0 * np.pi * f * t + phi, 2.0 * np.pi * f, 0.0
    if A != 0.0:
        g = A * np.sin(psi)
        gd = A * psid * np.cos(psi)
        gdd = A * (psidd * np.cos(psi) - psid * psid * np.sin(psi))
    elif B != 0.0 and (k > 0.0 or f > 0.0):
        c = B / (k * om) if k > 0.0 else B / psid
        g = c * (np.cos(phi) - np.cos(psi))
        gd = c * psid * np.sin(psi)
        gdd = c * (psidd * np.sin(psi) + psid * psid * np.cos(psi))
    else:
        g, gd, gdd = 0.0, 0.0, 0.0
    s, sd, sdd = smoothstep(t, tf)
    return th, thd, thdd, s * g, sd * g + s * gd, sdd * g + 2.0 * sd * gd + s * gdd


@njit(**KERNEL)
def band_cholesky_solve(ab, perm, b, x, work):
    """Solve S x = b with S[perm][:, perm] = U^T U, U in upper band storage ab (u+1, n), column-major:
    U^T y = b by columns of U (dot products, 4 partial sums: no chain of dependent additions), U x = y
    by column updates (`band_upper_solve`)."""
    u = ab.shape[0] - 1
    n = ab.shape[1]
    for i in range(n):
        work[i] = b[perm[i]]
    for j in range(n):  # U^T y = b: y_j = (b_j - sum_{i<j} U_ij y_i) / U_jj
        lo = max(0, j - u)
        m = j - lo
        col = ab[u - m:u, j]  # U[lo:j, j], and y[lo:j]: views from 0 (indices provably >= 0)
        ys = work[lo:j]
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        i = 0
        while i + 3 < m:
            s0 += col[i] * ys[i]
            s1 += col[i + 1] * ys[i + 1]
            s2 += col[i + 2] * ys[i + 2]
            s3 += col[i + 3] * ys[i + 3]
            i += 4
        while i < m:
            s0 += col[i] * ys[i]
            i += 1
        work[j] = (work[j] - ((s0 + s1) + (s2 + s3))) / ab[u, j]
    band_upper_solve(ab, u, work)  # U x = y
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def band_upper_solve(ab, u, work):
    """U x = y in place (work (n,)), U upper with u superdiagonals, U[i, j] = ab[u + i - j, j]
    (column-major): x_j, then its column leaves the rows above (column updates)."""
    n = ab.shape[1]
    for j in range(n - 1, -1, -1):
        xj = work[j] / ab[u, j]
        work[j] = xj
        lo = max(0, j - u)
        m = j - lo
        col = ab[u - m:u, j]  # U[lo:j, j], x[lo:j]: views from 0 (the update vectorizes)
        xs = work[lo:j]
        for i in range(m):
            xs[i] -= col[i] * xj


@njit(**KERNEL)
def band_lu_nopivot(ab, u):
    """LU factor without row exchanges, in place, of the band matrix A (n, n) held in ab (2u + 1, n)
    column-major, A[i, j] = ab[u + i - j, j] for |i - j| <= u: L unit lower (its multipliers below the
    diagonal), U on and above (u superdiagonals: no fill beyond the band, as partial pivoting's 2u).
    Exists and needs no exchanges when the symmetric part of A is positive definite (every pivot is
    then positive): the iteration matrix c_m M + ... with the running belt's small skew terms. Returns
    the number of columns eliminated: n, or the first column whose pivot is not positive (the caller
    falls back to partial pivoting)."""
    n = ab.shape[1]
    for k in range(n):
        p = ab[u, k]
        if not p > 0.0:
            return k
        lm = min(u, n - 1 - k)
        for i in range(1, lm + 1):
            ab[u + i, k] /= p
        for j in range(1, lm + 1):  # A[k+i, k+j] -= l_{k+i,k} u_{k,k+j}
            ukj = ab[u - j, k + j]
            if ukj != 0.0:
                off = u - j
                for i in range(1, lm + 1):
                    ab[off + i, k + j] -= ab[u + i, k] * ukj
    return n


@njit(**KERNEL)
def band_lu_nopivot_solve(ab, perm, b, x, work):
    """Solve S x = b with the `band_lu_nopivot` factor of S[perm][:, perm] in ab (2u + 1, n)."""
    u = (ab.shape[0] - 1) // 2
    n = ab.shape[1]
    for i in range(n):
        work[i] = b[perm[i]]
    for j in range(n - 1):  # L y = b (unit lower), by columns
        wj = work[j]
        lm = min(u, n - 1 - j)
        for i in range(1, lm + 1):
            work[j + i] -= ab[u + i, j] * wj
    band_upper_solve(ab, u, work)  # U x = y
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def band_lu_solve(ab, piv, perm, kl, ku, b, x, work):
    """Solve S x = b with the LAPACK dgbtrf factor of S[perm][:, perm] (band storage ab
    (2 kl + ku + 1, n), 0-based pivots piv): the dgbtrs algorithm for no transpose."""
    n = ab.shape[1]
    kd = kl + ku
    for i in range(n):
        work[i] = b[perm[i]]
    if kl > 0:
        for j in range(n - 1):
            lm = min(kl, n - 1 - j)
            p = piv[j]
            if p != j:
                tmp = work[p]
                work[p] = work[j]
                work[j] = tmp
            wj = work[j]
            for i in range(1, lm + 1):
                work[j + i] -= ab[kd + i, j] * wj
    for j in range(n - 1, -1, -1):  # U x = y, U with kd superdiagonals: U[i, j] = ab[kd + i - j, j]
        work[j] /= ab[kd, j]
        wj = work[j]
        lo = max(0, j - kd)
        for i in range(lo, j):
            work[i] -= ab[kd + i - j, j] * wj
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def factor_solve(fac, b, x, work):
    if fac.kind == 0:
        band_cholesky_solve(fac.ab, fac.perm, b, x, work)
    elif fac.kind == 2:
        band_lu_nopivot_solve(fac.ab, fac.perm, b, x, work)
    else:
        band_lu_solve(fac.ab, fac.piv, fac.perm, fac.kl, fac.ku, b, x, work)


@njit(**KERNEL)
def belt_forces(belt, q_ext, v_ext, E, Ed, fe, fd, f_el, f_dmp, gross, with_gross):
    """Reduced belt elastic (f_el) and damping (f_dmp) forces (n + 1,) at (q, v); with_gross: also
    gross (n + 1,), the sum of |T^T f_e| over elements (the round-off scale)."""
    bk.gather(q_ext, belt.e0, belt.T, belt.idx, belt.tsel, E)
    bk.element_forces(E, belt.dS, belt.d2S, belt.wEA, belt.wEI, belt.Kb, belt.curvature, fe)
    f_el[:] = 0.0
    bk.scatter_vector(fe, belt.T, belt.idx, belt.tsel, f_el)
    if with_gross:  # gross scale: |T^T f_e| per element entry
        gross[:] = 0.0
        n_elem, _, m = belt.T.shape
        for e in range(n_elem):
            if belt.tsel[e] < 0:
                for i in range(8):
                    gross[belt.idx[e, i]] += abs(fe[e, i])
            else:
                for j in range(m):
                    s = 0.0
                    for i in range(8):
                        s += belt.T[e, i, j] * fe[e, i]
                    gross[belt.idx[e, j]] += abs(s)
    f_dmp[:] = 0.0
    if belt.eta_a != 0.0 or belt.eta_b != 0.0:
        bk.gather_velocity(v_ext, belt.T, belt.idx, belt.tsel, Ed)
        bk.element_damping(E, Ed, belt.dS, belt.d2S, belt.wEA, belt.wEI, belt.Kb, belt.curvature, belt.eta_a,
                           belt.eta_b, fd)
        bk.scatter_vector(fd, belt.T, belt.idx, belt.tsel, f_dmp)
    sk.spring_forces(belt.springs, q_ext, v_ext, f_el, f_dmp, gross, with_gross)


@njit(**KERNEL)
def external_forces(F, cons, t, out, sig_val):
    """F(t) (n,): constant part + loads + inertia of the nominal belt travel."""
    n = out.shape[0]
    for i in range(n):
        out[i] = F.constant[i]
    if F.nominal_scale != 0.0:
        thdd = rotation_state(F.nominal_rotation, t)[2] * F.nominal_scale
        for i in range(n):
            out[i] -= F.nominal_mass[i] * thdd
    if F.sig_params.shape[0] > 0:
        signal_values(F, t, sig_val)
        for j in range(F.load_dof.shape[0]):
            out[F.load_dof[j]] += F.load_coef[j] * sig_val[F.load_sig[j]]


@njit(**KERNEL)
def transport_speed(tr, F, t):
    """(c, c') the belt speed (m/s) and its rate at time t."""
    if tr.follow:
        st = rotation_state(F.nominal_rotation, t)
        return st[1] * F.nominal_scale, st[2] * F.nominal_scale
    return tr.speed, 0.0


@njit(**KERNEL)
def transport_forces(tr, c, cd, q, v, out, Bq, Aq):
    """out (n,) = c G v - c^2 (B q + b0) + c' (A q + a0); Bq, Aq (n,) receive B q + b0 and A q + a0.
    Returns (q.B q + 2 b0.q, v.(A q + a0)) for the energy and the transport power."""
    csr_matvec(tr.B, q, Bq)
    csr_matvec(tr.A, q, Aq)
    csr_matvec(tr.G, v, out)
    return transport_from(tr, c, cd, q, v, out, Bq, Aq)


@njit(**KERNEL)
def fused_matvec(F, a, q, v, Ma, Aq, Bq, Gv):
    """Ma = M a, Aq = A q, Bq = B q, Gv = G v in one pass over the union pattern F (data rows M, A, G, B)."""
    n = F.indptr.shape[0] - 1
    d = F.data
    for i in range(n):
        sm = 0.0
        sa = 0.0
        sg = 0.0
        sb = 0.0
        for k in range(F.indptr[i], F.indptr[i + 1]):
            j = F.indices[k]
            sm += d[0, k] * a[j]
            sa += d[1, k] * q[j]
            sg += d[2, k] * v[j]
            sb += d[3, k] * q[j]
        Ma[i] = sm
        Aq[i] = sa
        Gv[i] = sg
        Bq[i] = sb


@njit(**KERNEL)
def transport_from(tr, c, cd, q, v, out, Bq, Aq):
    """As `transport_forces` with the products B q, A q and G v (in out) already made (`fused_matvec`)."""
    n = q.shape[0]
    qbq = 0.0
    vaq = 0.0
    for i in range(n):
        qbq += q[i] * (Bq[i] + 2.0 * tr.b0[i])  # q.B q + 2 b0.q
        Bq[i] += tr.b0[i]
        Aq[i] += tr.a0[i]
        vaq += v[i] * Aq[i]
        out[i] = c * out[i] - c * c * Bq[i] + cd * Aq[i]
    return qbq, vaq


@njit(**KERNEL)
def potential_energy(belt, lin, q, q_ext, E, U, dq, Kdq):
    """Belt strain energy (elements and spring spans) + 1/2 (q - q_ref)^T K_lin (q - q_ref)."""
    bk.gather(q_ext, belt.e0, belt.T, belt.idx, belt.tsel, E)
    bk.element_strain_energy(E, belt.dS, belt.d2S, belt.wEA, belt.wEI, belt.Kb, belt.curvature, U)
    total = sk.spring_energy(belt.springs, q_ext)
    for e in range(U.shape[0]):
        total += U[e]
    n = q.shape[0]
    for i in range(n):
        dq[i] = q[i] - lin.q_ref[i]
    split_matvec(lin.K, dq, Kdq)
    for i in range(n):
        total += 0.5 * dq[i] * Kdq[i]
    return total


@njit(**KERNEL)
def kinetic_energy(lin, v, Mv):
    split_matvec(lin.M, v, Mv)
    s = 0.0
    for i in range(v.shape[0]):
        s += 0.5 * v[i] * Mv[i]
    return s


@njit(**KERNEL)
def complete(arms, q, v, a):
    """The arm pulleys' centre offsets (p entries after n_q) from the arm angles, exactly."""
    for k in range(arms.dof.shape[0]):
        d, s, L, ang = arms.dof[k], arms.slot[k], arms.length[k], arms.angle[k]
        phi = ang + q[d]
        c, sn = np.cos(phi), np.sin(phi)
        w = v[d]
        q[s] = L * (c - np.cos(ang))
        q[s + 1] = L * (sn - np.sin(ang))
        v[s] = -L * sn * w
        v[s + 1] = L * c * w
        a[s] = -L * sn * a[d] - L * c * w * w
        a[s + 1] = L * c * a[d] - L * sn * w * w


@njit(**KERNEL)
def project(arms, q, x, out, absolute=False):
    """out (n_q,) = J(q)^T x for x (n_p,) on the joint coordinates (|J|^T x with absolute: round-off
    scales)."""
    for i in range(arms.n_q):
        out[i] = x[i]
    for k in range(arms.dof.shape[0]):
        d, s, L = arms.dof[k], arms.slot[k], arms.length[k]
        phi = arms.angle[k] + q[d]
        a, b = -L * np.sin(phi), L * np.cos(phi)
        if absolute:
            a, b = abs(a), abs(b)
        out[d] += a * x[s] + b * x[s + 1]


@njit(**KERNEL)
def arm_friction(arms, q, f):
    """Add the arms' dry friction torques clip(k_b (phi - z), -T_f, T_f) to f (on the angles); returns
    the bristles' stored energy sum tau^2 / (2 k_b)."""
    stored = 0.0
    for k in range(arms.dof.shape[0]):
        if arms.friction[k] != 0.0:
            d = arms.dof[k]
            tau = min(max(arms.bristle[k] * (q[d] - arms.anchor[k]), -arms.friction[k]), arms.friction[k])
            f[d] += tau
            stored += 0.5 * tau * tau / arms.bristle[k]
    return stored


@njit(**KERNEL)
def slide_anchors(arms, q):
    """Return mapping after an accepted step: an anchor whose bristle torque exceeds T_f slides along."""
    for k in range(arms.dof.shape[0]):
        if arms.friction[k] != 0.0:
            d = arms.dof[k]
            e = q[d] - arms.anchor[k]
            lim = arms.friction[k] / arms.bristle[k]
            if e > lim:
                arms.anchor[k] = q[d] - lim
            elif e < -lim:
                arms.anchor[k] = q[d] + lim


@njit(**KERNEL)
def advance(task, state, belt, lin, F, cons, chk, opts, fac, fresh, out, ev, info, arms, tr, work):
    """The stepper's one entry point from Python: task START runs `start_forces` (returns DONE), STEP
    `run_steps` (returns its code). One compiled function holds every kernel a transient calls from
    Python, so a run loads one library from numba's cache instead of one per kernel (each load parses
    its own copy of the callees' code: ~45 ms of a short command's start). work: the scratch
    (`workspace`), cleared here."""
    clear(work)
    if task == START:
        start_forces(state, belt, lin, F, cons, arms, tr, work)
        return DONE
    return run_steps(state, belt, lin, F, cons, chk, opts, fac, fresh, out, ev, info, arms, tr, work)


@njit(**KERNEL)
def clear(work):
    """Zero the scratch (`Work`): each call starts from zeros, as from freshly allocated arrays."""
    work.ext[:, :] = 0.0
    work.vec[:, :] = 0.0
    work.proj[:, :] = 0.0
    work.elem[:, :, :] = 0.0
    work.elem1[:, :] = 0.0
    work.group[:, :] = 0.0
    work.worst[:] = 0
    work.sig[:] = 0.0
    work.react[:] = 0.0
    work.span[:] = 0.0
    work.held[:] = 0


@njit(**KERNEL)
def start_forces(state, belt, lin, F, cons, arms, tr, work):
    """The initial state's forces at t = 0 (`transient.initial_state` solves for the acceleration):
    sets the prescribed DOFs' q, v, a and the arms' dependent entries (their angle accelerations 0 so
    far: a holds the centripetal part), relaxes the arms' friction bristles (anchors at the angles),
    and writes state.f0 = f(q, v) (belt elastic and damping, arm friction, K (q - q_ref), transport),
    state.fd0 its damping part, state.F0 = F(0), and scal[E0, KIN0, POT0, TR_P0] (the energy
    reference: kinetic + strain with the centripetal potential, and the transport power)."""
    q, v, a = state.q, state.v, state.a
    th = state.scal
    n = q.shape[0]
    n_elem = belt.T.shape[0]
    for k in range(cons.dof.shape[0]):
        g, gd, gdd = rotation_state(cons.params[k], 0.0)[3:]
        d = cons.dof[k]
        q[d] = cons.params[k, 7] + g
        v[d] = gd
        a[d] = gdd
    complete(arms, q, v, a)
    q_ext, v_ext, f_el, f_dmp, gross = work.ext[0], work.ext[1], work.ext[2], work.ext[3], work.ext[4]
    E, Ed, fe, fd = work.elem[0], work.elem[1], work.elem[2], work.elem[3]
    dq, Kd, f_tr, tmp, tmp2 = work.vec[0], work.vec[1], work.vec[2], work.vec[3], work.vec[4]
    for i in range(n):
        q_ext[i] = q[i]
        v_ext[i] = v[i]
    belt_forces(belt, q_ext, v_ext, E, Ed, fe, fd, f_el, f_dmp, gross, False)
    for k in range(arms.dof.shape[0]):
        arms.anchor[k] = q[arms.dof[k]]
    arm_friction(arms, q, f_dmp)
    for i in range(n):
        dq[i] = q[i] - lin.q_ref[i]
    split_matvec(lin.K, dq, Kd)
    external_forces(F, cons, 0.0, state.F0, work.sig)
    c0, cd0 = transport_speed(tr, F, 0.0)
    qbq, vaq = transport_forces(tr, c0, cd0, q, v, f_tr, tmp, tmp2)
    for i in range(n):
        state.f0[i] = f_el[i] + Kd[i] + f_dmp[i] + f_tr[i]
        state.fd0[i] = f_dmp[i]
    kin = kinetic_energy(lin, v, tmp)
    pot = potential_energy(belt, lin, q, q_ext, E, work.elem1[0], tmp, tmp2) - 0.5 * c0 * c0 * qbq
    th[E0] = kin + pot
    th[KIN0] = kin
    th[POT0] = pot
    th[TR_P0] = -cd0 * (c0 * qbq + vaq)


@njit(**KERNEL)
def run_steps(state, belt, lin, F, cons, chk, opts, fac, fresh, out, ev, info, arms, tr, work):
    """Advance the state until t_stop, a full buffer, a refactorization request or the step budget.

    Returns a code (DONE, BUFFER_FULL, REFACTOR, HALVE, MAX_STEPS). out receives the states at the
    output times (Hermite interpolation within the step), the energy terms of the step that contains
    each output time (exact at that step) and the constraint reactions. info (4,): on HALVE the
    time, the scaled residual, the worst DOF and the iterations.
    """
    q, v, a = state.q, state.v, state.a  # on the joint coordinates p (n); q[:nq] independent
    th = state.scal
    am, af, beta, gamma = opts.am, opts.af, opts.beta, opts.gamma
    n = q.shape[0]
    nq = arms.n_q
    n_elem = belt.T.shape[0]
    n_con = cons.dof.shape[0]
    B = out.t.shape[0]
    G = chk.n_groups
    q_ext, v_ext, f_el, f_dmp, gross = work.ext[0], work.ext[1], work.ext[2], work.ext[3], work.ext[4]
    E, Ed, fe, fd = work.elem[0], work.elem[1], work.elem[2], work.elem[3]
    U, min_elem = work.elem1[0], work.elem1[1]
    wv = work.vec
    F1, q1, v1, a1, dq, Ma, Ma0, Cv, Cv0 = wv[0], wv[1], wv[2], wv[3], wv[4], wv[5], wv[6], wv[7], wv[8]
    Kd, fi, fl, tmp, tmp2, f_tr, tr_Bq, tr_Aq = wv[9], wv[10], wv[11], wv[12], wv[13], wv[14], wv[15], wv[16]
    # the same terms projected on q (J^T at their own state): new (1) and old (0)
    # (without arms q = p, J = I: the terms themselves, no copies)
    with_arms = arms.dof.shape[0] > 0
    wp = work.proj
    R, dx, work_q = wp[0], wp[1], wp[2]
    if with_arms:
        Ma_q, Cv_q, fi_q, F1_q, Fc_q = wp[3], wp[4], wp[5], wp[6], wp[7]
        fl_q, Ma0_q, Cv0_q, f0_q, F0_q = wp[8], wp[9], wp[10], wp[11], wp[12]
    else:
        Ma_q = Ma
        Cv_q = Cv
        fi_q = fi
        F1_q = F1
        Fc_q = F.constant
        fl_q = fl
        Ma0_q = Ma0
        Cv0_q = Cv0
        f0_q = state.f0
        F0_q = state.F0
    sig_val = work.sig
    res_g, scale_g, floor_g = work.group[0], work.group[1], work.group[2]
    worst_g = work.worst
    R1 = work.react
    min_span = work.span
    held = work.held
    for k in range(n_con):
        held[cons.dof[k]] = 1
    moving = tr.follow != 0 or tr.speed != 0.0
    qbq = 0.0
    p_tr = 0.0
    split_matvec(lin.M, a, Ma0)
    split_matvec(lin.C, v, Cv0)
    if with_arms:
        project(arms, q, Ma0, Ma0_q)
        project(arms, q, Cv0, Cv0_q)
        project(arms, q, state.f0, f0_q)
        project(arms, q, state.F0, F0_q)
    eps = EPS
    steps = 0
    if fresh:  # a new factor: its age starts
        th[STALE] = 0.0
        th[REF_SUM] = 0.0
        th[REF_N] = 0.0
    tmp[:] = 0.0
    bristle0 = arm_friction(arms, q, tmp)
    bristle1 = bristle0
    while True:
        t, h = th[T_NOW], th[H]
        if t >= opts.t_stop - 1e-6 * h:
            return DONE
        if out.n[0] >= B:
            return BUFFER_FULL
        if steps >= opts.max_steps:
            return MAX_STEPS
        t1 = t + h
        c_a = 1.0 / (beta * h * h)
        c_v = gamma / (beta * h)
        for i in range(nq):  # predictor: same acceleration
            a1[i] = a[i]
            q1[i] = q[i] + h * v[i] + h * h * a[i] * 0.5
            v1[i] = v[i] + h * a[i]
        for k in range(n_con):
            g, gd, gdd = rotation_state(cons.params[k], t1)[3:]
            d = cons.dof[k]
            q1[d] = cons.params[k, 7] + g  # the static rotation plus the prescribed fluctuation
            v1[d] = gd
            a1[d] = gdd
        complete(arms, q1, v1, a1)
        external_forces(F, cons, t1, F1, sig_val)
        c1, cd1 = transport_speed(tr, F, t1)
        converged = False
        prev = np.inf
        it = 0
        res = np.inf
        worst = 0
        while True:  # at most max_iter corrections; the residual after the last one is checked
            for i in range(n):
                q_ext[i] = q1[i]
                v_ext[i] = v1[i]
                dq[i] = q1[i] - lin.q_ref[i]
            # the round-off scale at the step's first evaluation: a floor, not a force
            belt_forces(belt, q_ext, v_ext, E, Ed, fe, fd, f_el, f_dmp, gross, it == 0)
            bristle1 = arm_friction(arms, q1, f_dmp)
            split_matvec(lin.K, dq, Kd)
            split_matvec(lin.C, v1, Cv)
            if moving:  # M a, A q, G v, B q in one pass
                fused_matvec(tr.mag, a1, q1, v1, Ma, tr_Aq, tr_Bq, f_tr)
                qbq, vaq = transport_from(tr, c1, cd1, q1, v1, f_tr, tr_Bq, tr_Aq)
                p_tr = -cd1 * (c1 * qbq + vaq)
            else:
                split_matvec(lin.M, a1, Ma)
            for i in range(n):
                fi[i] = f_el[i] + Kd[i] + f_dmp[i] + f_tr[i]
                fl[i] = gross[i] + abs(Kd[i]) + abs(F.constant[i]) + abs(f_tr[i])
            if with_arms:
                project(arms, q1, Ma, Ma_q)
                project(arms, q1, Cv, Cv_q)
                project(arms, q1, fi, fi_q)
                project(arms, q1, F1, F1_q)
                project(arms, q1, F.constant, Fc_q)
                project(arms, q1, fl, fl_q, True)
            for g in range(G):
                res_g[g] = 0.0
                scale_g[g] = 0.0
                floor_g[g] = 0.0
            finite = True
            res = 0.0
            for i in range(nq):  # residual, scales and floors (every row), checked (the free rows)
                Ri = ((1.0 - am) * Ma_q[i] + am * Ma0_q[i]
                      + (1.0 - af) * (Cv_q[i] + fi_q[i] - F1_q[i]) + af * (Cv0_q[i] + f0_q[i] - F0_q[i]))
                g = chk.group[i]
                sc = abs(Ma_q[i]) + abs(Cv_q[i]) + abs(fi_q[i] - Fc_q[i]) + abs(F1_q[i] - Fc_q[i])
                if sc > scale_g[g]:
                    scale_g[g] = sc
                if fl_q[i] > floor_g[g]:
                    floor_g[g] = fl_q[i]
                if held[i]:  # a prescribed row: no residual
                    Ri = 0.0
                R[i] = Ri
                r = abs(Ri)
                if not np.isfinite(r):
                    finite = False
                    worst = i
                    break
                if r > res_g[g]:
                    res_g[g] = r
                    worst_g[g] = i
            if finite:
                for g in range(G):
                    allowed = chk.tol * scale_g[g] + 1e3 * eps * floor_g[g] + chk.noise
                    x = res_g[g] / allowed if allowed > 0.0 else (0.0 if res_g[g] == 0.0 else np.inf)
                    if x > res:
                        res = x
                        worst = worst_g[g]
            else:
                res = np.inf
                break
            if res <= 1.0:
                converged = True
                break
            if it >= chk.max_iter:
                break
            factor_solve(fac, R, dx, work_q)
            for k in range(n_con):
                dx[cons.dof[k]] = 0.0
            norm = 0.0
            for i in range(nq):
                d = -dx[i]
                q1[i] += d
                v1[i] += c_v * d
                a1[i] += c_a * d
                norm += d * d
            complete(arms, q1, v1, a1)
            it += 1
            if it >= 3 and norm > 0.25 * prev:  # convergence rate worse than 1/2 per iteration
                break
            prev = norm
        if not converged:
            info[0] = t1
            info[1] = res
            info[2] = worst
            info[3] = it
            if fresh:
                return HALVE
            return REFACTOR
        # the step is accepted only if all of its output samples fit in the buffer
        n_pend = 0
        tt = th[T_OUT]
        while tt <= t1 + 1e-6 * h:
            n_pend += 1
            tt += opts.dt_out
        if out.n[0] + n_pend > B:
            return BUFFER_FULL
        fresh = False
        # accepted: power of external forces and reactions, dissipation (trapezoid), on p (power is
        # invariant: F . v_p = (J^T F) . v_q)
        p_ext = 0.0
        p_dis = 0.0
        for i in range(n):
            p_ext += 0.5 * (F1[i] * v1[i] + state.F0[i] * v[i])
            p_dis += 0.5 * ((Cv[i] + f_dmp[i]) * v1[i] + (Cv0[i] + state.fd0[i]) * v[i])
        for k in range(n_con):
            d = cons.dof[k]
            R1[k] = Ma_q[d] + Cv_q[d] + fi_q[d] - F1_q[d]
            p_ext += 0.5 * (R1[k] * v1[d] + state.R0[k] * v[d])
        p_ext += 0.5 * (p_tr + th[TR_P0])  # the drive's work on the belt's transport while its speed changes
        W_old, D_old = th[WORK], th[DISS]
        th[WORK] = W_old + h * p_ext
        th[DISS] = D_old + h * p_dis - (bristle1 - bristle0)  # the bristles' stored part is not lost
        bristle0 = bristle1
        kin = 0.0
        pot = 0.0
        if n_pend > 0:  # energy at this step (exact, not interpolated)
            kin = kinetic_energy(lin, v1, tmp)
            pot = potential_energy(belt, lin, q1, q_ext, E, U, tmp, tmp2) + bristle1 - 0.5 * c1 * c1 * qbq
            bal = kin + pot - th[WORK] + th[DISS] - th[E0]
            if abs(bal) > th[WORST]:
                th[WORST] = abs(bal)
            moved = max(abs(kin - th[KIN0]) + abs(pot - th[POT0]), abs(th[WORK]), abs(th[DISS]))
            if moved > th[MOVED]:
                th[MOVED] = moved
        while th[T_OUT] <= t1 + 1e-6 * h:  # outputs at t_next_out in (t, t1]
            tau = th[T_OUT]
            s = (tau - t) / h
            h00 = 2 * s ** 3 - 3 * s ** 2 + 1
            h10 = s ** 3 - 2 * s ** 2 + s
            h01 = -2 * s ** 3 + 3 * s ** 2
            h11 = s ** 3 - s ** 2
            k = out.n[0]
            out.t[k] = tau
            for i in range(n):
                out.q[k, i] = h00 * q[i] + h10 * h * v[i] + h01 * q1[i] + h11 * h * v1[i]
                out.v[k, i] = h00 * v[i] + h10 * h * a[i] + h01 * v1[i] + h11 * h * a1[i]
                out.a[k, i] = (1.0 - s) * a[i] + s * a1[i]
            if arms.dof.shape[0] > 0:  # the dependent entries stay kinematically exact
                complete(arms, out.q[k], out.v[k], out.a[k])
            out.energy[k, 0] = kin
            out.energy[k, 1] = pot
            out.energy[k, 2] = th[WORK]
            out.energy[k, 3] = th[DISS]
            out.energy[k, 4] = kin + pot - th[WORK] + th[DISS] - th[E0]
            for c in range(n_con):
                out.reaction[k, c] = (1.0 - s) * state.R0[c] + s * R1[c]
            out.n[0] += 1
            th[T_OUT] += opts.dt_out
        # slack events: smallest 2nd Piola-Kirchhoff force per span (E: the accepted state, the last
        # one evaluated unless an energy evaluation gathered it again at q1)
        bk.element_min_axial_force(E, belt.dS, belt.EA, min_elem)
        for sp in range(belt.n_span):
            min_span[sp] = np.inf
        for e in range(n_elem):
            sp = belt.elem_span[e]
            if min_elem[e] < min_span[sp]:
                min_span[sp] = min_elem[e]
        sk.spring_min_force(belt.springs, q_ext, min_span)
        for sp in range(belt.n_span):
            now = 1.0 if min_span[sp] < 0.0 else 0.0
            if now != ev.slack[sp] and ev.n[0] < ev.data.shape[0]:
                ev.data[ev.n[0], 0] = t1
                ev.data[ev.n[0], 1] = sp
                ev.data[ev.n[0], 2] = now
                ev.data[ev.n[0], 3] = min_span[sp]
                ev.n[0] += 1
            ev.slack[sp] = now
        for i in range(n):
            q[i] = q1[i]
            v[i] = v1[i]
            a[i] = a1[i]
            state.f0[i] = fi[i]
            state.fd0[i] = f_dmp[i]
            state.F0[i] = F1[i]
            Ma0[i] = Ma[i]
            Cv0[i] = Cv[i]
        if with_arms:
            for i in range(nq):
                Ma0_q[i] = Ma_q[i]
                Cv0_q[i] = Cv_q[i]
                f0_q[i] = fi_q[i]
                F0_q[i] = F1_q[i]
        for k in range(n_con):
            state.R0[k] = R1[k]
        th[TR_P0] = p_tr
        slide_anchors(arms, q)
        bristle0 = arm_friction(arms, q, tmp)  # after the return mapping (tmp: scratch)
        th[T_NOW] = t1
        th[STEPS] += 1.0
        th[ITERS] += it
        steps += 1
        # an aging factor: the iterations its steps take beyond what it took fresh (the mean of its first
        # REF_STEPS steps) add up; once they cost more than a new factor, the next step gets one (the
        # rent-or-buy rule: within 2x of the best choice). A drive whose steps take as many iterations
        # with any factor never pays for one.
        if th[REF_N] < REF_STEPS:
            th[REF_SUM] += it
            th[REF_N] += 1.0
        else:
            th[STALE] = max(0.0, th[STALE] + it - th[REF_SUM] / th[REF_N])
            if opts.refresh > 0.0 and th[STALE] > opts.refresh:
                return REFACTOR


