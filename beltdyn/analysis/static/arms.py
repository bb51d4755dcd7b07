"""The predicted first layout of the solved geometry: the drive on a rigid belt under the target (or
conserved) span tensions, its bearings deflected and its sprung tensioner arms balanced about their
pivots (`predicted_centers`)."""

from __future__ import annotations

import math

import numpy as np

from beltdyn.model.angles import pivot_angle, unwrap_near
from beltdyn.model.geometry import Layout, belt_path, relay
from beltdyn.model.system import System
from beltdyn.model.wraps import centrifugal_tension


ROUGH_STEPS = 1e4  # the arm secant's trials rough (`span_tension`'s rough) while its step exceeds this x tol_x


def predicted_centers(system: System, anchored: set, fit, tol_x: float, span_tension) -> tuple[np.ndarray, Layout | None]:
    """(pulley centres (n, 2), the checked layout at them where `fit` alone placed the pulleys, else None) of
    the drive on a rigid belt whose span tensions `span_tension(angles,
    lengths, rough)` (arrays (n,) of a layout's span angles and lengths -> (n,); rough: a cheaper value
    for a trial far from the answer, the secant's steps above ROUGH_STEPS x tol_x) gives (the target or the
    belt's length, split by the accessory torques): the adjustable pulley where `fit(centers)` places
    it (mode "adjust"), every spring-supported pulley deflected by its bearing springs under the belt's
    pull T_j t_j - T_(j-1) t_(j-1) of that layout and the weight on its DOFs (`gravity_force`, the
    pulley's and its share of the belt's), every sprung tensioner arm (but the adjusting one) turned
    until its spring balances the moment of that pull about its pivot (secant on the arm angle, on the
    branch of the layout's angle). On a running belt (system.belt_speed) each span pulls with its
    tension less the centrifugal part rho v^2 lambda(T) (`analysis.running`).
    A fixed point over layouts (cheap geometry); the static passes correct what it leaves out (sag,
    bending, the arms' weight)."""

    lay0 = system.layout
    place = fit if fit is not None else (lambda c: relay(lay0, c, check=False))  # checked where laid (lay_out)
    # an arm's iterates: the spans alone (`belt_path`, the numbers of `relay`'s layout without its tangent points)
    path = fit if fit is not None else (lambda c: belt_path(c, lay0.radius, lay0.side_sign, lay0.orientation))
    k_diag = np.asarray(system.linear_matrix().diagonal()).ravel() if anchored else None
    arms = []  # (pulley, pivot, length, stiffness, layout angle, free angle) of each sprung arm it turns
    if system.arms is not None:
        a = system.arms
        for k, dof in enumerate(a.dof):
            spring = system.arm_spring(dof)
            if int(dof) == system.tension.adjust_dof or spring is None:
                continue
            j = a.pulleys[k]
            free = float(spring.free[0]) if spring.free is not None else 0.0
            arms.append((j, a.pivot[k], float(a.length[k]), float(spring.stiffness[0, 0]), float(a.angle[k]),
                         float(a.angle[k]) + free))
    centers = lay0.center.copy()
    if not anchored and not arms and fit is not None:  # nothing deflects: the fit alone places the pulleys
        laid = fit(centers)
        return laid.center, laid

    v = float(system.belt_speed)
    wm = system.wraps
    rho_v2 = 0.0 if not v or wm is None else wm.mass_per_length * v * v  # rho v^2 (N) of the running belt

    def pull(lay, at: int | None = None, rough: bool = False) -> np.ndarray:
        """The belt's pull on every pulley j (n, 2), or on pulley `at` alone (2,): T_j t_j - T_(j-1) t_(j-1)
        less the centrifugal part rho v^2 lambda(T) of each span's tension on a running belt (the hub
        loads of `analysis.running`)."""
        T = span_tension(lay.span_angle, lay.span_length, rough)
        if rho_v2:
            T = T - centrifugal_tension(T, wm.mass_per_length, v, wm.EA, wm.stretch)
        if at is not None:  # (two spans: their directions on floats)
            a, b = float(lay.span_angle[at]), float(lay.span_angle[at - 1])
            t_a, t_b = float(T[at]), float(T[at - 1])
            return np.array([t_a * math.cos(a) - t_b * math.cos(b), t_a * math.sin(a) - t_b * math.sin(b)])
        f = T[:, None] * lay.span_direction
        return f - np.roll(f, 1, axis=0)  # (span j - 1 arrives at pulley j)

    def arm_moment(j: int, pv: np.ndarray, length: float, k_s: float, phi_f: float):
        """The moment about the pivot on arm pulley j at arm angle phi (spring and belt pull), the other
        pulleys where `centers` has them (the fit, if any, moves the adjustable pulley with it)."""
        def moment(phi: float, rough: bool = False) -> float:
            c = centers.copy()
            rx, ry = length * math.cos(phi), length * math.sin(phi)  # pivot -> pulley
            c[j] = (pv[0] + rx, pv[1] + ry)
            f = pull(path(c), j, rough)
            return rx * float(f[1]) - ry * float(f[0]) - k_s * (phi - phi_f)
        return moment

    for _ in range(50):
        for j, pv, length, k_s, phi_ref, phi_f in arms:  # each arm's balance, the other pulleys where they are
            moment = arm_moment(j, pv, length, k_s, phi_f)
            phi0 = unwrap_near(pivot_angle(centers[j], pv), phi_ref)  # the layout's branch of the angle
            phi1 = phi0 + 1e-4
            m0, m1 = moment(phi0, True), moment(phi1, True)
            rough = True  # m1 a rough value (`span_tension`'s rough: far from the answer)
            for _ in range(30):
                if m1 == m0:
                    break
                phi0, phi1, m0 = phi1, phi1 - m1 * (phi1 - phi0) / (m1 - m0), m1
                step = abs(phi1 - phi0) * length
                if step <= tol_x and not rough:
                    break
                rough = step > ROUGH_STEPS * tol_x
                m1 = moment(phi1, rough)
            centers[j] = pv + length * np.array([np.cos(phi1), np.sin(phi1)])
        if not anchored and len(arms) == 1 and fit is None:  # the one arm balanced, nothing else moves: done
            break
        lay = place(centers)
        force = pull(lay)
        new = lay.center.copy()
        for j, (dofs, dirs) in enumerate(zip(system.trans_dof, system.trans_dir)):
            if any(k in anchored for k in dofs):
                new[j] = lay0.center[j]
            for k, v in zip(dofs, dirs):
                if k in anchored and k_diag[k] > 0.0:
                    new[j] = new[j] + v * (float(force[j] @ v) + float(system.gravity_force[k])) / k_diag[k]
        done = float(np.abs(new - centers).max()) <= tol_x
        centers = new
        if done:
            break
    return centers, None
