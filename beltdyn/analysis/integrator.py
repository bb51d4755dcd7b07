"""Generalized-alpha (Chung-Hulbert 1993) stepper of a `System`, compiled with numba.

Equations of motion on the independent coordinates q (n,):
    M a + C v + f(q, v) = F(t),
f = f_belt(q) + f_damp(q, v) + K_lin (q - q_ref)  (belt elastic force of paper Eqs. 14/17 through the joints and
of the spring spans (`spring_kernel`, `BeltData.springs`), Kelvin-Voigt belt damping, the linear components'
constant stiffness measured from the reference state q_ref, usually the static equilibrium), F(t) = F_const +
loads(t) - M u_nom s''(t) with F_const = preload + weight - K_lin q_ref (the constant part; it balances f at the
static equilibrium, so no force of the size of a bearing preload ever enters a tolerance), C the constant
damping (Rayleigh + components; M, C and K_lin as `Split`: a band and the entries off it). Any number of DOFs
may be prescribed (constraint objects: the rotation law `forcing_laws.rotation_state` per DOF); their residual
rows are dropped and their reactions recorded.

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

Dry friction (`friction_kernel`: its docstring explains the models): the tensioner arms' elasto-plastic
bristle, the decouplers' one-way clutches and the wraps that may slip, with their return mappings after
each accepted step (`accept`) and the wraps' capstan limits (`wrap_limits`). The iteration matrix holds a
sticking wrap bristle's k_b and none of a sliding one: a factor holds the regime of its moment
(`Wraps.factored`), and each Newton correction adds or removes the bristles of the wraps that changed
since by a low-rank update of its solve (`regime_correction`, the Woodbury identity), so a stick-slip
transition costs neither a factor nor a return to Python (on the FEAD example: ~500 transitions a second
had cost as many factors and ~800 failed Newton steps).

Array conventions: belt data as `belt_kernel` (T (n_elem, 8, m), idx (n_elem, m) with padding
index n, tsel, e0 (n_elem, 8), dS/d2S (n_elem, n_qp, 4), wEA/wEI (n_elem, n_qp), Kb (n_elem, 8, 8)).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from beltdyn.jitcache import configure, kernel_options


configure()  # where numba caches the kernels (the package folder, else a user cache folder): before numba loads
from numba import njit  # noqa: E402

from beltdyn.model import belt_kernel as bk
from beltdyn.model import spring_kernel as sk

# the forcing laws (prescribed rotations, signals, tables) and the dry-friction parts the loop calls
from beltdyn.analysis.forcing_laws import rotation_state, signal_values  # noqa: E402
from beltdyn.analysis.friction_kernel import (  # noqa: E402,F401
    accept_clutches, arm_friction, bristle, clutch_stored, clutch_torques, end_stretch, regime_changed,
    regime_correction, slid_anchor, slide_anchors, slide_wraps, stepped_wrap_torque, wrap_friction, wrap_limits)

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)
PART = dict(KERNEL, inline="always")  # the stepper's parts: inlined into `run_steps` at numba's IR level (public
# option), as the one loop they were. Reference counts (numba's runtime; `bench/refcounts.py` counts them): an
# inlined part's array arguments are new references, a count each per call; a called function that passes arrays
# on to another keeps a count per array and call; one that passes none may keep none, numba's pruner removing
# them where its arrays die together (`project_new`: measured, not assumed; other parts kept more when called)

# the stepper's data and band solvers (re-exported: `integrator.X` is where the transient reads them)
from beltdyn.analysis.band_solve import (  # noqa: E402,F401
    band_cholesky_solve, band_lu_nopivot, band_lu_nopivot_solve, band_lu_solve, band_upper_solve, factor_solve)
from beltdyn.analysis.stepper_data import (  # noqa: E402,F401
    ARM_PRESLIDING, BAND_COST, Arms, BeltData, Check, Constraints, Coo, Csr, Decouplers, Events, Factor, Forcing,
    Fused, Linear, Outputs, Split, State, StepOptions, StepperModel, Transport, Work, Wraps, empty_csr, fused, no_arms,
    no_decouplers, no_factor, no_transport, no_wraps, split, split_matrix, to_csr, workspace)

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

EPS = float(np.finfo(np.float64).eps)  # a constant to the compiled code (np.finfo there is numba's array module)

# scal slots
T_NOW, H, T_OUT, WORK, DISS, STEPS, E0, WORST, MOVED, KIN0, POT0, ITERS, TR_P0, STALE, REF_SUM, REF_N = range(16)
N_SCAL = 16  # TR_P0: the transport power at the last accepted step; STALE, REF_SUM, REF_N: the factor's age
REF_STEPS = 4  # a new factor's first steps: their mean iterations are what the factor does fresh
ENERGY_TERMS = ("kinetic", "strain", "work", "dissipated", "balance_error")

from beltdyn.analysis.timestep import alpha_parameters  # noqa: E402,F401  (one definition, numba-free)


@njit(**KERNEL)
def csr_matvec(A, x, out):
    n = A.indptr.shape[0] - 1
    for i in range(n):
        s = 0.0
        for k in range(A.indptr[i], A.indptr[i + 1]):
            s += A.data[k] * x[A.indices[k]]
        out[i] = s


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
def add_element_forces(e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, q_ext, v_ext, E, Ed, fe,
                        fd, f_el, f_dmp, gross, with_gross):
    """Add the belt elements' reduced elastic (f_el) and damping (f_dmp) forces (n + 1,) at q_ext, v_ext; with_gross:
    also to gross (n + 1,) the sum of |T^T f_e| (the round-off scale). The elements' tables e0 ... curvature of
    `BeltData`, E, Ed, fe, fd their scratch. The belt's arrays one by one, read once by the caller: a struct's
    would count at the call and at each read (`PART`)."""
    bk.gather(q_ext, e0, T, idx, tsel, E)
    bk.element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, fe)
    bk.scatter_vector(fe, T, idx, tsel, f_el)
    if with_gross:  # gross scale: |T^T f_e| per element entry
        n_elem, _, m = T.shape
        for e in range(n_elem):
            if tsel[e] < 0:
                for i in range(8):
                    gross[idx[e, i]] += abs(fe[e, i])
            else:
                for j in range(m):
                    s = 0.0
                    for i in range(8):
                        s += T[e, i, j] * fe[e, i]
                    gross[idx[e, j]] += abs(s)
    if eta_a != 0.0 or eta_b != 0.0:
        bk.gather_velocity(v_ext, T, idx, tsel, Ed)
        bk.element_damping(E, Ed, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fd)
        bk.scatter_vector(fd, T, idx, tsel, f_dmp)


@njit(**KERNEL)
def external_forces(F, t, out, sig_val):
    """F(t) (n,): constant part + loads + inertia and component damping of the nominal belt travel (`run_steps`
    copies the constant part instead where the forcing has neither)."""
    n = out.shape[0]
    for i in range(n):
        out[i] = F.constant[i]
    if F.nominal_scale != 0.0:
        st = rotation_state(F.nominal_rotation, t)
        thd, thdd = st[1] * F.nominal_scale, st[2] * F.nominal_scale
        for i in range(n):
            out[i] -= F.nominal_mass[i] * thdd + F.nominal_damping[i] * thd
    if F.sig_params.shape[0] > 0:
        signal_values(F, t, sig_val)
        for j in range(F.load_dof.shape[0]):
            out[F.load_dof[j]] += F.load_coef[j] * sig_val[F.load_sig[j]]


@njit(**KERNEL)
def transport_speed(follow, speed, rotation, scale, t):
    """(c, c') the belt speed (m/s) and its rate at time t: the prescribed rotation's nominal speed (rotation: its
    law's parameters, `rotation_state`) times scale where it follows it (follow), else the constant speed."""
    if follow:
        st = rotation_state(rotation, t)
        return st[1] * scale, st[2] * scale
    return speed, 0.0


@njit(**KERNEL)
def travel_speed(rotation, scale, t):
    """The belt's nominal travel speed (m/s) at time t: the prescribed rotation's nominal speed times
    scale (the driver's rim speed), 0 without a nominal rotation (scale 0; the wraps' creep, `wrap_limits`)."""
    if scale == 0.0:
        return 0.0
    return rotation_state(rotation, t)[1] * scale


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
    total = sk.spring_energy(belt.springs, q_ext) if belt.n_springs > 0 else 0.0
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
def advance(task, state, model, opts, fac, fresh, out, ev, info, work):
    """The stepper's one entry point from Python: task START runs `start_forces` (returns DONE), STEP
    `run_steps` (returns its code). One compiled function holds every kernel a transient calls from
    Python, so a run loads one library from numba's cache instead of one per kernel (each load parses
    its own copy of the callees' code: ~45 ms of a short command's start). model: the `StepperModel`;
    work: the scratch (`workspace`), cleared here."""
    clear(work)
    if task == START:
        start_forces(state, model, work)
        return DONE
    return run_steps(state, model, opts, fac, fresh, out, ev, info, work)


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


@njit(**PART)
def hold_prescribed(cons, t, q, v, a):
    """Constraints: the prescribed DOFs' q, v, a at time t (the static rotation params[k, 7] plus the
    prescribed fluctuation of `rotation_state`)."""
    dof, params = cons.dof, cons.params
    for k in range(dof.shape[0]):
        g, gd, gdd = rotation_state(params[k], t)[3:]
        d = dof[k]
        q[d] = params[k, 7] + g
        v[d] = gd
        a[d] = gdd


@njit(**KERNEL)
def start_forces(state, model, work):
    """The initial state's forces at t = 0 (`transient.initial_state` solves for the acceleration):
    sets the prescribed DOFs' q, v, a and the arms' dependent entries (their angle accelerations 0 so
    far: a holds the centripetal part), relaxes the arms' friction bristles (anchors at the angles),
    and writes state.f0 = f(q, v) (belt elastic and damping, arm friction, K (q - q_ref), transport),
    state.fd0 its damping part, state.F0 = F(0), and scal[E0, KIN0, POT0, TR_P0] (the energy
    reference: kinetic + strain with the centripetal potential, and the transport power)."""
    belt, lin, F, arms, tr = model.belt, model.linear, model.forcing, model.arms, model.transport
    q, v, a = state.q, state.v, state.a
    th = state.scal
    n = q.shape[0]
    hold_prescribed(model.constraints, 0.0, q, v, a)
    complete(arms, q, v, a)
    q_ext, v_ext, f_el, f_dmp, gross = work.ext[0], work.ext[1], work.ext[2], work.ext[3], work.ext[4]
    E, Ed, fe, fd = work.elem[0], work.elem[1], work.elem[2], work.elem[3]
    dq, Kd, f_tr, tmp, tmp2 = work.vec[0], work.vec[1], work.vec[2], work.vec[3], work.vec[4]
    for i in range(n):
        q_ext[i] = q[i]
        v_ext[i] = v[i]
    f_el[:] = 0.0
    f_dmp[:] = 0.0
    if belt.tsel.shape[0] > 0:
        add_element_forces(belt.e0, belt.T, belt.idx, belt.tsel, belt.dS, belt.d2S, belt.wEA, belt.wEI, belt.Kb,
                            belt.curvature, belt.eta_a, belt.eta_b, q_ext, v_ext, E, Ed, fe, fd, f_el, f_dmp, gross,
                            False)
    if belt.n_springs > 0:
        sk.spring_forces(belt.springs, q_ext, v_ext, f_el, f_dmp, gross, False)
    for k in range(arms.dof.shape[0]):
        arms.anchor[k] = q[arms.dof[k]]
    arm_friction(arms, q, f_dmp)
    dec = model.decouplers
    dec.slip[0, :] = 0.0  # the clutches hold at the start (a spring that would pull back slips at once)
    clutch0 = clutch_torques(dec, q, v, 0.0, f_dmp)
    accept_clutches(dec)
    for i in range(n):
        dq[i] = q[i] - lin.q_ref[i]
    split_matvec(lin.K, dq, Kd)
    external_forces(F, 0.0, state.F0, work.sig)
    c0, cd0 = transport_speed(tr.follow, tr.speed, F.nominal_rotation, F.nominal_scale, 0.0)
    qbq, vaq = transport_forces(tr, c0, cd0, q, v, f_tr, tmp, tmp2)
    wraps = model.wraps
    stored = 0.0
    if wraps.wrap.shape[0] > 0:  # each bristle carries what balances its wrap at the start, M0 = F - f there
        # (the static torque: the pulley's loads, inertia and damping sit on its own rotation, `Wraps`)
        for k in range(wraps.wrap.shape[0]):
            wraps.torque[k] = 0.0
        c_travel = travel_speed(F.nominal_rotation, F.nominal_scale, 0.0)
        wrap_limits(wraps, belt, E, q_ext, c0, c_travel)  # the capstan limits of the initial tensions
        for k in range(wraps.wrap.shape[0]):
            w = wraps.wrap[k]
            wraps.preload[k] = state.F0[w] - (f_el[w] + Kd[w] + f_dmp[w] + f_tr[w])
            wraps.anchor[k] = q[w] - q[wraps.hub[k]] - wraps.preload[k] / wraps.bristle[k]
            held = False
            for j in range(model.constraints.dof.shape[0]):
                held = held or model.constraints.dof[j] == wraps.hub[k]
            if not held:  # a run that starts at speed starts creeping: theta' = psi' - z' (the steady creep)
                v[wraps.hub[k]] -= wraps.creep[k]
        stored = wrap_friction(wraps, q, f_dmp, True, 0.0)
        for k in range(wraps.wrap.shape[0]):
            wraps.torque[k] = bristle(wraps.bristle[k], q[wraps.wrap[k]] - q[wraps.hub[k]], wraps.anchor[k],
                                      wraps.limit[k], wraps.limit[k])[0]
    for i in range(n):
        state.f0[i] = f_el[i] + Kd[i] + f_dmp[i] + f_tr[i]
        state.fd0[i] = f_dmp[i]
    kin = kinetic_energy(lin, v, tmp)
    pot = potential_energy(belt, lin, q, q_ext, E, work.elem1[0], tmp, tmp2) - 0.5 * c0 * c0 * qbq + clutch0 + stored
    th[E0] = kin + pot
    th[KIN0] = kin
    th[POT0] = pot
    th[TR_P0] = -cd0 * (c0 * qbq + vaq)


@njit(**PART)
def predict(h, q, v, a, q1, v1, a1, nq):
    """The predictor on the independent coordinates: the same acceleration over the step h."""
    for i in range(nq):
        a1[i] = a[i]
        q1[i] = q[i] + h * v[i] + h * h * a[i] * 0.5
        v1[i] = v[i] + h * a[i]


# The terms of the residual on the independent coordinates (the joint coordinates' terms projected by J^T at
# their own state, or the terms themselves without arms): new (step end) and old (step start), Fc the constant
# force, fl the round-off scale. Each (n_q,).
Terms = namedtuple("Terms", ["Ma", "Ma0", "Cv", "Cv0", "fi", "f0", "F1", "F0", "Fc", "fl"])


project_inline = njit(**PART)(project.py_func)  # `project` inlined where a part would call it six times


@njit(**KERNEL)
def project_new(arms, constant, q1, wv, wp):
    """The arms' part: the new terms (work.vec rows M a, C v, fi, F1, fl and the constant force) projected on q by
    J(q1)^T into their rows of work.proj (`projected_terms`). Called, `project` inlined, the scratch as its two
    tables: no reference counts (`PART`)."""
    x = projected_terms(wp)
    project_inline(arms, q1, wv[5], x.Ma)
    project_inline(arms, q1, wv[7], x.Cv)
    project_inline(arms, q1, wv[10], x.fi)
    project_inline(arms, q1, wv[0], x.F1)
    project_inline(arms, q1, constant, x.Fc)
    project_inline(arms, q1, wv[11], x.fl, True)


@njit(**PART)
def scaled_residual(chk, held, am, af, x, R, rows, worst_g):
    """The generalized-alpha residual R (n_q,) of the terms x (`Terms`), zero on the prescribed rows
    (held), and its size against the allowed one per DOF group (module docstring):
    (max_g res_g / (tol s_g + 1e3 eps floor_g + noise), worst DOF, finite). rows (3, n_groups): the scratch of
    res_g, scale_g, floor_g by row (`Work.group`, indexed: a row view would be a reference count); worst_g
    (n_groups,) the worst DOF of each (`Work.worst`)."""
    group, tol, noise = chk.group, chk.tol, chk.noise
    Ma, Ma0, Cv, Cv0, fi, f0, F1, F0, Fc, fl = x.Ma, x.Ma0, x.Cv, x.Cv0, x.fi, x.f0, x.F1, x.F0, x.Fc, x.fl
    G = chk.n_groups
    for g in range(G):
        rows[0, g] = 0.0
        rows[1, g] = 0.0
        rows[2, g] = 0.0
    worst = 0
    for i in range(R.shape[0]):  # residual, scales and floors (every row), checked (the free rows)
        Ri = ((1.0 - am) * Ma[i] + am * Ma0[i]
              + (1.0 - af) * (Cv[i] + fi[i] - F1[i]) + af * (Cv0[i] + f0[i] - F0[i]))
        g = group[i]
        sc = abs(Ma[i]) + abs(Cv[i]) + abs(fi[i] - Fc[i]) + abs(F1[i] - Fc[i])
        if sc > rows[1, g]:
            rows[1, g] = sc
        if fl[i] > rows[2, g]:
            rows[2, g] = fl[i]
        if held[i]:  # a prescribed row: no residual
            Ri = 0.0
        R[i] = Ri
        r = abs(Ri)
        if not np.isfinite(r):
            return np.inf, i, False
        if r > rows[0, g]:
            rows[0, g] = r
            worst_g[g] = i
    res = 0.0
    for g in range(G):
        allowed = tol * rows[1, g] + 1e3 * EPS * rows[2, g] + noise
        x_g = rows[0, g] / allowed if allowed > 0.0 else (0.0 if rows[0, g] == 0.0 else np.inf)
        if x_g > res:
            res = x_g
            worst = worst_g[g]
    return res, worst, True


@njit(**PART)
def correct(dof, dx, R, c_v, c_a, q1, v1, a1):
    """One Newton correction dx = S^-1 R (solved by the caller: the factor's solve, in the wraps' regime),
    zero on the prescribed DOFs `dof`: q1 -= dx, v1 -= c_v dx, a1 -= c_a dx. Returns |dx|^2."""
    for k in range(dof.shape[0]):
        dx[dof[k]] = 0.0
    norm = 0.0
    for i in range(R.shape[0]):
        d = -dx[i]
        q1[i] += d
        v1[i] += c_v * d
        a1[i] += c_a * d
        norm += d * d
    return norm


@njit(**PART)
def count_outputs(t_out, t1, h, dt_out):
    """The output times in (t, t1] still to come from t_out."""
    n_pend = 0
    tt = t_out
    while tt <= t1 + 1e-6 * h:
        n_pend += 1
        tt += dt_out
    return n_pend


@njit(**PART)
def step_power(state, dof, x, v1, p_tr, work):
    """The trapezoid of the step's power: (external forces and reactions, dissipated), on p (power is
    invariant: F . v_p = (J^T F) . v_q); the reactions R1 (work.react) of the prescribed DOFs `dof`."""
    th = state.scal
    v, F0, fd0, R0 = state.v, state.F0, state.fd0, state.R0
    Ma, Cv_q, fi, F1_q = x.Ma, x.Cv, x.fi, x.F1
    wv = work.vec
    F1, Cv, Cv0, f_dmp = wv[0], wv[7], wv[8], work.ext[3]
    R1 = work.react
    p_ext = 0.0
    p_dis = 0.0
    for i in range(v.shape[0]):
        p_ext += 0.5 * (F1[i] * v1[i] + F0[i] * v[i])
        p_dis += 0.5 * ((Cv[i] + f_dmp[i]) * v1[i] + (Cv0[i] + fd0[i]) * v[i])
    for k in range(dof.shape[0]):
        d = dof[k]
        R1[k] = Ma[d] + Cv_q[d] + fi[d] - F1_q[d]
        p_ext += 0.5 * (R1[k] * v1[d] + R0[k] * v[d])
    p_ext += 0.5 * (p_tr + th[TR_P0])  # the drive's work on the belt's transport while its speed changes
    return p_ext, p_dis


@njit(**PART)
def balance_energy(state, belt, lin, q1, v1, c1, qbq, bristle1, work):
    """Observer: kinetic and potential energy at the accepted step (exact, not interpolated), the
    balance error's running maximum scal[WORST] and the energy moved scal[MOVED]. Returns (kin, pot)."""
    th = state.scal
    tmp, tmp2 = work.vec[12], work.vec[13]
    kin = kinetic_energy(lin, v1, tmp)
    pot = potential_energy(belt, lin, q1, work.ext[0], work.elem[0], work.elem1[0], tmp,
                           tmp2) + bristle1 - 0.5 * c1 * c1 * qbq
    bal = kin + pot - th[WORK] + th[DISS] - th[E0]
    if abs(bal) > th[WORST]:
        th[WORST] = abs(bal)
    moved = max(abs(kin - th[KIN0]) + abs(pot - th[POT0]), abs(th[WORK]), abs(th[DISS]))
    if moved > th[MOVED]:
        th[MOVED] = moved
    return kin, pot


@njit(**PART)
def record_outputs(state, arms, dec, wr, n_con, opts, out, t, h, q1, v1, a1, kin, pot, R1):
    """Observer: the samples at the output times in (t, t1] (Hermite interpolation within the step, the
    arms' dependent entries kinematically exact), the step's energy terms and the reactions."""
    q, v, a, R0 = state.q, state.v, state.a, state.R0
    th = state.scal
    o_t, o_q, o_v, o_a, o_n = out.t, out.q, out.v, out.a, out.n
    o_energy, o_reaction, o_clutch, o_wrap = out.energy, out.reaction, out.clutch, out.wrap
    dt_out = opts.dt_out
    n = q.shape[0]
    t1 = t + h
    while th[T_OUT] <= t1 + 1e-6 * h:  # outputs at t_next_out in (t, t1]
        tau = th[T_OUT]
        s = (tau - t) / h
        h00 = 2 * s ** 3 - 3 * s ** 2 + 1
        h10 = s ** 3 - 2 * s ** 2 + s
        h01 = -2 * s ** 3 + 3 * s ** 2
        h11 = s ** 3 - s ** 2
        k = o_n[0]
        o_t[k] = tau
        for i in range(n):
            o_q[k, i] = h00 * q[i] + h10 * h * v[i] + h01 * q1[i] + h11 * h * v1[i]
            o_v[k, i] = h00 * v[i] + h10 * h * a[i] + h01 * v1[i] + h11 * h * a1[i]
            o_a[k, i] = (1.0 - s) * a[i] + s * a1[i]
        if arms.dof.shape[0] > 0:  # the dependent entries stay kinematically exact
            complete(arms, o_q[k], o_v[k], o_a[k])
        o_energy[k, 0] = kin
        o_energy[k, 1] = pot
        o_energy[k, 2] = th[WORK]
        o_energy[k, 3] = th[DISS]
        o_energy[k, 4] = kin + pot - th[WORK] + th[DISS] - th[E0]
        for c in range(n_con):
            o_reaction[k, c] = (1.0 - s) * R0[c] + s * R1[c]
        for c in range(dec.hub.shape[0]):
            o_clutch[k, c] = (1.0 - s) * dec.torque[0, c] + s * dec.torque[1, c]
        for c in range(wr.wrap.shape[0]):  # the bristle torque at the step's end: the anchor of its start, crept
            o_wrap[k, 0, c] = (1.0 - s) * wr.torque[c] + s * stepped_wrap_torque(wr, c, q1)
            o_wrap[k, 1, c] = wr.limit[c]
            o_wrap[k, 2, c] = wr.creep[c]
            o_wrap[k, 3, c] = wr.ratio[c]
        o_n[0] += 1
        th[T_OUT] += dt_out


@njit(**PART)
def span_min_forces(E, dS, EA, elem_span, n_span, min_elem, min_span):
    """min_span (n_span,): the smallest 2nd Piola-Kirchhoff force of each span's elements (inf: none; E the
    accepted state's element coordinates, the last ones evaluated unless an energy evaluation gathered them again
    at q1). dS, EA, elem_span: the belt's (`BeltData`); min_elem (n_elem,) the scratch. (`sk.spring_min_force`
    adds the spring spans'.)"""
    bk.element_min_axial_force(E, dS, EA, min_elem)
    for sp in range(n_span):
        min_span[sp] = np.inf
    for e in range(elem_span.shape[0]):
        sp = elem_span[e]
        if min_elem[e] < min_span[sp]:
            min_span[sp] = min_elem[e]


@njit(**PART)
def slack_events(min_span, n_span, t1, ev):
    """Observer: a slack event (t1, span, slack or taut, force) where a span's smallest 2nd Piola-Kirchhoff force
    min_span (n_span,) changes sign."""
    slack, data, count = ev.slack, ev.data, ev.n
    for sp in range(n_span):
        now = 1.0 if min_span[sp] < 0.0 else 0.0
        if now != slack[sp] and count[0] < data.shape[0]:
            data[count[0], 0] = t1
            data[count[0], 1] = sp
            data[count[0], 2] = now
            data[count[0], 3] = min_span[sp]
            count[0] += 1
        slack[sp] = now


@njit(**PART)
def accept(state, dof, p_tr, work):
    """The new state becomes the old one: q, v, a, the forces, the reactions, the transport power. (The arms'
    projected terms, `keep_projected`, and the dry friction's return mappings are parts of their own, `run_steps`
    calls those the drive has.)"""
    q, v, a, f0, fd0, F0, R0, th = state.q, state.v, state.a, state.f0, state.fd0, state.F0, state.R0, state.scal
    wv = work.vec
    q1, v1, a1, Ma, Ma0, Cv, Cv0, fi, F1 = wv[1], wv[2], wv[3], wv[5], wv[6], wv[7], wv[8], wv[10], wv[0]
    f_dmp, react = work.ext[3], work.react
    for i in range(q.shape[0]):
        q[i] = q1[i]
        v[i] = v1[i]
        a[i] = a1[i]
        f0[i] = fi[i]
        fd0[i] = f_dmp[i]
        F0[i] = F1[i]
        Ma0[i] = Ma[i]
        Cv0[i] = Cv[i]
    for k in range(dof.shape[0]):
        R0[k] = react[k]
    th[TR_P0] = p_tr


@njit(**KERNEL)
def keep_projected(wp):
    """The arms' projected new terms (rows of work.proj, `projected_terms`) become the old ones. Called, taking
    the table: no reference counts (`PART`)."""
    x = projected_terms(wp)
    for i in range(x.Ma.shape[0]):
        x.Ma0[i] = x.Ma[i]
        x.Cv0[i] = x.Cv[i]
        x.f0[i] = x.fi[i]
        x.F0[i] = x.F1[i]


@njit(**PART)
def factor_aged(th, it, refresh):
    """An aging factor: the iterations its steps take beyond what it took fresh (the mean of its first
    REF_STEPS steps) add up; once they cost more than a new factor (refresh > 0), True: the next step
    gets one (the rent-or-buy rule: within 2x of the best choice). A drive whose steps take as many
    iterations with any factor never pays for one."""
    if th[REF_N] < REF_STEPS:
        th[REF_SUM] += it
        th[REF_N] += 1.0
        return False
    th[STALE] = max(0.0, th[STALE] + it - th[REF_SUM] / th[REF_N])
    return refresh > 0.0 and th[STALE] > refresh


@njit(**PART)
def projected_terms(wp):
    """The residual's `Terms` with arms: views of the projection rows (work.proj)."""
    return Terms(Ma=wp[3], Ma0=wp[9], Cv=wp[4], Cv0=wp[10], fi=wp[5], f0=wp[11], F1=wp[6], F0=wp[12], Fc=wp[7],
                 fl=wp[8])


@njit(**PART)
def terms_of(state, model, work):
    """The residual's `Terms` on q: views of the work rows and the state (no arms: q = p, J = I, the
    terms themselves, no copies) or of the projection rows (arms)."""
    wv = work.vec
    if model.arms.dof.shape[0] > 0:
        return projected_terms(work.proj)
    return Terms(Ma=wv[5], Ma0=wv[6], Cv=wv[7], Cv0=wv[8], fi=wv[10], f0=state.f0, F1=wv[0], F0=state.F0,
                 Fc=model.forcing.constant, fl=wv[11])


@njit(**KERNEL)
def begin_steps(state, model, fresh, x, work):
    """What a call of `run_steps` sets up once: the prescribed rows (work.held), the old terms M a and C v (and,
    with arms, the old terms projected into x), the factor's age (fresh: a new factor, its age starts), the wraps'
    solves of the factor anew (`regime_correction`). Returns the bristles' stored energy at the state."""
    q, v, a, th = state.q, state.v, state.a, state.scal
    lin, arms, dec, wraps, cons = model.linear, model.arms, model.decouplers, model.wraps, model.constraints
    wv = work.vec
    Ma0, Cv0 = wv[6], wv[8]
    for k in range(cons.dof.shape[0]):
        work.held[cons.dof[k]] = 1
    split_matvec(lin.M, a, Ma0)
    split_matvec(lin.C, v, Cv0)
    if arms.dof.shape[0] > 0:
        project(arms, q, Ma0, x.Ma0)
        project(arms, q, Cv0, x.Cv0)
        project(arms, q, state.f0, x.f0)
        project(arms, q, state.F0, x.F0)
    if fresh:
        th[STALE], th[REF_SUM], th[REF_N] = 0.0, 0.0, 0.0
    for k in range(wraps.updated.shape[0]):
        wraps.updated[k] = 0.0
    wv[12, :] = 0.0
    bristle0 = 0.0
    if arms.dof.shape[0] > 0:
        bristle0 += arm_friction(arms, q, wv[12])
    if dec.hub.shape[0] > 0:
        bristle0 += clutch_stored(dec, q)
    if wraps.wrap.shape[0] > 0:
        bristle0 += wrap_friction(wraps, q, wv[12], False, 0.0)
    return bristle0


@njit(**KERNEL)
def run_steps(state, model, opts, fac, fresh, out, ev, info, work):
    """Advance the state until t_stop, a full buffer, a refactorization request or the step budget: a
    loop over the stepper's parts (as PyElastica's do_step calls the system's hooks): predictor,
    constraints (`hold_prescribed`), arms (`complete`), forcing (`external_forces`), Newton, the step's
    power (`step_power`), observers (`balance_energy`, `record_outputs`, `span_min_forces`, `slack_events`),
    `accept`, the dry friction's return mappings (`slide_anchors`, `accept_clutches`, `slide_wraps`) and the
    factor's age (`factor_aged`). A part of a feature the drive lacks (belt elements, spring spans, arms, clutches,
    wraps, loads) is not called.

    Newton, from the predictor: at most max_iter corrections, the residual after the last one checked. Each
    evaluation: the forces at the new state (q1, v1, a1) into the scratch rows (`Work`): f_el, f_dmp (the belt's
    elements, `add_element_forces`, and spring spans, `spring_forces`; arm friction, the clutches over the step,
    the wraps), K (q1 - q_ref), C v1, M a1, the transport terms f_tr
    at the belt speed c1 and rate cd1 of the step's end, fi = f_el + K d + f_dmp + f_tr and fl the round-off
    scale (gross at the first evaluation only: a floor, not a force); then the arms' projection
    (`project_new`), the residual (`scaled_residual`) and the correction (`correct`). It is this loop's body,
    not a part, the model's arrays and scratch rows read once before the loop: each array a part takes is a
    reference count per call (`PART`; `bench/refcounts.py` counts them).

    Returns a code (DONE, BUFFER_FULL, REFACTOR, HALVE, MAX_STEPS). out receives the states at the
    output times (Hermite interpolation within the step), the energy terms of the step that contains
    each output time (exact at that step) and the constraint reactions. info (4,): on HALVE the
    time, the scaled residual, the worst DOF and the iterations.
    """
    q, v, a = state.q, state.v, state.a  # on the joint coordinates p (n); q[:nq] independent
    th = state.scal
    lin, arms, cons = model.linear, model.arms, model.constraints
    belt, F, tr, chk = model.belt, model.forcing, model.transport, model.check
    dec, wraps = model.decouplers, model.wraps
    dof, constant = cons.dof, F.constant
    with_arms, with_clutches, with_wraps = arms.dof.shape[0] > 0, dec.hub.shape[0] > 0, wraps.wrap.shape[0] > 0
    forced = F.nominal_scale != 0.0 or F.sig_params.shape[0] > 0  # F(t) changes in time, else it is F.constant
    follow, speed, rotation, scale, sig = tr.follow, tr.speed, F.nominal_rotation, F.nominal_scale, work.sig
    n = q.shape[0]
    dS, EA, elem_span, n_span = belt.dS, belt.EA, belt.elem_span, belt.n_span
    springs, n_springs = belt.springs, belt.n_springs
    e0, T, idx, tsel, d2S, wEA, wEI, Kb = belt.e0, belt.T, belt.idx, belt.tsel, belt.d2S, belt.wEA, belt.wEI, belt.Kb
    curvature, eta_a, eta_b = belt.curvature, belt.eta_a, belt.eta_b
    with_elements = tsel.shape[0] > 0
    E, q_ext, min_elem, min_span = work.elem[0], work.ext[0], work.elem1[1], work.span  # E, q_ext: last evaluation
    wv = work.vec
    F1, q1, v1, a1 = wv[0], wv[1], wv[2], wv[3]
    x = terms_of(state, model, work)
    q_ref, K, C, M, mag = lin.q_ref, lin.K, lin.C, lin.M, tr.mag
    moving = follow != 0 or speed != 0.0
    am, af, max_iter = opts.am, opts.af, chk.max_iter
    held, group_rows, worst_g = work.held, work.group, work.worst
    v_ext, f_el, f_dmp, gross = work.ext[1], work.ext[2], work.ext[3], work.ext[4]
    Ed, fe, fd = work.elem[1], work.elem[2], work.elem[3]
    dq, Ma, Cv, Kd, fi, fl, f_tr, tr_Bq, tr_Aq = wv[4], wv[5], wv[7], wv[9], wv[10], wv[11], wv[14], wv[15], wv[16]
    wp = work.proj
    R, dx, work_q = wp[0], wp[1], wp[2]
    bristle0 = begin_steps(state, model, fresh, x, work)
    steps = 0
    while True:
        t, h = th[T_NOW], th[H]
        if t >= opts.t_stop - 1e-6 * h:
            return DONE
        if out.n[0] >= out.t.shape[0]:
            return BUFFER_FULL
        if steps >= opts.max_steps:
            return MAX_STEPS
        t1 = t + h
        predict(h, q, v, a, q1, v1, a1, arms.n_q)
        hold_prescribed(cons, t1, q1, v1, a1)
        if with_arms:
            complete(arms, q1, v1, a1)
        if forced:
            external_forces(F, t1, F1, sig)
        else:  # F(t) = F.constant
            for i in range(n):
                F1[i] = constant[i]
        c1, cd1 = transport_speed(follow, speed, rotation, scale, t1)
        # Newton (the docstring)
        inv_h, c_a, c_v = 1.0 / h, 1.0 / (opts.beta * h * h), opts.gamma / (opts.beta * h)
        prev = np.inf
        it = 0
        while True:
            for i in range(n):  # the forces at the new state
                q_ext[i] = q1[i]
                v_ext[i] = v1[i]
                dq[i] = q1[i] - q_ref[i]
            for i in range(n + 1):
                f_el[i] = 0.0
                f_dmp[i] = 0.0
            if it == 0:
                for i in range(n + 1):
                    gross[i] = 0.0
            if with_elements:
                add_element_forces(e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, q_ext, v_ext, E,
                                    Ed, fe, fd, f_el, f_dmp, gross, it == 0)
            if n_springs > 0:
                sk.spring_forces(springs, q_ext, v_ext, f_el, f_dmp, gross, it == 0)
            bristle1 = ((arm_friction(arms, q1, f_dmp) if with_arms else 0.0)
                        + (clutch_torques(dec, q1, v1, inv_h, f_dmp) if with_clutches else 0.0))
            if with_wraps:
                bristle1 += wrap_friction(wraps, q1, f_dmp, True, h)
            split_matvec(K, dq, Kd)
            split_matvec(C, v1, Cv)
            qbq = 0.0
            p_tr = 0.0
            if moving:  # M a, A q, G v, B q in one pass
                fused_matvec(mag, a1, q1, v1, Ma, tr_Aq, tr_Bq, f_tr)
                qbq, vaq = transport_from(tr, c1, cd1, q1, v1, f_tr, tr_Bq, tr_Aq)
                p_tr = -cd1 * (c1 * qbq + vaq)
            else:
                split_matvec(M, a1, Ma)
            for i in range(n):
                fi[i] = f_el[i] + Kd[i] + f_dmp[i] + f_tr[i]
                fl[i] = gross[i] + abs(Kd[i]) + abs(constant[i]) + abs(f_tr[i])
            if with_arms:
                project_new(arms, constant, q1, wv, wp)
            res, worst, finite = scaled_residual(chk, held, am, af, x, R, group_rows, worst_g)
            converged = finite and res <= 1.0
            if converged or not finite or it >= max_iter:
                break
            factor_solve(fac, R, dx, work_q)
            if with_wraps and regime_changed(wraps):  # S in the wraps' regime of this evaluation
                regime_correction(wraps, fac, held, 1.0 - af, dx, work_q)
            norm = correct(dof, dx, R, c_v, c_a, q1, v1, a1)
            if with_arms:
                complete(arms, q1, v1, a1)
            it += 1
            if it >= 3 and norm > 0.25 * prev:  # convergence rate worse than 1/2 per iteration
                break
            prev = norm
        if not converged:
            info[0], info[1], info[2], info[3] = t1, res, worst, it
            return HALVE if fresh else REFACTOR
        # the step is accepted only if all of its output samples fit in the buffer
        n_pend = count_outputs(th[T_OUT], t1, h, opts.dt_out)
        if out.n[0] + n_pend > out.t.shape[0]:
            return BUFFER_FULL
        fresh = False
        p_ext, p_dis = step_power(state, dof, x, v1, p_tr, work)
        th[WORK] = th[WORK] + h * p_ext
        th[DISS] = th[DISS] + h * p_dis - (bristle1 - bristle0)  # the bristles' stored part is not lost
        if n_pend > 0:  # energy at this step (exact, not interpolated) and the samples in (t, t1]
            kin, pot = balance_energy(state, belt, lin, q1, v1, c1, qbq, bristle1, work)
            record_outputs(state, arms, dec, wraps, dof.shape[0], opts, out, t, h, q1, v1, a1, kin, pot,
                           work.react)
        span_min_forces(E, dS, EA, elem_span, n_span, min_elem, min_span)
        if n_springs > 0:
            sk.spring_min_force(springs, q_ext, min_span)
        slack_events(min_span, n_span, t1, ev)
        accept(state, dof, p_tr, work)
        if with_arms:  # the projected terms, the dry friction's return mappings
            keep_projected(wp)
            slide_anchors(arms, q)
        if with_clutches:
            accept_clutches(dec)
        if with_wraps:
            slide_wraps(wraps, q)
        bristle0 = 0.0  # the stored energy after the return mappings: the arms' bristles, the clutches', the wraps'
        if with_arms:
            bristle0 += arm_friction(arms, q, wv[12])
        if with_clutches:
            bristle0 += clutch_stored(dec, q)
        if with_wraps:  # the wraps' limits from the accepted tensions (E: q1's)
            th[DISS] += wrap_limits(wraps, belt, E, q_ext, c1, travel_speed(rotation, scale, t1))
            bristle0 += wrap_friction(wraps, q, wv[12], False, 0.0)
        th[T_NOW] = t1
        th[STEPS] += 1.0
        th[ITERS] += it
        steps += 1
        if factor_aged(th, it, opts.refresh):
            return REFACTOR


