"""Spring spans (`model.springs.SpringSpans`): the one numpy implementation against the compiled
`spring_kernel` on random states (force, damping, energy, smallest force: 1e-12 relative), and
against an independent span-by-span computation of its static end forces and tensions (the formula
the former Python-float path wrote: N = EA eps lam along the chord, the lumped ends' weight)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.model import spring_kernel as sk
from beltdyn.model.system import build_system

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"
ALL = ("CRK-AC", "AC-ALT", "ALT-TEN", "TEN-WP", "WP-PS", "PS-IDL", "IDL-CRK")


def _system(spans, law="green-lagrange"):
    cfg = load_config(FEAD, [f'spans.{n}.model="spring"' for n in spans] + [f"belt.axial_law={law}"])
    return build_system(cfg).with_belt(damping_axial=3e-5)


@pytest.fixture(scope="module", params=[(ALL, "green-lagrange"), (("AC-ALT", "TEN-WP", "IDL-CRK"), "green-lagrange"),
                                        (ALL, "linear")], ids=["all-spring", "mixed", "all-spring-linear"])
def system(request):
    return _system(*request.param)


def test_kernel_equals_numpy_on_random_states(system):
    """Per state: the kernel's elastic and damping forces, energy and per-span smallest S = EA eps equal the
    numpy spans' (1e-12 relative to the largest entry); the energy's derivative in a rotation is the force
    (central differences, 1e-7 relative)."""
    sp = system.springs
    data = sk.spring_data(sp, 3e-5)
    rng = np.random.default_rng(26)
    n = system.n_p
    for _ in range(20):
        p = 2e-3 * rng.standard_normal(n)
        v = rng.standard_normal(n)
        f_el, f_d, gross = np.zeros(n + 1), np.zeros(n + 1), np.zeros(n + 1)
        sk.spring_forces(data, np.append(p, 0.0), np.append(v, 0.0), f_el, f_d, gross, True)
        ref = sp.force(p)
        assert np.abs(f_el[:-1] - ref).max() <= 1e-12 * np.abs(ref).max()
        X, Xd = sp.positions(p), sp.positions_batch(v[None], offset=False)[0]
        u = sp.axial(X)[0]
        Nd = sp.damping_force(X, Xd)
        ref_d = sp.reduce_vector(np.concatenate([-Nd[:, None] * u, Nd[:, None] * u], axis=1))
        assert np.abs(f_d[:-1] - ref_d).max() <= 1e-12 * np.abs(ref_d).max()
        assert sk.spring_energy(data, np.append(p, 0.0)) == pytest.approx(sp.strain_energy(p), rel=1e-12)
        lam = sp.axial(X)[2]
        low = np.full(sp.n_span, np.inf)
        sk.spring_min_force(data, np.append(p, 0.0), low)
        S = (sp.EA * 0.5 * (lam * lam - 1.0) if sp.axial_law == "green-lagrange"  # second Piola-Kirchhoff force,
             else sp.EA * (lam - 1.0) / lam)  # or the linear law's N / lambda, written out here
        assert np.abs(low[sp.span] - S).max() <= 1e-12 * np.abs(S).max()
        assert np.isinf(np.delete(low, sp.span)).all()
    i, h = int(system.rot_dof[1]), 1e-7  # the energy's derivative is the force (central differences)
    dp = np.zeros(n)
    dp[i] = h
    dU = (sp.strain_energy(p + dp) - sp.strain_energy(p - dp)) / (2 * h)
    assert dU == pytest.approx(sp.force(p)[i], rel=1e-7)


def test_static_ends_equal_a_span_by_span_computation(system):
    """static_ends (the one numpy path) against the spans one by one on floats, 1e-12 relative (N = EA eps lam
    amplifies the round-off of the chord by 1 / eps ~ 1e3)."""
    sp = system.springs
    g = np.array([0.3, -9.81])
    rng = np.random.default_rng(7)
    for _ in range(5):
        p = 1e-3 * rng.standard_normal(system.n_p)
        F, T, NL = sp.static_ends(p, g)
        F_ref, T_ref, NL_ref = np.zeros((sp.n_span, 2, 2)), np.zeros((sp.n_span, 2)), 0.0
        for k, ((xa, ya, xb, yb), L) in enumerate(zip(sp.positions(p).tolist(), sp.reference_length.tolist())):
            dx, dy = xb - xa, yb - ya
            l = math.sqrt(dx * dx + dy * dy)
            ux, uy, lam = dx / l, dy / l, l / L
            N = sp.EA * 0.5 * (lam * lam - 1.0) * lam if sp.axial_law == "green-lagrange" else sp.EA * (lam - 1.0)
            m = 0.5 * sp.rho * L
            f0 = (-N * ux - m * g[0], -N * uy - m * g[1])
            f1 = (N * ux - m * g[0], N * uy - m * g[1])
            s = sp.span[k]
            F_ref[s] = (f0, f1)
            T_ref[s] = (-(f0[0] * ux + f0[1] * uy), f1[0] * ux + f1[1] * uy)
            NL_ref += N * L
        assert np.abs(F - F_ref).max() <= 1e-12 * np.abs(F_ref).max()
        assert np.abs(T - T_ref).max() <= 1e-12 * np.abs(T_ref).max()
        assert NL == pytest.approx(NL_ref, rel=1e-12)
        X = sp.positions(p)[None]
        F_b = sp.end_forces(X, None, g)
        assert np.array_equal(F_b[0], F) and np.array_equal(sp.end_tensions(X, F_b)[0], T)


def test_tension_integral_gradient_by_central_differences(system):
    sp = system.springs
    p = 1e-3 * np.random.default_rng(3).standard_normal(system.n_p)
    val, grad = sp.tension_integral(p)
    h = 1e-7
    fd = np.array([(sp.tension_integral(p + h * e, gradient=False)[0] - sp.tension_integral(p - h * e, gradient=False)[0])
                   / (2 * h) for e in np.eye(system.n_p)])
    assert np.abs(fd - grad).max() <= 1e-6 * np.abs(grad).max()
    assert val == pytest.approx(sp.static_ends(p, np.zeros(2))[2], rel=1e-15)


def test_spring_spans_are_immutable_values(system):
    """No cache is written into the frozen spans: their __dict__ holds their fields and nothing else after use."""
    import dataclasses

    sp = system.springs
    sp.force_and_blocks(np.zeros(system.n_p))
    sp.transport_blocks()
    sp.static_ends(np.zeros(system.n_p), np.zeros(2))
    assert set(vars(sp)) == {f.name for f in dataclasses.fields(sp)}
