"""The transient's outputs and observers: the recorded quantities of each batch of output states
(`Observers`) and the warnings on what they saw (slack and near-slack spans, strain, arm stops, slip)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.model.decouplers import decouplers_of
from beltdyn.model.slip import drive_centrifugal_tension, pulley_tensions, required_friction, slip_margin
from beltdyn.model.system import System
from beltdyn.model.wraps import entry_exit, slip_arc
from beltdyn.analysis.transient_setup import TransientSetup, nominal_rotation, transport_speed
from beltdyn.analysis.transient_wraps import system_coordinates


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


def stop_warning(hit) -> tuple[str, ...]:
    if hit is None:
        return ()
    t, name, phi = hit
    return (f"the arm of pulley {name} is beyond its stops (arm_range) at t = {t:.6g} s ({phi:.6g} rad): the transient "
            f"does not model the stops, so the results from there on assume a free arm",)


def slip_warning(worst: tuple[float, float, str]) -> tuple[str, ...]:
    margin, t, name = worst
    if margin < 1.0:
        return (f"pulley {name} slips: slip margin {margin:.3g} < 1 at t = {t:.6g} s",)
    return ()


def decoupler_series(system: System, setup: TransientSetup, t, q, v, clutch) -> dict[str, np.ndarray]:
    """rotor_speed and decoupler_torque (B, n_dec) of the decouplers (`model.decouplers`, pulley order): the
    one-way ones' torques as the stepper's clutch gave them (clutch (B, n_one_way)), the others' k phi + c phi'."""
    found = decouplers_of(system.components)
    rotor = np.array([c.dofs[1] for c in found])
    hub = np.array([c.dofs[0] for c in found])
    sd_nom = nominal_rotation(setup, t)[1] if setup.nom_scale else np.zeros(len(t))
    speed = v[:, rotor] + sd_nom[:, None] * setup.u_nom[rotor]
    k = np.array([c.spring for c in found])
    c_ = np.array([c.viscous for c in found])
    torque = k * (q[:, hub] - q[:, rotor]) + c_ * (v[:, hub] - v[:, rotor])
    one_way = np.array([c.one_way for c in found])
    if one_way.any():
        torque[:, one_way] = clutch
    return {"rotor_speed": speed, "decoupler_torque": torque}


# ------------------------------------------------------------------------------------ observers
@dataclass
class Observers:
    """The recorded quantities of output states (B, n), vectorized over the batch."""

    system: System
    setup: TransientSetup
    slip: object = None  # transient_wraps.WrapSlip: the wraps that may slip (the stepper's q has their hubs)

    def __post_init__(self) -> None:
        self.names = {s.name for s in self.setup.series}
        self.worst_slip = (np.inf, np.nan, "")  # smallest slip margin, its time and pulley
        n_span = self.system.belt.n_span
        self.tension_low = np.full(n_span, np.inf)  # (n_span,) smallest end tension of each span, N
        self.tension_low_time = np.full(n_span, np.nan)  # (n_span,) s, when
        self.tension_high = (-np.inf, np.nan)  # largest end tension of any span (N) and when (s)
        self.stop_hit: tuple[float, str, float] | None = None  # first time an arm is beyond a stop, its pulley, angle

    def restore(self, *, tension_low: np.ndarray, tension_low_time: np.ndarray, tension_high: tuple[float, float],
                worst_slip: tuple[float, float, str], stop_hit: tuple[float, str, float] | None) -> None:
        """The running extrema of an earlier part of the run (a resumed transient, `TransientSnapshot`)."""
        self.tension_low = np.array(tension_low, dtype=float)
        self.tension_low_time = np.array(tension_low_time, dtype=float)
        self.tension_high = (float(tension_high[0]), float(tension_high[1]))
        self.worst_slip = (float(worst_slip[0]), float(worst_slip[1]), str(worst_slip[2]))
        self.stop_hit = stop_hit

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

    def compute(self, t, q, v, a, energy, reaction, clutch=None, wrap=None) -> dict[str, np.ndarray]:
        """The recorded series of the output states q, v, a (B, n) at the times t (B,), their energy terms
        (B, 5), constraint reactions (B, n_con), clutch (B, n_one_way) the one-way decouplers' torques and,
        with slipping wraps, the wraps' bristle torques, limits, creep rates and rim speed ratios wrap (B, 4, k)
        (the stepper's q then has the pulleys' own rotations after the system's), from the stepper."""
        if self.slip is None:
            return self._compute(t, q, v, a, energy, reaction, clutch)
        sl = self.slip
        out = self._compute(t, *(system_coordinates(sl, x) for x in (q, v, a)), energy, reaction, clutch)
        return out | self._wrap_series(t, q, v, wrap, out)

    def _wrap_series(self, t, q, v, wrap, out) -> dict[str, np.ndarray]:
        """The slipping wraps' series (module `transient_wraps`; NaN on the other pulleys) and the pulleys'
        own rotation for pulley_angle and pulley_speed (the wrap angle is the belt's)."""
        sysm, setup, names, sl = self.system, self.setup, self.names, self.slip
        B, n = len(t), sysm.layout.n
        j = sl.pulleys
        got: dict[str, np.ndarray] = {}
        if "pulley_angle" in names or "pulley_speed" in names:
            s_nom, sd_nom = (nominal_rotation(setup, t)[:2] if setup.nom_scale else (np.zeros(B), np.zeros(B)))
            ur = setup.u_nom[sl.wrap]
            if "pulley_angle" in names:
                got["pulley_angle"] = out["pulley_angle"].copy()
                got["pulley_angle"][:, j] = q[:, sl.hub] + s_nom[:, None] * ur
            if "pulley_speed" in names:
                got["pulley_speed"] = out["pulley_speed"].copy()
                got["pulley_speed"][:, j] = v[:, sl.hub] + sd_nom[:, None] * ur

        def per_pulley(values):
            full = np.full((B, n), np.nan)
            full[:, j] = values
            return full

        got["slip_speed"] = per_pulley(v[:, sl.wrap] - v[:, sl.hub])
        torque, limit = wrap[:, 0, : len(j)], wrap[:, 1, : len(j)]
        got["wrap_torque"] = per_pulley(torque)
        got["wrap_sliding"] = per_pulley((limit > 0.0) & (np.abs(torque) >= limit * (1.0 - 1e-9)))
        creep, ratio = wrap[:, 2, : len(j)], wrap[:, 3, : len(j)]  # (the stepper's creep law, docs/wraps.md)
        got["rim_speed_ratio"] = per_pulley(ratio)
        got["creep_power"] = per_pulley(torque * creep)
        if "slip_arc" in names:
            speed = transport_speed(setup, t)[0]
            t_in, t_out = pulley_tensions(out["span_tension"])
            te, tx = entry_exit(t_in, t_out, float(np.mean(speed)))
            # the slip margin's centrifugal part (the static's: one c of the drive, at its mean tension)
            c = drive_centrifugal_tension(sysm, speed, out["span_tension"].mean(axis=(1, 2)))
            got["slip_arc"] = per_pulley(slip_arc(te[:, j], tx[:, j], sysm.pulley_friction[j],
                                                  np.asarray(c, dtype=float).reshape(-1, 1)))
        return got

    def _compute(self, t, q, v, a, energy, reaction, clutch=None) -> dict[str, np.ndarray]:
        sysm, setup, names = self.system, self.setup, self.names
        belt = sysm.belt
        out: dict[str, np.ndarray] = {}
        if "rotor_speed" in names:
            out.update(decoupler_series(sysm, setup, t, q, v, clutch))
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
                    T = out["span_tension"]
                    c = drive_centrifugal_tension(sysm, transport_speed(setup, t)[0], T.mean(axis=(1, 2)))
                    m = slip_margin(required_friction(T, sysm.layout.wrap_angle, c), sysm.pulley_friction)
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
