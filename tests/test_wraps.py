"""The creep law of the wraps (`beltdyn.model.wraps`) against closed forms: Euler-Eytelwein at
impending gross slip, the slip arc against the slip margin of `model.slip`, the stress-free length and
the creep loss of the linear bar law integrated by hand, the energy balance of a loop of wraps, the rim
speed ratio of a solved two-pulley drive against the exact stretch ratio of its span tensions."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.model.barlaw import stretch_for_tension
from beltdyn.model.slip import required_friction, slip_margin
from beltdyn.model.wraps import (creep_power_loss, rim_speed_ratio, slip_arc, stress_free_length, wrap_state)

ROOT = Path(__file__).resolve().parents[1]
EA = 120000.0


def linear_stretch(T, EA):
    """The linear bar law's inverse: lambda = 1 + T / EA."""
    return 1.0 + np.asarray(T, dtype=float) / EA


@pytest.mark.parametrize("c", [0.0, 37.5])
def test_euler_eytelwein_at_impending_gross_slip(c):
    """Bisection on the gross-slip flag alone (slip arc > wrap) for the entry tension at which a wrap
    of beta = 2.7 rad, mu = 0.35 starts to slip under an exit tension of 180 N: the tension ratio with
    the centrifugal part removed equals exp(mu beta) to 1e-10 (Euler-Eytelwein)."""
    mu, beta, t_x = 0.35, 2.7, 180.0
    lo, hi = t_x, 10.0 * t_x
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        arc = slip_arc(np.array([mid]), np.array([t_x]), np.array([mu]), c)[0]
        lo, hi = (lo, mid) if arc > beta else (mid, hi)
    assert (hi - c) / (t_x - c) == pytest.approx(math.exp(mu * beta), rel=1e-10)


def test_slip_arc_over_wrap_is_one_over_the_slip_margin():
    """phi_s / beta = 1 / margin, the margin from `model.slip` (mu / (ln((T1 - c)/(T2 - c)) / beta)),
    on both sides of gross slip and for either sense of the tension step."""
    t_in = np.array([420.0, 150.0, 300.0, 900.0])
    t_out = np.array([150.0, 420.0, 290.0, 100.0])
    wrap = np.array([2.9, 1.1, 0.6, 3.3])
    mu = np.array([0.4, 0.5, 0.3, 0.45])
    c = 12.0
    span = np.stack([t_out, np.roll(t_in, -1)], axis=1)  # span j: start t_out[j], end t_in[j+1]
    margin = slip_margin(required_friction(span, wrap, centrifugal=c), mu)
    arc = slip_arc(t_in, t_out, mu, c)
    assert np.allclose(arc / wrap, 1.0 / margin, rtol=1e-13, atol=0.0)
    assert (arc > wrap).tolist() == (margin < 1.0).tolist()


def test_no_slip_arc_where_tensions_equal_or_no_friction_and_inf_where_slack():
    arc = slip_arc(np.array([300.0, 300.0, 300.0, 300.0]), np.array([300.0 * (1 + 1e-12), 200.0, -5.0, 200.0]),
                   np.array([0.3, np.nan, 0.3, 0.0]))
    assert arc.tolist() == [0.0, 0.0, np.inf, np.inf]


def test_stress_free_length_of_the_linear_law_by_hand():
    """Linear law lambda = 1 + T/EA: the slip arc's int dphi / (A + B e^(-mu phi)) = (phi + ln((A + B
    e^(-mu phi)) / (A + B)) / mu) / A, A = 1 + c/EA, B = (T_e - c)/EA; the adhesion arc at lambda(T_e)."""
    R, beta, mu, c = 0.05, 2.8, 0.4, 20.0
    t_e, t_x = 650.0, 260.0
    phi = math.log((t_e - c) / (t_x - c)) / mu
    A, B = 1.0 + c / EA, (t_e - c) / EA
    expected = R * (beta - phi) / (1.0 + t_e / EA) + R * (phi + math.log((A + B * math.exp(-mu * phi)) / (A + B)) / mu) / A
    arc = slip_arc(np.array([t_e]), np.array([t_x]), np.array([mu]), c)
    got = stress_free_length(np.array([R]), np.array([beta]), np.array([t_e]), np.array([t_x]), arc, EA, c,
                             stretch=linear_stretch)[0]
    assert got == pytest.approx(expected, rel=1e-14)
    # and a wrap without a step in tension: its arc length at the one stretch, any law
    same = stress_free_length(np.array([R]), np.array([beta]), np.array([t_e]), np.array([t_e]), np.array([0.0]), EA)
    assert same[0] == pytest.approx(R * beta / stretch_for_tension(t_e, EA), rel=1e-15)


def test_creep_loss_of_the_linear_law_and_the_energy_balance_of_a_loop():
    """Linear law: P = v (T_e - T_x)^2 / (2 EA). Any law: the losses of the wraps of a closed loop add up
    to the power the belt delivers to the pulleys, sum (T_e - T_x) v lambda(T_e)."""
    v = 14.0
    t_e, t_x = np.array([700.0, 260.0, 330.0]), np.array([260.0, 330.0, 700.0])  # a loop: T_x of j = T_e of j+1
    lin = creep_power_loss(t_e, t_x, v, EA, stretch=linear_stretch)
    assert np.allclose(lin, v * (t_e - t_x) ** 2 / (2 * EA), rtol=1e-13, atol=0.0)
    green = creep_power_loss(t_e, t_x, v, 8000.0)  # a soft belt: the law's curvature matters
    delivered = float(((t_e - t_x) * v * stretch_for_tension(t_e, 8000.0)).sum())
    assert green.sum() == pytest.approx(delivered, rel=1e-12)
    assert creep_power_loss(t_e, t_x, 0.0, EA).tolist() == [0.0, 0.0, 0.0]


def test_rigid_wraps_are_todays_model():
    st = wrap_state(t_in=np.array([300.0, 200.0]), t_out=np.array([200.0, 300.0]), radius=np.array([0.05, 0.1]),
                    wrap=np.array([2.5, 3.78]), friction=np.array([0.3, 0.3]), EA=EA, mass_per_length=0.1,
                    belt_speed=10.0, driver=0, model="rigid")
    assert st.slip_arc.tolist() == [0.0, 0.0] and st.rim_speed_ratio.tolist() == [1.0, 1.0]
    assert np.array_equal(st.stress_free_length, np.array([0.05 * 2.5, 0.1 * 3.78]))


def test_rim_speed_ratio_of_a_two_pulley_drive_is_the_stretch_ratio_of_its_span_tensions():
    """The smoke two-pulley drive solved under 15 N m on C: the rim speed of C over the driver A's is
    lambda(T of the span entering C) / lambda(T of the span entering A), the exact Green-Lagrange
    stretches computed here from the solved span tensions by the cubic's closed (trigonometric) form."""
    from beltdyn.config import load_config
    from beltdyn.pipeline import analyse

    cfg = load_config(ROOT / "configs" / "smoke" / "two_pulley.toml",
                      ["static.torque=[{pulley='C', value=15.0}]", "pulleys.A.friction=0.5",
                       "pulleys.C.friction=0.5"])
    st = analyse(cfg).static
    T = st.span_tension  # span 0: A -> C, span 1: C -> A (the belt's travel along the span order)
    assert abs(T[0, 0] - T[1, 0]) > 50.0  # a real tension step

    def cardano(t):  # lambda^3 - lambda - 2 t / EA = 0: its largest root (trigonometric form, three real roots)
        return 2.0 / math.sqrt(3.0) * math.cos(math.acos(3.0 * math.sqrt(3.0) * t / EA) / 3.0)

    expected = cardano(T[0, 1]) / cardano(T[1, 1])
    assert st.wraps.rim_speed_ratio[0] == 1.0
    assert st.wraps.rim_speed_ratio[1] == pytest.approx(expected, rel=1e-13)
    lam = stretch_for_tension(np.array([T[1, 1], T[0, 1]]), EA)
    assert np.allclose(rim_speed_ratio(np.array([T[1, 1], T[0, 1]]), 0, EA), lam / lam[0], rtol=1e-15)


def test_a_pulley_without_friction_never_slips_but_creeps():
    """Pulley 1 has no friction value: no slip arc (mu -> inf) but the creep loss, which does not depend on
    mu; pulley 0 (mu = 0.3) has both. Each loss is the linear-law closed form v (T_e - T_x)^2 / (2 EA) to the
    law's curvature (1e-2 at 0.3 % strain), and the two add up to the power the belt delivers,
    sum_j (T_e,j - T_x,j) v lambda(T_e,j) (1e-12: the balance of the module docstring)."""
    st = wrap_state(t_in=np.array([300.0, 200.0]), t_out=np.array([200.0, 300.0]), radius=np.array([0.05, 0.1]),
                    wrap=np.array([2.5, 3.78]), friction=np.array([0.3, np.nan]), EA=EA, mass_per_length=0.0,
                    belt_speed=10.0, driver=0)
    assert st.slip_arc[1] == 0.0 and st.adhesion_arc[1] == 3.78
    assert st.slip_arc[0] == pytest.approx(math.log(1.5) / 0.3, rel=1e-15)
    assert st.creep_power_loss.tolist() == pytest.approx([10.0 * 100.0 ** 2 / (2 * EA)] * 2, rel=1e-2)
    te = np.array([300.0, 200.0])
    delivered = np.sum((te - np.array([200.0, 300.0])) * 10.0 * stretch_for_tension(te, EA))
    assert st.creep_power_loss.sum() == pytest.approx(delivered, rel=1e-12)
