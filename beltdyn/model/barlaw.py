"""The bar law of the belt: the one place where the axial force of a stretch is written.

Nomenclature: stretch lambda = |r'| (current over reference length), Green-Lagrange strain
eps = (lambda^2 - 1) / 2, true (Cauchy) axial force N = EA eps lambda (a St. Venant-Kirchhoff bar,
paper Eqs. 12-14), its derivative dN/dlambda = EA (3 lambda^2 - 1) / 2, and the strain energy per
unit reference length EA eps^2 / 2. The inverse lambda(N) solves lambda^3 - lambda - 2 N / EA = 0
by Newton from `stretch_start`.

Every function takes floats or numpy arrays (elementwise); the compiled kernels call the same
functions through numba (`njit` of these sources).
"""

from __future__ import annotations

import math

import numpy as np


def strain(stretch):
    """Green-Lagrange strain eps = (lambda^2 - 1) / 2 of a stretch lambda."""
    return 0.5 * (stretch * stretch - 1.0)


def axial_force(stretch, EA):
    """True axial force N = EA eps lambda (N) of a stretch lambda on an axial stiffness EA (N)."""
    return EA * (0.5 * (stretch * stretch - 1.0)) * stretch


def axial_stiffness(stretch, EA):
    """dN/dlambda = EA (3 lambda^2 - 1) / 2 (N per unit stretch)."""
    return EA * (3.0 * stretch * stretch - 1.0) / 2.0


def strain_energy_density(stretch, EA):
    """Strain energy per unit reference length EA eps^2 / 2 (J/m)."""
    eps = 0.5 * (stretch * stretch - 1.0)
    return 0.5 * EA * eps * eps


def stretch_start(x):
    """A start for the stretch lambda of a bar at N / EA = x (`stretch_for_tension`; a float or an
    array): the series lambda = 1 + x - 3/2 x^2 + 4 x^3 + O(x^4) where the strain is small (one Newton
    step then reaches round-off for |x| < 1e-2), 1 + x beyond."""
    series = 1.0 + x * (1.0 - x * (1.5 - 4.0 * x))
    if isinstance(x, float):
        return series if abs(x) < 0.05 else 1.0 + x
    return np.where(np.abs(x) < 0.05, series, 1.0 + x)


def stretch_for_tension(tension, EA: float):
    """lambda with EA * eps * lambda = N, eps = (lambda^2 - 1)/2 (St. Venant-Kirchhoff bar); elementwise
    for an array of tensions (a float for a float: plain Python arithmetic, no numpy call)."""
    if not isinstance(tension, (float, int)) and np.size(tension) <= 16:  # a few: element by element in floats
        T = np.asarray(tension, dtype=float)
        if T.ndim == 0:
            return stretch_for_tension(float(T), EA)
        return np.array([stretch_for_tension(t, EA) for t in T.ravel().tolist()]).reshape(T.shape)
    if isinstance(tension, (float, int)):  # from `stretch_start`
        x = float(tension) / EA
        lam = stretch_start(x)
        largest = abs
    else:
        x = np.asarray(tension, dtype=float) / EA
        lam = stretch_start(x)

        def largest(step):
            return float(np.max(np.abs(step), initial=0.0))
    try:
        for _ in range(50):
            step = (lam * lam * lam - lam - 2.0 * x) / (3.0 * lam * lam - 1.0)  # (a float's ** raises on overflow)
            lam = lam - step
            if largest(step) <= 1e-15:  # lambda ~ 1: a few ulp; Newton is quadratic well before
                break
    except ZeroDivisionError:  # a float's 0 / 0 or x / 0 where numpy's would give nan or inf
        return math.nan
    return lam if isinstance(lam, float) or np.ndim(lam) else float(lam)
