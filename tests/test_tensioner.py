"""The tensioner arm (support = "arm"): exact arm kinematics on the joint coordinates, its tangent
against finite differences, the L0 fit by turning the arm, statics (moment balance about the pivot,
spring mode, adjust mode), modes (tensioner kind, long-arm and stiff-spring limits), transients
(friction hysteresis) and bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.errors import ConfigError
from beltdyn.model.system import build_system
from histories import arm_under_hub_force  # tests/histories.py

ROOT = Path(__file__).resolve().parents[1]
ARM = ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"


def arm_system(overrides=(), **kw):
    cfg = load_config(ARM, list(overrides))
    return cfg, build_system(cfg, **kw)


@pytest.mark.parametrize("dense", [True, False])
def test_arm_tangent_matches_finite_differences(dense):
    # dr/dq of the static residual r = J^T (f(P(q)) - F) (belt through the moving arm joint, arm spring,
    # pulley weight on the arm) against central differences (h = 1e-7), at a random state; within 1e-6
    # of the largest entry. The arm column carries the geometric term F . c''(phi).
    cfg, system = arm_system(["model.gravity=[0.0, -9.81]", "mesh.elements_per_span=4",
                              "pulleys[2].arm_free_angle=2.5"], dense=dense)
    rng = np.random.default_rng(3)
    q = 1e-3 * rng.standard_normal(system.n_dof)
    r, K = system.equilibrium(q)
    K = K.toarray() if hasattr(K, "toarray") else K
    h = 1e-7
    fd = np.empty_like(K)
    for i in range(system.n_dof):
        dq = np.zeros(system.n_dof)
        dq[i] = h
        fd[:, i] = (system.equilibrium(q + dq)[0] - system.equilibrium(q - dq)[0]) / (2 * h)
    assert np.abs(fd - K).max() <= 1e-6 * np.abs(K).max()
    a = int(system.arms.dof[0])
    assert abs(fd[a, a] - K[a, a]) <= 1e-6 * abs(K[a, a])


def test_arm_kinematics_are_exact():
    # The dependent centre offsets are c(phi) - c(phi_ref) for any angle (not linearized), J their
    # derivative (central differences, 1e-8), and J^T the projection of a force: f . (J dq) = (J^T f) . dq.
    cfg, system = arm_system(["mesh.elements_per_span=2"])
    arms = system.arms
    q = np.zeros(system.n_dof)
    q[arms.dof[0]] = 0.7  # a large turn
    p = system.expand(q)
    phi = arms.angle[0] + 0.7
    c = arms.pivot[0] + arms.length[0] * np.array([np.cos(phi), np.sin(phi)])
    c_ref = system.layout.center[2]
    assert np.allclose(p[arms.slot[0]: arms.slot[0] + 2], c - c_ref, rtol=0, atol=1e-15)
    assert np.allclose(system.pulley_centers(q)[2], c, rtol=0, atol=1e-15)
    dq = np.random.default_rng(1).standard_normal(system.n_dof)
    h = 1e-8
    fd = (system.expand(q + h * dq) - system.expand(q - h * dq)) / (2 * h)
    assert np.allclose(system.expand_motion(q, dq), fd, rtol=0, atol=1e-7)
    f = np.random.default_rng(2).standard_normal(system.n_p)
    assert np.isclose(f @ system.expand_motion(q, dq), system.arms.project(q, f) @ dq, rtol=1e-13)
    # The dense jacobian from q on floats (modal's) is the one from the arrays' slopes: the same formula,
    # math's sin/cos for numpy's (equal to the last bit here; 1 ulp allowed elsewhere), and J dq = expand_motion.
    J = system.arm_jacobian(q)
    assert np.allclose(J, system.arm_jacobian(slopes=system.arm_slopes(q)), rtol=2.3e-16, atol=0)
    assert np.allclose(J @ dq, system.expand_motion(q, dq), rtol=1e-15, atol=1e-15)


def test_arm_mass_is_arm_inertia_plus_m_l_squared():
    # The arm angle's mass: the arm's own inertia plus the pulley's m l^2, through J^T M J (not by hand),
    # plus the belt end nodes' share c'^T M_belt c' on the pulley's centre offsets; to 1e-13.
    cfg, system = arm_system(["mesh.elements_per_span=2"])
    p = cfg.pulleys[2]
    q = np.zeros(system.n_dof)
    M = system.mass_matrix(q)
    M = M.toarray() if hasattr(M, "toarray") else M
    a, s = int(system.arms.dof[0]), int(system.arms.slot[0])
    l = float(system.arms.length[0])
    Mb = system.assemble(system.belt.reduce_blocks(system.belt.elements.mass), linear=False)
    Mb = Mb.toarray() if hasattr(Mb, "toarray") else Mb
    dc = system.arms.first(system.arms.phi(q))[0]
    expect = p.arm_inertia + p.mass * l * l + dc @ Mb[s:s + 2, s:s + 2] @ dc
    assert np.isclose(M[a, a], expect, rtol=1e-13)
    assert np.isclose(l, np.hypot(*(np.array(p.center) - np.array(p.arm_pivot))), rtol=1e-12)


def test_l0_fit_turns_the_arm():
    # The geometry fits L0 by turning the arm about its pivot: belt length L0 to 1e-12, arm length kept.
    from beltdyn.model.geometry import layout_from_config

    cfg = load_config(ARM)
    lay = layout_from_config(cfg)
    p = cfg.pulleys[2]
    assert abs(lay.belt_length - cfg.belt.length) < 1e-12 * cfg.belt.length
    assert np.isclose(np.hypot(*(lay.center[2] - np.array(p.arm_pivot))), p.arm_length, rtol=1e-12)
    assert lay.adjust_kind == "arm" and lay.adjust_offset != 0.0


@pytest.mark.parametrize("sets,key", [
    (["pulleys[2].arm_pivot=[0.56, -0.07]"], "pulleys[2].arm_pivot"),  # the pivot at the centre: inside
    (["pulleys[2].arm_range=[0.0, 0.5]"], "pulleys[2].arm_range"),  # stops exclude the fitted angle
    (["pulleys[1].arm_stiffness=10.0"], "pulleys[1].arm_stiffness"),  # arm key on a fixed pulley
    (["tension.mode='spring'"], "tension.target"),  # the spring sets the tension: no target
    (["static.torque=[{pulley='A', value=5.0}]"], "static.torque[0].pulley"),  # the driver reacts torques
])
def test_bad_arm_input_names_the_key(sets, key):
    from beltdyn.model.geometry import layout_from_config

    with pytest.raises(ConfigError) as err:
        layout_from_config(load_config(ARM, sets))  # the stops are checked against the fitted angle
    assert err.value.key == key


def test_arm_without_pivot_names_the_key(tmp_path):
    text = ARM.read_text().replace('arm_pivot = [0.64, -0.07]', '')
    cfg = tmp_path / "c.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_config(cfg)
    assert err.value.key == "pulleys[2].arm_pivot"


# ------------------------------------------------------------------------------------ statics
def _analyse(overrides=(), modal=False):
    from beltdyn.pipeline import analyse

    return analyse(load_config(ARM, list(overrides)), modal=modal)


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


@pytest.mark.parametrize("overrides", [
    [],
    ["model.gravity=[0.0, -9.81]"],
    ["static.torque=[{pulley='C', value=-10.0}]", "model.gravity=[0.0, -9.81]"],
])
def test_static_balance_of_the_arm(overrides):
    # Statics of the arm + pulley, each to 1e-9 of its scale: the spring torque balances the moment of
    # the belt forces and of the pulley's weight about the pivot; the pivot reaction balances the hub
    # load and the weight; without weight (straight spans) the hub load is the sum of the two span-end
    # tension vectors along the spans (the spans meet the pulleys on their tangents);
    # the free pulley T and the loaded pulley C carry (T_in - T_out) R = applied torque; the driver
    # reacts them: tau_A / R_A + sum_j tau_j / R_j = 0 (the belt's force balance, all pulleys inside).
    run = _analyse(overrides)
    st, lay, cfg = run.static, run.layout, run.config
    j = 2
    p = cfg.pulleys[j]
    g = np.array(cfg.model.gravity)
    r = st.pulley_center[j] - np.array(p.arm_pivot)
    moment = _cross(r, st.hub_load[j] + p.mass * g)
    scale = float(np.abs(st.hub_load[j]).max()) * np.hypot(*r)
    assert abs(st.arm_torque[j] + moment) <= 1e-9 * scale
    assert np.allclose(st.pivot_reaction[j], -(st.hub_load[j] + p.mass * g), rtol=0, atol=1e-9 * scale)
    t = lay.span_direction
    for k in range(lay.n if not g.any() else 0):  # span k-1 arrives along t[k-1], span k leaves along t[k]
        pull = st.span_tension[k, 0] * t[k] - st.span_tension[k - 1, 1] * t[k - 1]
        assert np.allclose(st.hub_load[k], pull, rtol=0, atol=1e-7 * np.abs(st.span_tension).max())
    applied = st.applied_torque
    for k in ((1, 2) if not g.any() else ()):  # tension magnitudes: exact for straight spans
        transmitted = (st.span_tension[k - 1, 1] - st.span_tension[k, 0]) * lay.radius[k]
        assert abs(transmitted + applied[k]) <= 1e-7 * np.abs(st.span_tension).max() * lay.radius[k]
    balance = st.driver_torque / lay.radius[0] + sum(applied[k] / lay.radius[k] for k in (1, 2))
    if not g.any():  # (with weight the sagging spans hold a small torque of their own on the driver)
        assert abs(balance) <= 1e-7 * np.abs(st.span_tension).max()


def test_spring_mode_reproduces_adjust_mode_with_its_free_angle():
    # Mode "adjust" turns the arm until 200 N and reports the spring's free angle; mode "spring" with that
    # free angle must land on the same equilibrium: mean tension 200 N within 1e-6, arm angle within 1e-8.
    adj = _analyse().static
    free = float(adj.arm_free_angle[2])
    spr = _analyse([f"pulleys[2].arm_free_angle={free!r}", "tension={mode='spring'}"]).static
    assert abs(spr.mean_tension - 200.0) <= 1e-6 * 200.0
    assert abs(spr.arm_angle[2] - adj.arm_angle[2]) <= 1e-8


def test_a_torque_that_needs_the_arm_past_its_stop_is_a_named_failure():
    from beltdyn.errors import SolverError

    with pytest.raises(SolverError) as err:
        _analyse(["tension.target=2000.0"])
    assert "stops" in str(err.value) and "pulley 'T'" in str(err.value)
    assert "arm" in err.value.item


# ------------------------------------------------------------------------------------ limits
def _modes_by_kind(md, n):
    return np.array(md.frequency[:n])


def test_a_long_arm_reproduces_the_slide():
    # The paper bench's pulley A on an arm of 100 m perpendicular to its slide (pivot straight below),
    # spring k L^2 for the slide's k (2425300 N/m), no arm inertia: the arm pulley moves along x to
    # first order (its y moves by x^2 / 2L ~ 1e-8 m). Statics and the 14 lowest modes agree with the
    # slide bench within 0.1 % (measured: see the assertion margins).
    from beltdyn.config import config_from_dict, config_to_dict
    from beltdyn.pipeline import analyse

    bench = load_config(ROOT / "configs" / "paper" / "bench_T200.toml")
    raw = config_to_dict(bench)
    L = 100.0
    a = raw["pulleys"][0]
    for key in ("slide_direction", "slide_range"):
        a.pop(key, None)
    k = a.pop("bearing_stiffness")
    a.update(support="arm", arm_pivot=[a["center"][0], a["center"][1] - L], arm_stiffness=k * L * L)
    arm = config_from_dict(raw, file="long-arm")
    ref, got = analyse(bench, modal=True), analyse(arm, modal=True)
    assert np.allclose(got.static.span_tension, ref.static.span_tension, rtol=1e-3)
    assert np.allclose(got.static.hub_load, ref.static.hub_load, rtol=1e-3, atol=1e-3 * 400)
    assert np.allclose(got.static.pulley_center, ref.static.pulley_center, rtol=0, atol=1e-6)
    f_ref, f_got = ref.modal.frequency[:14], got.modal.frequency[:14]
    assert np.allclose(f_got, f_ref, rtol=1e-3)
    assert [got.modal.kind[i] for i in range(14)] == [
        "tensioner" if kd == "translational" else kd for kd in ref.modal.kind[:14]]


def test_a_stiff_arm_spring_reproduces_a_fixed_centre():
    # The tensioner with arm_stiffness 1e9 N m/rad, turned to 200 N, against the same drive whose pulley T
    # is set by the same tension step but then cannot move: on a slide from its L0-fit centre through its
    # solved centre (the chord of the arm's arc), bearing 1e13 N/m. Statics and the 12 lowest modes
    # within 0.1 % (measured 3e-8). (A prestrained drive at the same centres differs by
    # up to 0.35 % in both cases: the tension step leaves the span ends displaced along the spans by
    # R theta, DESIGN section 2.)
    from beltdyn.config import config_from_dict, config_to_dict
    from beltdyn.pipeline import analyse

    stiff = load_config(ARM, ["pulleys[2].arm_stiffness=1e9", "pulleys[2].arm_damping=0.0"])
    got = analyse(stiff, modal=True)
    raw = config_to_dict(stiff)
    t = raw["pulleys"][2]
    for key in ("arm_pivot", "arm_inertia", "arm_stiffness", "arm_damping", "arm_range"):
        t.pop(key, None)
    c0, c = got.fit_layout.center[2], got.static.pulley_center[2]
    t.update(support="slide", center=[float(x) for x in c0], slide_direction=[float(x) for x in c - c0],
             bearing_stiffness=1e13)
    ref = analyse(config_from_dict(raw, file="fixed"), modal=True)
    assert np.allclose(got.static.span_tension, ref.static.span_tension, rtol=1e-3)
    assert np.allclose(got.static.hub_load, ref.static.hub_load, rtol=0, atol=1e-3 * 400)
    assert np.allclose(got.modal.frequency[:12], ref.modal.frequency[:12], rtol=1e-3)


# ------------------------------------------------------------------------------------ transient
def test_dry_friction_gives_a_hysteresis_loop_of_width_twice_the_friction_torque():
    # A slow (1 Hz, far below the 29 Hz tensioner mode) hub force on the tensioner pulley swings the arm
    # back and forth against its spring, the belt and a dry friction torque T_f = 0.3 N m (no viscous
    # damping). Quasi-statically the applied moment about the pivot is M = g(phi) + T_f sign(phi'): the
    # loading and unloading branches are 2 T_f apart. A least-squares fit of M over the second cycle
    # (a cubic in phi plus a sign(phi') term, sliding samples) gives the half-width T_f within 2 %
    # (measured 0.12 %); the energy balance holds (the friction work is dissipated, less the bristle's stored energy).
    Tf = 0.3
    cfg = load_config(ARM, [
        f"pulleys[2].arm_friction={Tf}", "pulleys[2].arm_damping=0.0", "transient.rotation=[]",
        "transient.duration=2.0", "transient.step=2e-4", "transient.output_interval=1e-3",
        "transient.spectrum.enabled=false",
        "transient.hub_force=[{pulley='T', amplitude=[0.0, 30.0], frequency=1.0, ramp_time=0.25}]"])
    t, ph, MM = arm_under_hub_force(cfg)
    w = np.gradient(ph, t)
    slide = np.abs(w) > 0.2 * np.abs(w).max()
    x = ph[slide] - ph.mean()
    A = np.column_stack([np.ones(x.size), x, x**2, x**3, np.sign(w[slide])])
    coef = np.linalg.lstsq(A, MM[slide], rcond=None)[0]
    assert abs(coef[-1] / Tf - 1.0) < 0.02
    assert ph.max() - ph.min() > 0.02  # the arm really swings (about 2 deg)


def test_a_load_that_slackens_a_span_is_a_named_failure():
    # 45 N m on C with the mean tension held at 200 N puts the slack side in compression (-18 N): a
    # SolverError naming the span, not a result with a compressed belt.
    from beltdyn.errors import SolverError

    with pytest.raises(SolverError) as err:
        _analyse(["static.torque=[{pulley='C', value=-45.0}]"])
    assert err.value.item in ("span 2 (C-T)", "span 3 (T-A)") and "slack" in str(err.value)  # both -18 N


def test_sweep_over_an_accessory_torque_gives_the_working_curve(tmp_path):
    # beltdyn sweep over static.torque[0].value in spring mode: /sweep holds the arm angle and spring
    # torque per case; the slack side loses tension and the arm turns monotonically as the load grows,
    # and each case equals a single static run of that load (1e-9).
    import subprocess
    import sys

    import h5py

    exe = [str(Path(sys.executable).parent / "beltdyn")]
    sets = ["static.torque=[{pulley='C', value=0.0}]", "pulleys[2].arm_free_angle=3.19", "tension={mode='spring'}",
            "mesh.elements_per_span=6"]
    r = subprocess.run([*exe, "sweep", str(ARM), "--param", "static.torque[0].value=0:-30:4", "--analysis", "static",
                        *[x for s in sets for x in ("--set", s)], "-o", str(tmp_path / "s.h5"), "--workers", "1"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "s.h5") as f:
        angle = f["sweep/arm_angle"][:, 2]
        torque = f["sweep/arm_torque"][:, 2]
        slack = f["sweep/span_tension"][:, 1, 0]
    assert np.all(np.diff(angle) > 0) and np.all(np.diff(slack) < 0) and np.all(np.diff(torque) < 0)
    one = _analyse(sets[1:] + ["static.torque=[{pulley='C', value=-20.0}]"]).static
    assert abs(one.arm_angle[2] - angle[2]) < 1e-9 and abs(one.arm_torque[2] - torque[2]) < 1e-9 * abs(torque[2])


# ------------------------------------------------------------------------------------ modes
def _reference_drive_config(tmp_path, *, rho=1e-6, n_el=8, neighbours_locked=False):
    """The reference drive of tests/reference_tensioner.py (A, T on its arm, C; spans prestrained to
    200 N at the given centres, the arm spring's free angle from the reference statics) as a config."""
    import reference_tensioner as rt

    pulleys, arm, EA, T0 = rt.example_drive()
    geo = rt.loop_geometry(pulleys)
    length = float(geo["L"].sum() + (np.array([p["radius"] for p in pulleys]) * geo["wrap"]).sum())
    if neighbours_locked:
        pulleys[0]["inertia"] = pulleys[2]["inertia"] = 1e2  # with J_T: the 1-DOF limit within 2e-4
        pulleys[1]["inertia"] = 1e-6
    free = float(rt.arm_free_angle(pulleys, arm, T0))
    arm = {**arm, "pivot": [float(x) for x in arm["pivot"]]}
    pulleys = [{**p, "center": [float(x) for x in p["center"]]} for p in pulleys]
    lines = [f"[belt]\nlength = {length!r}\nEA = {EA!r}\nEI = 1e-7\nmass_per_length = {rho!r}\n"]
    for k, p in enumerate(pulleys):
        lines.append(f"[[pulleys]]\nname = \"{p['name']}\"\ncenter = [{p['center'][0]!r}, {p['center'][1]!r}]\n"
                     f"radius = {p['radius']!r}\nmass = {p['mass']!r}\ninertia = {p['inertia']!r}\n"
                     + ("driver = true\n" if k == 0 else "")
                     + (f"support = \"arm\"\narm_pivot = [{arm['pivot'][0]!r}, {arm['pivot'][1]!r}]\n"
                        f"arm_inertia = {arm['inertia']!r}\narm_stiffness = {arm['stiffness']!r}\n"
                        f"arm_free_angle = {free!r}\n" if k == arm["index"] else ""))
    lines.append(f"[tension]\ntarget = {T0!r}\nmode = \"prestrain\"\n[mesh]\nelements_per_span = {n_el}\n"
                 f"[modal]\nmodes = 6\n")
    path = tmp_path / "ref.toml"
    path.write_text("\n".join(lines))
    return path, (pulleys, arm, EA, T0)


def test_modes_match_the_independent_rigid_belt_model(tmp_path):
    # tests/reference_tensioner.py: an independent derivation (massless tensioned spans as axial and
    # transverse springs, rigid pulleys, exact arm kinematics; checked against finite differences of a
    # separately written nonlinear energy, docs/tensioner_reference.md). beltdyn with a belt of
    # negligible mass (1e-6 kg/m) and bending (1e-7 N m^2): the tensioner mode (43.02 Hz) and the two
    # pulley modes within 1e-3, the arm at its reference angle within 1e-9 rad.
    import reference_tensioner as rt

    from beltdyn.pipeline import analyse

    path, (pulleys, arm, EA, T0) = _reference_drive_config(tmp_path)
    run = analyse(load_config(path), modal=True)
    ref = rt.linear_frequencies(pulleys, arm, EA, T0)
    phi0 = rt.arm_kinematics(pulleys, arm)["phi0"]
    assert abs(run.static.arm_angle[1] - phi0) < 1e-9
    got = run.modal.frequency[:3]
    assert np.allclose(got, ref, rtol=1e-3), (got, ref)
    assert run.modal.kind[0] == "tensioner"


def test_all_spring_fead_modes_match_the_rigid_belt_rotational_model():
    # Issue 25: the rotational model of the FEAD example (every span a spring) against the rigid-belt model of
    # tests/reference_tensioner.py, laid out there from /static's outputs alone (the solved centres, the
    # span tensions, the arm's pivot, inertia and spring; the spans' end masses rho L0 / 2 with L0 the solved
    # chord over the stretch of its tension), its own tangent geometry and per-span tensions (the
    # accessory torques split them): every mode within 1e-6, at the creep-wrap equilibrium (the default) and
    # with rigid wraps.
    import reference_tensioner as rt

    from beltdyn.pipeline import analyse

    base = load_config(ROOT / "configs/examples/fead_4cyl.toml")
    for wraps in ("creep", "rigid"):
        cfg = load_config(ROOT / "configs/examples/fead_4cyl.toml",
                          [f'spans.{n}.model="spring"' for n in base.span_names] + [f"belt.wraps={wraps}"])
        run = analyse(cfg, modal=True, n_modes=7)
        st = run.static
        pulleys = [dict(name=p.name, center=tuple(st.pulley_center[j]), radius=p.radius, mass=p.mass,
                        inertia=p.inertia, side=-1 if p.side == "backside" else 1) for j, p in enumerate(cfg.pulleys)]
        iT = [j for j, p in enumerate(cfg.pulleys) if p.support == "arm"][0]
        ten = cfg.pulleys[iT]
        arm = dict(index=iT, pivot=tuple(ten.arm_pivot), inertia=ten.arm_inertia, stiffness=ten.arm_stiffness)
        EA, rho = cfg.belt.EA, cfg.belt.mass_per_length
        T = st.span_tension.mean(axis=1)
        geo = rt.loop_geometry(pulleys)
        L0 = geo["L"] / np.array([rt.static_stretch(EA, t) for t in T])
        f_ref = rt.linear_modes(pulleys, arm, EA, T, end_mass=0.5 * rho * L0)[0]
        np.testing.assert_allclose(run.modal.frequency, f_ref, rtol=1e-6)


def test_tensioner_frequency_matches_the_one_dof_closed_form(tmp_path):
    # The same drive with A and C of large inertia (100 kg m^2) and T of negligible inertia (1e-6): the
    # tensioner mode is the
    # 1-DOF closed form omega^2 = K_eff / J_eff, K_eff = k_arm + l H.e_r (the arm's geometric term)
    # + T0 l^2 ((n_in.e_phi)^2/L_in + (n_out.e_phi)^2/L_out) (the spans turning)
    # + k_in k_out/(k_in + k_out) l^2 ((t_in - t_out).e_phi)^2 (the two spans in series),
    # J_eff = J_arm + m_T l^2 (docs/tensioner_reference.md). Within 1e-3.
    import reference_tensioner as rt

    from beltdyn.pipeline import analyse

    # (belt 1e-3 kg/m: the eigen-solver's zero tolerance, ~1e3 eps of the largest K/M, stays below the
    # 0.8 Hz rotation of A and C)
    path, (pulleys, arm, EA, T0) = _reference_drive_config(tmp_path, neighbours_locked=True, rho=1e-3)
    run = analyse(load_config(path), modal=True)
    one = rt.one_dof_terms(pulleys, arm, EA, T0, limit="neighbours_locked")
    k = [i for i, kind in enumerate(run.modal.kind) if kind == "tensioner"]
    assert k, run.modal.label
    assert abs(run.modal.frequency[k[0]] / one["f"] - 1.0) < 1e-3, (run.modal.frequency[k[0]], one["f"])


def test_every_group_has_warnings_and_static_names_a_slipping_pulley(tmp_path):
    # /geometry, /static, /modal carry a `warnings` attribute (empty when none); a pulley whose slip
    # margin is below 1 under the static load case is named in /static warnings.
    import subprocess
    import sys

    import h5py

    exe = [str(Path(sys.executable).parent / "beltdyn")]
    r = subprocess.run([*exe, "modal", str(ARM), "--set", "pulleys[0].friction=0.05", "--set",
                        "static.torque=[{pulley='C', value=-10.0}]", "-o", str(tmp_path / "w.h5")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "w.h5") as f:
        assert len(f["geometry"].attrs["warnings"]) == 0 and len(f["modal"].attrs["warnings"]) == 0
        w = [str(x) for x in f["static"].attrs["warnings"]]
        # (and, since issue 25, C: it transmits the torque without a friction value, so it never slips)
        assert len(w) == 2 and "pulley A slips" in w[0] and "pulley C transmits 10 N m but has no friction" in w[1]
        assert f["static/slip_margin"][0] < 1.0 and f["static/gross_slip"][0] == 1


# ------------------------------------------------------------------------------ review findings
def test_an_arm_spring_without_free_angle_stays_anchored_across_re_lays():
    # No arm_free_angle: the spring is relaxed at the arm's L0-fit angle on every re-laid system (it
    # used to be re-anchored at each pass and crept until the stops). Same result as giving that angle.
    from beltdyn.model.geometry import layout_from_config

    sets = ["pulleys[2].adjustable=false", "tension={target=200.0, mode='prestrain'}", "pulleys[2].arm_range=[2.0, 4.0]"]
    fit = layout_from_config(load_config(ARM, sets))
    p = load_config(ARM).pulleys[2]
    phi_fit = float(np.arctan2(*(fit.center[2] - np.array(p.arm_pivot))[::-1]))
    a = _analyse(sets).static
    b = _analyse(sets + [f"pulleys[2].arm_free_angle={phi_fit!r}"]).static
    assert abs(a.arm_angle[2] - b.arm_angle[2]) < 1e-9 and abs(a.arm_torque[2] - b.arm_torque[2]) < 1e-6
    assert abs(a.mean_tension - 200.0) < 1e-6


def test_a_transient_at_rest_starts_stress_free():
    # transient.start = "rest": the stress-free reference (the L0 fit), not the re-laid solved drive.
    from beltdyn.pipeline import analyse, transient

    cfg = load_config(ROOT / "configs" / "examples" / "bench_transient_small.toml",
                      ['transient.start="rest"', "transient.duration=0.002", "transient.spectrum.enabled=false"])
    got = []
    transient(analyse(cfg), sink=lambda t, b: got.append(b["span_tension"][0]))
    assert np.abs(got[0]).max() < 1e-6


def test_a_constant_torque_arm_reports_its_torque():
    # arm_stiffness = 0 in adjust mode: the tension step's preload is the arm's torque (moment balance
    # about the pivot), not 0.
    st = _analyse(["pulleys[2].arm_stiffness=0.0"]).static
    r = st.pulley_center[2] - np.array(load_config(ARM).pulleys[2].arm_pivot)
    assert abs(st.arm_torque[2] + _cross(r, st.hub_load[2])) < 1e-9 * abs(st.arm_torque[2])
    assert np.isnan(st.arm_free_angle[2])


def test_arm_length_is_kept_through_extrapolated_re_lays():
    # A stiff, far-wound spring on the FEAD tensioner: the re-lay's extrapolation keeps the pulley on its
    # circle about the pivot (the arm length stays 0.08 m to 1e-12).
    from beltdyn.pipeline import analyse

    cfg = load_config(ROOT / "configs" / "examples" / "fead_4cyl.toml",
                      ["pulleys[3].arm_stiffness=300.0", "pulleys[3].arm_free_angle=5.0", "pulleys[3].arm_range=[3.0, 5.5]"])
    run = analyse(cfg)
    l = float(np.hypot(*(run.static.pulley_center[3] - np.array(cfg.pulleys[3].arm_pivot))))
    assert abs(l - 0.08) < 1e-12
    assert abs(float(run.system.arms.length[0]) - 0.08) < 1e-12


def test_a_spring_wound_more_than_half_a_turn_with_stops():
    # With arm_range the angles are literal: a free angle 2 pi beyond the working one winds the spring a
    # full extra turn (more torque, the arm pressed harder), instead of being wrapped to the nearest turn.
    base = ["pulleys[2].arm_range=[2.0, 4.0]", "tension={mode='spring'}", "pulleys[2].arm_stiffness=0.5"]
    near = _analyse(base + ["pulleys[2].arm_free_angle=4.5"]).static
    wound = _analyse(base + [f"pulleys[2].arm_free_angle={4.5 + 2 * np.pi!r}"]).static
    assert wound.arm_torque[2] > near.arm_torque[2] + 2.0
    assert abs(wound.arm_free_angle[2] - (4.5 + 2 * np.pi)) < 1e-9


def test_a_transient_that_passes_the_arm_stops_is_marked(tmp_path):
    # The transient does not model the stops: an arm that swings beyond arm_range is named in /transient
    # warnings with the time (the static equilibrium at 3.11485 rad, with the default creep wraps, is
    # within [2.99, 3.1149]; 3.0885 rad with rigid wraps).
    import subprocess
    import sys

    import h5py

    exe = [str(Path(sys.executable).parent / "beltdyn")]
    r = subprocess.run([*exe, "transient", str(ARM), "--set", "pulleys[2].arm_range=[2.99, 3.1149]", "--set",
                        "transient.duration=0.2", "--set", "transient.spectrum.start=0.1", "-o", str(tmp_path / "s.h5")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "s.h5") as f:
        w = [str(x) for x in f["transient"].attrs["warnings"]]
    assert any("beyond its stops" in x and "pulley T" in x for x in w), w


@pytest.mark.parametrize("first", [0, 1, 4])
def test_the_prediction_splits_the_torques_about_the_driver_wherever_it_sits(first):
    # The all-spring FEAD with its pulley list started at another pulley (the same drive; the crank,
    # the driver, then sits after the tensioner arm's DOF, so its rotation DOF is not its pulley index):
    # the rigid-belt prediction splits the accessory torques about the driver, so it is the equilibrium
    # (no Newton iteration, one layout) in every order, and the span tensions are the same (1e-9 N).
    from beltdyn.config import config_from_dict, config_to_dict
    from beltdyn.pipeline import analyse

    fead = load_config(ROOT / "configs/examples/fead_4cyl.toml")
    cfg = load_config(ROOT / "configs/examples/fead_4cyl.toml", [f'spans.{n}.model="spring"' for n in fead.span_names])
    d = config_to_dict(cfg)
    d["pulleys"] = d["pulleys"][first:] + d["pulleys"][:first]
    run = analyse(config_from_dict(d), modal=False)
    ref = analyse(cfg, modal=False)
    assert run.static.iterations == 0 and run.static_passes == 1
    np.testing.assert_allclose(run.static.span_tension, np.roll(ref.static.span_tension, -first, axis=0), rtol=0,
                               atol=1e-9)
