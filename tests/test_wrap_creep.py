"""Creep in time (issue 25, docs/wraps.md "Creep in time"): a sticking wrap's pulley turns at the creep law's
rim speed ratio, and the creep dissipates the static creep power loss.

The drive: the paper bench (two pulleys, T = 200 N, 10 elements per span) running at 10 m/s, the large
pulley C driven (prescribed rotation, the static's driver), the small pulley A loaded by a steady 2 N m
(below its capstan torque: its wrap sticks), both wraps with friction mu = 0.3. The closed forms, written
here apart from the code:

- Rim speed ratio (Grashof, Firbank): the rim of a sticking pulley moves with the belt at its wrap's entry
  (the adhesion arc), at v lambda(T_e): A's rim speed over C's is lambda(T_e,A) / lambda(T_e,C), lambda the
  stretch of the Green-Lagrange bar law at the true axial force T, the root of EA (lambda^2 - 1) lambda / 2
  = T (a cubic, solved here with numpy.roots), T_e the entry tensions of the static creep solution.
- Creep power: what the driver puts in less what the load takes out, M_C omega_C - M_A omega_A (torque x
  speed), is what the wraps' creep dissipates: the static `creep_power_loss` of both wraps together
  (v (T_t - T_s)^2 / EA to first order).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from beltdyn.config import load_config
from histories import run_histories  # tests/histories.py

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
MU = 0.3
RUNNING = ["transient.spectrum.enabled=false", "transient.damping.rayleigh_mass=0.0",
           "transient.output_interval=1e-3", 'belt.wraps="creep"', f"pulleys[0].friction={MU}",
           f"pulleys[1].friction={MU}", "pulleys[1].driver=true", "static.torque=[{pulley='A', value=-2.0}]",
           "transient.rotation=[{pulley='C', speed=98.425}]", "transient.record.full_state=true"]


def _run(sets):
    from beltdyn.pipeline import analyse, transient_start

    cfg = load_config(BENCH, RUNNING + sets)
    run = analyse(cfg, compiled=True)
    system, static = transient_start(run)
    histories, summary = run_histories(system, static, cfg.transient, time_key="t")
    return summary, histories, system, static, cfg


def _green_lagrange_stretch(T: float, EA: float) -> float:
    """The stretch lambda > 0 with EA (lambda^2 - 1) lambda / 2 = T (the real root near 1)."""
    roots = np.roots([0.5 * EA, 0.0, -0.5 * EA, -T])
    real = roots[np.abs(roots.imag) < 1e-9].real
    return float(real[np.argmin(np.abs(real - 1.0))])


def test_a_sticking_driven_pulley_turns_at_the_static_rim_speed_ratio_and_creep_dissipates_its_power():
    summary, h, system, static, cfg = _run(["transient.duration=0.1"])
    assert summary.status == "complete"
    assert not np.any(h["wrap_sliding"])  # both wraps stick
    wraps = static.wraps
    te = wraps.entry_tension  # (the static creep solution at speed)
    EA = float(cfg.belt.EA)
    exact = _green_lagrange_stretch(te[0], EA) / _green_lagrange_stretch(te[1], EA)
    assert exact < 1.0 and abs(wraps.rim_speed_ratio[0] / exact - 1.0) < 1e-12  # the static's law, checked
    first_order = (1.0 + te[0] / EA) / (1.0 + te[1] / EA)
    assert abs((1.0 - exact) / (1.0 - first_order) - 1.0) < 0.02  # (strain 0.2 %: second order 3/2 x 0.2 %)
    R = np.abs(system.layout.radius)
    t = h["t"]
    w_a, w_c = h["pulley_speed"][:, 0], h["pulley_speed"][:, 1]
    ratio = np.mean(np.abs(w_a)) * R[0] / (np.mean(np.abs(w_c)) * R[1])  # A's rim speed over C's
    creep = 1.0 - exact  # 4.4e-4: the belt's strain change over A's wrap
    # the run starts in the static creep state and stays there: the mean speed over the whole run
    assert abs((1.0 - ratio) / creep - 1.0) < 1e-6  # measured: 2e-12
    assert np.max(np.abs(h["rim_speed_ratio"][:, 0] / exact - 1.0)) < 1e-9  # the stepper's ratio (measured: 6e-13)
    assert np.all(h["rim_speed_ratio"][:, 1] == 1.0)  # the driver's own
    # creep power: torque x speed (driver in, load out) = the static creep loss of both wraps. The static takes
    # its belt speed v for the belt's mass-flow speed; the transient's is the driver's rim speed c = R_C omega_C
    # (the prescribed rotation), the belt's mass flow c / lambda(T_e,C): the static's loss over lambda(T_e,C)
    # (0.19 % less, the tight side's strain). Left: 1e-4, the static's own T_e - T_x at A against its torque
    # 2 N m / R_A (53.3386 N against 53.3333 N).
    p_in = np.mean(np.abs(h["driver_torque"] * w_c))
    p_out = np.mean(np.abs(2.0 * w_a))
    loss = float(np.sum(wraps.creep_power_loss)) / _green_lagrange_stretch(te[1], EA)
    assert loss > 0.0
    p_creep = np.nansum(h["creep_power"], axis=1)  # the wraps' own M z' (A's: C's hub is the reference)
    assert abs(np.mean(p_creep) / (p_in - p_out) - 1.0) < 1e-6  # measured: 7e-10
    assert abs(np.mean(p_creep) / loss - 1.0) < 1e-3  # measured: 1e-4
    assert np.all(h["creep_power"][:, 1] == 0.0)
    assert summary.energy_error < 1e-6  # measured: 3e-12
    dissipated = h["energy"][-1, 3]
    assert abs(dissipated / (np.mean(p_creep) * t[-1]) - 1.0) < 1e-3  # the creep work is what is dissipated


def test_after_a_load_step_the_pulley_settles_at_the_stretch_ratio_of_the_new_tensions():
    # From the steady creep state at 2 N m, 1.5 N m more on A ramped in over 0.1 s (still below the capstan
    # torque): the wrap keeps sticking, the tension difference grows from 53 to 93 N, and A settles at the rim
    # speed ratio of the new entry tensions (the recorded span tensions' means, the exact stretch ratio of the
    # bar law solved here), 1 - ratio from 4.4e-4 to 7.7e-4. The window means carry the drive's ringing
    # after the ramp (A against the spans, lightly damped): measured 2e-4 of the creep from t = 0.3 s on.
    summary, h, system, _, cfg = _run(["transient.duration=0.6", "transient.record.span_tension=true",
                                       "transient.torque=[{pulley='A', constant=-1.5, ramp_time=0.1}]"])
    assert summary.status == "complete" and summary.energy_error < 1e-6  # measured: 5e-9
    assert not np.any(h["wrap_sliding"])
    EA = float(cfg.belt.EA)
    R = np.abs(system.layout.radius)
    t, T = h["t"], h["span_tension"]
    late = t >= 0.3
    # A is entered by span 1 (C -> A) at its end, C by span 0 at its end (the belt runs along the span order)
    exact = (_green_lagrange_stretch(np.mean(T[late, 1, 1]), EA) / _green_lagrange_stretch(np.mean(T[late, 0, 1]), EA))
    ratio = (np.mean(np.abs(h["pulley_speed"][late, 0])) * R[0]) / (np.mean(np.abs(h["pulley_speed"][late, 1])) * R[1])
    assert 1.0 - exact > 1.5 * 4.4e-4  # the creep grew with the load
    assert abs((1.0 - ratio) / (1.0 - exact) - 1.0) < 1e-2
    assert abs(np.mean(h["wrap_torque"][late, 0]) / 3.5 - 1.0) < 1e-3  # J theta'' = 0 on average: the load
