"""The hybrid drive: statics, modal analysis, the paper's tables, closed forms and extremes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import config_from_dict, load_config
from beltdyn.errors import SolverError
from beltdyn.analysis.modal import solve_modes
from beltdyn.study.paper import CASES, compare
from beltdyn.analysis.static import solve_static
from beltdyn.model.barlaw import stretch_for_tension
from beltdyn.model.system import build_system

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def run(path_or_cfg, overrides=(), n_modes=16, dense=None):
    cfg = load_config(path_or_cfg, list(overrides)) if isinstance(path_or_cfg, (str, Path)) else path_or_cfg
    model = build_system(cfg, dense=dense)
    st = solve_static(model, cfg.static)
    return cfg, model, st, solve_modes(model, st.q, n_modes=n_modes)


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.config)
def test_paper_tables(case):
    # Against the paper's Tables 1 and 2 (theoretical column): every mode matched by kind and order
    # (compare() raises if a kind/order is missing) and within 0.5 %.
    _, _, _, modes = run(CONFIGS / "paper" / f"{case.config}.toml")
    rows = compare(case, modes)
    assert len(rows) == 8
    for r in rows:
        assert abs(r.diff_theory_pct) < 0.5, r


def test_paper_bench_static():
    # The target tension is met (1e-9 relative), both spans carry it (1e-6), the tension move of
    # pulley A is ~1.13 mm (DESIGN section 2), and the hub load on A equals N (t_out - t_in)
    # computed from the deformed tangent points (1e-6 relative).
    cfg, model, st, _ = run(CONFIGS / "paper" / "bench_T200.toml", n_modes=1)
    assert st.mean_tension == pytest.approx(200.0, rel=1e-9)
    np.testing.assert_allclose(st.span_tension, 200.0, rtol=1e-6)
    move = model.layout.adjust_offset - st.adjust_offset
    assert move == pytest.approx(1.13e-3, abs=0.01e-3)
    e = model.belt.element_coordinates(st.q)
    first = [s[0] for s in model.belt.span_elements]
    last = [s[-1] for s in model.belt.span_elements]
    t_out = e[first[0], 4:6] - e[first[0], 0:2]
    t_in = e[last[1], 4:6] - e[last[1], 0:2]
    expect = 200.0 * (t_out / np.linalg.norm(t_out) - t_in / np.linalg.norm(t_in))
    np.testing.assert_allclose(st.hub_load[0], expect, rtol=1e-6)
    np.testing.assert_allclose(st.hub_load[1], -expect, rtol=1e-6)


def test_tension_move_400N():
    # DESIGN section 2: about 2.25 mm of travel for 400 N.
    _, model, st, _ = run(CONFIGS / "paper" / "bench_T400.toml", n_modes=1)
    assert model.layout.adjust_offset - st.adjust_offset == pytest.approx(2.25e-3, abs=0.01e-3)


@pytest.mark.parametrize("tension", [20.0, 200.0])
def test_gravity_global_equilibrium(tension):
    # Independent check of the hub loads: the forces of the belt on the pulleys add up to the belt's
    # weight (rho g sum of reference lengths), relative 1e-8.
    cfg, model, st, _ = run(CONFIGS / "paper" / "bench_T200.toml",
                            ["model.gravity=[0.0, -9.81]", f"tension.target={tension}"], n_modes=1)
    weight = cfg.belt.mass_per_length * 9.81 * model.belt.reference_length.sum()
    np.testing.assert_allclose(st.hub_load.sum(axis=0), [0.0, -weight], rtol=0, atol=1e-8 * weight)
    assert st.mean_tension == pytest.approx(tension, rel=1e-9)


def test_reduced_tangent_against_finite_differences():
    # K_t = d f_int / dq of the reduced model (joints included) against central differences, 1e-6 relative.
    cfg = load_config(CONFIGS / "smoke" / "three_pulley.toml")
    model = build_system(cfg)
    st = solve_static(model, cfg.static)
    rng = np.random.default_rng(1)
    q = st.q + 1e-4 * rng.standard_normal(model.n_dof)
    _, K = model.force_and_tangent(q)
    h = 1e-7
    fd = np.empty((model.n_dof, model.n_dof))
    for i in range(model.n_dof):
        dq = np.zeros(model.n_dof)
        dq[i] = h
        fd[:, i] = (model.internal_force(q + dq) - model.internal_force(q - dq)) / (2 * h)
    assert np.abs(K - fd).max() <= 1e-6 * np.abs(K).max()
    T, dT = model.mean_tension_and_gradient(q)
    fd_T = np.array([(model.mean_tension_and_gradient(q + h * np.eye(model.n_dof)[i])[0]
                      - model.mean_tension_and_gradient(q - h * np.eye(model.n_dof)[i])[0]) / (2 * h)
                     for i in range(model.n_dof)])
    assert np.abs(dT - fd_T).max() <= 1e-6 * np.abs(dT).max()


def test_modes_are_mass_normalized_eigenvectors():
    # phi^T M phi = I and K phi = omega^2 M phi (relative residual 1e-8).
    _, model, st, modes = run(CONFIGS / "smoke" / "three_pulley.toml", n_modes=8)
    _, K = model.force_and_tangent(st.q)
    Phi = modes.shapes.T
    np.testing.assert_allclose(Phi.T @ model.mass @ Phi, np.eye(Phi.shape[1]), atol=1e-9)
    w2 = (2 * np.pi * modes.frequency) ** 2
    res = K @ Phi - (model.mass @ Phi) * w2
    assert np.abs(res).max() <= 1e-8 * np.abs(K @ Phi).max()
    assert modes.n_rigid == 1


def test_sparse_and_dense_solvers_agree():
    # Shift-invert ARPACK on CSR matrices against dense LAPACK on the same model (1e-9 relative).
    path = CONFIGS / "paper" / "bench_T200.toml"
    _, _, _, dense = run(path, ["mesh.elements_per_span=12"], n_modes=10, dense=True)
    _, _, _, sparse = run(path, ["mesh.elements_per_span=12"], n_modes=10, dense=False)
    assert dense.solver == "dense" and sparse.solver == "sparse"
    np.testing.assert_allclose(sparse.frequency, dense.frequency, rtol=1e-9)
    assert dense.kind == sparse.kind


def test_symmetric_shift_invert_against_dense_lapack():
    # The sparse path's standard symmetric form (M = L L^T, C = L^T (K - sigma M)^-1 L) against dense
    # LAPACK on the same matrices: eigenvalues to 1e-9, M-orthonormal vectors to 1e-12, residuals
    # K x - lam M x to 1e-8; a singular mass matrix is refused (LinAlgError: the caller falls back).
    from scipy.linalg import eigh
    from scipy.sparse import csr_matrix
    from scipy.sparse.linalg import splu

    from beltdyn.analysis.modal import _symmetric_shift_invert

    _, model, st, _ = run(CONFIGS / "paper" / "bench_T200.toml", ["mesh.elements_per_span=30"], n_modes=4)
    _, K = model.equilibrium(st.q)
    K, M = csr_matrix(K), csr_matrix(model.mass_matrix(st.q))
    sigma = -1.0
    lam, X = _symmetric_shift_invert(M, splu((K - sigma * M).tocsc()), sigma, 12)
    order = np.argsort(lam)
    lam, X = lam[order], X[:, order]
    ref = eigh(K.toarray(), M.toarray(), subset_by_index=[0, 11], eigvals_only=True)
    np.testing.assert_allclose(lam[1:], ref[1:], rtol=1e-9)  # [0]: the rigid mode, ~0
    np.testing.assert_allclose(X.T @ (M @ X), np.eye(12), atol=1e-12)
    assert np.abs(K @ X - (M @ X) * lam).max() <= 1e-8 * np.abs(K @ X).max()
    Ms = M.tolil()
    Ms[5, :] = 0.0
    Ms[:, 5] = 0.0
    with pytest.raises(np.linalg.LinAlgError):
        _symmetric_shift_invert(csr_matrix(Ms), splu((K - sigma * M).tocsc()), sigma, 4)


# ---------------------------------------------------------------------------------------------
# Closed forms: two equal pulleys with fixed centres and huge inertia, spans prestrained to T.
def heavy_drive(*, tension: float, EI: float, n_el: int, span: float = 0.6, EA: float = 120000.0,
                rho: float = 0.11915, curvature: str = "linear"):
    r = 0.05
    return config_from_dict({
        "belt": {"length": 2 * span + 2 * math.pi * r, "EA": EA, "EI": EI, "mass_per_length": rho},
        "pulleys": [
            {"name": "A", "center": [0.0, 0.0], "radius": r, "mass": 1.0, "inertia": 1e3},
            {"name": "B", "center": [span, 0.0], "radius": r, "mass": 1.0, "inertia": 1e3},
        ],
        "tension": {"target": tension, "mode": "prestrain"},
        "mesh": {"elements_per_span": n_el},
        "model": {"curvature": curvature},
        "modal": {"modes": 30},
    })


def closed_forms(tension, EI, EA, rho, span, n, EI_axial=0.0, ref_length=None):
    """Pinned beam under tension (taut string for EI = 0) and fixed-fixed bar about the prestretched
    state, in the reference length L_ref = span / lambda with S = EA eps (2nd Piola-Kirchhoff) and the
    axial tangent modulus dP/dlambda = EA (3 lambda^2 - 1)/2. EI_axial: the linear bending form of
    Eq. 17, EI int r''.r'' dx, also penalizes u'' along the span, adding EI k^4 to the bar's
    dispersion relation (the exact curvature of Eq. 15 does not)."""
    lam = stretch_for_tension(tension, EA)
    L = span / lam if ref_length is None else ref_length
    S = EA * (lam**2 - 1) / 2
    k = n * np.pi / L
    f_beam = np.sqrt(S * k**2 + EI * k**4) / np.sqrt(rho) / (2 * np.pi)
    f_bar = np.sqrt(EA * (3 * lam**2 - 1) / 2 * k**2 + EI_axial * k**4) / np.sqrt(rho) / (2 * np.pi)
    return f_beam, f_bar


@pytest.mark.parametrize("tension,EI,curvature", [(200.0, 0.0, "linear"), (200.0, 0.02, "linear"),
                                                   (50.0, 5.0, "linear"), (2000.0, 100.0, "linear"),
                                                   (2000.0, 100.0, "exact"), (5000.0, 0.0, "none")])
def test_span_frequencies_match_closed_forms(tension, EI, curvature):
    # Transverse: pinned beam under tension / taut string; axial: fixed-fixed bar (with the linear
    # bending form's EI k^4 term, see closed_forms). Within 0.1 %.
    cfg = heavy_drive(tension=tension, EI=EI, n_el=40, curvature=curvature)
    _, _, _, modes = run(cfg, n_modes=80)
    n = np.arange(1, 6)
    # exact curvature (Eq. 15) of a span stretched by lambda: kappa = w''/lambda^2 in reference
    # coordinates, so its bending stiffness per reference length is EI / lambda^4
    lam = stretch_for_tension(tension, 120000.0)
    EI_eff = {"none": 0.0, "linear": EI, "exact": EI / lam**4}[curvature]
    f_beam, f_bar = closed_forms(tension, EI_eff, 120000.0, 0.11915, 0.6, n,
                                 EI_axial=EI if curvature == "linear" else 0.0)
    trans = np.sort(modes.frequency[np.array(modes.kind) == "transverse"])[:10]
    np.testing.assert_allclose(trans, np.repeat(f_beam, 2), rtol=1e-3)
    order = modes.order[np.array(modes.kind) == "transverse"][np.argsort(modes.frequency[np.array(modes.kind) == "transverse"])][:10]
    np.testing.assert_array_equal(order, np.repeat(n, 2))
    axial = np.sort(modes.frequency[np.array(modes.kind) == "longitudinal"])[:2]
    np.testing.assert_allclose(axial, np.repeat(f_bar[:1], 2), rtol=1e-3)


def test_mesh_convergence_rate():
    # Cubic Hermite beam elements: the error of the 3rd pinned-beam frequency falls like h^4; the
    # measured log-log slope (polyfit) must be above 3.5.
    n_el = np.array([3, 4, 6, 8, 12])
    f_beam, _ = closed_forms(200.0, 10.0, 120000.0, 0.11915, 0.6, np.array([3]))
    errors = []
    for ne in n_el:
        _, _, _, modes = run(heavy_drive(tension=200.0, EI=10.0, n_el=int(ne)), n_modes=12)
        kinds = np.array(modes.kind)
        f3 = modes.frequency[(kinds == "transverse") & (modes.order == 3)].min()
        errors.append(abs(f3 - f_beam[0]) / f_beam[0])
    slope = np.polyfit(np.log(1.0 / n_el), np.log(errors), 1)[0]
    assert slope > 3.5, (slope, errors)


# ---------------------------------------------------------------------------------------------
# Extremes (issue 3): finite results with the tension reached, or a clear SolverError.
@pytest.mark.parametrize("EI", [0.0, 1e-6, 0.02, 100.0, 1000.0])
@pytest.mark.parametrize("tension", [1.0, 10.0, 200.0, 5000.0])
def test_extreme_stiffness_and_tension(EI, tension):
    # Against the closed form of the lower span (horizontal, not coupled to A's slide): its first
    # transverse mode is the pinned beam under S on L_ref within 1 % (10 elements per span, so the
    # discretization error of EI = 1000 N m^2 is included).
    cfg, model, st, modes = run(CONFIGS / "paper" / "bench_T200.toml",
                                [f"belt.EI={EI}", f"tension.target={tension}"], n_modes=12)
    assert st.mean_tension == pytest.approx(tension, rel=1e-8)
    assert np.all(np.isfinite(modes.frequency)) and np.all(np.isfinite(modes.shapes))
    lower = [k for k in range(len(modes.frequency))
             if modes.kind[k] == "transverse" and modes.order[k] == 1 and modes.span[k] == 1]
    assert lower, modes.label
    # tension mode "adjust": the spans are stress-free in the L0 geometry, so L_ref is the geometric length
    f_beam, _ = closed_forms(tension, EI, 120000.0, 0.11915, None, np.array([1]), ref_length=0.6715523)
    assert modes.frequency[lower[0]] == pytest.approx(f_beam[0], rel=1e-2)


@pytest.mark.parametrize("n_el", [1, 2, 400])
def test_extreme_meshes(n_el):
    # 1 to 400 elements per span: tension met, finite, the 1st transverse mode within 1 % of the taut
    # string estimate (0.7 % of the EI correction included at 1 element).
    _, model, st, modes = run(CONFIGS / "paper" / "bench_T200.toml", [f"mesh.elements_per_span={n_el}"], n_modes=6)
    assert st.mean_tension == pytest.approx(200.0, rel=1e-8)
    f_string = 1 / (2 * 0.6715523) * math.sqrt(200.0 / 0.11915)
    assert modes.frequency[0] == pytest.approx(f_string, rel=1e-2)
    assert modes.solver == ("sparse" if model.n_dof > 200 else "dense")


@pytest.mark.parametrize("k,f_trans", [(0.0, 63.6), (1e12, None)])
def test_extreme_bearing_stiffness(k, f_trans):
    # No bearing spring: A is held along the slide by the belt alone; the translational mode is the
    # belt's axial stiffness on m1, 2 EA/L (1 + cos^2 10.9 deg)/2 ... ~ 63.6 Hz (1 %). Rigid bearing:
    # no translational mode below 1 kHz; everything finite.
    _, _, st, modes = run(CONFIGS / "paper" / "bench_T200.toml", [f"pulleys[0].bearing_stiffness={k}"], n_modes=14)
    assert np.all(np.isfinite(modes.frequency))
    trans = modes.frequency[np.array(modes.kind) == "translational"]
    if f_trans is None:
        assert trans.size == 0
    else:
        EA, L, m1 = 120000.0, 0.6715523, 2.1543
        k_belt = EA / L * (1 + math.cos(math.radians(10.9048)) ** 2)
        assert trans[0] == pytest.approx(math.sqrt(k_belt / m1) / (2 * math.pi), rel=1e-2)


def test_low_tension_with_gravity_converges():
    # A sagging belt (EI = 0, T = 1 N, gravity): the bordered Newton fails and the tension loop takes
    # over; the weight is carried (global equilibrium 1e-8) and the target met.
    cfg, model, st, modes = run(CONFIGS / "paper" / "bench_T200.toml",
                                ["model.gravity=[0.0, -9.81]", "tension.target=1.0", "belt.EI=0.0"], n_modes=4)
    weight = cfg.belt.mass_per_length * 9.81 * model.belt.reference_length.sum()
    np.testing.assert_allclose(st.hub_load.sum(axis=0), [0.0, -weight], atol=1e-8 * weight)
    assert st.mean_tension == pytest.approx(1.0, rel=1e-8)
    assert np.all(modes.frequency > 0)


def test_slack_free_belt_fails_clearly():
    # A belt without tension and without bending stiffness has no transverse stiffness: the static
    # state is the stress-free one, and the modal analysis must fail with a SolverError naming the
    # analysis and a span DOF (not zero frequencies or NaN).
    from beltdyn.config import config_to_dict
    from beltdyn.model.geometry import layout_from_config

    raw = config_to_dict(load_config(CONFIGS / "paper" / "bench_T200.toml"))
    raw["pulleys"][0]["adjustable"] = False
    raw["belt"]["EI"] = 0.0
    raw["tension"] = {}
    raw["belt"]["length"] = layout_from_config(config_from_dict(raw)).belt_length  # exactly the path: no strain
    cfg = config_from_dict(raw)
    model = build_system(cfg)
    assert model.belt.prestrain_stretch == 1.0
    st = solve_static(model, cfg.static)
    with pytest.raises(SolverError) as err:
        solve_modes(model, st.q, n_modes=4)
    text = str(err.value)
    assert text.startswith("modal:") and "mechanism" in text and "span" in err.value.item


@pytest.mark.parametrize("w, zeros", [
    ([2.7e-3, 1.1e5, 3.9e5], [True, False, False]),  # FEAD at 640 el/span: the rigid turn, then true modes
    ([-0.28, -0.27, -0.03, 4e-4, 0.02], [True] * 5),  # a slack string's mechanism: one cluster
    ([-0.28, 4e-4, 0.1, 5e4], [True, True, True, False]),  # a mechanism, then a true mode past the gap
    ([-0.28, 4e-4, -5e4], [True, True, True]),  # a negative candidate is never a true mode
], ids=["rigid + modes", "mechanism", "mechanism + mode", "negative"])
def test_zero_modes_split_at_the_gap(w, zeros):
    # Candidates |w| <= tol (here 2.1e5 1/s^2, 1000 eps lam_max of the FEAD example at 640 el/span) are
    # zero below the first gap of more than 1e3 between consecutive |w|; positive ones above it are
    # true modes that the round-off bound reached. The cases use the measured magnitudes.
    from beltdyn.analysis.modal import zero_modes

    assert zero_modes(np.array(w), 2.1e5).tolist() == zeros


@pytest.mark.parametrize("elements", [10, 160])
def test_slack_string_is_a_mechanism_on_any_mesh(elements):
    # A belt of exactly its path length without bending stiffness is a mechanism: its zero modes come
    # out at up to 200 eps lam_max (negative) at 160 el/span; they stay one cluster of zeros there
    # (a tolerance of 100 eps lam_max called them an unstable equilibrium).
    from beltdyn.config import config_to_dict
    from beltdyn.model.geometry import layout_from_config

    raw = config_to_dict(load_config(CONFIGS / "paper" / "bench_T200.toml", [f"mesh.elements_per_span={elements}"]))
    raw["pulleys"][0]["adjustable"] = False
    raw["belt"]["EI"] = 0.0
    raw["tension"] = {}
    raw["belt"]["length"] = layout_from_config(config_from_dict(raw)).belt_length
    cfg = config_from_dict(raw)
    model = build_system(cfg)
    st = solve_static(model, cfg.static)
    with pytest.raises(SolverError, match="zero-frequency modes.*mechanism"):
        solve_modes(model, st.q, n_modes=4)


@pytest.mark.slow
def test_a_fine_mesh_keeps_its_lowest_mode_elastic():
    # At 640 el/span the FEAD example's stiffest element ratio K_ii/M_ii is 9.5e17 1/s^2 (eps x that =
    # 210): the zero tolerance of 1000 eps x that (2.1e5) reaches the first elastic mode (52.8 Hz, 1.1e5),
    # which was taken for a second zero mode (a mechanism: `modal --rtol 1e-8` failed); the gap to the
    # rigid turn (2.7e-3) tells them apart. Reference: the same drive at 160 el/span; the mode has
    # converged to 1e-7 there (the --rtol estimates), compared within 1e-6.
    from beltdyn.pipeline import analyse

    fead = CONFIGS / "examples" / "fead_4cyl.toml"
    coarse = analyse(load_config(fead, ["mesh.elements_per_span=160"]), modal=True, n_modes=3).modal
    fine = analyse(load_config(fead, ["mesh.elements_per_span=640"]), modal=True, n_modes=3).modal
    assert fine.n_rigid == 1
    np.testing.assert_allclose(fine.frequency, coarse.frequency, rtol=1e-6)


@pytest.mark.parametrize("EI", [0.0, 0.02, 100.0, 1000.0])
@pytest.mark.parametrize("tension", [1.0, 200.0, 5000.0])
def test_extremes_on_a_fine_mesh(EI, tension):
    # The extreme grid again at 400 el/span: the lower span's first transverse mode
    # matches the pinned beam under tension within 0.1 % (the 1 % of the 10-element test was
    # discretization).
    cfg, model, st, modes = run(CONFIGS / "paper" / "bench_T200.toml",
                                [f"belt.EI={EI}", f"tension.target={tension}", "mesh.elements_per_span=400"],
                                n_modes=12)
    lower = [k for k in range(len(modes.frequency))
             if modes.kind[k] == "transverse" and modes.order[k] == 1 and modes.span[k] == 1]
    f_beam, _ = closed_forms(tension, EI, 120000.0, 0.11915, None, np.array([1]), ref_length=0.6715523)
    assert modes.frequency[lower[0]] == pytest.approx(f_beam[0], rel=1e-3)


# ------------------------------------------------------------------ mid-span motion across the chord
def _bench_modes():
    from beltdyn.pipeline import analyse

    return analyse(load_config(Path(__file__).resolve().parents[1] / "configs" / "paper" / "bench_T200.toml"),
                   modal=True)


def test_modal_midspan_displacement_is_the_linearized_transient_definition():
    # /modal midspan_displacement is the first-order change of the transient's mid-span displacement
    # (from the moving chord) along each shape: against a central difference of the nonlinear
    # definition, step 1e-5, within 1e-6 of the largest value.
    run = _bench_modes()
    belt, q, md = run.system.belt, run.static.q, run.modal
    h = 1e-5
    for k in range(len(md.frequency)):
        plus = belt.midspan_displacement(belt.element_coordinates(q + h * md.shapes[k])[None])[0]
        minus = belt.midspan_displacement(belt.element_coordinates(q - h * md.shapes[k])[None])[0]
        fd = (plus - minus) / (2 * h)
        assert np.abs(fd - md.midspan_displacement[k]).max() <= 1e-6 * np.abs(md.midspan_displacement).max()


def test_modal_midspan_displacement_matches_the_pinned_string_closed_form():
    # A mass-normalized pinned-string mode sin(n pi x / L) has the mid-span amplitude sqrt(2 / (rho L))
    # for odd n (0 for even n, a node at mid-span). The bench's spans (EI = 0.02 N m^2) are string-like:
    # within 1 % for n = 1, 3, 5 on the span the mode lives on; even n and the other span below 1e-3 of
    # it. The rotational mode (the belt stretching axially) shows no motion across the chord.
    run = _bench_modes()
    md = run.modal
    cfg = run.config
    L = run.system.belt.reference_length
    for k in range(len(md.frequency)):
        s = int(md.span[k]) - 1
        ref = np.sqrt(2.0 / (cfg.belt.mass_per_length * L[max(s, 0)]))
        mid = np.abs(md.midspan_displacement[k])
        if md.kind[k] == "transverse":
            n = int(md.order[k])
            if n % 2:  # higher orders feel the bending stiffness (n = 7: +1.9 %)
                assert n > 5 or abs(mid[s] / ref - 1.0) < 1e-2, (md.label[k], mid[s], ref)
            else:
                assert mid[s] < 1e-3 * ref, (md.label[k], mid[s])
            assert mid[1 - s] < 1e-3 * ref
        elif md.kind[k] == "rotational":
            assert mid.max() < 1e-3 * ref, (md.label[k], mid)


@pytest.mark.parametrize("seed", range(4))
def test_vectorized_half_waves_count_as_the_definition(seed):
    # The classification counts half-waves of all of a span's transverse modes at once
    # (`half_waves_real`); reference: the definition, row by row (sign changes between the samples
    # above 5 % of the row's largest, + 1), on sine shapes with noise, random rows and rows with zeros.
    from beltdyn.analysis.modal import half_waves_real

    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 80)
    rows = [np.sin(np.pi * k * x) + 0.03 * rng.standard_normal(80) for k in range(1, 9)]
    rows += [rng.standard_normal(80) for _ in range(20)]
    rows += [np.where(rng.random(80) < 0.6, 0.0, rng.standard_normal(80)) for _ in range(20)]
    W = np.vstack(rows)

    def definition(w):
        s = np.sign(w[np.abs(w) > 0.05 * np.abs(w).max()])
        return int(np.count_nonzero(s[1:] != s[:-1])) + 1

    assert half_waves_real(W).tolist() == [definition(w) for w in W]
    clean = np.vstack([np.sin(np.pi * k * x) + 0.005 * rng.standard_normal(80) for k in range(1, 9)])
    assert half_waves_real(clean).tolist() == list(range(1, 9))  # the k-th sine (noise under 5 %): k half-waves


@pytest.mark.parametrize("seed", range(4))
def test_batched_envelope_half_waves_count_as_row_by_row(seed):
    # Travelling (complex) shapes: `half_waves_envelope` counts the humps of every row's envelope |w| at
    # once; reference: the count row by row on the envelope's extrema (the rule of `half_waves`: a new hump
    # where the envelope rises above twice a dip below half the hump's top and above 5 % of its largest),
    # on standing waves sin(k pi x) e^(i theta), travelling waves e^(i k pi x) with a standing part, and
    # random rows; the standing sine of order k has k humps.
    from beltdyn.analysis.modal import half_waves_envelope

    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 80)
    rows = [np.sin(np.pi * k * x) * np.exp(1j * rng.uniform(0, 6)) for k in range(1, 9)]
    rows += [np.exp(1j * np.pi * k * x) * 0.2 + np.sin(np.pi * k * x) for k in range(1, 9)]
    rows += [rng.standard_normal(80) + 1j * rng.standard_normal(80) for _ in range(20)]
    W = np.vstack(rows)

    def row_by_row(w):
        env = np.abs(w)
        slope = np.sign(np.diff(env))
        turns = env[np.concatenate(([0], np.flatnonzero(slope[1:] != slope[:-1]) + 1, [len(env) - 1]))]
        humps, top, low = 1, turns[0], turns[0]
        for v in turns[1:]:
            if low < 0.5 * top and v > 2.0 * low and v > 0.05 * env.max():
                humps, top, low = humps + 1, v, v
            elif v > top and low >= 0.5 * top:
                top = low = v
            else:
                low = min(low, v)
        return humps

    got = half_waves_envelope(W)
    assert got == [row_by_row(w) for w in W]
    assert got[:8] == list(range(1, 9))
