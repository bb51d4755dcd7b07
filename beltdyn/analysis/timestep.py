"""The time step's frequency error: generalized-alpha (Chung and Hulbert 1993) on x'' + w^2 x = 0.

One step of the method (the stepper's alpha_m, alpha_f, beta, gamma for spectral radius rho_inf, see
`alpha_parameters`, which the stepper imports) maps (x, h v, h^2 a) linearly: with Omega = w h,

    (1 - alpha_m) a1 + alpha_m a0 + w^2 ((1 - alpha_f) x1 + alpha_f x0) = 0,
    x1 = x0 + h v0 + h^2 ((1/2 - beta) a0 + beta a1),   v1 = v0 + h ((1 - gamma) a0 + gamma a1),

    alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 - alpha_m + alpha_f,
    beta = (1 - alpha_m + alpha_f)^2 / 4.

Its amplification matrix A(Omega) (`amplification`) has a principal complex pair
lambda = r e^(+-i Omega_h), r <= 1 the numerical decay per step (the third, spurious root is real):
the discrete free vibration runs at the frequency Omega_h / h instead of w. The relative frequency
error

    e(Omega) = Omega_h / Omega - 1      (negative: the method's frequencies are low, its periods long;
                                         the period error is 1/(1 + e) - 1 = -e + O(e^2))

is computed exactly from the eigenvalues (`frequency_error`). Its series (the principal root's
logarithm expanded in Omega, order by order in the characteristic polynomial det(A - lambda I) = 0):

    e = -c Omega^2 + d Omega^4 + O(Omega^6),
    c(rho) = (11 rho^2 - 14 rho + 11) / (24 (1 + rho)^2) = 1/12 + (3/8) ((1 - rho)/(1 + rho))^2,
    d(rho) = (683 rho^4 - 2428 rho^3 + 3618 rho^2 - 2428 rho + 683) / (640 (1 + rho)^4),

with c = 1/12, d = 1/80 at rho = 1, the trapezoidal rule's e = 2 atan(Omega/2)/Omega - 1
(`series_coefficients`; the decay per step is ln r = -(1 - rho)^3 / (2 (1 + rho)^3) Omega^4 + ...).
At dt = 1e-4 s and rho_inf = 0.9, e is -0.120 % at 190 Hz and -0.298 % at 300 Hz.

|e| grows monotonically with Omega for every rho_inf in [0, 1] (the pair stays complex and its
phase Omega_h stays below pi; checked on a grid by the tests), so `step_for_accuracy` inverts it by
bracketing: the longest step whose |e| stays below an accuracy for every frequency up to fmax is
Omega*(accuracy, rho_inf) / (2 pi fmax), and a step h resolves frequencies up to
`resolved_band` = Omega* / (2 pi h).

`resolve_step` decides the step a transient runs with (see `TransientOptions` in config.py): a step
given on the command line (--step) is used as given; otherwise, with transient.accuracy and
transient.fmax, the step they ask for, or transient.step if that is given and shorter (an upper
bound); otherwise transient.step (default 1e-4 s).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from beltdyn.config import TransientOptions

TWO_PI = 2.0 * math.pi
DEFAULT_ACCURACY = 1e-3  # the frequency error the console reports the resolved band at, when none is asked


def alpha_parameters(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, beta, gamma) of Chung and Hulbert for spectral radius rho_inf in [0, 1]."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - am + af
    beta = 0.25 * (1.0 - am + af) ** 2
    return am, af, beta, gamma


def amplification(omega_h, rho_inf: float) -> np.ndarray:
    """A (..., 3, 3): (x1, h v1, h^2 a1) = A (x0, h v0, h^2 a0) for Omega = omega h (scalar or array)."""
    am, af, beta, gamma = alpha_parameters(rho_inf)
    W2 = np.asarray(omega_h, dtype=float) ** 2
    A = np.empty(W2.shape + (3, 3))
    den = (1.0 - am) + W2 * (1.0 - af) * beta
    for j, (x0, v0, a0) in enumerate(np.eye(3)):  # scaled: v ~ h v, a ~ h^2 a
        # (1 - am) a1 + am a0 + W2 ((1 - af)(x0 + v0 + (1/2 - beta) a0 + beta a1) + af x0) = 0
        a1 = -(am * a0 + W2 * ((1.0 - af) * (x0 + v0 + (0.5 - beta) * a0) + af * x0)) / den
        A[..., 0, j] = x0 + v0 + (0.5 - beta) * a0 + beta * a1
        A[..., 1, j] = v0 + (1.0 - gamma) * a0 + gamma * a1
        A[..., 2, j] = a1
    return A


def characteristic_coefficients(omega_h, rho_inf: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(L3, L2, L1, L0): det(A - lambda I) = 0 written in mu = lambda - 1, free of cancellation.

    Seeking (x, h v, h^2 a)_n = lambda^n (X, V, Acc) in the step's equations (module docstring) and
    eliminating X and V gives, with W = Omega^2,

        (1 + (1 - alpha_m) mu) mu^2 + W (1 + (1 - alpha_f) mu) (1 + (gamma + 1/2) mu + beta mu^2) = 0,

    i.e. L3 mu^3 + L2 mu^2 + L1 mu + L0 = 0 with L3 = (1 - alpha_m) + W (1 - alpha_f) beta,
    L2 = 1 + W (beta + (1 - alpha_f)(gamma + 1/2)), L1 = W (2 - alpha_m), L0 = W: sums of positive
    terms, so each coefficient is accurate to round-off (the eigenvalues of A lose ~eps/Omega near
    lambda = 1, where the principal pair meets)."""
    am, af, beta, gamma = alpha_parameters(rho_inf)
    W = np.asarray(omega_h, dtype=float) ** 2
    L3 = (1.0 - am) + W * ((1.0 - af) * beta)
    L2 = 1.0 + W * (beta + (1.0 - af) * (gamma + 0.5))
    L1 = W * (gamma + 1.5 - af)
    return L3, L2, L1, W


def _error_of_omega(Om: np.ndarray, rho_inf: float) -> np.ndarray:
    """e(Omega) for an array of Omega = 2 pi f h (NaN where no complex pair is left).

    The cubic in mu = lambda - 1 (`characteristic_coefficients`), monic: mu^3 + c2 mu^2 + c1 mu + c0.
    Its real (spurious) root mu3 from the companion matrix, polished by Newton to round-off; deflated,
    mu^2 + a mu + b with b = -c0/mu3, a = c2 + mu3; the principal pair mu = -a/2 +- i sqrt(b - a^2/4),
    so Omega_h = atan2(sqrt(b - a^2/4), 1 - a/2) to a few ulps relative and e = Omega_h/Omega - 1 to
    a few ulps absolute (~1e-12 relative at e = 1e-4)."""
    Om = np.asarray(Om, dtype=float)
    out = np.zeros(Om.shape)
    pos = Om > 0.0
    if not np.any(pos):
        return out
    L3, L2, L1, L0 = characteristic_coefficients(Om[pos], rho_inf)
    c2, c1, c0 = L2 / L3, L1 / L3, L0 / L3
    companion = np.zeros(c0.shape + (3, 3))
    companion[:, 0, :] = -np.stack([c2, c1, c0], axis=-1)
    companion[:, 1, 0] = 1.0
    companion[:, 2, 1] = 1.0
    roots = np.linalg.eigvals(companion)  # (k, 3)
    real = np.take_along_axis(roots, np.argmin(np.abs(roots.imag), axis=-1)[:, None], axis=-1)[:, 0].real
    for _ in range(4):  # Newton on a simple, well separated root: round-off in two or three steps
        value = ((real + c2) * real + c1) * real + c0
        slope = (3.0 * real + 2.0 * c2) * real + c1
        real = real - np.where(slope != 0.0, value / np.where(slope != 0.0, slope, 1.0), 0.0)
    b = -c0 / real
    a = c2 + real
    disc = b - 0.25 * a * a
    with np.errstate(invalid="ignore"):
        phase = np.arctan2(np.sqrt(np.where(disc > 0.0, disc, 0.0)), 1.0 - 0.5 * a)
    out[pos] = np.where(disc > 0.0, phase / Om[pos] - 1.0, np.nan)
    return out


def frequency_error(frequency, step: float, rho_inf: float):
    """Relative frequency error (discrete / exact - 1, negative: low) of a free oscillation at
    `frequency` (Hz, scalar or array) integrated with `step` (s); exact, from the eigenvalues of the
    amplification matrix. NaN where the method no longer oscillates (not met for rho_inf in [0, 1])."""
    f = np.asarray(frequency, dtype=float)
    out = _error_of_omega(TWO_PI * f * step, rho_inf)
    return out if f.ndim else float(out)


def series_coefficients(rho_inf: float) -> tuple[float, float]:
    """(c, d) in e = -c Omega^2 + d Omega^4 + O(Omega^6) (see the module docstring)."""
    r = rho_inf
    c = (11.0 * r * r - 14.0 * r + 11.0) / (24.0 * (1.0 + r) ** 2)
    d = (683.0 * r ** 4 - 2428.0 * r ** 3 + 3618.0 * r ** 2 - 2428.0 * r + 683.0) / (640.0 * (1.0 + r) ** 4)
    return c, d


def series_coefficient(rho_inf: float) -> float:
    """c in e = -c Omega^2 + O(Omega^4): the leading-order frequency error per (2 pi f dt)^2."""
    return series_coefficients(rho_inf)[0]


def critical_omega(accuracy: float, rho_inf: float) -> float:
    """Omega* = 2 pi f h at which |e| reaches `accuracy` (0 < accuracy < 1)."""
    if not 0.0 < accuracy < 1.0:
        raise ValueError(f"accuracy must be in (0, 1), got {accuracy!r}")

    def excess(Om: float) -> float:
        e = float(_error_of_omega(np.array(Om), rho_inf))
        return (abs(e) if np.isfinite(e) else 1.0) - accuracy

    # start from the series' estimate and bracket: |e| grows with Omega (and tends to 1)
    hi = min(math.sqrt(accuracy / series_coefficient(rho_inf)), 1.0)
    lo = 0.0
    while excess(hi) < 0.0:
        lo, hi = hi, 2.0 * hi
        if hi > 1e6:
            raise ValueError(f"no step reaches the frequency error {accuracy!r}")
    return _root(excess, lo, hi)


def _root(f, lo: float, hi: float) -> float:
    """The root of f in [lo, hi] (f(lo) < 0 <= f(hi)) to a few ulps: regula falsi (Illinois), with a
    bisection whenever an interval fails to halve. scipy.optimize would cost the transient command
    ~0.15 s of imports for this one root."""
    f_lo, f_hi = f(lo), f(hi)
    side = 0
    while hi - lo > 4.0 * np.finfo(float).eps * hi + 1e-300:
        width = hi - lo
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx == 0.0:
            return x
        if fx < 0.0:
            lo, f_lo = x, fx
            if side == -1:
                f_hi *= 0.5  # Illinois: the end kept twice in a row counts half
            side = -1
        else:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        if hi - lo > 0.5 * width:  # too slow: bisect
            mid = 0.5 * (lo + hi)
            fm = f(mid)
            if fm < 0.0:
                lo, f_lo = mid, fm
            else:
                hi, f_hi = mid, fm
    return 0.5 * (lo + hi)


def step_for_accuracy(fmax: float, accuracy: float, rho_inf: float) -> float:
    """The longest step (s) with |frequency error| <= accuracy for every frequency up to fmax (Hz)."""
    return critical_omega(accuracy, rho_inf) / (TWO_PI * fmax)


def resolved_band(step: float, accuracy: float, rho_inf: float) -> float:
    """The highest frequency (Hz) a step resolves with |frequency error| <= accuracy."""
    return critical_omega(accuracy, rho_inf) / (TWO_PI * step)


STEP_ORIGINS = ("config", "accuracy", "--step")


def resolve_step(t: "TransientOptions", manual: float | None = None) -> tuple["TransientOptions", str]:
    """(options with `step` set, origin): the step a transient runs with.

    - manual (the command line's --step): that step, origin "--step" (a step that misses
      transient.accuracy is marked in the run's warnings, `transient.accuracy_warnings`);
    - transient.accuracy and transient.fmax given: the longest step that meets them, origin
      "accuracy"; if transient.step is given too it is an upper bound: when it is shorter it is kept,
      origin "config" (it meets the accuracy with room to spare);
    - otherwise transient.step (default 1e-4 s), origin "config".
    A step below transient.min_step is refused (ConfigError)."""
    if manual is not None:
        h, origin = float(manual), "--step"
    elif t.accuracy is not None and t.fmax is not None:
        h, origin = step_for_accuracy(t.fmax, t.accuracy, t.rho_inf), "accuracy"
        if t.step is not None and t.step < h:
            h, origin = t.step, "config"
    else:
        h, origin = t.step, "config"  # TransientOptions fills in the default
    if h < t.min_step:
        from beltdyn.errors import ConfigError

        key = "transient.accuracy" if origin == "accuracy" else "transient.step"
        raise ConfigError(f"the step {h:.4g} s ({origin}) is below transient.min_step = {t.min_step:g} s", key=key)
    return replace(t, step=h), origin


def describe(step: float, *, accuracy: float | None, fmax: float | None,
             rho_inf: float) -> tuple[str, float, float]:
    """A sentence on the band a step resolves, the band (Hz) and the accuracy it is quoted at
    (transient.accuracy, or DEFAULT_ACCURACY when none is given)."""
    acc = accuracy if accuracy is not None else DEFAULT_ACCURACY
    band = resolved_band(step, acc, rho_inf)
    text = (f"step {step:.4g} s: frequency error <= {acc:.3g} up to {band:.4g} Hz (generalized-alpha, "
            f"rho_inf = {rho_inf:g}; error ~ -{series_coefficient(rho_inf):.4f} (2 pi f dt)^2)")
    if fmax is not None:
        text += f"; {frequency_error(fmax, step, rho_inf):+.3%} at fmax = {fmax:g} Hz"
    return text, band, acc


STEP_PER_PERIOD = 0.1  # the longest step, as a share of the period, that resolves a motion (about 1 % in frequency)


def step_warnings(step: float, *, excitation_frequency: float | None = None,
                  mode_frequency: float | None = None, mode_source: str = "") -> tuple[str, ...]:
    """What a step does not resolve: a step longer than a tenth of the period of the excitation
    (Hz), or of the highest mode the run is meant to resolve (`mode_frequency`, Hz; `mode_source`
    says where it comes from: transient.fmax, or the highest mode computed). At a tenth of the
    period the generalized-alpha frequency error is about 0.8 % (e = -c (2 pi f h)^2, c ~ 0.08);
    longer steps lose the motion."""
    out = []
    if excitation_frequency and step > STEP_PER_PERIOD / excitation_frequency:
        out.append(f"the step {step:g} s exceeds a tenth of the excitation period "
                   f"({1.0 / excitation_frequency:.4g} s at {excitation_frequency:g} Hz): the response is not "
                   f"resolved; use transient.step <= {STEP_PER_PERIOD / excitation_frequency:.3g} s")
    if mode_frequency and step > STEP_PER_PERIOD / mode_frequency:
        out.append(f"the step {step:g} s exceeds a tenth of the period of the highest mode the run is meant to "
                   f"resolve ({1.0 / mode_frequency:.4g} s at {mode_frequency:.6g} Hz, {mode_source}): no motion above "
                   f"{STEP_PER_PERIOD / step:.4g} Hz is resolved; use transient.step <= "
                   f"{STEP_PER_PERIOD / mode_frequency:.3g} s, or transient.accuracy and transient.fmax")
    return tuple(out)


RESOLVE_ACCURACY = 0.1  # the frequency error (10 %) up to which a step is said to resolve a motion at all


def unresolved_motion(step: float, *, duration: float, rho_inf: float, excitation_frequency: float | None = None,
                      lowest_frequency: float | None = None, fmax: float | None = None,
                      accuracy: float | None = None) -> str | None:
    """Why a step resolves nothing of a run, or None: a step longer than the duration, or one whose
    band at a 10 % frequency error (`resolved_band` at RESOLVE_ACCURACY) lies below the excitation
    frequency (Hz) or the lowest non-rigid natural frequency (Hz). The sentence ends with the step
    that resolves fmax (transient.fmax, else the frequency missed) to the accuracy (transient.accuracy,
    else DEFAULT_ACCURACY)."""
    if step > duration:
        why = f"the step {step:g} s is longer than the duration {duration:g} s: not one step of the motion is resolved"
        target = max(f for f in (excitation_frequency, lowest_frequency, 1.0 / duration) if f)
    else:
        band = resolved_band(step, RESOLVE_ACCURACY, rho_inf)
        missed = [(f, what) for f, what in ((lowest_frequency, "the lowest natural frequency"),
                                            (excitation_frequency, "the excitation frequency")) if f and band < f]
        if not missed:
            return None
        f, what = min(missed)
        why = (f"the step {step:g} s resolves motion only up to {band:.4g} Hz (frequency error "
               f"{RESOLVE_ACCURACY:.0%}), below {what} {f:.6g} Hz: it resolves no mode of the model")
        target = max(f for f, _ in missed)
    target = fmax if fmax is not None else target
    acc = accuracy if accuracy is not None else DEFAULT_ACCURACY
    return f"{why}; the step {step_for_accuracy(target, acc, rho_inf):.3g} s resolves {target:.6g} Hz to {acc:g}"
