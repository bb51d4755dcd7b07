"""Compiled (numba) forces of the spring spans for the time stepper: `springs.SpringSpans` in loops.

Nomenclature as `springs.SpringSpans`: per spring span k, end positions x = x0 + T p[idx] (4,),
chord d = x[2:4] - x[0:2] = d0 + D p[idx] (D = T[2:4] - T[0:2], precomputed), l = |d|, u = d / l,
stretch lam = l / L, stretch rate lam' = (u . d') / L. The bar law is `barlaw`'s, compiled here from
its very functions (`axial_force`: N, `viscous_force`: N_d, `strain_energy_density`: the energy per
unit length, `second_piola_force`: S = EA eps) and their `linear_` twins, the axial law chosen by
``law`` (`AXIAL_LAW_CODE` of `belt_kernel`: 0 "green-lagrange", 1 "linear", the springs' belt.axial_law);
the end forces [-N u, N u] go back through T^T. Held equal to the numpy `SpringSpans` on random states by
tests/test_springs.py.

`SpringData` is a field of `integrator.BeltData` (`springs`); no spring spans: k = 0 (`no_springs`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from beltdyn.jitcache import kernel_options
from beltdyn.model import barlaw
from beltdyn.model.belt_kernel import AXIAL_LAW_CODE

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)

# the bar law, compiled from barlaw's functions (the one place it is written)
axial_force_kernel = njit(**KERNEL)(barlaw.axial_force)
viscous_force_kernel = njit(**KERNEL)(barlaw.viscous_force)
energy_density_kernel = njit(**KERNEL)(barlaw.strain_energy_density)
second_piola_kernel = njit(**KERNEL)(barlaw.second_piola_force)
linear_axial_force_kernel = njit(**KERNEL)(barlaw.linear_axial_force)
linear_viscous_force_kernel = njit(**KERNEL)(barlaw.linear_viscous_force)
linear_energy_density_kernel = njit(**KERNEL)(barlaw.linear_strain_energy_density)
linear_second_piola_kernel = njit(**KERNEL)(barlaw.linear_second_piola_force)
_LINEAR = AXIAL_LAW_CODE["linear"]


# D (k, 2, m) the chord d = x[2:4] - x[0:2] per joint coordinate, idx (k, m) (padding n), d0 (k, 2) the chord at
# p = 0, L (k,), span (k,) span index, EA, eta (retardation time, s), law (`AXIAL_LAW_CODE`)
SpringData = namedtuple("SpringData", ["D", "idx", "d0", "L", "span", "EA", "eta", "law"])


def no_springs() -> SpringData:
    return SpringData(D=np.zeros((0, 2, 1)), idx=np.zeros((0, 1), dtype=np.int64), d0=np.zeros((0, 2)),
                      L=np.zeros(0), span=np.zeros(0, dtype=np.int64), EA=0.0, eta=0.0, law=0)


def spring_data(springs, eta: float) -> SpringData:
    """The kernel's data of a `system.SpringSpans` (None: no spring spans); writable copies where the
    system's arrays are read-only (shared tables): numba types a read-only array apart, which would compile
    `advance` anew."""
    if springs is None:
        return no_springs()
    T = np.asarray(springs.T, dtype=float)
    return SpringData(D=np.ascontiguousarray(T[:, 2:4] - T[:, 0:2]), idx=np.array(springs.idx, dtype=np.int64),
                      d0=np.ascontiguousarray(springs.x0[:, 2:4] - springs.x0[:, 0:2], dtype=float),
                      L=np.ascontiguousarray(springs.reference_length, dtype=float),
                      span=np.ascontiguousarray(springs.span, dtype=np.int64), EA=float(springs.EA), eta=float(eta),
                      law=int(AXIAL_LAW_CODE[springs.axial_law]))


@njit(**KERNEL)
def _chord(sp, k, q_ext):
    """The chord (dx, dy) = d0 + D q_ext[idx] of spring k."""
    dx, dy = sp.d0[k, 0], sp.d0[k, 1]
    for j in range(sp.D.shape[2]):
        qj = q_ext[sp.idx[k, j]]
        dx += sp.D[k, 0, j] * qj
        dy += sp.D[k, 1, j] * qj
    return dx, dy


@njit(**KERNEL)
def spring_forces(sp, q_ext, v_ext, f_el, f_dmp, gross, with_gross):
    """Add the spring spans' elastic (f_el) and damping (f_dmp) forces (n + 1,) at (q, v); with_gross:
    also |T^T f| per entry to gross (the round-off scale)."""
    k_n, _, m = sp.D.shape
    for k in range(k_n):
        dx, dy = _chord(sp, k, q_ext)
        l = np.sqrt(dx * dx + dy * dy)
        ux, uy = dx / l, dy / l
        lam = l / sp.L[k]
        N = linear_axial_force_kernel(lam, sp.EA) if sp.law == _LINEAR else axial_force_kernel(lam, sp.EA)
        Nd = 0.0
        if sp.eta != 0.0:
            vx, vy = 0.0, 0.0
            for j in range(m):
                vj = v_ext[sp.idx[k, j]]
                vx += sp.D[k, 0, j] * vj
                vy += sp.D[k, 1, j] * vj
            rate = (ux * vx + uy * vy) / sp.L[k]
            if sp.law == _LINEAR:
                Nd = linear_viscous_force_kernel(lam, rate, sp.EA, sp.eta)
            else:
                Nd = viscous_force_kernel(lam, rate, sp.EA, sp.eta)
        for j in range(m):
            c = sp.D[k, 0, j] * ux + sp.D[k, 1, j] * uy  # u . d(chord)/dp_j
            f_el[sp.idx[k, j]] += N * c
            f_dmp[sp.idx[k, j]] += Nd * c
            if with_gross:
                gross[sp.idx[k, j]] += abs(N * c)


@njit(**KERNEL)
def spring_energy(sp, q_ext):
    """Strain energy of the spring spans, sum L U(lam) (U the law's energy per unit length)."""
    total = 0.0
    for k in range(sp.D.shape[0]):
        dx, dy = _chord(sp, k, q_ext)
        lam = np.sqrt(dx * dx + dy * dy) / sp.L[k]
        if sp.law == _LINEAR:
            total += linear_energy_density_kernel(lam, sp.EA) * sp.L[k]
        else:
            total += energy_density_kernel(lam, sp.EA) * sp.L[k]
    return total


@njit(**KERNEL)
def spring_min_force(sp, q_ext, min_span):
    """min_span[span] = min(min_span[span], N / lam) of each spring span (slack detection, the force per
    unit reference section as the belt's: EA eps for the green-lagrange law)."""
    for k in range(sp.D.shape[0]):
        dx, dy = _chord(sp, k, q_ext)
        lam = np.sqrt(dx * dx + dy * dy) / sp.L[k]
        v = linear_second_piola_kernel(lam, sp.EA) if sp.law == _LINEAR else second_piola_kernel(lam, sp.EA)
        s = sp.span[k]
        if v < min_span[s]:
            min_span[s] = v
