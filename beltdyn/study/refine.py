"""Mesh refinement (`modal --rtol`): meshes doubled until the Richardson error estimate of each wanted mode
meets the tolerance (`refine_mesh`), the estimate itself (`richardson`) and the convergence record
(`Refinement`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.config import DriveConfig
from beltdyn.model.reuse import Reuse

SAFETY = 1.25  # safety factor of the Richardson error estimate (Roache's grid convergence index)


def richardson(frequency: np.ndarray, elements: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per mode: extrapolated frequency, error estimate of each mesh, observed order.

    frequency (n_mesh, n_mode) on meshes with elements per span `elements` (increasing). With
    h = 1/elements, the observed order p from the three finest meshes (capped to [1, 4], 4 being the
    order of cubic Hermite elements for eigenfrequencies, so the estimate is never optimistic), then
    f_inf = f_n + (f_n - f_{n-1}) / (r^p - 1) and the estimate of mesh k is
    SAFETY * |f_k - f_inf| / f_inf with Roache's three-grid safety factor 1.25 (grid convergence index).
    """
    f = np.asarray(frequency, dtype=float)
    e = np.asarray(elements, dtype=float)
    n_mesh, n_mode = f.shape
    order = np.full(n_mode, 4.0)
    if n_mesh >= 3:
        r1, r2 = e[-2] / e[-3], e[-1] / e[-2]
        d1, d2 = f[-2] - f[-3], f[-1] - f[-2]
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.log(np.abs(d1 / d2)) / np.log(0.5 * (r1 + r2))
        order = np.where(np.isfinite(p), np.clip(p, 1.0, 4.0), 4.0)
    if n_mesh >= 2:
        r = e[-1] / e[-2]
        f_inf = f[-1] + (f[-1] - f[-2]) / (r ** order - 1.0)
    else:
        f_inf = f[-1].copy()
    est = SAFETY * np.abs(f - f_inf) / np.abs(f_inf)
    return f_inf, est, order


@dataclass(frozen=True, kw_only=True)
class Refinement:
    """Meshes tried (elements per span), tracked frequencies (n_mesh, n_modes), error estimates, choice."""

    elements: np.ndarray
    frequency: np.ndarray
    estimate: np.ndarray
    order: np.ndarray
    labels: tuple[str, ...]
    chosen: int  # index into elements
    converged: bool


def mode_keys(md) -> list[tuple]:
    return [(md.kind[k], int(md.order[k]), int(md.span[k])) for k in range(len(md.frequency))]


def refine_mesh(cfg: DriveConfig, *, n_modes: int, rtol: float, max_elements: int = 640):
    """Double elements_per_span from the configured mesh until the Richardson error estimate of each
    of the first n_modes modes (matched by kind, order and span) is <= rtol; return the cheapest mesh
    whose estimate meets it, with its model, static and modal results, and the Refinement record.
    At least three meshes are computed, so that the estimate rests on an observed order."""
    from beltdyn.config import with_overrides
    from beltdyn.pipeline import analyse

    n_el = cfg.mesh.elements_per_span
    runs, elements = [], []
    reuse = Reuse()  # (every mesh of one L0 fit: `pipeline.analyse`'s)
    while True:
        c = with_overrides(cfg, [f"mesh.elements_per_span={n_el}"])
        run = analyse(c, modal=True, n_modes=n_modes + 6, reuse=reuse)
        md = run.modal
        runs.append((c, run.system, run.static, md))
        elements.append(n_el)
        # the modes wanted are the first n_modes of the finest mesh; coarser meshes matched by label
        ref_keys = mode_keys(md)[:n_modes]
        labels = tuple(md.label[:n_modes])
        f = np.full((len(runs), n_modes), np.nan)
        for i, run in enumerate(runs):
            keys = mode_keys(run[3])
            for j, key in enumerate(ref_keys):
                if key in keys:
                    f[i, j] = run[3].frequency[keys.index(key)]
        if len(elements) >= 3 and np.all(np.isfinite(f[-3:])):  # three meshes: an observed order
            f_inf, est, p = richardson(f, np.array(elements, dtype=float))
            if np.all(est[-1] <= rtol):
                ok = [i for i in range(len(elements)) if np.all(est[i] <= rtol)]
                i = ok[0]
                ref = Refinement(elements=np.array(elements), frequency=f, estimate=est, order=p, labels=labels,
                                 chosen=i, converged=True)
                return runs[i], ref
        if 2 * n_el > max_elements:
            est = richardson(f, np.array(elements, dtype=float))[1] if len(elements) >= 2 else np.full_like(f, np.nan)
            ref = Refinement(elements=np.array(elements), frequency=f, estimate=est, order=np.full(n_modes, np.nan),
                             labels=labels, chosen=len(elements) - 1, converged=False)
            return runs[-1], ref
        n_el *= 2
