"""The span-pulley joints' set-up tables (pure numpy): which elements' transforms are the identity."""

from __future__ import annotations

import numpy as np


def joint_selection(T: np.ndarray, idx: np.ndarray, n_dof: int) -> np.ndarray:
    """tsel (n_elem,) int64: -1 where element k has T[k] == [I8 | 0] exactly and idx[k, 8:] all
    equal the padding index n_dof (identity fast path), else k (its own row of T).

    T (n_elem, 8, m) and idx (n_elem, m) with m >= 8.
    """
    T = np.asarray(T)
    idx = np.asarray(idx)
    if T.ndim != 3 or T.shape[1] != 8 or T.shape[2] < 8:
        raise ValueError(f"T must have shape (n_elem, 8, m >= 8), got {T.shape}")
    if idx.shape != (T.shape[0], T.shape[2]):
        raise ValueError(f"idx must have shape {(T.shape[0], T.shape[2])}, got {idx.shape}")
    ident = np.zeros(T.shape[1:])
    ident[:, :8] = np.eye(8)
    ok = (T == ident).all(axis=(1, 2)) & (idx[:, 8:] == n_dof).all(axis=1)  # (the methods: np.all's dispatch costs more)
    return np.where(ok, -1, np.arange(T.shape[0])).astype(np.int64)
