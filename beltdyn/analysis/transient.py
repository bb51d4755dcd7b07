"""Transient analysis: a `System` integrated in time from its static equilibrium.

`prepare` lowers the system and the transient options into the stepper's named structures (see
`integrator`): the belt kernel data, the components' constant matrices (stiffness about the static
state, damping, mass), the forcing (constant part, loads as signals on DOFs, inertia of the nominal
belt travel) and the constraints (prescribed rotations, any number). `drive` runs the compiled
stepper chunk by chunk, refactorizes the iteration matrix when Newton slows down, halves the step
when it fails, and hands batches of output samples to a sink; the recorded quantities come from
observers (the belt, the pulleys, the components' own series, the constraints' reactions), vectorized
over each batch.

By job: `transient_setup` (`prepare`, the set-up), `transient_factor` (the iteration matrix and its band
factor), this module (the stepping driver `drive`, `run_transient`, `integrate_linear` for the
analytic tests), `transient_outputs` (observers and their warnings), `transient_wraps` (the wraps that may slip: the
pulleys' own rotations added behind their wraps, `integrator.Wraps`), `integrator` (the compiled stepper,
a loop over the named parts of its `StepperModel`), `stepper_data` (its structures) and `band_solve`.
A run whose energy balance error exceeds ENERGY_LIMIT (1 % of the energy moved) fails (SolverError)
after every sample has reached the sink.

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

import json
import math
import struct
import time
import zlib
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from beltdyn.config import TransientOptions
from beltdyn.errors import SolverError
from beltdyn.analysis.static import StaticResult
from beltdyn.model.system import System

from beltdyn.analysis.transient_setup import (  # noqa: F401  (set-up, re-exported)
    ENERGY_TERMS, TransientSetup, band_order, belt_travel, nominal_rotation, output_volume, p_to_q, prepare, stepper_arms,
    stepper_decouplers, transport_speed)
from beltdyn.analysis.transient_factor import (  # noqa: F401  (the iteration matrix, re-exported)
    IterationPlan, band_factor, factorizer, stepper_system)
from beltdyn.analysis.transient_outputs import Observers, slip_warning, stop_warning, tension_warnings  # noqa: F401
from beltdyn.analysis.transient_factor import wrap_factorizer
from beltdyn.analysis.transient_wraps import stepper_arms as wrap_arms, stepper_setup, stepper_wraps, wrap_slip

Sink = Callable[[np.ndarray, dict[str, np.ndarray]], None]
Progress = Callable[[float], None]


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


ENERGY_LIMIT = 0.01  # energy-balance error, as a share of the energy moved, above which a run fails (SolverError;
# an error within round-off, `energy_roundoff`, never does)


SNAPSHOT_MAGIC = b"BDSNAP01"
_SNAPSHOT_HEAD = struct.Struct("<8sQI")  # magic, payload length, CRC-32 of the payload
SNAPSHOT_ARRAYS = ("q", "v", "a", "f0", "fd0", "F0", "R0", "scal", "anchor", "slack", "events", "factor_q", "factor_v",
                   "tension_low", "tension_low_time", "clutch", "wrap_state")


def _frozen(x) -> np.ndarray:
    a = np.array(x, dtype=np.float64)  # a copy of its own
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True)
class TransientSnapshot:
    """The stepper's full state at an accepted step, taken after every sample up to it reached the
    sink: what a resumed run (`run_transient(resume=...)`) restarts from, so that it continues as the
    uninterrupted run would have. Arrays are float64, read-only copies where `drive` and
    `snapshot_from_bytes` make them (`_frozen`).

    Stepper (`integrator.State`, n DOFs, m = max(constraints, 1)): q, v, a (n,) the state (generalized
    alpha in the form M a + ... with the real acceleration a: no auxiliary acceleration), f0, fd0, F0
    (n,) the internal, damping and external forces at it, R0 (m,) the constraint reactions, scal
    (integrator.N_SCAL,) the time, the step size, the next output time, the energy-balance accumulators
    (work, dissipated, reference energies, worst error, energy moved), the step and iteration counts
    and the factor's age. Arms: anchor (n_arms,) the friction bristles' anchors (decouplers: clutch). Slack: slack (n_span,)
    the spans' slack flags, events (k, 4) the slack events so far. Factor: factor_q, factor_v (n,),
    factor_h, factor_t, the state the current iteration matrix was computed at (recomputed on resume:
    the same matrix), fresh (the factor not used yet), calm (calm calls since a halving). Driver
    counts: delivered (samples handed to the sink), steps, refactorizations, halvings, min_step, refresh
    (the refresh rule's current factor cost).
    Observers (`transient_outputs.Observers`): tension_low, tension_low_time (n_span,), tension_high
    (N, s), worst_slip (margin, s, pulley), stop_hit (s, pulley, rad) or None."""

    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    f0: np.ndarray
    fd0: np.ndarray
    F0: np.ndarray
    R0: np.ndarray
    scal: np.ndarray
    anchor: np.ndarray
    slack: np.ndarray
    events: np.ndarray
    factor_q: np.ndarray
    factor_v: np.ndarray
    factor_h: float
    factor_t: float
    fresh: bool
    calm: int
    delivered: int
    steps: int
    refactorizations: int
    halvings: int
    min_step: float
    refresh: float = 0.0  # the refresh rule's factor cost in residual evaluations (`integrator.factor_aged`)
    tension_low: np.ndarray = field(default_factory=lambda: _frozen(np.zeros(0)))
    tension_low_time: np.ndarray = field(default_factory=lambda: _frozen(np.zeros(0)))
    tension_high: tuple[float, float] = (-np.inf, np.nan)
    worst_slip: tuple[float, float, str] = (np.inf, np.nan, "")
    stop_hit: tuple[float, str, float] | None = None
    clutch: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((2, 0))))  # (2, n_dec): the decouplers'
    # accepted clutch slip and torque (`integrator.Decouplers` slip[0], torque[0])
    wrap_state: np.ndarray = field(default_factory=lambda: _frozen(np.zeros((8, 0))))  # (8, k) the slipping
    # wraps' anchors, limits, torques, start torques, the factor's regime and the last evaluation's, their
    # creep rates and rim speed ratios (`integrator.Wraps`; k = 0 without)

    @property
    def time(self) -> float:
        """The simulated time of the snapshot (s)."""
        from beltdyn.analysis import integrator as itg

        return float(self.scal[itg.T_NOW])


def snapshot_bytes(snap: TransientSnapshot) -> bytes:
    """The snapshot as one checksummed record: a 20-byte head (SNAPSHOT_MAGIC, payload length u64,
    CRC-32 of the payload u32; little-endian), then the payload: a u32 length of a JSON text (the
    scalars and each array's shape), the JSON, then the arrays' float64 bytes in SNAPSHOT_ARRAYS order."""
    arrays = [np.ascontiguousarray(getattr(snap, k), dtype="<f8") for k in SNAPSHOT_ARRAYS]
    meta = {"shapes": [list(a.shape) for a in arrays], "factor_h": snap.factor_h, "factor_t": snap.factor_t,
            "fresh": snap.fresh, "calm": snap.calm, "delivered": snap.delivered, "steps": snap.steps,
            "refactorizations": snap.refactorizations, "halvings": snap.halvings, "min_step": snap.min_step,
            "refresh": snap.refresh,
            "tension_high": list(snap.tension_high), "worst_slip": list(snap.worst_slip),
            "stop_hit": None if snap.stop_hit is None else list(snap.stop_hit)}
    text = json.dumps(meta).encode()  # (json writes inf and nan as Infinity and NaN, and reads them back)
    payload = struct.pack("<I", len(text)) + text + b"".join(a.tobytes() for a in arrays)
    return _SNAPSHOT_HEAD.pack(SNAPSHOT_MAGIC, len(payload), zlib.crc32(payload)) + payload


def snapshot_from_bytes(data: bytes) -> TransientSnapshot:
    """The snapshot of a record written by `snapshot_bytes`; ValueError if it is torn or fails its CRC."""
    if len(data) < _SNAPSHOT_HEAD.size:
        raise ValueError("the snapshot is cut short")
    magic, length, crc = _SNAPSHOT_HEAD.unpack_from(data)
    payload = data[_SNAPSHOT_HEAD.size:]
    if magic != SNAPSHOT_MAGIC or len(payload) != length or zlib.crc32(payload) != crc:
        raise ValueError("the snapshot fails its checksum (torn or damaged)")
    (n_text,) = struct.unpack_from("<I", payload)
    meta = json.loads(payload[4:4 + n_text])
    arrays, pos = {}, 4 + n_text
    for key, shape in zip(SNAPSHOT_ARRAYS, meta["shapes"]):  # (a record without the last arrays: their defaults)
        count = int(np.prod(shape, dtype=np.int64))
        arrays[key] = _frozen(np.frombuffer(payload, dtype="<f8", count=count, offset=pos).reshape(shape))
        pos += 8 * count
    worst = meta["worst_slip"]
    stop = meta["stop_hit"]
    return TransientSnapshot(
        **arrays, factor_h=float(meta["factor_h"]), factor_t=float(meta["factor_t"]), fresh=bool(meta["fresh"]),
        calm=int(meta["calm"]), delivered=int(meta["delivered"]), steps=int(meta["steps"]),
        refactorizations=int(meta["refactorizations"]), halvings=int(meta["halvings"]),
        min_step=float(meta["min_step"]), refresh=float(meta["refresh"]), tension_high=(float(meta["tension_high"][0]), float(meta["tension_high"][1])),
        worst_slip=(float(worst[0]), float(worst[1]), str(worst[2])),
        stop_hit=None if stop is None else (float(stop[0]), str(stop[1]), float(stop[2])))


def energy_roundoff(scal: np.ndarray) -> float:
    """The balance error that round-off alone makes (J): 1e3 machine epsilons of the energy stored at
    the start (kinetic + strain, scal[KIN0], scal[POT0]) per square root of the steps added up. A drive
    at rest moves ~1e-13 J, so its balance error, all round-off, is a large share of that: not a failure."""
    from beltdyn.analysis import integrator as itg

    stored = abs(float(scal[itg.KIN0])) + abs(float(scal[itg.POT0]))
    return 1e3 * itg.EPS * stored * math.sqrt(max(float(scal[itg.STEPS]), 1.0))


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
    decouplers: tuple | None = None  # integrator.Decouplers (None: no one-way decoupler)
    wraps: tuple | None = None  # integrator.Wraps (None: no wrap slips)


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


def _buffers(batch: int, n: int, n_con: int, dec, wraps, n_span: int):
    """The stepper's output buffer (`integrator.Outputs`, batch samples of n DOFs, n_con reactions, the
    decouplers' and wraps' columns) and its slack-event buffer (`integrator.Events`, n_span spans)."""
    from beltdyn.analysis import integrator as itg

    out = itg.Outputs(t=np.zeros(batch), q=np.zeros((batch, n)), v=np.zeros((batch, n)), a=np.zeros((batch, n)),
                      energy=np.zeros((batch, 5)), reaction=np.zeros((batch, n_con)), n=np.zeros(1, dtype=np.int64),
                      clutch=np.zeros((batch, len(dec.hub))),
                      wrap=np.zeros((batch, 4, max(len(wraps.wrap), 1))))
    ev = itg.Events(data=np.zeros((2000 * max(n_span, 1) + 8, 4)), n=np.zeros(1, dtype=np.int64),
                    slack=np.zeros(max(n_span, 1)))
    return out, ev


def _resumed_state(resume: TransientSnapshot, arms, dec, wraps, ev):
    """The stepper's `State` of a snapshot (copies), its arms' anchors, clutches, wraps and slack flags
    written back into the stepper's parts (arms, dec, wraps, ev: `drive`'s)."""
    from beltdyn.analysis import integrator as itg

    state = itg.State(q=resume.q.copy(), v=resume.v.copy(), a=resume.a.copy(), f0=resume.f0.copy(),
                      fd0=resume.fd0.copy(), F0=resume.F0.copy(), R0=resume.R0.copy(), scal=resume.scal.copy())
    arms.anchor[:] = resume.anchor
    if len(dec.hub):
        dec.slip[0] = resume.clutch[0]
        dec.torque[0] = resume.clutch[1]
    if len(wraps.wrap):
        for row, part in enumerate((wraps.anchor, wraps.limit, wraps.torque, wraps.preload, wraps.factored)):
            part[:] = resume.wrap_state[row]
        wraps.creep[:], wraps.ratio[:] = resume.wrap_state[6], resume.wrap_state[7]
    ev.slack[:] = resume.slack
    return state


def _timed(opts, clock: dict, th: np.ndarray, steps_before: float, seconds: float):
    """The step options after a stepper call of `seconds` that began at steps_before (th: the state's
    scal): its step budget about HANDOVER_SECONDS of wall time, and the factor's cost in residual
    evaluations (the refresh rule, `integrator.run_steps`) from the clock's totals, which it updates
    (factor, factors: the factors' time and count; stepping, iterations: the calls' time and evaluations
    but the first's, which may have loaded the kernels from numba's cache; counted, calls)."""
    from beltdyn.analysis import integrator as itg

    if th[itg.STEPS] > steps_before:
        per_step = seconds / (th[itg.STEPS] - steps_before)
        opts = opts._replace(max_steps=int(min(2000, max(10, HANDOVER_SECONDS / max(per_step, 1e-9)))))
    evaluations = th[itg.ITERS] + th[itg.STEPS]  # residual evaluations: one more than corrections per step
    if clock["calls"]:
        clock["stepping"] += seconds
        clock["iterations"] += evaluations - clock["counted"]
    clock["counted"], clock["calls"] = evaluations, clock["calls"] + 1
    if REFRESH and clock["iterations"] > 0 and clock["stepping"] > 0.0:
        opts = opts._replace(refresh=(clock["factor"] / clock["factors"]) / (clock["stepping"] / clock["iterations"]))
    return opts


def _no_convergence(problem: StepProblem, info: np.ndarray, h: float, min_step: float) -> SolverError:
    """The SolverError of a step that found no convergence at the smallest step h (info: `run_steps`'s
    time, scaled residual, worst DOF and iterations)."""
    dof = problem.labels[int(info[2])] if int(info[2]) < len(problem.q0) else "?"
    return SolverError(f"no convergence at t = {info[0]:.6g} s even with the step reduced to {h:.3g} s "
                       f"(transient.min_step = {min_step:g} s)", analysis="transient", step=f"t = {info[0]:.6g} s",
                       residual=float(info[1]), item=dof)


def _snapshot(state, arms, dec, wraps, slack: np.ndarray, events: list, at_factor: dict, run: _Run, *, fresh: bool,
              calm: int, min_step: float, refresh: float) -> TransientSnapshot:
    """The `TransientSnapshot` of `drive`'s stepper at an accepted step: the state, the stepper's parts (arms,
    dec, wraps: their anchors, clutches and wraps), the slack flags and the events so far, the state the
    factor was computed at, the run's counts and the step control (fresh factor, calm calls, smallest step,
    the refresh rule's factor cost)."""
    from beltdyn.analysis import integrator as itg

    th = state.scal
    return TransientSnapshot(
        q=_frozen(state.q), v=_frozen(state.v), a=_frozen(state.a), f0=_frozen(state.f0), fd0=_frozen(state.fd0),
        F0=_frozen(state.F0), R0=_frozen(state.R0), scal=_frozen(th), anchor=_frozen(arms.anchor),
        clutch=_frozen(np.stack([dec.slip[0], dec.torque[0]])),
        wrap_state=_frozen(np.array([wraps.anchor, wraps.limit, wraps.torque, wraps.preload, wraps.factored,
                                     wraps.sliding, wraps.creep, wraps.ratio]).reshape(8, -1)),
        slack=_frozen(slack), events=_frozen(np.concatenate(events) if events else np.zeros((0, 4))),
        factor_q=_frozen(at_factor["q"]), factor_v=_frozen(at_factor["v"]), factor_h=float(at_factor["h"]),
        factor_t=float(at_factor["t"]), fresh=bool(fresh), calm=int(calm), delivered=run.delivered,
        steps=int(th[itg.STEPS]), refactorizations=run.refactors, halvings=run.halvings, min_step=float(min_step),
        refresh=float(refresh))


def drive(problem: StepProblem, *, rho_inf: float, step: float, min_step: float, duration: float,
          output_interval: float, tolerance: float, max_iterations: int, on_batch: Callable,
          progress: Progress | None = None, batch: int = 256, n_span: int = 0,
          resume: TransientSnapshot | None = None, on_checkpoint: Callable | None = None,
          checkpoint_seconds: float = 0.0):
    """Integrate the problem: outputs in batches to on_batch(t, q, v, a, energy, reaction, clutch, wrap); returns
    (status, run bookkeeping, final scal, slack events). Raises SolverError when the step cannot be
    reduced further (the batches before the failure have been delivered); KeyboardInterrupt
    propagates after the last complete batch was delivered.

    Restart hooks: with on_checkpoint, every checkpoint_seconds of wall time (0: before every step
    call) at an accepted step, the samples so far are delivered and then on_checkpoint(snapshot) is
    called with the stepper's `TransientSnapshot` (its observer fields left at their defaults). With
    resume (such a snapshot), the run continues from it instead of the initial state: the same
    state, factor (recomputed at the state it was computed at), counts and slack events, so the
    samples after it are those of the uninterrupted run."""
    from beltdyn.analysis import integrator as itg

    am, af, beta, gamma = itg.alpha_parameters(rho_inf)
    n = len(problem.q0)
    arms = problem.arms if problem.arms is not None else itg.no_arms(n)
    tr = problem.transport if problem.transport is not None else itg.no_transport(n)
    dec = problem.decouplers if problem.decouplers is not None else itg.no_decouplers()
    wraps = problem.wraps if problem.wraps is not None else itg.no_wraps()
    chk = itg.Check(group=problem.groups, n_groups=int(problem.groups.max(initial=0)) + 1, tol=float(tolerance),
                    max_iter=int(max_iterations), noise=residual_noise(problem.belt))
    batch = max(batch, int(math.ceil(step / output_interval)) + 2)  # a step's samples always fit
    out, ev = _buffers(batch, n, max(len(problem.constraints.dof), 1), dec, wraps, n_span)
    all_events: list[np.ndarray] = []
    info = np.zeros(4)
    n_total_out = int(math.floor(duration / output_interval + 1e-9)) + 1
    opts = itg.StepOptions(am=am, af=af, beta=beta, gamma=gamma, t_stop=float(duration), dt_out=float(output_interval),
                           max_steps=2000, refresh=0.0)

    work = itg.workspace(n, problem.belt, problem.forcing, problem.constraints, chk.n_groups, arms)

    model = itg.StepperModel(belt=problem.belt, linear=problem.linear, forcing=problem.forcing,
                             constraints=problem.constraints, check=chk, arms=arms, transport=tr, decouplers=dec,
                             wraps=wraps)

    def advance(task, st, fac, fresh):  # the compiled stepper (`integrator.advance`), opts as they are now
        return itg.advance(task, st, model, opts, fac, fresh, out, ev, info, work)

    if resume is None:
        state = initial_state(problem, step, lambda st: advance(itg.START, st, itg.no_factor(), False))
    else:
        state = _resumed_state(resume, arms, dec, wraps, ev)
        if len(resume.events):
            all_events.append(np.array(resume.events))
        opts = opts._replace(refresh=float(resume.refresh))
    th = state.scal
    clock = {"factor": 0.0, "factors": 0, "stepping": 0.0, "iterations": 0.0, "counted": 0.0, "calls": 0}
    at_factor = {}  # the state the current factor was computed at (q, v, h, t): a snapshot's

    def new_factor(q=None, v=None, h=None, t=None):
        """The factor at the current state (or at the one given); its wall time feeds the refresh rule
        (`integrator.run_steps`)."""
        args = (state.q.copy() if q is None else q, float(th[itg.H]) if h is None else h,
                state.v.copy() if v is None else v, float(th[itg.T_NOW]) if t is None else t)
        started = time.perf_counter()
        got = problem.factor(*args)
        clock["factor"] += time.perf_counter() - started
        clock["factors"] += 1
        at_factor.update(q=args[0], h=args[1], v=args[2], t=args[3])
        return got

    run = _Run()
    if resume is None:
        fac = new_factor()
        fresh = True
        run.refactors = 1
        min_h = th[itg.H]
        calm = 0
    else:
        if len(wraps.wrap):  # (the factor's regime into sliding: the factor takes it, then the last evaluation's)
            wraps.sliding[:] = resume.wrap_state[4]
        fac = new_factor(np.array(resume.factor_q), np.array(resume.factor_v), resume.factor_h, resume.factor_t)
        if len(wraps.wrap):
            wraps.sliding[:] = resume.wrap_state[5]
        fresh, calm, min_h = bool(resume.fresh), int(resume.calm), float(resume.min_step)
        run.steps, run.refactors, run.halvings, run.delivered = (int(resume.steps), int(resume.refactorizations),
                                                                  int(resume.halvings), int(resume.delivered))

    def drain() -> None:
        k = int(out.n[0])
        take = min(k, n_total_out - run.delivered)
        out.n[0] = 0  # counted as delivered before the sink runs: an interrupt inside it cannot repeat them
        if take > 0:
            run.delivered += take
            on_batch(out.t[:take].copy(), out.q[:take].copy(), out.v[:take].copy(), out.a[:take].copy(),
                     out.energy[:take].copy(), out.reaction[:take].copy(), out.clutch[:take].copy(),
                     out.wrap[:take].copy())

    def collect_events() -> None:
        if ev.n[0]:
            all_events.append(ev.data[: int(ev.n[0])].copy())
            ev.n[0] = 0

    def snapshot() -> TransientSnapshot:
        collect_events()
        return _snapshot(state, arms, dec, wraps, ev.slack, all_events, at_factor, run, fresh=fresh, calm=calm,
                         min_step=min_h, refresh=opts.refresh)

    last_drain = last_checkpoint = time.perf_counter()
    try:
        while True:
            # a checkpoint: here every count and the factor belong to the accepted state (an interrupt
            # elsewhere in the loop leaves the previous checkpoint the last one)
            if on_checkpoint is not None and time.perf_counter() - last_checkpoint >= checkpoint_seconds:
                drain()
                on_checkpoint(snapshot())
                last_checkpoint = time.perf_counter()
            started, steps_before = time.perf_counter(), th[itg.STEPS]
            code = advance(itg.STEP, state, fac, fresh)
            now = time.perf_counter()
            opts = _timed(opts, clock, th, steps_before, now - started)
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
                drain()
                raise _no_convergence(problem, info, float(th[itg.H]), min_step)
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
                  status: Callable | None = None, resume: TransientSnapshot | None = None,
                  on_checkpoint: Callable[[TransientSnapshot], None] | None = None,
                  checkpoint_seconds: float = 0.0) -> TransientSummary:
    """Integrate, feeding (time (B,), {series: (B, ...)}) batches to `sink`.

    Raises SolverError (with the failure time, residual and DOF) when the step cannot be reduced
    further; the batches before the failure have been delivered. KeyboardInterrupt propagates after
    the last complete batch was delivered. `status(text)` is told about a first-time kernel compile.
    on_checkpoint(snapshot): every checkpoint_seconds of wall time, the full state (stepper and
    observers, `TransientSnapshot`) once the samples up to it reached the sink; resume: such a
    snapshot of the same system and options, the run continues from it (the sink then gets only the
    samples after it, and the summary covers the whole run).
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
    slip = wrap_slip(system, opts, static=static, setup=setup)
    if slip is None:  # (no wrap slips: the stepper's structures as set up)
        factor = factorizer(system, setup, opts.rho_inf, arms)
        problem = StepProblem(
            belt=setup.belt, linear=setup.linear, forcing=setup.forcing, constraints=setup.constraints,
            groups=setup.groups, q0=setup.q0, v0=setup.v0, labels=system.dof_labels, factor=factor,
            arms=arms, transport=tr, decouplers=stepper_decouplers(system))
    else:  # the pulleys' own rotations added (`transient_wraps`)
        parts = stepper_setup(slip, system, setup)
        wraps = stepper_wraps(slip, system, setup)
        arms = wrap_arms(slip, arms)
        factor = wrap_factorizer(system, setup, opts.rho_inf, arms, slip, wraps, perm=parts.pop("perm"),
                                 bandwidth=parts.pop("bandwidth"), hold=parts["constraints"].dof)
        labels = list(system.dof_labels)
        labels[slip.n_dof:slip.n_dof] = [f"pulley {system.layout.names[j]} rotation (behind its wrap)"
                                         for j in slip.pulleys]
        problem = StepProblem(**parts, labels=tuple(labels), factor=factor, arms=arms, wraps=wraps,
                              decouplers=stepper_decouplers(system))
    observer = Observers(system=system, setup=setup, slip=slip)
    if resume is not None:
        observer.restore(tension_low=resume.tension_low, tension_low_time=resume.tension_low_time,
                         tension_high=resume.tension_high, worst_slip=resume.worst_slip, stop_hit=resume.stop_hit)

    def checkpoint(snap: TransientSnapshot) -> None:
        on_checkpoint(replace(snap, tension_low=_frozen(observer.tension_low),
                              tension_low_time=_frozen(observer.tension_low_time),
                              tension_high=tuple(map(float, observer.tension_high)),
                              worst_slip=observer.worst_slip, stop_hit=observer.stop_hit))

    run, th, min_h, events = drive(
        problem, rho_inf=opts.rho_inf, step=opts.step, min_step=opts.min_step, duration=opts.duration,
        output_interval=opts.output_interval, tolerance=opts.tolerance, max_iterations=opts.max_iterations,
        on_batch=lambda *b: sink(b[0], observer.compute(*b)), progress=progress, batch=batch,
        n_span=system.belt.n_span, resume=resume, on_checkpoint=None if on_checkpoint is None else checkpoint,
        checkpoint_seconds=checkpoint_seconds)
    moved = float(th[itg.MOVED])
    error = float(th[itg.WORST]) / moved if moved > 0 else 0.0
    if error > ENERGY_LIMIT and float(th[itg.WORST]) > energy_roundoff(th):  # every sample has reached the sink:
        # the results so far stay, marked failed
        raise SolverError(f"energy balance error {error:.2e} of the energy moved ({moved:.3g} J) exceeds "
                          f"{ENERGY_LIMIT:.0%}: the step {opts.step:g} s is too long for this run; reduce transient.step",
                          analysis="transient", step=f"t = {float(th[itg.T_NOW]):.6g} s", residual=error)
    return TransientSummary(status="complete", steps=run.steps, refactorizations=run.refactors,
                            step_halvings=run.halvings, final_time=float(th[itg.T_NOW]), min_step=float(min_h),
                            slack_events=events, n_outputs=run.delivered, energy_error=error, energy_moved=moved,
                            warnings=accuracy_warnings(opts, energy_error=error, min_step=float(min_h),
                                                       excitation_frequency=setup.excitation_frequency)
                            + slip_warning(observer.worst_slip) + stop_warning(observer.stop_hit)
                            + tension_warnings(system, observer, events, static.mean_tension),
                            worst_slip_margin=observer.worst_slip, newton_iterations=int(th[itg.ITERS]))


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
                        springs=no_springs(), n_springs=0)
    Cm = np.zeros((n, n)) if C is None else np.asarray(C, dtype=float)
    lin = itg.Linear(K=itg.split(K, n), q_ref=np.zeros(n), C=itg.split(None if C is None else Cm, n), M=itg.split(M, n))
    forcing = itg.Forcing(constant=np.zeros(n), load_dof=np.zeros(0, dtype=np.int64), load_coef=np.zeros(0),
                          load_sig=np.zeros(0, dtype=np.int64), sig_params=np.zeros((0, 5)),
                          tab_ptr=np.zeros(1, dtype=np.int64), tab_t=np.zeros(0), tab_v=np.zeros(0),
                          nominal_mass=np.zeros(n), nominal_rotation=np.zeros(10), nominal_scale=0.0,
                          nominal_damping=np.zeros(n))
    cons = itg.Constraints(dof=np.zeros(0, dtype=np.int64), params=np.zeros((0, 10)))
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

