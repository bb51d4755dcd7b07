"""Numerical helpers of the element tests: central differences per element and the per-element relative
error (written apart from the code they check)."""

from __future__ import annotations

import numpy as np


def element_differences(fun, e: np.ndarray, h: float) -> np.ndarray:
    """Central differences of an element-wise function fun(e) -> (n, ...) in the element coordinates
    e (n, 8): (n, ..., 8)."""
    cols = []
    for j in range(8):
        ep = e.copy()
        em = e.copy()
        ep[:, j] += h
        em[:, j] -= h
        cols.append((fun(ep) - fun(em)) / (2.0 * h))
    return np.stack(cols, axis=-1)


def element_error(a: np.ndarray, b: np.ndarray) -> float:
    """max over elements of ||a - b|| / ||b|| (Frobenius over the trailing axes)."""
    n = a.shape[0]
    num = np.linalg.norm((a - b).reshape(n, -1), axis=1)
    den = np.linalg.norm(b.reshape(n, -1), axis=1)
    return float(np.max(num / den))
