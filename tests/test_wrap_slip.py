"""Creep and slip of the wraps in time (issue 25 item 4, `analysis.transient_wraps`, docs/wraps.md).

The drive: the paper bench (two pulleys, T = 200 N, 10 elements per span), the large pulley C driven
(prescribed rotation), the small pulley A driven by the belt through a wrap with friction mu = 0.3, and
a load torque on A. The closed forms, written here apart from the code:

- Coulomb sliding: while the wrap slides it transmits exactly the capstan torque of the running belt,
  M_cap = R (T_max - c)(1 - exp(-mu beta)) (Euler-Eytelwein, T_tight - c = (T_slack - c) exp(mu beta),
  so T_tight - T_slack = (T_tight - c)(1 - exp(-mu beta)); c = 0 at rest), with T_max the larger of the
  two recorded end tensions at A; the pulley's own rotation obeys J theta'' = L + M_cap: a load L above
  the capstan torque decelerates it at (|L| - M_cap) / J.
- Sticking: below the capstan torque the pulley is in equilibrium with the wrap, J theta'' = 0, so the
  transmitted torque equals the load, and the wrap does not creep on the pulley: psi - theta stays put.
- Energy: the run-up's balance, kinetic + strain - work + dissipated (friction work included) = const.
- Without a friction value or with belt.wraps = "rigid" the stepper is the one without slip.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from histories import run_histories  # tests/histories.py

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
MU = 0.3
QUIET = ["transient.spectrum.enabled=false", "transient.damping.rayleigh_mass=0.0",
         "transient.output_interval=1e-3", 'belt.wraps="creep"']  # (the paper bench's own wraps are rigid)


def _run(sets, record_state=False):
    """(summary, histories, analysis) of a bench transient with the settings `sets`."""
    from beltdyn.pipeline import analyse, transient_start

    extra = ["transient.record.full_state=true"] if record_state else []
    cfg = load_config(BENCH, QUIET + sets + extra)
    run = analyse(cfg, compiled=True)
    system, static = transient_start(run)
    histories, summary = run_histories(system, static, cfg.transient, time_key="t")
    return summary, histories, system, static


def _capstan(span_tension, wrap, radius, c=0.0):
    """M_cap (B,) at pulley A (index 0: span 1 leaves it, span 2 arrives at its end)."""
    t_max = np.maximum(span_tension[:, 1, 1], span_tension[:, 0, 0])
    return radius * (t_max - c) * (1.0 - np.exp(-MU * wrap))


def test_a_load_above_the_capstan_torque_decelerates_the_pulley_at_the_load_less_the_capstan_torque():
    L = -8.0  # N m on A, clockwise; the capstan torque at rest is ~4.5 N m (6.2 once the tight side tightens)
    summary, h, system, _ = _run([f"pulleys[0].friction={MU}", "transient.duration=0.05",
                                  "transient.rotation=[{pulley='C', speed=0.0}]",
                                  f"transient.torque=[{{pulley='A', constant={L}, ramp_time=0.005}}]"])
    assert summary.status == "complete"
    J = load_config(BENCH).pulleys[0].inertia
    lay = system.layout
    t, w = h["t"], h["pulley_speed"][:, 0]
    cap = _capstan(h["span_tension"], lay.wrap_angle[0], lay.radius[0])
    sel = t >= 0.01
    assert np.all(h["wrap_sliding"][sel, 0] == 1.0)
    # the speed change over the window against the integral of (L + M_cap) / J (the capstan torque of the
    # recorded tensions swings by ~10 % in the window: the belt on the sliding wrap, rho R^2 beta, and its
    # spans vibrate after the load's ramp, so a straight line's slope is not the mean deceleration)
    ts, ws = t[sel], w[sel]
    expected = np.trapezoid((L + cap[sel]) / J, ts)
    assert abs((ws[-1] - ws[0]) / expected - 1.0) < 0.01  # measured: 5e-4
    # the transmitted torque is the capstan torque of the tensions (the stepper's: the elastic end force of
    # the previous step; the recorded joint reactions carry the spans' vibration, +-0.8 % sample by sample)
    assert abs(np.mean(h["wrap_torque"][sel, 0]) / np.mean(cap[sel]) - 1.0) < 1e-3  # measured: 2e-5
    assert np.all(h["slip_speed"][sel, 0] > 0.0)  # the belt on the wrap runs ahead of the falling pulley
    assert np.isnan(h["wrap_torque"][:, 1]).all()  # C has no friction value: never slips
    assert summary.energy_error < 1e-3


def test_below_the_capstan_torque_the_wrap_sticks_without_drift():
    L = -3.0
    summary, h, system, _ = _run([f"pulleys[0].friction={MU}", "transient.duration=0.3",
                                  "transient.rotation=[{pulley='C', speed=0.0}]",
                                  f"transient.torque=[{{pulley='A', constant={L}, ramp_time=0.03}}]",
                                  "transient.damping.rayleigh_mass=20.0"], record_state=True)
    assert summary.status == "complete"
    assert not np.any(h["wrap_sliding"][:, 0])
    t = h["t"]
    psi = h["q"][:, system.rot_dof[0]]  # the wrap's angle (the belt's side of the joint)
    theta = h["pulley_angle"][:, 0]  # the pulley's own rotation
    slip = psi - theta
    M = h["wrap_torque"][:, 0]
    # all of it the elastic part: psi - theta = z + M / k_b with the anchor z fixed (the drive rings after
    # the load's ramp, A's rotation against the spans at ~80 Hz): a straight line in M, no creep
    slope, z = np.polyfit(M, slip, 1)
    assert slope > 0.0 and 0.0 < np.abs(slip).max() < 2e-3
    assert np.max(np.abs(slip - (z + slope * M))) < 1e-3 * np.ptp(slip)
    late = t >= 0.05  # J theta'' = 0 on average over the decaying ringing (20 periods): M = -L
    assert abs(np.mean(M[late]) / -L - 1.0) < 1e-3


def test_a_run_up_that_slides_keeps_the_energy_balance_with_the_friction_work():
    # C ramps to 150 rad/s in 0.1 s: A (2.7 x faster) needs J alpha ~ 7 N m plus the load, more than the
    # capstan torque: the wrap slides during the ramp, and sticks again after it
    summary, h, system, _ = _run([f"pulleys[0].friction={MU}", "transient.duration=0.2",
                                  "transient.rotation=[{pulley='C', speed=150.0, ramp_time=0.1}]",
                                  "transient.torque=[{pulley='A', constant=-1.0, ramp_time=0.005}]"])
    assert summary.status == "complete"
    t = h["t"]
    assert np.any(h["wrap_sliding"][t < 0.1, 0] == 1.0)
    e = h["energy"]
    moved = summary.energy_moved
    assert moved > 1.0  # J: the run-up's kinetic energy
    assert np.max(np.abs(e[:, 4])) / moved < 1e-3  # the balance error (measured: 4e-6)
    assert np.max(e[:, 3]) > 0.05 * moved  # the friction work is a real part of it


def test_steady_running_transmits_the_static_torque_at_the_static_slip_arc():
    # The belt at 10 m/s (C at 98.4 rad/s from the static equilibrium at speed), A loaded by the static
    # accessory torque 2 N m: the transient stays at the static creep solution: the wrap transmits the
    # static torque and its slip arc is the static one (the capstan law with the centrifugal part).
    summary, h, system, static = _run([f"pulleys[0].friction={MU}", "transient.duration=0.05",
                                       "transient.rotation=[{pulley='C', speed=98.425}]",
                                       "pulleys[1].driver=true", "static.torque=[{pulley='A', value=-2.0}]"])
    assert summary.status == "complete"
    assert not np.any(h["wrap_sliding"][:, 0])
    assert np.max(np.abs(h["wrap_torque"][:, 0] / 2.0 - 1.0)) < 1e-6  # measured: 2e-10
    arc = static.wraps.slip_arc[0]
    assert arc > 0.0
    assert np.max(np.abs(h["slip_arc"][:, 0] / arc - 1.0)) < 1e-6  # measured: 8e-10


def test_rigid_wraps_or_no_friction_run_the_stepper_without_slip():
    # rigid wraps with a friction value: no slip part, every history bit-identical to the same rigid drive
    # without friction (which has none either); creep wraps without a friction value: no slip part
    common = ["transient.duration=0.01", "transient.rotation=[{pulley='C', speed=0.0, amplitude=1e-3, "
              "frequency=45.0}]", "transient.torque=[{pulley='A', constant=-8.0, ramp_time=0.005}]"]
    _, ref, _, _ = _run(common + ["belt.wraps='rigid'"])
    _, got, _, _ = _run(common + ["belt.wraps='rigid'", "pulleys[0].friction=0.3"])
    assert "wrap_torque" not in got and "slip_speed" not in got
    assert set(ref) <= set(got) <= set(ref) | {"slip_margin"}
    for k in ref:
        assert np.array_equal(ref[k], got[k], equal_nan=True), k
    _, creep, _, _ = _run(common)  # (creep wraps, no friction value)
    assert "wrap_torque" not in creep and "slip_speed" not in creep


def test_a_run_that_slips_resumed_at_each_checkpoint_continues_the_same_run(monkeypatch):
    # the wraps' state (anchors, limits, torques, the factor's regime) travels in the snapshot: from each
    # checkpoint the samples after it are the uninterrupted run's (the factor recomputed at the state it was
    # computed at, in the regime it held). (Without the refresh rule: it follows the wall clock, so with it the
    # Newton iterates of a resumed run differ within the tolerance, tests/test_decoupler.py; since a stick-slip
    # transition no longer takes a new factor, this run's factors age, and the rule would refresh them.)
    import beltdyn.analysis.transient as tr
    from beltdyn.analysis.transient import run_transient, snapshot_bytes, snapshot_from_bytes
    from beltdyn.pipeline import analyse, transient_start

    monkeypatch.setattr(tr, "REFRESH", False)

    cfg = load_config(BENCH, QUIET + [f"pulleys[0].friction={MU}", "transient.duration=0.15",
                                      "transient.rotation=[{pulley='C', speed=150.0, ramp_time=0.1}]",
                                      "transient.torque=[{pulley='A', constant=-1.0, ramp_time=0.005}]"])
    drive = analyse(cfg, compiled=True)

    def run(**kw):
        system, static = transient_start(drive)
        got: list = []
        # (batches of 16 samples: the stepper hands over, and a checkpoint is taken, every 16 ms of the run; a
        # stick-slip transition no longer returns to Python)
        summary = run_transient(system, static, cfg.transient, sink=lambda t, b: got.append((t, b)), batch=16, **kw)
        return summary, np.concatenate([g[0] for g in got]), {k: np.concatenate([g[1][k] for g in got])
                                                              for k in got[0][1]}

    snaps: list = []
    whole, t_ref, ref = run(on_checkpoint=snaps.append, checkpoint_seconds=0.0)
    assert len(snaps) >= 2 and np.any(ref["wrap_sliding"][:, 0] == 1.0)
    for snap in snaps[1:]:
        part, t, got = run(resume=snapshot_from_bytes(snapshot_bytes(snap)))
        k = snap.delivered
        np.testing.assert_array_equal(t, t_ref[k:])
        for name, r in ref.items():  # (as tests/test_resume.py: the round-off of the solves, 1e-12 measured)
            scale = float(np.max(np.abs(r[np.isfinite(r)]), initial=0.0))  # (finite values: a margin may be inf)
            np.testing.assert_allclose(got[name], r[k:], rtol=1e-9, atol=1e-9 * scale, err_msg=name)
        assert part.steps == whole.steps
