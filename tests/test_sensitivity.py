"""Frequency sensitivities from the eigenvectors (`analysis.sensitivity`, through `study.fit.Model`):
against a closed form on two degrees of freedom, and against central finite differences of whole
analyses of the paper bench (Richardson-extrapolated, so their own error is ~1e-9)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.analysis.sensitivity import (
    eigenvalue_derivatives,
    equilibrium_moves,
    frequency_derivatives,
)
from beltdyn.config import load_config
from beltdyn.study.fit import FitParameter, Model, parameter_value, system_at_state
from beltdyn.study.measured import MeasuredData

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs/paper/bench_T200.toml"


def measured(freq, kinds, orders, spans=None, case_keys=(), cases=((),), case=None) -> MeasuredData:
    """A MeasuredData made in memory (rows as given)."""
    m = len(freq)
    return MeasuredData(file="<synthetic>", line=np.arange(1, m + 1), frequency=np.asarray(freq, dtype=float),
                        kind=tuple(kinds), order=np.asarray(orders),
                        span=np.zeros(m, int) if spans is None else np.asarray(spans),
                        weight=np.ones(m), scatter=0.01 * np.asarray(freq, dtype=float), reference=np.full(m, np.nan),
                        case_keys=tuple(case_keys), case=np.zeros(m, int) if case is None else np.asarray(case),
                        cases=cases)


# the bench's lowest modes: six transverse pairs, the rotational and the translational mode
BENCH_ROWS = measured([30.5, 61.2, 92.3, 100.7, 124.0, 156.6, 178.5, 190.1],
                      ["transverse"] * 3 + ["rotational"] + ["transverse"] * 2 + ["translational", "transverse"],
                      [1, 2, 3, 1, 4, 5, 1, 6])


def test_eigenvalue_derivative_two_masses_closed_form():
    # m1, m2 on springs k1 (ground-m1) and k2 (m1-m2): det(K - lam M) = F(lam) = m1 m2 lam^2 -
    # (m2 (k1 + k2) + m1 k2) lam + k1 k2 = 0, so d lam / dp = -(dF/dp) / (dF/dlam) (implicit
    # differentiation of the characteristic polynomial), for p = k2 and p = m1.
    k1, k2, m1, m2 = 3.0e4, 1.2e4, 2.0, 0.7
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    M = np.diag([m1, m2])
    from scipy.linalg import eigh

    lam, phi = eigh(K, M)
    dF_dlam = 2 * m1 * m2 * lam - (m2 * (k1 + k2) + m1 * k2)
    d_k2 = -(-(m2 + m1) * lam + k1) / dF_dlam
    d_m1 = -(m2 * lam ** 2 - k2 * lam) / dF_dlam
    dK_k2 = np.array([[1.0, -1.0], [-1.0, 1.0]])
    np.testing.assert_allclose(eigenvalue_derivatives(phi.T, lam, dK_k2, np.zeros((2, 2))), d_k2, rtol=1e-12)
    dM_m1 = np.diag([1.0, 0.0])
    np.testing.assert_allclose(eigenvalue_derivatives(phi.T, lam, np.zeros((2, 2)), dM_m1), d_m1, rtol=1e-12)
    f = np.sqrt(lam) / (2 * math.pi)  # df = dlam / (8 pi^2 f)
    np.testing.assert_allclose(frequency_derivatives(phi.T, f, dK_k2, np.zeros((2, 2))),
                               d_k2 / (8 * math.pi ** 2 * f), rtol=1e-12)


def _model(cfg, keys, data=BENCH_ROWS) -> tuple[Model, np.ndarray]:
    params = tuple(FitParameter(key=k, initial=parameter_value(cfg, k)) for k in keys)
    return Model(cfg, data, params), np.array([p.initial for p in params])


KEYS = ["belt.EI", "belt.mass_per_length", "pulleys[0].inertia", "pulleys.C.inertia",
        "pulleys[0].bearing_stiffness", "pulleys[0].mass", "belt.EA", "tension.target"]


def test_bench_sensitivities_match_finite_differences_of_whole_analyses():
    # d f / d p of the eight measured-like rows (transverse pairs as their means, rotational,
    # translational) for each parameter, against central differences of whole analyses (static +
    # modal) at relative steps 1e-3 and 5e-4, Richardson-extrapolated (error O(h^4)): within 1e-6 of
    # the largest derivative of the column. EI, mass per length, inertias, the slide's spring and mass
    # are taken from the eigenvectors at the fixed state; EA and the tension move the equilibrium
    # (the fit differences whole analyses for them, and says so).
    cfg = load_config(BENCH)
    model, p0 = _model(cfg, KEYS)
    _, runs = model.frequencies(p0)
    D, method = model.derivatives(p0, runs)
    assert method == ("modal",) * 6 + ("analyses",) * 2
    for j, key in enumerate(KEYS):
        est = []
        for rel in (1e-3, 5e-4):
            h = rel * p0[j]
            lo, hi = p0.copy(), p0.copy()
            lo[j] -= h
            hi[j] += h
            est.append((model.frequencies(hi)[0] - model.frequencies(lo)[0]) / (2 * h))
        fd = (4 * est[1] - est[0]) / 3
        scale = float(np.abs(fd).max())
        assert scale > 0, key
        assert float(np.abs(D[:, j] - fd).max()) <= 1e-6 * scale, (key, D[:, j], fd)


def test_bench_sensitivities_have_the_physical_signs():
    # A stiffer belt in bending raises the transverse frequencies, more for the higher orders (EI k^4 of
    # the pinned beam under tension: the relative sensitivity grows as n^2); a heavier belt lowers
    # every transverse frequency by half its relative change (f ~ rho^-1/2 for a string); the slide's
    # spring raises the translational mode only appreciably.
    cfg = load_config(BENCH)
    model, p0 = _model(cfg, ["belt.EI", "belt.mass_per_length", "pulleys[0].bearing_stiffness"])
    f0, runs = model.frequencies(p0)
    D, _ = model.derivatives(p0, runs)
    rel = D * p0[None, :] / f0[:, None]  # d ln f / d ln p
    trans = np.array([k == "transverse" for k in BENCH_ROWS.kind])
    assert np.all(rel[trans, 0] > 0) and np.all(np.diff(rel[trans, 0]) > 0)
    np.testing.assert_allclose(rel[trans, 1], -0.5, atol=0.02)
    k = BENCH_ROWS.kind.index("translational")
    assert rel[k, 2] > 0.1 and np.all(np.abs(np.delete(rel[:, 2], k)) < 0.05 * rel[k, 2])


def test_equilibrium_moves_with_EA_not_with_EI():
    # At the bench's equilibrium (tension set by moving pulley A): the spans' axial force at a fixed
    # state changes with EA (so the tension target moves the equilibrium), not with EI (straight spans
    # carry no bending moment) nor with the slide's spring rate (its preload is the unknown of the
    # tension step).
    from beltdyn.config import with_overrides
    from beltdyn.pipeline import analyse

    cfg = load_config(BENCH)
    run = analyse(cfg, modal=True)
    q = run.static.q

    def pair(key: str, rel: float = 1e-3):
        v = parameter_value(cfg, key)
        return tuple(system_at_state(with_overrides(cfg, [f"{key}={v * (1 + s * rel)!r}"]), run) for s in (-1, 1))

    assert equilibrium_moves(run.system, *pair("belt.EA"), q)
    assert not equilibrium_moves(run.system, *pair("belt.EI"), q)
    assert not equilibrium_moves(run.system, *pair("pulleys[0].bearing_stiffness"), q)
    assert not equilibrium_moves(run.system, *pair("belt.mass_per_length"), q)


def test_mass_under_gravity_moves_the_equilibrium():
    # With gravity the belt's weight grows with its mass per length: the sag changes, so its
    # derivative is taken by whole analyses, and still matches their finite differences.
    from beltdyn.config import with_overrides

    cfg = with_overrides(load_config(BENCH), ["model.gravity=[0.0, -9.81]"])
    model, p0 = _model(cfg, ["belt.mass_per_length"])
    _, runs = model.frequencies(p0)
    D, method = model.derivatives(p0, runs)
    assert method == ("analyses",)
    h = 1e-3 * p0[0]
    fd = (model.frequencies(p0 + h)[0] - model.frequencies(p0 - h)[0]) / (2 * h)
    assert float(np.abs(D[:, 0] - fd).max()) <= 1e-5 * float(np.abs(fd).max())


@pytest.mark.parametrize("key", ["pulleys.T.arm_stiffness", "belt.EI"])
def test_tensioner_drive_sensitivities_match_finite_differences(key):
    # The three-pulley drive with a tensioner arm (tension set by turning the arm): the arm's spring
    # and EI from the eigenvectors (the mass matrix J^T M J of the arm kinematics at the state),
    # against Richardson-extrapolated central differences of whole analyses, 1e-6 of the column.
    from beltdyn.pipeline import analyse

    cfg = load_config(ROOT / "configs/examples/three_pulley_tensioner.toml")
    modal = analyse(cfg, modal=True).modal
    first = {}
    for k, o, s, f in zip(modal.kind, modal.order.tolist(), modal.span.tolist(), modal.frequency):
        first.setdefault((k, o, s), f)
    rows = list(first.items())[:8]
    data = measured([f for _, f in rows], [k for (k, _, _), _ in rows], [o for (_, o, _), _ in rows],
                    spans=[s for (_, _, s), _ in rows])
    model, p0 = _model(cfg, [key], data)
    _, runs = model.frequencies(p0)
    D, method = model.derivatives(p0, runs)
    assert method == ("modal",)
    est = []
    for rel in (1e-3, 5e-4):
        h = rel * p0[0]
        est.append((model.frequencies(p0 + h)[0] - model.frequencies(p0 - h)[0]) / (2 * h))
    fd = (4 * est[1] - est[0]) / 3
    assert float(np.abs(D[:, 0] - fd).max()) <= 1e-6 * float(np.abs(fd).max()), (D[:, 0], fd)
