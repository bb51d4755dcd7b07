"""Transient analysis: the nonlinear drive integrated in time from its static equilibrium.

Builds the numba kernel data from the model (see `integrator` for the equations), runs it chunk by
chunk, refactorizes the iteration matrix when Newton slows down, halves the step when it fails,
and hands batches of output samples to a sink (the CLI streams them to HDF5).

Belt travel. A prescribed pulley rotation theta(t) = nominal (speed ramp) + fluctuation is split:
the fluctuation is the prescribed value of the pulley's rotation DOF; the nominal part moves the
whole belt as a rigid loop, s(t) = theta_nominal(t) / u_rot, along the belt-travel vector u_nom (pulley
rotations 1/R, span nodes along their chords). The spans are described in that travelling frame:
their node coordinates stay where they are while the material passes through, and the nominal
motion enters only through its inertia, -M u_nom s''(t). Axial-transport (Coriolis and centripetal,
rho v^2) terms are not modelled: they matter when rho v^2 approaches the tension (at 10 m/s on the
paper's belt, rho v^2 = 12 N against 200 N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import ancf
from .config import DriveConfig
from .errors import ConfigError, SolverError
from .model import DriveModel
from .static import StaticResult

ENERGY_TERMS = ("kinetic", "strain", "work", "dissipated", "balance_error")


@dataclass(frozen=True, kw_only=True)
class Series:
    """One recorded history: trailing dims and their coordinate values, units."""

    name: str
    dims: tuple[str, ...]
    units: str
    description: str = ""


@dataclass(frozen=True, kw_only=True)
class TransientSetup:
    """Everything fixed for one run: series to record, their coordinates, the kernel data."""

    series: tuple[Series, ...]
    coords: dict[str, list]
    kernel: tuple
    M: object
    C: object
    perm: np.ndarray
    bandwidth: int
    q0: np.ndarray
    v0: np.ndarray
    u_nom: np.ndarray
    nom_scale: float
    rotation: np.ndarray  # (7,) parameters of the prescribed rotation
    pdof: int
    excitation_frequency: float | None
    pulley_mass_diag: np.ndarray  # (n,) pulley mass / inertia on their DOFs (the rest of M is element mass)


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
    energy_error: float = 0.0  # max |balance error| / largest energy exchanged (recorded outputs)


def _belt_travel(model: DriveModel) -> np.ndarray:
    """u_nom (n_dof,): the rigid belt loop advanced by 1 m (pulley rotations +-1/R, nodes along t)."""
    u = np.zeros(model.n_dof)
    lay = model.layout
    for j in range(lay.n):
        n_out = lay.start_normal[j]
        t = lay.span_direction[j]
        u[model.rot_dof[j]] = float(np.array([-n_out[1], n_out[0]]) @ t) / lay.radius[j]
    n_e = len(model.span_elements[0])
    for s, sl in enumerate(model.span_dof_slices):
        block = np.zeros(sl.stop - sl.start)
        for node in range(1, n_e):
            block[2 + 4 * (node - 1): 4 + 4 * (node - 1)] = model.reference_direction[s]
        u[sl] = block
    return u


def _csr(A):
    from scipy.sparse import csr_matrix

    A = csr_matrix(A)
    A.sort_indices()
    return A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data.astype(np.float64)


def _band_order(model: DriveModel) -> tuple[np.ndarray, int]:
    """Reverse Cuthill-McKee order of the element coupling graph and the half-bandwidth it gives
    (about twice an element's: the belt loop closes on itself)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    from .model import element_pairs

    n = model.n_dof
    rows, cols = element_pairs(model.idx)
    keep = (rows < n) & (cols < n)
    rows, cols = rows[keep], cols[keep]
    G = csr_matrix((np.ones(len(rows) + n), (np.r_[rows, np.arange(n)], np.r_[cols, np.arange(n)])), shape=(n, n))
    perm = np.asarray(reverse_cuthill_mckee(G, symmetric_mode=True), dtype=np.int64)
    inv = np.empty_like(perm)
    inv[perm] = np.arange(n)
    return perm, int(np.abs(inv[rows] - inv[cols]).max(initial=0))


def prepare(cfg: DriveConfig, model: DriveModel, static: StaticResult) -> TransientSetup:
    """Kernel data for the run: only the loads, damping and outputs the configuration asks for."""
    opts = cfg.transient
    assert opts is not None
    if cfg.model.curvature == "exact":
        raise ConfigError("the transient analysis supports curvature \"linear\" or \"none\"",
                          file=cfg.source, key="model.curvature")
    el = model.elements
    names = [p.name for p in cfg.pulleys]
    n = model.n_dof
    u_nom = _belt_travel(model)
    # prescribed rotation
    rot = np.zeros(8)
    pdof, nom_scale, f_exc = -1, 0.0, None
    if opts.rotation:
        r = opts.rotation[0]
        j = names.index(r.pulley)
        pdof = int(model.rot_dof[j])
        rot[:] = (r.speed, r.ramp_time, r.amplitude, r.speed_amplitude, r.frequency, r.phase, r.fluctuation_ramp,
                  static.q[pdof] if opts.start == "static" else 0.0)
        nom_scale = 1.0 / u_nom[pdof] if (r.speed != 0.0) else 0.0
        f_exc = r.frequency if (r.amplitude or r.speed_amplitude) else None
    # applied loads: one channel per (signal, DOF)
    params, tabs_t, tabs_v, ptr = [], [], [], [0]
    load_dof, load_coef, load_sig = [], [], []
    for load in opts.loads:
        j = names.index(load.pulley)
        for c, sig in enumerate(load.signals):
            k = len(params)
            params.append((sig.constant, sig.amplitude, sig.frequency, sig.phase, sig.ramp_time))
            tabs_t += list(sig.table_time)
            tabs_v += list(sig.table_value)
            ptr.append(len(tabs_t))
            if load.kind == "torque":
                load_dof.append(int(model.rot_dof[j]))
                load_coef.append(1.0)
                load_sig.append(k)
            else:
                for d, vec in zip(model.trans_dof[j], model.trans_dir[j]):
                    if vec[c] != 0.0:
                        load_dof.append(int(d))
                        load_coef.append(float(vec[c]))
                        load_sig.append(k)
            if f_exc is None and sig.amplitude and sig.frequency:
                f_exc = sig.frequency
    sig_params = np.array(params, dtype=float).reshape(-1, 5)
    M = model.mass
    Mu = np.asarray(M @ u_nom).ravel()
    d = opts.damping
    C = None
    if d.rayleigh_mass or d.rayleigh_stiffness:
        _, K0 = model.force_and_tangent(static.q)
        C = d.rayleigh_mass * M + d.rayleigh_stiffness * K0
    Kb = el.K_bend if cfg.model.curvature == "linear" else np.zeros((el.n_elem, 8, 8))
    grav = model.gravity_force
    kernel = (
        np.ascontiguousarray(model.T), np.ascontiguousarray(model.idx).astype(np.int64), np.ascontiguousarray(model.e0),
        np.ascontiguousarray(el.dS), np.ascontiguousarray(el.wL), np.ascontiguousarray(el.EA),
        np.ascontiguousarray(Kb), float(d.belt_axial), float(d.belt_bending), model.elem_span.astype(np.int64),
        int(model.layout.n), model.spring.astype(float), static.spring_preload.astype(float), grav.astype(float),
        Mu.astype(float), rot, int(pdof), float(nom_scale), np.array(load_dof, dtype=np.int64),
        np.array(load_coef, dtype=float), np.array(load_sig, dtype=np.int64), sig_params,
        np.array(ptr, dtype=np.int64), np.array(tabs_t, dtype=float), np.array(tabs_v, dtype=float),
    )
    perm, bandwidth = _band_order(model)
    q0 = static.q.copy() if opts.start == "static" else np.zeros(n)
    v0 = np.zeros(n)
    series, coords = _series(cfg, model, opts, pdof)
    extra = np.asarray(M.diagonal()).ravel() - np.asarray(model.reduce_matrix(el.mass).diagonal()).ravel()
    return TransientSetup(series=series, coords=coords, kernel=kernel, M=M, C=C, perm=perm, bandwidth=bandwidth,
                          q0=q0, v0=v0, u_nom=u_nom, nom_scale=nom_scale, rotation=rot, pdof=pdof,
                          excitation_frequency=f_exc, pulley_mass_diag=extra)


def _series(cfg, model, opts, pdof):
    lay = model.layout
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
                          description="true axial force EA (eps + eta deps/dt) |r'| at the span ends"))
    if rec.hub_load:
        out.append(Series(name="hub_load", dims=("pulley", "component"), units="N",
                          description="force of the belt on each pulley"))
    bearing = [p.name for p in cfg.pulleys if p.support != "fixed"]
    if rec.bearing_force and bearing:
        coords["bearing"] = bearing
        out.append(Series(name="bearing_force", dims=("bearing", "component"), units="N",
                          description="force of the bearing spring on the pulley (preload included)"))
    if rec.midspan_displacement:
        out.append(Series(name="midspan_displacement", dims=("span",), units="m",
                          description="mid-span displacement normal to the reference chord"))
    if rec.energy:
        coords["energy_term"] = list(ENERGY_TERMS)
        out.append(Series(name="energy", dims=("energy_term",), units="J",
                          description="kinetic + strain - work of loads + dissipated = balance error (deviation frame)"))
    if pdof >= 0:
        out.append(Series(name="driver_torque", dims=(), units="N m",
                          description="torque the prescribed rotation applies to its pulley"))
    if rec.full_state:
        coords["dof"] = list(model.dof_labels)
        out.append(Series(name="q", dims=("dof",), units="1", description="independent coordinates"))
        out.append(Series(name="v", dims=("dof",), units="1", description="their time derivatives (per s)"))
    return tuple(out), coords


# ------------------------------------------------------------------------------------ iteration matrix
def _factor(setup: TransientSetup, model: DriveModel, cfg: DriveConfig, q: np.ndarray, h: float):
    """Factor S = c_m M + c_c (C + C_belt) + (1 - alpha_f) K_t(q): banded Cholesky in RCM order, or LU."""
    from scipy.linalg import cholesky_banded, lu_factor

    from .integrator import alpha_parameters

    am, af, beta, gamma = alpha_parameters(cfg.transient.rho_inf)
    el = model.elements
    e = model.element_coordinates(q)
    _, Ke = ancf.internal_forces_and_tangent(el, e)
    d = cfg.transient.damping
    Kb = el.K_bend if cfg.model.curvature == "linear" else 0.0
    c_m = (1.0 - am) / (beta * h * h)
    c_c = (1.0 - af) * gamma / (beta * h)
    blocks = (1.0 - af) * Ke + c_c * (d.belt_axial * (Ke - Kb) + d.belt_bending * Kb) + c_m * el.mass
    # pulley masses and inertias sit on the diagonal of M, outside the element blocks
    Sd = model.reduce_matrix(blocks, (1.0 - af) * model.spring + c_m * setup.pulley_mass_diag)
    if setup.C is not None:
        Sd = Sd + c_c * setup.C
    n = model.n_dof
    if setup.pdof >= 0:  # the prescribed DOF is held: identity row and column
        p = setup.pdof
        if model.dense:
            Sd = Sd.copy()
            Sd[p, :] = 0.0
            Sd[:, p] = 0.0
            Sd[p, p] = 1.0
        else:
            Sd = Sd.tolil()
            Sd[p, :] = 0.0
            Sd[:, p] = 0.0
            Sd[p, p] = 1.0
            Sd = Sd.tocsr()
    perm = setup.perm
    u = setup.bandwidth
    Sp = (Sd[np.ix_(perm, perm)] if model.dense else Sd[perm][:, perm].tocoo())
    ab = np.zeros((u + 1, n))
    if model.dense:
        ii, jj = np.nonzero(np.triu(Sp) != 0.0)
        vals = Sp[ii, jj]
    else:
        mask = Sp.row <= Sp.col
        ii, jj, vals = Sp.row[mask], Sp.col[mask], Sp.data[mask]
    np.add.at(ab, (u + ii - jj, jj), vals)
    try:
        cb = cholesky_banded(ab, lower=False, check_finite=False)
        return (0, cb, perm, np.zeros((1, 1)), np.zeros(1, dtype=np.int64))
    except np.linalg.LinAlgError:
        Sfull = Sd if model.dense else Sd.toarray()
        lu, piv = lu_factor(Sfull, check_finite=False)
        return (1, np.zeros((1, 1)), perm, lu, piv.astype(np.int64))


# ------------------------------------------------------------------------------------ outputs
@dataclass
class _Derived:
    """Batch computation of the recorded quantities from output states (B, n)."""

    cfg: DriveConfig
    model: DriveModel
    setup: TransientSetup
    static: StaticResult
    energy0: float = field(default=0.0)
    mid: tuple = field(default=())
    worst_balance: float = field(default=0.0)  # max |balance error| so far, J
    exchanged: float = field(default=0.0)  # max |kinetic + strain - initial| and |work| so far, J

    def __post_init__(self) -> None:
        m = self.model
        n_e = len(m.span_elements[0])
        # mid-span point: the middle node (even mesh) or the middle of the middle element (odd mesh)
        k, xi = (n_e // 2, 0.0) if n_e % 2 == 0 else ((n_e - 1) // 2, 0.5)
        els = np.array([m.span_elements[s][k] for s in range(m.layout.n)])
        s_fun, _, _ = ancf.shape_functions(np.array([xi]), m.elements.length[els])
        ref = (m.layout.span_start + m.layout.span_end) / 2.0
        self.mid = (els, s_fun[:, 0, :], ref)

    def compute(self, t, q, v, a, w) -> dict[str, np.ndarray]:
        m, setup, cfg = self.model, self.setup, self.cfg
        B = len(t)
        out: dict[str, np.ndarray] = {}
        names = {s.name for s in setup.series}
        el = m.elements
        qe = np.concatenate([q, np.zeros((B, 1))], axis=1)[:, m.idx]  # (B, n_elem, mm)
        E = np.einsum("eim,bem->bei", m.T, qe) + m.e0  # (B, n_elem, 8)
        ve = np.concatenate([v, np.zeros((B, 1))], axis=1)[:, m.idx]
        Ed = np.einsum("eim,bem->bei", m.T, ve)
        rot_state = np.array([_rotation_numpy(setup.rotation, tt) for tt in t]) if setup.pdof >= 0 else None
        if "pulley_angle" in names or "pulley_speed" in names:
            s_nom = np.zeros(B)
            sd_nom = np.zeros(B)
            if rot_state is not None and setup.nom_scale:
                s_nom = rot_state[:, 0] * setup.nom_scale
                sd_nom = rot_state[:, 1] * setup.nom_scale
            ur = setup.u_nom[m.rot_dof]
            if "pulley_angle" in names:
                out["pulley_angle"] = q[:, m.rot_dof] + s_nom[:, None] * ur
            if "pulley_speed" in names:
                out["pulley_speed"] = v[:, m.rot_dof] + sd_nom[:, None] * ur
        if "span_tension" in names:
            first = np.array([s[0] for s in m.span_elements])
            last = np.array([s[-1] for s in m.span_elements])
            eta = cfg.transient.damping.belt_axial
            res = np.empty((B, m.layout.n, 2))
            for col, (els, x) in enumerate(((first, 0.0), (last, 1.0))):
                _, ds, _ = ancf.shape_functions(np.array([x]), el.length[els])
                D = ds[:, 0, :]  # (n_span, 4)
                rp = np.einsum("sk,bskd->bsd", D, E[:, els].reshape(B, len(els), 4, 2))
                rpd = np.einsum("sk,bskd->bsd", D, Ed[:, els].reshape(B, len(els), 4, 2))
                a2 = (rp ** 2).sum(-1)
                eps = 0.5 * (a2 - 1.0)
                epsd = (rp * rpd).sum(-1)
                res[:, :, col] = el.EA[els] * (eps + eta * epsd) * np.sqrt(a2)
            out["span_tension"] = res
        if "hub_load" in names:
            g = np.asarray(cfg.model.gravity, dtype=float)
            ge = ancf.gravity_forces(el, g)
            ae = np.einsum("eim,bem->bei", m.T, np.concatenate([a, np.zeros((B, 1))], axis=1)[:, m.idx])
            hub = np.zeros((B, m.layout.n, 2))
            eta_a, eta_b = cfg.transient.damping.belt_axial, cfg.transient.damping.belt_bending
            Kb = el.K_bend if cfg.model.curvature == "linear" else np.zeros_like(el.K_bend)
            for b in range(B):
                fe = ancf.internal_forces(el, E[b])
                if eta_a or eta_b:
                    fe = fe + _damping_forces(el, E[b], Ed[b], eta_a, eta_b, Kb)
                inert = np.einsum("eij,ej->ei", el.mass, ae[b])
                net = ge - fe - inert
                for s in range(m.layout.n):
                    f0, f1 = m.span_elements[s][0], m.span_elements[s][-1]
                    hub[b, s] += net[f0, 0:2]
                    hub[b, (s + 1) % m.layout.n] += net[f1, 4:6]
            out["hub_load"] = hub
        if "bearing_force" in names:
            rows = []
            for j, p in enumerate(cfg.pulleys):
                if p.support == "fixed":
                    continue
                F = np.zeros((B, 2))
                for dof, vec in zip(m.trans_dof[j], m.trans_dir[j]):
                    F += (self.static.spring_preload[dof] - m.spring[dof] * q[:, dof])[:, None] * vec
                rows.append(F)
            out["bearing_force"] = np.stack(rows, axis=1)
        if "midspan_displacement" in names:
            els, sfun, ref = self.mid
            pos = np.einsum("sk,bskd->bsd", sfun, E[:, els].reshape(B, len(els), 4, 2))
            out["midspan_displacement"] = np.einsum("bsd,sd->bs", pos - ref, m.reference_normal)
        if "energy" in names:
            kin = 0.5 * np.einsum("bi,bi->b", v, np.asarray((m.mass @ v.T).T))
            strain = np.array([ancf.strain_energy(el, E[b]).sum() for b in range(B)])
            strain += 0.5 * (m.spring * q * q).sum(axis=1)
            total = kin + strain - w[:, 0] + w[:, 1]
            out["energy"] = np.column_stack([kin, strain, w[:, 0], w[:, 1], total - self.energy0])
        if "driver_torque" in names:
            out["driver_torque"] = w[:, 2].copy()
        if "q" in names:
            out["q"] = q.copy()
            out["v"] = v.copy()
        return out


def _damping_forces(el, E, Ed, eta_a, eta_b, Kb):
    """Kelvin-Voigt belt damping forces (n_elem, 8) at one state (numpy, for outputs)."""
    Er = E.reshape(-1, 4, 2)
    Edr = Ed.reshape(-1, 4, 2)
    rp = np.matmul(el.dS, Er)
    rpd = np.matmul(el.dS, Edr)
    epsd = (rp * rpd).sum(-1)
    c = el.wL * el.EA[:, None] * eta_a * epsd
    f = np.einsum("eq,eqk,eqd->ekd", c, el.dS, rp).reshape(-1, 8)
    return f + eta_b * np.einsum("eij,ej->ei", Kb, Ed)


def _rotation_numpy(rot, t):
    from .integrator import rotation_state

    return np.array(rotation_state(rot, float(t)))


# ------------------------------------------------------------------------------------ the run
Sink = Callable[[np.ndarray, dict[str, np.ndarray]], None]
Progress = Callable[[float], None]


def run_transient(cfg: DriveConfig, model: DriveModel, static: StaticResult, *, sink: Sink,
                  progress: Progress | None = None, setup: TransientSetup | None = None,
                  batch: int = 256) -> TransientSummary:
    """Integrate, feeding (time (B,), {series: (B, ...)}) batches to `sink`.

    Raises SolverError (with the failure time, residual and DOF) when the step cannot be reduced
    further; the batches before the failure have been delivered. KeyboardInterrupt propagates after
    the last complete batch was delivered.
    """
    from . import integrator as itg

    opts = cfg.transient
    setup = setup or prepare(cfg, model, static)
    n = model.n_dof
    am, af, beta, gamma = itg.alpha_parameters(opts.rho_inf)
    M_ptr, M_idx, M_dat = _csr(model.mass)
    if setup.C is not None:
        C_ptr, C_idx, C_dat = _csr(setup.C)
    else:
        C_ptr, C_idx, C_dat = np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
    mats = (M_ptr, M_idx, M_dat, C_ptr, C_idx, C_dat)
    K = setup.kernel
    q, v = setup.q0.copy(), setup.v0.copy()
    if setup.pdof >= 0:
        st = itg.rotation_state(setup.rotation, 0.0)
        q[setup.pdof], v[setup.pdof] = setup.rotation[7] + st[3], st[4]
    # consistent initial acceleration: M a0 = F(0) - C v0 - f(q0, v0) on the free DOFs
    f_el, f_dmp = np.zeros(n + 1), np.zeros(n + 1)
    F = np.zeros(n)
    min_force = np.zeros(max(model.layout.n, 1))
    itg._forces(q, v, 0.0, K, f_el, f_dmp, F, min_force, np.zeros(K[21].shape[0]))
    rhs = F - f_el[:n] - f_dmp[:n]
    if setup.C is not None:
        rhs -= np.asarray(setup.C @ v).ravel()
    a = np.zeros(n)
    Md = model.mass if model.dense else model.mass.toarray()
    free = np.arange(n) if setup.pdof < 0 else np.delete(np.arange(n), setup.pdof)
    if setup.pdof >= 0:
        a[setup.pdof] = itg.rotation_state(setup.rotation, 0.0)[5]
        rhs -= Md[:, setup.pdof] * a[setup.pdof]
    a[free] = np.linalg.solve(Md[np.ix_(free, free)], rhs[free])
    f0 = np.concatenate([f_el[:n] + f_dmp[:n], f_dmp[:n]])
    Cv0 = np.asarray(setup.C @ v).ravel() if setup.C is not None else np.zeros(n)
    Rd0 = (float((Md @ a)[setup.pdof] + Cv0[setup.pdof] + f_el[setup.pdof] + f_dmp[setup.pdof] - F[setup.pdof])
           if setup.pdof >= 0 else 0.0)
    th = np.array([0.0, opts.step, 0.0, 0.0, 0.0, Rd0, 0.0])  # t, h, next output, W, D, reaction, steps
    state = (q, v, a, f0, F.copy(), th)
    derived = _Derived(cfg=cfg, model=model, setup=setup, static=static)
    n_span = model.layout.n
    events = np.zeros((2000 * max(model.layout.n, 1) + 8, 4))  # room for one call's transitions (2000 steps)
    all_events: list[np.ndarray] = []
    n_events = np.zeros(1, dtype=np.int64)
    slack = np.zeros(n_span)
    info = np.zeros(4)
    batch = max(batch, int(math.ceil(opts.step / opts.output_interval)) + 2)  # a step's samples always fit
    out_t = np.zeros(batch)
    out_q = np.zeros((batch, n))
    out_v = np.zeros((batch, n))
    out_a = np.zeros((batch, n))
    out_w = np.zeros((batch, 3))
    n_out = np.zeros(1, dtype=np.int64)
    n_total_out = int(math.floor(opts.duration / opts.output_interval + 1e-9)) + 1
    h_nominal = opts.step
    fac = _factor(setup, model, cfg, q, th[1])
    fresh = 1.0
    steps = refactors = halvings = 0
    min_h = th[1]
    delivered = 0
    first = True
    calm = 0

    def drain() -> None:
        nonlocal delivered, first
        k = int(n_out[0])
        take = min(k, n_total_out - delivered)
        n_out[0] = 0  # counted as delivered before the sink runs: an interrupt inside it cannot repeat them
        if take > 0:
            batch_out = derived.compute(out_t[:take], out_q[:take], out_v[:take], out_a[:take], out_w[:take])
            if first and "energy" in batch_out:
                derived.energy0 = float(batch_out["energy"][0, 0] + batch_out["energy"][0, 1])
                batch_out["energy"][:, 4] -= derived.energy0
            if "energy" in batch_out:
                e = batch_out["energy"]
                derived.worst_balance = max(derived.worst_balance, float(np.abs(e[:, 4]).max()))
                derived.exchanged = max(derived.exchanged, float(np.abs(e[:, 0] + e[:, 1] - derived.energy0).max()),
                                        float(np.abs(e[:, 2]).max()), float(np.abs(e[:, 3]).max()))
            first = False
            delivered += take
            sink(out_t[:take].copy(), batch_out)

    status, message = "complete", ""
    try:
        while True:
            code = itg.run_steps(state, K, mats, fac, np.array([am, af, beta, gamma, opts.tolerance, opts.max_iterations,
                                                                 opts.duration, opts.output_interval, 2000, fresh]),
                                 out_t, out_q, out_v, out_a, out_w, n_out, events, n_events, slack, info)
            if n_events[0]:
                all_events.append(events[: int(n_events[0])].copy())
                n_events[0] = 0
            if th[6] > steps:
                fresh = 0.0
            steps = int(th[6])
            if progress is not None:
                progress(min(th[0], opts.duration))
            if code == itg.DONE:
                break
            if code == itg.BUFFER_FULL or code == itg.MAX_STEPS:
                drain()
                if th[1] < h_nominal:  # grow the step back after a calm stretch
                    calm += 1
                    if calm >= 2:
                        th[1] = min(2.0 * th[1], h_nominal)
                        fac = _factor(setup, model, cfg, q, th[1])
                        fresh, calm = 1.0, 0
                        refactors += 1
                continue
            if code == itg.REFACTOR:
                fac = _factor(setup, model, cfg, q, th[1])
                fresh = 1.0
                refactors += 1
                calm = 0
                continue
            # HALVE
            if th[1] / 2.0 < opts.min_step:
                dof = model.dof_labels[int(info[2])] if int(info[2]) < n else "?"
                message = (f"no convergence at t = {info[0]:.6g} s even with the step reduced to {th[1]:.3g} s "
                           f"(transient.min_step = {opts.min_step:g} s)")
                status = "failed"
                drain()
                raise SolverError(message, analysis="transient", step=f"t = {info[0]:.6g} s",
                                  residual=float(info[1]), item=dof)
            th[1] /= 2.0
            min_h = min(min_h, th[1])
            halvings += 1
            calm = 0
            fac = _factor(setup, model, cfg, q, th[1])
            fresh = 1.0
            refactors += 1
        drain()
    except KeyboardInterrupt:
        status = "interrupted"
        drain()
        raise
    ev = np.concatenate(all_events) if all_events else np.zeros((0, 4))
    return TransientSummary(status=status, steps=steps, refactorizations=refactors, step_halvings=halvings,
                            final_time=float(th[0]), min_step=float(min_h), slack_events=ev, message=message,
                            n_outputs=delivered,
                            energy_error=derived.worst_balance / derived.exchanged if derived.exchanged > 0 else 0.0)
