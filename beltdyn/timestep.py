"""The time step's frequency error: generalized-alpha (Chung and Hulbert 1993) on x'' + w^2 x = 0.

One step of the method (the stepper's alpha_m, alpha_f, beta, gamma for spectral radius rho_inf, see
`alpha_parameters`, which the stepper imports) maps (x, h v, h^2 a) linearly: with Omega = w h,

    (1 - alpha_m) a1 + alpha_m a0 + w^2 ((1 - alpha_f) x1 + alpha_f x0) = 0,
    x1 = x0 + h v0 + h^2 ((1/2 - beta) a0 + beta a1),   v1 = v0 + h ((1 - gamma) a0 + gamma a1).

Its amplification matrix A(Omega) has a principal complex pair rho e^(+-i Omega_h) (the spurious root
is real): the discrete oscillation runs at the frequency Omega_h / h instead of w. The relative
frequency error

    e(Omega) = Omega_h / Omega - 1      (negative: the transient's peaks sit low, periods grow)

is computed exactly from the eigenvalues. For small Omega, e = -c Omega^2 + O(Omega^4) with
c = 1/12 for rho_inf = 1 (the trapezoidal rule's period elongation); `series_coefficient` gives c for
any rho_inf from the exact form at small Omega. At dt = 1e-4 s (rho_inf 0.9) e is -0.12 % at 190 Hz
and -0.29 % at 300 Hz. `step_for_accuracy` inverts it: the longest step whose |e| stays below an
accuracy for every frequency up to fmax (|e| grows monotonically with Omega over the band where the
pair stays complex, checked by the tests).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi


def alpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, beta, gamma) of Chung and Hulbert for spectral radius rho_inf in [0, 1]."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - am + af
    beta = 0.25 * (1.0 - am + af) ** 2
    return am, af, beta, gamma


def amplification(omega_h: float, rho_inf: float) -> np.ndarray:
    """A (3, 3): (x1, h v1, h^2 a1) = A (x0, h v0, h^2 a0) for Omega = omega h."""
    am, af, beta, gamma = alpha_parameters(rho_inf)
    W2 = omega_h * omega_h
    A = np.empty((3, 3))
    for j, (x0, v0, a0) in enumerate(np.eye(3)):  # scaled: v ~ h v, a ~ h^2 a
        # (1 - am) a1 + am a0 + W2 ((1 - af)(x0 + v0 + (1/2 - beta) a0 + beta a1) + af x0) = 0
        a1 = -(am * a0 + W2 * ((1.0 - af) * (x0 + v0 + (0.5 - beta) * a0) + af * x0)) / \
            ((1.0 - am) + W2 * (1.0 - af) * beta)
        A[0, j] = x0 + v0 + (0.5 - beta) * a0 + beta * a1
        A[1, j] = v0 + (1.0 - gamma) * a0 + gamma * a1
        A[2, j] = a1
    return A


def frequency_error(frequency, step: float, rho_inf: float):
    """Relative frequency error (discrete / exact - 1) of an oscillation at `frequency` (Hz, scalar or
    array) integrated with `step` (s); NaN where the method no longer oscillates (Omega too large)."""
    f = np.asarray(frequency, dtype=float)
    out = np.empty(f.shape)
    for i, fi in np.ndenumerate(f):
        Om = TWO_PI * fi * step
        if Om == 0.0:
            out[i] = 0.0
            continue
        lam = np.linalg.eigvals(amplification(Om, rho_inf))
        cplx = lam[np.abs(lam.imag) > 1e-14 * np.abs(lam).max()]
        out[i] = float(np.abs(np.angle(cplx)).max()) / Om - 1.0 if cplx.size else np.nan
    return out if f.ndim else float(out)


def series_coefficient(rho_inf: float) -> float:
    """c in e = -c Omega^2 + O(Omega^4) (from the exact error at Omega = 1e-2)."""
    Om = 1e-2
    return -frequency_error(Om / (TWO_PI * 1.0), 1.0, rho_inf) / (Om * Om)


def step_for_accuracy(fmax: float, accuracy: float, rho_inf: float) -> float:
    """The longest step (s) with |frequency error| <= accuracy for every frequency up to fmax (Hz)."""
    from scipy.optimize import brentq

    def excess(Om: float) -> float:
        e = frequency_error(Om / TWO_PI, 1.0, rho_inf)
        return (abs(e) if np.isfinite(e) else 1.0) - accuracy

    lo, hi = 1e-6, 0.5
    while excess(hi) < 0.0 and hi < 3.0:
        lo, hi = hi, 2.0 * hi
    Om = brentq(excess, lo, hi, xtol=1e-14, rtol=1e-12)
    return Om / (TWO_PI * fmax)


def resolved_band(step: float, accuracy: float, rho_inf: float) -> float:
    """The highest frequency (Hz) a step resolves with |frequency error| <= accuracy."""
    return step_for_accuracy(1.0, accuracy, rho_inf) / step


DEFAULT_ACCURACY = 1e-3  # the frequency error the console reports the resolved band at, when none is asked


def choose_step(step: float, *, accuracy: float | None, fmax: float | None, rho_inf: float,
                manual: bool) -> tuple[float, str]:
    """(step, origin): a step given on the command line (manual) wins ("--step"); otherwise, with
    transient.accuracy and transient.fmax, the longest step that meets them ("accuracy"); otherwise
    transient.step ("config")."""
    if manual:
        return step, "--step"
    if accuracy is not None and fmax is not None:
        return step_for_accuracy(fmax, accuracy, rho_inf), "accuracy"
    return step, "config"


def describe(step: float, *, accuracy: float | None, fmax: float | None, rho_inf: float) -> tuple[str, float, float]:
    """A sentence on what the step resolves, the band (Hz) and the accuracy it is quoted at."""
    acc = accuracy if accuracy is not None else DEFAULT_ACCURACY
    band = resolved_band(step, acc, rho_inf)
    text = (f"step {step:.4g} s resolves frequencies up to {band:.4g} Hz within {acc:.3g} (generalized-alpha, "
            f"rho_inf = {rho_inf:g}; the error grows as {series_coefficient(rho_inf):.4f} (2 pi f dt)^2)")
    if fmax is not None:
        text += f"; at fmax = {fmax:g} Hz the frequency error is {frequency_error(fmax, step, rho_inf):+.3g}"
    return text, band, acc
