"""The belt's length and tension over layouts: the reference lengths carried between span and wrap
when a tangent point moves (`carried_reference`), the span tensions of a belt of conserved length
(`conserved_tension`), the accessory torques' split of the span tensions (`torque_split`) and the
prestrain secant that meets the target tension (`meet_prestrain`).

Nomenclature: L_s span lengths, reference_s their stress-free lengths, lambda stretch, T tension
(N), EA axial stiffness (N), rho = orientation x side x radius the signed pulley radii (m)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.analysis.static.newton import Budget, solve_static
from beltdyn.config import StaticOptions
from beltdyn.errors import SolverError
from beltdyn.model.angles import wrap_angle
from beltdyn.model.barlaw import BarLaw, axial_force, axial_stiffness, bar_law, stretch_for_tension, stretch_start
from beltdyn.model.wraps import WrapModel, centrifugal_tension, slip_part, wrap_lengths

GREEN = bar_law("green-lagrange")


def carried_reference(old, new, reference_length: np.ndarray) -> np.ndarray:
    """Span reference lengths (n,) on layout `new` of the belt whose spans had `reference_length` on
    layout `old`, the wraps unstretched: where a tangent point moves along its pulley by an arc
    R dpsi in the direction of belt travel, that much belt passes from the span onto the wrap (or
    back). The total, sum(reference lengths) + sum(arc lengths), is kept. Pulley rotations stay
    coordinates of the system (the joints slide the span ends along the tangent lines).

    Both tangent points of span s turn with its tangent line: their normals are +-(sin a_s, -cos a_s),
    so dpsi = a_s(new) - a_s(old) (wrapped to [-pi, pi)) at both ends, and with the signed radii
    rho = orientation x side x R the span leaves rho_s dpsi onto pulley s and takes rho_(s+1) dpsi
    from pulley s+1: reference_s - dpsi_s (rho_s - rho_(s+1))."""
    return carried_lengths(old.span_angle, new.span_angle, radius_steps(new), reference_length, new.span_name)


def radius_steps(layout) -> np.ndarray:
    """rho_s - rho_(s+1) (n,) of each span s, rho = orientation x side x radius (`carried_reference`)."""
    rho = layout.orientation * layout.side_sign * layout.radius
    return rho - np.roll(rho, -1)


def carried_lengths(old_angle: np.ndarray, new_angle: np.ndarray, radius_step: np.ndarray, reference: np.ndarray,
                    span_name) -> np.ndarray:
    """`carried_reference` on arrays (n,): the old and new span angles a_s, the spans' `radius_steps`
    and the old reference lengths; span_name(s) names span s in the error. (A span whose angle is
    unchanged keeps its length: the turn wraps to an exact 0 there.) A span left without a positive
    reference length (or with NaN, an iterate's span between coincident centres) is a SolverError."""
    turn = wrap_angle(np.asarray(new_angle, dtype=float) - np.asarray(old_angle, dtype=float))
    out = np.asarray(reference, dtype=float) - turn * np.asarray(radius_step, dtype=float)
    if not (out > 0.0).all():  # (NaN fails too)
        s = int(np.argmin(np.where(np.isnan(out), -np.inf, out)))
        raise SolverError(f"span {span_name(s)} has no belt left at the solved pulley positions (reference "
                          f"length {out[s]:.3g} m)", analysis="static", step="re-lay", item=f"span {s + 1}")
    return out


def meet_prestrain(build, layout, lam: float, free: np.ndarray, options: StaticOptions, slope: float | None,
                    budget: Budget | None = None):
    """Secant on the spans' uniform prestrain stretch lam until the static mean tension equals the
    target (the pulleys free on their bearings). Returns (system, static, lam, slope, solves)."""
    system = build(layout, lam, free)
    target = float(system.tension.target)
    EA = system.EA
    tol_T = options.tolerance * abs(target) + 100 * np.finfo(float).eps * EA
    if slope is None:
        slope = float(axial_stiffness(lam, EA))  # rigid supports
    prev = None
    for it in range(options.max_iterations):
        if it:
            system = build(layout, lam, free)
        st = solve_static(system, options, budget=budget)
        g = st.mean_tension - target
        if abs(g) <= tol_T:
            return system, st, lam, slope, it + 1
        if prev is not None and lam == prev[0]:  # no representable step left (the stretch is at 1)
            raise SolverError(
                f'tension.mode = "prestrain" cannot reach tension.target = {target:g} N: the mean span tension is '
                f"{st.mean_tension:.6g} N at span stretch {lam:.12g}" + (" (unstretched spans: the weight and the "
                "supports alone give it)" if lam == 1.0 else "") + '; lower the target or use mode = "adjust"',
                analysis="static", step=f"prestrain iteration {it + 1}", residual=abs(g) / tol_T, item="tension.target")
        if prev is not None:
            secant = (g - prev[1]) / (lam - prev[0])
            if not (np.isfinite(secant) and secant > 1e-9 * EA):
                raise SolverError(
                    f'tension.mode = "prestrain" cannot reach tension.target = {target:g} N: the mean span tension '
                    f"({st.mean_tension:.6g} N at span stretch {lam:.9g}) does not grow with the prestrain "
                    f"(dT/dstretch = {secant:.3g} N); a support gives way without limit", analysis="static",
                    step=f"prestrain iteration {it + 1}", residual=abs(g) / tol_T, item="tension.target")
            slope = secant
        prev = (lam, g)
        new = lam - g / slope
        lam = new if new > 1.0 else 1.0 + 0.5 * (lam - 1.0)
    raise SolverError(f'tension.mode = "prestrain": the mean span tension did not reach tension.target = '
                      f"{target:g} N in {options.max_iterations} prestrain iterations (last {st.mean_tension:.9g} N)",
                      analysis="static", step="prestrain iteration", residual=abs(g) / tol_T, item="tension.target")


def torque_split(layout, loads: np.ndarray | None, rot_dof: np.ndarray, driver: int) -> np.ndarray:
    """(n,) span tensions relative to the span leaving the driver (its pulley index) that the static
    accessory torques ask for on a rigid belt: the belt's torque on pulley j is rho_j (T_j - T_(j-1)), rho = orientation x
    side x radius, so every other pulley has T_j = T_(j-1) - tau_j / rho_j (the driver reacts the rest)."""
    n = layout.n
    split = np.zeros(n)
    if loads is None:
        return split
    rho = layout.orientation * layout.side_sign * layout.radius
    tau = loads[rot_dof]
    for i in range(1, n):  # (a recurrence around the belt, from the driver)
        j = (driver + i) % n
        split[j] = split[j - 1] - tau[j] / rho[j]
    return split


def conserved_tension(total_length: float, split: np.ndarray, reference: np.ndarray, EA: float) -> np.ndarray:
    """(n,) span tensions T_ref + split of a belt whose spans' reference lengths are `reference` (n,)
    (`carried_reference`: the wraps unstretched) on a path whose spans are total_length long together,
    its pulleys turning freely: the rotations slide the span ends along the tangent lines (the joints),
    which moves chord between neighbouring spans and keeps their sum, so
    sum_s lambda(T_s) reference_s = sum_s L_s (Newton on T_ref, the bar law of `model.barlaw`)."""
    L = float(total_length)
    ref, sp = np.asarray(reference, dtype=float), np.asarray(split, dtype=float)
    total = float(ref.sum())
    T_ref = EA * (L / total - 1.0) - float(ref @ sp) / total  # the start: lambda = 1 + x,
    x = (T_ref + sp) / EA
    T_ref += 1.5 * EA * float((ref * x * x).sum()) / total  # then 1 + x - 3/2 x^2 (one step)
    lam = stretch_start((T_ref + sp) / EA)
    if np.abs((T_ref + sp) / EA).max() >= 0.05:
        lam = stretch_for_tension(T_ref + sp, EA)
    for _ in range(50):  # Newton on T_ref, each stretch first stepped to its span's tension (one Newton step)
        slope = axial_stiffness(lam, EA)  # dT/dlambda
        d = (axial_force(lam, EA) - (T_ref + sp)) / slope
        lam = lam - d
        worst = float(np.abs(d).max())
        step = (float(lam @ ref) - L) / float((ref / slope).sum())
        T_ref -= step
        # done when the stretches were exact (Newton on the cubic leaves about 1.5 d^2 after a step d, below
        # 2e-16 for d <= 1e-8) and what T_ref still lacks is below 1e-12 EA: Newton leaves c step^2 / EA after
        # a step, c = |g''| EA / (2 g') <= 6 lambda_max / (3 lambda_min^2 - 1)^2 (1.5 at lambda = 1)
        if worst <= 1e-8:
            lo = float(lam.min())
            h = 3.0 * lo * lo - 1.0
            if abs(step) <= 1e-12 * EA or (h > 0.1 and 6.0 * float(lam.max()) * step * step <= 1e-12 * EA * EA * h * h):
                break
    return T_ref + sp


def settled_tension(lengths: np.ndarray, split: np.ndarray, total_reference: float, EA: float, *,
                    law: BarLaw = GREEN, wraps: "WrapBudget | None" = None) -> np.ndarray:
    """(n,) span tensions T_ref + split of a belt whose spans, of lengths L_s (n,), together hold the
    reference (stress-free) length `total_reference`, each span stretched by its own tension and the
    pulleys unturned (the rotations' material in the spans, `relay.settled_reference`): so
    sum_s L_s / lambda(T_ref + split_s) = total_reference (Newton on T_ref, the bar law `law`; each
    span's reference length is then L_s / lambda(T_s)). wraps: creep wraps in the budget (`settled_budget`)."""
    return settled_budget(lengths, split, total_reference, EA, law=law, wraps=wraps)[0]


SLIP_EVALUATIONS = 8  # `settled_budget`: evaluations of the slip part at most
SlipModel = tuple[float, float, float]  # (T_ref, delta, d delta / d T_ref): the slip part held linear in T_ref


def settled_budget(lengths: np.ndarray, split: np.ndarray, total_reference: float, EA: float, *,
                   law: BarLaw = GREEN, wraps: "WrapBudget | None" = None, start: SlipModel | None = None,
                   evaluations: int = SLIP_EVALUATIONS, centrifugal: float = 0.0
                   ) -> tuple[np.ndarray, SlipModel | None]:
    """(T (n,), slip model) of `settled_tension`. With creep wraps (`WrapBudget`) the wraps' stress-free
    length takes the place of their arc length in the budget,

        sum_s (L_s + a_s) / lambda(T_s) + delta(T) = total_reference + sum_j R_j beta_j,

    a_s the arc of the wrap span s enters (its adhesion stretch is the span's) and delta the slip arcs'
    part (`WrapBudget.slip_part`): delta is held linear in T_ref over an inner Newton solve (its slope the
    secant of its evaluations; `start` a model of a nearby solve, else delta at the first iterate with
    slope 0) and evaluated again at the result until it meets the model to 1e-14 of the belt's length.
    The slip model returned starts the next solve of a nearby layout (None without creep wraps).
    evaluations: at most so many evaluations of delta (1: a rough value, the budget solved once with delta
    refreshed at the start's answer; for a trial far from its answer, the statics' predictor's secant).
    centrifugal: rho v^2 (N) of a running belt: the split then holds between the tensions less their
    centrifugal parts, T_s - rho v^2 lambda_s = T_ref + split_s (the pulleys' torque balance on the hub
    loads, `analysis.running`); 0 at rest."""
    L = np.asarray(lengths, dtype=float)
    sp = np.asarray(split, dtype=float)
    total = float(total_reference)
    spans = L  # (the spans' laid lengths: their reference lengths L_s / lambda_s weigh the mean tension)

    rv2 = float(centrifugal)

    def tension(T_ref: float, lam: np.ndarray) -> np.ndarray:
        return T_ref + sp + rv2 * lam if rv2 else T_ref + sp

    if wraps is not None:
        L = L + wraps.entry_arc
        total += wraps.arc_total
    length = float(L.sum())
    T_ref = EA * (length / total - 1.0) - float(L @ sp) / length  # the linear start
    if start is not None and wraps is not None:
        T_ref = start[0]  # (a nearby solve's)
    lam = None  # the first-order stretches (`_budget_newton`)
    if wraps is None:
        T_ref, lam = _budget_newton(L, sp, total, 0.0, T_ref, lam, EA, law, rv2)
        return tension(T_ref, lam), None
    model = start  # (T_ref, delta, d delta / d T_ref) the inner solve holds delta to
    if model is None:  # (delta evaluated first: at the first-order stretches)
        lam = 1.0 + (T_ref + sp) / law.axial_stiffness(1.0, EA)
    else:
        T_ref, lam = _budget_newton(L, sp, total - model[1] + model[2] * model[0], model[2], T_ref, lam, EA, law,
                                    rv2)
    for _ in range(evaluations):  # the slip part evaluated, the budget solved with it linear in T_ref
        T = tension(T_ref, lam)
        ref = spans / lam  # the mean tension weighted by the reference lengths, as the static result's
        d_now = float(wraps.slip_part(T, float(ref @ T) / float(ref.sum())))
        if model is not None:
            t0, d0, d_slope = model
            if abs(d_now - (d0 + d_slope * (T_ref - t0))) <= 1e-14 * total:  # (~ 1e-14 EA: far below the statics')
                return T, (T_ref, d_now, d_slope)
            d_slope = (d_now - d0) / (T_ref - t0) if T_ref != t0 else d_slope
        else:
            d_slope = 0.0  # (a fixed-point step first: delta changes slowly with T_ref)
        model = (T_ref, d_now, d_slope)
        T_ref, lam = _budget_newton(L, sp, total - d_now + d_slope * T_ref, d_slope, T_ref, lam, EA, law, rv2)
        if d_now == 0.0 and not sp.any():  # equal tensions: no slip arc at any T_ref
            break
    return tension(T_ref, lam), model


def _budget_newton(L: np.ndarray, sp: np.ndarray, total: float, d_slope: float, T_ref: float, lam: np.ndarray | None,
                   EA: float, law: BarLaw, centrifugal: float = 0.0) -> tuple[float, np.ndarray]:
    """(T_ref, lambda (n,)) with sum_s L_s / lambda_s + d_slope T_ref = total, N(lambda_s) - rho v^2 lambda_s =
    T_ref + split_s (N the bar law, rho v^2 = centrifugal: 0 at rest), from the stretches lam (None: the first
    order ones, 1 + (T_ref + split_s) / k(1)): Newton on both, each stretch stepped
    to its span's tension (one Newton step on the bar law), then T_ref, the stretches following it to first
    order (d lambda / d T = 1 / k, k = dN/dlambda - rho v^2). Done when the stretches needed no step beyond
    1e-8 and the step of T_ref leaves a Newton remainder below 1e-13 of the tension scale: the remainder
    after a step dT is |f''| / (2 |f'|) dT^2 <= 5 dT^2 / EA for strains below 10 % (f = sum L_s / lambda_s,
    f' ~ -sum L / EA, f'' ~ 5 sum L / EA^2 for either bar law: 2 from 1 / lambda, 3 from the law's
    curvature), counted twice. On Python floats, span by span (numpy's calls on a few numbers cost more than
    the arithmetic; the bar law's functions take floats as arrays)."""
    force, stiffness = law.axial_force, law.axial_stiffness
    rv2 = float(centrifugal)
    lengths, split = L.tolist(), sp.tolist()
    if lam is None:  # the first-order stretches 1 + T / k(1)
        k1 = stiffness(1.0, EA)
        stretch = [1.0 + (T_ref + s) / k1 for s in split]
    else:
        stretch = np.asarray(lam, dtype=float).tolist()
    n = len(lengths)
    k = [0.0] * n
    for _ in range(60):
        f, df, worst = d_slope * T_ref - total, d_slope, 0.0  # f and d f / d T_ref
        for i in range(n):
            y = stretch[i]
            k_i = stiffness(y, EA) - rv2  # dT/dlambda
            d = (force(y, EA) - rv2 * y - (T_ref + split[i])) / k_i
            y -= d
            share = lengths[i] / y  # L_s / lambda_s
            f += share
            df -= share / (y * k_i)
            stretch[i], k[i] = y, k_i
            worst = max(worst, abs(d))
        step = f / df
        T_ref -= step
        for i in range(n):
            stretch[i] -= step / k[i]
        if 10.0 * step * step <= 1e-13 * max(abs(T_ref), 1e-6 * EA) * EA and worst <= 1e-8:
            break
    return T_ref, np.array(stretch)


@dataclass(frozen=True, kw_only=True)
class WrapBudget:
    """Creep wraps in the budget of `settled_tension` on one layout. Shapes: (n,) per span / pulley."""

    wraps: WrapModel
    radius: np.ndarray  # m, the pulleys' radii
    wrap: np.ndarray  # rad, their wrap angles
    entry_arc: np.ndarray  # m, R beta of the wrap each span enters (the next pulley's, the belt running along the spans)
    arc_total: float  # m, sum R beta
    belt_speed: float = 0.0  # m/s, the running belt's (0 at rest)

    def slip_part(self, T: np.ndarray, mean_tension: float) -> float:
        """delta (m): the wraps' stress-free total less sum_j R_j beta_j / lambda(T_e,j) at the span
        tensions T (n,) (`model.wraps.slip_part`): what the slip arcs add to the adhesion stretch, with the
        drive's centrifugal tension rho v^2 lambda(mean_tension) in the slip arcs (as the static result's)."""
        wm = self.wraps
        c = centrifugal_tension(mean_tension, wm.mass_per_length, self.belt_speed, wm.EA, wm.stretch)
        return slip_part(wm, span_tension=T, radius=self.radius, wrap=self.wrap, centrifugal=float(c))


def wrap_budget(wraps: WrapModel | None, radius: np.ndarray, wrap: np.ndarray,
                belt_speed: float = 0.0) -> WrapBudget | None:
    """The `WrapBudget` of creep wraps of radii and wrap angles (n,) at belt_speed (m/s) (None for rigid
    wraps)."""
    if wraps is None or wraps.kind == "rigid":
        return None
    arc = np.asarray(radius, dtype=float) * np.asarray(wrap, dtype=float)
    return WrapBudget(wraps=wraps, radius=np.asarray(radius, dtype=float), wrap=np.asarray(wrap, dtype=float),
                      entry_arc=np.concatenate((arc[1:], arc[:1])), arc_total=float(arc.sum()), belt_speed=float(belt_speed))


def wrap_budget_change(wraps: WrapModel | None, layout, belt_speed: float = 0.0, centrifugal: float = 0.0):
    """change(T) -> the wraps' stress-free length less their arc length (m) on `layout` at span tensions T
    ((n,) or (n, 2)): what creep wraps give the spans in the belt-length budget. None for rigid wraps."""
    if wraps is None or wraps.kind == "rigid":
        return None
    R, beta = layout.radius, layout.wrap_angle

    def change(T: np.ndarray) -> float:
        return float((wrap_lengths(wraps, span_tension=T, radius=R, wrap=beta, belt_speed=belt_speed,
                                   centrifugal=centrifugal) - R * beta).sum())
    return change


def turned_wraps(layout, span_angle: np.ndarray) -> np.ndarray:
    """(n,) the wrap angles of `layout`'s pulleys once its span angles a_s are `span_angle` (n,) (the centres
    moved, `carried_reference`): pulley j's wrap grows by sign_j (dpsi_j - dpsi_(j-1)), dpsi_s the turn of
    span s, sign = orientation x side (the arc rho_j dpsi the spans hand over at its two tangent points)."""
    turn = wrap_angle(np.asarray(span_angle, dtype=float) - layout.span_angle)
    return layout.wrap_angle + layout.orientation * layout.side_sign * (turn - np.concatenate((turn[-1:], turn[:-1])))


def budget_excess(system, static, material: float, tolerance: float) -> tuple[float, float] | None:
    """(S, W) m: the spans' reference total plus the wraps' arc lengths (what the re-lay passes keep,
    `carried_reference`: S moves only by the budget's own steps) and the creep wraps' stress-free total
    less their arcs (the static result's `wraps`, `model.wraps` at its span tensions and the drive's
    centrifugal tension), where S + W misses the belt's undeformed length `material` by more than the
    tension's tolerance as a length, tolerance |T| material / EA (T the mean span tension); None where they
    meet it (or the wraps are rigid)."""
    wm = system.wraps
    if wm is None or wm.kind == "rigid":
        return None
    arc = float(system.layout.arc_length.sum())
    W = float(static.wraps.stress_free_length.sum())
    S = float(system.belt.reference_length.sum()) + arc  # (S + the arcs: what a re-lay keeps, `carried_reference`)
    allowed = max(tolerance * abs(float(static.mean_tension)) / float(system.EA), 4.0 * np.finfo(float).eps) * material
    return None if abs(S + (W - arc) - material) <= allowed else (S, W - arc)


def budget_step(history: list[tuple[float, float]], total: float) -> float:
    """The change dS of the spans' reference total that meets the belt-length budget S + W(S) = total
    (m, the belt's undeformed length), S and W as `budget_excess` gives them: from the solved (S_k, W_k)
    so far (`history`, oldest first), Newton dS = -(S + W - total) / (1 + W'), W' the secant of the last
    two (0 with one: a fixed-point step, contracting by |W'| ~ R beta / L < 1)."""
    S, W = history[-1]
    slope = 0.0
    if len(history) > 1:
        S0, W0 = history[-2]
        if S != S0:
            slope = min(max((W - W0) / (S - S0), -0.5), 5.0)  # (a bad secant of round-off kept in bounds)
    return -(S + W - total) / (1.0 + slope)
