"""Tests of the compiled belt kernel (beltdyn.model.belt_kernel) against the numpy reference `ancf`.

Every numerical test states what it compares against and with which tolerance.  Relative errors
are per element: norm of the difference / norm of the reference (Frobenius over the trailing axes),
maximum over elements.
"""

from __future__ import annotations

import numpy as np
import pytest
from numerics import element_differences, element_error  # tests/numerics.py

from beltdyn.model import ancf
from beltdyn.model import belt_kernel as bk

CURVATURES = ("none", "linear", "exact")
N_GAUSS = (3, 5)
L_EL = 0.067  # the paper bench's element length at 10 elements per span
EA, EI, RHO = 1.2e5, 0.02, 0.119

# ----------------------------------------------------------------------------------------------
# helpers: meshes and states


def _lengths(mesh: str) -> np.ndarray:
    """Element lengths: 8 uniform (ancf shares the tables of equal elements) or 6 uneven ones."""
    if mesh == "uneven":
        return L_EL * np.array([0.45, 1.0, 1.7, 0.8, 1.25, 0.6])
    return np.full(8, L_EL)


def _elements(mesh: str, curvature: str, n_gauss: int) -> ancf.ElementSet:
    """mesh "uniform", "uneven" or "EI0" (uneven lengths, EI = 0)."""
    return ancf.make_elements(_lengths(mesh), EA, 0.0 if mesh == "EI0" else EI, RHO, curvature=curvature,
                              n_gauss=n_gauss)


def _rot(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def _state(lengths: np.ndarray, kind: str, seed: int) -> np.ndarray:
    """Element coordinates (n, 8) of a chain of elements (shared nodes).

    "straight-<noise>": a straight span along 0.4 rad, stretched by 1.02, each element's
    coordinates perturbed independently by noise * N(0, 1) (times L for the positions, so that
    the perturbation is dimensionless).  "bent": a circular arc of radius 0.05 m (about 1.3 rad of
    arc per element, stretch 1.01), perturbed by 1e-3.
    """
    rng = np.random.default_rng(seed)
    x = np.concatenate(([0.0], np.cumsum(lengths)))
    origin = np.array([0.12, -0.05])
    if kind == "bent":
        radius, lam, noise = 0.05, 1.01, 1e-3
        t = lam * x / radius
        pos = np.stack((radius * np.sin(t), radius * (1.0 - np.cos(t))), axis=-1)
        grad = lam * np.stack((np.cos(t), np.sin(t)), axis=-1)
    else:
        lam, noise = 1.02, float(kind.split("-", 1)[1])
        pos = np.stack((lam * x, np.zeros_like(x)), axis=-1)
        grad = np.tile([lam, 0.0], (x.size, 1))
    R = _rot(0.4)
    pos = origin + pos @ R.T
    grad = grad @ R.T
    e = np.concatenate((pos[:-1], grad[:-1], pos[1:], grad[1:]), axis=1)
    scale = np.concatenate((np.repeat(lengths[:, None], 2, 1), np.ones((lengths.size, 2)),
                            np.repeat(lengths[:, None], 2, 1), np.ones((lengths.size, 2))), axis=1)
    return np.ascontiguousarray(e + noise * scale * rng.standard_normal(e.shape))


STATES = ("straight-1e-3", "straight-1e-2", "straight-1e-1", "bent")
MESHES = ("uniform", "uneven", "EI0")


def _setup(mesh: str, curvature: str, n_gauss: int, state: str, seed: int = 0):
    el = _elements(mesh, curvature, n_gauss)
    return el, bk.tables_from_elements(el), _state(el.length, state, seed)


CASES = pytest.mark.parametrize("curvature", CURVATURES)
GAUSS = pytest.mark.parametrize("n_gauss", N_GAUSS)
STATE = pytest.mark.parametrize("state", STATES)
MESH = pytest.mark.parametrize("mesh", MESHES)

# ----------------------------------------------------------------------------------------------
# 1. tables


@CASES
def test_tables_are_plain_copies_of_the_element_set(curvature):
    # Exact equality with the ancf tables (same products), and writable C-contiguous float64.
    el = _elements("uneven", curvature, 5)
    tab = bk.tables_from_elements(el)
    np.testing.assert_array_equal(tab.wEA, el.wL * el.EA[:, None])
    np.testing.assert_array_equal(tab.wEI, el.wL * el.EI[:, None])
    np.testing.assert_array_equal(tab.Kb, el.K_bend)
    np.testing.assert_array_equal(tab.dS, el.dS)
    np.testing.assert_array_equal(tab.d2S, el.d2S)
    assert tab.curvature == bk.CURVATURE_CODE[curvature]
    for a in (tab.dS, tab.d2S, tab.wEA, tab.wEI, tab.EA, tab.Kb):
        assert a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable
    assert tab.args == (tab.dS, tab.d2S, tab.wEA, tab.wEI, tab.Kb, tab.curvature)


# ----------------------------------------------------------------------------------------------
# 2. element functions against ancf: relative 1e-12 per element, ||kernel - ancf|| / ||ancf||.
#    Both codes sum the same terms in a different order, so they differ by round-off only.  The
#    strain is the worst-conditioned quantity: r' cancels nodal terms of size |x|/L, so eps loses
#    about |x|/L ulps (measured worst: forces 2e-13, energies 1.1e-13, tangents 3.4e-15).


@CASES
@GAUSS
@STATE
@MESH
def test_forces_match_ancf(curvature, n_gauss, state, mesh):
    el, tab, E = _setup(mesh, curvature, n_gauss, state)
    f = np.empty_like(E)
    bk.element_forces(E, *tab.args, f)
    assert element_error(f, ancf.internal_forces(el, E)) <= 1e-12


@CASES
@GAUSS
@STATE
@MESH
def test_forces_and_tangent_match_ancf(curvature, n_gauss, state, mesh):
    el, tab, E = _setup(mesh, curvature, n_gauss, state)
    f = np.empty_like(E)
    K = np.empty((E.shape[0], 8, 8))
    bk.element_forces_tangent(E, *tab.args, f, K, bk.scratch(E.shape[0], tab.dS.shape[1]))
    f_ref, K_ref = ancf.internal_forces_and_tangent(el, E)
    assert element_error(f, f_ref) <= 1e-12
    assert element_error(K, K_ref) <= 1e-12
    np.testing.assert_array_equal(K, np.swapaxes(K, 1, 2))  # symmetric by construction


@CASES
@GAUSS
@STATE
@MESH
def test_strain_energy_matches_ancf(curvature, n_gauss, state, mesh):
    el, tab, E = _setup(mesh, curvature, n_gauss, state)
    U = np.empty(E.shape[0])
    bk.element_strain_energy(E, *tab.args, U)
    U_ref = ancf.strain_energy(el, E)
    assert np.max(np.abs(U - U_ref) / np.abs(U_ref)) <= 1e-12


@GAUSS
@STATE
def test_min_axial_force_matches_ancf(n_gauss, state):
    # Smallest EA eps over the Gauss points against ancf.axial_strain at the Gauss abscissae,
    # relative 1e-12 of EA |eps|max per element.
    el, tab, E = _setup("uneven", "linear", n_gauss, state)
    out = np.empty(E.shape[0])
    bk.element_min_axial_force(E, tab.dS, tab.EA, out)
    N = el.EA[:, None] * ancf.axial_strain(el, E, el.gauss_xi)
    np.testing.assert_allclose(out, N.min(axis=1), rtol=0, atol=1e-12 * np.abs(N).max())


def test_min_axial_force_detects_slack():
    # A span compressed to 0.95 of its length: every element reports EA eps < 0 (eps = (0.95^2-1)/2).
    el, tab, _ = _setup("uniform", "linear", 5, "straight-1e-3")
    x = np.concatenate(([0.0], np.cumsum(el.length))) * 0.95
    z = np.zeros_like(x)
    E = np.ascontiguousarray(np.stack((x[:-1], z[:-1], 0.95 + z[:-1], z[:-1], x[1:], z[1:], 0.95 + z[1:], z[1:]), 1))
    out = np.empty(E.shape[0])
    bk.element_min_axial_force(E, tab.dS, tab.EA, out)
    np.testing.assert_allclose(out, EA * 0.5 * (0.95**2 - 1.0), rtol=1e-12)


# ----------------------------------------------------------------------------------------------
# 3. derivative identities (finite differences)


@CASES
@STATE
@MESH
def test_forces_are_the_strain_energy_gradient(curvature, state, mesh):
    # f = dU/de against central differences of element_strain_energy, step 1e-6, relative 1e-6.
    el, tab, E = _setup(mesh, curvature, 5, state)
    f = np.empty_like(E)
    bk.element_forces(E, *tab.args, f)

    def energy(e):
        U = np.empty(e.shape[0])
        bk.element_strain_energy(np.ascontiguousarray(e), *tab.args, U)
        return U

    assert element_error(element_differences(energy, E, 1e-6), f) <= 1e-6


@CASES
@STATE
def test_tangent_is_the_force_jacobian(curvature, state):
    # K = df/de against central differences of element_forces, step 1e-6, relative 1e-6.
    el, tab, E = _setup("uneven", curvature, 3, state)
    f = np.empty_like(E)
    K = np.empty((E.shape[0], 8, 8))
    bk.element_forces_tangent(E, *tab.args, f, K, bk.scratch(E.shape[0], tab.dS.shape[1]))

    def forces(e):
        out = np.empty_like(e)
        bk.element_forces(np.ascontiguousarray(e), *tab.args, out)
        return out

    assert element_error(element_differences(forces, E, 1e-6), K) <= 1e-6


# ----------------------------------------------------------------------------------------------
# 4. belt damping

ETAS = pytest.mark.parametrize("eta_a, eta_b", [(2e-4, 0.0), (0.0, 3e-3), (2e-4, 3e-3)])


def _damping(E, Ed, tab, eta_a, eta_b):
    fd = np.empty_like(E)
    bk.element_damping(E, Ed, *tab.args, eta_a, eta_b, fd)
    return fd


def _damping_matrix(E, tab, eta_a, eta_b):
    C = np.empty((E.shape[0], 8, 8))
    bk.element_damping_matrix(E, *tab.args, eta_a, eta_b, C, bk.scratch(E.shape[0], tab.dS.shape[1]))
    return C


def _velocities(E: np.ndarray, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(E.shape)


@CASES
@STATE
@ETAS
def test_damping_matrix_is_the_damping_jacobian(curvature, state, eta_a, eta_b):
    # fd is linear in Ed: central differences with the step h = 1 are exact up to round-off
    # (relative 1e-12), and fd = C Ed (relative 1e-12).
    el, tab, E = _setup("uneven", curvature, 5, state)
    Ed = _velocities(E, 1)
    C = _damping_matrix(E, tab, eta_a, eta_b)
    fd = _damping(E, Ed, tab, eta_a, eta_b)
    if curvature == "none" and eta_a == 0.0:
        assert not fd.any() and not C.any()
        return
    fd_cols = element_differences(lambda v: _damping(E, np.ascontiguousarray(v), tab, eta_a, eta_b), Ed, 1.0)
    assert element_error(fd_cols, C) <= 1e-12
    assert element_error(fd, (C @ Ed[:, :, None])[:, :, 0]) <= 1e-12


@CASES
@STATE
@MESH
def test_damping_matrix_is_symmetric_positive_semidefinite(curvature, state, mesh):
    # Exactly symmetric; eigenvalues >= -1e-12 * the largest (PSD up to round-off); so the damping
    # power Ed . fd is >= 0 (dissipation).
    el, tab, E = _setup(mesh, curvature, 5, state)
    C = _damping_matrix(E, tab, 2e-4, 3e-3)
    np.testing.assert_array_equal(C, np.swapaxes(C, 1, 2))
    lam = np.linalg.eigvalsh(C)
    assert np.all(lam >= -1e-12 * lam.max(axis=1, keepdims=True))
    Ed = _velocities(E, 2)
    power = np.einsum("ni,ni->n", Ed, _damping(E, Ed, tab, 2e-4, 3e-3))
    assert np.all(power >= -1e-12 * np.abs(power).max())


@CASES
@STATE
def test_damping_matrix_content(curvature, state):
    # Independent reference (relative 1e-10): eta_a sum_q wEA G G^T + eta_b B, with G = dA/de / 2 and
    # gc = dc/de by central differences of the quadratic forms A = r'.r' and c = r' x r'' (exact
    # for quadratics up to round-off, step 0.1), B = Kb ("linear"), sum_q wEI/A^3 gc gc^T ("exact").
    el, tab, E = _setup("uneven", curvature, 5, state)
    eta_a, eta_b = 2e-4, 3e-3

    def slopes(e):
        e4 = e.reshape(-1, 4, 2)
        return el.dS @ e4, el.d2S @ e4

    def A_of(e):
        rp, _ = slopes(e)
        return (rp**2).sum(-1)

    def c_of(e):
        rp, rpp = slopes(e)
        return rp[..., 0] * rpp[..., 1] - rp[..., 1] * rpp[..., 0]

    G = 0.5 * element_differences(A_of, E, 0.1)  # (n, q, 8)
    C_ref = eta_a * np.einsum("nq,nqi,nqj->nij", el.wL * el.EA[:, None], G, G)
    if curvature == "linear":
        C_ref += eta_b * el.K_bend
    elif curvature == "exact":
        gc = element_differences(c_of, E, 0.1)
        C_ref += eta_b * np.einsum("nq,nqi,nqj->nij", el.wL * el.EI[:, None] / A_of(E) ** 3, gc, gc)
    assert element_error(_damping_matrix(E, tab, eta_a, eta_b), C_ref) <= 1e-10


@CASES
def test_damping_is_zero_without_retardation(curvature):
    # eta_a = eta_b = 0: the outputs are overwritten with exact zeros.
    el, tab, E = _setup("uneven", curvature, 5, "bent")
    fd = np.full_like(E, np.nan)
    C = np.full((E.shape[0], 8, 8), np.nan)
    bk.element_damping(E, _velocities(E, 3), *tab.args, 0.0, 0.0, fd)
    bk.element_damping_matrix(E, *tab.args, 0.0, 0.0, C, bk.scratch(E.shape[0], tab.dS.shape[1]))
    assert not fd.any() and not C.any()


# ----------------------------------------------------------------------------------------------
# 5. reduced coordinates: gather / scatter / reduce_blocks against dense numpy, relative 1e-14


def _layout(seed: int = 0):
    """A model-like layout: two chains of 4 elements (4 DOFs per node) whose end elements are
    joints (end-node positions replaced by 3 pulley DOFs, columns 8..10), plus two tricky elements:
    T = [I8 | 0] with a non-padding idx[8] and T = [I8 | 0] + 1e-300 (both general).

    Returns T (n, 8, 11), idx (n, 11), n_dof and the expected joint flags.
    """
    rng = np.random.default_rng(seed)
    n_chain, m = 4, 11
    n_pulley = 6
    n_dof = n_pulley + 2 * 4 * (n_chain + 1) + 8
    pad = n_dof
    T, idx, joint = [], [], []
    for span in range(2):
        base = n_pulley + span * 4 * (n_chain + 1)
        for k in range(n_chain):
            t = np.zeros((8, m))
            t[:, :8] = np.eye(8)
            ix = np.full(m, pad)
            ix[:8] = base + 4 * k + np.arange(8)
            is_joint = k in (0, n_chain - 1)
            if is_joint:
                side = 0 if k == 0 else 1
                rows = slice(4 * side, 4 * side + 2)
                t[rows, rows] = 0.0
                ix[4 * side: 4 * side + 2] = pad
                ix[8:] = rng.choice(n_pulley, 3, replace=False)
                t[rows, 8:] = rng.standard_normal((2, 3))
            T.append(t)
            idx.append(ix)
            joint.append(is_joint)
    extra = n_dof - 8
    t = np.zeros((8, m))
    t[:, :8] = np.eye(8)
    ix = np.full(m, pad)
    ix[:8] = extra + np.arange(8)
    ix2 = ix.copy()
    ix2[8] = 0  # not padding, with a zero column of T: general
    T += [t, t + 1e-300]
    idx += [ix2, ix.copy()]
    joint += [True, True]
    return np.array(T), np.array(idx, dtype=np.int64), n_dof, np.array(joint)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def test_joint_selection_marks_identity_elements():
    T, idx, n_dof, joint = _layout()
    tsel = bk.joint_selection(T, idx, n_dof)
    assert tsel.dtype == np.int64
    np.testing.assert_array_equal(tsel, np.where(joint, np.arange(len(joint)), -1))


@pytest.mark.parametrize("T_shape, idx_shape", [((3, 8, 7), (3, 7)), ((3, 6, 9), (3, 9)), ((3, 8, 9), (3, 8))])
def test_joint_selection_rejects_bad_shapes(T_shape, idx_shape):
    with pytest.raises(ValueError):
        bk.joint_selection(np.zeros(T_shape), np.zeros(idx_shape, dtype=np.int64), 5)


def test_gather_matches_dense():
    T, idx, n_dof, _ = _layout()
    tsel = bk.joint_selection(T, idx, n_dof)
    rng = np.random.default_rng(4)
    q_ext = np.append(rng.standard_normal(n_dof), 0.0)
    e0 = rng.standard_normal((T.shape[0], 8))
    Tq = np.einsum("kij,kj->ki", T, q_ext[idx])
    E = np.empty_like(e0)
    bk.gather(q_ext, e0, T, idx, tsel, E)
    assert _rel(E, e0 + Tq) <= 1e-14
    Ed = np.empty_like(e0)
    bk.gather_velocity(q_ext, T, idx, tsel, Ed)
    assert _rel(Ed, Tq) <= 1e-14


def test_scatter_vector_matches_dense_and_accumulates():
    T, idx, n_dof, _ = _layout()
    tsel = bk.joint_selection(T, idx, n_dof)
    rng = np.random.default_rng(5)
    fe = rng.standard_normal((T.shape[0], 8))
    out0 = rng.standard_normal(n_dof + 1)
    ref = out0 + np.bincount(idx.ravel(), weights=np.einsum("kij,ki->kj", T, fe).ravel(), minlength=n_dof + 1)
    out = out0.copy()
    bk.scatter_vector(fe, T, idx, tsel, out)
    assert _rel(out[:n_dof], ref[:n_dof]) <= 1e-14


def test_reduce_blocks_matches_dense():
    T, idx, n_dof, _ = _layout()
    tsel = bk.joint_selection(T, idx, n_dof)
    rng = np.random.default_rng(6)
    a = rng.standard_normal((T.shape[0], 8, 8))
    Ke = a + np.swapaxes(a, 1, 2)
    out = np.full((T.shape[0], T.shape[2], T.shape[2]), np.nan)
    bk.reduce_blocks(Ke, T, tsel, out, np.empty((8, T.shape[2])))
    ref = np.einsum("kip,kij,kjq->kpq", T, Ke, T)
    assert _rel(out, ref) <= 1e-14
    np.testing.assert_array_equal(out, np.swapaxes(out, 1, 2))


@CASES
@pytest.mark.parametrize("state", ("straight-1e-2", "bent"))
def test_reduced_force_and_blocks_match_ancf_through_the_layout(curvature, state):
    # The fused functions against ancf forces/tangents reduced densely (T^T f, T^T K T), relative
    # 1e-12: states from the layout's DOFs (e0 = a state of the elements, q random).
    T, idx, n_dof, _ = _layout()
    tsel = bk.joint_selection(T, idx, n_dof)
    n = T.shape[0]
    lengths = np.resize(_lengths("uneven"), n)
    el = ancf.make_elements(lengths, EA, EI, RHO, curvature=curvature, n_gauss=5)
    tab = bk.tables_from_elements(el)
    q_ext = np.append(1e-2 * np.random.default_rng(7).standard_normal(n_dof), 0.0)
    e0 = _state(lengths, state, 8)
    E = e0 + np.einsum("kij,kj->ki", T, q_ext[idx])
    f_ref, K_ref = ancf.internal_forces_and_tangent(el, E)
    fr_ref = np.bincount(idx.ravel(), weights=np.einsum("kij,ki->kj", T, f_ref).ravel(), minlength=n_dof + 1)
    blocks_ref = np.einsum("kip,kij,kjq->kpq", T, K_ref, T)

    f_out = np.full(n_dof + 1, np.nan)
    blocks = np.full((n, T.shape[2], T.shape[2]), np.nan)
    work = bk.scratch(n, tab.dS.shape[1], T.shape[2])
    bk.reduced_force_and_tangent_blocks(q_ext, e0, T, idx, tsel, *tab.args, f_out, blocks, work)
    assert _rel(f_out[:n_dof], fr_ref[:n_dof]) <= 1e-12
    assert element_error(blocks, blocks_ref) <= 1e-12
    f_only = np.full(n_dof + 1, np.nan)
    bk.reduced_force(q_ext, e0, T, idx, tsel, *tab.args, f_only, work)
    assert _rel(f_only[:n_dof], fr_ref[:n_dof]) <= 1e-12
