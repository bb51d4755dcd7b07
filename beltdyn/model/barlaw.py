"""The bar law of the belt: the one place where the axial force of a stretch is written.

Nomenclature: stretch lambda = |r'| (current over reference length), Green-Lagrange strain
eps = (lambda^2 - 1) / 2, second Piola-Kirchhoff force S = EA eps, true (Cauchy) axial force
N = S lambda = EA eps lambda (a St. Venant-Kirchhoff bar, paper Eqs. 12-14), its derivative
dN/dlambda = EA (3 lambda^2 - 1) / 2, the strain energy per unit reference length EA eps^2 / 2, and
the Kelvin-Voigt force of a stretch rate lambda' with retardation time eta,
N_d = EA eta lambda d(eps)/dt = EA eta lambda^2 lambda'. The inverse lambda(N) solves
lambda^3 - lambda - 2 N / EA = 0 by Newton from `stretch_start`.

Every function takes floats or numpy arrays (elementwise) and is plain arithmetic, so the compiled
kernels use these very functions through numba (`njit(barlaw.axial_force)`, `spring_kernel`); only
`stretch_for_tension` and `stretch_start` are numpy-only (set-up and statics).

The law is one choice: `LAWS` names the laws this module knows and `bar_law(name)` gives the
functions of one (`BarLaw`): "green-lagrange" (St. Venant-Kirchhoff, above; the default) and "linear",
the law of Exudyn's cable element and of catalog EA values,

    N = EA (lambda - 1),  dN/dlambda = EA,  energy EA (lambda - 1)^2 / 2,  lambda(N) = 1 + N / EA,

with the Kelvin-Voigt force N_d = EA eta lambda' and the force per unit reference section N / lambda
(the slack test: its sign is N's). Both are the virtual work of N d lambda, lambda = |r'|. The
module-level functions without a prefix are the "green-lagrange" law's; `linear_...` the linear law's.
The ANCF element (`ancf.make_elements(axial_law=...)`) and its compiled kernel (`belt_kernel`, the
`law` argument) take either; the configuration key, the spring spans and the statics use the default.
For one tension the green elongation lambda - 1 is smaller than the linear law's by 3/2 N/EA of it
(about 1 % at the paper's 0.7 % strain).
"""

from __future__ import annotations

import math
from typing import Callable, NamedTuple

import numpy as np

from beltdyn.config import AXIAL_LAWS


def strain(stretch):
    """Green-Lagrange strain eps = (lambda^2 - 1) / 2 of a stretch lambda."""
    return 0.5 * (stretch * stretch - 1.0)


def second_piola_force(stretch, EA):
    """Second Piola-Kirchhoff axial force S = EA eps (N) of a stretch lambda (the force per unit
    reference section: the slack test of the belt and its springs)."""
    return EA * (0.5 * (stretch * stretch - 1.0))


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


def viscous_force(stretch, stretch_rate, EA, eta):
    """Kelvin-Voigt axial force N_d = EA eta lambda d(eps)/dt = EA eta lambda^2 lambda' (N) of a stretch
    rate lambda' (1/s), retardation time eta (s)."""
    return EA * eta * stretch * stretch * stretch_rate


def stretch_start(x):
    """A start for the stretch lambda of a bar at N / EA = x (`stretch_for_tension`; a float or an
    array, the same type back): the series lambda = 1 + x - 3/2 x^2 + 4 x^3 + O(x^4) where the strain
    is small (one Newton step then reaches round-off for |x| < 1e-2), 1 + x beyond."""
    series = 1.0 + x * (1.0 - x * (1.5 - 4.0 * x))
    small = abs(x) < 0.05
    if isinstance(small, bool):  # a Python number: the choice np.where makes elementwise, without its cost
        return series if small else 1.0 + x
    if small.all():  # (the series everywhere: np.where's choice without its cost)
        return series
    return np.where(small, series, 1.0 + x)[()]


def stretch_for_tension(tension, EA: float):
    """lambda with EA eps lambda = N, eps = (lambda^2 - 1)/2 (the inverse of `axial_force`), elementwise:
    a float for a number, an array of the tensions' shape for an array (`_newton`, one code for both: a
    number in Python floats, the statics' many one-tension calls). NaN where no stretch carries the
    tension (the Newton step divides 0 by 0)."""
    if isinstance(tension, (int, float)):
        try:
            return float(_newton(float(tension) / float(EA), abs))
        except ZeroDivisionError:  # (a float's x / 0, where numpy's gives inf or nan)
            return math.nan
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        lam = _newton(np.asarray(tension, dtype=float) / EA, _largest)
    return float(lam) if np.ndim(lam) == 0 else lam


def _largest(step) -> float:
    """max |step| of an array (0 for an empty one)."""
    return float(np.abs(step).max(initial=0.0))  # (the method: np.max's dispatch costs more than the max of a few)


def _newton(x, largest):
    """lambda^3 - lambda - 2 x = 0 by Newton from `stretch_start`(x) (x = N / EA, a float or an array) until
    the largest step (`largest`(step)) is <= 1e-15 (lambda ~ 1: a few ulp; Newton is quadratic well
    before), at most 50 steps."""
    lam = stretch_start(x)
    for _ in range(50):
        step = (lam * lam * lam - lam - 2.0 * x) / (3.0 * lam * lam - 1.0)  # (a float's ** raises on overflow)
        lam = lam - step
        if largest(step) <= 1e-15:
            break
    return lam


def linear_axial_force(stretch, EA):
    """Linear law: axial force N = EA (lambda - 1) (N)."""
    return EA * (stretch - 1.0)


def linear_axial_stiffness(stretch, EA):
    """Linear law: dN/dlambda = EA (N per unit stretch; `stretch` only for the common signature)."""
    return EA + 0.0 * stretch


def linear_second_piola_force(stretch, EA):
    """Linear law: N / lambda = EA (lambda - 1) / lambda (N per unit reference section)."""
    return EA * (stretch - 1.0) / stretch


def linear_strain_energy_density(stretch, EA):
    """Linear law: strain energy per unit reference length EA (lambda - 1)^2 / 2 (J/m)."""
    d = stretch - 1.0
    return 0.5 * EA * d * d


def linear_viscous_force(stretch, stretch_rate, EA, eta):
    """Linear law: Kelvin-Voigt axial force N_d = EA eta lambda' (N); `stretch` for the common signature."""
    return EA * eta * stretch_rate + 0.0 * stretch


def linear_stretch_for_tension(tension, EA: float):
    """Linear law: lambda = 1 + N / EA (a float for a number, an array for an array; NaN for EA = 0)."""
    if isinstance(tension, (int, float)):
        return 1.0 + float(tension) / float(EA) if EA else math.nan
    return 1.0 + np.asarray(tension, dtype=float) / EA


class BarLaw(NamedTuple):
    """The functions of one axial law, each as the module's function of the same name (floats or arrays;
    all but `stretch_for_tension` compile with numba)."""

    name: str
    axial_force: Callable
    axial_stiffness: Callable
    second_piola_force: Callable
    strain_energy_density: Callable
    viscous_force: Callable
    stretch_for_tension: Callable


LAWS = AXIAL_LAWS  # "green-lagrange" (St. Venant-Kirchhoff) and "linear" N = EA (lambda - 1): the key belt.axial_law


def bar_law(name: str = "green-lagrange") -> BarLaw:
    """The functions of the axial law `name` (one of `LAWS`); the one switch between laws."""
    if name == "green-lagrange":
        return BarLaw(name=name, axial_force=axial_force, axial_stiffness=axial_stiffness,
                      second_piola_force=second_piola_force, strain_energy_density=strain_energy_density,
                      viscous_force=viscous_force, stretch_for_tension=stretch_for_tension)
    if name == "linear":
        return BarLaw(name=name, axial_force=linear_axial_force, axial_stiffness=linear_axial_stiffness,
                      second_piola_force=linear_second_piola_force,
                      strain_energy_density=linear_strain_energy_density, viscous_force=linear_viscous_force,
                      stretch_for_tension=linear_stretch_for_tension)
    raise ValueError(f"unknown axial law {name!r}: one of {', '.join(LAWS)}")
