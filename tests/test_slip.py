"""Slip margins: the capstan (Euler-Eytelwein) formula on hand-computed cases."""

from __future__ import annotations

import math

import numpy as np

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
