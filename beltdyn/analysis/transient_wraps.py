"""The wraps that may slip in the transient (issue 25, docs/wraps.md): the set-up of the stepper's `Wraps`
part and the state it adds.

With `belt.wraps = "creep"`, each pulley with a `friction` value gets its rotation split in two: the wrap
angle psi, the system's rotation DOF of the pulley, which the span ends follow through their joints
(r = c + R n + R psi t), and the pulley's own rotation theta, a DOF the stepper adds after the system's
independent coordinates (`hub`), which carries the pulley's inertia J, its rotational damping (and the
Rayleigh mass part alpha J), its loads and constant torques and a prescribed rotation of it. The two are
joined by the elasto-plastic bristle of the arms' friction (`friction_kernel.bristle`):

    M = clip(k_b (psi - theta - z), -M_cap, M_cap),   M_cap = R (T_max - c)(1 - exp(-mu beta)),

+M on psi and -M on theta, z the anchor (slides in the return mapping after each accepted step), T_max
the larger end tension of the wrap's two spans at the last accepted step, c = rho v^2 lambda(T_max) its
centrifugal part, k_b the creep law's tangent about the run's operating point (`presliding_stiffness`). Below
M_cap the wrap sticks (no drift beyond M / k_b but the creep: z drifts at z' = c u (1 - lambda_e /
lambda_e,drv), the pulley at the static rim speed ratio, `friction_kernel.wrap_creep`); beyond it the wrap
slides and transmits exactly M_cap (Coulomb): the capstan law of the running belt. The wrap angle keeps the
inertia the span-end nodes give it through the joints and carries the belt lying on the wrap, rho R^2 beta
(`wrap_belt_inertia`).

Nothing here when `belt.wraps = "rigid"` or no pulley has a friction value (`wrap_slip` is None): the
stepper's structures are then those of `transient_setup.prepare`, unchanged.

Index maps. The system's joint coordinates p (n_p,) are q (n_dof,) followed by the arms' dependent
offsets; the stepper's are q, the k hubs, then the offsets: `mapping` (n_p + 1,) gives each old index
(and the padding index n_p of the belt's tables) its new one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.config import TransientOptions
from beltdyn.analysis.stepper_data import split_matrix
from beltdyn.analysis.transient_setup import TransientSetup, slipping_pulleys, travel_rotation  # noqa: F401
# (slipping_pulleys re-exported)
from beltdyn.model.slip import belt_density
from beltdyn.model.system import System


@dataclass(frozen=True, kw_only=True)
class WrapSlip:
    """The slipping wraps of a run. Shapes (k,), one entry per slipping pulley."""

    pulleys: np.ndarray  # pulley index
    wrap: np.ndarray  # the wrap angle's DOF (the system's rotation DOF of the pulley)
    hub: np.ndarray  # the stepper's index of the pulley's own rotation (n_dof + i)
    inertia: np.ndarray  # kg m^2, J of the pulley (moved from the wrap to the hub)
    damping: np.ndarray  # N m s/rad, the pulley's rotational damping + rayleigh_mass J (moved likewise)
    bristle: np.ndarray  # N m/rad, k_b
    belt_inertia: np.ndarray  # kg m^2, rho R^2 beta: the belt lying on the wrap (on the wrap angle)
    belt_damping: np.ndarray  # N m s/rad, rayleigh_mass rho R^2 beta (likewise)
    n_dof: int  # the system's independent coordinates
    mapping: np.ndarray  # (n_p + 1,) the stepper's index of each joint coordinate (and of the padding n_p)
    driver: int = -1  # the pulley whose prescribed rotation carries the belt's nominal travel (-1: none, no creep)

    @property
    def n(self) -> int:
        return int(self.wrap.shape[0])


def _pulley_rotation(system: System) -> tuple[np.ndarray, np.ndarray]:
    """(J, d) (n_pulley,): each pulley's inertia and rotational damping (the "pulley inertia" component)."""
    n = len(system.rot_dof)
    J, d = np.zeros(n), np.zeros(n)
    where = {int(r): j for j, r in enumerate(system.rot_dof)}
    for c in system.components:
        if c.name != "pulley inertia":
            continue
        for i, dof in enumerate(c.dofs):
            j = where.get(int(dof))
            if j is None:
                continue
            if c.mass is not None:
                J[j] += float(np.asarray(c.mass)[i, i])
            if c.damping is not None:
                d[j] += float(np.asarray(c.damping)[i, i])
    return J, d


def wrap_slip(system: System, opts: TransientOptions, *, static=None, setup: TransientSetup | None = None
              ) -> WrapSlip | None:
    """The run's slipping wraps (module docstring), None when no wrap may slip. With the static state
    (`static.required_friction`, its wraps' operating point) and the run's set-up (the wrap angles' inertia
    and the step), k_b is the creep law's tangent there (`presliding_stiffness`); without them, the secant."""
    pulleys = slipping_pulleys(system)
    if not len(pulleys):
        return None
    k, n_dof, n_p = len(pulleys), system.n_dof, system.n_p
    J, d = _pulley_rotation(system)
    old = np.arange(n_p + 1)
    mapping = np.where(old < n_dof, old, old + k).astype(np.int64)
    wrap = system.rot_dof[pulleys].astype(np.int64)
    m_w = wrap_belt_inertia(system, pulleys)
    alpha = float(opts.damping.rayleigh_mass)
    if static is not None and setup is not None:
        held = {int(system.pulley_index(r.pulley)) for r in opts.rotation}  # prescribed hubs: theta held
        J_psi = split_matrix(setup.linear.M, n_p).diagonal()[wrap] - J[pulleys] + m_w
        reduced = np.array([J_psi[i] if int(j) in held else J_psi[i] * J[j] / max(J_psi[i] + J[j], 1e-300)
                            for i, j in enumerate(pulleys)])
        bristle = presliding_stiffness(system, pulleys, required=np.asarray(static.required_friction)[pulleys],
                                       reduced_inertia=reduced, step=float(opts.step))
    else:
        bristle = presliding_stiffness(system, pulleys)
    return WrapSlip(pulleys=pulleys, wrap=wrap, hub=n_dof + np.arange(k, dtype=np.int64), inertia=J[pulleys],
                    damping=d[pulleys] + alpha * J[pulleys], bristle=bristle, belt_inertia=m_w,
                    belt_damping=alpha * m_w, n_dof=n_dof, mapping=mapping, driver=travel_driver(system, opts))


def wrap_belt_inertia(system: System, pulleys: np.ndarray) -> np.ndarray:
    """(k,) kg m^2: the belt lying on each wrap, rho R beta of belt (rho per undeformed length, the wrap's
    stretch neglected: below 1 %) at radius R: rho R^2 beta. The spans' elements end at the tangent points,
    so without it the wrap angle psi has only the span ends' inertia."""
    lay = system.layout
    R = np.abs(lay.radius[pulleys])
    return float(belt_density(system)) * R * R * lay.wrap_angle[pulleys]


def travel_driver(system: System, opts: TransientOptions) -> int:
    """The pulley whose prescribed rotation carries the belt's nominal travel (`travel_rotation`, as
    `transient_setup.prepare` takes it), -1 without one: the reference of the wraps' creep."""
    i = travel_rotation(opts)
    return -1 if i < 0 else int(system.pulley_index(opts.rotation[i].pulley))


def secant_stiffness(EA: float, R: np.ndarray, mu: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """k_s (k,) N m/rad: the secant of a wrap's creep at rest from zero torque up to gross slip (linear law).
    At impending gross slip the slip arc is the whole wrap beta: the belt has crept by delta = int_0^beta
    (lambda(T(phi)) - lambda(T_e)) dphi = (T_e - c)(beta - (1 - exp(-mu beta)) / mu) / EA against the rim
    while it transmits M_cap = R (T_e - c)(1 - exp(-mu beta)): k_s = M_cap / delta, whatever the tension.
    The softest the wrap is anywhere below gross slip (the creep law's tangent falls as the torque rises)."""
    cap = 1.0 - np.exp(-mu * beta)
    return EA * R * cap / np.maximum(beta - cap / mu, 1e-12)


def tangent_stiffness(EA: float, R: np.ndarray, mu: np.ndarray, beta: np.ndarray, required: np.ndarray
                      ) -> np.ndarray:
    """k_t (k,) N m/rad: the creep law's tangent dM / d(delta) about a wrap loaded to the tension ratio
    (T_e - c) / (T_x - c) = exp(mu_req beta) (`required`: mu_req, the static's required friction).
    Nomenclature: T_e, T_x the tight and slack end tensions, c the centrifugal part, phi_s the slip arc
    (T_x - c = (T_e - c) exp(-mu phi_s), so mu phi_s = mu_req beta), delta the belt's creep against the rim
    (an angle) over the slip arc. With T_e held, dM/dphi_s = R mu (T_x - c), d delta/dphi_s = (T_e - T_x) / EA:

        k_t = EA R mu (T_x - c) / (T_e - T_x) = EA R mu / (exp(mu_req beta) - 1),

    which grows with mu (a longer adhesion arc) and without bound as the torque vanishes (inf where
    mu_req = 0: no slip arc); 0 where a span is slack (mu_req = inf)."""
    x = required * beta
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        k = EA * R * mu / np.expm1(x)
    return np.where(x <= 0.0, np.inf, np.where(np.isfinite(x), k, 0.0))


def resolved_stiffness(reduced_inertia: np.ndarray, step: float) -> np.ndarray:
    """k_h (k,) N m/rad: the bristle stiffness whose psi-theta mode sits at the step's Nyquist frequency,
    omega h = pi: k_h = (pi / h)^2 J_r, J_r = J_psi J / (J_psi + J) the reduced inertia of the wrap angle psi
    and the pulley theta (J_psi where theta is prescribed). A stiffer bristle puts its mode beyond what the
    step can represent (the generalized-alpha maps it to its high-frequency limit, damped by rho_inf): the
    wrap is then rigid for every frequency the run resolves."""
    return (np.pi / step) ** 2 * reduced_inertia


def half_torque_friction(mu: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """mu_half (k,): the tension ratio's friction exp(mu_half beta) = (T_e - c) / (T_x - c) of a wrap carrying half
    its capstan torque, T_e - T_x = (T_e - c)(1 - exp(-mu beta)) / 2: exp(mu_half beta) = 2 / (1 + exp(-mu beta)).
    The tangent there (`tangent_stiffness`) is EA R mu / tanh(mu beta / 2)."""
    return np.log(2.0 / (1.0 + np.exp(-mu * beta))) / beta


def presliding_stiffness(system: System, pulleys: np.ndarray, *, required: np.ndarray | None = None,
                         reduced_inertia: np.ndarray | None = None, step: float | None = None) -> np.ndarray:
    """k_b (k,) N m/rad of the wraps' bristles (docs/wraps.md, "The bristle's stiffness"): the creep law's
    tangent about the run's operating point, bounded below by the secant up to gross slip and above by the
    step's resolved stiffness:

        k_b = max(k_s, min(k_t(max(mu_req, mu_half)), k_h))
        (`secant_stiffness`, `tangent_stiffness`, `half_torque_friction`, `resolved_stiffness`).

    The operating point is the static state's tension ratio (`required`: mu_req), or half the capstan torque
    (mu_half) for a wrap the static loads less: such a wrap (an idler's, or one the run alone loads) carries the
    run's torque swings, which the static does not know; its tangent at no torque is infinite, and at half its
    torque range it is the stiffness of the middle of the range it can carry, finite, continuous in the static
    torque and growing with mu.

    Without an operating point (required None) the secant k_s."""
    lay = system.layout
    EA, R = float(system.EA), np.abs(lay.radius[pulleys])
    mu, beta = system.pulley_friction[pulleys], lay.wrap_angle[pulleys]
    k_s = secant_stiffness(EA, R, mu, beta)
    if required is None or reduced_inertia is None or step is None:
        return k_s
    operating = np.maximum(np.asarray(required, dtype=float), half_torque_friction(mu, beta))
    k_t = tangent_stiffness(EA, R, mu, beta, operating)
    return np.maximum(k_s, np.minimum(k_t, resolved_stiffness(np.asarray(reduced_inertia, dtype=float), step)))


def stepper_wraps(slip: WrapSlip, system: System, setup: TransientSetup):
    """integrator.Wraps of the run (its state: anchors, limits and torques set by the stepper's start).
    The end tensions come from the arriving span's last element (its end node) and the leaving span's
    first (its start node), or from their spring (`setup.belt.springs`, a spring span)."""
    from beltdyn.analysis import integrator as itg

    belt, lay = system.belt, system.layout
    n = lay.n
    counts = np.bincount(belt.elem_span, minlength=n)[:n] if len(belt.elem_span) else np.zeros(n, dtype=np.int64)
    first = np.r_[0, np.cumsum(counts)[:-1]]
    spring_of = np.full(n, -1, dtype=np.int64)  # the spring of each spring span
    spans = np.asarray(setup.belt.springs.span, dtype=np.int64)
    spring_of[spans] = np.arange(len(spans))

    def ends(pulleys):  # (in_elem, out_elem, in_spring, out_spring) of the pulleys' arriving and leaving spans
        arriving = (pulleys - 1) % n  # span j - 1 arrives at pulley j (its end), span j leaves it (its start)
        leaving = pulleys
        in_elem = np.where(counts[arriving] > 0, first[arriving] + counts[arriving] - 1, -1).astype(np.int64)
        out_elem = np.where(counts[leaving] > 0, first[leaving], -1).astype(np.int64)
        return (in_elem, out_elem, np.where(in_elem < 0, spring_of[arriving], -1).astype(np.int64),
                np.where(out_elem < 0, spring_of[leaving], -1).astype(np.int64))

    in_elem, out_elem, in_spring, out_spring = ends(slip.pulleys)
    k = slip.n
    ref_elem, ref_spring = np.full(2, -1, dtype=np.int64), np.full(2, -1, dtype=np.int64)
    travel = np.zeros(k)
    if slip.driver >= 0:  # the creep's reference: the stretch at the driver's entry (`friction_kernel.wrap_creep`)
        d_in, d_out, s_in, s_out = ends(np.array([slip.driver]))
        ref_elem, ref_spring = np.r_[d_in, d_out].astype(np.int64), np.r_[s_in, s_out].astype(np.int64)
        travel = np.asarray(setup.u_nom[slip.wrap], dtype=float)
    return itg.Wraps(wrap=slip.wrap.copy(), hub=slip.hub.copy(), radius=np.abs(lay.radius[slip.pulleys]).astype(float),
                     capstan=1.0 - np.exp(-system.pulley_friction[slip.pulleys] * lay.wrap_angle[slip.pulleys]),
                     rho=float(belt_density(system)), bristle=slip.bristle.astype(float), anchor=np.zeros(k),
                     limit=np.zeros(k), torque=np.zeros(k), preload=np.zeros(k), sliding=np.zeros(k),
                     factored=np.zeros(k), update=np.zeros((k, slip.n_dof + k)), updated=np.zeros(k),
                     small=np.zeros((k, k + 1)), in_elem=in_elem, out_elem=out_elem,
                     in_spring=in_spring, out_spring=out_spring, travel=travel, ref_elem=ref_elem,
                     ref_spring=ref_spring, ratio=np.ones(k), creep=np.zeros(k), step=np.zeros(1))


def _embed(A, slip: WrapSlip, n_new: int):
    """A (n_p, n_p) (dense, scipy or None) on the stepper's coordinates (n_new, n_new), CSR."""
    from scipy.sparse import coo_matrix, csr_matrix

    if A is None:
        return csr_matrix((n_new, n_new))
    C = coo_matrix(A)
    return csr_matrix((C.data, (slip.mapping[C.row], slip.mapping[C.col])), shape=(n_new, n_new))


def _on_hubs(slip: WrapSlip, n_new: int, wrap_value: np.ndarray, hub_value: np.ndarray):
    """The diagonal matrix (n_new, n_new) CSR with wrap_value on the wraps and hub_value on the hubs."""
    from scipy.sparse import csr_matrix

    rows = np.r_[slip.wrap, slip.hub]
    return csr_matrix((np.r_[wrap_value, hub_value], (rows, rows)), shape=(n_new, n_new))


def _vector(x: np.ndarray, slip: WrapSlip, n_new: int) -> np.ndarray:
    out = np.zeros(n_new)
    out[slip.mapping[: len(x)]] = x
    return out


def stepper_setup(slip: WrapSlip, system: System, setup: TransientSetup) -> dict:
    """The stepper's structures of `setup` (the system's) on the stepper's coordinates: the hubs added
    with the pulleys' inertia, damping, constant torques, loads and prescribed rotations moved onto them.
    Returns the fields of `transient.StepProblem` that change (belt, linear, forcing, constraints,
    groups, q0, v0, transport) and the band order (perm, bandwidth)."""
    from beltdyn.analysis import integrator as itg

    k, n_p = slip.n, system.n_p
    n_new = n_p + k
    m = slip.mapping
    J, d = slip.inertia, slip.damping
    belt = setup.belt
    springs = belt.springs._replace(idx=m[belt.springs.idx]) if belt.springs.idx.size else belt.springs
    belt = belt._replace(idx=m[belt.idx], springs=springs)
    lin = setup.linear
    m_w, d_w = slip.belt_inertia, slip.belt_damping  # the belt on the wrap stays on the wrap angle
    M = _embed(itg.split_matrix(lin.M, n_p), slip, n_new) + _on_hubs(slip, n_new, m_w - J, J)
    C = _embed(itg.split_matrix(lin.C, n_p), slip, n_new) + _on_hubs(slip, n_new, d_w - d, d)
    K = _embed(itg.split_matrix(lin.K, n_p), slip, n_new)
    for A in (M, C):
        A.eliminate_zeros()
    q_ref = _vector(lin.q_ref, slip, n_new)
    q_ref[slip.hub] = q_ref[slip.wrap]
    linear = itg.Linear(K=itg.split(K, n_new), q_ref=q_ref, C=itg.split(C, n_new), M=itg.split(M, n_new))
    F = setup.forcing
    constant = _vector(F.constant, slip, n_new)  # the pulleys' constant torques onto their hubs; the belt's
    weight = system.gravity_force[slip.wrap]  # weight on the wrap angle stays there
    constant[slip.hub] = constant[slip.wrap] - weight
    constant[slip.wrap] = weight
    nominal_mass = _vector(F.nominal_mass, slip, n_new)  # the pulleys' inertia of the nominal travel
    u_rot = setup.u_nom[slip.wrap]
    nominal_mass[slip.wrap] += (m_w - J) * u_rot  # (the belt on the wrap travels with it)
    nominal_mass[slip.hub] = J * u_rot
    nominal_damping = _vector(F.nominal_damping, slip, n_new)
    moved = nominal_damping[slip.wrap].copy()  # (the components' damping: the pulleys' rotational damping)
    nominal_damping[slip.wrap] = 0.0
    nominal_damping[slip.hub] = moved
    to_hub = dict(zip(slip.wrap.tolist(), slip.hub.tolist()))
    load_dof = np.array([to_hub.get(int(i), int(m[i])) for i in F.load_dof], dtype=np.int64)
    forcing = F._replace(constant=constant, nominal_mass=nominal_mass, nominal_damping=nominal_damping,
                         load_dof=load_dof)
    cons = setup.constraints
    constraints = cons._replace(dof=np.array([to_hub.get(int(i), int(m[i])) for i in cons.dof], dtype=np.int64))
    groups = np.r_[setup.groups[: slip.n_dof], setup.groups[slip.wrap], setup.groups[slip.n_dof:]].astype(np.int64)
    q0 = _vector(setup.q0, slip, n_new)
    q0[slip.hub] = q0[slip.wrap]
    v0 = _vector(setup.v0, slip, n_new)
    v0[slip.hub] = v0[slip.wrap]
    tr = setup.transport
    if tr is not None and (tr.follow or tr.speed):
        from scipy.sparse import csr_matrix

        def back(c):
            return csr_matrix((c.data, c.indices, c.indptr), shape=(n_p, n_p))

        A, G, B = (_embed(back(x), slip, n_new) for x in (tr.A, tr.G, tr.B))
        tr = tr._replace(A=itg.to_csr(A), G=itg.to_csr(G), B=itg.to_csr(B), a0=_vector(tr.a0, slip, n_new),
                         b0=_vector(tr.b0, slip, n_new), mag=itg.fused(M, A, G, B))
    elif tr is not None:
        tr = itg.no_transport(n_new)
    perm, bandwidth = band_order(slip, setup)
    return dict(belt=belt, linear=linear, forcing=forcing, constraints=constraints, groups=groups, q0=q0, v0=v0,
                transport=tr, perm=perm, bandwidth=bandwidth)


def band_order(slip: WrapSlip, setup: TransientSetup) -> tuple[np.ndarray, int]:
    """The band order of the stepper's q (n_dof + k,): the system's, each hub right after its wrap; the
    half-bandwidth grows by at most k (each hub shifts the DOFs after it by one)."""
    to_hub = dict(zip(slip.wrap.tolist(), slip.hub.tolist()))
    order = []
    for i in setup.perm.tolist():
        order.append(i)
        if i in to_hub:
            order.append(to_hub[i])
    return np.array(order, dtype=np.int64), int(setup.bandwidth) + slip.n


def stepper_arms(slip: WrapSlip, arms):
    """The arms (integrator.Arms) on the stepper's coordinates: their offsets' slots after the hubs."""
    return arms._replace(slot=slip.mapping[arms.slot], n_q=int(arms.n_q) + slip.n)


def system_coordinates(slip: WrapSlip, x: np.ndarray) -> np.ndarray:
    """The system's joint coordinates (..., n_p) of the stepper's (..., n_p + k): the hubs left out (the
    belt sees the wrap angles)."""
    keep = slip.mapping[:-1]
    return x[..., keep]
