"""A pulley's rotational damping (issue 25, item 4): a viscous torque to ground -d omega on its rotation,
a component (`components.rotation_component`), in the static at speed, the transient and the response.

Compared against: the same drive with the torque -d omega_j (omega_j = v / R_j at the running speed, the
rigid loop's closed form) given as a constant [[static.torque]] instead (the existing load path, an
independent computation); the driver's torque by the power balance of the rigid loop; the exponential
closed form of a pulley's speed under a step torque with viscous damping."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import config_from_dict, load_config
from beltdyn.pipeline import analyse

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


def test_the_damping_is_a_component_on_the_rotation():
    cfg = load_config(FEAD, ['pulleys[2].rotational_damping=0.004'])
    sysm = analyse(cfg).system
    C = np.asarray(sysm.linear_damping.todense() if hasattr(sysm.linear_damping, "todense") else sysm.linear_damping)
    d = int(sysm.rot_dof[2])
    assert C[d, d] == pytest.approx(0.004, rel=1e-15)
    cfg0 = load_config(FEAD)
    C0 = analyse(cfg0).system.linear_damping
    C0 = np.zeros_like(C) if C0 is None else np.asarray(C0.todense() if hasattr(C0, "todense") else C0)
    diff = C - C0
    diff[d, d] -= 0.004
    assert np.abs(diff).max() == 0.0  # nothing else changed


def test_the_static_at_speed_carries_d_omega_into_the_driver_torque():
    """FEAD at 20 m/s with d = 0.004 N m s/rad on ALT (r = 0.028 m: omega = 714 rad/s, d omega = 2.86 N m):
    the same static as with the constant torque -d omega on ALT among the [[static.torque]] loads (span
    tensions and driver torque to 1e-9 relative), and the driver's extra torque from the rigid loop's
    power balance: Delta T_drv omega_drv = d omega_ALT^2 (to the belt's stretch, 1e-2 relative)."""
    from beltdyn.model.components import belt_rotation_rates

    raw = tomllib.loads(FEAD.read_text())
    raw["running"] = {"belt_speed": 20.0}
    base = analyse(config_from_dict(copy.deepcopy(raw)))
    damped_raw = copy.deepcopy(raw)
    j = [p["name"] for p in raw["pulleys"]].index("ALT")
    damped_raw["pulleys"][j]["rotational_damping"] = 0.004
    damped = analyse(config_from_dict(damped_raw))
    sysm = damped.system
    rates = belt_rotation_rates(sysm.layout, sysm.rot_dof, sysm.n_p)[sysm.rot_dof]
    omega = 20.0 * rates  # (n,) rad/s, counter-clockwise
    assert abs(omega[j]) == pytest.approx(20.0 / sysm.layout.radius[j], rel=1e-14)
    loaded_raw = copy.deepcopy(raw)
    for tq in loaded_raw["static"]["torque"]:
        if tq["pulley"] == "ALT":
            tq["value"] += -0.004 * omega[j]
    loaded = analyse(config_from_dict(loaded_raw))
    np.testing.assert_allclose(damped.static.span_tension, loaded.static.span_tension, rtol=1e-9)
    assert damped.static.driver_torque == pytest.approx(loaded.static.driver_torque, rel=1e-9)
    drv = sysm.driver
    extra = damped.static.driver_torque - base.static.driver_torque
    assert abs(extra * omega[drv]) == pytest.approx(0.004 * omega[j] ** 2, rel=1e-2)
    # at rest the damping adds nothing
    rest = copy.deepcopy(damped_raw)
    del rest["running"]
    raw0 = copy.deepcopy(raw)
    del raw0["running"]
    assert analyse(config_from_dict(rest)).static.driver_torque == analyse(config_from_dict(raw0)).static.driver_torque


def test_a_damped_pulley_spins_up_as_the_exponential_closed_form():
    """The two-pulley smoke drive, free (no prescribed rotation, belt at rest), C damped with d = 0.94
    N m s/rad, a step torque T on C at t = 0: the rigid loop (coordinate s, m of belt travel; u the loop's
    rates, `transient_setup.belt_travel`) obeys m s'' + D s' = T u_C with m = u^T M u, D = u^T C u = d u_C^2,
    so omega_C(t) = u_C T u_C / D (1 - exp(-D t / m)) (tau = m / D = 0.05 s). The transient's omega_C
    against it, 4 tau long, to 1 % of the final speed (the belt's elastic modes ring on top: Kelvin-Voigt
    belt damping, which does no work on the rigid loop, and rho_inf = 0.8 settle them); the energy balance
    holds (the damper's dissipation counted) to 1e-5 of the work done."""
    from beltdyn.analysis.transient import run_transient
    from beltdyn.analysis.transient_setup import belt_travel

    raw = tomllib.loads((ROOT / "configs" / "smoke" / "two_pulley.toml").read_text())
    raw["pulleys"][1]["rotational_damping"] = 0.94
    T = 0.01  # N m: 2e-3 rad over the run, the tension changes by 0.1 N (linear range)
    raw["transient"] = {"duration": 0.2, "step": 2e-4, "output_interval": 1e-3, "rho_inf": 0.8,
                        "torque": [{"pulley": "C", "constant": T}], "damping": {"belt_axial": 2e-4},
                        "spectrum": {"enabled": False}}
    cfg = config_from_dict(raw)
    run = analyse(cfg)
    sysm = run.system
    u = belt_travel(sysm)
    M = np.asarray(sysm.mass.todense() if hasattr(sysm.mass, "todense") else sysm.mass)
    m = float(u @ M @ u)
    c_dof = int(sysm.rot_dof[1])
    uC = u[c_dof]
    D = 0.94 * uC * uC
    got: dict[str, list] = {}

    def sink(t, batch):
        got.setdefault("time", []).append(t)
        got.setdefault("speed", []).append(batch["pulley_speed"][:, 1])
        got.setdefault("energy", []).append(batch["energy"])

    run_transient(sysm, run.static, cfg.transient, sink=sink)
    t, w = np.concatenate(got["time"]), np.concatenate(got["speed"])
    energy = np.concatenate(got["energy"])  # kinetic, strain, work, dissipated, balance error (J)
    assert np.abs(energy[:, 4]).max() < 1e-5 * np.abs(energy[:, 2]).max()  # the damper's work is dissipated
    w_final = uC * T * uC / D
    expected = w_final * (1.0 - np.exp(-D * t / m))
    assert m / D == pytest.approx(0.05, rel=0.1)
    late = t > 0.01
    assert np.abs(w[late] - expected[late]).max() < 1e-2 * abs(w_final)
    assert w[-1] == pytest.approx(w_final * (1 - np.exp(-4.0)), rel=1e-2)


def test_a_prescribed_running_drive_with_a_damped_pulley_stays_at_its_running_equilibrium():
    """The smoke drive running at a constant prescribed speed of its static driver A (100 rad/s, from the
    static at that speed), C damped (d = 0.02 N m s/rad, d omega_C = 0.74 N m): the damping of the nominal
    travel replaces the static's constant torque (counted once, not twice), so the drive stays at its
    running equilibrium: C turns at the nominal speed to 1e-6 relative, the reaction torque on A equals the
    static driver torque (which carries d omega_C R_A / R_C) to 1e-6 relative."""
    from beltdyn.analysis.transient import run_transient
    from beltdyn.pipeline import transient_start

    raw = tomllib.loads((ROOT / "configs" / "smoke" / "two_pulley.toml").read_text())
    raw["pulleys"][1]["rotational_damping"] = 0.02
    raw["transient"] = {"duration": 0.05, "step": 1e-4, "output_interval": 1e-3, "rho_inf": 0.9,
                        "rotation": [{"pulley": "A", "speed": 100.0}], "spectrum": {"enabled": False}}
    cfg = config_from_dict(raw)
    sysm, st = transient_start(analyse(cfg))
    assert sysm.driver == 0 and sysm.belt_speed != 0.0
    omega_C = 100.0 * sysm.layout.radius[0] / sysm.layout.radius[1]
    assert abs(st.driver_torque) == pytest.approx(0.02 * omega_C * sysm.layout.radius[0] / sysm.layout.radius[1],
                                                  rel=1e-2)
    got: dict[str, list] = {}

    def sink(t, batch):
        got.setdefault("speed", []).append(batch["pulley_speed"][:, 1])
        got.setdefault("torque", []).append(batch["driver_torque"])

    run_transient(sysm, st, cfg.transient, sink=sink)
    w, tq = np.concatenate(got["speed"]), np.concatenate(got["torque"])
    assert np.abs(np.abs(w) - omega_C).max() < 1e-6 * omega_C
    assert np.abs(np.abs(tq) - abs(st.driver_torque)).max() < 1e-6 * abs(st.driver_torque)
