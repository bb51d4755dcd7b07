"""The fidelity ladder of the spans: the cheapest model of each span for a frequency band and a tolerance.

Rungs, cheapest first: "spring" (an axial spring between the tangent points, no DOFs of its own,
`system.SpringSpans`), "string" (ANCF elements without bending) and "ancf" (ANCF beam elements), the
last two with 1, 2, 4, ... elements (4 DOFs per element). `study.fidelity.choose_models(cfg, fmax=, rtol=)` picks,
span by span, the cheapest rung whose modes below fmax are within rtol of the converged ANCF answer:

1. The all-spring (rotational) model of the drive gives, at almost no cost, the static span tensions
   N_s and stretches lam_s and the drive's own modes below fmax (pulley rotations, translations, arms).
2. A spring span has no modes of its own: it is a candidate only if its first transverse and first
   axial mode (`continuum_frequencies`, the converged ANCF answer of the span pinned at its ends)
   lie above SPRING_MARGIN x fmax; the modes it cannot represent are listed (`unrepresented_modes`),
   never dropped silently.
3. What a spring span changes in a drive mode i: the dynamic stiffness of the span between its end
   displacements y differs from that of the continuous span (`spring_errors`). Per direction (along
   the chord: stiffness k = dN/dl, across: the string's N / l; span mass m) with x = omega sqrt(m / k):
       D_exact = k x / sin x [[cos x, -1], [-1, cos x]]      (bar / taut string between two points)
       D_spring = k [[1, -1], [-1, 1]] - omega^2 m / 2 I      (the spring with its lumped mass)
   so omega_i^2 moves by y^T (D_spring - D_exact) y / (phi^T M phi) to first order, and the relative
   frequency error is e_is = |sum over both directions y^T dD y| / (2 omega_i^2) (mass-normalized
   shapes). For small x, dD = -(k x^2 / 6) [[1, -1], [-1, 1]]: the lumped mass misses a sixth of the
   span's inertia in the stretching motion. Candidate spans are dropped (the largest contributor to
   the worst mode first) until every drive mode's sum over the spring spans is within the budget.
4. Every other span gets the cheapest string or ANCF mesh whose local modes (the span pinned at its
   ends under N_s, `span_frequencies`: the same elements, linearized about the straight stretched
   span) are within the budget of the closed-form continuum of the ANCF span, pinned beam under
   tension: omega_n^2 = (S k_n^2 + EI_eff k_n^4) / rho, k_n = n pi / L_ref, S = EA eps the second
   Piola-Kirchhoff force (EI_eff = EI for the linear curvature of paper Eq. 17, EI / lam^4 for the
   exact one), and the fixed bar omega_n^2 = EA (3 lam^2 - 1) / 2 k_n^2 / rho. The modes below fmax
   count, and the first one above, its error scaled by (fmax / f)^4 for "ancf" (the mesh error of
   cubic Hermite elements grows as (k h)^4 with the wave number k) and (fmax / f)^2 for "string" (its
   missing bending, EI k^2 / 2S, grows as k^2), so that it bounds the error of a mode up to fmax.
   This continuum is the limit that Richardson extrapolation (`sweep.richardson`, `modal --rtol`)
   approximates for a whole drive; for one span it is known in closed form, so the error of a mesh
   is measured, not extrapolated.
5. The budget: rtol for the spring spans when all spans are springs, else rtol / 2 for the spring
   spans and rtol / 2 for the others. The chosen drive is solved, and the spring spans' errors are
   evaluated again on its modes below fmax (a posteriori, no extra solve); where the sum exceeds the
   budget, the worst spring span is raised to the next rung and the drive solved again. A band that
   even ANCF at `max_elements` elements cannot meet is reported as not met (`LadderChoice.met`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from beltdyn.model import barlaw

from beltdyn.config import DriveConfig

SPRING_MARGIN = 1.05  # a spring span's own first mode must lie this far above fmax
MESHES = (1, 2, 4, 8, 16, 32, 64)


@dataclass(frozen=True, kw_only=True)
class SpanChoice:
    """The rung chosen for one span: model, elements, its own DOFs and the estimated relative error
    of the modes below fmax it causes."""

    span: int  # 0-based span index
    name: str
    model: str  # "spring" | "string" | "ancf"
    elements: int  # 0 for a spring span
    dofs: int  # the span's own DOFs (4 per element; a spring span none)
    estimate: float  # relative frequency error (spring: the largest over the drive modes below fmax)
    note: str = ""


@dataclass(frozen=True, kw_only=True)
class LadderChoice:
    """What `choose_models` chose and why; `config` is the drive with the [spans] table filled in."""

    fmax: float
    rtol: float
    spans: tuple[SpanChoice, ...]
    config: DriveConfig
    met: bool  # every estimate within the budget
    estimate: float  # largest estimated relative error of a mode below fmax (spring + mesh parts)
    mode_estimate: np.ndarray  # (n_below,) estimate per mode of the chosen drive below fmax
    solves: int  # drive solves (static + modal) the choice took, the final one included
    unrepresented: tuple[tuple[int, str, int, float], ...] = ()  # modes of spring spans below fmax


# ------------------------------------------------------------------------------------ the span alone
def continuum_frequencies(*, length: float, stretch: float, EA: float, EI: float, rho: float, curvature: str,
                          n: int) -> tuple[np.ndarray, np.ndarray]:
    """The first n transverse and axial frequencies (Hz) of the converged ANCF span pinned at its ends,
    reference length `length`, stretched by `stretch` (module docstring, item 4)."""
    k = np.arange(1, n + 1) * np.pi / length
    S = barlaw.second_piola_force(stretch, EA)
    EI_eff = 0.0 if curvature == "none" else (EI / stretch**4 if curvature == "exact" else EI)
    f_t = np.sqrt(np.maximum(S * k**2 + EI_eff * k**4, 0.0) / rho) / (2 * np.pi)
    f_a = np.sqrt(barlaw.axial_stiffness(stretch, EA) * k**2 / rho) / (2 * np.pi)
    return f_t, f_a


def element_blocks(lengths: np.ndarray, *, stretch: float | np.ndarray, EA: float, EI: float, rho: float,
                   curvature: str, n_gauss: int) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and mass matrices (k, 8, 8) of ANCF elements of the given lengths (k,), straight along x and
    stretched by `stretch` (one, or one per element): one element build for any number of meshes and spans."""
    from beltdyn.model import ancf

    h = np.asarray(lengths, dtype=float)
    lam = np.broadcast_to(np.asarray(stretch, dtype=float), h.shape)
    el = ancf.make_elements(h, EA, np.full(len(h), EI), rho, curvature=curvature, n_gauss=n_gauss)
    e = np.zeros((len(h), 8))
    e[:, 2] = e[:, 6] = lam
    e[:, 4] = lam * h
    return ancf.internal_forces_and_tangent(el, e)[1], el.mass


def span_frequencies(*, length: float, stretch: float, EA: float, EI: float, rho: float, curvature: str,
                     elements: int, n_gauss: int, n_t: int, n_a: int,
                     blocks: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The lowest n_t transverse and n_a axial frequencies (Hz) of one span of `elements` ANCF elements,
    pinned at both ends, linearized about the straight span stretched by `stretch` (NaN where the
    mesh has fewer modes). Along x the straight span's tangent decouples: x entries axial, y transverse.
    blocks: the element's (tangent, mass) (8, 8) each, if built already (`element_blocks`)."""
    from beltdyn.analysis.modal import generalized_eigh

    if blocks is None:
        Kt, Mt = element_blocks(np.array([length / elements]), stretch=stretch, EA=EA, EI=EI, rho=rho,
                                curvature=curvature, n_gauss=n_gauss)
        blocks = (Kt[0], Mt[0])
    n = 4 * (elements + 1)
    flat = _chain_slots(elements)  # every element alike: its (8, 8) block on its two nodes' rows and columns
    K, M = (np.bincount(flat, weights=np.tile(np.asarray(b, dtype=float).ravel(), elements),
                        minlength=n * n).reshape(n, n) for b in blocks)
    out = []
    for comp, want in ((1, n_t), (0, n_a)):  # y: transverse, x: axial; the end positions held
        keep = np.r_[np.arange(comp, n, 4)[1:-1], np.arange(comp + 2, n, 4)]
        f = np.full(want, np.nan)
        k = min(want, len(keep))
        if k > 0:
            # all eigenvalues by divide and conquer: faster than the subset driver at these sizes (<= 130)
            rows = keep[:, None]
            w = generalized_eigh(K[rows, keep], M[rows, keep], vectors=False)[0][:k]
            f[:k] = np.sqrt(np.maximum(w, 0.0)) / (2 * np.pi)
        out.append(f)
    return out[0], out[1]


@functools.lru_cache(maxsize=32)
def _chain_slots(elements: int) -> np.ndarray:
    """(elements * 64,) flat slot row * n + col of each entry of each element's (8, 8) block in the (n, n)
    matrix of a chain of `elements` ANCF elements (n = 4 (elements + 1): element e on nodes e, e + 1),
    element by element, row-major (read-only, cached)."""
    n = 4 * (elements + 1)
    dof = 4 * np.arange(elements)[:, None] + np.arange(8)  # (elements, 8)
    out = (dof[:, :, None] * n + dof[:, None, :]).ravel()
    out.setflags(write=False)
    return out


def local_error(*, model: str, elements: int, fmax: float, length: float, stretch: float, EA: float, EI: float,
                rho: float, curvature: str, n_gauss: int, blocks: tuple[np.ndarray, np.ndarray] | None = None) -> float:
    """Relative error of the span's local modes up to fmax for model "string" or "ancf" with `elements`
    elements against the converged ANCF span (module docstring, item 4); inf where the mesh lacks a mode.
    blocks: the mesh's element matrices, if built already (`element_blocks`, with the model's EI and law)."""
    ref_curv = curvature if curvature != "none" else "linear"
    n_max = 1
    while True:  # enough continuum modes to pass fmax in both directions
        f_t, f_a = continuum_frequencies(length=length, stretch=stretch, EA=EA, EI=EI, rho=rho, curvature=ref_curv,
                                         n=n_max)
        if f_t[-1] > fmax and f_a[-1] > fmax:
            break
        n_max *= 2
    n_t = int(np.searchsorted(f_t, fmax, side="right")) + 1
    n_a = int(np.searchsorted(f_a, fmax, side="right")) + 1
    h_curv = "none" if model == "string" else ref_curv
    g_t, g_a = span_frequencies(length=length, stretch=stretch, EA=EA, EI=0.0 if model == "string" else EI, rho=rho,
                                curvature=h_curv, elements=elements, n_gauss=n_gauss, n_t=n_t, n_a=n_a, blocks=blocks)
    worst = 0.0
    for g, f in ((g_t, f_t[:n_t]), (g_a, f_a[:n_a])):
        err = np.abs(g / f - 1.0)
        if not np.all(np.isfinite(err)):
            return np.inf
        err[-1] *= (fmax / f[-1]) ** (2 if model == "string" else 4)  # the first mode above fmax bounds the top
        worst = max(worst, float(err.max()))
    return worst


# ------------------------------------------------------------------------------------ spring spans
def span_state(system, static) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tension (n_span,) N, reference length (n_span,) m, stretch (n_span,)) of each span at the static
    equilibrium: the mean of its end tensions N, and the stretch of the Green-Lagrange law that
    carries it, EA (lam^3 - lam) / 2 = N (the layout's chord at q = 0 is not the solved one)."""
    T = static.span_tension.mean(axis=1)
    return T, np.asarray(system.belt.reference_length, dtype=float), barlaw.stretch_for_tension(T, system.EA)


def unrepresented_modes(system, static, band: float) -> tuple[tuple[int, str, int, float], ...]:
    """The modes below `band` (Hz) that the spring spans of `system` cannot represent: each spring span's
    own transverse and axial modes (the converged ANCF span pinned at its ends: n c / 2L for a taut
    string, corrected for bending). ((span index, "transverse" | "longitudinal", order, Hz), ...)."""
    sp = system.springs
    if sp is None or not band > 0:
        return ()
    _, L_ref, lam = span_state(system, static)
    out = []
    for s in sp.span.tolist():
        n = 1
        while True:
            f_t, f_a = continuum_frequencies(length=L_ref[s], stretch=lam[s], EA=sp.EA, EI=sp.EI, rho=sp.rho,
                                             curvature=sp.curvature, n=n)
            if f_t[-1] > band and f_a[-1] > band:
                break
            n *= 2
        out += [(s, "transverse", i + 1, float(f)) for i, f in enumerate(f_t) if f <= band]
        out += [(s, "longitudinal", i + 1, float(f)) for i, f in enumerate(f_a) if f <= band]
    return tuple(sorted(out, key=lambda x: x[3]))


def _dD(k: np.ndarray, m: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """(modes, k, 2, 2) D_spring - D_exact of a span of static stiffness k (k,) and mass m (k,) at the
    circular frequencies omega (modes,) (module docstring, item 3)."""
    x = omega[:, None] * np.sqrt(m / k)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(x > 1e-6, x / np.sin(x), 1.0)
    diag = 1.0 - 0.5 * x**2 - r * np.cos(x)
    off = -1.0 + r
    out = np.empty(x.shape + (2, 2))
    out[..., 0, 0] = out[..., 1, 1] = diag
    out[..., 0, 1] = out[..., 1, 0] = off
    return k[None, :, None, None] * out


def spring_errors(system, q: np.ndarray, frequency: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """(modes, k) e_is: the relative frequency error each spring span of `system` causes in each mode
    (frequency (modes,) Hz, mass-normalized shapes (modes, n_dof) about q) against the continuous span
    (module docstring, item 3). The chord, tension and stiffness at the state q."""
    sp = system.springs
    if sp is None or not len(frequency):
        return np.zeros((len(frequency), 0))
    p = system.expand(q)
    u, l, lam, _, N = sp.axial(sp.positions(p))
    k_axial = barlaw.axial_stiffness(lam, sp.EA) / sp.reference_length
    k_across = N / l
    m = sp.rho * sp.reference_length
    Y = sp.positions_batch(system.expand_motion(q, shapes), offset=False).reshape(len(frequency), -1, 2, 2)
    nrm = np.column_stack([-u[:, 1], u[:, 0]])
    a = np.einsum("bkjd,kd->bkj", Y, u)
    b = np.einsum("bkjd,kd->bkj", Y, nrm)
    omega = 2 * np.pi * np.asarray(frequency, dtype=float)
    quad = (np.einsum("bki,bkij,bkj->bk", a, _dD(k_axial, m, omega), a)
            + np.einsum("bki,bkij,bkj->bk", b, _dD(np.maximum(k_across, 1e-300), m, omega), b))
    return np.abs(quad) / (2.0 * omega[:, None] ** 2)




__all__ = ["SpanChoice", "LadderChoice", "continuum_frequencies", "span_frequencies", "local_error",
           "spring_errors", "unrepresented_modes", "span_state", "element_blocks", "SPRING_MARGIN", "MESHES"]
