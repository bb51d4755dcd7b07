"""Order tracking: the orders of a transient's histories against a reference pulley's angle.

Pure functions on histories (no model). Nomenclature:
    t (m,) s          the history's times; theta (m,) rad the reference pulley's angle at them (turning
                      one way: its sense is taken as positive)
    x (m, c)          the histories (c channels: the trailing axes of every series flattened)
    n                 samples per revolution of the angle grid; R revolutions per window (N = n R samples)
    k                 an order (cycles per revolution of the reference; k R must be whole: the window
                      holds whole cycles of every order)
    X_k = (2 / N) sum_j x(theta_j) exp(-i k theta_j)   over a window's uniform angle grid theta_j
    amplitude |X_k|, phase arg X_k: x ~ x_0 + sum_k |X_k| cos(k theta + arg X_k)
    Omega             the reference's mean speed over the window (2 pi R / its duration), rad/s
The histories are resampled on the angle grid by cubic splines (t(theta), then x(t)): a harmonic of a
whole order is exact over the window at constant speed (the grid's exponentials are orthogonal); while
the speed changes the window's mean order content is measured (its amplitude is the window's, so a
run-up's windows must be short against the speed change: a few revolutions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline


@dataclass(frozen=True, kw_only=True)
class OrderTracking:
    """Order amplitudes of c channels in w windows of whole revolutions of the reference."""

    speed: np.ndarray  # (w,) rad/s, the reference's mean speed over each window (Omega)
    time: np.ndarray  # (w,) s, the middle of each window
    orders: np.ndarray  # (o,) orders (cycles per revolution of the reference)
    amplitude: np.ndarray  # (w, o, c) |X_k|, the channels' units
    phase: np.ndarray  # (w, o, c) rad, arg X_k: the harmonic |X_k| cos(k theta + phase), theta from the first sample


def check_orders(orders: np.ndarray, revolutions: int, samples: int) -> None:
    """ValueError unless every order is positive, whole per window (k R integral) and below the angle grid's
    Nyquist order n / 2."""
    kr = np.asarray(orders, dtype=float) * revolutions
    if np.any(kr <= 0) or np.any(np.abs(kr - np.round(kr)) > 1e-9):
        raise ValueError(f"orders must be positive multiples of 1/{revolutions} (whole cycles per window of "
                         f"{revolutions} revolutions)")
    if np.any(np.asarray(orders) >= samples / 2):
        raise ValueError(f"orders must stay below {samples / 2:g} (half the {samples} samples per revolution)")


def resample_by_angle(time: np.ndarray, angle: np.ndarray, values: np.ndarray,
                      samples: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The histories on a uniform grid of the reference's angle: (theta_j (N + 1,) rad from the first sample,
    t_j (N + 1,) s, x (N + 1, c)), n = samples per revolution, the grid covering the whole revolutions turned
    (N = n turns) and closing the last.
    time (m,), angle (m,) turning one way (else ValueError), values (m, c)."""
    theta = np.asarray(angle, dtype=float) - float(angle[0])
    if theta[-1] < 0:
        theta = -theta
    if not np.all(np.diff(theta) > 0):
        raise ValueError("the reference pulley must turn one way throughout the history")
    turns = int(np.floor(theta[-1] / (2 * np.pi) + 1e-12))
    grid = np.arange(turns * samples + 1) * (2 * np.pi / samples)  # with the closing point of the last turn
    t_at = CubicSpline(theta, time)(grid)
    x = CubicSpline(time, values, axis=0)(t_at)
    return grid, t_at, x


def order_tracking(time: np.ndarray, angle: np.ndarray, values: np.ndarray, orders, *, revolutions: int = 2,
                   samples: int = 64) -> OrderTracking:
    """Order amplitudes and phases per window of `revolutions` whole revolutions of the reference (module
    docstring). time (m,) s, angle (m,) rad of the reference, values (m, c) or (m,), orders (o,); samples
    per revolution n. ValueError for orders the windows cannot resolve or fewer turns than one window."""
    orders = np.atleast_1d(np.asarray(orders, dtype=float))
    check_orders(orders, revolutions, samples)
    values = np.asarray(values, dtype=float)
    x2 = values.reshape(values.shape[0], -1)
    grid, t_at, x = resample_by_angle(np.asarray(time, dtype=float), angle, x2, samples)
    N = revolutions * samples
    w = (grid.size - 1) // N
    if w == 0:
        raise ValueError(f"the history turns the reference less than one window ({revolutions} revolutions)")
    xw = x[: w * N].reshape(w, N, -1)
    basis = np.exp(-1j * orders[:, None] * grid[None, :N])  # (o, N): the same in every window (whole cycles)
    X = (2.0 / N) * np.einsum("on,wnc->woc", basis, xw)
    edges = t_at[:: N][: w + 1]  # (w + 1,) s: the windows' first samples and the last one's closing point
    dt = np.diff(edges)
    return OrderTracking(speed=2 * np.pi * revolutions / dt, time=edges[:-1] + 0.5 * dt, orders=orders,
                         amplitude=np.abs(X), phase=np.angle(X))
