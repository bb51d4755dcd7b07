"""The sparse pattern's parts derived once where it is built: `assembly.sorted_unique` against numpy's
unique, and the system's stored arm folding (`arms.arm_folding`) against the folding derived from K itself
and the dense product J^T K J."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.model.arms import arm_folding
from beltdyn.model.assembly import sorted_unique
from beltdyn.model.system import build_system

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


@pytest.mark.parametrize("k, high", [(1, 5), (2, 2), (50, 3), (1000, 10**6), (5000, 40)])
def test_sorted_unique_is_numpys_unique(k, high):
    """(distinct keys, inverse) equal np.unique(return_inverse=True)'s, on random keys and on keys mostly in order."""
    rng = np.random.default_rng(k)
    for keys in (rng.integers(0, high, k), np.sort(rng.integers(0, high, k)) + rng.integers(0, 2, k)):
        u, inv = sorted_unique(keys)
        u_np, inv_np = np.unique(keys, return_inverse=True)
        assert np.array_equal(u, u_np) and np.array_equal(inv, inv_np.ravel())
        assert np.array_equal(u[inv], keys)


def test_stored_folding_is_the_patterns_and_projects_as_the_dense_product():
    """The sparse FEAD's folding stored at its build holds its pattern, equals the one derived from the tangent
    K, and J^T K J through it equals the dense J^T K J (to rounding); a K on another pattern folds its own."""
    from scipy.sparse import csr_matrix

    system = build_system(load_config(FEAD))
    assert not system.dense and system.arms is not None and system.arm_folding is not None
    q = np.zeros(system.n_dof)
    q[system.arms.dof] = 0.05
    K = system.tangent_on_joints(q)
    fresh = arm_folding(system.arms, K.indptr, K.indices)
    stored = system.arm_folding
    assert stored.holds(K.indptr, K.indices)
    for name in ("rows", "fold", "ptr", "idx", "diag"):
        assert np.array_equal(getattr(stored, name), getattr(fresh, name)), name
    J = system.arms.dense_jacobian(q)
    dense = J.T @ K.toarray() @ J
    scale = np.abs(dense).max()
    folded = system.project_matrix(q, K)
    assert np.abs(folded.toarray() - dense).max() <= 1e-12 * scale
    other = csr_matrix(K.toarray() + np.eye(K.shape[0])[::-1])  # the anti-diagonal: a pattern the stored one lacks
    assert not stored.holds(other.indptr, other.indices)
    assert np.abs(system.project_matrix(q, other).toarray() - J.T @ other.toarray() @ J).max() <= 1e-12 * scale
