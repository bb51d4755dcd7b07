"""The static result and its outputs: the equilibrium's span tensions, hub loads, driver torque, arm
angles and torques, slip margins (`static_result`), and the checks of a solved equilibrium against
the drive's limits: the adjustable pulley's slide range, the arms' stops, no span in compression."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.errors import SolverError
from beltdyn.model.angles import unwrap_near, wrap_angle
from beltdyn.model.slip import drive_centrifugal_tension, pulley_tensions, required_friction, slip_margin
from beltdyn.model.wraps import WrapState, wrap_model_state, wrap_state
from beltdyn.model.system import System


@dataclass(frozen=True, kw_only=True)
class StaticResult:
    """Equilibrium. Shapes: n_dof, n_span = n_pulley = n."""

    q: np.ndarray  # (n_dof,) independent coordinates at equilibrium
    spring_preload: np.ndarray  # (n_dof,) bearing spring preload p (N)
    span_tension: np.ndarray  # (n, 2) axial force at the start/end of each span (joint reactions), N
    mean_tension: float  # N, length-weighted mean over all spans
    hub_load: np.ndarray  # (n, 2) force of the belt on each pulley, N
    pulley_center: np.ndarray  # (n, 2) m
    pulley_rotation: np.ndarray  # (n,) rad
    driver_torque: float  # N m, torque the driver's support applies to hold it
    adjust_offset: float  # m, total travel of the adjustable pulley from its given centre
    residual_history: np.ndarray  # (n_iter,) residual norm / allowed residual after each Newton iteration
    load_factor_history: np.ndarray  # (n_iter,) load factor of each iteration
    iterations: int
    tension_mode: str
    # tensioner arms (NaN for pulleys without one), the static load case and the slip margins
    arm_angle: np.ndarray | None = None  # (n,) rad, counter-clockwise from +x
    arm_torque: np.ndarray | None = None  # (n,) N m, torque of the arm's spring on the arm (counter-clockwise +)
    arm_free_angle: np.ndarray | None = None  # (n,) rad, the spring's free angle (what mode "adjust" needs)
    pivot_reaction: np.ndarray | None = None  # (n, 2) N, force of the pivot on the arm
    applied_torque: np.ndarray | None = None  # (n,) N m, the accessory torques of the static load case
    required_friction: np.ndarray | None = None  # (n,) ln(T_tight / T_slack) / wrap (inf: a slack span)
    slip_margin: np.ndarray | None = None  # (n,) friction / required_friction (NaN: no friction given)
    wraps: WrapState | None = None  # the wraps' creep state (`model.wraps`): slip and adhesion arcs, rim speeds, losses



def check_travel(system: System, q: np.ndarray) -> None:
    """The tension step's travel of the adjustable pulley (from its given centre) within its slide_range."""
    ts = system.tension
    lim = ts.adjust_range
    if lim is None or ts.adjust_dof < 0 or system.dof_groups[ts.adjust_dof] != 2:  # arms: `check_stops`
        return
    travel = system.layout.adjust_offset + float(q[ts.adjust_dof])
    span = max(abs(lim[0]), abs(lim[1]), 1e-3)
    if lim[0] - 1e-12 * span <= travel <= lim[1] + 1e-12 * span:
        return
    raise SolverError(
        f"tension.target = {ts.target:g} N needs pulley '{ts.adjust_name}' to travel {travel:.6g} m along its slide "
        f"(from its given centre), outside its slide_range [{lim[0]:g}, {lim[1]:g}] m; lower the target or "
        f"widen the slide_range", analysis="static", step="tension step",
        item=system.dof_labels[ts.adjust_dof])


def check_slack(system: System, st: StaticResult) -> None:
    """A span in compression at equilibrium: the belt would go slack (it carries no compression; the
    model's bending stiffness holds it only numerically). A named failure, never a silent result."""
    T = st.span_tension
    if T.min() >= 0.0:  # (the common case: no span in compression at all)
        return
    lowest = T.min(axis=1)
    worst = int(lowest.argmin())
    if lowest[worst] >= -1e-6 * float(np.abs(T).max(initial=1.0)):
        return
    loads = " under the accessory torques" if system.loads is not None and np.any(system.loads) else ""
    raise SolverError(f"span {system.layout.span_name(worst)} is compressed ({T[worst].min():.4g} N){loads}: the belt "
                      f"goes slack there; raise the tension (tension.target or the tensioner spring) or lower the "
                      f"loads", analysis="static", step="slack check", residual=float(-T[worst].min()),
                      item=f"span {worst + 1} ({system.layout.span_name(worst)})")


def check_stops(system: System, q: np.ndarray) -> None:
    """Every tensioner arm's equilibrium angle between its stops (arm_range)."""
    a = system.arms
    if a is None or a.stops is None:
        return

    for k, (lo, hi) in enumerate(a.stops.tolist()):
        if lo != lo:  # NaN: no stops
            continue
        phi = unwrap_near(float(a.angle[k] + q[a.dof[k]]), 0.5 * (lo + hi))
        if lo - 1e-12 <= phi <= hi + 1e-12:
            continue
        ts = system.tension
        why = (f"tension.target = {ts.target:g} N needs" if ts.adjust_dof == int(a.dof[k]) else
               "the static equilibrium puts")
        raise SolverError(f"{why} the arm of pulley '{a.names[k]}' at {phi:.6g} rad, outside its stops "
                          f"arm_range = [{lo:g}, {hi:g}] rad; change the target, the spring or the stops",
                          analysis="static", step="tension step" if ts.adjust_dof == int(a.dof[k]) else "equilibrium",
                          item=system.dof_labels[int(a.dof[k])])


def static_result(model: System, q, preload, hist_r, hist_l, iterations, driver_dof, *, known: dict | None = None
            ) -> StaticResult:
    """The outputs at the solution q; known: values the solve already evaluated at q (see
    `solve_equilibrium`)."""
    lay = model.layout
    known = known or {}
    p = known["joint"] if "joint" in known else model.expand(q)
    hub, span_tension, T_mean = model.static_span_outputs(q, p=p, mean="mean_tension" not in known)
    if "driver_torque" in known:
        driver_torque = known["driver_torque"] - float(preload[driver_dof])
    else:
        driver_torque = float((model.equilibrium(q, tangent=False)[0] - preload)[driver_dof])
    if T_mean is None:
        T_mean = known["mean_tension"]
    a = lay.adjust_index
    if a is None:
        offset = 0.0
    elif lay.adjust_kind == "arm":
        offset = float(wrap_angle(lay.adjust_offset + float(q[model.dofs.arm_dof[a]])))  # a turn: a direction
    else:
        offset = lay.adjust_offset + float(q[model.trans_dof[a][0]])

    n = lay.n
    arm_angle = np.full(n, np.nan)
    arm_torque, arm_free, pivot = arm_angle.copy(), arm_angle.copy(), np.full((n, 2), np.nan)
    if model.arms is not None:
        arms = model.arms
        for k, (j, spring, weight) in enumerate(model.arm_statics):
            d = int(arms.dof[k])
            arm_angle[j] = float(arms.angle[k] + q[d])
            if spring is not None:
                k_s = float(spring.stiffness[0, 0])
                free = float(spring.free[0]) if spring.free is not None else 0.0
                arm_torque[j] = -(k_s * (q[d] - free) - preload[d])  # the spring's torque on the arm
                arm_free[j] = arm_angle[j] + arm_torque[j] / k_s
            else:  # no spring: a constant preload torque (adjust mode), if any
                arm_torque[j] = float(preload[d])
            pivot[j] = -(hub[j] + weight)  # statics of arm + pulley: pivot + belt + weight = 0
    applied = np.zeros(n) if model.loads is None else model.loads[model.dofs.torque_dof]
    friction = model.pulley_friction
    t_in, t_out = pulley_tensions(span_tension)
    c = drive_centrifugal_tension(model, model.belt_speed, T_mean)  # (the slip arcs' and the margins': one c)
    if model.wraps is not None:
        wraps = wrap_model_state(model.wraps, span_tension=span_tension, radius=lay.radius, wrap=lay.wrap_angle,
                                 belt_speed=float(model.belt_speed), driver=int(model.driver), centrifugal=float(c))
    else:
        wraps = wrap_state(t_in=t_in, t_out=t_out, radius=lay.radius, wrap=lay.wrap_angle, friction=friction,
                           EA=float(model.EA), mass_per_length=mass_per_length(model),
                           belt_speed=float(model.belt_speed), driver=int(model.driver), centrifugal=float(c))
    mu_req = required_friction(span_tension, lay.wrap_angle, c)  # (the running belt's capstan law, `slip`)
    return StaticResult(
        q=q, spring_preload=preload, span_tension=span_tension, mean_tension=T_mean,
        hub_load=hub, pulley_center=known["pulley_center"] if "pulley_center" in known else model.pulley_centers(q, p=p),
        pulley_rotation=q[model.rot_dof],
        driver_torque=driver_torque, adjust_offset=offset,
        residual_history=np.array(hist_r), load_factor_history=np.array(hist_l), iterations=iterations,
        tension_mode=model.tension.mode, arm_angle=arm_angle, arm_torque=arm_torque, arm_free_angle=arm_free,
        pivot_reaction=pivot, applied_torque=applied, required_friction=mu_req,
        slip_margin=(slip_margin(mu_req, friction) if friction is not None and not np.isnan(friction).all()
                     else np.full(n, np.nan)), wraps=wraps)


def mass_per_length(model: System) -> float:
    """The belt's mass per unit reference length (kg/m): of its elements, or of its spring spans."""
    el = model.belt.elements
    if el.n_elem:
        return float(el.rho.max())
    return float(model.springs.rho) if model.springs is not None else 0.0


