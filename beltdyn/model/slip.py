"""Slip margins of the pulleys: the Euler-Eytelwein (capstan) limit on each wrap.

A belt on a pulley of wrap angle beta transmits the tension ratio T_tight / T_slack without slipping
as long as  ln(T_tight / T_slack) <= mu beta,  mu the effective belt-pulley friction coefficient (for
a V-ribbed belt the wedge-effective value mu / sin(half groove angle), as the user gives it). So

    mu_required = ln(T_tight / T_slack) / beta,     margin = mu / mu_required,

with T_tight and T_slack the larger and smaller of the tensions in the two spans at the pulley (the
end of the arriving span, the start of the departing one) and beta the loaded wrap angle (the
geometry at the solved pulley positions). margin > 1: no slip; margin < 1: the pulley slips. A slack
span (tension <= 0) gives mu_required = inf and margin 0; equal tensions mu_required = 0 and margin
inf. Pulleys without a friction value get NaN margins. Once the running belt is modelled the
tensions are reduced by the centrifugal part rho v^2 before the ratio is taken.
"""

from __future__ import annotations

import math

import numpy as np


def pulley_tensions(span_tension: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T_in, T_out) (..., n): the tension of the span arriving at each pulley (its end) and of the
    span leaving it (its start), from span_tension (..., n_span, 2) (span s runs pulley s -> s + 1)."""
    t_end = span_tension[..., 1]
    return np.concatenate((t_end[..., -1:], t_end[..., :-1]), axis=-1), span_tension[..., 0]


def required_friction(span_tension: np.ndarray, wrap: np.ndarray, centrifugal: float = 0.0) -> np.ndarray:
    """mu_required (..., n) = ln(T_tight / T_slack) / wrap, inf where a span is slack."""
    if span_tension.ndim == 2 and not centrifugal:  # one state: on Python floats (a few pulleys)
        return np.array(_required_one(span_tension.tolist(), np.asarray(wrap, dtype=float).tolist()))
    t_in, t_out = pulley_tensions(span_tension)
    if centrifugal:
        t_in, t_out = t_in - centrifugal, t_out - centrifugal
    tight, slack = np.maximum(t_in, t_out), np.minimum(t_in, t_out)
    taut = slack > 0.0
    if taut.all():
        return np.log(tight / slack) / wrap
    # (the ratio is 1 where slack: no log of a non-positive number; wrap > 0)
    return np.where(taut, np.log(np.where(taut, tight / np.where(taut, slack, 1.0), 1.0)) / wrap, np.inf)


def _required_one(span_tension: list, wrap: list) -> list:
    """`required_friction` of one state: span_tension (n_span, 2) and wrap (n,) as lists."""
    out = []
    arriving = span_tension[-1][1]
    for (leaving, end), beta in zip(span_tension, wrap):
        tight, slack = (arriving, leaving) if arriving >= leaving else (leaving, arriving)
        out.append(math.log(tight / slack) / beta if slack > 0.0 and tight == tight else math.inf)
        arriving = end
    return out


def slip_margin(mu_required: np.ndarray, friction: np.ndarray) -> np.ndarray:
    """friction / mu_required (..., n): inf where no ratio is needed, 0 where slack, NaN without friction."""
    if mu_required.ndim == 1:  # one state: on Python floats (a few pulleys)
        return np.array([math.nan if f != f else (0.0 if mu == math.inf else (f / mu if mu > 0.0 else math.inf))
                         for mu, f in zip(mu_required.tolist(), np.asarray(friction, dtype=float).tolist())])
    f = np.asarray(friction, dtype=float)
    needed = mu_required > 0.0
    m = np.where(needed, f / np.where(needed, mu_required, 1.0), np.inf)  # (no division by 0: mu_required >= 0)
    m[mu_required == np.inf] = 0.0
    return np.where(f != f, np.nan, m)
