"""Slip margins of the pulleys: the Euler-Eytelwein (capstan) limit on each wrap.

A belt on a pulley of wrap angle beta transmits the tension ratio T_tight / T_slack without slipping
as long as  ln(T_tight / T_slack) <= mu beta,  mu the effective belt-pulley friction coefficient (for
a V-ribbed belt the wedge-effective value mu / sin(half groove angle), as the user gives it). So

    mu_required = ln(T_tight / T_slack) / beta,     margin = mu / mu_required,

with T_tight and T_slack the larger and smaller of the tensions in the two spans at the pulley (the
end of the arriving span, the start of the departing one) and beta the loaded wrap angle (the
geometry at the solved pulley positions). margin > 1: no slip; margin < 1: the pulley slips. A slack
span (tension <= 0) gives mu_required = inf and margin 0. A pulley with no torque demand (an idler,
the tensioner in the statics) sees equal tensions, but computed ones differ in their last digits
(up to ~2e-13 of the tension in the FEAD example, ANCF or spring spans), and ln(T1/T2) of
those gave margins of ~1e12 or inf by chance. So tensions equal to |T1 - T2| <= 1e-9 max(|T1|, |T2|)
(`ROUND_OFF`: thousands of times the round-off seen, and far below any torque a pulley transmits: 1e-9
of a 300 N span on a 30 mm pulley is 1e-8 N m) count as equal, in every span model: mu_required = 0 and
margin inf. Pulleys without a friction value get NaN margins.

A running belt: the capstan law holds for the tensions less their centrifugal part
c = rho v^2 lambda (rho the mass per unit undeformed length, v the belt speed in undeformed length per
second, lambda the stretch: the moving belt's mass per current length rho / lambda times its current
speed v lambda squared), (T_tight - c) / (T_slack - c) = exp(mu beta), so

    mu_required = ln((T_tight - c) / (T_slack - c)) / beta,

and a wrap with T_slack <= c is slack on the pulley (mu_required inf, margin 0). lambda is taken at one
tension for the whole drive (`centrifugal_tension`; the callers pass the mean span tension): the
stretch differs between the tight and slack sides by (T_tight - T_slack) / EA ~ 1e-3, a change of c far
below the tensions' accuracy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from beltdyn.model.barlaw import stretch_for_tension

if TYPE_CHECKING:
    from beltdyn.model.system import System


def pulley_tensions(span_tension: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T_in, T_out) (..., n): the tension of the span arriving at each pulley (its end) and of the
    span leaving it (its start), from span_tension (..., n_span, 2) (span s runs pulley s -> s + 1)."""
    t_end = span_tension[..., 1]
    return np.concatenate((t_end[..., -1:], t_end[..., :-1]), axis=-1), span_tension[..., 0]


# |T_in - T_out| <= ROUND_OFF max(|T_in|, |T_out|): no torque demand (equal tensions to round-off)
ROUND_OFF = 1e-9


def centrifugal_tension(rho: float, speed, stretch):
    """c = rho v^2 lambda (N): the centrifugal part of a running belt's tension, rho (kg/m, per undeformed
    length), belt speed v (m/s of undeformed length; a float or an array of times), stretch lambda."""
    return rho * np.square(speed) * stretch


def belt_density(system: "System") -> float:
    """The belt's mass per unit undeformed length rho (kg/m): its elements' (or, with every span a spring,
    its springs')."""
    rho = system.belt.elements.rho
    if rho.size:
        return float(np.max(rho))
    return float(system.springs.rho) if system.springs is not None else 0.0


def drive_centrifugal_tension(system: "System", speed, mean_tension):
    """c = rho v^2 lambda(T) (N) of a drive at belt speed v (m/s; a float or (B,) of times), lambda the
    stretch at its mean tension T (N, the same shape as v): the value `required_friction` takes."""
    speed = np.asarray(speed, dtype=float)
    if not speed.any():
        return np.zeros(speed.shape)[()]
    stretch = stretch_for_tension if system.wraps is None else system.wraps.stretch  # (the belt's bar law)
    lam = stretch(np.asarray(mean_tension, dtype=float), system.EA)
    return centrifugal_tension(belt_density(system), speed, lam)


def required_friction(span_tension: np.ndarray, wrap: np.ndarray, centrifugal=0.0) -> np.ndarray:
    """mu_required (..., n) = ln((T_tight - c) / (T_slack - c)) / wrap, c = centrifugal (N: a float, or
    an array (...) of the states' leading shape, `centrifugal_tension`; 0 at rest): inf where a span
    is slack (T_slack <= c, or its tension NaN), 0 where the pulley's two span tensions are equal to
    round-off (module docstring, `ROUND_OFF`)."""
    t_in, t_out = pulley_tensions(span_tension)
    scale = np.maximum(np.abs(t_in), np.abs(t_out))  # (the span tensions' own scale: round-off is of them)
    equal = np.abs(t_in - t_out) <= ROUND_OFF * scale
    c = np.asarray(centrifugal, dtype=float)
    if c.any():
        c = c[..., None]  # (one value per state, the same for its pulleys)
        t_in, t_out = t_in - c, t_out - c
    tight, slack = np.maximum(t_in, t_out), np.minimum(t_in, t_out)
    taut = slack > 0.0
    # (the ratio is 1 where slack or equal: no log of a non-positive number; wrap > 0)
    ratio = np.where(taut & ~equal, tight / np.where(taut, slack, 1.0), 1.0)
    return np.where(taut, np.log(ratio) / wrap, np.inf)


def slip_margin(mu_required: np.ndarray, friction: np.ndarray) -> np.ndarray:
    """friction / mu_required (..., n): inf where no ratio is needed, 0 where slack, NaN without friction."""
    f = np.asarray(friction, dtype=float)
    needed = mu_required > 0.0
    m = np.where(needed, f / np.where(needed, mu_required, 1.0), np.inf)  # (no division by 0: mu_required >= 0)
    m = np.where(mu_required == np.inf, 0.0, m)
    return np.where(f != f, np.nan, m)
