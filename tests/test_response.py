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
