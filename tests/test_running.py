"""The running belt (`beltdyn.analysis.running`): transport matrices, running tension, gyroscopic modes against
the moving string and the moving pinned beam, the transient at speed, the Campbell sweep."""

from __future__ import annotations

import math
import subprocess
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.model import ancf
from beltdyn.config import config_from_dict, load_config
from beltdyn.analysis.modal import critical_speed, solve_modes
from beltdyn.study.paper import CASES, compare
from beltdyn.pipeline import analyse, transient_start
from beltdyn.analysis.running import linearized_matrices
from beltdyn.model.barlaw import stretch_for_tension
from beltdyn.model.system import build_system
from beltdyn.analysis.transient import prepare, run_transient
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
RHO, EA = 0.11915, 120000.0


def bench(*overrides: str):
    return load_config(BENCH, list(overrides))


def reference_tension(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(2nd Piola-Kirchhoff force S = N / lambda, stretch lambda) of a span with true tension N: the
    closed forms in the reference (material) coordinate, in which the model's rho (kg per undeformed
    m) and belt speed c (undeformed m/s) are defined. In physical terms rho c^2 / S = rho_cur v^2 / N
    (rho_cur = rho / lambda, v = lambda c), so the forms below are the textbook ones."""
    lam = stretch_for_tension(np.asarray(N, dtype=float), EA)
    return N / lam, lam


# ------------------------------------------------------------------------------------ the element
def test_transport_matrices_by_independent_quadrature():
    # A = int rho S^T S' dx and B = int rho S'^T S' dx against a 20-point Gauss rule on the shape
    # functions written out here (Eq. 3), to 1e-14; the gyroscopic matrix A - A^T is skew-symmetric
    # exactly, B symmetric positive semi-definite with the rigid translations in its null space.
    L = np.array([0.2, 0.05, 1.3])
    rho = np.array([0.1, 2.0, 0.7])
    el = ancf.make_elements(L, 1e5, 0.1, rho)
    A, B = ancf.transport_matrices(el)
    x, w = np.polynomial.legendre.leggauss(20)
    xi, w = 0.5 * (x + 1), 0.5 * w
    for k in range(3):
        s = np.column_stack([1 - 3 * xi**2 + 2 * xi**3, L[k] * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3,
                             L[k] * (xi**3 - xi**2)])
        ds = np.column_stack([(-6 * xi + 6 * xi**2) / L[k], 1 - 4 * xi + 3 * xi**2, (6 * xi - 6 * xi**2) / L[k],
                              3 * xi**2 - 2 * xi])
        S = np.zeros((20, 2, 8))
        Sp = np.zeros((20, 2, 8))
        for a in range(4):
            S[:, 0, 2 * a] = S[:, 1, 2 * a + 1] = s[:, a]
            Sp[:, 0, 2 * a] = Sp[:, 1, 2 * a + 1] = ds[:, a]
        A_ref = np.einsum("q,qia,qib->ab", w * L[k] * rho[k], S, Sp)
        B_ref = np.einsum("q,qia,qib->ab", w * L[k] * rho[k], Sp, Sp)
        np.testing.assert_allclose(A[k], A_ref, atol=1e-14 * np.abs(A_ref).max())
        np.testing.assert_allclose(B[k], B_ref, atol=1e-14 * np.abs(B_ref).max())
        G = A[k] - A[k].T
        assert np.array_equal(G, -G.T)
        assert np.array_equal(B[k], B[k].T) and np.linalg.eigvalsh(B[k]).min() > -1e-14 * np.abs(B[k]).max()
        shift = np.tile([0.3, -0.7, 0.0, 0.0], 2)  # a rigid translation (positions only)
        assert np.abs(B[k] @ shift).max() < 1e-14 * np.abs(B[k]).max()


def test_transport_terms_are_the_kinetic_energy_derivatives():
    # T(e, e') = 1/2 int rho |S e' + c S' e|^2 dx by 12-point quadrature: its gradients by central
    # differences against the element's terms, dT/de' = M e' + c A e and dT/de = c A^T e' + c^2 B e
    # (so that Lagrange's equations give c (A - A^T) e' + c' A e - c^2 B e), within 1e-9.
    el = ancf.make_elements(np.array([0.07]), 1e5, 0.1, 0.3)
    A, B = (m[0] for m in ancf.transport_matrices(el))
    M = el.mass[0]
    xi, w = np.polynomial.legendre.leggauss(12)
    xi, w = 0.5 * (xi + 1), 0.5 * w
    s, ds, _ = ancf.shape_functions(xi, el.length)
    S = np.zeros((12, 2, 8))
    Sp = np.zeros((12, 2, 8))
    for a in range(4):
        S[:, 0, 2 * a] = S[:, 1, 2 * a + 1] = s[0, :, a]
        Sp[:, 0, 2 * a] = Sp[:, 1, 2 * a + 1] = ds[0, :, a]
    c = 13.0
    rng = np.random.default_rng(3)
    e, ed = rng.normal(size=8), rng.normal(size=8)

    def T(e_, ed_):
        V = S @ ed_ + c * (Sp @ e_)
        return 0.5 * float(np.sum(w * 0.07 * 0.3 * np.einsum("qi,qi->q", V, V)))

    _assert_transport_terms(T, e, ed, M, A, B, c)


def _assert_transport_terms(T, x, xd, M, A, B, c: float) -> None:
    """The kinetic energy T(x, x') of a body moving with the belt at speed c: its gradients by central
    differences (step 1e-6) against dT/dx = c A^T x' + c^2 B x and dT/dx' = M x' + c A x, within 1e-9 of
    the largest dT/dx."""
    h = 1e-6
    I = np.eye(len(x))
    dT_dx = np.array([(T(x + h * I[i], xd) - T(x - h * I[i], xd)) / (2 * h) for i in range(len(x))])
    dT_dxd = np.array([(T(x, xd + h * I[i]) - T(x, xd - h * I[i])) / (2 * h) for i in range(len(x))])
    scale = np.abs(dT_dx).max()
    np.testing.assert_allclose(dT_dx, c * A.T @ xd + c * c * B @ x, atol=1e-9 * scale)
    np.testing.assert_allclose(dT_dxd, M @ xd + c * A @ x, atol=1e-9 * scale)


def test_spring_span_transport_terms_are_the_kinetic_energy_derivatives():
    # A spring span's ends carry rho L / 2 each and move at x' + c d / L (the material flowing through
    # the chord d = x_b - x_a): T(x, x') = sum_ends 1/2 rho L / 2 |x'_end + c d / L|^2. Its gradients by
    # central differences against the span's terms, dT/dx' = M x' + c A_s x and dT/dx = c A_s^T x' +
    # c^2 B_s x (M = rho L / 2 I4), within 1e-9.
    cfg = bench(*[f'spans.{n}.model="spring"' for n in ("A-C", "C-A")])
    sp = build_system(cfg).springs
    A, B = (m[0] for m in sp.transport_end_matrices())
    L, m_end = float(sp.reference_length[0]), float(sp.end_mass[0])
    c = 13.0
    rng = np.random.default_rng(5)
    x, xd = rng.normal(size=4), rng.normal(size=4)

    def T(x_, xd_):
        v = xd_.reshape(2, 2) + c * (x_[2:4] - x_[0:2]) / L
        return 0.5 * m_end * float(np.sum(v * v))

    _assert_transport_terms(T, x, xd, m_end * np.eye(4), A, B, c)


@pytest.mark.parametrize("spring", [(), ("C-A",), ("A-C", "C-A")], ids=["ancf", "mixed", "all-spring"])
def test_centripetal_force_and_tangent_against_finite_differences(spring):
    # On the paper bench at 20 m/s: the system's centripetal term -c^2 (B p + b0) of the internal force is
    # the gradient of the centripetal potential V = -c^2/2 (sum_e e^T B_e e + sum_k x_k^T B_s x_k)
    # (central differences; ANCF spans e, spring spans x), and the running tangent of the equilibrium
    # residual is its derivative (central differences of the residual), within 1e-7 of the largest entry.
    cfg = bench("running.belt_speed=20.0", "mesh.elements_per_span=3", *[f'spans.{n}.model="spring"' for n in spring])
    system = build_system(cfg)
    assert system.belt_speed == 20.0
    _, B_e = ancf.transport_matrices(system.belt.elements)
    sp = system.springs
    B_s = sp.transport_end_matrices()[1] if sp is not None else None
    rng = np.random.default_rng(0)
    q = 1e-4 * rng.normal(size=system.n_dof)

    def V(q_):
        E = system.belt.element_coordinates(q_)
        v = float(np.einsum("ei,eij,ej->", E, B_e, E))
        if sp is not None:
            X = sp.positions(q_)
            v += float(np.einsum("ki,kij,kj->", X, B_s, X))
        return -0.5 * 400.0 * v

    h = 1e-6
    grad = np.array([(V(q + h * d) - V(q - h * d)) / (2 * h) for d in np.eye(system.n_dof)])
    f_c = system.centripetal_force(q)
    np.testing.assert_allclose(f_c, grad, atol=1e-7 * np.abs(f_c).max())
    r, K = system.equilibrium(q)
    K_fd = np.column_stack([(system.equilibrium(q + h * d, tangent=False)[0]
                             - system.equilibrium(q - h * d, tangent=False)[0]) / (2 * h) for d in np.eye(system.n_dof)])
    np.testing.assert_allclose(K, K_fd, atol=1e-7 * np.abs(K).max())
    G = system.gyroscopic_matrix(q)
    assert np.array_equal(G, -G.T) and np.abs(G).max() > 0


# ------------------------------------------------------------------------------------ speed 0
def test_speed_zero_is_the_drive_at_rest():
    # [running] with speed 0 builds exactly today's system (the same matrices and static state, bit for
    # bit), and reproduces the paper's Tables 1 and 2 to 1e-9 (the same numbers as without [running]).
    for over in (["running.belt_speed=0.0"], ["running.driver_speed=0.0"]):
        a, b = build_system(bench()), build_system(bench(*over))
        assert b.belt_speed == 0.0
        q = np.linspace(-1e-4, 1e-4, a.n_dof)
        ra, Ka = a.equilibrium(q)
        rb, Kb = b.equilibrium(q)
        assert np.array_equal(ra, rb) and np.array_equal(Ka, Kb) and np.array_equal(a.mass, b.mass)
        assert not np.any(linearized_matrices(b, q).G)
    for case in CASES:
        cfg = load_config(ROOT / "configs" / "paper" / f"{case.config}.toml")
        ref = compare(case, analyse(cfg, modal=True).modal)
        run = analyse(load_config(ROOT / "configs" / "paper" / f"{case.config}.toml", ["running.belt_speed=0.0"]), modal=True)
        got = compare(case, run.modal)
        assert np.isrealobj(run.modal.shapes) and run.modal.growth_rate is None
        for x, y in zip(ref, got):
            assert y.ours == pytest.approx(x.ours, rel=1e-9) and y.our_label == x.our_label


# ------------------------------------------------------------------------------------ running tension
@pytest.mark.parametrize("spring", [False, True], ids=["ancf", "all-spring"])
def test_running_tension_with_fixed_centres(spring):
    # Fixed centres (the bench with both centres held, the tension from the belt's length): the span
    # tension does not change with speed (to 1e-8 N), and every hub load drops by the centrifugal tension,
    # H(v) = H(0) - rho c^2 lambda (t_j - t_(j-1)), to 1e-8 N (the wrap carries rho c^2 lambda). The
    # same for spring spans (their own transport terms, `SpringSpans`).
    raw = tomllib.loads(BENCH.read_text())
    if spring:
        raw["spans"] = {"A-C": {"model": "spring"}, "C-A": {"model": "spring"}}
    raw["pulleys"][0].update(support="fixed", adjustable=False, bearing_stiffness=0.0)
    raw["belt"]["length"] = 1.79
    del raw["tension"]
    rest = analyse(config_from_dict(raw))
    raw["running"] = {"belt_speed": 25.0}
    run = analyse(config_from_dict(raw))
    assert run.system.belt_speed == 25.0
    np.testing.assert_allclose(run.static.span_tension, rest.static.span_tension, atol=1e-8)
    lam = reference_tension(run.static.span_tension.mean(axis=1))[1]
    t = run.layout.span_direction
    flux = RHO * 25.0**2 * lam[:, None] * t
    expected = rest.static.hub_load - (flux - np.roll(flux, 1, axis=0))
    np.testing.assert_allclose(run.static.hub_load, expected, atol=1e-8)


@pytest.mark.parametrize("spring", [False, True], ids=["ancf", "all-spring"])
def test_running_tension_of_a_dead_weight_tensioner(spring):
    # A 20 kg pulley hanging on the belt (vertical slide, no spring, gravity): its weight holds
    # N - rho c^2 lambda, so the span tensions rise by the centrifugal tension rho c^2 lambda. Within
    # 1e-3 of rho c^2 (the pulley drops ~0.1 mm as the belt stretches, turning the spans by ~1e-4 rad).
    # The same with every span a spring.
    def drive(speed):
        raw = {"belt": {"length": 2.0, "EA": EA, "EI": 0.02, "mass_per_length": RHO},
               "pulleys": [{"name": "A", "center": [0.0, 0.0], "radius": 0.05, "mass": 1.0, "inertia": 1e-3,
                            "driver": True},
                           {"name": "B", "center": [0.6, 0.0], "radius": 0.05, "mass": 1.0, "inertia": 1e-3},
                           {"name": "W", "center": [0.3, -0.5], "radius": 0.05, "mass": 20.0, "inertia": 1e-3,
                            "support": "slide", "slide_direction": [0.0, 1.0], "bearing_stiffness": 0.0}],
               "model": {"gravity": [0.0, -9.81]}, "mesh": {"elements_per_span": 8},
               "running": {"belt_speed": speed}}
        if spring:
            raw["spans"] = {n: {"model": "spring"} for n in ("A-B", "B-W", "W-A")}
        return analyse(config_from_dict(raw)).static

    rest = drive(0.0)
    for v in (10.0, 30.0):
        st = drive(v)
        lam = reference_tension(st.span_tension)[1]
        err = np.abs(st.span_tension - RHO * v * v * lam - rest.span_tension).max()
        assert err <= 1e-3 * RHO * v * v, (v, err)


@pytest.mark.parametrize("spring", [(), ("C-A",), ("A-C", "C-A")], ids=["ancf", "mixed", "all-spring"])
def test_hub_loads_are_the_wraps_momentum_balance(spring):
    # The bench at 20 m/s (tension set at speed, mode "adjust"): the mean span tension is the target and
    # each hub load is (N_j - rho c^2 lambda_j) t_j - (N_(j-1) - rho c^2 lambda_(j-1)) t_(j-1) with the
    # span-end tensions and chord directions of the solved layout, within 1e-6 of the load; ANCF and
    # spring spans alike.
    run = analyse(bench("running.driver_speed=533.3333333333334", *[f'spans.{n}.model="spring"' for n in spring]))
    c = run.system.belt_speed
    assert c == pytest.approx(20.0, rel=1e-12)
    st = run.static
    assert st.mean_tension == pytest.approx(200.0, rel=1e-9)
    N_start, N_end = st.span_tension[:, 0], st.span_tension[:, 1]
    t = run.layout.span_direction
    out = (N_start - RHO * c * c * reference_tension(N_start)[1])[:, None] * t
    inn = np.roll((N_end - RHO * c * c * reference_tension(N_end)[1])[:, None] * t, 1, axis=0)
    np.testing.assert_allclose(st.hub_load, out - inn, atol=1e-6 * np.abs(st.hub_load).max())


# ------------------------------------------------------------------------------------ gyroscopic modes
def transverse(md, span: int, n: int) -> float:
    hit = [f for f, k, o, s in zip(md.frequency, md.kind, md.order, md.span) if k == "transverse" and o == n
           and s == span]
    assert len(hit) == 1, (span, n, md.label)
    return hit[0]


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.7])
def test_moving_string_frequencies(fraction):
    # The bench's spans with EI -> 0 (curvature "none", 10 el/span) at v = fraction x the wave speed:
    # f_n = n c_w / (2 L) (1 - v^2 / c_w^2), c_w^2 = P / rho, for n = 1..3 on both spans, within 0.3 %
    # (measured: 1.8e-4 at worst, n = 3 at 0.7 c_w). In the reference coordinate: c_w^2 = S / rho,
    # v = c (see reference_tension).
    rest = analyse(bench('model.curvature="none"'))
    S0 = reference_tension(rest.static.span_tension.mean())[0]
    c = fraction * math.sqrt(S0 / RHO)
    run = analyse(bench('model.curvature="none"', f"running.belt_speed={c!r}"), modal=True, n_modes=24)
    md = run.modal
    assert all(st == "stable" for st in md.stability)
    for s in range(2):
        S = reference_tension(run.static.span_tension[s].mean())[0]
        L = run.system.belt.reference_length[s]
        for n in (1, 2, 3):
            f = n / (2 * L) * math.sqrt(S / RHO) * (1 - RHO * c * c / S)
            assert transverse(md, s + 1, n) == pytest.approx(f, rel=3e-3), (s, n)


def test_moving_pinned_beam_divergence():
    # Pinned span under tension with EI = 5 N m^2 (the bench, 10 el/span): the first critical speed is
    # rho c_cr^2 = P + EI (pi / L)^2 (reference coordinate: S + EI (pi / L_ref)^2, the linear bending form).
    # critical_speed within 0.5 % (measured 2.4e-6); just below it the first transverse modes are stable
    # and slow, just above them the modal analysis reports divergence (frequency 0, growth > 0) with
    # the critical speed, not garbage.
    over = ["belt.EI=5.0"]
    rest = analyse(bench(*over))
    S = reference_tension(rest.static.span_tension.mean())[0]
    L = rest.system.belt.reference_length
    c_cr = np.sqrt((S + 5.0 * (np.pi / L) ** 2) / RHO)
    assert critical_speed(rest.system, rest.static.q) == pytest.approx(c_cr.min(), rel=5e-3)
    below = analyse(bench(*over, f"running.belt_speed={float(0.99 * c_cr.min())!r}"), modal=True).modal
    assert below.stability[:2] == ("stable", "stable") and 0 < below.frequency[0] < 0.2 * transverse(
        rest_modes(over), 1, 1)
    above = analyse(bench(*over, f"running.belt_speed={float(1.01 * c_cr.max())!r}"), modal=True).modal
    assert above.stability[:2] == ("divergence", "divergence")
    assert np.all(above.frequency[:2] == 0.0) and np.all(above.growth_rate[:2] > 0)
    assert "divergence" in above.label[0] and above.kind[0] == "transverse"
    assert above.critical_speed == pytest.approx(c_cr.min(), rel=5e-3)
    assert above.n_rigid == 1 and above.stability[2] == "stable" and above.frequency[2] > 0


def rest_modes(over):
    return analyse(bench(*over), modal=True).modal


@pytest.mark.parametrize("dense", [True, False], ids=["dense", "sparse"])
def test_gyroscopic_modes_solve_the_quadratic_eigenproblem(dense):
    # At 15 m/s on the bench: every mode satisfies (s^2 M + s G + K) phi = 0 with s = i 2 pi f, its
    # normwise backward error |r| / ((|s|^2 |M| + |s| |G| + |K|) |phi|) <= 1e-11 (measured 2e-16 dense,
    # 2e-12 ARPACK at its tolerance 1e-12), phi^H M phi = 1, the largest entry real and positive; dense (Hermitian form) and
    # sparse (ARPACK shift-invert) agree to 1e-8 in frequency and kind.
    cfg = bench("running.belt_speed=15.0", "mesh.elements_per_span=12")
    run = analyse(cfg)
    md = solve_modes(run.system, run.static.q, n_modes=10, solver="dense" if dense else "sparse")
    lin = linearized_matrices(run.system, run.static.q)
    K, M, G = (np.asarray(x) for x in (lin.K, lin.M, lin.G))
    assert np.array_equal(G, -G.T)
    norm = [np.linalg.norm(x, 2) for x in (M, G, K)]
    for f, phi in zip(md.frequency, md.shapes):
        s = 2j * np.pi * f
        r = (s * s * M + s * G + K) @ phi
        eta = np.linalg.norm(r) / ((abs(s) ** 2 * norm[0] + abs(s) * norm[1] + norm[2]) * np.linalg.norm(phi))
        assert eta <= 1e-11, (f, eta)
        assert np.real(np.conj(phi) @ M @ phi) == pytest.approx(1.0, rel=1e-10)
        big = phi[np.argmax(np.abs(phi))]
        assert abs(big.imag) <= 1e-12 * abs(big) and big.real > 0
    ref = solve_modes(run.system, run.static.q, n_modes=10)
    np.testing.assert_allclose(md.frequency, ref.frequency, rtol=1e-8)
    assert md.kind == ref.kind
    assert md.solver == ("dense gyroscopic" if dense else "sparse gyroscopic")


def test_sparse_gyroscopic_modes_repeat_to_the_bit():
    # ARPACK with its own random start vector made two solves of one sparse gyroscopic problem differ by
    # ~1e-6 in a frequency (the FEAD at 12 m/s, 16 el/span); with the fixed start vector a run repeats exactly.
    cfg = bench("running.belt_speed=15.0", "mesh.elements_per_span=12")
    run = analyse(cfg)
    first, again = (solve_modes(run.system, run.static.q, n_modes=10, solver="sparse") for _ in range(2))
    assert np.array_equal(first.frequency, again.frequency)
    assert np.array_equal(first.shapes, again.shapes)


def test_running_modes_midspan_displacement_is_linear_in_the_complex_shape():
    # A running belt's mode shapes are complex (travelling waves); the mid-span displacement is linear in
    # the shape, so that of phi = a + i b is mid(a) + i mid(b), each evaluated on a real shape
    # (`BeltSpans.midspan_displacement_linear`), to 1e-12 of the largest. A spring span (no elements, its
    # column put in with zeros) must not drop the flexible spans' imaginary parts (it did: the modal
    # result came out real and /modal midspan_displacement_imag all zeros).
    run = analyse(bench('spans.C-A.model="spring"', "running.belt_speed=15.0", "mesh.elements_per_span=6",
                        "modal.modes=4"), modal=True)
    md, s = run.modal, run.system
    E = s.belt.element_coordinates(s.expand(run.static.q))

    def mid(phi):
        motion = s.belt.element_coordinates_batch(s.expand_motion(run.static.q, phi), offset=False)
        return s.belt.midspan_displacement_linear(E, motion)

    ref = mid(md.shapes.real) + 1j * mid(md.shapes.imag)
    assert np.abs(ref.imag).max() > 0.1 * np.abs(ref).max()  # travelling: the imaginary part is not small
    np.testing.assert_allclose(md.midspan_displacement, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


# ------------------------------------------------------------------------------------ transient
def transient_raw(**transient):
    raw = tomllib.loads(BENCH.read_text())
    raw["transient"] = {"duration": 0.05, "step": 1e-5, "output_interval": 1e-3, "rho_inf": 1.0,
                        "spectrum": {"enabled": False}, "tolerance": 1e-10, **transient}
    return raw


@pytest.mark.parametrize("spring", [(), ("C-A",)], ids=["ancf", "mixed"])
def test_transient_energy_balance_at_constant_speed(spring):
    # The bench at a constant belt speed of 15 m/s ([running], no prescribed rotation), no damping,
    # rho_inf = 1, started from the equilibrium at rest so that the centripetal force sets it moving:
    # kinetic + strain (with the centripetal potential) - work stays constant, the balance error
    # <= 1e-6 of the energy moved (measured ~1e-10): the gyroscopic forces do no work (a spring span's
    # included).
    raw = transient_raw()
    if spring:
        raw["spans"] = {n: {"model": "spring"} for n in spring}
    rest = analyse(config_from_dict(raw))
    raw["running"] = {"belt_speed": 15.0}
    cfg = config_from_dict(raw)
    run = analyse(cfg)
    got = []
    summary = run_transient(run.system, rest.static, cfg.transient, sink=lambda t, b: got.append(b["energy"]))
    e = np.concatenate(got)
    assert summary.status == "complete" and summary.energy_moved > 1e-3
    assert summary.energy_error <= 1e-6
    assert np.abs(e[:, 4]).max() <= 1e-6 * summary.energy_moved
    assert e[:, 0].max() > 1e-4 * summary.energy_moved  # it did move


def test_running_equilibrium_is_a_steady_state_of_the_transient():
    # A prescribed driver speed of 400 rad/s from t = 0 (15 m/s): the transient starts from the running
    # equilibrium at that speed (pipeline.transient_start) and stays there: kinetic energy < 1e-15 J,
    # span tensions and hub loads (with the momentum flux) within 1e-6 N of the static ones.
    cfg = config_from_dict(transient_raw(step=1e-4, rho_inf=0.9, rotation=[{"pulley": "A", "speed": 400.0}]))
    run = analyse(cfg)
    system, st = transient_start(run)
    assert run.system.belt_speed == 0.0 and system.belt_speed == pytest.approx(15.0, rel=1e-12)
    got = []
    summary = run_transient(system, st, cfg.transient,
                            sink=lambda t, b: got.append((b["energy"], b["span_tension"], b["hub_load"])))
    e, T, H = (np.concatenate([g[k] for g in got]) for k in range(3))
    assert summary.status == "complete"
    assert e[:, 0].max() < 1e-15
    assert np.abs(T - st.span_tension).max() < 1e-6 and np.abs(H - st.hub_load).max() < 1e-6


def test_transient_free_vibration_is_the_gyroscopic_mode():
    # At 15 m/s, started on the first transverse mode, x(0) = eps Re(phi), x'(0) = eps Re(i w phi): the
    # linear solution is x(t) = eps Re(phi e^{i w t}). The nonlinear transient's mid-span displacement
    # (eps = 1e-4, dt = 2e-5) follows eps Re(m e^{i w t}) (m the mode's mid-span displacement) within
    # 2 % of its amplitude over 3 periods (measured 2.2e-3; without the gyroscopic term the frequency
    # would be 7 % off).
    raw = transient_raw(duration=0.1, step=2e-5, output_interval=5e-4)
    raw["running"] = {"belt_speed": 15.0}
    cfg = config_from_dict(raw)
    run = analyse(cfg, modal=True)
    md = run.modal
    k = 0
    w = 2 * np.pi * md.frequency[k]
    eps = 1e-4
    setup = prepare(run.system, run.static, cfg.transient)
    import dataclasses

    q0 = setup.q0 + eps * np.real(md.shapes[k])
    v0 = eps * np.real(1j * w * md.shapes[k])
    setup = dataclasses.replace(setup, q0=q0, v0=v0)
    got = []
    run_transient(run.system, run.static, cfg.transient, setup=setup,
                  sink=lambda t, b: got.append((t, b["midspan_displacement"])))
    t = np.concatenate([g[0] for g in got])
    y = np.concatenate([g[1] for g in got])
    y0 = run.system.belt.midspan_displacement(run.system.belt.element_coordinates(run.static.q)[None])[0]
    expect = eps * np.real(md.midspan_displacement[k][None, :] * np.exp(1j * w * t)[:, None]) + y0
    amp = eps * np.abs(md.midspan_displacement[k]).max()
    sel = t <= 3 * 2 * np.pi / w
    assert np.abs(y[sel] - expect[sel]).max() <= 0.02 * amp


# ------------------------------------------------------------------------------------ Campbell sweep
def run_cli(*args, cwd):
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_campbell_sweep_lists_engine_order_crossings(tmp_path):
    # beltdyn sweep over the driver speed with [running] orders: /sweep has the speeds per case, tracked
    # frequencies and growth rates, and a crossing table whose entries lie on their order's line and on
    # the tracked mode: the modal analysis at the crossing's speed gives that mode's frequency within
    # 0.1 % of order x speed / 2 pi (the interpolation between cases 50 rad/s apart).
    raw = tomllib.loads(BENCH.read_text())
    raw["mesh"]["elements_per_span"] = 6
    raw["running"] = {"orders": [2.0, 4.0]}
    cfg_path = tmp_path / "bench.toml"
    import tomli_w

    cfg_path.write_bytes(tomli_w.dumps(raw).encode())
    out = tmp_path / "c.h5"
    r = run_cli("sweep", cfg_path, "--param", "running.driver_speed=0:400:9", "--modes", "6", "-o", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Campbell diagram" in r.stdout
    with h5py.File(out) as f:
        g = f["sweep"]
        speed = g["driver_speed"][()]
        np.testing.assert_allclose(speed, np.linspace(0, 400, 9))
        assert g["driver_speed"].attrs["units"] == "rad/s" and g["growth_rate"].shape == (9, 6)
        order = g["crossing_order"][()]
        W = g["crossing_driver_speed"][()]
        f_x = g["crossing_frequency"][()]
        mode = g["crossing_mode"][()]
        labels = [x.decode() for x in g["crossing_label"][()]]
        assert set(order) == {2.0, 4.0} and len(order) >= 4
        np.testing.assert_allclose(f_x, order * W / (2 * np.pi), rtol=1e-12)
    checked = 0
    for k, Wk, fk, lab in zip(order, W, f_x, labels):
        if lab.startswith("1st transverse"):
            md = analyse(load_config(cfg_path, [f"running.driver_speed={float(Wk)!r}"]), modal=True, n_modes=6).modal
            assert min(abs(f - fk) for f in md.frequency) <= 1e-3 * fk, (k, Wk, lab)
            checked += 1
    assert checked >= 2


def test_campbell_sweep_reports_the_critical_speed(tmp_path):
    # EI = 5 N m^2: the sweep through the first critical speed reports a divergence of the first
    # transverse modes at the belt speed of the closed form rho c^2 = S + EI (pi / L)^2 within 0.5 %
    # (interpolating omega^2 - sigma^2 linearly in the squared speed between cases 2 m/s apart).
    raw = tomllib.loads(BENCH.read_text())
    raw["belt"]["EI"] = 5.0
    cfg_path = tmp_path / "bench.toml"
    import tomli_w

    cfg_path.write_bytes(tomli_w.dumps(raw).encode())
    out = tmp_path / "c.h5"
    r = run_cli("sweep", cfg_path, "--param", "running.belt_speed=40:56:9", "--modes", "4", "-o", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "divergence" in r.stdout
    rest = analyse(load_config(cfg_path))
    S = reference_tension(rest.static.span_tension.mean())[0]
    c_cr = math.sqrt((S + 5.0 * (np.pi / rest.system.belt.reference_length.mean()) ** 2) / RHO)
    with h5py.File(out) as f:
        kinds = [x.decode() for x in f["sweep/instability_kind"][()]]
        c = f["sweep/instability_belt_speed"][()]
    assert kinds[:2] == ["divergence", "divergence"]
    np.testing.assert_allclose(c[:2], c_cr, rtol=5e-3)


def test_modal_at_speed_writes_complex_shapes(tmp_path):
    # beltdyn modal at a driver speed: /modal has shape and shape_imag (phi = shape + 1j shape_imag solves
    # the quadratic eigenproblem, backward error 1e-12), growth_rate, stability and the speeds as attributes; it opens
    # in xarray; both speeds at once are a configuration error naming the key (exit 2).
    out = tmp_path / "m.h5"
    r = run_cli("modal", BENCH, "--set", "running.driver_speed=400", "--modes", "4", "-o", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "gyroscopic" in r.stdout
    with h5py.File(out) as f:
        g = f["modal"]
        phi = g["shape"][()] + 1j * g["shape_imag"][()]
        assert g.attrs["driver_speed_rad_per_s"] == pytest.approx(400.0)
        assert g.attrs["belt_speed_m_per_s"] == pytest.approx(15.0)
        assert list(g["stability"].asstr()[()]) == ["stable"] * 4
        assert np.all(g["growth_rate"][()] == 0.0)
        f_hz = g["frequency"][()]
    run = analyse(load_config(BENCH, ["running.driver_speed=400"]))
    lin = linearized_matrices(run.system, run.static.q)
    norm = [np.linalg.norm(x, 2) for x in (lin.M, lin.G, lin.K)]
    for f, p in zip(f_hz, phi):
        s = 2j * np.pi * f
        r = (s * s * lin.M + s * lin.G + lin.K) @ p
        assert np.linalg.norm(r) <= 1e-12 * (abs(s) ** 2 * norm[0] + abs(s) * norm[1] + norm[2]) * np.linalg.norm(p)
    xr = pytest.importorskip("xarray")
    ds = xr.open_dataset(out, group="modal", engine="h5netcdf")
    assert ds["shape_imag"].dims == ("mode", "dof")
    bad = run_cli("modal", BENCH, "--set", "running.driver_speed=400", "--set", "running.belt_speed=3",
                  "-o", tmp_path / "x.h5", cwd=tmp_path)
    assert bad.returncode == 2 and "running.driver_speed" in bad.stderr and "Traceback" not in bad.stderr


@pytest.mark.parametrize("spring", [False, True], ids=["ancf", "all-spring"])
def test_speed_ramp_torque_is_the_drive_inertia(spring):
    # The bench's driver A ramped linearly to 100 rad/s over 0.3 s (mass-proportional damping 20 1/s
    # settles the start's vibration): the mean driver torque over 0.1-0.29 s is the drive's inertia
    # times the acceleration, (J_A + J_C (R_A/R_C)^2 + rho sum(L_span) R_A^2) alpha (the spans' belt;
    # the wraps ride rigid on their pulleys), within 1 % (measured 0.4 %). The spans' axial inertia is
    # their transport term c' A alone: counting a spring span's lumped mass in the nominal load as well
    # put the all-spring drive 3.6 % above.
    raw = tomllib.loads(BENCH.read_text())
    raw["transient"] = {"duration": 0.3, "step": 1e-4, "output_interval": 1e-4, "rho_inf": 0.9,
                        "spectrum": {"enabled": False}, "damping": {"rayleigh_mass": 20.0},
                        "rotation": [{"pulley": "A", "speed": 100.0, "ramp_time": 0.3}]}
    if spring:
        raw["spans"] = {"A-C": {"model": "spring"}, "C-A": {"model": "spring"}}
    cfg = config_from_dict(raw)
    run = analyse(cfg)
    got = []
    run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: got.append((t, b["driver_torque"])))
    t = np.concatenate([g[0] for g in got])
    torque = np.concatenate([g[1] for g in got]).reshape(len(t), -1)[:, 0]
    (RA, JA), (RC, JC) = ((p.radius, p.inertia) for p in cfg.pulleys)
    expected = (JA + JC * (RA / RC) ** 2 + RHO * float(run.system.belt.reference_length.sum()) * RA ** 2) * (100.0 / 0.3)
    window = (t > 0.1) & (t < 0.29)
    assert torque[window].mean() == pytest.approx(expected, rel=1e-2)
