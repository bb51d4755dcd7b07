"""The wraps in the belt-length budget and the axial-law switch (issue 25, items 2, 3 and 5):
`belt.wraps = "creep" | "rigid"`, `belt.axial_law = "green-lagrange" | "linear"`.

Compared against: the belt's undeformed length (the stress-free lengths of spans and wraps add up to
belt.length), the closed form of a two-pulley fixed-centre drive under a steady torque (written here
from the capstan law and the linear bar law, integrated by hand), the closed form of the linear law
(a straight span under tension T has the stretch 1 + T/EA), the series of the Green-Lagrange law, the
issue's numbers for the FEAD example, and the running capstan law's own identity slip arc / wrap =
1 / slip margin."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from beltdyn.config import config_from_dict, load_config, with_overrides
from beltdyn.model.barlaw import bar_law
from beltdyn.pipeline import analyse
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"

EA, MU = 1.0e5, 0.5
R_A, R_C, D = 0.05, 0.1, 0.5  # driver A at the origin, driven C at (D, 0): fixed centres
L0 = 1.472  # the belt: 0.29 % shorter than its path (1.47625 m): about 290 N


def two_pulley(load: float, *, wraps: str = "creep", law: str = "linear", spans: str = "spring") -> dict:
    """A two-pulley drive on fixed centres (tension.mode = "length"), the load torque `load` (N m, counter-
    clockwise: negative brakes) on the driven pulley C, both spans of model `spans`."""
    raw = {"title": "two pulleys, fixed centres",
           "belt": {"length": L0, "EA": EA, "EI": 0.01, "mass_per_length": 0.1, "wraps": wraps, "axial_law": law},
           "pulleys": [{"name": "A", "center": [0.0, 0.0], "radius": R_A, "mass": 1.0, "inertia": 1e-3,
                        "driver": True, "friction": MU},
                       {"name": "C", "center": [D, 0.0], "radius": R_C, "mass": 2.0, "inertia": 4e-3,
                        "friction": MU}],
           "tension": {"mode": "length"},
           "spans": {"A-C": {"model": spans}, "C-A": {"model": spans}}}
    if load:
        raw["static"] = {"torque": [{"pulley": "C", "value": load}]}
    return raw


def _wrap_closed_form(R: float, beta: float, t_entry: float, t_exit: float) -> float:
    """Stress-free length of a wrap, linear law lambda = 1 + T/EA, at rest: the adhesion arc at the entry
    stretch, then the slip arc phi_s = |ln(T_x/T_e)| / mu with T = T_e exp(k phi), k = mu sign(T_x - T_e):
    int_0^phi_s dphi / (1 + (T_e/EA) e^(k phi)) = phi_s - ln((1 + T_x/EA) / (1 + T_e/EA)) / k."""
    if t_entry == t_exit:
        return R * beta / (1.0 + t_entry / EA)
    phi = abs(math.log(t_exit / t_entry)) / MU
    k = MU * math.copysign(1.0, t_exit - t_entry)
    return R * ((beta - phi) / (1.0 + t_entry / EA) + phi - math.log((1.0 + t_exit / EA) / (1.0 + t_entry / EA)) / k)


def closed_form_tensions(load: float, wraps: str) -> tuple[float, float]:
    """(T_0, T_1) of span A-C (the slack side, entering C) and C-A (the tight side, entering the driver A):
    T_1 - T_0 = -load / R_C (C's torque balance) and the budget L (1/lambda_0 + 1/lambda_1) + the wraps =
    L0 (creep: `_wrap_closed_form`; rigid: the wraps stretched with the belt as in mode "length",
    sum L_s / lambda_s = 2 L / lambda_fit, lambda_fit = path / L0)."""
    s = math.asin((R_C - R_A) / D)
    L = math.sqrt(D * D - (R_C - R_A) ** 2)
    beta_A, beta_C = math.pi - 2.0 * s, math.pi + 2.0 * s
    path = 2.0 * L + R_A * beta_A + R_C * beta_C
    dT = -load / R_C

    def budget(t0: float) -> float:
        t1 = t0 + dT
        spans = L / (1.0 + t0 / EA) + L / (1.0 + t1 / EA)
        if wraps == "rigid":
            return spans - 2.0 * L * L0 / path
        return spans + _wrap_closed_form(R_A, beta_A, t1, t0) + _wrap_closed_form(R_C, beta_C, t0, t1) - L0

    t0 = brentq(budget, 1.0, 2000.0, xtol=1e-14, rtol=1e-15)
    return t0, t0 + dT


@pytest.mark.parametrize("wraps", ["creep", "rigid"])
def test_two_pulley_drive_under_load_against_its_closed_form(wraps):
    # The span tensions of the fixed-centre drive at three loads equal the closed form to 1e-9; with creep
    # wraps the mean span tension rises with the load (the slip arcs hand the wraps' material to the spans
    # at a lower stretch), with rigid wraps it stays (it moves by the curvature of 1/lambda alone, O(dT^2/EA)).
    means = []
    for load in (0.0, -4.0, -8.0):
        st = analyse(config_from_dict(two_pulley(load, wraps=wraps))).static
        t0, t1 = closed_form_tensions(load, wraps)
        np.testing.assert_allclose(st.span_tension, [[t0, t0], [t1, t1]], rtol=1e-9, atol=0.0)
        assert not st.wraps.gross_slip.any()
        if wraps == "rigid":  # today's wrap: no slip arc, the rims at the driver's speed
            assert (st.wraps.slip_arc == 0.0).all() and (st.wraps.rim_speed_ratio == 1.0).all()
        elif load:
            assert st.wraps.slip_arc.min() > 0.0 and st.wraps.rim_speed_ratio[1] < 1.0  # C entered by the slack side
        means.append(0.5 * (t0 + t1))
    rise = np.diff(means)
    if wraps == "creep":
        assert (rise > 0.5).all(), means  # N per 4 N m: 1.7 and 1.7 N here
    else:
        assert np.abs(rise).max() < 0.05, means  # (dT^2 / (4 EA)-sized: 0.02 N at 80 N of split)


@pytest.mark.parametrize("spans", ["spring", "ancf"])
@pytest.mark.parametrize("wraps", ["creep", "rigid"])
def test_stress_free_lengths_of_spans_and_wraps_add_up_to_the_belt_length(spans, wraps):
    # The budget: sum of the spans' reference lengths + the wraps' stress-free lengths (/static
    # wrap_reference_length; R beta for rigid wraps in a mode that conserves the belt) = belt.length.
    run = analyse(config_from_dict(two_pulley(-6.0, wraps=wraps, law="green-lagrange", spans=spans)))
    total = run.system.belt.reference_length.sum() + run.static.wraps.stress_free_length.sum()
    if wraps == "creep":
        assert total == pytest.approx(L0, rel=1e-13, abs=0.0)
    fead = load_config(FEAD, [f"belt.wraps={wraps}"])
    run = analyse(fead)
    total = run.system.belt.reference_length.sum() + run.static.wraps.stress_free_length.sum()
    assert total == pytest.approx(fead.belt.length, rel=1e-13, abs=0.0)


def test_fead_spring_mode_tensions_drop_with_creep_wraps_as_the_issue_says():
    # Issue 25: in tension.mode = "spring" the rigid-wrap budget overstated every span tension of the FEAD
    # by about 23 N (6 %), the crank's slip margin 1.69 instead of 1.56. (The tensioner's spring takes the
    # belt's extra length, so the drop is the same on every span: the split by the torques is kept.)
    creep = analyse(load_config(FEAD)).static
    rigid = analyse(load_config(FEAD, ["belt.wraps=rigid"])).static
    drop = rigid.span_tension - creep.span_tension
    np.testing.assert_allclose(drop, drop[0, 0], rtol=1e-6)
    assert 20.0 < drop[0, 0] < 25.0
    crank = 0
    assert rigid.slip_margin[crank] == pytest.approx(1.69, abs=0.005)
    assert creep.slip_margin[crank] == pytest.approx(1.56, abs=0.01)


def test_slip_arc_over_wrap_is_one_over_the_slip_margin_at_a_belt_speed():
    # One centrifugal tension c = rho v^2 lambda(T_mean) in the slip arcs and in the margins (model.wraps,
    # model.slip): phi_s / beta = 1 / margin to round-off, at rest and at 25 m/s.
    for speed in (0.0, 25.0):
        raw = two_pulley(-6.0, law="green-lagrange")
        if speed:
            raw["running"] = {"belt_speed": speed}
        st = analyse(config_from_dict(raw)).static
        lay_wrap = st.wraps.slip_arc + st.wraps.adhesion_arc
        ratio = st.wraps.slip_arc / lay_wrap
        np.testing.assert_allclose(ratio, 1.0 / st.slip_margin, rtol=1e-12)


@pytest.mark.parametrize("spans", ["spring", "ancf"])
def test_linear_law_a_straight_span_under_tension_has_the_stretch_one_plus_T_over_EA(spans):
    # belt.axial_law = "linear": N = EA (lambda - 1), so each straight span's chord over its reference
    # length is 1 + T/EA (the closed form), for spring spans and ANCF spans (EI's share: the spans are
    # straight, the end gradients free).
    run = analyse(config_from_dict(two_pulley(-6.0, spans=spans)))
    T = run.static.span_tension.mean(axis=1)
    lam = run.layout.span_length / run.system.belt.reference_length
    np.testing.assert_allclose(lam, 1.0 + T / EA, rtol=1e-11, atol=0.0)


def test_the_two_laws_differ_by_three_halves_of_the_strain():
    # For one tension T (x = T/EA) the green-lagrange elongation e solves (1 + e)^3 - (1 + e) = 2x (numpy's
    # cubic roots here), e = x - 3/2 x^2 + 4 x^3 + O(x^4), the linear law's is x: the elongations differ by
    # 3/2 x - 4 x^2 of it, 1.04 % at the paper's 0.7 % strain (the issue's "0.5 % in stretch at 0.7 %
    # strain" is the figure at 0.35 %: 0.52 %).
    green, linear = bar_law("green-lagrange"), bar_law("linear")
    for x, differ in ((0.0035, 0.0052), (0.007, 0.0103)):
        e_g, e_l = green.stretch_for_tension(x * EA, EA) - 1.0, linear.stretch_for_tension(x * EA, EA) - 1.0
        root = max(r.real for r in np.roots([1.0, 0.0, -1.0, -2.0 * x]) if abs(r.imag) < 1e-12) - 1.0
        assert e_g == pytest.approx(root, rel=1e-9)
        assert e_l == pytest.approx(x, rel=1e-15)
        assert (e_l - e_g) / e_l == pytest.approx(1.5 * x - 4.0 * x * x, abs=20.0 * x ** 3)
        assert (e_l - e_g) / e_l == pytest.approx(differ, abs=5e-5)


def test_the_axial_law_switches_every_span_model_and_the_statics():
    # One switch: the ANCF elements and the spring spans of one drive take belt.axial_law, and the static
    # tensions follow it: on fixed centres with the same belt the stretches are (nearly) the same, and the
    # green-lagrange force EA (lambda^2 - 1) lambda / 2 exceeds the linear EA (lambda - 1) by 3/2 (lambda - 1).
    cfg = load_config(FEAD, ['spans.AC-ALT.model="spring"'])
    for law in ("green-lagrange", "linear"):
        system = analyse(with_overrides(cfg, [f"belt.axial_law={law}"]), static=False).system
        assert system.belt.elements.axial_law == law
        assert system.springs.axial_law == law
        assert system.wraps.axial_law == law
    lin = analyse(config_from_dict(two_pulley(0.0, law="linear"))).static.mean_tension
    gl = analyse(config_from_dict(two_pulley(0.0, law="green-lagrange"))).static.mean_tension
    assert gl / lin - 1.0 == pytest.approx(1.5 * lin / EA, rel=0.02)


@pytest.mark.parametrize("key,value", [("belt.wraps", "elastic"), ("belt.axial_law", "hooke")])
def test_other_values_are_a_key_path_error(tmp_path, key, value):
    r = subprocess.run([*BELTDYN, "static", str(FEAD), "--set", f"{key}={value}", "-o", str(tmp_path / "x.h5")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert f"{key}: must be one of" in r.stderr and "Traceback" not in r.stderr


def test_resolved_configuration_shows_both_keys():
    from beltdyn.config import resolved_toml

    text = resolved_toml(load_config(FEAD))
    assert 'wraps = "creep"' in text and 'axial_law = "green-lagrange"' in text


def test_a_transient_with_the_linear_law_keeps_its_energy_balance():
    # The paper bench with belt.axial_law = "linear" (the ANCF spans' compiled kernel on its linear branch),
    # C's rotation fluctuating at 45 Hz, rho_inf = 1 and a 5e-5 s step: the stepper's energy balance closes
    # within 1e-3 of the energy exchanged (as tests/test_transient.py asks of the default law).
    from beltdyn.analysis.transient import run_transient
    from beltdyn.config import config_to_dict

    raw = config_to_dict(load_config(ROOT / "configs" / "paper" / "bench_T200.toml", ["belt.axial_law=linear"]))
    raw["transient"] = {"duration": 0.1, "step": 5e-5, "output_interval": 5e-4, "rho_inf": 1.0,
                        "rotation": [{"pulley": "C", "amplitude": 1e-3, "frequency": 45.0, "fluctuation_ramp": 0.02}],
                        "spectrum": {"enabled": False}}
    cfg = config_from_dict(raw)
    run = analyse(cfg)
    assert run.system.belt.elements.axial_law == "linear"
    got: list = []
    summary = run_transient(run.system, run.static, cfg.transient, sink=lambda t, batch: got.append(batch["energy"]))
    assert summary.status == "complete"
    e = np.concatenate(got)
    exchanged = np.ptp(e[:, 0]) + np.ptp(e[:, 1]) + np.abs(e[:, 2]).max()
    assert exchanged > 0.0
    assert np.abs(e[:, 4]).max() <= 1e-3 * exchanged
