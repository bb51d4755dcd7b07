"""The static equilibrium on the solved geometry (`solve_static_on_solved_geometry`): the belt laid
anew at the solved pulley centres, the system rebuilt and solved again until the pulleys stay where
they are laid (the package docstring, `beltdyn.analysis.static`, tells the whole)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from beltdyn.analysis.static.arms import predicted_centers
from beltdyn.analysis.static.newton import Budget, predictor, solve_equilibrium
from beltdyn.analysis.static.result import StaticResult, check_slack, static_result
from beltdyn.analysis.static.tension import (SLIP_EVALUATIONS, budget_excess, budget_step, carried_lengths,
                                             carried_reference, meet_prestrain, settled_budget, radius_steps,
                                             torque_split, turned_wraps, wrap_budget, wrap_budget_change)
from beltdyn.config import StaticOptions
from beltdyn.errors import SolverError
from beltdyn.model.angles import pivot_angle, wrap_angle
from beltdyn.model.barlaw import bar_law
from beltdyn.model.geometry import GeometryError, Layout, fit_adjustable, relay
from beltdyn.model.system import System


MAX_PASSES = 25


@dataclass(frozen=True, kw_only=True)
class SolvedDrive:
    """The static equilibrium on the solved geometry: the final system (laid out at the solved pulley
    positions) and its static result."""

    system: System
    static: StaticResult
    passes: int  # layouts solved on (the first included)
    settles: int = 0  # solves after re-referencing the rotations' material (`settled_reference`)
    solves: int  # static solves (prestrain iterations included)
    movement: np.ndarray  # (passes,) largest pulley displacement from its laid centre after each pass, m
    newton_iterations: int = 0  # Newton iterations of all passes and solves (failed attempts included)
    tangent: object = None  # dr/dq of `system.equilibrium` at static.q at full load, if the solve evaluated it there



def warm_start(system: System, previous: System, q: np.ndarray, *, rotations: bool = True) -> np.ndarray:
    """A start for the static solve on a re-laid system: the previous solution's pulley rotations (0
    with rotations=False: the material they moved carried into the spans, `settled_reference`), the
    moved supports at their new layout position (0), and each span's previous shape carried over: its
    nodes moved by the linear interpolation of its end nodes' moves (a sagging span keeps its sag, a
    taut one stays straight between its new end nodes), the slopes kept."""
    q0 = np.zeros(system.n_dof)
    if rotations:
        q0[system.rot_dof] = q[previous.rot_dof]
    rotor, was = system.dofs.rotor_dof, previous.dofs.rotor_dof
    if rotor is not None and (rotor >= 0).any():  # a decoupler's rotor keeps its spring's wind-up
        on = rotor >= 0
        q0[rotor[on]] = q0[system.rot_dof[on]] - (q[previous.rot_dof[on]] - q[was[on]])
    old = previous.belt.element_coordinates(previous.expand(q))
    new = system.belt.element_coordinates(system.expand(q0))  # the end nodes where q0 puts them
    model = system.belt
    for s_, els in enumerate(model.span_elements):
        n_e = len(els)
        if not n_e:  # a spring span: no nodes of its own
            continue
        frac = (np.arange(n_e + 1) / n_e)[:, None]
        nodes = np.vstack([old[els, 0:4], old[els[-1], 4:8][None]])  # (n_e + 1, 4): r, r' of each node
        da, db = new[els[0], 0:2] - nodes[0, 0:2], new[els[-1], 4:6] - nodes[-1, 0:2]
        nodes[:, 0:2] += (1.0 - frac) * da + frac * db
        e0 = np.vstack([model.e0[els, 0:4], model.e0[els[-1], 4:8][None]])
        d = nodes - e0
        # span DOFs: the first node's slope, the interior nodes (r, r'), the last node's slope
        q0[system.dofs.span_slices[s_]] = np.concatenate([d[0, 2:4], d[1:-1].ravel(), d[-1, 2:4]])
    return q0


def span_end_points(system: System, q: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
    """(n_span, 2, 2) the start and end point of each span at q (p: q on the joint coordinates, if at
    hand): an ANCF span's first and last node, a spring span's two ends."""
    p = system.expand(q) if p is None else p
    out = np.zeros((system.layout.n, 2, 2))
    model = system.belt
    if model.elements.n_elem:
        E = model.element_coordinates(p)
        for s_, els in enumerate(model.span_elements):
            if len(els):
                out[s_, 0], out[s_, 1] = E[els[0], 0:2], E[els[-1], 4:6]
    if system.springs is not None:
        X = system.springs.positions(p)
        out[system.springs.span, 0], out[system.springs.span, 1] = X[:, 0:2], X[:, 2:4]
    return out


def settled_reference(system: System, q: np.ndarray, p: np.ndarray | None = None) -> np.ndarray:
    """(n_span,) the spans' reference lengths with the material the pulley rotations moved carried in.

    A pulley's rotation theta_j at equilibrium slides both span ends on it R_j theta_j along their
    tangent lines (the joint r = c + R n + R theta t): belt that has moved over the pulley. Laid anew
    with the end nodes on the tangent points (theta = 0), that belt is the spans': the span arriving
    at pulley j gives m_j = R_j theta_j (t . u) to the wrap and the span leaving it takes m_j from the
    wrap (`carried_reference`'s rule: the wrap unstretched, so the belt's undeformed length,
    sum(references) + sum(R wrap), is conserved exactly). m_j is measured as the mean of the two span
    ends' slides along their span directions u between q and q with the rotations zeroed (equal: the
    joints are linear in theta, and t . u is the same at both tangent points). The tensions then change by about T m / L (the stretch of the material moved),
    which the next solve meets with rotations smaller by the strain T / EA: a few solves settle it."""
    unturned = np.array(q, dtype=float)
    unturned[system.rot_dof] = 0.0
    slide = span_end_points(system, q, p) - span_end_points(system, unturned)  # (the joints are linear in theta)
    u = system.layout.span_direction
    start = (slide[:, 0] * u).sum(axis=1)  # slide of span s's start (on pulley s)
    end = (slide[:, 1] * u).sum(axis=1)  # slide of span s's end (on pulley s + 1)
    moved = 0.5 * (np.roll(end, 1) + start)  # m_j (n_pulley,): arriving span j-1's end, leaving span j's start
    return system.belt.reference_length - np.roll(moved, -1) + moved


def _rotation_slide(system: System, q: np.ndarray) -> float:
    """max_j R_j |theta_j| (m): how far the joints slide the span ends from the tangent points."""
    return float(np.abs(system.layout.radius * q[system.rot_dof]).max(initial=0.0))


@dataclass(frozen=True, kw_only=True)
class _Plan:
    """The facts of a drive that the re-lay passes use, fixed over the passes. Shapes: n pulleys."""

    system: System  # the system on the L0 fit (its layout lay0, its springs' and arms' data)
    build: object  # build(layout, prestrain_stretch, spring_free) -> System
    arm_of: dict  # an arm pulley's first translation slot -> its arm index
    anchored: set  # spring-supported translation DOFs whose springs stay anchored at the L0 fit
    conserve: bool  # the belt's length is carried over (`carried_reference`)
    moving: bool  # some pulley can move in the static solve
    prestrain: bool  # mode "prestrain" with a target: `meet_prestrain` on each layout
    tol_x: float  # m, the allowed movement from the laid centre (tolerance x shortest span)
    material: float | None = None  # m, the belt's undeformed length held by spans and creep wraps; None: rigid wraps

    @property
    def law(self):
        """The bar law of the belt (`barlaw.BarLaw`)."""
        wm = self.system.wraps
        return bar_law("green-lagrange" if wm is None else wm.axial_law)

    @property
    def lay0(self) -> Layout:
        return self.system.layout


def _plan(system: System, build, options: StaticOptions) -> _Plan:
    ts, d, lay0 = system.tension, system.dofs, system.layout
    arm_of = {} if system.arms is None else {int(s_): k for k, s_ in enumerate(system.arms.slot)}
    trans = np.array([k for dofs in d.trans_dof for k in dofs if (dofs[0] if dofs else -1) not in arm_of],
                     dtype=np.int64)  # spring-supported translations (an arm pulley's offsets are not)
    return _Plan(system=system, build=build, arm_of=arm_of,
                 anchored=set((trans[trans != ts.adjust_dof] if ts.mode == "adjust" else trans).tolist()),
                 conserve=ts.mode in ("adjust", "spring") or (ts.mode == "geometry" and lay0.adjust_index is not None),
                 moving=bool(trans.size) or system.arms is not None,
                 prestrain=ts.mode == "prestrain" and ts.target is not None,
                 tol_x=options.tolerance * float(lay0.span_length.min()),
                 material=(None if ts.mode == "prestrain" or system.wraps is None or system.wraps.kind == "rigid"
                           else float(lay0.belt_length) / float(system.belt.prestrain_stretch)))


def _adjust_offset(plan: _Plan, old: Layout, centers: np.ndarray) -> float | None:
    """The adjustable pulley's offset at `centers` (m along its slide, or rad of its arm's turn)."""
    a, d = old.adjust_index, plan.system.dofs
    if a is None:
        return None
    if old.adjust_kind == "arm":  # the further turn of the arm about its pivot
        pv = plan.system.arms.pivot[plan.arm_of[d.trans_dof[a][0]]]
        return float(wrap_angle(old.adjust_offset + pivot_angle(centers[a], pv) - pivot_angle(old.center[a], pv)))
    return old.adjust_offset + float((centers[a] - old.center[a]) @ d.trans_dir[a][0])


def _spring_free(plan: _Plan, centers: np.ndarray) -> np.ndarray:
    """(n_dof,) the springs' free values at `centers`: relaxed where they were on the L0 fit."""
    system, d, lay0 = plan.system, plan.system.dofs, plan.lay0
    free = np.zeros(d.n)
    for j, (dofs, dirs) in enumerate(zip(d.trans_dof, d.trans_dir) if plan.anchored else ()):
        for k, v in zip(dofs, dirs):
            if k in plan.anchored:
                free[k] = -float((centers[j] - lay0.center[j]) @ v)
    if system.arms is not None:  # an arm spring without a free angle: relaxed at its L0-fit angle
        for k, dof in enumerate(system.arms.dof):
            if int(dof) == system.tension.adjust_dof:
                continue  # the tension step sets its preload
            j = system.arms.pulleys[k]
            pv = system.arms.pivot[k]
            free[int(dof)] = float(wrap_angle(pivot_angle(lay0.center[j], pv) - pivot_angle(centers[j], pv)))
    return free


def _lay_out(plan: _Plan, old: Layout, centers: np.ndarray, ref_old: np.ndarray, step: str, *, carry: bool = False,
             build: bool = True, laid: Layout | None = None):
    """(layout, spring_free, system or None) at `centers`, the belt carried over from `old` (its
    reference lengths carried, `carried_reference`, where the mode conserves the belt or `carry`: the
    spans' references already hold the material the rotations moved); build=False: no system (None).
    laid: the checked layout of old's pulleys at `centers`, if at hand (`relay`'s but for the adjustable
    pulley's fields, which are old's and its offset at `centers`)."""
    try:
        offset = _adjust_offset(plan, old, centers)
        new = relay(old, centers, adjust_offset=offset) if laid is None else \
            replace(laid, adjust_index=old.adjust_index, adjust_kind=old.adjust_kind,
                    adjust_offset=old.adjust_offset if offset is None else float(offset))
    except GeometryError as exc:
        j = int(np.argmax(np.linalg.norm(centers - old.center, axis=1)))
        raise SolverError(f"no belt path through the solved pulley positions: {exc}", analysis="static",
                          step=step, item=f"pulley {old.names[j]}") from None
    free = _spring_free(plan, centers)
    if not build:
        return new, free, None
    if plan.conserve or (carry and not plan.prestrain):
        return new, free, plan.build(new, new.span_length / carried_reference(old, new, ref_old), free)
    if plan.prestrain:
        return new, free, None  # built by meet_prestrain
    return new, free, plan.build(new, None, free)


def _span_tension_law(plan: _Plan, split: np.ndarray):
    """span_tension(angles, lengths, rough=False) -> (n,) span tensions on a rigid belt of a layout with
    those span angles and lengths (arrays (n,)): the target as the length-weighted mean, or what the belt's
    conserved length gives on that path, split by the accessory torques; None if neither applies. rough:
    the creep wraps' slip part evaluated once (`settled_budget(evaluations=1)`), for a trial far from the
    answer."""
    system, lay0 = plan.system, plan.lay0
    ts = system.tension
    if ts.target is not None:
        target = float(ts.target)

        def span_tension(angle: np.ndarray, length: np.ndarray, rough: bool = False) -> np.ndarray:
            return target - float(length @ split) / float(length.sum()) + split
        return span_tension
    if plan.conserve and ts.mode != "adjust":
        EA, ref0, steps0 = float(system.EA), system.belt.reference_length, radius_steps(lay0)
        slip: list = [None]  # creep wraps: the slip model of the last call (`settled_budget`), the next one's start
        wm, v = system.wraps, float(system.belt_speed)
        rho_v2 = 0.0 if wm is None or not v else wm.mass_per_length * v * v  # the running belt's rho v^2 (N)

        def span_tension(angle: np.ndarray, length: np.ndarray, rough: bool = False) -> np.ndarray:
            ref = carried_lengths(lay0.span_angle, angle, steps0, ref0, lay0.span_name)
            wraps = None if plan.material is None else wrap_budget(system.wraps, lay0.radius, turned_wraps(lay0, angle),
                                                                     system.belt_speed)
            T, slip[0] = settled_budget(length, split, float(ref.sum()), EA, law=plan.law, wraps=wraps,
                                        start=slip[0], evaluations=1 if rough else SLIP_EVALUATIONS,
                                        centrifugal=rho_v2)  # (the pulleys unturned)
            return T
        return span_tension
    return None


def _adjust_fit(plan: _Plan):
    """fit(centers) -> Layout: the adjustable pulley where spans at the target stretch fit the belt
    (mode "adjust"), the arm's turn counted from the drawn arm angle as on the L0 fit."""
    system, lay0, d = plan.system, plan.lay0, plan.system.dofs
    EA = float(system.EA)
    lam_T = plan.law.stretch_for_tension(float(system.tension.target), EA)
    material = float(system.belt.reference_length.sum() + lay0.arc_length.sum())  # L0, wraps unstretched
    arc_weight = lam_T if plan.material is None else 1.0  # creep wraps: stretched as the spans (no torques)
    j = lay0.adjust_index
    pivot = None if lay0.adjust_kind != "arm" else system.arms.pivot[plan.arm_of[d.trans_dof[j][0]]]

    def fit(centers: np.ndarray) -> Layout:
        lay_f = fit_adjustable(centers, lay0.radius, lay0.side_sign, lay0.names, index=j,
                               direction=d.trans_dir[j][0], target_length=lam_T * material,
                               arc_weight=arc_weight, orientation=lay0.orientation, pivot=pivot,
                               base=lay0 if np.array_equal(centers, lay0.center) else None)
        if pivot is not None:
            lay_f = replace(lay_f, adjust_offset=float(wrap_angle(lay0.adjust_offset + lay_f.adjust_offset)))
        return lay_f
    return fit


def _predicted_start(plan: _Plan):
    """(system, layout, spring_free, warm start or None, prestrain stretch) of the first pass: the
    predicted layout (`predicted_centers`, the pulleys turned to the predicted span tensions), or the
    L0 fit where there is no prediction (or it fails)."""
    system, lay0, ts = plan.system, plan.lay0, plan.system.tension
    n_dof, EA = system.dofs.n, float(system.EA)
    lam_p = float(system.belt.prestrain_stretch)
    span_tension = _span_tension_law(plan, torque_split(lay0, system.loads, system.dofs.torque_dof, system.driver))
    if span_tension is None or not (plan.moving or ts.mode == "adjust"):
        return system, lay0, np.zeros(n_dof), None, lam_p
    fit = _adjust_fit(plan) if ts.mode == "adjust" else None
    try:
        centers, laid = predicted_centers(system, plan.anchored, fit, plan.tol_x, span_tension)
        settled = not plan.prestrain and (ts.target is None or plan.conserve)
        lay, free, built = _lay_out(plan, lay0, centers, system.belt.reference_length, "prediction", build=not settled,
                                    laid=laid)
        if plan.prestrain:
            return system, lay, free, None, plan.law.stretch_for_tension(float(ts.target), EA)
        T = span_tension(lay.span_angle, lay.span_length)
        lam = plan.law.stretch_for_tension(T, EA)
        if ts.target is None:  # the belt's conserved length settled on the spans: references L_s / lambda(T_s)
            built = plan.build(lay, lam, free)
            # (each span laid at the stretch of its predicted tension: `predictor`'s elongations are all 0, and
            # so is its answer, the pulleys unturned and the spans straight between their tangent points)
            return built, lay, free, np.zeros(built.n_dof), lam_p
        elif plan.conserve:  # the same, scaled to the belt's carried reference total (exact without torques)
            ref = lay.span_length / lam
            change = wrap_budget_change(system.wraps, lay)  # creep wraps: their stretch to the spans
            total = float(carried_reference(lay0, lay, system.belt.reference_length).sum())
            ref *= (total - (0.0 if change is None else change(T))) / float(ref.sum())
            built = plan.build(lay, lay.span_length / ref, free)
        warm = predictor(built, lam, ts.adjust_dof, built.driver_dof)
        return built, lay, free, warm, lam_p
    except (GeometryError, SolverError, ArithmeticError, ValueError, np.linalg.LinAlgError):
        return system, lay0, np.zeros(n_dof), None, lam_p  # no prediction: start from the L0 fit


def _extrapolated(plan: _Plan, system: System, centers: np.ndarray, step: np.ndarray, prev_step) -> np.ndarray:
    """The next layout's centres: the solved ones, extrapolated (Aitken) where the passes contract
    steadily along one line; an arm pulley kept on its circle about the pivot."""
    if prev_step is None:
        return centers
    rho = float(np.vdot(step, prev_step) / np.vdot(prev_step, prev_step))
    cos = float(np.vdot(step, prev_step) / (np.linalg.norm(step) * np.linalg.norm(prev_step)))
    if not (abs(rho) < 0.5 and abs(cos) > 0.9):  # steps along one line, shrinking (or alternating)
        return centers
    centers = centers + rho / (1.0 - rho) * step
    if system.arms is not None:  # an arm pulley stays on its circle about the pivot
        for k in range(len(system.arms.dof)):
            j = system.arms.pulleys[k]
            pv = system.arms.pivot[k]
            r = centers[j] - pv
            centers[j] = pv + r * (np.hypot(*(plan.lay0.center[j] - pv)) / np.hypot(*r))
    return centers


SETTLE_PASSES = 8  # re-references after the solve (each leaves rotations smaller by about the belt strain)
BUDGET_PASSES = 20  # creep wraps: budget steps (a secant: two or three where the prediction was right)


def _resettled(plan: _Plan, system: System, q: np.ndarray, free: np.ndarray, budget: float = 0.0) -> System:
    """The drive on the same layout with the spans' `settled_reference` lengths at q, their total changed
    by `budget` (m, the creep wraps' `budget_step`; in proportion to the lengths)."""
    ref = settled_reference(system, q)
    if budget:
        ref = ref * (1.0 + budget / float(ref.sum()))
    built = plan.build(system.layout, system.layout.span_length / ref, free)
    return built.full() if hasattr(built, "full") else built


def _settle(plan: _Plan, system: System, lay: Layout, free: np.ndarray, q: np.ndarray, options: StaticOptions,
            budget: Budget):
    """The equilibrium with the pulley rotations carried into the spans (`settled_reference`): the drive
    rebuilt on the same layout with those reference lengths, solved from q with the rotations zeroed,
    until no joint slides more than plan.tol_x (the centres' own tolerance: a pulley within tol_x of its
    laid centre leaves its rotation that far from 0 to meet its tangent points). Returns (system, q, preload, history, known, solves,
    Newton iterations)."""
    solves = iterations = 0
    for k in range(SETTLE_PASSES):
        built = _resettled(plan, system, q, free)
        warm = warm_start(built, system, q, rotations=False)
        q, preload, hist, known = solve_equilibrium(built, options, q0=warm, known=True, budget=budget)
        system, solves, iterations = built, solves + 1, iterations + len(hist)
        if _rotation_slide(system, q) <= plan.tol_x:
            break
    return system, q, preload, hist, known, solves, iterations


def solve_static_on_solved_geometry(system: System, build, options: StaticOptions, *,
                                    max_passes: int = MAX_PASSES) -> SolvedDrive:
    """Static equilibrium with the belt laid out at the solved pulley positions.

    `system` is laid out on the L0 fit (`build_system`); build(layout, prestrain_stretch, spring_free)
    builds the same drive on another layout (see `build_system`). A pulley that moves in the static
    solve (the adjustable pulley's tension travel, a bearing's deflection) leaves its spans meeting it
    off tangent (the joints keep the tangent points of the layout), so the layout is laid anew at the
    solved centres (`geometry.relay`: tangent points, spans and wraps recomputed), the system rebuilt
    and solved again, until no pulley moves more than tolerance x (shortest span) from its laid centre.
    The first layout is predicted (`predicted_centers`: the drive under a uniform tension, pure
    geometry), and from the third pass on the next centres are extrapolated (Aitken) when the passes
    contract steadily: one pass without weight, two or three with it.

    The reference (stress-free) state of the re-laid spans, by tension mode:
    - "adjust" (and no target with an adjustable pulley): the belt of undeformed length L0 lies on the
      spans and the wraps, the wraps unstretched (as in the L0 geometry of DESIGN section 2, where the
      spans are stress-free and moving the pulley stretches the spans only): `carried_reference` moves
      belt between span and wrap where a tangent point moves, so the spans' reference lengths sum to
      L0 - sum(R_j wrap_j) on every layout, and the pulley rotations stay what they were.
    - "prestrain": a uniform span stretch, iterated (secant, `meet_prestrain`) until the static mean
      tension equals the target with every pulley free on its bearing.
    - no target, no adjustable pulley: the belt of length L0 stretched uniformly onto the new path.
    Bearing springs stay anchored where they were relaxed on the L0 fit (spring_free); the adjustable
    pulley's spring in mode "adjust" carries the preload its slide equation asks for, as before.
    """
    plan = _plan(system, build, options)
    system, lay, free, warm, lam_p = _predicted_start(plan)
    unpredicted = warm is None and not plan.prestrain  # (no rigid-belt prediction: from the L0 fit)
    if hasattr(system, "full"):  # a deferred build (pipeline.analyse): solved on the L0 fit after all
        system = system.full()
    slope, prev_step = None, None
    movement: list[float] = []
    solves = iterations = 0
    budget = Budget.of(options)  # over all passes and solves
    settles = referenced = 0  # solves on re-referenced spans alone; re-references (`settled_reference`) in all
    budget_history: list[tuple[float, float]] = []  # creep wraps: `budget_excess`'s (S, W) of the solves so far
    carry = False  # once re-referenced, every re-lay carries the spans' references over
    for p in range(1, max_passes + 1):
        if plan.prestrain:
            system, st, lam_p, slope, k = meet_prestrain(build, lay, lam_p, free, options, slope, budget)
            solves += k
            q_p, known = st.q, {}
            iterations += st.iterations  # (the last prestrain solve's)
        else:
            q_p, preload, hist, known = solve_equilibrium(system, options, q0=warm, known=True, budget=budget)
            solves += 1
            iterations += len(hist)
        solved_centers = system.pulley_centers(q_p, p=known.get("joint"))
        step = solved_centers - lay.center
        movement.append(float(np.sqrt((step * step).sum(axis=1)).max(initial=0.0)))  # (the largest |step|)
        if not plan.moving or movement[-1] <= plan.tol_x:
            slide = _rotation_slide(system, q_p)
            short, checked = 0.0, None  # creep wraps: the change of the spans' reference total the budget asks for
            if plan.material is not None and not plan.prestrain:
                checked = static_result(system, q_p, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof,
                                        known={**known, "pulley_center": solved_centers})  # (its wraps: the budget's)
                excess = budget_excess(system, checked, plan.material, options.tolerance)
                if excess is not None:
                    budget_history.append(excess)
                    short = budget_step(budget_history, plan.material)
            if not plan.prestrain and ((slide > plan.tol_x and referenced < SETTLE_PASSES)
                                       or (short and len(budget_history) <= BUDGET_PASSES)):
                # the material the rotations moved into the spans' references, solved again (`settled_reference`)
                settles, referenced, carry = settles + 1, referenced + 1, True
                prev_system, system = system, _resettled(plan, system, q_p, free, short)
                warm = warm_start(system, prev_system, q_p, rotations=False)
                continue
            if short:  # the budget steps spent and the budget still open: a named failure, never a silent result
                raise SolverError(f"the creep wraps' belt-length budget did not close in {BUDGET_PASSES} steps: the "
                                  f"spans and wraps hold {budget_history[-1][0] + budget_history[-1][1]:.12g} m of belt "
                                  f"against belt.length {plan.material:.12g} m", analysis="static",
                                  step=f"budget step {len(budget_history)}", residual=abs(short), item="belt.wraps")
            if plan.prestrain and slide > plan.tol_x:  # (the secant's uniform stretch is done: settled once here)
                system, q_p, preload, hist, known, k, its = _settle(plan, system, lay, free, q_p, options, budget)
                solves, iterations = solves + k, iterations + its
                st = static_result(system, q_p, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof,
                                   known={**known, "pulley_center": system.pulley_centers(q_p, p=known.get("joint"))})
            elif checked is not None:
                st = checked
            elif not plan.prestrain:
                st = static_result(system, q_p, preload, hist[:, 0], hist[:, 1], len(hist), system.driver_dof,
                                   known={**known, "pulley_center": solved_centers})
            check_slack(system, st)
            return SolvedDrive(system=system, static=st, passes=p - settles, settles=settles, solves=solves, movement=np.array(movement),
                               newton_iterations=iterations, tangent=None if plan.prestrain else known.get("tangent"))
        centers = _extrapolated(plan, system, solved_centers, step, prev_step)
        prev_step = step
        # the rotations' material carried into the references on the way (the same pass as the re-lay)
        settle = not plan.prestrain and referenced < SETTLE_PASSES and _rotation_slide(system, q_p) > plan.tol_x
        ref_old = settled_reference(system, q_p) if settle else system.belt.reference_length
        referenced, carry = referenced + settle, carry or settle
        if unpredicted and plan.material is not None and len(budget_history) < BUDGET_PASSES:
            # creep wraps without a prediction: the belt-length budget met on the way (a secant across re-lays)
            excess = budget_excess(system, static_result(system, q_p, preload, hist[:, 0], hist[:, 1], len(hist),
                                                         system.driver_dof, known={**known, "pulley_center": solved_centers}),
                                   plan.material, options.tolerance)
            if excess is not None:
                budget_history.append(excess)
                ref_old = ref_old * (1.0 + budget_step(budget_history, plan.material) / float(ref_old.sum()))
                carry = True
        prev_system, prev_q = system, q_p
        lay, free, built = _lay_out(plan, lay, centers, ref_old, f"re-lay pass {p}", carry=carry)
        if plan.prestrain:
            lam_p = float(lay.span_length.sum() / ref_old.sum())
        else:
            system = built
            warm = warm_start(system, prev_system, prev_q, rotations=not settle)
    j = int(np.argmax(np.linalg.norm(step, axis=1)))
    raise SolverError(f"the solved geometry did not settle in {max_passes} re-lay passes: pulley "
                      f"'{lay.names[j]}' still moves {movement[-1]:.3g} m from its laid centre "
                      f"(allowed {plan.tol_x:.3g} m)", analysis="static", step=f"re-lay pass {max_passes}",
                      item=f"pulley {lay.names[j]}")
