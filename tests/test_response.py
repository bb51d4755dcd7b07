"""beltdyn response: the harmonic steady state of the linearized drive, checked against the nonlinear
static equilibrium (quasi-static limit) and the nonlinear transient's steady state."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from beltdyn.config import load_config
from beltdyn.pipeline import analyse
from beltdyn.pipeline import response_of
from beltdyn.analysis.static import solve_static

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
TENSIONER = ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"


def _write(tmp_path: Path, raw: dict, name: str = "drive.toml") -> Path:
    path = tmp_path / name
    path.write_bytes(tomli_w.dumps(raw).encode())
    return path


def _bench_with_response(tmp_path: Path, *, omega: float, order: float, B: float, alpha: float,
                         transport: bool = False) -> Path:
    """The paper bench with a speed fluctuation B sin(order x angle) of A at the mean speed omega, as
    [response] (one speed) and as [transient] (1.5 s, rho_inf 1, Rayleigh damping alpha M in both), both
    with the running belt's transport terms (transport) or both in the travelling frame."""
    raw = tomllib.loads(BENCH.read_text())
    raw["response"] = {"speed": [omega, omega * 1.0001], "points": 2, "orders": [order], "transport": transport,
                       "damping": {"rayleigh_mass": alpha},
                       "excitation": [{"pulley": "A", "kind": "speed", "amplitude": B}]}
    raw["transient"] = {"duration": 1.5, "step": 1e-4, "output_interval": 2e-4, "rho_inf": 1.0, "transport": transport,
                        "spectrum": {"enabled": False}, "damping": {"rayleigh_mass": alpha},
                        "rotation": [{"pulley": "A", "speed": omega, "speed_amplitude": B, "order": order,
                                      "fluctuation_ramp": 0.3}]}
    return _write(tmp_path, raw)


def _harmonic(t: np.ndarray, y: np.ndarray, w: float) -> np.ndarray:
    """Complex amplitude Y of y(t) ~ mean + Re(Y e^{i w t}) by least squares, (B, ...) -> (...)."""
    A = np.column_stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)])
    c = np.linalg.lstsq(A, y.reshape(len(t), -1), rcond=None)[0]
    return (c[1] - 1j * c[2]).reshape(y.shape[1:])


@pytest.mark.parametrize("transport", [False, True], ids=["travelling frame", "running belt"])
@pytest.mark.parametrize("omega, what", [(200.0, "away from resonance (31.8 Hz)"),
                                         (336.0, "at the 53.5 Hz resonance (at rest)")])
def test_response_equals_the_transient_steady_state(tmp_path, omega, what, transport):
    # Against the nonlinear transient at small amplitude (0.01 rad/s): the harmonic of the span tensions
    # and hub loads over the last ~0.5 s (integer periods), complex amplitudes within 1 % of the largest
    # (measured 1e-4 away from the resonance, 3e-3 at it: the step's frequency error of 1e-4 over the
    # 3 % damping). Rayleigh damping 20 M in both, so that the start has died out. With transport the
    # response is linearized about the running equilibrium at 7.5 / 12.6 m/s (gyroscopic and centripetal
    # terms, momentum flux in the hub loads) and the transient runs at that speed.
    from beltdyn.analysis.timestep import resolve_step
    from beltdyn.analysis.transient import run_transient

    cfg = load_config(_bench_with_response(tmp_path, omega=omega, order=1.0, B=0.01, alpha=20.0,
                                           transport=transport))
    run = analyse(cfg)
    res = response_of(cfg, run)
    got = []
    opts, _ = resolve_step(cfg.transient)
    run_transient(run.system, run.static, opts, sink=lambda t, d: got.append((t, d["span_tension"], d["hub_load"])))
    t = np.concatenate([g[0] for g in got])
    w = omega
    periods = int(0.5 / (2 * np.pi / w))
    sel = t > t[-1] - periods * 2 * np.pi / w + 1e-9
    for k, name in ((1, "span_tension"), (2, "hub_load")):
        y = np.concatenate([g[k] for g in got])[sel]
        Y_t = _harmonic(t[sel], y, w)
        Y_r = res.outputs[name][0, 0]
        assert np.abs(Y_t - Y_r).max() <= 1e-2 * np.abs(Y_r).max(), (what, name)


def test_quasi_static_response_equals_the_static_sensitivity(tmp_path):
    # At w -> 0 (1e-4 rad/s) and without damping the response to a torque tau on C is the derivative of
    # the nonlinear static equilibrium of the same system (same joints) with respect to tau: central
    # difference of two static solves at +-tau (independent of the linearization) within 1e-6
    # (measured 4e-8 on tensions, 3e-9 on the arm angle). Spring mode, so that the arm is free.
    raw = tomllib.loads(TENSIONER.read_text())
    free = float(np.nanmax(analyse(load_config(TENSIONER)).static.arm_free_angle))
    raw["tension"] = {"mode": "spring"}
    raw["pulleys"][2]["arm_free_angle"] = free
    tau = 0.05
    raw["response"] = {"speed": [1e-4, 2e-4], "points": 2, "orders": [1.0],
                       "excitation": [{"pulley": "C", "kind": "torque", "amplitude": tau}]}
    cfg = load_config(_write(tmp_path, raw))
    run = analyse(cfg)
    res = response_of(cfg, run)
    system = run.system

    def solved(torque: float):
        loads = np.zeros(system.n_p) if system.loads is None else system.loads.copy()
        loads[system.rot_dof[1]] += torque
        return solve_static(dataclasses.replace(system, loads=loads), cfg.static, q0=run.static.q)

    plus, minus = solved(tau), solved(-tau)
    pairs = {"span_tension": (plus.span_tension, minus.span_tension), "hub_load": (plus.hub_load, minus.hub_load),
             "pulley_angle": (plus.pulley_rotation, minus.pulley_rotation),
             "arm_angle": (plus.arm_angle[2:], minus.arm_angle[2:]),
             "driver_torque": (np.array(plus.driver_torque), np.array(minus.driver_torque))}
    for name, (a, b) in pairs.items():
        d = (a - b) / 2.0
        y = res.outputs[name][0, 0]
        assert np.abs(y.real - d).max() <= 1e-6 * np.abs(d).max(), name
        assert np.abs(y.imag).max() <= 1e-6 * np.abs(d).max(), name  # no damping: in phase


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "beltdyn.cli", *args], cwd=cwd, capture_output=True, text=True)


def test_cli_writes_the_response_group(tmp_path):
    # The command's /response equals the library's result; axes speed x order, amplitude and phase.
    from beltdyn.results.io import read_group

    path = _bench_with_response(tmp_path, omega=100.0, order=1.0, B=1.0, alpha=5.0)
    raw = tomllib.loads(path.read_text())
    raw["response"].update({"speed": [50.0, 400.0], "points": 8, "orders": [1.0, 2.0]})
    path = _write(tmp_path, raw)
    out = tmp_path / "r.h5"
    proc = _cli("response", str(path), "-o", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    g = read_group(out, "response")
    cfg = load_config(path)
    res = response_of(cfg, analyse(cfg))
    v = g["variables"]
    np.testing.assert_allclose(g["coords"]["speed"], np.linspace(50.0, 400.0, 8))
    np.testing.assert_allclose(v["frequency"], res.frequency)
    np.testing.assert_allclose(v["span_tension_amplitude"], np.abs(res.outputs["span_tension"]), rtol=1e-12)
    np.testing.assert_allclose(v["hub_load_phase"], np.angle(res.outputs["hub_load"]), atol=1e-12)
    assert g["dims"]["span_tension_amplitude"] == ("speed", "order", "span", "end")
    assert v["span_tension_amplitude"].shape == (8, 2, 2, 2)


@pytest.mark.parametrize("change, key", [
    ({"excitation": [{"pulley": "A", "kind": "torque", "amplitude": 1.0}]}, "response.excitation[0].pulley"),
    ({"excitation": [{"pulley": "Z", "kind": "speed", "amplitude": 1.0}]}, "response.excitation[0].pulley"),
    ({"excitation": [{"pulley": "C", "kind": "torque", "amplitude": 1.0, "order": 3.0}]},
     "response.excitation[0].order"),
    ({"orders": [2.0, 1.0]}, "response.orders[1]"),
    ({"speed": [0.0, 10.0]}, "response.speed"),
    ({"excitation": []}, "response.excitation"),
])
def test_bad_response_tables_exit_2_naming_the_key(tmp_path, change, key):
    path = _bench_with_response(tmp_path, omega=100.0, order=1.0, B=1.0, alpha=5.0)
    raw = tomllib.loads(path.read_text())
    raw["response"].update(change)
    proc = _cli("response", str(_write(tmp_path, raw)), "-o", str(tmp_path / "x.h5"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert key in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "x.h5").exists()


def test_response_without_its_table_exits_2(tmp_path):
    proc = _cli("response", str(BENCH), "-o", str(tmp_path / "x.h5"), cwd=tmp_path)
    assert proc.returncode == 2 and "[response]" in proc.stderr and "Traceback" not in proc.stderr


# ------------------------------------------------------------------ the linear response's limits
TWO_D, TWO_R, TWO_EA, TWO_RHO, TWO_J, TWO_ALPHA, TWO_T0 = 0.5, 0.05, 1.2e5, 1e-6, 1e-3, 2.0, 300.0


def _two_inertias(tmp_path: Path, tau: float, speeds: tuple[float, float, int]) -> Path:
    """Two equal pulleys D apart, the driver A (prescribed) and B (inertia J), both spans axial springs
    prestrained to T0, Rayleigh damping alpha M, a torque tau cos(omega t) on B: one rotational DOF."""
    raw = {"title": "two inertias",
           "belt": {"length": 2 * TWO_D + 2 * np.pi * TWO_R, "EA": TWO_EA, "EI": 0.0, "mass_per_length": TWO_RHO},
           "pulleys": [{"name": "A", "center": [0.0, 0.0], "radius": TWO_R, "mass": 1.0, "inertia": 1.0,
                        "driver": True},
                       {"name": "B", "center": [TWO_D, 0.0], "radius": TWO_R, "mass": 1.0, "inertia": TWO_J}],
           "tension": {"mode": "prestrain", "target": TWO_T0},
           "spans": {"A-B": {"model": "spring"}, "B-A": {"model": "spring"}},
           "response": {"speed": [speeds[0], speeds[1]], "points": speeds[2], "orders": [1.0], "transport": False,
                        "damping": {"rayleigh_mass": TWO_ALPHA},
                        "excitation": [{"pulley": "B", "kind": "torque", "amplitude": tau}]}}
    return _write(tmp_path, raw, f"two_{tau:.6g}.toml")


def _two_inertias_tension_amplitude(omega: np.ndarray, tau: float) -> np.ndarray:
    """Closed form: the stretch lam of a span at T0 from the bar law N = EA lam (lam^2 - 1) / 2, its
    reference length L = D / lam and stiffness k = dN/dl = EA (3 lam^2 - 1) / 2L; B's rotation theta =
    tau / (2 k R^2 - omega^2 J' + i omega alpha J') with J' = J + rho L R^2 (each span's mass lumped half
    on its ends); each span's tension amplitude k R |theta|."""
    lam = max(r.real for r in np.roots([1.0, 0.0, -1.0, -2.0 * TWO_T0 / TWO_EA]) if abs(r.imag) < 1e-12)
    L = TWO_D / lam
    k = TWO_EA * (3 * lam ** 2 - 1) / (2 * L)
    J = TWO_J + TWO_RHO * L * TWO_R ** 2
    theta = tau / (2 * k * TWO_R ** 2 - omega ** 2 * J + 1j * omega * TWO_ALPHA * J)
    return k * TWO_R * np.abs(theta)


def test_slack_warning_appears_exactly_where_the_closed_form_amplitude_exceeds_the_tension(tmp_path):
    # Against the closed form of the two-inertia drive (`_two_inertias_tension_amplitude`; measured 2e-8
    # relative within 1e-6 at and around the 175 Hz resonance, damping 0.09 %, the static tension meeting T0 to
    # 2e-14): the response's amplitudes equal it, and the
    # slack warning appears for a torque 0.1 % above the one whose largest closed-form amplitude equals the
    # static tension T0 and not for one 0.1 % below; at three times it, it names the first grid speed where the
    # closed form exceeds T0 and the worst (the resonance's grid point).
    speeds = (1080.0, 1120.0, 41)
    omega = np.linspace(*speeds[:2], speeds[2])
    unit = _two_inertias_tension_amplitude(omega, 1.0)
    tau_slack = TWO_T0 / unit.max()
    for factor, slack in ((0.999, False), (1.001, True), (3.0, True)):
        tau = factor * tau_slack
        cfg = load_config(_two_inertias(tmp_path, tau, speeds))
        res = response_of(cfg, analyse(cfg))
        closed = _two_inertias_tension_amplitude(omega, tau)
        got = np.abs(res.outputs["span_tension"][:, 0])  # (speed, span, end)
        np.testing.assert_allclose(got, np.broadcast_to(closed[:, None, None], got.shape), rtol=1e-6)
        np.testing.assert_allclose(res.static_tension, TWO_T0, rtol=1e-9)
        warned = [w for w in res.warnings if "would go slack" in w]
        assert len(warned) == (2 if slack else 0), (factor, res.warnings)
        if slack:
            first = omega[np.argmax(closed > TWO_T0)]
            worst = omega[np.argmax(closed)]
            for w in warned:
                assert f"from {first:.5g} rad/s, order 1" in w and f"worst {worst:.5g} rad/s, order 1" in w, w
                assert f"{closed.max():.4g} N about {TWO_T0:.4g} N" in w, w
    assert not any("slide" in w for w in res.warnings)  # no arm


def test_arm_friction_is_its_sticking_spring(tmp_path):
    # The linear response holds an arm's dry friction T_f as the transient's presliding spring T_f / delta
    # (delta = 1e-3 rad): the response with arm_friction = 0.4 N m equals (1e-9) the one without friction and
    # the arm spring stiffened by 0.4 / 1e-3 N m/rad (an independent model of the same drive), and an arm
    # amplitude above delta is a warning naming the first such speed (recomputed from the amplitudes).
    from beltdyn.analysis.stepper_data import ARM_PRESLIDING

    raw = tomllib.loads(TENSIONER.read_text())
    arm = next(p for p in raw["pulleys"] if p.get("support") == "arm")
    raw["response"] = {"speed": [20.0, 400.0], "points": 12, "orders": [1.0, 2.0], "transport": False,
                       "damping": {"rayleigh_mass": 10.0},
                       "excitation": [{"pulley": raw["pulleys"][0]["name"], "kind": "speed", "amplitude": 5.0}]}
    with_friction = {**raw, "pulleys": [dict(p, arm_friction=0.4) if p is arm else p for p in raw["pulleys"]]}
    stiffer = {**raw, "pulleys": [dict(p, arm_stiffness=arm["arm_stiffness"] + 0.4 / ARM_PRESLIDING)
                                  if p is arm else p for p in raw["pulleys"]]}
    results = []
    for name, table in (("friction.toml", with_friction), ("stiffer.toml", stiffer)):
        cfg = load_config(_write(tmp_path, table, name))
        results.append(response_of(cfg, analyse(cfg)))
    a, b = results
    for name in a.outputs:
        scale = np.abs(b.outputs[name]).max()
        assert np.abs(a.outputs[name] - b.outputs[name]).max() <= 1e-9 * scale, name
    A = np.abs(a.outputs["arm_angle"][:, :, 0])
    over = np.argwhere(A > ARM_PRESLIDING)
    slid = [w for w in a.warnings if "would slide" in w]
    assert len(over) and len(slid) == 1, (A.max(), a.warnings)
    s = over[:, 0].min()
    assert f"from {a.speed[s]:.5g} rad/s" in slid[0]
    assert not any("would slide" in w for w in b.warnings)  # no friction, no sliding limit


FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


def test_fead_response_warns_of_slack_spans_and_a_sliding_arm_through_the_cli(tmp_path):
    # Issue 26 item 6: the FEAD's linear response at idle-to-redline speeds predicts tension amplitudes
    # above the static tensions and arm amplitudes above the presliding angle. Through the real CLI (12 speeds,
    # 4 elements per span): /response warnings and the console name each such span and the arm, with the
    # first speed and order and the worst, recomputed here from the file's amplitudes and static tensions.
    from beltdyn.analysis.stepper_data import ARM_PRESLIDING
    from beltdyn.results.io import read_group

    out = tmp_path / "fead.h5"
    proc = _cli("response", str(FEAD), "-o", str(out), "--set", "response.points=12", "--set",
                "mesh.elements_per_span=4", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    g = read_group(out, "response")
    v, c = g["variables"], g["coords"]
    warnings = list(g["attrs"]["warnings"])
    speed, orders = c["speed"], c["order"]
    ratio = v["span_tension_amplitude"] / v["static_span_tension"][:, None]  # (speed, order, span, end)
    slack_spans = [s for i, s in enumerate(c["span"]) if (ratio[:, :, i] > 1).any()]
    assert slack_spans, ratio.max()  # the slack belt
    console = " ".join(proc.stdout.split())
    for i, span in enumerate(c["span"]):
        said = [w for w in warnings if w.startswith(f"span {span} would go slack")]
        r = ratio[:, :, i]
        assert len(said) == (1 if span in slack_spans else 0), (span, warnings)
        if said:
            s, o, _ = np.unravel_index(np.argmax(r), r.shape)
            first = np.argwhere(r > 1)[:, 0].min()
            assert f"from {speed[first]:.5g} rad/s" in said[0]
            assert f"worst {speed[s]:.5g} rad/s, order {orders[o]:g}" in said[0]
            assert " ".join(said[0].split()) in console  # the console says it too
    A = v["arm_angle_amplitude"][:, :, 0]
    slid = [w for w in warnings if w.startswith("arm TEN would slide")]
    assert A.max() > ARM_PRESLIDING and len(slid) == 1, warnings
    s, o = np.unravel_index(np.argmax(A), A.shape)
    assert f"from {speed[np.argwhere(A > ARM_PRESLIDING)[:, 0].min()]:.5g} rad/s" in slid[0]
    assert f"worst {speed[s]:.5g} rad/s, order {orders[o]:g}" in slid[0]
    assert " ".join(slid[0].split()) in console


def test_sticking_arm_response_equals_the_transient_with_dry_friction(tmp_path):
    # Against the nonlinear transient with the arm's dry friction (0.4 N m, the elasto-plastic law) at an amplitude
    # far below the presliding angle (7e-6 rad << 1e-3 rad): the harmonic of the span tensions and the arm angle
    # over the last ~0.5 s within 1e-3 of the largest (measured 5e-5); the response without the sticking spring
    # (the arm free) is 2.7 times the tensions, so the test tells the two apart. The tensioner in spring mode at
    # its adjusted free angle, 4 elements per span, 150 rad/s order 1, Rayleigh 20 M.
    from beltdyn.analysis.timestep import resolve_step
    from beltdyn.analysis.transient import run_transient

    raw = tomllib.loads(TENSIONER.read_text())
    free = float(np.nanmax(analyse(load_config(TENSIONER)).static.arm_free_angle))
    omega, B, alpha = 150.0, 0.01, 20.0
    raw["tension"] = {"mode": "spring"}
    raw["mesh"] = {"elements_per_span": 4}
    raw["pulleys"][2].update(arm_free_angle=free, arm_friction=0.4)
    raw["response"] = {"speed": [omega, omega * 1.0001], "points": 2, "orders": [1.0], "transport": False,
                       "damping": {"rayleigh_mass": alpha},
                       "excitation": [{"pulley": "A", "kind": "speed", "amplitude": B}]}
    raw["transient"] = {"duration": 1.5, "step": 1e-4, "output_interval": 2e-4, "rho_inf": 1.0, "transport": False,
                        "spectrum": {"enabled": False}, "damping": {"rayleigh_mass": alpha},
                        "rotation": [{"pulley": "A", "speed": omega, "speed_amplitude": B, "order": 1.0,
                                      "fluctuation_ramp": 0.3}]}
    cfg = load_config(_write(tmp_path, raw))
    run = analyse(cfg)
    res = response_of(cfg, run)
    raw["pulleys"][2]["arm_friction"] = 0.0
    free_cfg = load_config(_write(tmp_path, raw, "free.toml"))
    free_arm = response_of(free_cfg, analyse(free_cfg))
    got = []
    opts, _ = resolve_step(cfg.transient)
    run_transient(run.system, run.static, opts, sink=lambda t, d: got.append((t, d["span_tension"], d["arm_angle"])))
    t = np.concatenate([g[0] for g in got])
    periods = int(0.5 / (2 * np.pi / omega))
    sel = t > t[-1] - periods * 2 * np.pi / omega + 1e-9
    for k, name in ((1, "span_tension"), (2, "arm_angle")):
        Y_t = _harmonic(t[sel], np.concatenate([g[k] for g in got])[sel], omega)
        Y_r = res.outputs[name][0, 0]
        assert np.abs(Y_t - Y_r).max() <= 1e-3 * np.abs(Y_r).max(), name
    assert np.abs(free_arm.outputs["span_tension"][0, 0]).max() > 1.5 * np.abs(res.outputs["span_tension"][0, 0]).max()
    assert np.abs(res.outputs["arm_angle"]).max() < 1e-3 and not any("would slide" in w for w in res.warnings)
