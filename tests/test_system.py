"""The system of components: a component written here (a linear rotational spring) joins the drive
without touching any analysis, and its static, modal and transient results match closed forms;
transient convergence does not depend on the size of a bearing preload."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import config_from_dict, config_to_dict, load_config
from beltdyn.analysis.modal import solve_modes
from beltdyn.analysis.static import solve_static
from beltdyn.model.components import LinearComponent
from beltdyn.model.system import build_system
from beltdyn.analysis.transient import prepare, run_transient

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"


def rotational_spring(system, k: float, *, pulleys: tuple[str, ...], free: float = 0.0) -> LinearComponent:
    """A torsion spring: between two pulleys' rotations (k (theta_a - theta_b)) or from one pulley to
    the ground (k (theta - free))."""
    dofs = np.array([system.rot_dof[system.pulley_index(p)] for p in pulleys], dtype=np.int64)
    K = k * (np.array([[1.0, -1.0], [-1.0, 1.0]]) if len(pulleys) == 2 else np.ones((1, 1)))
    return LinearComponent(name=f"torsion spring {'-'.join(pulleys)}", dofs=dofs, stiffness=K,
                           free=None if len(pulleys) == 2 else np.array([free]))


def bench(overrides=()):
    cfg = load_config(BENCH, list(overrides))
    return cfg, build_system(cfg)


@pytest.mark.parametrize("dense", [True, False])
def test_torsion_spring_static_matches_belt_stiffness_closed_form(dense):
    # A torsion spring on C with its free angle theta0 = 1e-3 rad, A held (the static driver). Without the
    # spring C already turns to theta* (the tension move of A is not symmetric); the spring turns it on
    # until its torque k (theta0 - theta) equals the belt's, kb (theta - theta*) with kb = 2 EA R_C^2 / L
    # (the spans stretch and shorten by R_C (theta - theta*)). Closed form
    # theta - theta* = k (theta0 - theta*) / (k + kb) within 1e-2 (the tension-stiffening of the end
    # joints adds ~T / EA ~ 0.2 % to kb); the tension difference 2 EA R_C (theta - theta*) / L within
    # 1e-2; the driver's torque equals the spring torque carried across the belt, R_A / R_C k (theta0 - theta)
    # (1e-6: exact moment balance of the equilibrium).
    cfg = load_config(BENCH)
    system = build_system(cfg, dense=dense)
    base = solve_static(system, cfg.static)
    k, theta0 = 2000.0, 1e-3
    s = system.with_components(rotational_spring(system, k, pulleys=("C",), free=theta0))
    st = solve_static(s, cfg.static)
    L = float(system.layout.span_length[0])
    R_A, R_C, EA = 0.0375, 0.1016, cfg.belt.EA
    kb = 2 * EA * R_C ** 2 / L
    star = base.q[s.rot_dof[1]]
    theta = st.q[s.rot_dof[1]]
    assert theta - star == pytest.approx(k * (theta0 - star) / (k + kb), rel=1e-2)
    dT = np.ptp(st.span_tension[:, 0]) - np.ptp(base.span_tension[:, 0])
    assert abs(dT) == pytest.approx(2 * EA * R_C * (theta - star) / L, rel=1e-2)
    assert abs(st.driver_torque - base.driver_torque) == pytest.approx(R_A / R_C * k * (theta0 - theta), rel=1e-6)


def rigid_belt_frequency(cfg, system, k):
    """Torsion spring between A and C on the belt-turning (rigid-body) mode: belt travel s turns A by
    s / R_A and C by s / R_C; kinetic energy 1/2 s'^2 (J_A / R_A^2 + J_C / R_C^2 + rho (L1 + L2)) (the
    model's belt mass is on the spans), potential 1/2 k s^2 (1/R_A - 1/R_C)^2."""
    pa, pc = cfg.pulleys
    m = pa.inertia / pa.radius ** 2 + pc.inertia / pc.radius ** 2 + cfg.belt.mass_per_length * system.layout.span_length.sum()
    return np.sqrt(k * (1 / pa.radius - 1 / pc.radius) ** 2 / m) / (2 * np.pi)


@pytest.mark.parametrize("k,rel", [(0.05, 1e-4), (0.5, 1e-3), (5.0, 1e-2)])
def test_torsion_spring_modal_matches_rigid_belt_closed_form(k, rel):
    # Without the spring the belt turning with the pulleys is the one rigid-body mode; the spring turns
    # it into an elastic mode at the rigid-belt frequency (closed form above). The flexible belt lowers
    # it in proportion to k (measured -3.3e-5, -3.3e-4, -3.3e-3 for k = 0.05, 0.5, 5 N m/rad: the
    # spans' transverse and axial flexibility, vanishing in the rigid limit), hence the tolerances.
    cfg, system = bench()
    s = system.with_components(rotational_spring(system, k, pulleys=("A", "C")))
    st = solve_static(s, cfg.static)
    modes = solve_modes(s, st.q, n_modes=4)
    assert modes.n_rigid == 0
    assert modes.frequency[0] == pytest.approx(rigid_belt_frequency(cfg, system, k), rel=rel)
    assert modes.kind[0] == "rotational"
    # the other modes barely move: the paper's 1st transverse mode stays within 1e-4
    base = solve_modes(system, solve_static(system, cfg.static).q, n_modes=3)
    assert modes.frequency[1] == pytest.approx(base.frequency[0], rel=1e-4)


def test_torsion_spring_transient_oscillates_at_closed_form():
    # Started from the equilibrium with the belt-turning velocity s' = 1e-3 m/s, the spring (0.5 N m/rad)
    # between A and C makes the drive oscillate at the rigid-belt frequency (0.889 Hz): zero crossings
    # of theta_A - theta_C over 4 periods give it within 1e-3 (the modal test's flexibility share is
    # 3.3e-4; rho_inf = 1, dt = 2e-4 s: the trapezoidal period error (w h)^2 / 12 ~ 1e-7).
    raw = config_to_dict(load_config(BENCH))
    raw["transient"] = {"duration": 4.6, "step": 2e-4, "output_interval": 2e-3, "rho_inf": 1.0,
                        "spectrum": {"enabled": False}, "record": {"hub_load": False}}
    cfg = config_from_dict(raw, file=str(BENCH))
    system = build_system(cfg)
    k = 0.5
    s = system.with_components(rotational_spring(system, k, pulleys=("A", "C")))
    st = solve_static(s, cfg.static)
    from beltdyn.analysis.transient import belt_travel

    setup = dataclasses.replace(prepare(s, st, cfg.transient), v0=1e-3 * belt_travel(s))
    got = []
    summary = run_transient(s, st, cfg.transient, setup=setup, sink=lambda t, b: got.append((t, b["pulley_angle"])))
    t = np.concatenate([g[0] for g in got])
    ang = np.concatenate([g[1] for g in got])
    x = ang[:, 0] - ang[:, 1]
    x = x - x.mean()
    i = np.nonzero(np.sign(x[:-1]) * np.sign(x[1:]) < 0)[0]
    tz = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    f = (len(tz) - 1) / 2 / (tz[-1] - tz[0])
    assert f == pytest.approx(rigid_belt_frequency(cfg, system, k), rel=1e-3)
    assert summary.energy_error < 1e-4  # no damping, rho_inf = 1: the balance closes


@pytest.mark.parametrize("stiffness", [1e6, 2.4253e11, 1e13])
def test_convergence_does_not_depend_on_bearing_preload(stiffness):
    # Issue 15: a 20 Hz, 0.01 rad rotation of C with the slide bearing of A from 1e6 to 1e13 N/m. The
    # convergence test was scaled by the largest force, which held the bearing's preload (k times the
    # 1.1 mm tension move: 2.7e8 N at 2.4e11 N/m), so Newton stopped far too early (tensions 133-267 N
    # instead of 188-212 N). Now each DOF group is measured against the forces that change: the span
    # tensions equal a run at 10x tighter tolerance within 1e-6 of their range, for every stiffness.
    def tensions(tol):
        cfg = load_config(ROOT / "configs/examples/bench_transient_small.toml",
                          [f"pulleys[0].bearing_stiffness={stiffness!r}", "transient.duration=0.1",
                           "transient.rotation[0].amplitude=0.01", "transient.rotation[0].frequency=20.0",
                           "transient.rotation[0].fluctuation_ramp=0.02", "transient.spectrum.enabled=false",
                           f"transient.tolerance={tol!r}"])
        system = build_system(cfg)
        st = solve_static(system, cfg.static)
        got = []
        summary = run_transient(system, st, cfg.transient, sink=lambda t, b: got.append(b["span_tension"]))
        assert summary.status == "complete"
        return np.concatenate(got)

    a, b = tensions(1e-8), tensions(1e-9)
    assert np.abs(a - b).max() <= 1e-6 * np.ptp(b)


def test_inaccurate_transient_is_flagged_not_silently_complete(tmp_path):
    # Issue 14/15: `--step 0.01` on the small example resolves nothing of its 45 Hz excitation (issue
    # 26: refused before the run). A well-resolved run has no warnings (an empty array of strings).
    import subprocess
    import sys

    import h5py

    exe = Path(sys.executable).parent / "beltdyn"
    cfg = ROOT / "configs/examples/bench_transient_small.toml"
    bad = subprocess.run([str(exe), "transient", str(cfg), "-o", str(tmp_path / "bad.h5"), "--step", "0.01",
                          "--duration", "0.6", "--set", "transient.spectrum.start=0.3"],
                         capture_output=True, text=True, timeout=300)
    # issue 26: such a step is now refused before the run (exit 2, naming --step; its band at a 10 %
    # frequency error, 19 Hz, lies below the lowest mode, 30.5 Hz); tests/test_trustworthy_transient.py
    assert bad.returncode == 2, bad.stderr
    assert "--step" in bad.stderr and "resolves no mode" in bad.stderr
    good = subprocess.run([str(exe), "transient", str(cfg), "-o", str(tmp_path / "good.h5"), "--duration", "0.6",
                           "--set", "transient.spectrum.start=0.3"], capture_output=True, text=True, timeout=300)
    assert good.returncode == 0, good.stderr
    with h5py.File(tmp_path / "good.h5") as f:
        assert len(f["transient"].attrs["warnings"]) == 0
        assert f["transient"].attrs["energy_balance_error"] < 0.01


@pytest.mark.parametrize("curvature", ["linear", "exact"])
def test_transient_with_either_curvature_conserves_energy(curvature):
    # The compiled kernel has every curvature model: the bench under the small rotation of C, no
    # damping, rho_inf = 1, dt = 2.5e-5 s: the energy balance at the steps closes within 1e-3 of the
    # energy moved, and at EI = 0.02 N m^2 the bending model changes the bearing force by < 1e-3 of
    # its range (the exact and linear curvatures differ by O(strain) in the bending energy).
    def history(curv):
        cfg = load_config(ROOT / "configs/examples/bench_transient_small.toml",
                          [f"model.curvature={curv}", "transient.duration=0.05", "transient.step=2.5e-5",
                           "transient.rho_inf=1.0", "transient.spectrum.enabled=false", "transient.damping={}"])
        system = build_system(cfg)
        st = solve_static(system, cfg.static)
        got = []
        s = run_transient(system, st, cfg.transient, sink=lambda t, b: got.append(b["bearing_force"][:, 0, 0]))
        return s, np.concatenate(got)

    s, h = history(curvature)
    assert s.status == "complete" and s.energy_error < 1e-3
    _, ref = history("linear")
    assert np.abs(h - ref).max() <= 1e-3 * np.ptp(ref)


@pytest.mark.parametrize("curvature", ["none", "linear", "exact"])
def test_numpy_and_compiled_belt_forces_agree_through_the_system(curvature):
    # Static and modal evaluate the belt with the numpy reference (`ancf`), the stepper with the
    # compiled kernel (`belt_kernel`): through the whole joint map (reduced force, tangent, joint
    # reactions) they agree to 1e-12 relative on a random state about the static equilibrium.
    cfg, system = bench([f"model.curvature='{curvature}'", "mesh.elements_per_span=6"])
    q = solve_static(system, cfg.static).q
    rng = np.random.default_rng(7)
    q = q + 1e-3 * rng.standard_normal(q.shape)
    fast = system.with_belt(compiled=True)
    f_np, K_np = system.force_and_tangent(q)
    f_c, K_c = fast.force_and_tangent(q)
    K_np, K_c = (np.asarray(K.todense()) if hasattr(K, "todense") else K for K in (K_np, K_c))
    assert np.abs(f_c - f_np).max() <= 1e-12 * np.abs(f_np).max()
    assert np.abs(K_c - K_np).max() <= 1e-12 * np.abs(K_np).max()
    hub_np, span_np = system.joint_reactions(q)
    hub_c, span_c = fast.joint_reactions(q)
    assert np.abs(hub_c - hub_np).max() <= 1e-12 * np.abs(hub_np).max()
    assert np.abs(span_c - span_np).max() <= 1e-12 * np.abs(span_np).max()


def test_static_and_modal_do_not_load_numba():
    # Start-up: `beltdyn modal` must not pay numba's ~0.3 s import and cache load (bench/run.py times it).
    import subprocess
    import sys

    code = ("import sys; from beltdyn.config import load_config; from beltdyn.pipeline import analyse; "
            f"analyse(load_config({str(BENCH)!r}), modal=True); print('numba' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_a_new_support_is_one_class(monkeypatch):
    # The supports are classes (beltdyn.model.supports): a support written here, a slide along a fixed
    # direction with its own spring, registered in place of "bearing", builds through the unchanged
    # system, statics and modes, and reproduces the built-in slide with that direction: frequencies
    # within 1e-12.
    from beltdyn.model import supports
    from beltdyn.pipeline import analyse

    d = np.array([math.cos(0.3), math.sin(0.3)])
    dx, dy = float(d[0]), float(d[1])

    class TiltedSlide(supports.Support):
        kind = "bearing"

        def independent(self):
            return (("tilted", "m", "translation"),)

        def directions(self):
            return d[None, :]

        def springs(self):
            return (3.0e6,)

    three = ROOT / "configs" / "examples" / "three_pulley_backside_idler.toml"
    ref = analyse(load_config(three, ["pulleys[2].support='slide'", f"pulleys[2].slide_direction=[{dx!r}, {dy!r}]",
                                      "pulleys[2].bearing_stiffness=3.0e6"]), modal=True)
    monkeypatch.setitem(supports.SUPPORT_CLASSES, "bearing", TiltedSlide)
    got = analyse(load_config(three, ["pulleys[2].bearing_stiffness=[3.0e6, 3.0e6]"]), modal=True)
    assert "pulley C tilted" in got.system.dof_labels
    assert np.allclose(got.modal.frequency, ref.modal.frequency, rtol=1e-12)


def test_energy_shares_with_and_without_the_precomputed_motion():
    # solve_modes hands the shapes' element motion to the classification; computed inside it is the
    # same (to the bit).
    from beltdyn.analysis.modal import classify
    from beltdyn.pipeline import analyse

    run = analyse(load_config(BENCH), modal=True)
    md = run.modal
    got = classify(run.system, md.shapes, md.frequency, run.static.q)
    assert got[0] == md.kind and np.array_equal(got[4], md.energy_share)


def _pulley(name: str, angle: float, **more) -> dict:
    """A pulley of radius 0.25 m on the unit circle at `angle` (deg)."""
    c = [math.cos(math.radians(angle)), math.sin(math.radians(angle))]
    return {"name": name, "center": c, "radius": 0.25, "mass": 1.0, "inertia": 2e-3, **more}


TWO_ARMS = {  # six pulleys around a circle: two arms, a bearing, a slide, two spring spans
    "belt": {"EA": 1.0e5, "EI": 0.0, "mass_per_length": 0.1, "length": 7.3},
    "pulleys": [_pulley("P0", 0, driver=True),
                _pulley("P1", 60, support="bearing", bearing_stiffness=[1.0e5, 2.0e5]),
                _pulley("P2", 120, support="arm", arm_pivot=[-0.067, 1.116], arm_stiffness=50.0, arm_inertia=1e-3),
                _pulley("P3", 180),
                _pulley("P4", 240, support="slide", slide_direction=[0.6, 0.8], bearing_stiffness=3.0e4),
                _pulley("P5", 300, support="arm", arm_pivot=[0.067, -1.116], arm_stiffness=80.0, arm_damping=0.1)],
    "mesh": {"elements_per_span": 2},
    "spans": {"P1-P2": {"model": "spring"}, "P4-P5": {"model": "spring"}},
    "tension": {"target": 50.0, "mode": "prestrain"},
}


def _fields_equal(a, b, path: str = "system") -> None:
    """Every dataclass field of a and b equal, to the bit (arrays, components, nested dataclasses)."""
    assert type(a) is type(b), path
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _fields_equal(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
    elif isinstance(a, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=path)
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _fields_equal(x, y, f"{path}[{i}]")
    elif hasattr(a, "__dict__") and not callable(a):
        _fields_equal(vars(a), vars(b), path)
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _fields_equal(a[k], b[k], f"{path}[{k}]")
    else:
        assert a == b or (a != a and b != b), path


@pytest.mark.parametrize("dense", [True, False])
def test_a_build_from_the_analysis_facts_is_the_build_from_the_configuration(dense):
    # pipeline.analyse computes the configuration's DriveFacts once, on the L0 fit, and builds every
    # re-laid system from them: a build on another layout (pulleys moved, two arms turned, a bearing and a
    # slide displaced, springs anchored elsewhere) from the facts is the build from the configuration
    # alone, field by field to the bit (DOF map, components, arms, belt and spring spans, matrices).
    from beltdyn.model.geometry import layout_from_config, relay
    from beltdyn.model.system import drive_facts

    cfg = config_from_dict(TWO_ARMS)
    fit = layout_from_config(cfg)
    facts = drive_facts(cfg, fit)
    centers = fit.center + np.array([[0, 0], [1e-3, -2e-3], [2e-3, 1e-3], [0, 0], [3e-3, 4e-3], [-1e-3, 2e-3]])
    moved = relay(fit, centers)
    free = np.linspace(-1e-3, 1e-3, facts.dofs.n)
    stretch = np.linspace(1.001, 1.002, fit.n)
    kw = dict(prestrain_stretch=stretch, spring_free=free, dense=dense)
    for lay in (fit, moved):
        _fields_equal(build_system(cfg, lay, facts=facts, **kw), build_system(cfg, lay, **kw))


@pytest.mark.parametrize("dense", [True, False])
def test_the_objects_of_a_build_hold_every_field(dense):
    # drive_facts and build_system make their frozen dataclasses through their constructors: each holds every
    # field of its class, on the two-arm drive and on the all-spring example drive (tests/test_assembly.py holds
    # them to exactly their fields after use).
    from beltdyn.model.geometry import layout_from_config
    from beltdyn.model.system import drive_facts

    fead = ROOT / "configs" / "examples" / "fead_4cyl.toml"
    springs = load_config(fead, [f'spans.{n}.model="spring"' for n in load_config(fead).span_names])
    for cfg in (config_from_dict(TWO_ARMS), springs):
        lay = layout_from_config(cfg)
        facts = drive_facts(cfg, lay)
        system = build_system(cfg, lay, facts=facts, dense=dense)
        made = [facts, facts.tension, facts.arms, system, system.belt, system.springs, system.arms, system.pattern,
                *system.components]
        for obj in made:
            assert {k for k in vars(obj) if not k.startswith("_")} == {f.name for f in dataclasses.fields(obj)}, obj


def test_the_dense_assembly_of_the_components_is_the_sparse_one():
    # assemble_system sums the components on the pattern (`assembly.component_sums`), dense (n, n) or the CSR
    # data of a sparse one: the same mass, stiffness, damping, weight and spring
    # offsets on the two-arm drive under gravity (arms with springs relaxed off the layout, a bearing, a slide,
    # spring and ANCF spans). Compared to 1e-14 of each matrix's largest entry: the two paths add an entry's element,
    # spring-span and component parts in different orders.
    from scipy.sparse import csr_matrix

    from beltdyn.model.geometry import layout_from_config
    from beltdyn.model.dofs import number_dofs

    cfg = config_from_dict({**TWO_ARMS, "model": {"gravity": [0.0, -9.81]}})
    lay = layout_from_config(cfg)
    n = number_dofs(cfg).n
    kw = dict(prestrain_stretch=np.linspace(1.001, 1.002, lay.n), spring_free=np.linspace(-1e-3, 1e-3, n))
    dense, sparse = build_system(cfg, lay, dense=True, **kw), build_system(cfg, lay, dense=False, **kw)
    assert dense.dense and not sparse.dense
    assert sum(len(c.dofs) == 1 and c.free is not None for c in dense.components) == 2  # the two sprung arms
    stiffness = csr_matrix((sparse.linear_stiffness, sparse.pattern.indices, sparse.pattern.indptr),
                           shape=(n, n)).toarray()
    pairs = [(dense.mass, sparse.mass.toarray()), (dense.linear_stiffness, stiffness),
             (dense.linear_damping, sparse.linear_damping.toarray()), (dense.gravity_force, sparse.gravity_force),
             (dense.linear_offset, sparse.linear_offset)]
    for a, b in pairs:
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-14 * np.abs(b).max())
        assert np.abs(b).max() > 0
