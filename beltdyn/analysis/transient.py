"""Transient analysis: a `System` integrated in time from its static equilibrium.

`prepare` lowers the system and the transient options into the stepper's named structures (see
`integrator`): the belt kernel data, the components' constant matrices (stiffness about the static
state, damping, mass), the forcing (constant part, loads as signals on DOFs, inertia of the nominal
belt travel) and the constraints (prescribed rotations, any number). `drive` runs the compiled
stepper chunk by chunk, refactorizes the iteration matrix when Newton slows down, halves the step
when it fails, and hands batches of output samples to a sink; the recorded quantities come from
observers (the belt, the pulleys, the components' own series, the constraints' reactions), vectorized
over each batch.

Belt travel. A prescribed pulley rotation theta(t) = nominal (speed ramp) + fluctuation is split:
the fluctuation is the prescribed value of the pulley's rotation DOF; the nominal part turns the pulleys
(their inertia: -M_pulleys u_nom s''(t), u_nom the belt-travel vector, pulley rotations 1/R) and makes
the belt's material flow through the spans, which stay fixed in space between their tangent points
(Eulerian/ALE, see `running`): the belt speed c(t) = s'(t) = theta_nominal'(t) / u_rot enters through
the spans' transport terms, gyroscopic c G q', centripetal -c^2 (B q + b0) and the axial inertia
c' (A q + a0) (`integrator.Transport`). Without a prescribed speed the belt runs at the system's
constant belt speed ([running]). transient.transport = false keeps the former travelling-frame
approximation instead (the belt's nominal inertia -M_belt u_nom s'' only, no gyroscopic or centripetal
term); on the bench it shifts the first transverse span frequency by the factor 1 - rho c^2 / T that
the moving-string closed form gives (-6 % at 10 m/s), see tests/test_running.py.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from beltdyn.config import TransientOptions
from beltdyn.errors import SolverError
from beltdyn.analysis.static import StaticResult
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


@dataclass(frozen=True, kw_only=True)
class TransientSummary:
    """What the run did (the histories went to the sink)."""

    status: str  # complete | failed | interrupted
    steps: int
    refactorizations: int
    step_halvings: int
    final_time: float
    min_step: float
    slack_events: np.ndarray  # (k, 4): time, span index, 1 slack / 0 taut again, min 2nd PK force (N)
    message: str = ""
    n_outputs: int = 0
    energy_error: float = 0.0  # max |balance error| at the steps / energy moved in the run
    energy_moved: float = 0.0  # J, max of |d kinetic| + |d strain|, |work|, |dissipated|
    warnings: tuple[str, ...] = ()  # accuracy warnings (see `accuracy_warnings`) and slip
    worst_slip_margin: tuple[float, float, str] = (np.inf, np.nan, "")  # smallest slip margin, time, pulley
    newton_iterations: int = 0  # corrections (iteration-matrix solves) of the accepted steps


ENERGY_LIMIT = 0.01  # energy-balance error, as a share of the energy moved, above which a run fails (SolverError)


def accuracy_warnings(opts: TransientOptions, *, energy_error: float, excitation_frequency: float | None,
                      min_step: float) -> tuple[str, ...]:
    """What makes a finished run's numbers doubtful (an energy-balance error above ENERGY_LIMIT is
    not a warning: the run fails, see `run_transient`): a step longer than a tenth of the excitation period, an output interval below the step
    (samples between steps are interpolated, not computed)."""
    out = []
    from beltdyn.analysis.timestep import step_warnings

    out += step_warnings(opts.step, excitation_frequency=excitation_frequency)
    if opts.accuracy is not None and opts.fmax is not None:
        from beltdyn.analysis.timestep import frequency_error

        e = frequency_error(opts.fmax, opts.step, opts.rho_inf)
        if not abs(e) <= opts.accuracy * (1.0 + 1e-9):
            out.append(f"the step {opts.step:g} s misses transient.accuracy = {opts.accuracy:g} at transient.fmax = "
                       f"{opts.fmax:g} Hz (frequency error {e:+.3g}); leave out --step to get a step that meets it")
    if opts.output_interval < opts.step:
        out.append(f"transient.output_interval {opts.output_interval:g} s is below the step {opts.step:g} s: "
                   f"samples between steps are interpolated, not computed")
    return tuple(out)


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
    u = np.zeros(system.n_p)
    lay = system.layout
    for j in range(lay.n):
        n_out = lay.start_normal[j]
        t = lay.span_direction[j]
        u[system.rot_dof[j]] = float(np.array([-n_out[1], n_out[0]]) @ t) / lay.radius[j]
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


def stepper_arms(system: System):
    """integrator.Arms of the system (no arms: the identity map)."""
    from beltdyn.analysis import integrator as itg

    a = system.arms
    if a is None:
        return itg.no_arms(system.n_dof)
    fric = a.friction if a.friction is not None else np.zeros(len(a.dof))
    return itg.Arms(dof=a.dof.astype(np.int64), slot=a.slot.astype(np.int64), length=a.length.astype(float),
                    angle=a.angle.astype(float), friction=fric,
                    bristle=np.where(fric > 0, fric / itg.ARM_PRESLIDING, 1.0),
                    anchor=np.zeros(len(a.dof)),  # the bristles relaxed at the start (set from q0 by `drive`)
                    n_q=int(system.n_dof))


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


def prepare(system: System, static: StaticResult, opts: TransientOptions) -> TransientSetup:
    """The stepper's structures for the run: only the loads, damping and outputs the options ask for."""
    from beltdyn.analysis import integrator as itg
    from beltdyn.model.belt_kernel import CURVATURE_CODE
    from beltdyn.model.spring_kernel import spring_data

    n = system.n_p
    u_nom = belt_travel(system)
    # constraints: prescribed rotations (any number); the first with a speed carries the belt travel
    cons_dof, cons_par = [], []
    nom_rot, nom_scale, f_exc = np.zeros(9), 0.0, None
    for r in opts.rotation:
        d = int(system.rot_dof[system.pulley_index(r.pulley)])
        par = np.array([r.speed, r.ramp_time, r.amplitude, r.speed_amplitude, r.frequency, r.phase, r.fluctuation_ramp,
                        static.q[d] if opts.start == "static" else 0.0, r.order])
        cons_dof.append(d)
        cons_par.append(par)
        if r.speed != 0.0 and nom_scale == 0.0:
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
                load_dof.append(int(system.rot_dof[j]))
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
    tab = system.belt.kernel_tables
    belt = system.belt
    belt_data = itg.BeltData(
        e0=belt.e0, T=belt.T, idx=belt.idx, tsel=belt.tsel, dS=tab.dS, d2S=tab.d2S, wEA=tab.wEA, wEI=tab.wEI,
        EA=tab.EA, Kb=tab.Kb, curvature=int(tab.curvature), eta_a=float(d.belt_axial), eta_b=float(d.belt_bending),
        elem_span=belt.elem_span.astype(np.int64), n_span=int(belt.n_span),
        springs=spring_data(system.springs, d.belt_axial))
    assert CURVATURE_CODE[belt.elements.curvature] == tab.curvature
    linear = itg.Linear(K=itg.split(K_lin, n), q_ref=q_ref, C=itg.split(C, n), M=itg.split(M, n))
    forcing = itg.Forcing(
        constant=constant, load_dof=np.array(load_dof, dtype=np.int64), load_coef=np.array(load_coef, dtype=float),
        load_sig=np.array(load_sig, dtype=np.int64), sig_params=np.array(params, dtype=float).reshape(-1, 5),
        tab_ptr=np.array(ptr, dtype=np.int64), tab_t=np.array(tabs_t, dtype=float),
        tab_v=np.array(tabs_v, dtype=float), nominal_mass=np.asarray(M @ u_nom).ravel().astype(float),
        nominal_rotation=nom_rot, nominal_scale=float(nom_scale))
    constraints = itg.Constraints(dof=np.array(cons_dof, dtype=np.int64),
                                  params=np.array(cons_par, dtype=float).reshape(-1, 9))
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
    times the belt-travel scale `nom_scale` (m, m/s, m/s^2 of belt): `integrator.rotation_state`'s
    nominal part vectorized, a linear ramp of the speed to Omega over T_r."""
    om, ramp_time = float(setup.forcing.nominal_rotation[0]), float(setup.forcing.nominal_rotation[1])
    t = np.asarray(t, dtype=float)
    ramp = (t < ramp_time) if ramp_time > 0.0 else np.zeros(t.shape, dtype=bool)
    per = 1.0 / ramp_time if ramp_time > 0.0 else 0.0
    th = np.where(ramp, 0.5 * om * t * t * per, om * (t - 0.5 * ramp_time))
    thd = np.where(ramp, om * t * per, om)
    thdd = np.where(ramp, om * per, 0.0)
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
    if system.arms is not None:
        coords["arm"] = list(system.arms.names)
        out.append(Series(name="arm_angle", dims=("arm",), units="rad",
                          description="tensioner arm angle, counter-clockwise from +x"))
        out.append(Series(name="arm_speed", dims=("arm",), units="rad/s", description="tensioner arm angular speed"))
    if rec.span_tension and system.pulley_friction is not None and not np.all(np.isnan(system.pulley_friction)):
        out.append(Series(name="slip_margin", dims=("pulley",), units="1",
                          description="friction / (ln(T_tight / T_slack) / wrap) on the loaded wrap (< 1: slips; "
                                      "NaN: no friction given)"))
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


# ------------------------------------------------------------------------------------ iteration matrix
def band_factor(S, perm: np.ndarray, u: int, *, symmetric: bool, hold: np.ndarray | None = None,
                diagonal: np.ndarray | None = None):
    """Factor S (dense or sparse; + `diagonal` (n,) if given) in RCM order with the DOFs `hold` held
    (their rows and columns replaced by the identity): band Cholesky when symmetric positive definite,
    else band LU without row exchanges (`integrator.band_lu_nopivot`: the running belt's S, whose
    symmetric part is positive definite; its U has u superdiagonals, half of what partial pivoting
    leaves, so each Newton solve costs a third less), and band LU with partial pivoting (LAPACK
    dgbtrf) when a pivot is not positive. Returns an integrator.Factor."""
    from scipy.linalg import cholesky_banded
    from scipy.linalg.lapack import dgbtrf
    from scipy.sparse import issparse

    from beltdyn.analysis.integrator import Factor

    n = S.shape[0]
    if issparse(S):
        C = S.tocoo()
        row, col, val = C.row, C.col, C.data
    else:
        row, col = np.nonzero(np.asarray(S))
        val = np.asarray(S)[row, col]
    if hold is not None and len(hold):
        held = np.zeros(n, dtype=bool)
        held[hold] = True
        keep = ~(held[row] | held[col])
        h_ = np.asarray(hold, dtype=row.dtype)
        row, col = np.concatenate([row[keep], h_]), np.concatenate([col[keep], h_])
        val = np.concatenate([val[keep], np.ones(len(h_))])
    inv = np.empty(n, dtype=np.int64)
    inv[perm] = np.arange(n)
    r, c = inv[row], inv[col]  # positions in RCM order (each (row, col) once: a CSR's or a dense array's entries)
    d = None
    if diagonal is not None:
        d = np.flatnonzero(diagonal if hold is None else np.where(np.isin(np.arange(n), hold), 0.0, diagonal))
    none = np.zeros(1, dtype=np.int64)
    if symmetric:
        ab = np.zeros((u + 1, n))
        mask = r <= c
        ab[u + r[mask] - c[mask], c[mask]] = val[mask]
        if d is not None:
            ab[u, inv[d]] += diagonal[d]
        try:
            return Factor(kind=0, ab=np.asfortranarray(cholesky_banded(ab, lower=False, check_finite=False)),
                          piv=none, perm=perm, kl=0, ku=u)
        except np.linalg.LinAlgError:
            pass
    from beltdyn.analysis.integrator import band_lu_nopivot

    ab = np.zeros((2 * u + 1, n), order="F")  # without row exchanges: U keeps the band (module docstring)
    ab[u + r - c, c] = val
    if d is not None:
        ab[u, inv[d]] += diagonal[d]
    if band_lu_nopivot(ab, u) == n:
        return Factor(kind=2, ab=ab, piv=none, perm=perm, kl=u, ku=u)
    ab = np.zeros((3 * u + 1, n))  # a pivot not positive: partial pivoting (its U has 2u superdiagonals)
    ab[2 * u + r - c, c] = val
    if d is not None:
        ab[2 * u, inv[d]] += diagonal[d]
    lu, piv, info = dgbtrf(ab, u, u, overwrite_ab=True)
    if info > 0:
        raise np.linalg.LinAlgError(f"singular iteration matrix (pivot {info})")
    # both factors column-major (the solves run down the columns), so the stepper has one signature
    return Factor(kind=1, ab=np.asfortranarray(lu), piv=piv.astype(np.int64), perm=perm, kl=u, ku=u)


def _belt_damping_matrix(system: System, setup: TransientSetup, q: np.ndarray, p: np.ndarray):
    """The belt's Kelvin-Voigt damping matrix dN_d/dq' at q (p = system.expand(q)) on the system's pattern,
    from the compiled element kernel; None without belt damping."""
    from beltdyn.model import belt_kernel as bk

    b = setup.belt
    if not (b.eta_a or b.eta_b):
        return None
    E = system.belt.element_coordinates(p)
    Ce = np.empty((E.shape[0], 8, 8))
    bk.element_damping_matrix(E, b.dS, b.d2S, b.wEA, b.wEI, b.Kb, b.curvature, b.eta_a, b.eta_b, Ce,
                              system.belt.kernel_scratch())
    return system.belt_damping_matrix(q, Ce)


def _iteration_matrix(system: System, setup: TransientSetup, q: np.ndarray, h: float, rho_inf: float,
                      v: np.ndarray | None = None, arms=None, t: float = 0.0):
    """S = c_m M + c_c (C + C_belt(q) + c G) + (1 - alpha_f) (K_t(q) - c^2 B + c' A) on q (prescribed DOFs
    are held by `band_factor`); c, c' the belt speed and its rate at t (no transport terms at rest).
    The terms are summed on the joint coordinates p, where they share the system's pattern (their data
    added), and projected once: J^T S_p J with the arms' geometric term of (1 - alpha_f) times the loaded
    internal force (as `System.equilibrium`). Returns (S, diagonal): the arms' sticking bristles k_b as a
    diagonal (n_dof,) to add, or None."""
    from beltdyn.analysis.integrator import alpha_parameters

    am, af, beta, gamma = alpha_parameters(rho_inf)
    c_m = (1.0 - am) / (beta * h * h)
    c_c = (1.0 - af) * gamma / (beta * h)
    q = q[: system.n_dof]  # the stepper's state is on the joint coordinates: q is its head
    at_rest = system.with_speed(0.0) if system.belt_speed else system  # the transport terms: below, at t
    p = system.expand(q)
    f, K = at_rest.belt_force_and_tangent(p)  # + the components' constant stiffness
    terms = [((1.0 - af), K), (c_m, system.mass)]
    tr = setup.transport
    if tr is not None and (tr.follow or tr.speed):
        c, cd = (float(x[0]) for x in transport_speed(setup, np.array([t])))
        A, B, _, _ = system.transport_matrices()
        G = system.__dict__.get("_gyroscopic_unit")
        if G is None:
            G = A - A.T
            object.__setattr__(system, "_gyroscopic_unit", G)
        terms += [(c_c * c, G), ((1.0 - af) * cd, A), (-(1.0 - af) * c * c, B)]
    C_belt = _belt_damping_matrix(system, setup, q, p)
    if C_belt is not None:
        terms.append((c_c, C_belt))
    if setup.C is not None:
        terms.append((c_c, setup.C))
    S = _weighted_sum(terms)
    if system.arms is not None:
        f_loaded = f + system.linear_force(p) - system.external_force(1.0)
        S = system.arms.project_matrix(q, S, (1.0 - af) * f_loaded, dense=system.dense)
    diagonal = None
    if arms is not None and np.any(arms.friction):  # a sticking bristle is a spring k_b on the arm angle
        e = q[arms.dof] - arms.anchor
        diagonal = np.zeros(system.n_dof)
        diagonal[arms.dof] = (1.0 - af) * np.where(np.abs(arms.bristle * e) < arms.friction, arms.bristle, 0.0)
    return S, diagonal


def stepper_system(system: System, opts: TransientOptions) -> System:
    """The system the stepper evaluates: the compiled belt kernel (thousands of evaluations, see
    system.BeltSpans) with the run's belt damping."""
    return system.with_belt(damping_axial=float(opts.damping.belt_axial),
                            damping_bending=float(opts.damping.belt_bending), compiled=True)


def factorizer(system: System, setup: TransientSetup, rho_inf: float, arms, *, plan: bool = True) -> Callable:
    """factor(q, h, v=None, t=0.0) -> integrator.Factor of the iteration matrix at the state q for the
    step h at time t: by the run's `IterationPlan` where it applies (plan=True), else (or when its
    factorization needs row exchanges) `band_factor` of `_iteration_matrix`. `system` as
    `stepper_system` gives it."""
    tr = setup.transport
    symmetric = tr is None or not (tr.follow or tr.speed)  # the gyroscopic term makes S non-symmetric: band LU
    fast = IterationPlan.build(system, setup, rho_inf, arms, symmetric=symmetric) if plan else None

    def factor(q, h, v=None, t=0.0):
        got = fast.factor(q, h, t) if fast is not None else None
        if got is not None:
            return got
        S, diagonal = _iteration_matrix(system, setup, q, h, rho_inf, v, arms, t)
        return band_factor(S, setup.perm, setup.bandwidth, symmetric=symmetric, hold=setup.constraints.dof,
                           diagonal=diagonal)

    factor.plan = fast
    return factor


@dataclass(frozen=True, kw_only=True)
class IterationPlan:
    """`_iteration_matrix` + `band_factor` for one run, assembled straight into band storage.

    Every term of S lives on the system's joint pattern (CSR slots, `system.Pattern`): the belt's
    tangent (and damping) through their assembly, the constant matrices (mass, components' damping,
    the running belt's A, G = A - A^T, B) mapped onto it once. Each pattern entry (i, j) has, once for
    the run, its place in the band of S on q: the arms' offsets folded onto their angle, the order
    `perm`, the held DOFs' rows and columns dropped. A factorization then sums the terms' data with
    their weights, scales the arm rows and columns by dc/dphi, and scatters them into the band in
    one pass (numpy), instead of summing, projecting and converting scipy matrices: ~0.15 instead of
    ~0.55 ms on the FEAD example, so the refresh rule (`integrator.run_steps`) affords more factors
    and the Newton iterations fewer. Same matrix (summed in another order: round-off).
    `build` returns None where it does not apply (a dense system, a matrix off the pattern, an entry
    outside the band): `band_factor(_iteration_matrix(...))` then."""

    system: System  # as `stepper_system` gives it
    at_rest: System  # the same without the belt speed (the transport terms are added at their time)
    setup: TransientSetup
    arms: tuple  # integrator.Arms (their bristles' anchors: the state of the run)
    symmetric: bool  # band Cholesky (upper, u + 1 rows), else LU without row exchanges (2 u + 1 rows)
    n: int  # DOFs of q
    u: int  # half-bandwidth
    height: int  # rows of the band storage
    const: dict  # name -> (nnz,) data on the joint pattern: M, C (and A, G, B when the belt runs)
    moving: bool  # the transport terms are in
    entries: np.ndarray  # (k,) the pattern entries that go into the band (held rows/columns out)
    flat: np.ndarray  # (k,) their places in the band storage, column-major, flattened
    rows_p: np.ndarray  # (nnz,) row of each pattern entry (joint coordinates)
    cols_p: np.ndarray  # (nnz,) its column
    diag: np.ndarray  # (n,) the flat place of each q's diagonal
    held: np.ndarray  # (h,) the held (prescribed) DOFs: identity
    alpha: tuple  # (alpha_m, alpha_f, beta, gamma)

    @classmethod
    def build(cls, system: System, setup: TransientSetup, rho_inf: float, arms, *, symmetric: bool):
        from scipy.sparse import coo_matrix

        pat = system.pattern
        if system.dense or pat.indptr is None:
            return None
        n_p, n = system.n_p, system.n_dof
        nnz = pat.nnz
        rows_p = np.repeat(np.arange(n_p, dtype=np.int64), np.diff(pat.indptr))
        cols_p = np.asarray(pat.indices, dtype=np.int64)
        keys = rows_p * (n_p + 1) + cols_p

        def on_pattern(A):
            """A's entries as data on the pattern (None if one lies off it)."""
            if A is None:
                return np.zeros(nnz)
            C = coo_matrix(A)
            C.sum_duplicates()
            live = C.data != 0.0
            r, c, v = C.row[live].astype(np.int64), C.col[live].astype(np.int64), C.data[live]
            where = pat.slots_of(r, c)
            if np.any(where >= nnz) or not np.array_equal(keys[np.minimum(where, nnz - 1)], r * (n_p + 1) + c):
                return None
            out = np.zeros(nnz)
            np.add.at(out, where, v)
            return out

        at_rest = system.with_speed(0.0) if system.belt_speed else system
        const = {"M": on_pattern(system.mass), "C": on_pattern(setup.C)}
        tr = setup.transport
        moving = tr is not None and bool(tr.follow or tr.speed)
        if moving:
            A, B, _, _ = system.transport_matrices()
            const.update(A=on_pattern(A), G=on_pattern(A - A.T), B=on_pattern(B))
        if any(v is None for v in const.values()):
            return None
        to_q = p_to_q(system)
        inv = np.empty(n, dtype=np.int64)
        inv[setup.perm] = np.arange(n)
        u = setup.bandwidth
        held = np.zeros(n, dtype=bool)
        held[setup.constraints.dof] = True
        r, c = inv[to_q[rows_p]], inv[to_q[cols_p]]
        keep = ~held[to_q[rows_p]] & ~held[to_q[cols_p]]
        if np.abs(r - c)[keep].max(initial=0) > u:
            return None
        height = u + 1 if symmetric else 2 * u + 1  # upper Cholesky band, or LU without row exchanges
        if symmetric:
            keep &= r <= c
        diag = inv * height + u  # the flat place of each q's diagonal
        from beltdyn.analysis.timestep import alpha_parameters

        return cls(system=system, at_rest=at_rest, setup=setup, arms=arms, symmetric=symmetric, n=n, u=u,
                   height=height, const=const, moving=moving, entries=np.flatnonzero(keep),
                   flat=(c * height + u + r - c)[keep], rows_p=rows_p, cols_p=cols_p, diag=diag,
                   held=np.asarray(setup.constraints.dof, dtype=np.int64), alpha=alpha_parameters(rho_inf))

    def factor(self, q: np.ndarray, h: float, t: float = 0.0):
        """The integrator.Factor of S at the state q (n_dof,) for the step h at time t."""
        from beltdyn.analysis.integrator import Factor, band_lu_nopivot

        am, af, beta, gamma = self.alpha
        c_m = (1.0 - am) / (beta * h * h)
        c_c = (1.0 - af) * gamma / (beta * h)
        system, setup, k = self.system, self.setup, self.const
        q = q[: self.n]
        p = system.expand(q)
        f, K = self.at_rest.belt_force_and_tangent(p)  # on the pattern (+ the components' constant stiffness)
        if len(K.data) != len(k["M"]):
            raise AssertionError("the belt's tangent is off the joint pattern")
        data = (1.0 - af) * K.data + c_m * k["M"] + c_c * k["C"]
        if self.moving:
            c, cd = (float(x[0]) for x in transport_speed(setup, np.array([t])))
            data += (c_c * c) * k["G"] + ((1.0 - af) * cd) * k["A"] - ((1.0 - af) * c * c) * k["B"]
        C_belt = _belt_damping_matrix(system, setup, q, p)
        if C_belt is not None:
            data += c_c * C_belt.data
        arms, a = self.arms, system.arms
        if a is not None:  # J^T S J: the arm offsets' rows and columns scaled by dc/dphi, folded onto the angle
            phi = a.phi(q)
            w = np.ones(system.n_p)
            dc = a.first(phi)
            w[a.slot], w[a.slot + 1] = dc[:, 0], dc[:, 1]
            data = data * w[self.rows_p] * w[self.cols_p]
        ab = np.bincount(self.flat, weights=data[self.entries], minlength=self.height * self.n)
        if a is not None:
            f_loaded = f + system.linear_force(p) - system.external_force(1.0)
            geo = np.einsum("kd,kd->k", a.second(phi), f_loaded[a.n_q:].reshape(len(a.dof), 2))
            np.add.at(ab, self.diag[a.dof], (1.0 - af) * geo)  # the geometric term of the loaded force
            if np.any(arms.friction):  # a sticking bristle is a spring k_b on the arm angle
                e = q[arms.dof] - arms.anchor
                np.add.at(ab, self.diag[arms.dof],
                          (1.0 - af) * np.where(np.abs(arms.bristle * e) < arms.friction, arms.bristle, 0.0))
        ab[self.diag[self.held]] = 1.0  # held DOFs: identity
        ab = ab.reshape(self.n, self.height).T  # (height, n), column-major
        perm, none, u = setup.perm, np.zeros(1, dtype=np.int64), self.u
        if self.symmetric:
            from scipy.linalg import cholesky_banded

            try:
                return Factor(kind=0, ab=np.asfortranarray(cholesky_banded(ab, lower=False, check_finite=False)),
                              piv=none, perm=perm, kl=0, ku=u)
            except np.linalg.LinAlgError:
                return None
        ab = np.asfortranarray(ab)
        if band_lu_nopivot(ab, u) == self.n:
            return Factor(kind=2, ab=ab, piv=none, perm=perm, kl=u, ku=u)
        return None  # a pivot not positive: `band_factor` (partial pivoting)


def _weighted_sum(terms):
    """sum_k w_k A_k of dense arrays or CSR matrices; CSR ones on one pattern (the same indptr and
    indices, as `System.assemble` gives) by adding their data, others by scipy."""
    first = terms[0][1]
    if not hasattr(first, "tocsr"):
        out = terms[0][0] * np.asarray(first, dtype=float)
        for w, A in terms[1:]:
            out = out + w * (A.toarray() if hasattr(A, "toarray") else np.asarray(A))
        return out
    from scipy.sparse import csr_matrix

    first = csr_matrix(first)
    data = terms[0][0] * first.data
    rest = None
    for w, A in terms[1:]:
        A = csr_matrix(A)
        if A.indptr is first.indptr or (A.nnz == first.nnz and np.array_equal(A.indptr, first.indptr)
                                        and np.array_equal(A.indices, first.indices)):
            data = data + w * A.data
        else:
            rest = w * A if rest is None else rest + w * A
    S = csr_matrix((data, first.indices, first.indptr), shape=first.shape)
    return S if rest is None else S + rest


# ------------------------------------------------------------------------------------ the driver
Sink = Callable[[np.ndarray, dict[str, np.ndarray]], None]
Progress = Callable[[float], None]


@dataclass(frozen=True, kw_only=True)
class StepProblem:
    """What `drive` integrates: the stepper's structures, the initial state and a factor callback
    factor(q, h) -> integrator.Factor. n_span is the number of belt spans (slack events)."""

    belt: tuple
    linear: tuple
    forcing: tuple
    constraints: tuple
    groups: np.ndarray
    q0: np.ndarray
    v0: np.ndarray
    factor: Callable  # factor(q, h, v, t) -> integrator.Factor at the state (q, v) at time t for the step h
    labels: tuple[str, ...]
    arms: tuple | None = None  # integrator.Arms (None: no arms, q = p)
    transport: tuple | None = None  # integrator.Transport (None: the belt at rest)


def initial_state(problem: StepProblem, step: float, start: Callable):
    """Consistent initial acceleration M a0 = F(0) - C v0 - f(q0, v0) on the free DOFs, and the
    energy reference. start(state): the compiled forces at t = 0 (`integrator.start_forces`, through
    the stepper's entry point `integrator.advance`)."""
    from beltdyn.analysis import integrator as itg

    lin, cons = problem.linear, problem.constraints
    n = len(problem.q0)
    arms = problem.arms if problem.arms is not None else itg.no_arms(n)
    nq = int(arms.n_q)
    scal = np.zeros(itg.N_SCAL)
    scal[itg.H] = step
    state = itg.State(q=problem.q0.copy(), v=problem.v0.copy(), a=np.zeros(n), f0=np.empty(n), fd0=np.empty(n),
                      F0=np.empty(n), R0=np.zeros(max(len(cons.dof), 1)), scal=scal)  # (at least one slot)
    start(state)  # q, v, a of the prescribed DOFs and arms (a: the centripetal part), f0, fd0, F0, energies
    q, v, a, f0, F0 = state.q, state.v, state.a, state.f0, state.F0
    from scipy.sparse import coo_matrix

    Md = itg.split_matrix(lin.M, n).toarray()
    Cv = itg.split_matrix(lin.C, n) @ v
    # J^T (M (J a_q + h) + C v + f - F) = 0 on the free independent DOFs (J = I without arms)
    phi = arms.angle + q[arms.dof]
    J = coo_matrix((np.r_[np.ones(nq), -arms.length * np.sin(phi), arms.length * np.cos(phi)],
                    (np.r_[np.arange(nq), arms.slot, arms.slot + 1], np.r_[np.arange(nq), arms.dof, arms.dof])),
                   shape=(n, nq)).tocsr()
    h = a.copy()
    h[:nq] = 0.0
    Mq = np.asarray((J.T @ (J.T @ Md).T))  # J^T M J (M symmetric)
    rhs = J.T @ (F0 - Cv - f0 - Md @ h) - Mq[:, cons.dof] @ a[cons.dof]
    free = np.setdiff1d(np.arange(nq), cons.dof)
    a[free] = np.linalg.solve(Mq[np.ix_(free, free)], rhs[free])
    itg.complete.py_func(arms, q, v, a)  # (plain Python: a few arms, no compiled entry point to load)
    state.R0[: len(cons.dof)] = (J.T @ (Md @ a + Cv + f0 - F0))[cons.dof]
    return state


def residual_noise(belt) -> float:
    """Round-off of the belt's residual (N): the Green-Lagrange strain (r'.r' - 1)/2 loses ~eps per
    Gauss point, so the axial force loses ~eps EA whatever its size; the linear bending force loses
    ~eps of sum_j |K_b,ij| |e_j|."""
    eps = np.finfo(float).eps
    n_elem = belt.T.shape[0] + belt.springs.D.shape[0]  # elements and spring spans
    if n_elem == 0:
        return 0.0
    bend = float((np.abs(belt.Kb) @ np.abs(belt.e0)[:, :, None]).max(initial=0.0))
    EA = max(float(belt.EA.max(initial=0.0)), float(belt.springs.EA))
    return 100.0 * eps * (EA * math.sqrt(n_elem) + bend)


@dataclass
class _Run:
    """Mutable bookkeeping of one `drive` call."""

    steps: int = 0
    refactors: int = 0
    halvings: int = 0
    delivered: int = 0


HANDOVER_SECONDS = 0.2  # wall time between hand-overs of samples to the sink (and checks for Ctrl-C/SIGTERM)
REFRESH = True  # a new factor once the old one's extra Newton iterations cost more (`integrator.run_steps`)


def drive(problem: StepProblem, *, rho_inf: float, step: float, min_step: float, duration: float,
          output_interval: float, tolerance: float, max_iterations: int, on_batch: Callable,
          progress: Progress | None = None, batch: int = 256, n_span: int = 0):
    """Integrate the problem: outputs in batches to on_batch(t, q, v, a, energy, reaction); returns
    (status, run bookkeeping, final scal, slack events). Raises SolverError when the step cannot be
    reduced further (the batches before the failure have been delivered); KeyboardInterrupt
    propagates after the last complete batch was delivered."""
    from beltdyn.analysis import integrator as itg

    am, af, beta, gamma = itg.alpha_parameters(rho_inf)
    n = len(problem.q0)
    arms = problem.arms if problem.arms is not None else itg.no_arms(n)
    tr = problem.transport if problem.transport is not None else itg.no_transport(n)
    chk = itg.Check(group=problem.groups, n_groups=int(problem.groups.max(initial=0)) + 1, tol=float(tolerance),
                    max_iter=int(max_iterations), noise=residual_noise(problem.belt))
    n_con = max(len(problem.constraints.dof), 1)
    batch = max(batch, int(math.ceil(step / output_interval)) + 2)  # a step's samples always fit
    out = itg.Outputs(t=np.zeros(batch), q=np.zeros((batch, n)), v=np.zeros((batch, n)), a=np.zeros((batch, n)),
                      energy=np.zeros((batch, 5)), reaction=np.zeros((batch, n_con)), n=np.zeros(1, dtype=np.int64))
    ev = itg.Events(data=np.zeros((2000 * max(n_span, 1) + 8, 4)), n=np.zeros(1, dtype=np.int64),
                    slack=np.zeros(max(n_span, 1)))
    all_events: list[np.ndarray] = []
    info = np.zeros(4)
    n_total_out = int(math.floor(duration / output_interval + 1e-9)) + 1
    opts = itg.StepOptions(am=am, af=af, beta=beta, gamma=gamma, t_stop=float(duration), dt_out=float(output_interval),
                           max_steps=2000, refresh=0.0)

    work = itg.workspace(n, problem.belt, problem.forcing, problem.constraints, chk.n_groups, arms)

    model = itg.StepperModel(belt=problem.belt, linear=problem.linear, forcing=problem.forcing,
                             constraints=problem.constraints, check=chk, arms=arms, transport=tr)

    def advance(task, st, fac, fresh):  # the compiled stepper (`integrator.advance`), opts as they are now
        return itg.advance(task, st, model, opts, fac, fresh, out, ev, info, work)

    state = initial_state(problem, step, lambda st: advance(itg.START, st, itg.no_factor(), False))
    th = state.scal
    clock = {"factor": 0.0, "factors": 0, "stepping": 0.0, "iterations": 0.0, "counted": 0.0, "calls": 0}

    def new_factor():
        """The factor at the current state; its wall time feeds the refresh rule (`integrator.run_steps`)."""
        started = time.perf_counter()
        got = problem.factor(state.q, th[itg.H], state.v, th[itg.T_NOW])
        clock["factor"] += time.perf_counter() - started
        clock["factors"] += 1
        return got

    fac = new_factor()
    fresh = True
    run = _Run()
    run.refactors = 1
    min_h = th[itg.H]
    calm = 0

    def drain() -> None:
        k = int(out.n[0])
        take = min(k, n_total_out - run.delivered)
        out.n[0] = 0  # counted as delivered before the sink runs: an interrupt inside it cannot repeat them
        if take > 0:
            run.delivered += take
            on_batch(out.t[:take].copy(), out.q[:take].copy(), out.v[:take].copy(), out.a[:take].copy(),
                     out.energy[:take].copy(), out.reaction[:take].copy())

    def collect_events() -> None:
        if ev.n[0]:
            all_events.append(ev.data[: int(ev.n[0])].copy())
            ev.n[0] = 0

    last_drain = time.perf_counter()
    try:
        while True:
            started, steps_before = time.perf_counter(), th[itg.STEPS]
            code = advance(itg.STEP, state, fac, fresh)
            now = time.perf_counter()
            if th[itg.STEPS] > steps_before:  # the step budget of a call: about HANDOVER_SECONDS of wall time
                per_step = (now - started) / (th[itg.STEPS] - steps_before)
                opts = opts._replace(max_steps=int(min(2000, max(10, HANDOVER_SECONDS / max(per_step, 1e-9)))))
            evaluations = th[itg.ITERS] + th[itg.STEPS]  # residual evaluations: one more than corrections per step
            if clock["calls"]:  # (not the first call: it may have loaded the kernels from numba's cache)
                clock["stepping"] += now - started
                clock["iterations"] += evaluations - clock["counted"]
            clock["counted"], clock["calls"] = evaluations, clock["calls"] + 1
            if REFRESH and clock["iterations"] > 0 and clock["stepping"] > 0.0:  # a factor's cost in evaluations
                opts = opts._replace(refresh=(clock["factor"] / clock["factors"])
                                     / (clock["stepping"] / clock["iterations"]))
            if now - last_drain >= HANDOVER_SECONDS:  # the samples so far reach the sink (the results file)
                drain()
                last_drain = now
            collect_events()
            if th[itg.STEPS] > run.steps:
                fresh = False
            run.steps = int(th[itg.STEPS])
            if progress is not None:
                progress(min(th[itg.T_NOW], duration))
            if code == itg.DONE:
                break
            if code in (itg.BUFFER_FULL, itg.MAX_STEPS):
                if code == itg.BUFFER_FULL:  # (a call's step budget only hands over: the clock above drains)
                    drain()
                if th[itg.H] < step:  # grow the step back after a calm stretch
                    calm += 1
                    if calm >= 2:
                        th[itg.H] = min(2.0 * th[itg.H], step)
                        fac, fresh, calm = new_factor(), True, 0
                        run.refactors += 1
                continue
            if code == itg.REFACTOR:
                fac, fresh, calm = new_factor(), True, 0
                run.refactors += 1
                continue
            # HALVE
            if th[itg.H] / 2.0 < min_step:
                dof = problem.labels[int(info[2])] if int(info[2]) < n else "?"
                drain()
                raise SolverError(
                    f"no convergence at t = {info[0]:.6g} s even with the step reduced to {th[itg.H]:.3g} s "
                    f"(transient.min_step = {min_step:g} s)", analysis="transient", step=f"t = {info[0]:.6g} s",
                    residual=float(info[1]), item=dof)
            th[itg.H] /= 2.0
            min_h = min(min_h, th[itg.H])
            run.halvings += 1
            calm = 0
            fac, fresh = new_factor(), True
            run.refactors += 1
        drain()
    except KeyboardInterrupt:
        drain()
        raise
    ev_all = np.concatenate(all_events) if all_events else np.zeros((0, 4))
    return run, th, min_h, ev_all


def run_transient(system: System, static: StaticResult, opts: TransientOptions, *, sink: Sink,
                  progress: Progress | None = None, setup: TransientSetup | None = None, batch: int | None = None,
                  status: Callable | None = None) -> TransientSummary:
    """Integrate, feeding (time (B,), {series: (B, ...)}) batches to `sink`.

    Raises SolverError (with the failure time, residual and DOF) when the step cannot be reduced
    further; the batches before the failure have been delivered. KeyboardInterrupt propagates after
    the last complete batch was delivered. `status(text)` is told about a first-time kernel compile.
    """
    from beltdyn.analysis import integrator as itg

    if opts.step is None:
        raise ValueError("TransientOptions.step is not set: resolve it from transient.accuracy and fmax first "
                         "(timestep.resolve_step)")
    setup = setup or prepare(system, static, opts)
    if batch is None:  # samples per batch of outputs: ~1.5 MB of states (the observers' cost is per batch)
        batch = int(min(4096, max(256, 65536 // max(len(setup.q0), 1))))
    # the time stepper evaluates the belt thousands of times: the compiled kernel (system.BeltSpans)
    system = stepper_system(system, opts)
    tr = setup.transport
    arms = stepper_arms(system)
    factor = factorizer(system, setup, opts.rho_inf, arms)
    problem = StepProblem(
        belt=setup.belt, linear=setup.linear, forcing=setup.forcing, constraints=setup.constraints,
        groups=setup.groups, q0=setup.q0, v0=setup.v0, labels=system.dof_labels, factor=factor,
        arms=arms, transport=tr)
    observer = Observers(system=system, setup=setup)
    run, th, min_h, events = drive(
        problem, rho_inf=opts.rho_inf, step=opts.step, min_step=opts.min_step, duration=opts.duration,
        output_interval=opts.output_interval, tolerance=opts.tolerance, max_iterations=opts.max_iterations,
        on_batch=lambda *b: sink(b[0], observer.compute(*b)), progress=progress, batch=batch,
        n_span=system.belt.n_span)
    moved = float(th[itg.MOVED])
    error = float(th[itg.WORST]) / moved if moved > 0 else 0.0
    if error > ENERGY_LIMIT:  # every sample has reached the sink: the results so far stay, marked failed
        raise SolverError(f"energy balance error {error:.2e} of the energy moved ({moved:.3g} J) exceeds "
                          f"{ENERGY_LIMIT:.0%}: the step {opts.step:g} s is too long for this run; reduce transient.step",
                          analysis="transient", step=f"t = {float(th[itg.T_NOW]):.6g} s", residual=error)
    return TransientSummary(status="complete", steps=run.steps, refactorizations=run.refactors,
                            step_halvings=run.halvings, final_time=float(th[itg.T_NOW]), min_step=float(min_h),
                            slack_events=events, n_outputs=run.delivered, energy_error=error, energy_moved=moved,
                            warnings=accuracy_warnings(opts, energy_error=error, min_step=float(min_h),
                                                       excitation_frequency=setup.excitation_frequency)
                            + _slip_warning(observer.worst_slip) + _stop_warning(observer.stop_hit)
                            + tension_warnings(system, observer, events, static.mean_tension),
                            worst_slip_margin=observer.worst_slip, newton_iterations=int(th[itg.ITERS]))


def tension_warnings(system: System, observer: "Observers", events: np.ndarray,
                     mean_tension: float) -> tuple[str, ...]:
    """The spans' tension outside the model's validity during the run (the static thresholds,
    result_warnings.SLACK_WARNING and STRAIN_WARNING): a span that went slack (slack events), one that came
    close to slack (its smaller end tension below 10 % of the static mean tension at a sample), and a
    belt strain beyond 5 % at a sample (the last two from the recorded span tensions)."""
    from beltdyn.analysis.result_warnings import SLACK_WARNING, strain_warning

    lay = system.layout
    out = []
    went = set()
    for s_ in np.unique(events[events[:, 2] == 1, 1].astype(int)) if len(events) else ():
        rows = events[(events[:, 1] == s_) & (events[:, 2] == 1)]
        went.add(int(s_))
        out.append(f"span {lay.span_name(int(s_))} went slack {len(rows)} time(s), first at t = {rows[0, 0]:.6g} s "
                   f"(axial force down to {events[events[:, 1] == s_, 3].min():.4g} N): a real belt carries no "
                   f"compression, it flaps and may slip there; raise the tension or lower the excitation")
    scale = abs(float(mean_tension))
    for s_, (t_low, when) in enumerate(zip(observer.tension_low, observer.tension_low_time)):
        if s_ in went or not np.isfinite(t_low):
            continue
        if t_low < 0.0:  # a span in compression is slack, whatever the slack events saw at the steps
            out.append(f"span {lay.span_name(s_)} went slack: its tension reached {t_low:.4g} N at one end at "
                       f"t = {when:.6g} s: a real belt carries no compression, it flaps and may slip there")
        elif t_low < SLACK_WARNING * scale:
            out.append(f"span {lay.span_name(s_)} came close to slack: {t_low:.4g} N at one end at t = {when:.6g} s, "
                       f"{t_low / scale:.1%} of the static mean tension {scale:.4g} N")
    T, when = observer.tension_high
    out += strain_warning(T, float(system.EA), f" at t = {when:.6g} s")
    return tuple(out)


def _stop_warning(hit) -> tuple[str, ...]:
    if hit is None:
        return ()
    t, name, phi = hit
    return (f"the arm of pulley {name} is beyond its stops (arm_range) at t = {t:.6g} s ({phi:.6g} rad): the transient "
            f"does not model the stops, so the results from there on assume a free arm",)


def _slip_warning(worst: tuple[float, float, str]) -> tuple[str, ...]:
    margin, t, name = worst
    if margin < 1.0:
        return (f"pulley {name} slips: slip margin {margin:.3g} < 1 at t = {t:.6g} s",)
    return ()


# ------------------------------------------------------------------------------------ observers
@dataclass
class Observers:
    """The recorded quantities of output states (B, n), vectorized over the batch."""

    system: System
    setup: TransientSetup

    def __post_init__(self) -> None:
        self.names = {s.name for s in self.setup.series}
        self.worst_slip = (np.inf, np.nan, "")  # smallest slip margin, its time and pulley
        n_span = self.system.belt.n_span
        self.tension_low = np.full(n_span, np.inf)  # (n_span,) smallest end tension of each span, N
        self.tension_low_time = np.full(n_span, np.nan)  # (n_span,) s, when
        self.tension_high = (-np.inf, np.nan)  # largest end tension of any span (N) and when (s)
        self.stop_hit: tuple[float, str, float] | None = None  # first time an arm is beyond a stop, its pulley, angle

    def _track_tension(self, t: np.ndarray, T: np.ndarray) -> None:
        """The smallest end tension of each span (and when) and the largest of all, over the samples
        T (B, n_span, 2) at times t (B,)."""
        low = T.min(axis=2)  # (B, n_span)
        k = np.argmin(low, axis=0)
        lowest = low[k, np.arange(low.shape[1])]
        better = lowest < self.tension_low
        self.tension_low = np.where(better, lowest, self.tension_low)
        self.tension_low_time = np.where(better, t[k], self.tension_low_time)
        b = int(np.argmax(T.max(axis=(1, 2))))
        if T[b].max() > self.tension_high[0]:
            self.tension_high = (float(T[b].max()), float(t[b]))

    def compute(self, t, q, v, a, energy, reaction) -> dict[str, np.ndarray]:
        sysm, setup, names = self.system, self.setup, self.names
        belt = sysm.belt
        out: dict[str, np.ndarray] = {}
        if "pulley_angle" in names or "pulley_speed" in names:
            s_nom = np.zeros(len(t))
            sd_nom = np.zeros(len(t))
            if setup.nom_scale:
                s_nom, sd_nom = nominal_rotation(setup, t)[:2]
            ur = setup.u_nom[sysm.rot_dof]
            if "pulley_angle" in names:
                out["pulley_angle"] = q[:, sysm.rot_dof] + s_nom[:, None] * ur
            if "pulley_speed" in names:
                out["pulley_speed"] = v[:, sysm.rot_dof] + sd_nom[:, None] * ur
        E = None
        if names & {"span_tension", "hub_load", "midspan_displacement"}:
            E = belt.element_coordinates_batch(q)
        if "span_tension" in names or "hub_load" in names:
            F = sysm.span_end_forces(q, v, E)  # internal (elastic + damping) - weight, spring spans included
            if "span_tension" in names:
                out["span_tension"] = sysm.span_end_tensions(q, F, E)
                self._track_tension(t, out["span_tension"])
                if "slip_margin" in names:
                    from beltdyn.model.slip import required_friction, slip_margin

                    m = slip_margin(required_friction(out["span_tension"], sysm.layout.wrap_angle),
                                    sysm.pulley_friction)
                    out["slip_margin"] = m
                    finite = np.where(np.isnan(m), np.inf, m)
                    b, j = np.unravel_index(int(np.argmin(finite)), finite.shape)
                    if finite[b, j] < self.worst_slip[0]:
                        self.worst_slip = (float(finite[b, j]), float(t[b]), sysm.layout.names[j])
            if "hub_load" in names:  # the pulley also carries the inertia of the end elements' nodes
                H = F + sysm.span_end_inertia(a)
                tr = setup.transport
                if tr is not None and (tr.follow or tr.speed):  # and the running belt's momentum flux
                    Ed = belt.element_coordinates_batch(v, offset=False)
                    H = H + sysm.span_transport_forces(E, Ed, *transport_speed(setup, t), p=q, vp=v)
                out["hub_load"] = sysm.hub_loads(H)
        for c in sysm.components:
            for obs in c.observations(sysm):
                if obs.name in names:
                    out.update(c.observe(sysm, q, setup.preload))
        if "midspan_displacement" in names:
            out["midspan_displacement"] = belt.midspan_displacement(E)
        if "arm_angle" in names:
            arms = sysm.arms
            out["arm_angle"] = arms.angle + q[:, arms.dof]
            out["arm_speed"] = v[:, arms.dof].copy()
            if self.stop_hit is None and arms.stops is not None:
                from beltdyn.model.angles import TWO_PI

                for k, (lo, hi) in enumerate(arms.stops):
                    if np.isnan(lo):
                        continue
                    phi = out["arm_angle"][:, k]
                    phi = phi + TWO_PI * np.round((0.5 * (lo + hi) - phi) / TWO_PI)
                    bad = np.nonzero((phi < lo) | (phi > hi))[0]
                    if bad.size and self.stop_hit is None:
                        self.stop_hit = (float(t[bad[0]]), arms.names[k], float(phi[bad[0]]))
        if "energy" in names:
            out["energy"] = energy
        if "driver_torque" in names:
            out["driver_torque"] = reaction[:, 0].copy()
        if "constraint_reaction" in names:
            out["constraint_reaction"] = reaction.copy()
        if "q" in names:  # the independent coordinates (the head of the joint coordinates)
            out["q"] = q[:, : sysm.n_dof].copy()
            out["v"] = v[:, : sysm.n_dof].copy()
        return out


# ------------------------------------------------------------------------------------ analytic tests
def integrate_linear(M: np.ndarray, K: np.ndarray, C: np.ndarray | None, q0: np.ndarray, v0: np.ndarray, *,
                     step: float, n_steps: int, rho_inf: float, tol: float = 1e-12):
    """Integrate M a + C v + K q = 0 through the production path (the same `drive`, compiled stepper
    and band factorization as the drive, with no belt elements). For tests on analytic oscillators.
    Returns t (n_steps+1,), q, v, a (n_steps+1, n)."""
    from beltdyn.analysis import integrator as itg
    from beltdyn.model.spring_kernel import no_springs

    n = M.shape[0]
    belt = itg.BeltData(e0=np.zeros((0, 8)), T=np.zeros((0, 8, 8)), idx=np.zeros((0, 8), dtype=np.int64),
                        tsel=np.zeros(0, dtype=np.int64), dS=np.zeros((0, 1, 4)), d2S=np.zeros((0, 1, 4)),
                        wEA=np.zeros((0, 1)), wEI=np.zeros((0, 1)), EA=np.zeros(0), Kb=np.zeros((0, 8, 8)),
                        curvature=1, eta_a=0.0, eta_b=0.0, elem_span=np.zeros(0, dtype=np.int64), n_span=0,
                        springs=no_springs())
    Cm = np.zeros((n, n)) if C is None else np.asarray(C, dtype=float)
    lin = itg.Linear(K=itg.split(K, n), q_ref=np.zeros(n), C=itg.split(None if C is None else Cm, n), M=itg.split(M, n))
    forcing = itg.Forcing(constant=np.zeros(n), load_dof=np.zeros(0, dtype=np.int64), load_coef=np.zeros(0),
                          load_sig=np.zeros(0, dtype=np.int64), sig_params=np.zeros((0, 5)),
                          tab_ptr=np.zeros(1, dtype=np.int64), tab_t=np.zeros(0), tab_v=np.zeros(0),
                          nominal_mass=np.zeros(n), nominal_rotation=np.zeros(9), nominal_scale=0.0)
    cons = itg.Constraints(dof=np.zeros(0, dtype=np.int64), params=np.zeros((0, 8)))
    am, af, beta, gamma = itg.alpha_parameters(rho_inf)

    def factor(q, h, v=None, t=0.0):
        S = (1 - am) / (beta * h * h) * M + (1 - af) * gamma / (beta * h) * Cm + (1 - af) * K
        return band_factor(S, np.arange(n, dtype=np.int64), max(n - 1, 0), symmetric=bool(np.allclose(S, S.T)))

    problem = StepProblem(belt=belt, linear=lin, forcing=forcing, constraints=cons, groups=np.zeros(n, dtype=np.int64),
                          q0=np.asarray(q0, dtype=float), v0=np.asarray(v0, dtype=float), factor=factor,
                          labels=tuple(f"q{i}" for i in range(n)))
    got: list = []
    drive(problem, rho_inf=rho_inf, step=step, min_step=step, duration=n_steps * step, output_interval=step,
          tolerance=tol, max_iterations=20, on_batch=lambda *b: got.append(b[:4]), batch=n_steps + 2)
    t, q, v, a = (np.concatenate([g[i] for g in got]) for i in range(4))
    return t, q, v, a


WARM_DRIVE = {  # the smallest drive that takes every compiled path of a transient (see `warm_up`)
    "belt": {"length": 1.2, "EA": 1e5, "EI": 0.02, "mass_per_length": 0.1},
    "pulleys": [
        {"name": "A", "center": [0.0, 0.0], "radius": 0.05, "mass": 1.0, "inertia": 1e-3, "driver": True},
        {"name": "B", "center": [0.5, 0.0], "radius": 0.05, "mass": 1.0, "inertia": 1e-3, "support": "slide",
         "bearing_stiffness": 1e6, "adjustable": True},
        {"name": "T", "center": [0.25, -0.06], "radius": 0.02, "mass": 0.2, "inertia": 1e-4, "side": "backside",
         "support": "arm", "arm_pivot": [0.3, -0.09], "arm_stiffness": 20.0, "arm_damping": 0.01,
         "arm_friction": 0.01}],
    "tension": {"target": 100.0},
    "mesh": {"elements_per_span": 2},
    "model": {"gravity": [0.0, -9.81]},
    "transient": {"duration": 1e-3, "step": 1e-4, "output_interval": 1e-4,  # (10 steps: energy error 0.56 %)
                  "damping": {"rayleigh_mass": 1.0, "rayleigh_stiffness": 1e-5, "belt_axial": 1e-5,
                              "belt_bending": 1e-5},
                  "rotation": [{"pulley": "A", "speed": 1.0, "amplitude": 1e-3, "frequency": 50.0}],
                  "torque": [{"pulley": "B", "constant": 0.1, "amplitude": 0.1, "frequency": 30.0}],
                  "spectrum": {"enabled": False}},
}


def entry_kernels() -> tuple:
    """The compiled functions a transient calls from Python (some only for some drives: the LU factor of
    a running belt, the belt damping's), each loaded from numba's cache on its own; every other kernel
    runs inside them, compiled into their libraries. What `jitcache.is_warm` checks before a run and
    `warm_up` compiles; `tests/test_startup.py` checks the list against what transients dispatch."""
    from beltdyn.model import belt_kernel as bk
    from beltdyn.analysis import integrator as itg

    return (itg.advance, itg.band_lu_nopivot, bk.element_forces, bk.element_damping, bk.element_damping_matrix,
            bk.reduced_force_and_tangent_blocks)

