"""Independent reference for the pivoting-tensioner natural frequencies of a belt drive
in the rigid-belt limit (massless spans).  Pure numpy; does NOT import beltdyn.

Model (see DERIVATION.md for the derivation and every sign convention):

* planar drive, belt loop running COUNTER-CLOCKWISE around the pulleys, listed in loop order;
  span s runs from pulley s to pulley s+1 (mod N) with unit direction t_s, tangent points
  a_s (on pulley s) and b_s (on pulley s+1), length L_s = |b_s - a_s|;
* pulley j: centre c_j, radius R_j, mass m_j, polar inertia J_j, absolute rotation theta_j
  (counter-clockwise positive), optional ``side`` = +1 (default: pulley inside the loop, belt
  wraps it counter-clockwise) or -1 (backside idler: pulley outside the loop, wrapped clockwise);
* span-pulley joint: span end = material point of the pulley at the tangent point,
  r_end = c_j + R_j n + R_j theta_j tau + (centre displacement), n the outward normal of the pulley
  at the tangent point, tau = z x n  (tau = side_j * t_s);
* span = massless string, Green-Lagrange law: eps = (lambda^2 - 1)/2, lambda = ell/L0,
  true axial force N = EA * eps * lambda; the static state has N = T0 in every span and the
  given (tangent) geometry, so L0_s = L_s / lambda0 with lambda0 (lambda0^2 - 1)/2 = T0/EA;
* one pulley (arm['index']) sits on a rigid arm: centre c(phi) = P + l (cos phi, sin phi),
  phi counter-clockwise from +x, l = |c_T - P| at the static state; arm inertia J_arm about P
  (arm alone), torsion spring: torque on the arm about P = -k_arm (phi - phi_free)
  (counter-clockwise positive);
* all other centres are fixed, all rotations free (no rotation is held; the one rigid-body mode
  R_j theta_j side_j = const, phi = 0 is removed exactly).

Generalized coordinates q = (theta_0, ..., theta_{N-1}, psi), psi = phi - phi0.
Mass matrix M = diag(J_0, ..., J_{N-1}, J_arm + m_T l^2)  (theta_T is the ABSOLUTE pulley angle).
Stiffness  K = sum_s B_s^T (k_s t_s t_s^T + (T0/L_s) n_s n_s^T) B_s
               + e_psi e_psi^T (k_arm + l H.e_r),
with k_s = dN/dell = EA lambda0 (3 lambda0^2 - 1) / (2 L_s), H = T0 (t_out - t_in) the belt force on
the arm pulley, e_r = (c_T - P)/l, e_phi = z x e_r.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


# ----------------------------------------------------------------------------- material law
def static_stretch(EA: float, T0: float) -> float:
    """Stretch lambda0 = ell/L0 of a span carrying true axial force T0 (Green-Lagrange law).

    Solves lambda (lambda^2 - 1) / 2 = T0/EA (the unique root > 0 for T0 > -EA/(3 sqrt 3)...;
    we require T0 >= 0) by Newton from lambda = 1 + T0/EA.
    """
    if EA <= 0:
        raise ValueError(f"EA must be > 0, got {EA}")
    if T0 < 0:
        raise ValueError(f"T0 must be >= 0, got {T0}")
    x = T0 / EA
    lam = 1.0 + x
    for _ in range(60):
        f = 0.5 * lam * (lam * lam - 1.0) - x
        df = 0.5 * (3.0 * lam * lam - 1.0)
        step = f / df
        lam -= step
        if abs(step) < 1e-16 * lam:
            break
    return lam


def axial_stiffness(EA: float, T0: float, L: float) -> float:
    """Tangent axial stiffness dN/d(ell) of a span of CURRENT length L carrying true force T0.

    Green-Lagrange: N(ell) = EA * eps * lambda, eps = (lambda^2-1)/2, lambda = ell/L0, so
    dN/dell = (EA/L0) (3 lambda^2 - 1)/2 = EA lambda0 (3 lambda0^2 - 1) / (2 L)
            = (EA/L) (1 + 4 T0/EA - 1.5 (T0/EA)^2 + ...).
    """
    lam = static_stretch(EA, T0)
    return EA * lam * (3.0 * lam * lam - 1.0) / (2.0 * L)


# ----------------------------------------------------------------------------- geometry
def _as_arrays(pulleys):
    c = np.array([np.asarray(p["center"], dtype=float) for p in pulleys])
    R = np.array([float(p["radius"]) for p in pulleys])
    side = np.array([float(p.get("side", 1)) for p in pulleys])
    if c.ndim != 2 or c.shape[1] != 2:
        raise ValueError("each pulley center must be a 2-vector")
    if np.any(R <= 0):
        raise ValueError(f"radii must be > 0, got {R}")
    if not np.all(np.isin(side, (1.0, -1.0))):
        raise ValueError(f"side must be +1 or -1, got {side}")
    return c, R, side


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _angle_ccw(u, v):
    """Counter-clockwise angle from unit vector u to unit vector v, in [0, 2 pi)."""
    return np.mod(np.arctan2(_cross(u, v), np.dot(u, v)), TWO_PI)


def loop_geometry(pulleys, check: bool = True) -> dict:
    """Tangent geometry of a counter-clockwise belt loop.

    Span s: from pulley j = s to pulley k = s+1 (mod N). With nL = z x t (left normal of the
    belt), a pulley with side = +1 lies on the LEFT of the belt (inside the CCW loop): its
    centre is c = a + R nL; side = -1 lies on the right. Tangency of the line to both circles
    requires nL . (c_k - c_j) = side_k R_k - side_j R_j =: rho, so with c_k - c_j = d (cos b, sin b)
    the direction is t = (cos alpha, sin alpha), alpha = b - asin(rho/d) (branch with t.(c_k-c_j)>0).

    Returns dict with t, nL (span left normals), a, b (tangent points), L (span lengths),
    n_a, n_b (outward pulley normals at a_s and b_s), tau_a, tau_b (z x n; = side*t),
    wrap (contact angle on each pulley, > 0), and the inputs.
    """
    c, R, side = _as_arrays(pulleys)
    N = len(c)
    if N < 2:
        raise ValueError("need at least two pulleys")
    t = np.zeros((N, 2))
    nL = np.zeros((N, 2))
    a = np.zeros((N, 2))
    b = np.zeros((N, 2))
    L = np.zeros(N)
    for s in range(N):
        j, k = s, (s + 1) % N
        D = c[k] - c[j]
        d = np.hypot(*D)
        rho = side[k] * R[k] - side[j] * R[j]
        if abs(rho) >= d:
            raise ValueError(f"span {s}: no common tangent between pulleys {j} and {k}")
        alpha = np.arctan2(D[1], D[0]) - np.arcsin(rho / d)
        t[s] = (np.cos(alpha), np.sin(alpha))
        nL[s] = (-np.sin(alpha), np.cos(alpha))
        a[s] = c[j] - side[j] * R[j] * nL[s]
        b[s] = c[k] - side[k] * R[k] * nL[s]
        L[s] = np.sqrt(d * d - rho * rho)
    n_a = np.array([(a[s] - c[s]) / R[s] for s in range(N)])
    n_b = np.array([(b[s] - c[(s + 1) % N]) / R[(s + 1) % N] for s in range(N)])
    zx = lambda v: np.stack([-v[:, 1], v[:, 0]], axis=1)  # z x v
    tau_a, tau_b = zx(n_a), zx(n_b)
    # contact (wrap) angle on pulley j: from the arrival normal (end of span j-1) to the
    # departure normal (start of span j), counter-clockwise for side=+1, clockwise for side=-1.
    wrap = np.zeros(N)
    for j in range(N):
        n_arr, n_dep = n_b[(j - 1) % N], n_a[j]
        wrap[j] = _angle_ccw(n_arr, n_dep) if side[j] > 0 else _angle_ccw(n_dep, n_arr)
    geo = dict(c=c, R=R, side=side, t=t, nL=nL, a=a, b=b, L=L, n_a=n_a, n_b=n_b,
               tau_a=tau_a, tau_b=tau_b, wrap=wrap)
    if check:
        _check_loop(geo)
    return geo


def _check_loop(geo):
    c, R, side, a, b, wrap = geo["c"], geo["R"], geo["side"], geo["a"], geo["b"], geo["wrap"]
    N = len(c)
    turning = float(np.sum(side * wrap))
    if not np.isclose(turning, TWO_PI, atol=1e-9):
        raise ValueError(
            f"not a simple counter-clockwise loop: sum(side*wrap) = {turning:.6f} rad, expected 2 pi "
            f"(wraps {np.degrees(wrap)} deg); list the pulleys in counter-clockwise loop order")
    for s in range(N):
        for j in range(N):
            if j in (s, (s + 1) % N):
                continue
            # distance from centre j to segment a_s b_s
            ab = b[s] - a[s]
            u = np.clip(np.dot(c[j] - a[s], ab) / np.dot(ab, ab), 0.0, 1.0)
            dist = np.hypot(*(a[s] + u * ab - c[j]))
            if dist < R[j] * (1 - 1e-12):
                raise ValueError(f"span {s} cuts through pulley {j}")


# ----------------------------------------------------------------------------- arm / statics
def arm_kinematics(pulleys, arm) -> dict:
    """phi0, l, e_r, e_phi of the arm at the given geometry (phi CCW from +x, from P to c_T)."""
    c, _, _ = _as_arrays(pulleys)
    iT = int(arm["index"])
    P = np.asarray(arm["pivot"], dtype=float)
    rvec = c[iT] - P
    l = float(np.hypot(*rvec))
    if l <= 0:
        raise ValueError("arm pivot coincides with the tensioner pulley centre")
    e_r = rvec / l
    e_phi = np.array([-e_r[1], e_r[0]])
    return dict(index=iT, P=P, l=l, phi0=float(np.arctan2(e_r[1], e_r[0])), e_r=e_r, e_phi=e_phi)


def hub_force(pulleys, T0: float, index: int, geo=None) -> np.ndarray:
    """Force of the belt on pulley `index`: H = T0 (t_out - t_in), |H| = 2 T0 sin(wrap/2)."""
    geo = loop_geometry(pulleys) if geo is None else geo
    N = len(geo["c"])
    return T0 * (geo["t"][index] - geo["t"][(index - 1) % N])


def arm_belt_torque(pulleys, arm, T0: float) -> float:
    """Moment about the pivot of the belt force on the arm pulley, z-component (CCW positive):
    M_belt = (c_T - P) x H = l H.e_phi.  The spring must supply -M_belt, i.e.
    k_arm (phi0 - phi_free) = M_belt."""
    geo = loop_geometry(pulleys)
    ak = arm_kinematics(pulleys, arm)
    H = hub_force(pulleys, T0, ak["index"], geo)
    return float(_cross(ak["l"] * ak["e_r"], H))


def arm_free_angle(pulleys, arm, T0: float) -> float:
    """Spring free angle phi_free (rad, CCW from +x, same convention as phi) that makes the given
    geometry a static equilibrium with tension T0 in all spans: phi_free = phi0 - M_belt/k_arm."""
    k = float(arm["stiffness"])
    if k <= 0:
        raise ValueError("arm stiffness must be > 0 to have a free angle")
    ak = arm_kinematics(pulleys, arm)
    return ak["phi0"] - arm_belt_torque(pulleys, arm, T0) / k


# ----------------------------------------------------------------------------- linear model
ALL_TERMS = ("axial", "transverse", "arm_geometric")


def linear_model(pulleys, arm, EA: float, T0, terms=ALL_TERMS, end_mass=None) -> dict:
    """Mass and stiffness matrices of the rigid-belt model about the static state.

    q = (theta_0..theta_{N-1}, psi).  Returns dict(K, M, rigid (exact rigid-body vector),
    geo, arm kinematics, H, k_axial (per span), K_geo (= l H.e_r), lambda0, L0 (per span)).
    `terms` is for diagnostics only (drop a term to see that the checks detect it).

    T0: the true axial force of every span, or one per span (N,) (a drive under accessory torques: the
    hub force on the arm pulley is then H = T_out t_out - T_in t_in, each span's axial and transverse
    stiffness at its own force). end_mass (N,), kg: a mass lumped on each end of span s (a spring span's
    rho L0_s / 2), moving with the material point of its pulley at the tangent point (velocity
    R_j theta_j' tau + l psi' e_phi on the arm pulley): M then has the blocks m B^T B of each end.
    """
    geo = loop_geometry(pulleys)
    ak = arm_kinematics(pulleys, arm)
    N = len(geo["c"])
    iT, l, e_r, e_phi = ak["index"], ak["l"], ak["e_r"], ak["e_phi"]
    R = geo["R"]
    nq = N + 1
    T_s = np.broadcast_to(np.asarray(T0, dtype=float), (N,))
    lam0 = np.array([static_stretch(EA, T) for T in T_s])
    kax = np.array([axial_stiffness(EA, T, Ls) for T, Ls in zip(T_s, geo["L"])])
    K = np.zeros((nq, nq))
    M_ends = np.zeros((nq, nq))
    for s in range(N):
        j, k = s, (s + 1) % N
        B = np.zeros((2, nq))          # d_s = (end displacement) - (start displacement) = B q
        B[:, j] -= R[j] * geo["tau_a"][s]
        B[:, k] += R[k] * geo["tau_b"][s]
        if j == iT:
            B[:, N] -= l * e_phi
        if k == iT:
            B[:, N] += l * e_phi
        t, n = geo["t"][s], geo["nL"][s]
        D = (("axial" in terms) * kax[s] * np.outer(t, t)
             + ("transverse" in terms) * (T_s[s] / geo["L"][s]) * np.outer(n, n))
        K += B.T @ D @ B
        if end_mass is not None:  # the velocities of the span's two ends (tangent points)
            Ba, Bb = np.zeros((2, nq)), np.zeros((2, nq))
            Ba[:, j] = R[j] * geo["tau_a"][s]
            Bb[:, k] = R[k] * geo["tau_b"][s]
            if j == iT:
                Ba[:, N] = l * e_phi
            if k == iT:
                Bb[:, N] = l * e_phi
            M_ends += float(end_mass[s]) * (Ba.T @ Ba + Bb.T @ Bb)
    H = T_s[iT] * geo["t"][iT] - T_s[(iT - 1) % N] * geo["t"][(iT - 1) % N]  # (`hub_force` for one T0)
    K_geo = l * float(np.dot(H, e_r))   # = -H . d2c/dphi2 = H.(c_T - P)
    K[N, N] += float(arm["stiffness"]) + ("arm_geometric" in terms) * K_geo
    m = np.array([float(p["inertia"]) for p in pulleys]
                 + [float(arm["inertia"]) + float(pulleys[iT]["mass"]) * l * l])
    if np.any(m <= 0):
        raise ValueError("all inertias must be > 0")
    rigid = np.append(geo["side"] / R, 0.0)   # R_j theta_j side_j = 1, psi = 0: K @ rigid = 0
    return dict(K=K, M=np.diag(m) + M_ends, m=m, rigid=rigid, geo=geo, arm=ak, H=H, k_axial=kax,
                K_geo=K_geo, lambda0=lam0 if np.ndim(T0) else float(lam0[0]), L0=geo["L"] / lam0)


def _reduced_symmetric(model):
    """Mass-normalized stiffness on the M-orthogonal complement of the rigid-body mode.

    Returns (A, Q, s) with A = Q^T S K S Q, S = M^{-1/2}; eigenpairs (w2, y) of A give mode
    shapes q = S Q y.  The rigid-body vector is removed exactly (no zero threshold)."""
    K, m = model["K"], model["m"]
    s = 1.0 / np.sqrt(m)
    Kt = K * np.outer(s, s)
    r = np.sqrt(m) * model["rigid"]
    r /= np.linalg.norm(r)
    # orthonormal basis of the complement of r (Householder reflection)
    n = len(r)
    v = r.copy()
    v[0] += np.copysign(1.0, r[0]) if r[0] != 0 else 1.0
    Hh = np.eye(n) - 2.0 * np.outer(v, v) / np.dot(v, v)   # Hh e0 = -+ r
    Q = Hh[:, 1:]
    A = Q.T @ Kt @ Q
    return 0.5 * (A + A.T), Q, s


def linear_modes(pulleys, arm, EA: float, T0, end_mass=None):
    """(frequencies in Hz ascending, mode shapes as columns in q, model); rigid mode excluded.
    T0, end_mass: as `linear_model` (with end masses M is full: the modes on the M-orthogonal complement
    of the rigid-body vector, by scipy's generalized symmetric eigensolver)."""
    model = linear_model(pulleys, arm, EA, T0, end_mass=end_mass)
    if end_mass is not None:
        from scipy.linalg import eigh, null_space

        K, M, r = model["K"], model["M"], model["rigid"]
        Q = null_space((M @ r)[None, :])  # the complement of the rigid mode, M-orthogonal to it
        w2, Y = eigh(Q.T @ K @ Q, Q.T @ M @ Q)
        return np.sqrt(np.clip(w2, 0.0, None)) / TWO_PI, Q @ Y, model
    A, Q, s = _reduced_symmetric(model)
    w2, Y = np.linalg.eigh(A)
    if np.any(w2 < -1e-9 * np.max(np.abs(w2))):
        raise ValueError(f"static state unstable: omega^2 = {w2}")
    f = np.sqrt(np.clip(w2, 0.0, None)) / TWO_PI
    shapes = (s[:, None] * (Q @ Y))
    return f, shapes, model


def kinetic_energy_fractions(shapes, model) -> np.ndarray:
    """(n_dof, n_mode) share of each coordinate in each mode's kinetic energy; the last row is
    the arm (psi).  The tensioner mode is the one with the largest last-row entry."""
    e = model["m"][:, None] * shapes ** 2
    return e / e.sum(axis=0)


def linear_frequencies(pulleys, arm, EA: float, T0: float) -> np.ndarray:
    """Natural frequencies (Hz, ascending) of the rigid-belt model, rigid-body zero excluded.

    pulleys: list of dicts in counter-clockwise loop order with keys center (2,), radius,
             inertia, mass, optional side (+1 inside the loop, default; -1 backside idler).
    arm:     dict(index, pivot (2,), inertia (arm alone about the pivot), stiffness (N m/rad)).
    EA (N), T0 (N, true static axial force in every span).
    """
    return linear_modes(pulleys, arm, EA, T0)[0]


# ----------------------------------------------------------------------------- 1-DOF limits
def one_dof_terms(pulleys, arm, EA: float, T0: float, limit: str = "neighbours_locked") -> dict:
    """Stiffness terms of the arm coordinate psi in an exact 1-DOF limit; omega^2 = K_eff/J_eff.

    K_eff = k_arm + K_geo + K_trans + K_ax, J_eff = J_arm + m_T l^2, with
      K_geo   = l H.e_r                                      (arm geometric stiffness)
      K_trans = T0 l^2 [ (n_in.e_phi)^2/L_in + (n_out.e_phi)^2/L_out ]   (span rotation)
      K_ax    = depends on which pulley rotations are free, with g_in = l t_in.e_phi,
                g_out = l t_out.e_phi, k_in, k_out the tangent axial stiffnesses:
        'all_locked'        (every J -> inf, incl. J_T):       k_in g_in^2 + k_out g_out^2
        'neighbours_locked' (J_j -> inf for j != T, J_T -> 0):  k_io (g_in - g_out)^2,
                             k_io = k_in k_out / (k_in + k_out)  (the two spans in series)
        'all_free'          (every J_j -> 0):                    k_loop (g_in - g_out)^2,
                             k_loop = 1 / sum_s (1/k_s)          (the whole belt in series)
    Note l (t_in - t_out).e_phi = -l H.e_phi / T0 = -M_belt/T0.
    """
    geo = loop_geometry(pulleys)
    ak = arm_kinematics(pulleys, arm)
    N = len(geo["c"])
    iT, l, e_r, e_phi = ak["index"], ak["l"], ak["e_r"], ak["e_phi"]
    s_in, s_out = (iT - 1) % N, iT
    H = hub_force(pulleys, T0, iT, geo)
    kax = np.array([axial_stiffness(EA, T0, Ls) for Ls in geo["L"]])
    g_in = l * np.dot(geo["t"][s_in], e_phi)
    g_out = l * np.dot(geo["t"][s_out], e_phi)
    K_geo = l * float(np.dot(H, e_r))
    K_trans = T0 * l * l * (np.dot(geo["nL"][s_in], e_phi) ** 2 / geo["L"][s_in]
                            + np.dot(geo["nL"][s_out], e_phi) ** 2 / geo["L"][s_out])
    if limit == "all_locked":
        K_ax = kax[s_in] * g_in ** 2 + kax[s_out] * g_out ** 2
    elif limit == "neighbours_locked":
        K_ax = kax[s_in] * kax[s_out] / (kax[s_in] + kax[s_out]) * (g_in - g_out) ** 2
    elif limit == "all_free":
        K_ax = (g_in - g_out) ** 2 / np.sum(1.0 / kax)
    else:
        raise ValueError(f"unknown limit {limit!r}")
    k_arm = float(arm["stiffness"])
    J_eff = float(arm["inertia"]) + float(pulleys[iT]["mass"]) * l * l
    K_eff = k_arm + K_geo + K_trans + K_ax
    return dict(k_arm=k_arm, K_geo=K_geo, K_trans=K_trans, K_ax=K_ax, K_eff=K_eff, J_eff=J_eff,
                f=np.sqrt(K_eff / J_eff) / TWO_PI, H=H, l=l)


def symmetric_three_pulley_frequency(h, v, R_out, R_T, chi, l, EA, T0, k_arm, J_arm, m_T):
    """Closed form (no matrix model) for the symmetric three-pulley drive in the
    'neighbours_locked' limit (J_A, J_C -> inf, J_T -> 0).

    Geometry: A at (-h, 0), C at (+h, 0), both radius R_out, tensioner T at (0, -v), radius R_T,
    loop A -> T -> C -> A counter-clockwise (T inside the loop, hub force along +y).
    chi: angle from the arm direction e_r = (c_T - P)/l to the hub force H (CCW positive),
    i.e. phi0 = pi/2 - chi.

      L   = sqrt(h^2 + v^2 - (R_T - R_out)^2)                       (length of spans A-T, T-C)
      w/2 = atan(v/h) + asin((R_T - R_out)/sqrt(h^2 + v^2))          (half wrap angle on T)
      k   = EA lambda0 (3 lambda0^2 - 1)/(2 L),  lambda0 (lambda0^2 - 1)/2 = T0/EA
      K_eff = k_arm + 2 T0 l sin(w/2) cos(chi)                        (geometric, = l H.e_r)
              + (T0 l^2 / L) (1 - cos(2 chi) cos(w))                  (span rotation)
              + 2 k l^2 sin^2(w/2) sin^2(chi)                         (spans A-T, T-C in series)
      J_eff = J_arm + m_T l^2,     f = sqrt(K_eff/J_eff) / (2 pi).
    Returns dict with the pieces.
    """
    D = np.hypot(h, v)
    L = np.sqrt(D * D - (R_T - R_out) ** 2)
    half_w = np.arctan2(v, h) + np.arcsin((R_T - R_out) / D)
    k = axial_stiffness(EA, T0, L)
    K_geo = 2.0 * T0 * l * np.sin(half_w) * np.cos(chi)
    K_trans = T0 * l * l / L * (1.0 - np.cos(2.0 * chi) * np.cos(2.0 * half_w))
    K_ax = 2.0 * k * l * l * np.sin(half_w) ** 2 * np.sin(chi) ** 2
    K_eff = k_arm + K_geo + K_trans + K_ax
    J_eff = J_arm + m_T * l * l
    return dict(L=L, wrap=2.0 * half_w, k_axial=k, K_geo=K_geo, K_trans=K_trans, K_ax=K_ax,
                K_eff=K_eff, J_eff=J_eff, f=np.sqrt(K_eff / J_eff) / TWO_PI)


# ----------------------------------------------------------------------------- the example
def example_drive(phi0_deg: float = 15.0):
    """The brief's example: A (driver) (0,0) R 0.05; T (0.25,-0.10) R 0.03 on the arm; C (0.5,0)
    R 0.08.  With T below the line A-C the counter-clockwise loop order is A -> T -> C -> A.
    Arm: l = 0.08, phi0 = 15 deg (pivot P = c_T - l (cos phi0, sin phi0)); the hub force points
    at 86.78 deg, so the arm is 71.78 deg from it (roughly perpendicular, stabilizing K_geo > 0).
    Returns (pulleys, arm, EA, T0)."""
    cT = np.array([0.25, -0.10])
    l = 0.08
    ph = np.radians(phi0_deg)
    P = cT - l * np.array([np.cos(ph), np.sin(ph)])
    pulleys = [
        dict(name="A", center=(0.0, 0.0), radius=0.05, mass=1.0, inertia=1e-3),
        dict(name="T", center=tuple(cT), radius=0.03, mass=0.3, inertia=2e-4),
        dict(name="C", center=(0.5, 0.0), radius=0.08, mass=2.0, inertia=4e-3),
    ]
    arm = dict(index=1, pivot=tuple(P), inertia=1e-3, stiffness=50.0)
    return pulleys, arm, 1.2e5, 200.0


if __name__ == "__main__":
    pulleys, arm, EA, T0 = example_drive()
    print("frequencies (Hz):", linear_frequencies(pulleys, arm, EA, T0))
    print("arm free angle (deg):", np.degrees(arm_free_angle(pulleys, arm, T0)))
