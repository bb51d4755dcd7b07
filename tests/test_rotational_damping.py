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
