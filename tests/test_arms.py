"""Arm kinematics (`model.arms`): the one numpy implementation of the arm pulley's offset u(phi), its
slope and curvature, against the closed form u = L (cos(phi0 + phi) - cos phi0, sin(phi0 + phi) - sin phi0)
and central differences; the projections J^T f, J^T K J (+ the geometric term) against dense matrices
built from finite differences of the expansion p(q), dense and sparse alike, on random states."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.model.arms import arm_curvature, arm_offset, arm_slope
from beltdyn.model.system import build_system

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


@pytest.fixture(scope="module")
def arms():
    return build_system(load_config(FEAD)).arms


def test_offset_slope_and_curvature_closed_form_and_differences():
    rng = np.random.default_rng(5)
    L, phi0 = 0.05 + 0.1 * rng.random(3), 2 * np.pi * rng.random(3)
    dphi = 0.5 * rng.standard_normal((7, 3))
    u = arm_offset(L, phi0, phi0 + dphi)
    closed = L[:, None] * np.stack([np.cos(phi0 + dphi) - np.cos(phi0), np.sin(phi0 + dphi) - np.sin(phi0)], axis=-1)
    assert u.shape == (7, 3, 2) and np.abs(u - closed).max() <= 1e-15
    assert np.abs(arm_offset(L, phi0, phi0)).max() == 0.0
    h = 1e-5
    d1 = (arm_offset(L, phi0, phi0 + dphi + h) - arm_offset(L, phi0, phi0 + dphi - h)) / (2 * h)
    assert np.abs(d1 - arm_slope(L, phi0 + dphi)).max() <= 1e-10
    d2 = (arm_slope(L, phi0 + dphi + h) - arm_slope(L, phi0 + dphi - h)) / (2 * h)
    assert np.abs(d2 - arm_curvature(L, phi0 + dphi)).max() <= 1e-10


def _fd_jacobian(arms, q, h=1e-6):
    return np.stack([(arms.expand(q + h * e) - arms.expand(q - h * e)) / (2 * h) for e in np.eye(arms.n_q)], axis=1)


def test_expansion_and_jacobians_against_finite_differences(arms):
    rng = np.random.default_rng(6)
    for _ in range(5):
        q = 0.2 * rng.standard_normal(arms.n_q)
        p = arms.expand(q)
        assert np.array_equal(p[: arms.n_q], q)
        u = p[arms.n_q:].reshape(-1, 2)
        phi = arms.angle + q[arms.dof]
        closed = arms.length[:, None] * np.stack([np.cos(phi) - np.cos(arms.angle), np.sin(phi) - np.sin(arms.angle)], -1)
        assert np.abs(u - closed).max() <= 1e-15
        J = arms.dense_jacobian(q)
        assert np.abs(J - _fd_jacobian(arms, q)).max() <= 1e-9
        assert np.array_equal(arms.jacobian(q).toarray(), J)
        assert np.array_equal(arms.dense_jacobian(slopes=arms.first(arms.phi(q))), J)
        dq = rng.standard_normal(arms.n_q)
        assert np.abs(arms.expand_motion(q, dq) - J @ dq).max() <= 1e-15
        # batch of states = state by state
        Q = np.stack([q, 0.5 * q])
        assert np.array_equal(arms.expand(Q)[1], arms.expand(0.5 * q))
    assert np.array_equal(arms.dense_jacobian(np.zeros(arms.n_q)), arms.dense_jacobian(slopes=arms.reference_slopes))


def test_acceleration_is_the_second_derivative_along_a_path(arms):
    # p(q(t)) with q(t) = q0 + v t + a t^2 / 2: d2p/dt2 at t = 0 by central differences
    rng = np.random.default_rng(8)
    q0, v, a = 0.1 * rng.standard_normal(arms.n_q), rng.standard_normal(arms.n_q), rng.standard_normal(arms.n_q)
    h = 1e-4
    path = [arms.expand(q0 + v * t + 0.5 * a * t * t) for t in (-h, 0.0, h)]
    fd = (path[0] - 2 * path[1] + path[2]) / (h * h)
    assert np.abs(arms.expand_acceleration(q0, v, a) - fd).max() <= 1e-5 * np.abs(fd).max()


def test_projections_dense_sparse_and_the_geometric_term(arms):
    """J^T f equals the dense product; J^T K J + geo, dense and CSR, equals the derivative of J(q)^T (K p(q) + f0)
    by central differences (the geometric term is d(J^T)/dq f), for a random symmetric K."""
    from scipy.sparse import csr_matrix

    rng = np.random.default_rng(9)
    n_p = arms.n_p
    A = rng.standard_normal((n_p, n_p))
    K = A + A.T
    K[np.abs(K) < 0.8] = 0.0  # a sparse pattern
    f0 = rng.standard_normal(n_p)
    q = 0.2 * rng.standard_normal(arms.n_q)

    def force(qq):
        return arms.project(qq, K @ arms.expand(qq) + f0)

    f = K @ arms.expand(q) + f0
    J = arms.dense_jacobian(q)
    assert np.abs(arms.project(q, f) - J.T @ f).max() <= 1e-13 * np.abs(f).max()
    assert np.abs(arms.project(None, f) - arms.dense_jacobian(np.zeros(arms.n_q)).T @ f).max() <= 1e-13 * np.abs(f).max()
    h = 1e-6
    fd = np.stack([(force(q + h * e) - force(q - h * e)) / (2 * h) for e in np.eye(arms.n_q)], axis=1)
    r_dense, K_dense = arms.project_both(q, f, K, dense=True)
    r_sparse, K_sparse = arms.project_both(q, f, csr_matrix(K), dense=False)
    assert np.abs(K_dense - fd).max() <= 1e-7 * np.abs(fd).max()
    assert np.abs(K_sparse.toarray() - K_dense).max() <= 1e-13 * np.abs(K_dense).max()
    assert np.array_equal(r_dense, r_sparse) and np.array_equal(r_dense, arms.project(q, f))
    assert np.abs(arms.project_matrix(q, K, f, dense=True) - K_dense).max() == 0.0
    assert np.abs(arms.project_matrix(q, K, None, dense=True) - J.T @ K @ J).max() <= 1e-13 * np.abs(K).max()
    slopes = arms.first(arms.phi(q))
    assert np.array_equal(arms.project_matrix_at(slopes, K, dense=True), arms.project_matrix(q, K, None, dense=True))
    assert np.abs(arms.project_matrix_at(slopes, csr_matrix(K), dense=False).toarray() - J.T @ K @ J).max() \
        <= 1e-13 * np.abs(K).max()


def test_arm_joints_are_immutable_values(arms):
    from scipy.sparse import csr_matrix

    q = np.zeros(arms.n_q)
    arms.expand(q), arms.dense_jacobian(q), arms.project_both(q, np.ones(arms.n_p), csr_matrix(np.eye(arms.n_p)), dense=False)
    assert set(vars(arms)) == {f.name for f in dataclasses.fields(arms)}
