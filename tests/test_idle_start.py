"""A run-up from idle (issue 29): `[[transient.rotation]] start_speed`, the nominal speed ramped linearly from
start_speed to speed over ramp_time, the run starting from the running equilibrium at start_speed.

Compared against: the running static equilibrium at the start's belt speed (`analyse(..., belt_speed=...)`,
an independent solve); a run held at the idle speed (no ramp); the ramp's closed form
theta = Omega_0 t + (Omega - Omega_0) t^2 / (2 T_r)."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import config_from_dict
from beltdyn.errors import ConfigError
from beltdyn.pipeline import analyse, transient_start
from histories import run_histories  # tests/histories.py

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "configs" / "smoke" / "two_pulley.toml"


def _run(rotation: dict, duration: float = 0.03):
    raw = tomllib.loads(SMOKE.read_text())
    raw["static"] = {"torque": [{"pulley": "C", "value": -1.0}]}
    raw["transient"] = {"duration": duration, "step": 1e-4, "output_interval": 1e-3, "rho_inf": 0.9,
                        "tolerance": 1e-10, "rotation": [rotation], "spectrum": {"enabled": False}}
    cfg = config_from_dict(raw)
    sysm, st = transient_start(analyse(cfg, compiled=True))
    return run_histories(sysm, st, cfg.transient)[0], sysm, st, raw


def test_a_start_speed_needs_a_ramp():
    raw = tomllib.loads(SMOKE.read_text())
    raw["transient"] = {"rotation": [{"pulley": "A", "speed": 200.0, "start_speed": 100.0}]}
    with pytest.raises(ConfigError, match=r"transient\.rotation\[0\]\.start_speed"):
        config_from_dict(raw)


def test_a_run_up_from_idle_starts_in_the_running_steady_state():
    """A from 100 to 300 rad/s over 0.1 s: the run starts from the static equilibrium at the belt speed
    100 R_A (the same span tensions as that running static, solved apart, to 1e-12), C turns at 100 R_A / R_C
    at t = 0 and A's angle follows the ramp's closed form; held at idle instead (no ramp) the drive stays in
    that steady state (C's speed and the tensions to 1e-9: measured 8e-13 and 5e-11); a ramp from the start
    speed to itself is the idle run."""
    w0, w1, tr = 100.0, 300.0, 0.1
    got, sysm, st, raw = _run({"pulley": "A", "speed": w1, "start_speed": w0, "ramp_time": tr})
    R_A, R_C = sysm.layout.radius
    assert sysm.belt_speed == pytest.approx(w0 * R_A, rel=1e-12)
    cfg = config_from_dict(copy.deepcopy(raw))
    apart = analyse(cfg, belt_speed=sysm.belt_speed)
    np.testing.assert_allclose(st.span_tension, apart.static.span_tension, rtol=1e-12)
    t = got["time"]
    speed = got["pulley_speed"]
    assert abs(speed[0, 1]) == pytest.approx(w0 * R_A / R_C, rel=1e-9)
    theta_A = got["pulley_angle"][:, 0] - got["pulley_angle"][0, 0]
    np.testing.assert_allclose(theta_A, w0 * t + 0.5 * (w1 - w0) * t * t / tr, rtol=0, atol=1e-12)
    idle, *_ = _run({"pulley": "A", "speed": w0})  # held at idle from the same start: a steady state
    w_C, T = idle["pulley_speed"][:, 1], idle["span_tension"]
    assert np.abs(w_C - w_C[0]).max() < 1e-9 * abs(w_C[0])
    assert np.abs(T - T[0]).max() < 1e-9 * np.abs(T[0]).max()
    # a ramp from the start speed to itself is the idle run
    flat, *_ = _run({"pulley": "A", "speed": w0, "start_speed": w0, "ramp_time": tr})
    for name in ("pulley_speed", "span_tension"):
        np.testing.assert_allclose(flat[name], idle[name], rtol=1e-12, atol=1e-12 * np.abs(idle[name]).max())
