"""Angles as directions: one full turn, the branch nearest a reference, the direction of a point
seen from a pivot (rad, counter-clockwise from +x)."""

from __future__ import annotations

import math

TWO_PI = 2.0 * math.pi


def wrap_angle(angle):
    """angle wrapped to [-pi, pi) (a float or an array, elementwise): a turn as a direction change."""
    return (angle + math.pi) % TWO_PI - math.pi


def unwrap_near(angle: float, ref: float) -> float:
    """angle + 2 pi k, the one nearest to ref."""
    return float(angle + TWO_PI * round((ref - angle) / TWO_PI))


def pivot_angle(point, pivot) -> float:
    """The angle (rad, counter-clockwise from +x) of pivot -> point, both (2,)."""
    (x, y), (px, py) = point, pivot
    return math.atan2(float(y) - float(py), float(x) - float(px))
