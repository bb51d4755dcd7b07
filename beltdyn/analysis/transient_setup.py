"""The transient's set-up: `prepare` lowers a `System` and the transient options into the
stepper's named structures (`TransientSetup`; see `transient`'s docstring for the belt travel), the
series to record and their coordinates, the arms and the band order."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from beltdyn.config import TransientOptions
from beltdyn.analysis.static import StaticResult
from beltdyn.model.components import belt_rotation_rates
from beltdyn.model.decouplers import CLUTCH_DRAG, decouplers_of
from beltdyn.model.components import Observation as Series  # one declaration of a recorded series
from beltdyn.model.assembly import element_pairs
from beltdyn.model.system import System

ENERGY_TERMS = ("kinetic", "strain", "work", "dissipated", "balance_error")


@dataclass(frozen=True, kw_only=True)
class TransientSetup:
    """Everything fixed for one run: series to record, their coordinates, the stepper's structures."""

    series: tuple[Series, ...]
    coords: dict[str, list]
    belt: tuple  # integrator.BeltData
    linear: tuple  # integrator.Linear
    forcing: tuple  # integrator.Forcing
    constraints: tuple  # integrator.Constraints
    groups: np.ndarray  # (n,) DOF group of each DOF (convergence is measured per group)
    C: object  # constant damping (Rayleigh + components), dense/CSR, or None
    perm: np.ndarray
    bandwidth: int
    q0: np.ndarray
    v0: np.ndarray
    u_nom: np.ndarray
    nom_scale: float
    excitation_frequency: float | None
    preload: np.ndarray  # (n,) static spring preload
    transport: tuple | None = None  # integrator.Transport (the running belt's transport terms)


def output_volume(system: System, opts: TransientOptions) -> tuple[int, int]:
    """(samples, bytes) the run's histories will write: float64 values of every recorded series plus
    the time, at every output time from 0 to the duration (the spectra and attributes are small).
    Known before any analysis runs."""
    cons_dof = [int(system.rot_dof[system.pulley_index(r.pulley)]) for r in opts.rotation]
    series, coords = _series(system, opts, cons_dof)
    shapes = {name: len(v) for name, v in coords.items()}
    per_sample = 1 + sum(int(np.prod([shapes[d] for d in s.dims], dtype=np.int64)) for s in series)
    n = int(math.floor(opts.duration / opts.output_interval + 1e-9)) + 1
    return n, 8 * n * per_sample


def belt_travel(system: System) -> np.ndarray:
    """u_nom (n_p,): the rigid belt loop advanced by 1 m (pulley rotations +-1/R, nodes along t; the
    pulley centres stay)."""
    u = belt_rotation_rates(system.layout, system.rot_dof, system.n_p, system.dofs.rotor_dof)
    for s, sl in enumerate(system.dofs.span_slices):
        labels = system.dof_labels[sl]
        block = np.zeros(sl.stop - sl.start)
        for k, lab in enumerate(labels):  # interior node positions move along the chord
            if lab.endswith(" r1"):
                block[k] = system.belt.reference_direction[s][0]
            elif lab.endswith(" r2"):
                block[k] = system.belt.reference_direction[s][1]
        u[sl] = block
    return u


def p_to_q(system: System) -> np.ndarray:
    """(n_p,) the independent coordinate each joint coordinate depends on (an arm pulley's centre
    offsets: its arm angle)."""
    m = np.arange(system.n_p)
    if system.arms is not None:
        m[system.arms.slot] = system.arms.dof
        m[system.arms.slot + 1] = system.arms.dof
    return m


def slipping_pulleys(system: System) -> np.ndarray:
    """(k,) the pulleys whose wraps may slip in the transient (`transient_wraps`): creep wraps
    (`System.wraps`, belt.wraps) and a friction value, not a decoupler's pulley (its hub carries the
    decoupler's spring: its wrap is held sticking, `wrap_slip_notes`)."""
    mu = system.pulley_friction
    if (system.wraps is not None and system.wraps.kind != "creep") or mu is None:  # (None: creep)
        return np.zeros(0, dtype=np.int64)
    hubs = {int(c.dofs[0]) for c in decouplers_of(system.components)}
    held = np.array([int(d) in hubs for d in system.rot_dof], dtype=bool)
    return np.flatnonzero(np.isfinite(mu) & (mu > 0.0) & ~held).astype(np.int64)


def wrap_slip_notes(system: System) -> tuple[str, ...]:
    """What the transient says of wraps held sticking although they could slip: a decoupler's pulley with a
    friction value (the split rotation of `transient_wraps` would leave the decoupler's spring on the wrap
    angle, bypassing the wrap's friction)."""
    mu = system.pulley_friction
    if (system.wraps is not None and system.wraps.kind != "creep") or mu is None:
        return ()
    names = [c.pulley_name for c in decouplers_of(system.components)
             if np.isfinite(mu[system.pulley_index(c.pulley_name)]) and mu[system.pulley_index(c.pulley_name)] > 0.0]
    return tuple(f"pulley {n}: a decoupler's pulley, its wrap is held sticking in the transient (no wrap slip "
                 f"modelled behind a decoupler)" for n in names)


def stepper_arms(system: System):
    """integrator.Arms of the system (no arms: the identity map)."""
    from beltdyn.analysis import integrator as itg

    a = system.arms
    if a is None:
        return itg.no_arms(system.n_dof)
    fric = a.friction if a.friction is not None else np.zeros((len(a.dof), 2))
    top = fric.max(axis=1)
    return itg.Arms(dof=a.dof.astype(np.int64), slot=a.slot.astype(np.int64), length=a.length.astype(float),
                    angle=a.angle.astype(float), friction_up=fric[:, 0].copy(), friction_down=fric[:, 1].copy(),
                    bristle=np.where(top > 0, top / itg.ARM_PRESLIDING, 1.0),
                    anchor=np.zeros(len(a.dof)),  # the bristles relaxed at the start (set from q0 by `drive`)
                    n_q=int(system.n_dof))


def stepper_decouplers(system: System):
    """integrator.Decouplers of the system's one-way decouplers (`model.decouplers`; a decoupler without a
    clutch is all in the linear part), their clutches holding at the start."""
    from beltdyn.analysis import integrator as itg

    found = [c for c in decouplers_of(system.components) if c.one_way]
    if not found:
        return itg.no_decouplers()
    k = len(found)
    return itg.Decouplers(hub=np.array([c.dofs[0] for c in found], dtype=np.int64),
                          rotor=np.array([c.dofs[1] for c in found], dtype=np.int64),
                          stiffness=np.array([c.spring for c in found]), damping=np.array([c.viscous for c in found]),
                          drag=np.full(k, CLUTCH_DRAG), slip=np.zeros((2, k)), torque=np.zeros((2, k)))


def band_order(system: System) -> tuple[np.ndarray, int]:
    """Reverse Cuthill-McKee order of the coupling graph (elements and components) and the
    half-bandwidth it gives (about twice an element's: the belt loop closes on itself)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    n = system.n_dof
    to_q = p_to_q(system)
    rows, cols = element_pairs(system.belt.idx)
    keep = (rows < system.n_p) & (cols < system.n_p)
    rows, cols = [rows[keep]], [cols[keep]]
    if system.springs is not None:
        r, cc = element_pairs(system.springs.idx)
        live = (r < system.n_p) & (cc < system.n_p)
        rows.append(r[live])
        cols.append(cc[live])
    for c in system.components:
        for mat in (c.stiffness, c.damping, c.mass):
            if mat is not None:
                r, cc = np.nonzero(mat)
                rows.append(c.dofs[r])
                cols.append(c.dofs[cc])
    rows, cols = to_q[np.concatenate(rows)], to_q[np.concatenate(cols)]
    G = csr_matrix((np.ones(len(rows) + n), (np.r_[rows, np.arange(n)], np.r_[cols, np.arange(n)])), shape=(n, n))
    perm = np.asarray(reverse_cuthill_mckee(G, symmetric_mode=True), dtype=np.int64)
    inv = np.empty_like(perm)
    inv[perm] = np.arange(n)
    return perm, int(np.abs(inv[rows] - inv[cols]).max(initial=0))


def travel_rotation(opts: TransientOptions) -> int:
    """The index in `opts.rotation` of the prescribed rotation that carries the belt's nominal travel: the
    first with a speed; -1 without one."""
    for i, r in enumerate(opts.rotation):
        if r.speed != 0.0:
            return i
    return -1


def prepare(system: System, static: StaticResult, opts: TransientOptions) -> TransientSetup:
    """The stepper's structures for the run: only the loads, damping and outputs the options ask for."""
    from beltdyn.analysis import integrator as itg
    from beltdyn.model.belt_kernel import CURVATURE_CODE
    from beltdyn.model.spring_kernel import spring_data

    n = system.n_p
    u_nom = belt_travel(system)
    # constraints: prescribed rotations (any number); the first with a speed carries the belt travel
    cons_dof, cons_par = [], []
    nom_rot, nom_scale, f_exc = np.zeros(10), 0.0, None
    nominal = travel_rotation(opts)
    for i, r in enumerate(opts.rotation):
        d = int(system.rot_dof[system.pulley_index(r.pulley)])
        par = np.array([r.speed, r.ramp_time, r.amplitude, r.speed_amplitude, r.frequency, r.phase, r.fluctuation_ramp,
                        static.q[d] if opts.start == "static" else 0.0, r.order, r.start_speed])
        cons_dof.append(d)
        cons_par.append(par)
        if i == nominal:
            nom_rot, nom_scale = par.copy(), 1.0 / u_nom[d]
        if f_exc is None and (r.amplitude or r.speed_amplitude):  # at the mean speed for an engine order
            f_exc = r.order * abs(r.speed) / (2.0 * np.pi) if r.order > 0 else r.frequency
    # loads: one channel per (signal, DOF)
    params, tabs_t, tabs_v, ptr = [], [], [], [0]
    load_dof, load_coef, load_sig = [], [], []
    for load in opts.loads:
        j = system.pulley_index(load.pulley)
        for c, sig in enumerate(load.signals):
            k = len(params)
            params.append((sig.constant, sig.amplitude, sig.frequency, sig.phase, sig.ramp_time))
            tabs_t += list(sig.table_time)
            tabs_v += list(sig.table_value)
            ptr.append(len(tabs_t))
            if load.kind == "torque":
                load_dof.append(int(system.dofs.torque_dof[j]))  # (a decoupler's rotor)
                load_coef.append(1.0)
                load_sig.append(k)
            else:
                for d, vec in zip(system.trans_dof[j], system.trans_dir[j]):
                    if vec[c] != 0.0:
                        load_dof.append(int(d))
                        load_coef.append(float(vec[c]))
                        load_sig.append(k)
            if f_exc is None and sig.amplitude and sig.frequency:
                f_exc = sig.frequency
    M = system.mass
    d = opts.damping
    C = system.linear_damping
    if d.rayleigh_mass or d.rayleigh_stiffness:
        K0 = system.tangent_on_joints(static.q)
        ray = d.rayleigh_mass * M + d.rayleigh_stiffness * K0
        C = ray if C is None else C + ray
    q_ref = system.expand(static.q)
    K_lin = system.linear_matrix()
    preload = np.zeros(n)
    preload[: system.n_dof] = static.spring_preload
    constant = preload + system.external_force(1.0) - np.asarray(K_lin @ q_ref).ravel()
    if system.linear_offset is not None:  # the components' force is K q - offset
        constant = constant + system.linear_offset
    # the components' damping of the nominal belt travel (a pulley's rotational_damping): -C u_nom c(t) at the
    # travel's speed c(t) when a prescribed rotation carries it, in place of the static's -C v_run at the
    # constant running speed (`System.running_damping_force`, in external_force); otherwise that constant stays
    nominal_damping = np.zeros(n)
    if nom_scale and system.linear_damping is not None:
        constant = constant + system.running_damping_force()
        nominal_damping = np.asarray(system.linear_damping @ u_nom, dtype=float).ravel()
    tab = system.belt.kernel_tables
    belt = system.belt
    springs = spring_data(system.springs, d.belt_axial)
    belt_data = itg.BeltData(
        e0=belt.e0, T=belt.T, idx=belt.idx, tsel=belt.tsel, dS=tab.dS, d2S=tab.d2S, wEA=tab.wEA, wEI=tab.wEI,
        EA=tab.EA, Kb=tab.Kb, curvature=int(tab.curvature), eta_a=float(d.belt_axial), eta_b=float(d.belt_bending),
        elem_span=belt.elem_span.astype(np.int64), n_span=int(belt.n_span),
        springs=springs, n_springs=int(springs.L.shape[0]))
    assert CURVATURE_CODE[belt.elements.curvature] == tab.curvature
    linear = itg.Linear(K=itg.split(K_lin, n), q_ref=q_ref, C=itg.split(C, n), M=itg.split(M, n))
    forcing = itg.Forcing(
        constant=constant, load_dof=np.array(load_dof, dtype=np.int64), load_coef=np.array(load_coef, dtype=float),
        load_sig=np.array(load_sig, dtype=np.int64), sig_params=np.array(params, dtype=float).reshape(-1, 5),
        tab_ptr=np.array(ptr, dtype=np.int64), tab_t=np.array(tabs_t, dtype=float),
        tab_v=np.array(tabs_v, dtype=float), nominal_mass=np.asarray(M @ u_nom).ravel().astype(float),
        nominal_rotation=nom_rot, nominal_scale=float(nom_scale), nominal_damping=nominal_damping)
    constraints = itg.Constraints(dof=np.array(cons_dof, dtype=np.int64),
                                  params=np.array(cons_par, dtype=float).reshape(-1, 10))
    transport = itg.no_transport(n)
    if opts.transport and (nom_scale or system.belt_speed):  # the running belt (module docstring)
        A, B, a0, b0 = system.transport_matrices()
        transport = itg.Transport(A=itg.to_csr(A), G=itg.to_csr(A - A.T), B=itg.to_csr(B), a0=a0.astype(float),
                                  b0=b0.astype(float), speed=0.0 if nom_scale else float(system.belt_speed),
                                  follow=1 if nom_scale else 0, mag=itg.fused(M, A, A - A.T, B))
        if nom_scale:  # the belt's axial inertia is c' (A q + a0): only the pulleys' stays a nominal load
            springs = system.springs  # (the spring spans' lumped masses are belt too)
            belt_mass = system.assemble(belt.reduce_blocks(belt.elements.mass), linear=False,
                                        springs=None if springs is None else springs.mass_blocks())
            forcing = forcing._replace(nominal_mass=np.asarray((M - belt_mass) @ u_nom).ravel().astype(float))
    perm, bandwidth = band_order(system)
    q0 = q_ref.copy() if opts.start == "static" else np.zeros(n)
    series, coords = _series(system, opts, cons_dof)
    return TransientSetup(series=series, coords=coords, belt=belt_data, linear=linear, forcing=forcing,
                          constraints=constraints, groups=system.dof_groups.astype(np.int64), C=C, perm=perm,
                          bandwidth=bandwidth, q0=q0, v0=np.zeros(n), u_nom=u_nom, nom_scale=nom_scale,
                          excitation_frequency=f_exc, preload=preload, transport=transport)


def nominal_rotation(setup: TransientSetup, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nominal angle (rad), speed and acceleration of the prescribed rotation at the times t (B,),
    times the belt-travel scale `nom_scale` (m, m/s, m/s^2 of belt): `forcing_laws.rotation_state`'s
    nominal part vectorized, a linear ramp of the speed from Omega_0 to Omega over T_r."""
    om, ramp_time = float(setup.forcing.nominal_rotation[0]), float(setup.forcing.nominal_rotation[1])
    om0 = float(setup.forcing.nominal_rotation[9])
    t = np.asarray(t, dtype=float)
    ramp = (t < ramp_time) if ramp_time > 0.0 else np.zeros(t.shape, dtype=bool)
    per = 1.0 / ramp_time if ramp_time > 0.0 else 0.0
    th = np.where(ramp, om0 * t + 0.5 * (om - om0) * t * t * per, om * (t - 0.5 * ramp_time) + 0.5 * om0 * ramp_time)
    thd = np.where(ramp, om0 + (om - om0) * t * per, om)
    thdd = np.where(ramp, (om - om0) * per, 0.0)
    return th * setup.nom_scale, thd * setup.nom_scale, thdd * setup.nom_scale


def transport_speed(setup: TransientSetup, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The belt speed c (m/s) and its rate c' (m/s^2) at the times t (B,) of a run (`integrator.Transport`)."""
    tr = setup.transport
    t = np.asarray(t, dtype=float)
    if tr is None or not tr.follow:
        return np.full(t.shape, 0.0 if tr is None else float(tr.speed)), np.zeros(t.shape)
    return nominal_rotation(setup, t)[1:]


def _series(system: System, opts: TransientOptions, cons_dof: list[int]):
    lay = system.layout
    rec = opts.record
    coords = {"pulley": list(lay.names), "span": [lay.span_name(i) for i in range(lay.n)], "end": ["start", "end"],
              "component": ["x", "y"]}
    out = []
    if rec.pulley_angles:
        out.append(Series(name="pulley_angle", dims=("pulley",), units="rad",
                          description="pulley rotation, counter-clockwise (nominal belt travel included)"))
    if rec.pulley_speeds:
        out.append(Series(name="pulley_speed", dims=("pulley",), units="rad/s"))
    if rec.span_tension:
        out.append(Series(name="span_tension", dims=("span", "end"), units="N",
                          description="axial force at the span ends from the joint reactions (belt damping included)"))
    if rec.hub_load:
        out.append(Series(name="hub_load", dims=("pulley", "component"), units="N",
                          description="force of the belt on each pulley (span-end inertia and belt damping included)"))
    if rec.bearing_force:
        for c in system.components:
            for obs in c.observations(system):
                if obs.name == "bearing_force":
                    coords["bearing"] = list(c.pulley_names)
                out.append(Series(name=obs.name, dims=obs.dims, units=obs.units, description=obs.description))
    found = decouplers_of(system.components)
    if found:  # the decouplers' rotors and torques, on an axis of their pulleys' names
        coords["decoupler"] = [c.pulley_name for c in found]
        out.append(Series(name="rotor_speed", dims=("decoupler",), units="rad/s",
                          description="speed of the decoupler's rotor, counter-clockwise (nominal travel included)"))
        out.append(Series(name="decoupler_torque", dims=("decoupler",), units="N m",
                          description="torque the decoupler transmits from the hub to the rotor (spring and damper "
                                      "through the one-way clutch: never below -drag, 0 N m, while it overruns)"))
    if system.arms is not None:
        coords["arm"] = list(system.arms.names)
        out.append(Series(name="arm_angle", dims=("arm",), units="rad",
                          description="tensioner arm angle, counter-clockwise from +x"))
        out.append(Series(name="arm_speed", dims=("arm",), units="rad/s", description="tensioner arm angular speed"))
    if rec.span_tension and system.pulley_friction is not None and not np.all(np.isnan(system.pulley_friction)):
        out.append(Series(name="slip_margin", dims=("pulley",), units="1",
                          description="friction / (ln(T_tight / T_slack) / wrap) on the loaded wrap (< 1: slips; "
                                      "NaN: no friction given)"))
    if len(slipping_pulleys(system)):  # the wraps that may slip (NaN on the others)
        if rec.span_tension:
            out.append(Series(name="slip_arc", dims=("pulley",), units="rad",
                              description="capstan slip arc |ln((T_e - c)/(T_x - c))| / mu of the wrap's end tensions "
                                          "(> wrap: the wrap slides; docs/wraps.md)"))
        out.append(Series(name="slip_speed", dims=("pulley",), units="rad/s",
                          description="speed of the belt on the wrap over the pulley's, psi' - theta' (0 sticking "
                                      "but for the bristle's elastic part)"))
        out.append(Series(name="wrap_torque", dims=("pulley",), units="N m",
                          description="torque the belt transmits to the pulley through its wrap (the bristle's)"))
        out.append(Series(name="wrap_sliding", dims=("pulley",), units="1",
                          description="1 while the wrap slides at its capstan torque, 0 while it sticks"))
        out.append(Series(name="rim_speed_ratio", dims=("pulley",), units="1",
                          description="the creep law's rim speed over the driver's, lambda(T_e) / lambda(T_e,driver) "
                                      "of the entry stretches (1 on the driver and without a prescribed speed)"))
        out.append(Series(name="creep_power", dims=("pulley",), units="W",
                          description="power the wrap's creep dissipates, wrap_torque x creep rate (the pulley "
                                      "turning behind its wrap at the rim speed ratio while it sticks)"))
    if rec.midspan_displacement:
        out.append(Series(name="midspan_displacement", dims=("span",), units="m",
                          description="mid-span displacement from the chord between the span's current end points, "
                                      "along the chord's normal z x t"))
    if rec.energy:
        coords["energy_term"] = list(ENERGY_TERMS)
        out.append(Series(name="energy", dims=("energy_term",), units="J",
                          description="kinetic + strain - work + dissipated - initial = balance error, evaluated "
                                      "at the end of the step that contains the output time (springs measured "
                                      "from the static state; the running belt's centripetal potential in strain, "
                                      "the drive's work on its transport in work)"))
    if cons_dof:
        out.append(Series(name="driver_torque", dims=(), units="N m",
                          description="torque the first prescribed rotation applies to its pulley"))
        if len(cons_dof) > 1:
            coords["constraint"] = [system.dof_labels[d] for d in cons_dof]
            out.append(Series(name="constraint_reaction", dims=("constraint",), units="N m",
                              description="generalized force each prescribed rotation applies"))
    if rec.full_state:
        coords["dof"] = list(system.dof_labels)
        out.append(Series(name="q", dims=("dof",), units="mixed (see dof_unit)",
                          description="independent coordinates from the reference state, each in its dof_unit"))
        out.append(Series(name="v", dims=("dof",), units="mixed (see dof_unit, per s)",
                          description="their time derivatives, each in its dof_unit per s"))
    return tuple(out), coords
