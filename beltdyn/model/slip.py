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
margin inf. Pulleys without a friction value get NaN margins. Once the running belt is modelled the
tensions are reduced by the centrifugal part rho v^2 before the ratio is taken.
"""

from __future__ import annotations

import numpy as np


def pulley_tensions(span_tension: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T_in, T_out) (..., n): the tension of the span arriving at each pulley (its end) and of the
    span leaving it (its start), from span_tension (..., n_span, 2) (span s runs pulley s -> s + 1)."""
    t_end = span_tension[..., 1]
    return np.concatenate((t_end[..., -1:], t_end[..., :-1]), axis=-1), span_tension[..., 0]


# |T_in - T_out| <= ROUND_OFF max(|T_in|, |T_out|): no torque demand (equal tensions to round-off)
ROUND_OFF = 1e-9


def required_friction(span_tension: np.ndarray, wrap: np.ndarray, centrifugal: float = 0.0) -> np.ndarray:
    """mu_required (..., n) = ln(T_tight / T_slack) / wrap: inf where a span is slack (or its tension NaN),
    0 where the pulley's two span tensions are equal to round-off (module docstring, `ROUND_OFF`)."""
    t_in, t_out = pulley_tensions(span_tension)
    scale = np.maximum(np.abs(t_in), np.abs(t_out))  # (the span tensions' own scale: round-off is of them)
    equal = np.abs(t_in - t_out) <= ROUND_OFF * scale
    if centrifugal:
        t_in, t_out = t_in - centrifugal, t_out - centrifugal
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
