"""Slip margins: the capstan (Euler-Eytelwein) formula on hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beltdyn.model.slip import pulley_tensions, required_friction, slip_margin


def test_pulley_tensions_take_the_arriving_span_end_and_the_departing_span_start():
    T = np.array([[10.0, 11.0], [20.0, 21.0], [30.0, 31.0]])  # span s: pulley s -> s + 1
    t_in, t_out = pulley_tensions(T)
    assert list(t_in) == [31.0, 11.0, 21.0] and list(t_out) == [10.0, 20.0, 30.0]


def test_capstan_ratio_and_margin_by_hand():
    # Two pulleys, tight span 300 N, slack 100 N: mu_req = ln 3 / wrap on each pulley; with mu = 0.5 and
    # wraps pi and 2 rad the margins are 0.5 pi / ln 3 and 1 / ln 3 (hand computation), to 1e-14.
    T = np.array([[300.0, 300.0], [100.0, 100.0]])
    wrap = np.array([math.pi, 2.0])
    mu = required_friction(T, wrap)
    assert np.allclose(mu, [math.log(3) / math.pi, math.log(3) / 2.0], rtol=1e-14)
    m = slip_margin(mu, np.array([0.5, 0.5]))
    assert np.allclose(m, [0.5 * math.pi / math.log(3), 1.0 / math.log(3)], rtol=1e-14)


def test_slack_equal_and_missing_friction():
    T = np.array([[200.0, 200.0], [-1.0, -1.0], [200.0, 200.0]])
    wrap = np.array([2.0, 2.0, 2.0])
    mu = required_friction(T, wrap)
    assert np.isinf(mu[1]) and np.isinf(mu[2]) and mu[0] == 0.0  # pulley 0 sees 200 / 200
    m = slip_margin(mu, np.array([0.3, 0.3, np.nan]))
    assert m[0] == np.inf and m[1] == 0.0 and np.isnan(m[2])


def test_histories_vectorize():
    rng = np.random.default_rng(0)
    T = 100.0 + 50.0 * rng.random((7, 3, 2))
    wrap = np.array([2.5, 2.0, 1.8])
    mu = required_friction(T, wrap)
    assert mu.shape == (7, 3)
    assert np.allclose(mu[4], required_friction(T[4], wrap), rtol=1e-15)


def test_equal_to_round_off_needs_no_friction_a_real_difference_does():
    # |T1 - T2| <= 1e-9 max|T|: mu_required 0, margin inf (round-off of the span tensions, `ROUND_OFF`);
    # 1e-6 apart: ln(1 + 1e-6) / wrap needed, margin finite (hand computation of the capstan formula)
    T = np.array([[300.0, 300.0 * (1 + 1e-12)], [300.0, 300.0 * (1 + 1e-6)]])
    wrap = np.array([2.0, 2.0])
    mu = required_friction(T, wrap)
    assert mu[1] == 0.0  # pulley 1: arriving 300 (1 + 1e-12), leaving 300
    assert mu[0] == pytest.approx(math.log1p(1e-6) / 2.0, rel=1e-9)  # pulley 0: arriving 300 (1 + 1e-6)
    m = slip_margin(mu, np.array([0.3, 0.3]))
    assert m[1] == np.inf and 0.0 < m[0] < np.inf
    # a history: the same rule on every state, and with the centrifugal part taken off
    hist = np.stack([T, T])
    assert np.array_equal(required_friction(hist, wrap)[1], mu)
    mu_c = required_friction(hist, wrap, centrifugal=50.0)
    assert mu_c[0, 1] == 0.0 and mu_c[0, 0] == pytest.approx(math.log(300.0003 - 50.0) / 2.0 - math.log(250.0) / 2.0,
                                                           rel=1e-6)


@pytest.mark.parametrize("model", ["ancf", "spring"])
def test_idlers_of_a_drive_have_an_infinite_margin(model):
    """The FEAD example's idler (IDL) and tensioner (TEN) carry no torque in the statics: margin inf (it was
    ~1e12 with ANCF spans from the round-off of ln(T1/T2)); the loaded pulleys keep a finite margin."""
    from pathlib import Path

    from beltdyn.config import load_config
    from beltdyn.pipeline import analyse

    fead = Path(__file__).resolve().parents[1] / "configs" / "examples" / "fead_4cyl.toml"
    cfg = load_config(fead)
    if model == "spring":
        cfg = load_config(fead, [f'spans.{n}.model="spring"' for n in cfg.span_names])
    st = analyse(cfg).static
    names = [p.name for p in cfg.pulleys]
    for j, name in enumerate(names):
        if name in ("IDL", "TEN"):
            assert st.required_friction[j] == 0.0 and st.slip_margin[j] == np.inf, name
        else:
            assert 0.0 < st.required_friction[j] < np.inf and 1.0 < st.slip_margin[j] < 1e3, name


# ------------------------------------------------------------------ the running belt (issue 25, item 3)
def test_capstan_law_of_a_running_belt_at_impending_gross_slip():
    # Closed form: at impending gross slip (T_tight - c) / (T_slack - c) = exp(mu beta), c = rho v^2 lambda.
    # Tensions built from it give mu_required = mu and margin 1 to 1e-10 (c = 0.12 kg/m (25 m/s)^2 1.004).
    from beltdyn.model.slip import centrifugal_tension

    c = centrifugal_tension(0.12, 25.0, 1.004)
    assert c == pytest.approx(0.12 * 625.0 * 1.004, rel=1e-15)
    mu, wrap, slack = 0.45, np.array([2.7, 3.4]), 160.0
    tight = c + (slack - c) * np.exp(mu * wrap[0])  # pulley 0 takes the whole ratio: span 1 -> 0
    T = np.array([[tight, tight], [slack, slack]])  # span 0: pulley 0 -> 1 (tight), span 1: 1 -> 0 (slack)
    req = required_friction(T, wrap, c)
    assert req[0] == pytest.approx(mu, rel=1e-10)
    assert slip_margin(req, np.array([mu, mu]))[0] == pytest.approx(1.0, rel=1e-10)
    # without the centrifugal part the ratio is smaller, the friction needed lower (the old, optimistic law)
    assert required_friction(T, wrap)[0] < mu
    # a wrap whose slack tension is all centrifugal is slack on the pulley: margin 0
    assert np.isinf(required_friction(np.array([[300.0, 300.0], [c, c]]), wrap, c)).all()


def test_a_history_takes_one_centrifugal_tension_per_state():
    # (B, n_span, 2) tensions with c (B,): each state as on its own (the same formula, state by state)
    T = np.array([[[300.0, 300.0], [100.0, 100.0]], [[320.0, 320.0], [120.0, 120.0]]])
    wrap = np.array([2.0, 3.0])
    c = np.array([10.0, 40.0])
    mu = required_friction(T, wrap, c)
    for b in range(2):
        assert np.array_equal(mu[b], required_friction(T[b], wrap, c[b]))
    assert mu[1, 0] == pytest.approx(math.log((320.0 - 40.0) / (120.0 - 40.0)) / 2.0, rel=1e-14)


def test_the_fead_crank_margin_falls_with_speed():
    """The FEAD example's crank (the driver, the largest torque) at rest, 20 m/s and 40 m/s: the static at
    speed carries the centrifugal tension in every span, and with it removed in the capstan law the
    margin falls with speed (the load torques being the same): it grew (1.69 -> 2.81) with ln(T1/T2).
    Independent check: mu_required from the static's own span tensions and the closed form
    c = rho v^2 lambda(T_mean)."""
    from pathlib import Path

    from beltdyn.config import load_config
    from beltdyn.model.barlaw import stretch_for_tension
    from beltdyn.model.slip import belt_density
    from beltdyn.pipeline import analyse

    fead = Path(__file__).resolve().parents[1] / "configs" / "examples" / "fead_4cyl.toml"
    margins = []
    for v in (0.0, 20.0, 40.0):
        run = analyse(load_config(fead, [f"running.belt_speed={v}"]))
        st, sysm = run.static, run.system
        j = sysm.driver
        margins.append(st.slip_margin[j])
        c = belt_density(sysm) * v * v * stretch_for_tension(st.mean_tension, sysm.EA)
        t_in, t_out = st.span_tension[-1, 1], st.span_tension[0, 0]
        expected = math.log((max(t_in, t_out) - c) / (min(t_in, t_out) - c)) / sysm.layout.wrap_angle[j]
        assert st.required_friction[j] == pytest.approx(expected, rel=1e-12)
    assert margins[0] > margins[1] > margins[2]
