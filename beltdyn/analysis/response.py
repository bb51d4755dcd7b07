"""Steady forced response of a running drive: the harmonic steady state of the drive linearized about
its static equilibrium, over a range of driver speeds and engine orders (`beltdyn response`).

Nomenclature (independent coordinates q, n = n_dof):
    q0          the static equilibrium (`static.StaticResult.q`)
    M           J^T M J at q0, the mass matrix on q (`System.mass_matrix`)
    K           the loaded tangent at q0 (`System.equilibrium`: belt, springs, the arms' geometric terms) and
                the arms' dry friction while they stick, T_f / delta on their angles (below)
    C           J^T (C_c + alpha M + beta K_0 + C_belt(q0)) J: the components' dampers, Rayleigh damping
                (K_0 the tangent on the joint coordinates, as in the transient) and the belt's Kelvin-Voigt
                damping matrix at q0 (retardation times [response.damping] belt_axial / belt_bending)
    Omega       the driver's mean speed (rad/s); k an engine order; omega = k Omega the excitation (rad/s)

Small motions x(t) = Re(X e^{i omega t}) about q0 obey M x'' + C x' + K x = f(t), so for each
(Omega, k) one complex solve

    D(omega) X = F,     D = K + i omega C - omega^2 M,

with the prescribed rotations held: the driver's (and any pulley with a "speed" excitation) move by
Theta; the free DOFs solve D_ff X_f = F_f - D_fp Theta. A speed fluctuation B sin(omega t + phase) is
the angle Theta = -(B / omega) e^{i phase} (the transient's engine-order fluctuation at constant speed,
`forcing_laws.rotation_state`); a torque tau cos(omega t + phase) is F = tau e^{i phase} on the pulley's
rotation. The excitations of one order act together (their phases add).

Outputs Y = h'(q0) X are the transient's own output functions linearized by central differences in the
directions Re X and Im X (the velocities i omega X and accelerations -omega^2 X go with them), so a
span tension, hub load, bearing force or mid-span displacement means here exactly what it means in
/transient; amplitudes |Y| and phases arg Y (y(t) = |Y| cos(omega t + arg Y)).

The running belt: with response.transport (default) the drive is linearized at each speed about its
running equilibrium at the belt speed c = speed x R_driver (`running.linearized_matrices`: the
gyroscopic G joins C, K holds the centripetal -c^2 B; the hub loads carry the momentum flux), one
static solve per speed; transport = false linearizes once about the equilibrium of [running] (or at
rest), the travelling frame of the transient's transport = false.

The tensioner arms' dry friction T_f (N m) is, as in the transient (`integrator`), an elasto-plastic
element: a torsion spring k_f = T_f / delta (delta = `stepper_data.ARM_PRESLIDING`, the presliding
angle) from an anchor at the static angle, saturating at T_f. While the arm's amplitude stays below
delta the arm sticks and that law is exactly the linear spring k_f, which K holds (`linearize`): the
linear response is the arm sticking, the transient's small-amplitude limit. Beyond delta the arm
slides (a torque of T_f against the motion, not linear): the response is not valid there, and says so.

The wraps (docs/wraps.md): the response holds every wrap sticking, the pulley turning with the belt on
it (rigid wraps: the transient's wrap bristle without its presliding compliance); with creep wraps and
friction values it says so in its notes (a wrap that reaches its capstan torque slides: a transient).

Limits (`limit_warnings`, in `ResponseResult.warnings`): a span whose tension amplitude |Y| at an end
exceeds that end's static tension T0 (at the equilibrium the speed is linearized about) would go slack,
T0 + |Y| cos(...) < 0; both vary along a span about linearly between its ends and T0 - |Y| is then
concave, so its least value lies at an end and the ends are checked. An arm with dry friction whose
angle amplitude exceeds delta slides. Each is reported with the first (lowest) speed where it happens
and the worst (largest ratio), with the order.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from beltdyn.analysis.static import StaticResult
from beltdyn.analysis.stepper_data import ARM_PRESLIDING
from beltdyn.analysis.transient_setup import slipping_pulleys
from beltdyn.config import Damping, ResponseOptions
from beltdyn.errors import SolverError
from beltdyn.model.decouplers import decouplers_of
from beltdyn.model.system import System

OUTPUTS = ("span_tension", "hub_load", "pulley_angle", "pulley_speed", "arm_angle", "midspan_displacement",
           "driver_torque")


@dataclass(frozen=True, kw_only=True)
class ResponseResult:
    """Complex amplitudes over (speed, order): y(t) = Re(Y e^{i omega t})."""

    speed: np.ndarray  # (n_speed,) rad/s, the driver's mean speed
    orders: np.ndarray  # (n_order,)
    frequency: np.ndarray  # (n_speed, n_order) Hz, the excitation frequency k Omega / (2 pi)
    belt_speed: np.ndarray  # (n_speed,) m/s, Omega R_driver
    outputs: dict  # name -> complex array (n_speed, n_order, ...) (see OUTPUTS and the components' series)
    dims: dict  # name -> the trailing dimension names of the output
    units: dict  # name -> units
    prescribed: tuple[str, ...]  # the pulleys whose rotation is prescribed
    static_tension: np.ndarray  # (n_speed, n_span, 2) N, the span-end tensions of the equilibrium of each speed
    span_names: tuple[str, ...]  # (n_span,) as /static names the spans
    arm_names: tuple[str, ...]  # (n_arm,) as outputs["arm_angle"]'s last axis
    arm_friction: np.ndarray  # (n_arm,) N m, each arm's dry friction torque (0: none)
    notes: tuple[str, ...] = ()  # warnings about the model (damping, friction), not about the amplitudes
    warnings: tuple[str, ...] = ()  # notes + limit_warnings(self)


@dataclass(frozen=True, kw_only=True)
class LinearDrive:
    """The drive linearized about q0: matrices on q (dense or CSR as the system)."""

    M: object
    C: object
    K: object
    q0: np.ndarray


def linearize(system: System, static: StaticResult, damping: Damping) -> LinearDrive:
    """M, C, K of the drive about its static equilibrium (see the module docstring;
    `running.linearized_matrices`, whose gyroscopic G is zero at rest)."""
    from beltdyn.analysis.running import linearized_matrices

    lin = linearized_matrices(system, static.q, damping)
    K = lin.K
    stick = sticking_stiffness(system)
    if np.any(stick):
        from scipy.sparse import diags, issparse

        K = (K + diags(stick)).tocsr() if issparse(K) else np.asarray(K) + np.diag(stick)
    return LinearDrive(M=lin.M, C=lin.C + lin.G if system.belt_speed else lin.C, K=K, q0=lin.q0)


def arm_friction_limit(arms) -> np.ndarray:
    """(n_arm,) N m: each arm's dry friction as the linear response holds it, the larger of its two
    limits by sense of rotation (`ArmJoints.friction` (arms, 2)), whose bristle stiffness the stepper
    uses too (`transient_setup`); 0 without friction."""
    if arms.friction is None:
        return np.zeros(len(arms.dof))
    friction = np.asarray(arms.friction, dtype=float)
    return friction.max(axis=1) if friction.ndim == 2 else friction


def sticking_stiffness(system: System) -> np.ndarray:
    """(n_dof,) N m/rad: the arms' dry friction while they stick, k_f = T_f / delta on each arm's angle
    (the transient's elasto-plastic law below its presliding angle delta), 0 elsewhere."""
    k = np.zeros(system.n_dof)
    arms = system.arms
    if arms is not None and arms.friction is not None:
        k[np.asarray(arms.dof, dtype=np.int64)] += arm_friction_limit(arms) / ARM_PRESLIDING
    return k


def excitation_sets(system: System, opts: ResponseOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(prescribed DOFs (p,), speed amplitudes B e^{i phase} (n_order, p), torques (n_order, n_dof))."""
    driver = int(system.rot_dof[system.driver])
    presc = [driver] + sorted({int(system.rot_dof[system.pulley_index(e.pulley)]) for e in opts.excitation
                               if e.kind == "speed"} - {driver})
    B = np.zeros((len(opts.orders), len(presc)), dtype=complex)
    tau = np.zeros((len(opts.orders), system.n_dof), dtype=complex)
    for e in opts.excitation:
        j = system.pulley_index(e.pulley)
        d = int((system.rot_dof if e.kind == "speed" else system.dofs.torque_dof)[j])  # (a torque: on a rotor)
        for o, k in enumerate(opts.orders):
            if e.order and e.order != k:
                continue
            z = e.amplitude * np.exp(1j * e.phase)
            if e.kind == "speed":
                B[o, presc.index(d)] += z
            else:
                tau[o, d] += z
    return np.array(presc, dtype=np.int64), B, tau


def solve_harmonic(lin: LinearDrive, omega: np.ndarray, presc: np.ndarray, theta: np.ndarray,
                   force: np.ndarray) -> np.ndarray:
    """X (F, n) complex for excitation frequencies omega (F,) rad/s, prescribed motions theta (F, p) of the
    DOFs presc and forces force (F, n): D_ff X_f = F_f - D_fp theta, X_p = theta. Raises SolverError at a
    frequency where D_ff is singular (an undamped resonance hit exactly)."""
    from scipy.sparse import issparse

    n = lin.q0.shape[0]
    is_free = np.ones(n, dtype=bool)
    is_free[presc] = False
    free = np.flatnonzero(is_free)
    X = np.zeros((len(omega), n), dtype=complex)
    X[:, presc] = theta
    if not issparse(lin.K):
        K, C, M = (np.asarray(A)[free] for A in (lin.K, lin.C, lin.M))  # the free rows (n_f, n)
        for lo in range(0, len(omega), 64):  # (chunk, n_f, n) complex rows at once, D_ff and D_fp their columns
            w = omega[lo: lo + 64, None, None]
            D_rows = K[None] + 1j * w * C[None] - w * w * M[None]
            D, Dp = D_rows[:, :, free], D_rows[:, :, presc]
            rhs = force[lo: lo + 64][:, free] - np.einsum("fij,fj->fi", Dp, theta[lo: lo + 64])
            try:
                X[lo: lo + 64, free] = np.linalg.solve(D, rhs[..., None])[..., 0]
            except np.linalg.LinAlgError:
                raise SolverError("singular dynamic stiffness K + i w C - w^2 M: an undamped resonance at an "
                                  "excitation frequency (add [response.damping])", analysis="response",
                                  step=f"{omega[lo] / (2 * np.pi):.6g}-{omega[min(lo + 63, len(omega) - 1)] / (2 * np.pi):.6g} Hz") from None
        return X
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    K, C, M = (csc_matrix(A) for A in (lin.K, lin.C, lin.M))
    Kff, Cff, Mff = (A[free][:, free] for A in (K, C, M))
    Kfp, Cfp, Mfp = (A[free][:, presc] for A in (K, C, M))
    for f, w in enumerate(omega):
        D = (Kff + 1j * w * Cff - w * w * Mff).tocsc()
        rhs = force[f, free] - (Kfp + 1j * w * Cfp - w * w * Mfp) @ theta[f]
        try:
            X[f, free] = splu(D).solve(rhs)
        except RuntimeError:
            raise SolverError("singular dynamic stiffness K + i w C - w^2 M: an undamped resonance at the "
                              "excitation frequency (add [response.damping])", analysis="response",
                              step=f"{w / (2 * np.pi):.6g} Hz") from None
    return X


def _outputs_of(system: System, q0: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray,
                preload: np.ndarray) -> dict:
    """The transient's outputs of states (B, n_dof) near q0 (q: positions, v, a: small velocities and
    accelerations), as /transient defines them (the pulley angles without the nominal rotation)."""
    p = system.expand(q)
    vp = system.expand_motion(q0, v)  # J(q0) v: the states differ from q0 by O(eps), v and a are O(eps)
    ap = system.expand_motion(q0, a)
    belt = system.belt
    E = belt.element_coordinates_batch(p)
    F = system.span_end_forces(p, vp, E)
    H = F + system.span_end_inertia(ap)
    if system.belt_speed:  # the running belt's momentum flux at the span ends (as /transient's hub loads)
        H = H + system.span_transport_forces(E, belt.element_coordinates_batch(vp, offset=False), system.belt_speed,
                                             p=p, vp=vp)
    out = {"span_tension": system.span_end_tensions(p, F, E),
           "hub_load": system.hub_loads(H),
           "pulley_angle": q[:, system.rot_dof], "pulley_speed": v[:, system.rot_dof],
           "midspan_displacement": belt.midspan_displacement(E)}
    if system.arms is not None:
        out["arm_angle"] = q[:, system.arms.dof]
    for c in system.components:
        if c.observations(system):
            out.update(c.observe(system, p, preload))
    return out


def linear_outputs(system: System, lin: LinearDrive, X: np.ndarray, omega: np.ndarray, preload: np.ndarray,
                   presc: np.ndarray, theta: np.ndarray, force: np.ndarray) -> dict:
    """Y = h'(q0) X per frequency (complex (F, ...)) by central differences along Re X and Im X with
    their velocities and accelerations; the driver torque from the prescribed DOF's row of D X - F."""
    F_ = len(omega)
    scale = float(np.abs(X).max(initial=0.0))
    eps = 1e-6 / scale if scale > 0 else 1.0  # motions of ~1e-6 in the DOFs' units: central differences to ~1e-12
    w = omega[:, None]
    V, A = 1j * w * X, -(w * w) * X
    q0 = lin.q0[None]
    states = []
    for part in (np.real, np.imag):
        for s in (1.0, -1.0):
            states.append((q0 + s * eps * part(X), s * eps * part(V), s * eps * part(A)))
    q = np.concatenate([st[0] for st in states])
    v = np.concatenate([st[1] for st in states])
    a = np.concatenate([st[2] for st in states])
    h = _outputs_of(system, lin.q0, q, v, a, preload)
    out = {}
    for name, y in h.items():
        y = y.reshape(4, F_, *y.shape[1:])
        out[name] = (y[0] - y[1] + 1j * (y[2] - y[3])) / (2.0 * eps)
    # the torque the driver's prescription applies: the residual of its row (as /transient driver_torque)
    d = presc[0]
    row = lambda A_: np.asarray(A_[[d], :].todense() if hasattr(A_, "todense") else A_[[d], :]).ravel()  # noqa: E731
    K_d, C_d, M_d = row(lin.K), row(lin.C), row(lin.M)
    out["driver_torque"] = (X @ K_d + 1j * omega * (X @ C_d) - omega ** 2 * (X @ M_d)) - force[:, d]
    return out


def speeds_of(opts: ResponseOptions) -> np.ndarray:
    """(points,) the driver's mean speeds of the response, rad/s."""
    return np.linspace(opts.speed[0], opts.speed[1], opts.points)


@dataclass(frozen=True, kw_only=True)
class Excitation:
    """What the response prescribes and applies, on a drive's DOF map (`excitation_sets`): the same for
    every speed of a response (each speed's drive has the DOF map of the configuration)."""

    prescribed: np.ndarray  # (p,) the DOFs whose rotation is prescribed, the driver's first
    speed_amplitude: np.ndarray  # (n_order, p) complex, B e^{i phase} of each order's speed excitations
    torque: np.ndarray  # (n_order, n_dof) complex, tau e^{i phase} of each order's torques


def excitation_of(system: System, opts: ResponseOptions) -> Excitation:
    """The `Excitation` of opts on the system's DOF map."""
    presc, B, tau = excitation_sets(system, opts)
    return Excitation(prescribed=presc, speed_amplitude=B, torque=tau)


def harmonic_outputs(system: System, static: StaticResult, opts: ResponseOptions, speed: np.ndarray,
                     excitation: Excitation) -> dict:
    """The complex amplitudes (name -> (S, O, ...)) of the outputs at the speeds (S,) x opts.orders (O,),
    all about the one equilibrium `static` of `system` (the module docstring)."""
    lin = linearize(system, static, opts.damping)
    presc, B, tau = excitation.prescribed, excitation.speed_amplitude, excitation.torque
    orders = np.asarray(opts.orders, dtype=float)
    omega = (speed[:, None] * orders[None, :]).ravel()  # (S * O,)
    o_idx = np.tile(np.arange(len(orders)), len(speed))
    theta = -B[o_idx] / omega[:, None]  # speed B sin(w t + phase): angle -(B / w) e^{i phase}
    force = tau[o_idx]
    X = solve_harmonic(lin, omega, presc, theta, force)
    preload = np.zeros(system.n_p)
    preload[: system.n_dof] = static.spring_preload
    Y = linear_outputs(system, lin, X, omega, preload, presc, theta, force)
    S, O = len(speed), len(orders)
    return {name: y.reshape(S, O, *y.shape[1:]) for name, y in Y.items()}


def response_notes(system: System, opts: ResponseOptions) -> tuple[str, ...]:
    """What the response says of its model (damping, the arms' friction, decouplers, wraps): of the drive's
    make, the same at every speed."""
    notes = []
    if not (opts.damping.rayleigh_mass or opts.damping.rayleigh_stiffness or opts.damping.belt_axial
            or opts.damping.belt_bending) and system.linear_damping is None:
        notes.append("no damping: the amplitudes at the resonances are bounded only by the speed grid "
                     "(give [response.damping])")
    arms = system.arms
    friction = np.zeros(0) if arms is None else arm_friction_limit(arms)
    if np.any(friction > 0):
        notes.append(f"the tensioner arms' dry friction is linear only while they stick: the response holds it as "
                     f"the spring T_f / {ARM_PRESLIDING:g} rad of the transient's presliding law (valid for arm "
                     f"amplitudes below {ARM_PRESLIDING:g} rad; beyond, the arm slides)")
    one_way = [c.pulley_name for c in decouplers_of(system.components) if c.one_way]
    if one_way:
        notes.append(f"the decoupler(s) of {', '.join(one_way)}: the response holds the one-way clutch engaged (linear); "
                     f"where the decoupler's torque amplitude exceeds its static torque the clutch would overrun "
                     f"(the transient models that)")
    slipping = slipping_pulleys(system)
    if len(slipping):
        notes.append(f"the wraps stick in the linear response: pulley(s) {', '.join(system.layout.names[j] for j in slipping)} "
                     f"turn with their wraps (rigid wraps, without the transient's presliding compliance and "
                     f"without slip); a wrap whose torque reaches its capstan torque slips: run a transient")
    return tuple(notes)


def response_result(system: System, opts: ResponseOptions, speed: np.ndarray, outputs: dict,
                    static_tension: np.ndarray, excitation: Excitation) -> ResponseResult:
    """The `ResponseResult` of the amplitudes `outputs` (name -> (S, O, ...), `harmonic_outputs`) at the
    speeds (S,), with static_tension (S, n_span, 2) the span-end tensions of each speed's equilibrium, its
    notes (`response_notes`) and the limit warnings of the whole speed range."""
    from beltdyn.model.geometry import travel_sense

    lay = system.layout
    orders = np.asarray(opts.orders, dtype=float)
    dims, units = {}, {}
    for name in outputs:
        dims[name], units[name] = _dims_units(system, name, outputs[name].ndim - 2)
    arms = system.arms
    R_d = float(lay.radius[system.driver]) * travel_sense(lay, system.driver)
    presc = set(excitation.prescribed.tolist())
    names = tuple(lay.names[j] for j in range(lay.n) if int(system.rot_dof[j]) in presc)
    result = ResponseResult(speed=speed, orders=orders, frequency=(speed[:, None] * orders[None, :]) / (2 * np.pi),
                            belt_speed=speed * R_d, outputs=outputs, dims=dims, units=units, prescribed=names,
                            static_tension=static_tension, span_names=tuple(lay.span_name(i) for i in range(lay.n)),
                            arm_names=() if arms is None else tuple(arms.names),
                            arm_friction=np.zeros(0) if arms is None else arm_friction_limit(arms),
                            notes=response_notes(system, opts))
    return replace(result, warnings=result.notes + limit_warnings(result))


def solve_response(system: System, static: StaticResult, opts: ResponseOptions,
                   speed: np.ndarray | None = None) -> ResponseResult:
    """The steady forced response over the speeds (default `speeds_of(opts)`) x opts.orders, all about
    the one equilibrium `static` of `system` (see the module docstring)."""
    speed = speeds_of(opts) if speed is None else np.asarray(speed, dtype=float)
    excitation = excitation_of(system, opts)
    tension = np.broadcast_to(np.asarray(static.span_tension, dtype=float),
                              (len(speed), *np.shape(static.span_tension))).copy()
    return response_result(system, opts, speed, harmonic_outputs(system, static, opts, speed, excitation), tension,
                           excitation)


def running_response(drive_at, opts: ResponseOptions) -> ResponseResult:
    """The response with each speed linearized about its own equilibrium: drive_at(speed) -> (system,
    static result) the drive at that driver speed (rad/s) and its running equilibrium (`pipeline.response_of`
    with response.transport). The excitation, notes and result are made once, for the speed range, on
    the DOF map all these drives share; the amplitudes speed by speed (as `solve_response` of each)."""
    speed = speeds_of(opts)
    parts, tension, excitation = [], [], None
    for omega in speed:
        system, static = drive_at(float(omega))
        if excitation is None:
            excitation = excitation_of(system, opts)
        parts.append(harmonic_outputs(system, static, opts, np.array([omega]), excitation))
        tension.append(np.asarray(static.span_tension, dtype=float))
    outputs = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return response_result(system, opts, speed, outputs, np.stack(tension), excitation)


def _first_and_worst(r: np.ndarray) -> tuple[tuple, tuple] | None:
    """The indices into r (S, ...) (S speeds first) of its first entry above 1 (the lowest speed, the
    largest there) and of its largest; None if no entry is above 1."""
    over = np.argwhere(r > 1.0)
    if not len(over):
        return None
    first = tuple(over[np.lexsort((-r[tuple(over.T)], over[:, 0]))[0]])
    return first, np.unravel_index(int(np.argmax(r)), r.shape)


def limit_warnings(res: ResponseResult) -> tuple[str, ...]:
    """Where the linear response leaves its range (module docstring): one warning per span that would go
    slack and per arm that would slide, naming the first (lowest) speed and the worst, with the order."""
    out = []
    T0 = res.static_tension[:, None]  # (S, 1, span, 2)
    Y = np.abs(res.outputs["span_tension"])  # (S, O, span, 2)
    ratio = np.where(T0 > 0, Y / np.where(T0 > 0, T0, 1.0), np.inf)
    for i, name in enumerate(res.span_names):
        r = ratio[:, :, i, :]  # (S, O, 2)
        found = _first_and_worst(r)
        if found is None:
            continue
        first, worst = found
        out.append(f"span {name} would go slack (its tension amplitude exceeds its static tension: the linear "
                   f"response is not valid there): from {_slack_at(res, i, first)}; worst {_slack_at(res, i, worst)}")
    if "arm_angle" in res.outputs and np.any(res.arm_friction > 0):
        A = np.abs(res.outputs["arm_angle"])  # (S, O, arm)
        for a, name in enumerate(res.arm_names):
            if not res.arm_friction[a] > 0:
                continue
            found = _first_and_worst(A[:, :, a] / ARM_PRESLIDING)
            if found is None:
                continue
            first, worst = found
            out.append(f"arm {name} would slide (its angle amplitude exceeds the presliding angle "
                       f"{ARM_PRESLIDING:g} rad of its dry friction {res.arm_friction[a]:g} N m; the linear response "
                       f"holds it stuck): from {_slide_at(res, A[:, :, a], first)}; worst "
                       f"{_slide_at(res, A[:, :, a], worst)}")
    return tuple(out)


def _slack_at(res: ResponseResult, span: int, at: tuple) -> str:
    s, o, e = (int(i) for i in at)
    Y = abs(res.outputs["span_tension"][s, o, span, e])
    T0 = res.static_tension[s, span, e]
    return (f"{res.speed[s]:.5g} rad/s, order {res.orders[o]:g} ({res.frequency[s, o]:.4g} Hz): {Y:.4g} N about "
            f"{T0:.4g} N at its {('start', 'end')[e]}")


def _slide_at(res: ResponseResult, A: np.ndarray, at: tuple) -> str:
    s, o = (int(i) for i in at)
    return (f"{res.speed[s]:.5g} rad/s, order {res.orders[o]:g} ({res.frequency[s, o]:.4g} Hz): "
            f"{A[s, o]:.3g} rad ({np.degrees(A[s, o]):.3g} deg)")


def _dims_units(system: System, name: str, ndim: int) -> tuple[tuple[str, ...], str]:
    """The trailing dimensions and units of an output, named as in /transient."""
    known = {"span_tension": (("span", "end"), "N"), "hub_load": (("pulley", "component"), "N"),
             "pulley_angle": (("pulley",), "rad"), "pulley_speed": (("pulley",), "rad/s"),
             "arm_angle": (("arm",), "rad"), "midspan_displacement": (("span",), "m"),
             "driver_torque": ((), "N m")}
    if name in known:
        return known[name]
    for c in system.components:
        for obs in c.observations(system):
            if obs.name == name:
                return tuple(obs.dims), obs.units
    raise KeyError(name)  # every output is named above or by a component


def coordinates(system: System) -> dict:
    """The trailing coordinates of the outputs (as /transient names them)."""
    lay = system.layout
    coords = {"pulley": list(lay.names), "span": [lay.span_name(i) for i in range(lay.n)], "end": ["start", "end"],
              "component": ["x", "y"]}
    if system.arms is not None:
        coords["arm"] = list(system.arms.names)
    for c in system.components:
        for obs in c.observations(system):
            if obs.name == "bearing_force":
                coords["bearing"] = list(c.pulley_names)
    return coords

