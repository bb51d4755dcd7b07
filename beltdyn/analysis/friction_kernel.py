"""The stepper's dry-friction kernels (`integrator`'s parts, compiled with numba): the tensioner arms'
friction, the decouplers' one-way clutches and the wraps that may slip.

An arm's dry friction torque T_f is regularized as an elasto-plastic (bristle, Dahl-type) element: a
stiff torsion spring k_b = T_f / delta (presliding angle delta = `ARM_PRESLIDING`) from an anchor
angle z that slides when the torque reaches T_f (a return mapping after each accepted step):
torque = clip(k_b (phi - z), -T_down, T_up), with two limits by sense (asymmetric damping: T_up while
the arm slides counter-clockwise, T_down clockwise; `model.arms.friction_by_sense` maps loading and
unloading onto them) and k_b from the larger. It sticks exactly (no creep) and slides at exactly its limit;
its stiffness k_b enters the iteration matrix like a spring, not like a damper over the step, so the
stick-slip transitions keep the factor (a tanh(phi'/omega) law put T_f / omega / h there and forced
step halvings). Its work is dissipated, less the bristle's stored energy tau^2 / (2 k_b).

Decouplers (`Decouplers`, `model.decouplers`): the engaged spring k and damper c between a pulley's hub
and its rotor are in the linear part (K, C); a one-way clutch in series slips by an angle z when the
torque would fall below the bound -drag (the rotor overruns): tau = k (phi - z) + c (phi' - z'), phi =
theta_hub - theta_rotor, held at tau >= -drag, with z from a backward-Euler slip over the step
(`clutch_torques`: while it slips, k (phi - z1) + c (phi' - (z1 - z0)/h) = -drag) and accepted with the
step. Its correction to the linear part's torque, tau - k phi - c phi', joins the dissipative forces;
the spring's stored energy k (phi - z)^2 / 2 replaces the linear part's k phi^2 / 2 (the difference
joins the bristles' stored energy), so the clutch's slip work counts as dissipated.

Wraps that may slip (`Wraps`, `transient_wraps`, docs/wraps.md): a pulley's rotation split into the wrap
angle psi (the rotation DOF the span ends follow) and its own rotation theta (a DOF after the system's
independent coordinates), joined by the same elasto-plastic bristle (`bristle`, `slid_anchor`): torque
M = clip(k_b (psi - theta - z), -M_cap, M_cap), +M on psi and -M on theta, the limit M_cap = R (T_max - c)
(1 - exp(-mu beta)) of the end tensions at the last accepted step (`wrap_limits`, explicit over a step;
the stored energy a falling limit releases is dissipated). The iteration matrix holds a sticking
bristle's k_b and none of a sliding one, in the regime the last evaluation found (`Wraps.sliding`;
`regime_changed` tells the stepper where the factor's regime differs, `friction_kernel.regime_correction` updates
its solve by a low-rank correction). Without
slipping wraps (k = 0) none of this runs: the stepper is the one without the part.

Creep of a sticking wrap (`wrap_creep`, docs/wraps.md "Creep in time"): the rim of pulley k moves with the
belt at its wrap's entry (the adhesion arc), at lambda_e,k / lambda_e,drv of the driver's rim speed c (the
belt travel speed of the prescribed rotation), so its anchor drifts at z' = c u_k (1 - lambda_e,k /
lambda_e,drv) (u_k the nominal rotation per metre of belt): z = anchor + z' dt over a step (`wrap_friction`,
`slide_wraps`), z' from the accepted state's end stretches (`wrap_limits`, explicit over a step as the limit
is). Its work, the integral of M dz, is what the dissipated term (the bristle's power less the change of its
stored energy) holds.

Nomenclature: tau, M torque (N m), k_b bristle stiffness (N m/rad), z anchor angle (rad), phi arm angle or
hub-rotor angle (rad), psi wrap angle, theta the pulley's own rotation (rad), T tension (N), lambda stretch
(1), c belt speed (m/s), mu friction coefficient, beta wrap angle (rad), R radius (m), h step (s). Arrays
as `stepper_data` (`Arms`, `Decouplers`, `Wraps`: (k,) per item).
"""

from __future__ import annotations

import numpy as np

from beltdyn.jitcache import configure, kernel_options

configure()  # where numba caches the kernels (the package folder, else a user cache folder): before numba loads
from numba import njit  # noqa: E402

from beltdyn.analysis.band_solve import factor_solve  # noqa: E402
from beltdyn.model import spring_kernel as sk  # noqa: E402

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)
PART = dict(KERNEL, inline="always")  # a part of the stepper's Newton loop (`integrator.correct`), inlined there


@njit(**KERNEL)
def bristle(k_b, x, z, up, down):
    """The elasto-plastic (bristle, Dahl-type) dry friction element, the one implementation of the arms'
    and the wraps' friction: (tau, stored) = (clip(k_b (x - z), -down, up), tau^2 / (2 k_b)) for the
    coordinate x (rad), its anchor z, the stiffness k_b (N m/rad) and the limits up, down (N m) by sense."""
    tau = min(max(k_b * (x - z), -down), up)
    return tau, 0.5 * tau * tau / k_b


@njit(**KERNEL)
def slid_anchor(k_b, x, z, up, down):
    """The return mapping of a `bristle` after an accepted step: its anchor z, slid along where the
    bristle's torque k_b (x - z) exceeds a limit (up in the positive sense, down in the negative)."""
    e = x - z
    u, d = up / k_b, down / k_b
    if e > u:
        return x - u
    if e < -d:
        return x + d
    return z


@njit(**KERNEL)
def arm_friction(arms, q, f):
    """Add the arms' dry friction torques clip(k_b (phi - z), -T_down, T_up) to f (on the angles); returns
    the bristles' stored energy sum tau^2 / (2 k_b). T_up, T_down: the limits sliding counter-clockwise
    and clockwise (arms.friction_up, arms.friction_down: loading or unloading by the arm's sense)."""
    stored = 0.0
    for k in range(arms.dof.shape[0]):
        if arms.friction_up[k] != 0.0 or arms.friction_down[k] != 0.0:
            d = arms.dof[k]
            tau, e = bristle(arms.bristle[k], q[d], arms.anchor[k], arms.friction_up[k], arms.friction_down[k])
            f[d] += tau
            stored += e
    return stored


@njit(**KERNEL)
def clutch_torques(dec, q, v, inv_h, f):
    """The decouplers' clutches at the state (q, v) of a step of length 1 / inv_h (inv_h = 0: no step, the
    slip a spring's alone) from the accepted slip z0 = dec.slip[0]: tau = k (phi - z0) + c phi' while it
    holds, else -drag with z1 = (k phi + c phi' + c z0 / h + drag) / (k + c / h) (module docstring); adds the
    correction tau - k phi - c phi' to f at the hub (minus at the rotor), writes z1 and tau into dec.slip[1],
    dec.torque[1]. Returns the stored energy beyond the linear part's: sum k ((phi - z1)^2 - phi^2) / 2."""
    stored = 0.0
    for i in range(dec.hub.shape[0]):
        b, r = dec.hub[i], dec.rotor[i]
        k, c, drag = dec.stiffness[i], dec.damping[i], dec.drag[i]
        phi = q[b] - q[r]
        w = v[b] - v[r]
        z0 = dec.slip[0, i]
        z = z0
        tau = k * (phi - z0) + c * w
        if tau < -drag:  # overrunning: the clutch slips at its bound
            tau = -drag
            z = (k * phi + c * w + c * z0 * inv_h + drag) / (k + c * inv_h)
        dec.slip[1, i] = z
        dec.torque[1, i] = tau
        extra = tau - k * phi - c * w
        f[b] += extra
        f[r] -= extra
        stored += 0.5 * k * ((phi - z) * (phi - z) - phi * phi)
    return stored


@njit(**KERNEL)
def clutch_stored(dec, q):
    """The decouplers' stored energy beyond the linear part's at q with the accepted slip (`clutch_torques`)."""
    stored = 0.0
    for i in range(dec.hub.shape[0]):
        phi = q[dec.hub[i]] - q[dec.rotor[i]]
        e = phi - dec.slip[0, i]
        stored += 0.5 * dec.stiffness[i] * (e * e - phi * phi)
    return stored


@njit(**KERNEL)
def accept_clutches(dec):
    """The slip and torque of the step solved become the accepted ones."""
    for i in range(dec.hub.shape[0]):
        dec.slip[0, i] = dec.slip[1, i]
        dec.torque[0, i] = dec.torque[1, i]


@njit(**KERNEL)
def slide_anchors(arms, q):
    """Return mapping after an accepted step: an anchor whose bristle torque exceeds its limit (T_up
    counter-clockwise, T_down clockwise) slides along."""
    for k in range(arms.dof.shape[0]):
        if arms.friction_up[k] != 0.0 or arms.friction_down[k] != 0.0:
            d = arms.dof[k]
            arms.anchor[k] = slid_anchor(arms.bristle[k], q[d], arms.anchor[k], arms.friction_up[k],
                                         arms.friction_down[k])


@njit(**KERNEL)
def wrap_friction(wraps, q, f, mark, dt):
    """Add the wraps' bristle torques M = clip(k_b (psi - theta - z), -M_cap, M_cap) to f: +M on the wrap
    angle psi, -M on the pulley's rotation theta (`Wraps`); returns their stored energy sum M^2 / (2 k_b).
    z = anchor + z' dt: the anchor crept at the rate z' (`wraps.creep`) over the time dt since the accepted
    step (0: the accepted state). mark (a Newton evaluation of a step of length dt): mark each wrap sliding
    (beyond its limit) or not (wraps.sliding) and keep dt (wraps.step) for the return mapping."""
    stored = 0.0
    for k in range(wraps.wrap.shape[0]):
        w, hb = wraps.wrap[k], wraps.hub[k]
        z = crept_anchor(wraps, k, dt)
        tau, e = bristle(wraps.bristle[k], q[w] - q[hb], z, wraps.limit[k], wraps.limit[k])
        if mark:
            wraps.sliding[k] = 1.0 if abs(wraps.bristle[k] * (q[w] - q[hb] - z)) > wraps.limit[k] else 0.0
        f[w] += tau
        f[hb] -= tau
        stored += e
    if mark:
        wraps.step[0] = dt
    return stored


@njit(**KERNEL)
def crept_anchor(wraps, k, dt):
    """Wrap k's bristle anchor crept at its rate z' (`wraps.creep`, `wrap_creep`) over the time dt since the
    accepted step: anchor + z' dt."""
    return wraps.anchor[k] + wraps.creep[k] * dt


@njit(**KERNEL)
def stepped_wrap_torque(wraps, k, q):
    """Wrap k's bristle torque at the state q of the step solved (its anchor crept over that step,
    `wraps.step`), before the return mapping."""
    z = crept_anchor(wraps, k, wraps.step[0])
    return bristle(wraps.bristle[k], q[wraps.wrap[k]] - q[wraps.hub[k]], z, wraps.limit[k], wraps.limit[k])[0]


@njit(**KERNEL)
def slide_wraps(wraps, q):
    """The wraps' return mapping after an accepted step (`slid_anchor`, from the anchor crept over the step,
    `crept_anchor`) and their torques there (`stepped_wrap_torque`)."""
    for k in range(wraps.wrap.shape[0]):
        x = q[wraps.wrap[k]] - q[wraps.hub[k]]
        z = crept_anchor(wraps, k, wraps.step[0])
        wraps.torque[k] = stepped_wrap_torque(wraps, k, q)
        wraps.anchor[k] = slid_anchor(wraps.bristle[k], x, z, wraps.limit[k], wraps.limit[k])


@njit(**KERNEL)
def regime_changed(wraps):
    """True where a wrap's last evaluation (of the accepted step) found another regime, sticking or sliding,
    than the iteration matrix holds (`Wraps.factored`)."""
    for k in range(wraps.wrap.shape[0]):
        if wraps.sliding[k] != wraps.factored[k]:
            return True
    return False


@njit(**PART)
def regime_correction(wraps, fac, held, weight, dx, work_q):
    """Newton's correction dx = S^-1 R, S the factor's matrix with its wraps in the regime `Wraps.factored`,
    made the correction of S' = S + U D U^T, the matrix of the regime the last evaluation found
    (`Wraps.sliding`): for each wrap whose regime differs, u_k = e_psi - e_theta (a held DOF's entry left
    out, as the factor holds its row and column) and d_k = +weight k_b where it sticks now (the factor
    left its bristle out), -weight k_b where it slides now. By the Woodbury identity
        dx' = dx - Z (D^-1 + U^T Z)^-1 U^T dx,   Z = S^-1 U,
    Z the factor's solves of the changed wraps (`Wraps.update`, each solved once per factor: `Wraps.updated`,
    cleared by `run_steps`), the small system (m <= k) by Gaussian elimination with partial pivoting in
    `Wraps.small` (m, m + 1). The same correction as a new factor of the new regime at the factor's state,
    without one: a stick-slip transition costs neither a factor nor a return to Python."""
    kn = wraps.wrap.shape[0]
    m = 0
    for k in range(kn):
        if wraps.sliding[k] != wraps.factored[k]:
            if wraps.updated[k] == 0.0:
                z = wraps.update[k]
                for i in range(z.shape[0]):
                    z[i] = 0.0
                if held[wraps.wrap[k]] == 0:
                    z[wraps.wrap[k]] = 1.0
                if held[wraps.hub[k]] == 0:
                    z[wraps.hub[k]] = -1.0
                factor_solve(fac, z, z, work_q)  # (the solvers copy b first: in place)
                wraps.updated[k] = 1.0
            m += 1
    A = wraps.small
    i = 0
    for ki in range(kn):  # A = D^-1 + U^T Z, the right-hand side U^T dx in column m
        if wraps.sliding[ki] == wraps.factored[ki]:
            continue
        w, hb = wraps.wrap[ki], wraps.hub[ki]
        j = 0
        for kj in range(kn):
            if wraps.sliding[kj] != wraps.factored[kj]:
                z = wraps.update[kj]
                A[i, j] = z[w] - z[hb]  # (z and dx are 0 on held DOFs)
                j += 1
        d = weight * wraps.bristle[ki]
        A[i, i] += 1.0 / d if wraps.sliding[ki] == 0.0 else -1.0 / d
        A[i, m] = dx[w] - dx[hb]
        i += 1
    for c in range(m):  # elimination with partial pivoting
        p = c
        for r in range(c + 1, m):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if p != c:
            for j in range(c, m + 1):
                A[c, j], A[p, j] = A[p, j], A[c, j]
        for r in range(c + 1, m):
            f = A[r, c] / A[c, c]
            for j in range(c, m + 1):
                A[r, j] -= f * A[c, j]
    for c in range(m - 1, -1, -1):  # back substitution: the coefficients in column m
        s = A[c, m]
        for j in range(c + 1, m):
            s -= A[c, j] * A[j, m]
        A[c, m] = s / A[c, c]
    j = 0
    for kj in range(kn):  # dx' = dx - Z coef
        if wraps.sliding[kj] != wraps.factored[kj]:
            coef = A[j, m]
            z = wraps.update[kj]
            for i in range(dx.shape[0]):
                dx[i] -= coef * z[i]
            j += 1


@njit(**KERNEL)
def end_stretch(belt, elem, spring, at_end, E, q_ext):
    """The stretch lambda at a span's end: of element elem at its end node (at_end) or start node (the
    node's gradient, |r'|), or of the spring span `spring`'s chord (its length over its reference)."""
    if elem >= 0:
        o = 6 if at_end else 2
        return np.sqrt(E[elem, o] * E[elem, o] + E[elem, o + 1] * E[elem, o + 1])
    sp = belt.springs
    dx, dy = sp.d0[spring, 0], sp.d0[spring, 1]
    for j in range(sp.idx.shape[1]):
        dx += sp.D[spring, 0, j] * q_ext[sp.idx[spring, j]]
        dy += sp.D[spring, 1, j] * q_ext[sp.idx[spring, j]]
    return np.sqrt(dx * dx + dy * dy) / sp.L[spring]


@njit(**KERNEL)
def wrap_limits(wraps, belt, E, q_ext, c, speed):
    """The wraps' capstan limits M_cap = R (T_max - c_T)(1 - exp(-mu beta)) from the end tensions of their
    spans (the true axial force N = EA eps lambda of the bar law, `end_stretch`) at the accepted state (E its
    element coordinates, q_ext its padded coordinates), T_max the larger, c_T = rho c^2 lambda(T_max) the
    centrifugal part at the belt speed c (0 where T_max <= c_T: a slack wrap holds nothing), and their
    creep (`wrap_creep`) at the belt travel speed `speed`. Returns the bristles' stored energy the new
    limits release (a limit that falls below a bristle's torque: the anchor slides at the next return
    mapping, dissipated)."""
    released = 0.0
    lam_ref = reference_stretch(wraps, belt, E, q_ext, speed)
    for k in range(wraps.wrap.shape[0]):
        lam_in = end_stretch(belt, wraps.in_elem[k], wraps.in_spring[k], True, E, q_ext)
        lam_out = end_stretch(belt, wraps.out_elem[k], wraps.out_spring[k], False, E, q_ext)
        wrap_creep(wraps, k, lam_in if speed >= 0.0 else lam_out, lam_ref, speed)
        ea_in = belt.EA[wraps.in_elem[k]] if wraps.in_elem[k] >= 0 else belt.springs.EA
        ea_out = belt.EA[wraps.out_elem[k]] if wraps.out_elem[k] >= 0 else belt.springs.EA
        t_in, t_out = sk.axial_force_kernel(lam_in, ea_in), sk.axial_force_kernel(lam_out, ea_out)
        t_max, lam = (t_in, lam_in) if t_in >= t_out else (t_out, lam_out)
        cap = wraps.radius[k] * max(t_max - wraps.rho * c * c * lam, 0.0) * wraps.capstan[k]
        tau = wraps.torque[k]
        if abs(tau) > cap:
            released += 0.5 * (tau * tau - cap * cap) / wraps.bristle[k]
            wraps.torque[k] = cap if tau > 0.0 else -cap
        wraps.limit[k] = cap
    return released


@njit(**KERNEL)
def reference_stretch(wraps, belt, E, q_ext, speed):
    """lambda_e,drv: the stretch at the driver's entry (its arriving span's end for speed >= 0, its leaving
    span's start otherwise; `Wraps.ref_elem`, `ref_spring`), 0 without a driver (no creep)."""
    entry = 0 if speed >= 0.0 else 1
    elem, spring = wraps.ref_elem[entry], wraps.ref_spring[entry]
    if elem < 0 and spring < 0:
        return 0.0
    return end_stretch(belt, elem, spring, entry == 0, E, q_ext)


@njit(**KERNEL)
def wrap_creep(wraps, k, lam_e, lam_ref, speed):
    """The creep of wrap k in stick (docs/wraps.md "Creep in time"): its rim follows the belt's speed at its
    entry (the adhesion arc), so it turns at ratio = lambda_e,k / lambda_e,drv of the driver's rim speed c
    (the belt travel speed, the driver's nominal rim speed): its anchor drifts at z' = c u_k (1 - ratio)
    (u_k the nominal rotation per metre of belt, `Wraps.travel`), the pulley's rotation theta' = psi' - z'
    behind its wrap's. Writes wraps.ratio[k] and wraps.creep[k] (1 and 0 without a driver, lam_ref = 0)."""
    if lam_ref > 0.0:
        ratio = lam_e / lam_ref
        wraps.ratio[k] = ratio
        wraps.creep[k] = speed * wraps.travel[k] * (1.0 - ratio)
    else:
        wraps.ratio[k] = 1.0
        wraps.creep[k] = 0.0
