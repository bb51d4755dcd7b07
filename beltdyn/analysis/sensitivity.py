"""Frequency sensitivities from the eigenvectors (modal perturbation), for parameters that leave the
static equilibrium where it is.

Nomenclature (reduced coordinates, n = `System.n_dof`, k modes):
- K (n, n): the tangent stiffness dr/dq at the equilibrium q (`System.equilibrium`), M (n, n): the
  mass matrix at q (`System.mass_matrix`); the pencil K phi = lambda M phi, lambda = omega^2 (1/s^2).
- phi (k, n): mass-normalized shapes (phi^T M phi = 1, `ModalResult.shapes`), f = sqrt(lambda) / 2 pi (Hz).
- p: one parameter; dK, dM (n, n): dK/dp and dM/dp at fixed q, by central differences of the matrices
  of two systems built with p -/+ h (`matrix_derivatives`): exact for a parameter the matrices are
  linear in (EI, mass per length, inertias, masses, spring rates), O(h^2) otherwise.

d lambda / dp = phi^T (dK - lambda dM) phi and d f / dp = (d lambda / dp) / (8 pi^2 f), for each
simple eigenvalue (first-order perturbation of a symmetric pencil). For a near-degenerate pair (the
upper and lower spans' transverse modes) each value is still exact, but the pair's splitting makes
it valid in a tiny neighbourhood only; the pair's mean is smooth, which is how `study.fit` uses it.

The formula holds only where q does not move with p: `equilibrium_moves` says whether it does (the
static residual and the mean tension at q change with p); where it does (EA with a tension target,
the tension itself, a mass with gravity), derivatives are central differences of whole analyses
(`study.fit`). Running belts (gyroscopic modes) are left to those as well.
"""

from __future__ import annotations

import math

import numpy as np

from beltdyn.model.system import System

MOVE_TOLERANCE = 1e-8  # a residual change below this x the force scale (per step) is round-off


def _dense(A) -> np.ndarray:
    """A dense (n, n) array of a dense array or a scipy sparse matrix."""
    return A.toarray() if hasattr(A, "toarray") else np.asarray(A)


def matrix_derivatives(lower: System, upper: System, q: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """(dK, dM), each (n, n) dense: central differences (X(upper) - X(lower)) / (2 step) of the tangent
    stiffness and of the mass matrix at the state q (n,), `lower` and `upper` the same drive built with
    the parameter at p - step and p + step on the same layout and reference state."""
    K_lo, K_hi = _dense(lower.equilibrium(q)[1]), _dense(upper.equilibrium(q)[1])
    M_lo, M_hi = _dense(lower.mass_matrix(q)), _dense(upper.mass_matrix(q))
    return (K_hi - K_lo) / (2.0 * step), (M_hi - M_lo) / (2.0 * step)


def eigenvalue_derivatives(shapes: np.ndarray, eigenvalues: np.ndarray, dK: np.ndarray, dM: np.ndarray
                           ) -> np.ndarray:
    """d lambda / dp (k,) = phi^T (dK - lambda dM) phi for mass-normalized shapes phi (k, n), eigenvalues
    lambda (k,) (1/s^2), dK and dM (n, n)."""
    phi = np.asarray(shapes, dtype=float)
    return np.einsum("kn,kn->k", phi @ dK, phi) - eigenvalues * np.einsum("kn,kn->k", phi @ dM, phi)


def frequency_derivatives(shapes: np.ndarray, frequency: np.ndarray, dK: np.ndarray, dM: np.ndarray) -> np.ndarray:
    """d f / dp (k,) in Hz per unit of p for mass-normalized shapes phi (k, n) of frequencies f (k,) Hz:
    (d lambda / dp) / (8 pi^2 f), lambda = (2 pi f)^2."""
    f = np.asarray(frequency, dtype=float)
    lam = (2.0 * math.pi * f) ** 2
    return eigenvalue_derivatives(shapes, lam, dK, dM) / (8.0 * math.pi ** 2 * f)


def equilibrium_moves(base: System, lower: System, upper: System, q: np.ndarray) -> bool:
    """Whether the static equilibrium q (n,) of `base` moves when the parameter goes from the value of
    `lower` to that of `upper` (the same drive built on the same layout and reference state): the
    static residual at q changes beyond MOVE_TOLERANCE x the force scale (the belt's mean tension, the
    largest internal force), or the mean tension at q does. The adjustable DOF of tension mode
    "adjust" is left out: its preload is whatever the tension target asks for (an unknown of the
    static solve), so a spring rate on it moves nothing."""
    r_lo = lower.equilibrium(q, tangent=False)[0]
    r_hi = upper.equilibrium(q, tangent=False)[0]
    change = np.abs(r_hi - r_lo)
    ts = base.tension
    if ts.mode == "adjust" and ts.adjust_dof >= 0:
        change[ts.adjust_dof] = 0.0
    T_lo = lower.mean_tension_and_gradient(q, gradient=False)[0]
    T_hi = upper.mean_tension_and_gradient(q, gradient=False)[0]
    T0 = base.mean_tension_and_gradient(q, gradient=False)[0]
    scale = max(abs(T0), float(np.max(np.abs(base.internal_force(q)), initial=0.0)), 1e-300)
    return bool(float(np.max(change, initial=0.0)) > MOVE_TOLERANCE * scale
                or abs(T_hi - T_lo) > MOVE_TOLERANCE * scale)


def same_matrices(a: System, b: System, q: np.ndarray, *, rtol: float = 1e-12) -> bool:
    """Whether two systems have the same tangent stiffness, mass matrix and static residual at q (n,)
    to rtol of their largest entries: a rebuilt drive is the drive it replaces."""
    pairs = ((_dense(a.equilibrium(q)[1]), _dense(b.equilibrium(q)[1])),
             (_dense(a.mass_matrix(q)), _dense(b.mass_matrix(q))),
             (a.equilibrium(q, tangent=False)[0], b.equilibrium(q, tangent=False)[0]))
    def close(x: np.ndarray, y: np.ndarray) -> bool:
        big = max(float(np.max(np.abs(x), initial=0.0)), 1e-300)
        return x.shape == y.shape and float(np.max(np.abs(x - y), initial=0.0)) <= rtol * big

    return a.n_dof == b.n_dof and all(close(x, y) for x, y in pairs)


__all__ = [
    "MOVE_TOLERANCE",
    "eigenvalue_derivatives",
    "equilibrium_moves",
    "frequency_derivatives",
    "matrix_derivatives",
    "same_matrices",
]
