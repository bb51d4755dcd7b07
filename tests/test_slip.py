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
