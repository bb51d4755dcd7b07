"""`beltdyn positions` (issue 29): the tensioner arm's positions over the belt's life on the example
FEAD (configs/examples/fead_4cyl.toml, a spring-mode arm). Each position is compared against an
independent run of the plain static pipeline (`pipeline.analyse`) on the same drive; MIN / MAX and
WORN against NOMINAL by the physics (a longer belt lets the spring turn the arm further towards its
free angle, so the arm angle grows and the tension falls); FREE against the closed form k (phi_0 - phi)
at the stop."""

from __future__ import annotations

import subprocess
from dataclasses import replace
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.errors import ConfigError
from beltdyn.pipeline import analyse
from beltdyn.study.positions import POSITIONS, spring_arm, tensioner_positions
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


@pytest.fixture(scope="module")
def cfg():
    return load_config(FEAD)


@pytest.fixture(scope="module")
def result(cfg):
    return tensioner_positions(cfg, length_tolerance=0.005, wear=0.01)


def row(res, name):
    return POSITIONS.index(name)


def test_nominal_and_load_are_the_plain_static_solution(cfg, result):
    arm = spring_arm(cfg)
    plain = analyse(replace(cfg, static=replace(cfg.static, torque=()))).static  # NOMINAL: no torques
    k = row(result, "NOMINAL")
    assert result.status[k] == "ok"
    assert result.arm_angle[k] == plain.arm_angle[arm] and result.spring_torque[k] == plain.arm_torque[arm]
    np.testing.assert_array_equal(result.span_tension[k], plain.span_tension)
    np.testing.assert_array_equal(result.hub_load[k], plain.hub_load)
    loaded = analyse(cfg).static  # LOAD: the drive as given, with its [[static.torque]]
    k = row(result, "LOAD")
    assert result.arm_angle[k] == loaded.arm_angle[arm]
    np.testing.assert_array_equal(result.span_tension[k], loaded.span_tension)
    np.testing.assert_array_equal(result.slip_margin[k], loaded.slip_margin)
    assert np.isfinite(loaded.slip_margin[cfg.driver_index])  # the load case has torques: a finite margin


def test_min_max_bracket_nominal_monotonically(cfg, result):
    i = {name: row(result, name) for name in ("MIN", "NOMINAL", "MAX", "WORN")}
    assert all(result.status[k] == "ok" for k in i.values())
    angle = result.arm_angle
    assert angle[i["MIN"]] < angle[i["NOMINAL"]] < angle[i["MAX"]] < angle[i["WORN"]]  # wear 1 % > 5 mm / 1.61 m
    torque = result.spring_torque
    assert torque[i["MIN"]] > torque[i["NOMINAL"]] > torque[i["MAX"]] > torque[i["WORN"]] > 0
    tension = result.span_tension
    assert np.all(tension[i["MIN"]] > tension[i["NOMINAL"]]) and np.all(tension[i["NOMINAL"]] > tension[i["MAX"]])
    np.testing.assert_allclose(result.belt_length[[i["MIN"], i["MAX"], i["WORN"]]],
                               [cfg.belt.length - 0.005, cfg.belt.length + 0.005, 1.01 * cfg.belt.length], rtol=1e-15)
    lo, hi = cfg.pulleys[spring_arm(cfg)].arm_range
    belt = angle[1:]
    assert result.take_up_used == pytest.approx((belt.max() - belt.min()) / (hi - lo), rel=1e-15)


def test_worn_at_zero_wear_equals_nominal(cfg):
    res = tensioner_positions(cfg, length_tolerance=0.005, wear=0.0)
    k, n = row(res, "WORN"), row(res, "NOMINAL")
    assert res.arm_angle[k] == res.arm_angle[n] and res.spring_torque[k] == res.spring_torque[n]
    np.testing.assert_array_equal(res.span_tension[k], res.span_tension[n])
    np.testing.assert_array_equal(res.hub_load[k], res.hub_load[n])


def test_free_rests_on_the_stop_with_the_closed_form_torque(cfg, result):
    p = cfg.pulleys[spring_arm(cfg)]
    assert p.arm_free_angle > p.arm_range[1]  # the example's spring is wound past the upper stop
    k = row(result, "FREE")
    assert result.arm_angle[k] == p.arm_range[1] and result.status[k] == "at stop"
    assert result.spring_torque[k] == pytest.approx(p.arm_stiffness * (p.arm_free_angle - p.arm_range[1]), rel=1e-15)
    assert np.all(result.span_tension[k] == 0.0)


def test_a_position_beyond_the_stops_is_reported_not_hidden(cfg):
    # 2.5 % longer: the spring would turn the arm to 4.1015 rad, past its upper stop 4.1 rad
    res = tensioner_positions(cfg, length_tolerance=0.005, wear=0.025)
    k = row(res, "WORN")
    assert res.status[k] == "beyond stops" and "outside its stops" in res.message[k]
    assert np.isnan(res.arm_angle[k]) and np.isnan(res.span_tension[k]).all()
    assert res.status[row(res, "NOMINAL")] == "ok"
    # 5 % longer: the belt cannot even be laid with the arm between its stops
    res = tensioner_positions(cfg, length_tolerance=0.005, wear=0.05)
    assert res.status[k] in ("beyond stops", "no fit") and res.message[k] and np.isnan(res.arm_angle[k])


def test_a_drive_without_a_spring_arm_is_refused(cfg):
    no_arm = load_config(ROOT / "configs" / "smoke" / "two_pulley.toml")
    with pytest.raises(ConfigError, match="needs a tensioner arm"):
        tensioner_positions(no_arm)
    adjust = load_config(ROOT / "configs" / "examples" / "three_pulley_tensioner.toml")
    with pytest.raises(ConfigError, match=r'tension\.mode = "spring"'):
        tensioner_positions(adjust)


def test_cli_writes_positions_and_exits_2_without_an_arm(tmp_path):
    out = tmp_path / "pos.h5"
    proc = subprocess.run([*BELTDYN, "positions", str(FEAD), "-o", str(out), "--length-tolerance", "0.005"],
                          cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    text = " ".join(proc.stdout.split())
    assert "take-up used: 27.0 % of the arm's range [3.3, 4.1] rad" in text  # (creep wraps; 28.6 % with rigid ones)
    assert "FREE: at stop" in text
    with h5py.File(out, "r") as f:
        g = f["positions"]
        assert [x.decode() for x in g["position"][()]] == list(POSITIONS)
        assert g["span_tension"].shape == (6, 7, 2) and g["arm_angle"].shape == (6,)
    proc = subprocess.run([*BELTDYN, "positions", str(ROOT / "configs" / "smoke" / "two_pulley.toml"),
                           "-o", str(tmp_path / "two.h5")], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 2
    message = (proc.stdout + proc.stderr).strip()
    assert "needs a tensioner arm" in message and len(message.splitlines()) == 1 and "Traceback" not in message
