"""The belt-length budget of the statics' prediction (`analysis.static.tension.settled_budget`): its Newton
stops on the quadratic remainder of its last step, so its answer is checked here against each bar law's
definition solved independently (closed forms), at rest and on a running belt."""

from __future__ import annotations

import numpy as np
import pytest

from beltdyn.analysis.static.tension import settled_budget
from beltdyn.model.barlaw import bar_law

EA = 1.2e5
L = np.array([0.31, 0.084, 0.22, 0.15, 0.4])
SPLIT = np.array([0.0, 120.0, -40.0, 35.0, 80.0])


@pytest.mark.parametrize("shrink", [1e-4, 3e-3, 0.05])
@pytest.mark.parametrize("centrifugal", [0.0, 36.0])
def test_linear_law_meets_its_closed_form(shrink, centrifugal):
    """Linear law N = EA (lambda - 1): lambda_s = 1 + T_s / EA exactly, so the budget sum L_s / lambda_s and the
    split T_s - rho v^2 lambda_s = T_ref + split_s are checked on the tensions returned alone."""
    total = float(L.sum()) * (1.0 - shrink)
    T, _ = settled_budget(L, SPLIT, total, EA, law=bar_law("linear"), centrifugal=centrifugal)
    lam = 1.0 + T / EA
    base = T - centrifugal * lam  # T_ref + split_s
    np.testing.assert_allclose(base - base[0], SPLIT - SPLIT[0], rtol=0.0, atol=1e-9 * EA)
    assert float((L / lam).sum()) == pytest.approx(total, rel=1e-13)


@pytest.mark.parametrize("shrink", [1e-4, 3e-3, 0.05])
def test_green_lagrange_on_a_running_belt_meets_its_definition(shrink):
    """Green-Lagrange law with rho v^2 = 36 N: stretches from numpy's cubic roots of EA (lambda^3 - lambda) / 2 = T,
    independently of the bar law's Newton; T_s - rho v^2 lambda_s = T_ref + split_s and sum L_s / lambda_s = total."""
    total = float(L.sum()) * (1.0 - shrink)
    T, _ = settled_budget(L, SPLIT, total, EA, centrifugal=36.0)
    lam = np.array([max(r.real for r in np.roots([1.0, 0.0, -1.0, -2.0 * t / EA]) if abs(r.imag) < 1e-12) for t in T])
    base = T - 36.0 * lam
    np.testing.assert_allclose(base - base[0], SPLIT - SPLIT[0], rtol=0.0, atol=1e-9 * EA)
    assert float((L / lam).sum()) == pytest.approx(total, rel=1e-13)
