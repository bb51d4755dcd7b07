"""The ANCF element with the linear axial law N = EA (|r'| - 1) (issue 25, item 2; `ancf.make_elements(...,
axial_law="linear")`).

Compared against: the element's strain energy differentiated by central differences (its forces),
its forces differentiated by central differences (its tangent), for the three curvature models; a
straight bar stretched uniformly (end nodes at 0 and lambda L, slopes (lambda, 0)): its end forces are
-+N(lambda) of the law's closed form (EA (lambda - 1), or EA (lambda^2 - 1) lambda / 2 for green-lagrange)."""

from __future__ import annotations

import numpy as np
import pytest

from beltdyn.model import ancf

EA, EI, RHO = 1.2e5, 0.02, 0.12


def perturbed_state(el, seed=3) -> np.ndarray:
    """(n, 8) a curved, stretched state of elements along x (a few % strain, rotated slopes)."""
    rng = np.random.default_rng(seed)
    n = el.n_elem
    e = np.zeros((n, 8))
    e[:, 0], e[:, 4] = 0.0, 1.02 * el.length
    e[:, 2], e[:, 6] = 1.03, 1.01
    return e + 0.005 * rng.standard_normal((n, 8))


@pytest.mark.parametrize("curvature", ["linear", "exact", "none"])
def test_linear_law_forces_are_the_energy_gradient_and_the_tangent_their_jacobian(curvature):
    el = ancf.make_elements(np.array([0.05, 0.08]), EA, EI, RHO, curvature=curvature, axial_law="linear")
    e = perturbed_state(el)
    f, K = ancf.internal_forces_and_tangent(el, e)
    np.testing.assert_allclose(ancf.internal_forces(el, e), f, rtol=1e-12, atol=1e-12 * np.abs(f).max())
    h = 1e-7
    fd_f = np.zeros_like(f)
    fd_K = np.zeros_like(K)
    for i in range(8):
        d = np.zeros(8)
        d[i] = h
        fd_f[:, i] = (ancf.strain_energy(el, e + d) - ancf.strain_energy(el, e - d)) / (2 * h)
        fd_K[:, :, i] = (ancf.internal_forces(el, e + d) - ancf.internal_forces(el, e - d)) / (2 * h)
    np.testing.assert_allclose(fd_f, f, rtol=1e-6, atol=1e-6 * np.abs(f).max())
    np.testing.assert_allclose(fd_K, K, rtol=1e-6, atol=1e-6 * np.abs(K).max())
    # the laws differ (the switch does something) and "green-lagrange" stays the default
    green = ancf.make_elements(np.array([0.05, 0.08]), EA, EI, RHO, curvature=curvature)
    assert green.axial_law == "green-lagrange"
    assert not np.allclose(ancf.internal_forces(green, e), f, rtol=1e-3)


@pytest.mark.parametrize("law", ["linear", "green-lagrange"])
def test_a_straight_bar_under_axial_load_has_the_laws_end_forces(law):
    L, lam = 0.1, 1.05
    el = ancf.make_elements(np.array([L]), EA, EI, RHO, curvature="linear", axial_law=law)
    e = np.array([[0.0, 0.0, lam, 0.0, lam * L, 0.0, lam, 0.0]])
    f = ancf.internal_forces(el, e)[0]
    N = EA * (lam - 1.0) if law == "linear" else EA * (lam * lam - 1.0) * lam / 2.0
    # dU/dx at the end nodes: -N at node 0, +N at node 1 (a uniform stretch: no slope forces)
    np.testing.assert_allclose(f[[0, 4]], [-N, N], rtol=1e-12)
    np.testing.assert_allclose(f[[1, 3, 5, 7]], 0.0, atol=1e-9 * N)
    np.testing.assert_allclose(f[[2, 6]], 0.0, atol=1e-9 * N * L)
    np.testing.assert_allclose(ancf.axial_force(el, e, np.array([0.0, 0.3, 1.0])), N, rtol=1e-12)
    assert ancf.strain_energy(el, e)[0] == pytest.approx(
        L * EA * ((lam - 1.0) ** 2 / 2 if law == "linear" else ((lam * lam - 1) / 2) ** 2 / 2), rel=1e-12)


def test_an_unknown_law_is_refused():
    with pytest.raises(ValueError, match="axial_law"):
        ancf.make_elements(np.array([0.1]), EA, EI, RHO, axial_law="cubic")


@pytest.mark.parametrize("curvature", ["linear", "exact", "none"])
@pytest.mark.parametrize("law", ["green-lagrange", "linear"])
def test_the_compiled_kernel_equals_the_numpy_element_for_both_laws(curvature, law):
    """`belt_kernel`'s element force, tangent and energy with the law's code against `ancf`'s numpy
    element (the reference implementation), to 1e-12 relative."""
    from beltdyn.model import belt_kernel as bk

    el = ancf.make_elements(np.array([0.05, 0.08, 0.03]), EA, EI, RHO, curvature=curvature, axial_law=law)
    tab = bk.tables_from_elements(el)
    assert tab.axial_law == bk.AXIAL_LAW_CODE[law]
    e = np.ascontiguousarray(perturbed_state(el, seed=7))
    f_ref, K_ref = ancf.internal_forces_and_tangent(el, e)
    n = el.n_elem
    f = np.empty((n, 8))
    bk.element_forces(e, *tab.args, f, tab.axial_law)
    np.testing.assert_allclose(f, f_ref, rtol=1e-12, atol=1e-12 * np.abs(f_ref).max())
    f2, K = np.empty((n, 8)), np.empty((n, 8, 8))
    bk.element_forces_tangent(e, *tab.args, f2, K, bk.scratch(n, el.n_gauss), tab.axial_law)
    np.testing.assert_allclose(f2, f_ref, rtol=1e-12, atol=1e-12 * np.abs(f_ref).max())
    np.testing.assert_allclose(K, K_ref, rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())
    U = np.empty(n)
    bk.element_strain_energy(e, *tab.args, U, tab.axial_law)
    np.testing.assert_allclose(U, ancf.strain_energy(el, e), rtol=1e-12)
