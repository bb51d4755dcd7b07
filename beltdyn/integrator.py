"""Generalized-alpha (Chung-Hulbert 1993) time stepping of the reduced drive equations, in numba.

Equations of motion on the independent coordinates q (n,):
    M a + C v + f(q, v) = F(t),
f = f_belt(q) + f_damp(q, v) + k_s * q  (belt elastic force of paper Eqs. 14/17 through the joints,
Kelvin-Voigt belt damping, bearing springs), F(t) = preload + weight + applied loads - M u_nom s''(t)
(the inertia of the nominal belt travel s(t)), C = Rayleigh damping (CSR). One DOF may be
prescribed (the driver pulley's rotation); its residual row is dropped and its reaction recorded.

Generalized-alpha with spectral radius rho_inf:
    alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 - alpha_m + alpha_f,
    beta = (1 - alpha_m + alpha_f)^2 / 4,
    (1 - alpha_m) M a1 + alpha_m M a0 + (1 - alpha_f) (C v1 + f1 - F1) + alpha_f (C v0 + f0 - F0) = 0,
    q1 = q0 + h v0 + h^2 ((1/2 - beta) a0 + beta a1),  v1 = v0 + h ((1 - gamma) a0 + gamma a1).
Newton on q1 with a reused factorization of the iteration matrix
    S = (1 - alpha_m)/(beta h^2) M + (1 - alpha_f) gamma/(beta h) C_t + (1 - alpha_f) K_t,
given as a banded Cholesky factor (RCM-permuted) or a dense LU; the kernel returns to Python when
the factor is stale (slow convergence) or the step must be halved.

Array conventions: element data T (n_elem, 8, m), idx (n_elem, m) with padding index n, e0 (n_elem, 8),
dS (n_elem, n_qp, 4) = ds/dx at Gauss points, wL (n_elem, n_qp), EA (n_elem,), Kb (n_elem, 8, 8) =
EI int S''^T S'' dx (zeros without bending), elem_span (n_elem,).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# return codes of run_steps
DONE = 0  # reached t_stop
BUFFER_FULL = 1  # output buffer full: drain and call again
REFACTOR = 2  # convergence slowed: refactorize S at the current state and call again
HALVE = 3  # no convergence with a fresh factor: halve the step, refactorize, call again
MAX_STEPS = 4  # step budget of this call used up (keeps Ctrl-C responsive)


def alpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, beta, gamma) of Chung and Hulbert for spectral radius rho_inf in [0, 1]."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - am + af
    beta = 0.25 * (1.0 - am + af) ** 2
    return am, af, beta, gamma


@njit(cache=True)
def csr_matvec(indptr, indices, data, x, out):
    n = indptr.shape[0] - 1
    for i in range(n):
        s = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            s += data[k] * x[indices[k]]
        out[i] = s


@njit(cache=True)
def element_forces(q, v, T, idx, e0, dS, wL, EA, Kb, eta_a, eta_b, elem_span, n_span, f_el, f_dmp, min_force):
    """Belt elastic (f_el) and Kelvin-Voigt damping (f_dmp) forces, reduced, added into the outputs;
    min_force[s] = smallest 2nd Piola-Kirchhoff axial force EA eps over the Gauss points of span s."""
    n_elem, _, m = T.shape
    nq = dS.shape[1]
    E = np.empty(8)
    Ed = np.empty(8)
    fe = np.empty(8)
    fd = np.empty(8)
    for s in range(n_span):
        min_force[s] = np.inf
    for e in range(n_elem):
        for i in range(8):
            acc = e0[e, i]
            accd = 0.0
            for j in range(m):
                k = idx[e, j]
                acc += T[e, i, j] * q[k]
                accd += T[e, i, j] * v[k]
            E[i] = acc
            Ed[i] = accd
            fe[i] = 0.0
            fd[i] = 0.0
        for g in range(nq):
            rx = 0.0
            ry = 0.0
            rdx = 0.0
            rdy = 0.0
            for k in range(4):
                d = dS[e, g, k]
                rx += d * E[2 * k]
                ry += d * E[2 * k + 1]
                rdx += d * Ed[2 * k]
                rdy += d * Ed[2 * k + 1]
            eps = 0.5 * (rx * rx + ry * ry - 1.0)
            epsd = rx * rdx + ry * rdy
            s_el = wL[e, g] * EA[e] * eps
            s_dm = wL[e, g] * EA[e] * eta_a * epsd
            if EA[e] * eps < min_force[elem_span[e]]:
                min_force[elem_span[e]] = EA[e] * eps
            for k in range(4):
                d = dS[e, g, k]
                fe[2 * k] += s_el * d * rx
                fe[2 * k + 1] += s_el * d * ry
                fd[2 * k] += s_dm * d * rx
                fd[2 * k + 1] += s_dm * d * ry
        for i in range(8):
            a = 0.0
            b = 0.0
            for j in range(8):
                a += Kb[e, i, j] * E[j]
                b += Kb[e, i, j] * Ed[j]
            fe[i] += a
            fd[i] += eta_b * b
        for j in range(m):
            k = idx[e, j]
            a = 0.0
            b = 0.0
            for i in range(8):
                a += T[e, i, j] * fe[i]
                b += T[e, i, j] * fd[i]
            f_el[k] += a
            f_dmp[k] += b


@njit(cache=True)
def signal_values(params, tab_ptr, tab_t, tab_v, t, out):
    """out[i] = ramp_i(t) * (c + A sin(2 pi f t + phi)) or table interpolation; params (n, 5) = c, A, f, phi, T_ramp."""
    for i in range(params.shape[0]):
        a, b = tab_ptr[i], tab_ptr[i + 1]
        if b > a:
            val = np.interp(t, tab_t[a:b], tab_v[a:b])
        else:
            val = params[i, 0] + params[i, 1] * np.sin(2.0 * np.pi * params[i, 2] * t + params[i, 3])
        tr = params[i, 4]
        if tr > 0.0 and t < tr:
            val *= t / tr
        out[i] = val


@njit(cache=True)
def smoothstep(t, tr):
    """C1 fade-in 3x^2 - 2x^3 over [0, tr] and its first two derivatives."""
    if tr <= 0.0 or t >= tr:
        return 1.0, 0.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    x = t / tr
    return x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x) / tr, (6.0 - 12.0 * x) / (tr * tr)


@njit(cache=True)
def rotation_state(rot, t):
    """Prescribed rotation: (nominal angle, speed, acceleration), (fluctuation angle, speed, acceleration).

    rot = [speed Omega, ramp T_r, angle amplitude A, speed amplitude B, frequency f, phase phi, fade T_f,
           static angle offset] (the offset is added to the prescribed DOF by the caller).
    Nominal: speed ramps linearly to Omega over T_r. Fluctuation: w(t) * A sin(wt + phi) for an angle
    amplitude, or the angle whose speed is w(t) * B sin(wt + phi) (integrated analytically, zero at t=0
    for the unfaded part), w(t) the smoothstep fade-in over T_f.
    """
    om, tr, A, B, f, phi, tf = rot[0], rot[1], rot[2], rot[3], rot[4], rot[5], rot[6]
    if tr > 0.0 and t < tr:
        th, thd, thdd = 0.5 * om * t * t / tr, om * t / tr, om / tr
    else:
        th, thd, thdd = om * (t - 0.5 * tr), om, 0.0
    w = 2.0 * np.pi * f
    if A != 0.0:
        g, gd, gdd = A * np.sin(w * t + phi), A * w * np.cos(w * t + phi), -A * w * w * np.sin(w * t + phi)
    elif B != 0.0 and w > 0.0:
        g = (B / w) * (np.cos(phi) - np.cos(w * t + phi))
        gd = B * np.sin(w * t + phi)
        gdd = B * w * np.cos(w * t + phi)
    else:
        g, gd, gdd = 0.0, 0.0, 0.0
    s, sd, sdd = smoothstep(t, tf)
    return th, thd, thdd, s * g, sd * g + s * gd, sdd * g + 2.0 * sd * gd + s * gdd


@njit(cache=True)
def band_solve(cb, perm, b, x, work):
    """Solve S x = b with S[perm][:, perm] = U^T U, U in upper band storage cb (u+1, n)."""
    u = cb.shape[0] - 1
    n = cb.shape[1]
    for i in range(n):
        work[i] = b[perm[i]]
    for j in range(n):  # U^T y = b
        s = work[j]
        lo = max(0, j - u)
        for i in range(lo, j):
            s -= cb[u + i - j, j] * work[i]
        work[j] = s / cb[u, j]
    for i in range(n - 1, -1, -1):  # U x = y
        s = work[i]
        hi = min(n - 1, i + u)
        for j in range(i + 1, hi + 1):
            s -= cb[u + i - j, j] * work[j]
        work[i] = s / cb[u, i]
    for i in range(n):
        x[perm[i]] = work[i]


@njit(cache=True)
def dense_lu_solve(lu, piv, b, x):
    """Solve with a LAPACK getrf factorization (row interchanges piv, unit-lower L and U in lu)."""
    n = lu.shape[0]
    for i in range(n):
        x[i] = b[i]
    for i in range(n):
        p = piv[i]
        if p != i:
            tmp = x[i]
            x[i] = x[p]
            x[p] = tmp
    for i in range(n):
        s = x[i]
        for j in range(i):
            s -= lu[i, j] * x[j]
        x[i] = s
    for i in range(n - 1, -1, -1):
        s = x[i]
        for j in range(i + 1, n):
            s -= lu[i, j] * x[j]
        x[i] = s / lu[i, i]


@njit(cache=True)
def _forces(q, v, t, K, f_el, f_dmp, F, min_force, sig_val):
    """Internal force parts f_el (elastic + springs), f_dmp (belt damping) and external force F at (q, v, t)."""
    (T, idx, e0, dS, wL, EA, Kb, eta_a, eta_b, elem_span, n_span, spring, preload, grav, Mu, rot, pdof,
     nom_scale, load_dof, load_coef, load_sig, sig_params, tab_ptr, tab_t, tab_v) = K
    n = q.shape[0]
    for i in range(n + 1):
        f_el[i] = 0.0
        f_dmp[i] = 0.0
    element_forces(q, v, T, idx, e0, dS, wL, EA, Kb, eta_a, eta_b, elem_span, n_span, f_el, f_dmp, min_force)
    for i in range(n):
        f_el[i] += spring[i] * q[i]
        F[i] = preload[i] + grav[i]
    if nom_scale != 0.0:
        thdd = rotation_state(rot, t)[2]
        for i in range(n):
            F[i] -= Mu[i] * thdd * nom_scale
    signal_values(sig_params, tab_ptr, tab_t, tab_v, t, sig_val)
    for j in range(load_dof.shape[0]):
        F[load_dof[j]] += load_coef[j] * sig_val[load_sig[j]]


@njit(cache=True)
def run_steps(state, K, mats, fac, opts, out_t, out_q, out_v, out_a, out_w, n_out, events, n_events,
              slack, info):
    """Advance the state until t_stop, a full buffer, a refactorization request or the step budget.

    state: dict-like arrays packed as (q, v, a, f0, F0, t_h) with t_h = [t, h, t_next_out, W, D, R_d, steps];
    mats: (M CSR, C CSR); fac: (mode, cb, perm, lu, piv) mode 0 banded Cholesky, 1 dense LU;
    opts = [alpha_m, alpha_f, beta, gamma, tol, max_iter, t_stop, dt_out, max_steps, fresh];
    out_w (B, 3): work of loads, dissipated energy, driver reaction at the output times.
    info (4,): on HALVE/failure the time, residual, worst DOF, iterations.
    """
    q, v, a, f0, F0, th = state
    M_ptr, M_idx, M_dat, C_ptr, C_idx, C_dat = mats
    mode, cb, perm, lu, piv = fac
    am, af, beta, gamma = opts[0], opts[1], opts[2], opts[3]
    tol, max_iter, t_stop, dt_out, max_steps, fresh = opts[4], int(opts[5]), opts[6], opts[7], int(opts[8]), opts[9]
    n = q.shape[0]
    rot = K[15]
    pdof = K[16]
    n_span = K[10]
    B = out_t.shape[0]
    f_el = np.zeros(n + 1)
    f_dmp = np.zeros(n + 1)
    F1 = np.zeros(n)
    q1 = np.empty(n)
    v1 = np.empty(n)
    a1 = np.empty(n)
    R = np.empty(n)
    dq = np.empty(n)
    Ma = np.empty(n)
    Ma0 = np.empty(n)
    Cv = np.empty(n)
    Cv0 = np.empty(n)
    work = np.empty(n)
    min_force = np.empty(max(n_span, 1))
    sig_val = np.empty(K[21].shape[0])
    csr_matvec(M_ptr, M_idx, M_dat, a, Ma0)
    if C_ptr.shape[0] > 1:
        csr_matvec(C_ptr, C_idx, C_dat, v, Cv0)
    else:
        Cv0[:] = 0.0
    steps = 0
    while True:
        t, h = th[0], th[1]
        if t >= t_stop - 1e-6 * th[1]:
            return DONE
        if n_out[0] >= B:
            return BUFFER_FULL
        if steps >= max_steps:
            return MAX_STEPS
        t1 = t + h
        c_a = 1.0 / (beta * h * h)
        c_v = gamma / (beta * h)
        # predictor: same acceleration
        for i in range(n):
            a1[i] = a[i]
            q1[i] = q[i] + h * v[i] + h * h * a[i] * 0.5
            v1[i] = v[i] + h * a[i]
        if pdof >= 0:
            g, gd, gdd = rotation_state(rot, t1)[3:]
            q1[pdof] = rot[7] + g  # the static rotation plus the prescribed fluctuation
            v1[pdof] = gd
            a1[pdof] = gdd
        converged = False
        prev = np.inf
        it = 0
        res = np.inf
        worst = 0
        while True:  # at most max_iter corrections; the residual after the last one is checked
            _forces(q1, v1, t1, K, f_el, f_dmp, F1, min_force, sig_val)
            csr_matvec(M_ptr, M_idx, M_dat, a1, Ma)
            if C_ptr.shape[0] > 1:
                csr_matvec(C_ptr, C_idx, C_dat, v1, Cv)
            else:
                for i in range(n):
                    Cv[i] = 0.0
            scale = 1e-300
            res = 0.0
            for i in range(n):
                fi = f_el[i] + f_dmp[i]
                R[i] = ((1.0 - am) * Ma[i] + am * Ma0[i]
                        + (1.0 - af) * (Cv[i] + fi - F1[i]) + af * (Cv0[i] + f0[i] - F0[i]))
                sc = abs(Ma[i]) + abs(fi) + abs(F1[i]) + abs(Cv[i])
                if sc > scale:
                    scale = sc
            if pdof >= 0:
                R[pdof] = 0.0
            for i in range(n):
                r = abs(R[i])
                if not np.isfinite(r):
                    res = np.inf
                    worst = i
                    break
                if r > res:
                    res = r
                    worst = i
            res = res / scale
            if not np.isfinite(res):
                break
            if res <= tol:
                converged = True
                break
            if it >= max_iter:
                break
            if mode == 0:
                band_solve(cb, perm, R, dq, work)
            else:
                dense_lu_solve(lu, piv, R, dq)
            if pdof >= 0:
                dq[pdof] = 0.0
            norm = 0.0
            for i in range(n):
                d = -dq[i]
                q1[i] += d
                v1[i] += c_v * d
                a1[i] += c_a * d
                norm += d * d
            it += 1
            if it >= 3 and norm > 0.25 * prev:  # convergence rate worse than 1/2 per iteration
                break
            prev = norm
        if not converged:
            info[0] = t1
            info[1] = res
            info[2] = worst
            info[3] = it
            if fresh > 0.0:
                return HALVE
            return REFACTOR
        # the step is accepted only if all of its output samples fit in the buffer
        n_pend = 0
        tt = th[2]
        while tt <= t1 + 1e-6 * h:
            n_pend += 1
            tt += dt_out
        if n_out[0] + n_pend > B:
            return BUFFER_FULL
        fresh = 0.0
        # accepted: energy accounting (trapezoid) and outputs
        W_old, D_old = th[3], th[4]
        p_ext = 0.0
        p_dis = 0.0
        for i in range(n):
            p_ext += 0.5 * (F1[i] * v1[i] + F0[i] * v[i])
            p_dis += 0.5 * ((Cv[i] + f_dmp[i]) * v1[i] + (Cv0[i] + f0[n + i]) * v[i])
        # driver reaction (generalized force the prescribed motion applies) and its power
        Rd = 0.0
        if pdof >= 0:
            Rd = Ma[pdof] + Cv[pdof] + f_el[pdof] + f_dmp[pdof] - F1[pdof]
            p_ext += 0.5 * (Rd * v1[pdof] + th[5] * v[pdof])
        W_new = W_old + h * p_ext
        D_new = D_old + h * p_dis
        # outputs at t_next_out in (t, t1]
        while th[2] <= t1 + 1e-6 * h:
            tau = th[2]
            s = (tau - t) / h
            h00 = 2 * s ** 3 - 3 * s ** 2 + 1
            h10 = s ** 3 - 2 * s ** 2 + s
            h01 = -2 * s ** 3 + 3 * s ** 2
            h11 = s ** 3 - s ** 2
            k = n_out[0]
            out_t[k] = tau
            for i in range(n):
                out_q[k, i] = h00 * q[i] + h10 * h * v[i] + h01 * q1[i] + h11 * h * v1[i]
                out_v[k, i] = h00 * v[i] + h10 * h * a[i] + h01 * v1[i] + h11 * h * a1[i]
                out_a[k, i] = (1.0 - s) * a[i] + s * a1[i]
            out_w[k, 0] = (1.0 - s) * W_old + s * W_new
            out_w[k, 1] = (1.0 - s) * D_old + s * D_new
            out_w[k, 2] = (1.0 - s) * th[5] + s * Rd
            n_out[0] += 1
            th[2] += dt_out
        # slack events
        for sp in range(n_span):
            now = 1.0 if min_force[sp] < 0.0 else 0.0
            if now != slack[sp] and n_events[0] < events.shape[0]:
                events[n_events[0], 0] = t1
                events[n_events[0], 1] = sp
                events[n_events[0], 2] = now
                events[n_events[0], 3] = min_force[sp]
                n_events[0] += 1
            slack[sp] = now
        for i in range(n):
            q[i] = q1[i]
            v[i] = v1[i]
            a[i] = a1[i]
            f0[i] = f_el[i] + f_dmp[i]
            f0[n + i] = f_dmp[i]
            F0[i] = F1[i]
            Ma0[i] = Ma[i]
            Cv0[i] = Cv[i]
        th[0] = t1
        th[3] = W_new
        th[4] = D_new
        th[5] = Rd
        th[6] += 1.0
        steps += 1


def integrate_linear(M: np.ndarray, K: np.ndarray, C: np.ndarray | None, q0: np.ndarray, v0: np.ndarray, *,
                     step: float, n_steps: int, rho_inf: float, tol: float = 1e-12):
    """Integrate M a + C v + K q = 0 (dense, small) with the same kernel as the drive.

    For tests on analytic oscillators: no belt elements; K enters as a diagonal spring when it is
    diagonal, else through the Rayleigh slot is not possible, so K must be diagonal here and
    coupling goes through M and C. Returns t (n_steps+1,), q, v, a (n_steps+1, n).
    """
    from scipy.linalg import lu_factor

    n = M.shape[0]
    if np.count_nonzero(K - np.diag(np.diag(K))):
        raise ValueError("integrate_linear: K must be diagonal (couple through M or C)")
    am, af, beta, gamma = alpha_parameters(rho_inf)
    T = np.zeros((0, 8, 1))
    kernel = (T, np.zeros((0, 1), dtype=np.int64), np.zeros((0, 8)), np.zeros((0, 1, 4)), np.zeros((0, 1)),
              np.zeros(0), np.zeros((0, 8, 8)), 0.0, 0.0, np.zeros(0, dtype=np.int64), 0, np.diag(K).astype(float),
              np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(8), -1, 0.0, np.zeros(0, dtype=np.int64), np.zeros(0),
              np.zeros(0, dtype=np.int64), np.zeros((0, 5)), np.zeros(1, dtype=np.int64), np.zeros(0), np.zeros(0))

    def csr(A):
        rows, cols = np.nonzero(A)
        indptr = np.searchsorted(rows, np.arange(n + 1)).astype(np.int64)
        return indptr, cols.astype(np.int64), A[rows, cols].astype(float)

    Cm = np.zeros((n, n)) if C is None else C
    mats = (*csr(M), *(csr(Cm) if C is not None else (np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0))))
    S = (1 - am) / (beta * step**2) * M + (1 - af) * gamma / (beta * step) * Cm + (1 - af) * K
    lu, piv = lu_factor(S)
    fac = (1, np.zeros((1, 1)), np.arange(n, dtype=np.int64), lu, piv.astype(np.int64))
    q, v = q0.astype(float).copy(), v0.astype(float).copy()
    a = np.linalg.solve(M, -Cm @ v - K @ q)
    f0 = np.concatenate([K @ q, np.zeros(n)])
    state = (q, v, a, f0, np.zeros(n), np.array([0.0, step, 0.0, 0.0, 0.0, 0.0, 0.0]))
    B = n_steps + 1
    out_t, out_q, out_v, out_a, out_w = np.zeros(B), np.zeros((B, n)), np.zeros((B, n)), np.zeros((B, n)), np.zeros((B, 3))
    n_out = np.zeros(1, dtype=np.int64)
    opts = np.array([am, af, beta, gamma, tol, 20, n_steps * step, step, n_steps + 10, 1.0])
    code = run_steps(state, kernel, mats, fac, opts, out_t, out_q, out_v, out_a, out_w, n_out,
                     np.zeros((1, 4)), np.zeros(1, dtype=np.int64), np.zeros(0), np.zeros(4))
    if code not in (DONE, BUFFER_FULL):
        raise RuntimeError(f"integrate_linear: kernel returned {code}")
    k = int(n_out[0])
    return out_t[:k], out_q[:k], out_v[:k], out_a[:k]
