"""Amplitude spectra of transient histories and their dominant peaks.

The transient analysis records histories at a uniform output interval with the time axis first:
span tensions (n_t, n_span, 2), hub loads (n_t, n_pulley, 2), mid-span transverse displacement
(n_t, n_span), pulley speeds (n_t, n_pulley), ...  `amplitude_spectrum` turns any of them into a
single-sided amplitude spectrum (n_f, *channel_shape) in the signal's own units, `find_peaks` lists
the dominant peaks over all channels with their relation to the excitation frequency (harmonic
number) and to the natural frequencies (nearest mode), and `harmonic_content` reads the amplitude
at the first harmonics of the excitation.

Scaling
-------
The record (after `start`, mean removed by default) is multiplied by a DFT-even (periodic) window
w of its own length N and transformed with a real FFT along axis 0.  Bins 0 < k < N/2 are scaled by
2 / sum(w), the DC bin and (N even) the Nyquist bin by 1 / sum(w).  A sinusoid of amplitude A whose
frequency falls on a bin therefore shows a peak of height A (coherent-gain correction), and with the
rectangular window sum(amp[1:-1]**2) / 2 + amp[0]**2 + amp[-1]**2 equals the variance of the record
(Parseval; for N odd the last term is an ordinary bin).  Windows (cosine sums):

* ``"hann"``: 0.5 - 0.5 cos; ENBW 1.5 bins, worst-case scalloping loss 15 % (-1.42 dB) between bins.
* ``"rect"``: no window; ENBW 1 bin, scalloping up to 36 %, slowly decaying leakage.
* ``"flattop"``: HFT116D (Heinzel, Ruediger & Schilling, "Spectrum and spectral density estimation
  by the DFT", 2002); ENBW 4.22 bins, side lobes below -116 dB, amplitude flat within +-0.035 %
  for any frequency between bins: read amplitudes directly, without refinement.

Peak refinement (accuracy)
--------------------------
A peak at bin k with amplitudes a[k-1], a[k], a[k+1] is refined by quadratic (parabolic)
interpolation of the *natural log* of the amplitude: d = (L- - L+) / (2 (L- - 2 L0 + L+)), the
vertex offset in bins.  For a pure tone that estimate is biased, by an amount that depends only on
the window and the true offset: up to 0.016 bin for hann, 0.17 bin for rect and 0.15 bin for
flattop.  The bias is removed by inverting (bracketed regula falsi) the same interpolation applied to the
window's exact kernel (a closed-form sum of Dirichlet kernels): the offset delta in [-1/2, 1/2] whose
noise-free bins give the measured d.  The amplitude is then a[k] divided by the window's normalized
kernel magnitude at delta (scalloping correction).  Measured on noise-free real tones of any phase
and any offset between bins, at least 10 bins from DC and Nyquist (the remaining error is the
leakage of the tone's negative-frequency image, so it shrinks as the tone moves away from them):

* hann:    frequency within 1e-4 bin, amplitude within 1e-4 relative (1e-6 beyond 30 bins);
* flattop: frequency within 1e-4 bin, amplitude within 1e-5 relative;
* rect:    frequency within 0.05 bin, amplitude within 1.5 % (0.015 bin and 0.5 % beyond 30
           bins): its leakage decays only as 1/distance, prefer hann for peak tables.

Additive noise adds its own error (hann, tone-to-noise rms ratio 100 over 2048 samples: ~1e-3
bin), as do other tones within a few main-lobe widths (2 bins hann, 5 bins flattop).  Peaks in
bin 1 or in the last bin are not refined (a neighbour is the DC bin, scaled differently and
altered by the mean removal, or is missing).  All functions raise ValueError naming the problem.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

WINDOWS = ("hann", "rect", "flattop")
DETRENDS = ("mean", "none")
MIN_SAMPLES = 8
UNIFORM_RTOL = 1e-6

# cosine-sum coefficients c_j of w[n] = sum_j (-1)^j c_j cos(2 pi j n / N) (DFT-even)
_COSINE_SUM = {
    "rect": (1.0,),
    "hann": (0.5, 0.5),
    # HFT116D, Heinzel et al. (2002), Table of flat-top windows
    "flattop": (1.0, 1.9575375, 1.4780705, 0.6367431, 0.1228389, 0.0066288),
}
_LOG_FLOOR = 1e-10  # neighbours below this fraction of the peak are taken as numerically zero
_TABLE_POINTS = 257  # vertex table per window and record length (`_refine`)
_SECANT_STEPS = 8  # regula falsi steps from a 1/256-bin bracket (to round-off in 5-6)


@dataclass(frozen=True, kw_only=True)
class Spectrum:
    """Single-sided amplitude spectrum of a uniformly sampled history.

    frequency: (n_f,) Hz, k / (N dt) for k = 0 .. N // 2 (0 .. Nyquist), n_f = N // 2 + 1.
    amplitude: (n_f, *channel_shape) in the signal's units (N, m, rad/s, ...); coherent-gain
        corrected so that a sinusoid of amplitude A on a bin shows a peak of height A (the mean is
        removed first unless detrend="none"; bin 0 is then the residual mean).
    window: one of WINDOWS.
    resolution: Hz, bin spacing 1 / (N dt).
    n_samples: N, samples used (those at or after `start`).
    start_time: s, time of the first sample used.
    """

    frequency: np.ndarray
    amplitude: np.ndarray
    window: str
    resolution: float
    n_samples: int
    start_time: float


@dataclass(frozen=True, kw_only=True)
class Peak:
    """One dominant spectral peak of one channel.

    frequency: Hz, refined (log-parabolic interpolation with the window's bias removed; see the
        module docstring for the accuracy).
    amplitude: refined peak amplitude (signal units), scalloping-corrected.
    channel: channel label, e.g. "span_tension[C-A, start]".
    harmonic: k if frequency is within max(2 bins, 1 % of k f_exc) of k * excitation frequency
        (k >= 1), else 0 (also 0 when no excitation frequency is given).
    nearest_mode: 1-based index into the given modal frequencies of the closest one, 0 if none given.
    mode_frequency: Hz of that mode (nan if none given).
    mode_distance_pct: 100 (f - f_mode) / f_mode (nan if none given).
    """

    frequency: float
    amplitude: float
    channel: str
    harmonic: int
    nearest_mode: int
    mode_frequency: float
    mode_distance_pct: float


# ----------------------------------------------------------------------------------------------
# windows and their kernels


def _window(name: str, n: int) -> np.ndarray:
    """DFT-even (periodic) window of length n."""
    z = 2.0 * np.pi * np.arange(n) / n
    w = np.zeros(n)
    for j, c in enumerate(_COSINE_SUM[name]):
        w += (-1.0) ** j * c * np.cos(j * z)
    return w


def _dirichlet(x: np.ndarray, n: int) -> np.ndarray:
    """sum_{m<n} exp(-2 pi i x m / n) for |x| < n (x in bins)."""
    x = np.asarray(x, dtype=float)
    zero = np.abs(x) < 1e-12
    xs = np.where(zero, 1.0, x)
    d = np.exp(-1j * np.pi * xs * (n - 1) / n) * np.sin(np.pi * xs) / np.sin(np.pi * xs / n)
    return np.where(zero, float(n), d)


def _kernel(name: str, n: int, offset: np.ndarray) -> np.ndarray:
    """|W(offset)| / W(0): normalized magnitude of the window's transform `offset` bins from a tone.
    The Dirichlet kernels at offset and offset -+ j (j = 1 .. terms - 1) are evaluated in one call
    (the peak refinement calls this thousands of times: numpy's per-call cost, not the arithmetic)."""
    coef = _COSINE_SUM[name]
    offset = np.asarray(offset, dtype=float)
    j = np.arange(1, len(coef), dtype=float).reshape((-1,) + (1,) * offset.ndim)
    d = _dirichlet(np.concatenate([offset[None], offset - j, offset + j]), n)  # (2 terms - 1, *offset.shape)
    total = coef[0] * d[0]
    for k in range(1, len(coef)):
        c = (-1.0) ** k * coef[k] / 2.0
        total = total + c * (d[k] + d[k + len(coef) - 1])
    return np.abs(total) / (n * coef[0])


def _log_vertex(lo: np.ndarray, mid: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Vertex offset (bins, clipped to [-1/2, 1/2]) of the parabola through the logs of 3 bins."""
    floor = _LOG_FLOOR * np.maximum(mid, np.finfo(float).tiny)
    y0 = np.log(np.maximum(lo, floor))
    y1 = np.log(np.maximum(mid, floor))
    y2 = np.log(np.maximum(hi, floor))
    den = y0 - 2.0 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.where(den < 0.0, 0.5 * (y0 - y2) / np.where(den < 0.0, den, -1.0), 0.0)
    return np.clip(d, -0.5, 0.5)


def _model_vertex(name: str, n: int, delta: np.ndarray) -> np.ndarray:
    """The log-parabola vertex of a noise-free tone `delta` bins from its bin: |W(delta + 1)|,
    |W(delta)|, |W(delta - 1)| in bins k - 1, k, k + 1 (one kernel call for the three)."""
    return _log_vertex(*_kernel(name, n, np.stack([delta + 1.0, delta, delta - 1.0])))


@functools.lru_cache(maxsize=16)
def _vertex_table(name: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(delta, vertex) on _TABLE_POINTS offsets over [-1/2, 1/2]: the brackets of `_refine`."""
    delta = np.linspace(-0.5, 0.5, _TABLE_POINTS)
    return delta, _model_vertex(name, n, delta)


def _refine(name: str, n: int, lo: np.ndarray, mid: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bias-free offset delta (bins) and scalloping-corrected amplitude for peaks at the `mid` bins.

    A tone at `delta` bins from bin k puts |W(delta + 1)|, |W(delta)|, |W(delta - 1)| in bins
    k - 1, k, k + 1; the log-parabola vertex of those values increases monotonically with delta
    over [-1/2, 1/2], so the measured vertex is matched: bracketed in a table of the window's
    vertices (cached per window and record length), then regula falsi (Illinois) on the exact
    kernel to round-off (_SECANT_STEPS: the bracket starts 1/256 bin wide and converges
    superlinearly; a vertex outside the table's range gives its end, -1/2 or 1/2).
    """
    measured = _log_vertex(lo, mid, hi)
    grid, table = _vertex_table(name, n)
    k = np.clip(np.searchsorted(table, measured), 1, len(grid) - 1)
    a, b = grid[k - 1], grid[k]
    fa, fb = table[k - 1] - measured, table[k] - measured
    x = np.where(fb <= 0.0, b, a)  # (outside the table: its end)
    inside = (fa < 0.0) & (fb > 0.0)
    side = np.zeros(measured.shape, dtype=int)  # the end moved last: -1 a, +1 b (Illinois)
    for _ in range(_SECANT_STEPS if np.any(inside) else 0):
        x = np.where(inside, np.clip(b - fb * (b - a) / np.where(inside, fb - fa, 1.0), a, b), x)
        fx = _model_vertex(name, n, x) - measured
        below = fx < 0.0
        fb = np.where(below & (side == -1), 0.5 * fb, fb)
        fa = np.where(~below & (side == 1), 0.5 * fa, fa)
        a, fa = np.where(below, x, a), np.where(below, fx, fa)
        b, fb = np.where(below, b, x), np.where(below, fb, fx)
        side = np.where(below, -1, 1)
        inside = inside & (fx != 0.0) & (b > a)
    return x, mid / _kernel(name, n, x)


def _refine_at(spec: Spectrum, amp2: np.ndarray, bins: np.ndarray, chans: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Refined (frequency, amplitude) at given bins/channels of the flattened amplitude (n_f, n_ch)."""
    n_f = amp2.shape[0]
    bins = np.asarray(bins, dtype=int)
    chans = np.asarray(chans, dtype=int)
    mid = amp2[bins, chans]
    freq = bins * spec.resolution
    amp = mid.astype(float).copy()
    inner = (bins >= 2) & (bins <= n_f - 2)
    if np.any(inner):
        bi, ci = bins[inner], chans[inner]
        delta, a = _refine(spec.window, spec.n_samples, amp2[bi - 1, ci], amp2[bi, ci], amp2[bi + 1, ci])
        freq = freq.astype(float)
        freq[inner] = (bi + delta) * spec.resolution
        amp[inner] = a
    return freq, amp


# ----------------------------------------------------------------------------------------------
# spectrum


def amplitude_spectrum(
    time: np.ndarray,
    values: np.ndarray,
    *,
    start: float = 0.0,
    window: str = "hann",
    detrend: str = "mean",
) -> Spectrum:
    """Single-sided amplitude spectrum of `values` (n_t, ...) sampled at `time` (n_t,) s.

    Only samples with time >= start are used (at least 8, uniformly spaced within 1e-6 relative,
    all finite).  detrend: "mean" removes each channel's mean, "none" keeps it (it then appears in
    bin 0).  Returns amplitude (n_f, *values.shape[1:]); see the module docstring for the scaling.
    """
    if window not in WINDOWS:
        raise ValueError(f"unknown window {window!r}: expected one of {', '.join(WINDOWS)}")
    if detrend not in DETRENDS:
        raise ValueError(f"unknown detrend {detrend!r}: expected one of {', '.join(DETRENDS)}")
    t = np.asarray(time, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"time must be a 1-D array, got shape {t.shape}")
    v = np.asarray(values)
    if np.iscomplexobj(v):
        raise ValueError("values must be real")
    v = v.astype(float, copy=False)
    if v.ndim < 1 or v.shape[0] != t.shape[0]:
        raise ValueError(f"values must have the time axis first: shape {v.shape} does not start with "
                         f"len(time) = {t.shape[0]}")
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"time contains a non-finite value at index {bad}")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        bad = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"time is not strictly increasing (time[{bad + 1}] = {t[bad + 1]:g} s "
                         f"<= time[{bad}] = {t[bad]:g} s)")
    start = float(start)
    if not np.isfinite(start):
        raise ValueError(f"start must be finite, got {start}")
    step = (t[-1] - t[0]) / (t.size - 1) if t.size > 1 else 0.0
    keep = t >= start - UNIFORM_RTOL * step
    n = int(np.count_nonzero(keep))
    if n < MIN_SAMPLES:
        raise ValueError(f"too few samples: {n} at or after start = {start:g} s "
                         f"(of {t.size}), need at least {MIN_SAMPLES}")
    t = t[keep]
    v = v[keep]
    dt = (t[-1] - t[0]) / (n - 1)
    steps = np.diff(t)
    dev = float(np.max(np.abs(steps - dt)) / dt)
    if dev > UNIFORM_RTOL:
        raise ValueError(f"time is not uniformly sampled: steps range from {steps.min():.9g} to "
                         f"{steps.max():.9g} s (relative deviation {dev:.2e} > {UNIFORM_RTOL:g})")
    finite = np.isfinite(v)
    if not np.all(finite):
        idx = np.unravel_index(int(np.flatnonzero(~finite)[0]), v.shape)
        where = f" channel {tuple(int(i) for i in idx[1:])}" if v.ndim > 1 else ""
        raise ValueError(f"values contain a non-finite entry ({v[idx]}) at time {t[idx[0]]:g} s{where}")

    if detrend == "mean":
        v = v - v.mean(axis=0)
    w = _window(window, n)
    x = v * w.reshape((n,) + (1,) * (v.ndim - 1))
    amp = np.abs(np.fft.rfft(x, axis=0)) * (2.0 / w.sum())
    amp[0] *= 0.5
    if n % 2 == 0:
        amp[-1] *= 0.5
    freq = np.fft.rfftfreq(n, dt)
    freq.setflags(write=False)
    amp.setflags(write=False)
    return Spectrum(frequency=freq, amplitude=amp, window=window, resolution=float(1.0 / (n * dt)),
                    n_samples=n, start_time=float(t[0]))


# ----------------------------------------------------------------------------------------------
# peaks


def _flat(spec: Spectrum) -> np.ndarray:
    amp = np.asarray(spec.amplitude, dtype=float)
    return amp.reshape(amp.shape[0], -1)


def _check_frequency(value: float, name: str) -> float:
    f = float(value)
    if not np.isfinite(f) or f <= 0.0:
        raise ValueError(f"{name} must be a positive finite frequency in Hz, got {value!r}")
    return f


def _local_maxima(a: np.ndarray, rel: float) -> np.ndarray:
    """Local-maximum bins (DC excluded) of one channel above rel * max, strongest first, with the
    weaker of two maxima within 2 bins dropped (side lobes / noise ripple on one resolved peak)."""
    n_f = a.shape[0]
    if n_f < 2:
        return np.zeros(0, dtype=int)
    top = float(a[1:].max())
    if not top > 0.0:
        return np.zeros(0, dtype=int)
    k = np.arange(1, n_f)
    left = a[1:] > a[:-1]
    right = np.ones(n_f - 1, dtype=bool)
    right[:-1] = a[1:-1] >= a[2:]
    cand = k[left & right & (a[1:] >= rel * top)]
    cand = cand[np.argsort(-a[cand], kind="stable")]
    blocked = np.zeros(n_f + 2, dtype=bool)
    kept: list[int] = []
    for b in cand.tolist():
        if not blocked[b]:
            kept.append(b)
            blocked[max(b - 2, 0):b + 3] = True
    return np.asarray(kept, dtype=int)


def find_peaks(
    spec: Spectrum,
    *,
    labels: list[str] | None = None,
    n_peaks: int = 8,
    excitation_frequency: float | None = None,
    modal_frequencies: np.ndarray | None = None,
    min_relative_height: float = 1e-3,
) -> list[Peak]:
    """The `n_peaks` largest spectral peaks over all channels, by decreasing refined amplitude.

    The channel axes are flattened in C order; `labels` (one per flattened channel) name them, else
    "ch0", "ch1", ...  A peak is a local maximum (DC bin excluded) of at least
    min_relative_height times its channel's largest non-DC amplitude; of two maxima of one channel
    within 2 bins only the larger is kept.  The same frequency may be reported for several
    channels (once per channel); n_peaks limits the total.  Ties keep channel order.
    excitation_frequency (Hz) sets `harmonic`; modal_frequencies (Hz, > 0) set `nearest_mode`,
    `mode_frequency` and `mode_distance_pct`.
    """
    amp2 = _flat(spec)
    n_ch = amp2.shape[1]
    if labels is None:
        names = [f"ch{i}" for i in range(n_ch)]
    else:
        names = [str(s) for s in labels]
        if len(names) != n_ch:
            raise ValueError(f"labels has {len(names)} entries but the spectrum has {n_ch} channels "
                             f"(channel shape {tuple(spec.amplitude.shape[1:])}, flattened in C order)")
    if int(n_peaks) != n_peaks or n_peaks < 0:
        raise ValueError(f"n_peaks must be a non-negative integer, got {n_peaks!r}")
    n_peaks = int(n_peaks)
    rel = float(min_relative_height)
    if not np.isfinite(rel) or rel < 0.0:
        raise ValueError(f"min_relative_height must be finite and >= 0, got {min_relative_height!r}")
    f_exc = None if excitation_frequency is None else _check_frequency(excitation_frequency, "excitation_frequency")
    modes = np.zeros(0)
    if modal_frequencies is not None:
        modes = np.asarray(modal_frequencies, dtype=float).reshape(-1)
        if not np.all(np.isfinite(modes)) or np.any(modes <= 0.0):
            raise ValueError("modal_frequencies must be positive finite frequencies in Hz, "
                             f"got {modes.tolist()}")
    if n_peaks == 0:
        return []

    bins_l, chans_l = [], []
    for c in range(n_ch):
        b = _local_maxima(amp2[:, c], rel)
        bins_l.append(b)
        chans_l.append(np.full(b.shape, c, dtype=int))
    bins = np.concatenate(bins_l) if bins_l else np.zeros(0, dtype=int)
    chans = np.concatenate(chans_l) if chans_l else np.zeros(0, dtype=int)
    if bins.size == 0:
        return []
    raw = amp2[bins, chans]
    # refinement multiplies a bin by 1/kernel(delta), within [1/kmax, 1/kmin] for |delta| <= 1/2:
    # candidates whose best case cannot reach the n_peaks-th raw amplitude are skipped.
    if bins.size > n_peaks:
        grid = _kernel(spec.window, spec.n_samples, np.linspace(-0.5, 0.5, 101))
        kth = np.sort(raw)[::-1][n_peaks - 1]
        sel = raw >= kth * float(grid.min()) / float(grid.max()) * (1.0 - 1e-6)
        bins, chans, raw = bins[sel], chans[sel], raw[sel]
    freq, amp = _refine_at(spec, amp2, bins, chans)
    order = np.lexsort((freq, chans, -amp))[:n_peaks]

    peaks = []
    for i in order:
        f = float(freq[i])
        harmonic = 0
        if f_exc is not None:
            k = int(round(f / f_exc))
            if k >= 1 and abs(f - k * f_exc) <= max(2.0 * spec.resolution, 0.01 * k * f_exc):
                harmonic = k
        if modes.size:
            m = int(np.argmin(np.abs(modes - f)))
            fm = float(modes[m])
            nearest, dist = m + 1, 100.0 * (f - fm) / fm
        else:
            nearest, fm, dist = 0, float("nan"), float("nan")
        peaks.append(Peak(frequency=f, amplitude=float(amp[i]), channel=names[int(chans[i])],
                          harmonic=harmonic, nearest_mode=nearest, mode_frequency=fm,
                          mode_distance_pct=float(dist)))
    return peaks


def harmonic_content(spec: Spectrum, excitation_frequency: float, *, n_harmonics: int = 5) -> np.ndarray:
    """Amplitude at k * excitation_frequency, k = 1 .. n_harmonics: (n_harmonics, *channel_shape).

    For each k and channel the largest of the 3 bins around k f_exc (DC excluded) is taken and
    refined like a peak (offset clipped to +-1/2 bin, scalloping corrected), so the value does not
    depend on where k f_exc falls between bins.  Harmonics above the Nyquist frequency are nan.
    """
    f_exc = _check_frequency(excitation_frequency, "excitation_frequency")
    if int(n_harmonics) != n_harmonics or n_harmonics < 1:
        raise ValueError(f"n_harmonics must be a positive integer, got {n_harmonics!r}")
    n_harmonics = int(n_harmonics)
    amp2 = _flat(spec)
    n_f, n_ch = amp2.shape
    nyquist = 0.5 * spec.n_samples * spec.resolution
    out = np.full((n_harmonics, n_ch), np.nan)
    rows, bins = [], []
    for k in range(1, n_harmonics + 1):
        fk = k * f_exc
        if fk > nyquist * (1.0 + 1e-12) or n_f < 2:
            continue
        j = int(round(fk / spec.resolution))
        near = np.arange(max(j - 1, 1), min(j + 1, n_f - 1) + 1)
        rows.append(k - 1)
        bins.append(near[np.argmax(amp2[near], axis=0)])
    if rows:
        best = np.concatenate(bins)
        chans = np.tile(np.arange(n_ch), len(rows))
        _, amp = _refine_at(spec, amp2, best, chans)
        out[rows] = amp.reshape(len(rows), n_ch)
    return out.reshape((n_harmonics,) + tuple(spec.amplitude.shape[1:]))
