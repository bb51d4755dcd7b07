"""The stepper's compiled arm kinematics (`integrator.complete`, `integrator.project`) held to the
numpy one (`model.arms.ArmJoints`: expand, expand_motion, expand_acceleration, project, dense_jacobian)
on random states, 1e-12; the dry-friction bristle (`arm_friction`, `slide_anchors`) against its
closed form clip(k_b (phi - z), -T_down, T_up) (symmetric and by sense)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.analysis import integrator as itg
from beltdyn.analysis import friction_kernel
from beltdyn.analysis.transient import stepper_arms
from beltdyn.config import load_config
from beltdyn.model.system import build_system

ROOT = Path(__file__).resolve().parents[1]
WITH_ARMS = [ROOT / "configs" / "examples" / "fead_4cyl.toml", ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"]


def _system(path):
    system = build_system(load_config(path))
    assert system.arms is not None and len(system.arms.dof) >= 1
    return system


def _close(a, b):
    scale = max(np.abs(b).max(), 1.0)
    np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * scale)


@pytest.mark.parametrize("path", WITH_ARMS, ids=lambda p: p.stem)
def test_complete_is_the_numpy_arm_kinematics(path):
    system = _system(path)
    joints, arms = system.arms, stepper_arms(system)
    rng = np.random.default_rng(7)
    for _ in range(20):
        q, v, a = rng.normal(size=(3, joints.n_q))
        q[joints.dof] = rng.uniform(-np.pi, np.pi, len(joints.dof))  # any arm angle, not just small turns
        p, vp, ap = (np.concatenate([x, np.full(joints.n_p - joints.n_q, np.nan)]) for x in (q, v, a))
        itg.complete(arms, p, vp, ap)
        _close(p, joints.expand(q))
        _close(vp, joints.expand_motion(q, v))
        _close(ap, joints.expand_acceleration(q, v, a))


@pytest.mark.parametrize("path", WITH_ARMS, ids=lambda p: p.stem)
def test_project_is_the_numpy_transpose(path):
    system = _system(path)
    joints, arms = system.arms, stepper_arms(system)
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = rng.normal(size=joints.n_q)
        q[joints.dof] = rng.uniform(-np.pi, np.pi, len(joints.dof))
        p = joints.expand(q)
        x = rng.normal(size=joints.n_p)
        out = np.full(joints.n_q, np.nan)
        itg.project(arms, p, x, out)
        _close(out, joints.project(q, x))
        J = joints.dense_jacobian(q)  # (n_p, n_q): an independent product J^T x, and |J|^T x
        _close(out, J.T @ x)
        itg.project(arms, p, x, out, True)
        _close(out, np.abs(J).T @ x)


def test_bristle_friction_is_the_clipped_spring():
    # two arms with friction T_f, one without; torque clip(k_b (phi - z), -T_f, T_f), stored energy
    # tau^2 / (2 k_b); the return mapping moves an anchor to within T_f / k_b of the angle
    arms = itg.Arms(dof=np.array([0, 1, 2]), slot=np.array([3, 5, 7]), length=np.ones(3), angle=np.zeros(3),
                    friction_up=np.array([2.0, 3.0, 0.0]), friction_down=np.array([2.0, 3.0, 0.0]),
                    bristle=np.array([2000.0, 3000.0, 1.0]),
                    anchor=np.zeros(3), n_q=3)
    q = np.array([5e-4, -4e-3, 0.7, 0, 0, 0, 0, 0, 0])
    f = np.zeros(9)
    stored = friction_kernel.arm_friction(arms, q, f)
    tau = np.array([2000.0 * 5e-4, -3.0, 0.0])
    np.testing.assert_allclose(f[:3], tau, rtol=1e-15)
    assert stored == pytest.approx(tau[0] ** 2 / 4000.0 + 9.0 / 6000.0, rel=1e-15)
    friction_kernel.slide_anchors(arms, q)
    np.testing.assert_allclose(arms.anchor, [0.0, -4e-3 + 1e-3, 0.0], rtol=1e-15)


def test_asymmetric_bristle_slides_at_its_limit_by_sense():
    # T_up = 2 (counter-clockwise), T_down = 0.5 (clockwise), k_b = 2000: the closed form clip(k_b (phi - z),
    # -T_down, T_up) on both sides; the return mapping leaves the anchor T_up / k_b behind a counter-clockwise
    # slide and T_down / k_b ahead of a clockwise one
    arms = itg.Arms(dof=np.array([0, 1, 2]), slot=np.array([3, 5, 7]), length=np.ones(3), angle=np.zeros(3),
                    friction_up=np.full(3, 2.0), friction_down=np.full(3, 0.5), bristle=np.full(3, 2000.0),
                    anchor=np.zeros(3), n_q=3)
    q = np.array([5e-3, -5e-3, -1e-4, 0, 0, 0, 0, 0, 0])
    f = np.zeros(9)
    stored = friction_kernel.arm_friction(arms, q, f)
    tau = np.array([2.0, -0.5, -0.2])
    np.testing.assert_allclose(f[:3], tau, rtol=1e-15)
    assert stored == pytest.approx(float(np.sum(tau**2)) / 4000.0, rel=1e-15)
    friction_kernel.slide_anchors(arms, q)
    np.testing.assert_allclose(arms.anchor, [5e-3 - 1e-3, -5e-3 + 2.5e-4, 0.0], rtol=1e-15)


def test_friction_by_sense_maps_loading_and_unloading():
    # loading = turning away from the free angle: counter-clockwise above it, clockwise below it
    from beltdyn.model.arms import friction_by_sense

    cfg = load_config(WITH_ARMS[1], ["pulleys[2].arm_friction=0.8", "pulleys[2].arm_friction_unloading=0.2",
                                     "pulleys[2].arm_free_angle=3.0"])
    p = cfg.pulleys[2]
    assert friction_by_sense(p, 3.1) == (0.8, 0.2)
    assert friction_by_sense(p, 2.9) == (0.2, 0.8)
    system = build_system(cfg)
    k = system.arms.pulleys.index(2)
    expect = (0.8, 0.2) if system.arms.angle[k] >= 3.0 else (0.2, 0.8)
    assert tuple(system.arms.friction[k]) == expect
    arms = stepper_arms(system)
    assert (arms.friction_up[k], arms.friction_down[k]) == expect and arms.bristle[k] == 0.8 / itg.ARM_PRESLIDING
