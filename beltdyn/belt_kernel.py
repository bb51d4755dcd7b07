"""Compiled (numba) belt kernel: the planar ANCF element of `ancf`, element by element, and the
reduced-coordinate gather/scatter of the drive model.

`ancf` is the reference implementation (vectorized numpy); this module computes the same quantities
with plain loops, one element at a time, without allocating in the element loop, so that Newton
solvers and the compiled time stepper (`integrator`) can call it.  Every function is
``@njit(cache=True)`` except the set-up helpers `tables_from_elements` and `joint_selection`.

Nomenclature (as `ancf`, paper "Modelling and dynamic analysis of belt drive system by hybrid
flexible multibody method"):

* Eq. 1-6   r(x) = S(x) e, e = [r(0), r'(0), r(L), r'(L)] (8,); ``E`` (n_elem, 8) holds one e per
            row, index ``2 a + i`` for shape function a in 0..3 and component i in 0..1.
* ``D = dS[k, q]`` (4,) ds/dx and ``D2 = d2S[k, q]`` (4,) d2s/dx2 at Gauss point q of element k,
  so r' = sum_a D_a e_a and r'' = sum_a D2_a e_a with e_a = (e[2a], e[2a+1]).
* ``wEA[k, q]`` = Gauss weight * L * EA, ``wEI[k, q]`` = Gauss weight * L * EI (integration weights
  in x), ``Kb[k]`` the constant bending matrix EI int S''^T S'' dx of Eq. 17 (zeros unless "linear").
* Eq. 12    eps = (A - 1)/2 with A = r'.r' (Green-Lagrange axial strain).
* Eq. 13-14 U_l = sum_q wEA eps^2 / 2,  f_l = sum_q wEA eps G_q,  G_q = S'^T r' = D (x) r' (8,),
            K_l = sum_q wEA [G_q G_q^T + eps P_q],  P_q = (D D^T) (x) I2.
* Eq. 17    "linear" bending: U_t = e^T Kb e / 2, f_t = Kb e, K_t = Kb.
* Eq. 15-16 "exact" bending, per Gauss point u = wEI c^2 / (2 A^3), c = r' x r'' = r'^T J r''
            (J = [[0, 1], [-1, 0]]); gc = dc/de = D (x) J r'' + D2 (x) J^T r', gA = dA/de = 2 G:
            f_t = u_c gc + u_A gA with u_c = wEI c/A^3, u_A = -3/2 wEI c^2/A^4;
            K_t = a gc gc^T + b (gc gA^T + gA gc^T) + d gA gA^T + u_c (Q + Q^T) + 2 u_A P_q,
            a = wEI/A^3, b = -3 wEI c/A^4, d = 6 wEI c^2/A^5, Q = (D D2^T) (x) J; the rank terms
            are evaluated as a h h^T - 12 wEI c^2/A^5 G G^T with h = gc - 6 c/A G (as `ancf`).
* "none": no bending energy (a cable).
* Kelvin-Voigt belt damping (retardation times eta_a, eta_b in s), linear in the velocities Ed:
            fd = eta_a sum_q wEA (G_q . Ed) G_q + eta_b B Ed,  with B = Kb ("linear"),
            B = sum_q wEI/A^3 gc gc^T ("exact": the material rank-1 term of the exact bending
            tangent, symmetric positive semi-definite) or B = 0 ("none").  C = d fd / d Ed.

Curvature codes (`CURVATURE_CODE`): 0 "none", 1 "linear", 2 "exact".

Reduced coordinates: e = e0 + T q_ext[idx] per element, with T (n_elem, 8, m), idx (n_elem, m)
int64, q_ext (n_dof + 1,) = [q, 0] (index n_dof is the padding: q_ext[n_dof] must be 0).  Interior
span elements have T = [I8 | 0] and idx[:, 8:] == n_dof; `joint_selection` marks them with
tsel = -1 and every other ("joint") element k with tsel = k, its own row of T (the stepper relies on
this).  Reduced vectors are (n_dof + 1,): their last slot collects the padding's share and is
meaningless.

Array contract (to keep one compiled specialization per function): float64 C-contiguous writable
arrays, int64 index arrays, ``curvature`` a Python int, ``eta_a``/``eta_b`` Python floats.  The
compiled functions do not check shapes; outputs are written (not accumulated) unless said otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from . import ancf

__all__ = [
    "CURVATURE_CODE",
    "KernelTables",
    "tables_from_elements",
    "element_forces",
    "element_forces_tangent",
    "element_damping",
    "element_damping_matrix",
    "element_strain_energy",
    "element_min_axial_force",
    "joint_selection",
    "gather",
    "gather_velocity",
    "scatter_vector",
    "reduce_blocks",
    "reduced_force",
    "reduced_force_and_tangent_blocks",
]

CURVATURE_CODE = {"none": 0, "linear": 1, "exact": 2}
_LINEAR = 1
_EXACT = 2


@dataclass(frozen=True, kw_only=True, eq=False)
class KernelTables:
    """The kernel's tables of an `ancf.ElementSet` (writable float64 C-contiguous copies).

    Shapes (n = n_elem, q = n_gauss): ``dS``, ``d2S`` (n, q, 4); ``wEA``, ``wEI`` (n, q) Gauss weight
    * L * EA and * EI; ``EA`` (n,); ``Kb`` (n, 8, 8) linear bending matrix (zeros unless curvature
    "linear"); ``curvature`` the code of `CURVATURE_CODE`.
    """

    dS: np.ndarray
    d2S: np.ndarray
    wEA: np.ndarray
    wEI: np.ndarray
    EA: np.ndarray
    Kb: np.ndarray
    curvature: int

    @property
    def args(self) -> tuple:
        """(dS, d2S, wEA, wEI, Kb, curvature), the table arguments of the element functions."""
        return self.dS, self.d2S, self.wEA, self.wEI, self.Kb, self.curvature


def _plain(a: np.ndarray) -> np.ndarray:
    """A writable float64 C-contiguous copy (ancf's arrays are read-only: numba would compile a
    second, read-only specialization of every function for them)."""
    return np.array(a, dtype=np.float64, order="C", copy=True)


def tables_from_elements(el: ancf.ElementSet) -> KernelTables:
    """The `KernelTables` of ``el`` (same Gauss rule and curvature model)."""
    return KernelTables(dS=_plain(el.dS), d2S=_plain(el.d2S), wEA=_plain(el.wL * el.EA[:, None]),
                        wEI=_plain(el.wL * el.EI[:, None]), EA=_plain(el.EA), Kb=_plain(el.K_bend),
                        curvature=int(CURVATURE_CODE[el.curvature]))


# ------------------------------------------------------------------------------------ one element
@njit(cache=True)
def _slope(ev, tab, k, g):
    """sum_a tab[k, g, a] e_a: r' (tab = dS) or r'' (tab = d2S) of the 8-vector ev."""
    x = tab[k, g, 0] * ev[0] + tab[k, g, 1] * ev[2] + tab[k, g, 2] * ev[4] + tab[k, g, 3] * ev[6]
    y = tab[k, g, 0] * ev[1] + tab[k, g, 1] * ev[3] + tab[k, g, 2] * ev[5] + tab[k, g, 3] * ev[7]
    return x, y


@njit(cache=True)
def _add_kb(ev, Kb, k, scale, fo):
    """fo += scale * Kb[k] @ ev."""
    for i in range(8):
        acc = 0.0
        for j in range(8):
            acc += Kb[k, i, j] * ev[j]
        fo[i] += scale * acc


@njit(cache=True)
def _mirror_upper(Ko):
    """Copy the upper triangle of the 8 x 8 Ko onto its lower triangle (exact symmetry)."""
    for i in range(8):
        for j in range(i):
            Ko[i, j] = Ko[j, i]


@njit(cache=True)
def _force_one(ev, k, dS, d2S, wEA, wEI, Kb, curvature, fo):
    """fo (8,) = dU/de of element k at ev (8,)."""
    for i in range(8):
        fo[i] = 0.0
    for g in range(dS.shape[1]):
        rx, ry = _slope(ev, dS, k, g)
        A = rx * rx + ry * ry
        s = 0.5 * wEA[k, g] * (A - 1.0)  # wEA eps
        if curvature == _EXACT:
            px, py = _slope(ev, d2S, k, g)
            c = rx * py - ry * px
            iA = 1.0 / A
            uc = wEI[k, g] * c * (iA * iA * iA)
            s -= 3.0 * uc * c * iA  # + 2 u_A (gA = 2 G)
            for a in range(4):
                D = dS[k, g, a]
                D2 = d2S[k, g, a]
                fo[2 * a] += s * D * rx + uc * (D * py - D2 * ry)
                fo[2 * a + 1] += s * D * ry + uc * (D2 * rx - D * px)
        else:
            for a in range(4):
                D = dS[k, g, a]
                fo[2 * a] += s * D * rx
                fo[2 * a + 1] += s * D * ry
    if curvature == _LINEAR:
        _add_kb(ev, Kb, k, 1.0, fo)


@njit(cache=True)
def _force_tangent_one(ev, k, dS, d2S, wEA, wEI, Kb, curvature, fo, Ko, w):
    """fo (8,) = dU/de and Ko (8, 8) = dfo/de of element k at ev (8,); w (16,) scratch."""
    for i in range(8):
        fo[i] = 0.0
        for j in range(8):
            Ko[i, j] = 0.0
    for g in range(dS.shape[1]):
        rx, ry = _slope(ev, dS, k, g)
        A = rx * rx + ry * ry
        s = 0.5 * wEA[k, g] * (A - 1.0)  # coefficient of P_q (secant matrix)
        for a in range(4):
            D = dS[k, g, a]
            w[2 * a] = D * rx  # G
            w[2 * a + 1] = D * ry
        if curvature == _EXACT:
            px, py = _slope(ev, d2S, k, g)
            c = rx * py - ry * px
            iA = 1.0 / A
            ca = wEI[k, g] * (iA * iA * iA)  # a = wEI / A^3
            uc = ca * c
            s -= 3.0 * uc * c * iA
            cG = wEA[k, g] - 12.0 * uc * c * iA * iA  # wEA - 12 wEI c^2 / A^5
            t = 6.0 * c * iA
            for a in range(4):
                D = dS[k, g, a]
                D2 = d2S[k, g, a]
                gx = D * py - D2 * ry  # gc
                gy = D2 * rx - D * px
                fo[2 * a] += s * w[2 * a] + uc * gx
                fo[2 * a + 1] += s * w[2 * a + 1] + uc * gy
                w[8 + 2 * a] = gx - t * w[2 * a]  # h = gc - 6 c/A G
                w[9 + 2 * a] = gy - t * w[2 * a + 1]
            for i in range(8):
                gi = cG * w[i]
                hi = ca * w[8 + i]
                for j in range(i, 8):
                    Ko[i, j] += gi * w[j] + hi * w[8 + j]
            # u_c (Q + Q^T): (2a, 2b+1) += u_c (D_a D2_b - D2_a D_b), (2a+1, 2b) the negative
            for a in range(4):
                Da = dS[k, g, a]
                D2a = d2S[k, g, a]
                for b in range(a, 4):
                    q = uc * (Da * d2S[k, g, b] - D2a * dS[k, g, b])
                    Ko[2 * a, 2 * b + 1] += q
                    if b > a:
                        Ko[2 * a + 1, 2 * b] -= q
        else:
            cG = wEA[k, g]
            for i in range(8):
                fo[i] += s * w[i]
                gi = cG * w[i]
                for j in range(i, 8):
                    Ko[i, j] += gi * w[j]
        for a in range(4):  # s P_q
            sa = s * dS[k, g, a]
            for b in range(a, 4):
                p = sa * dS[k, g, b]
                Ko[2 * a, 2 * b] += p
                Ko[2 * a + 1, 2 * b + 1] += p
    if curvature == _LINEAR:
        _add_kb(ev, Kb, k, 1.0, fo)
        for i in range(8):
            for j in range(i, 8):
                Ko[i, j] += Kb[k, i, j]
    _mirror_upper(Ko)


@njit(cache=True)
def _damping_one(ev, evd, k, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fo):
    """fo (8,) Kelvin-Voigt damping force of element k at ev, velocities evd (8,)."""
    for i in range(8):
        fo[i] = 0.0
    bend = eta_b != 0.0 and curvature == _EXACT
    if eta_a != 0.0 or bend:
        for g in range(dS.shape[1]):
            rx, ry = _slope(ev, dS, k, g)
            vx, vy = _slope(evd, dS, k, g)
            if eta_a != 0.0:
                sa = eta_a * wEA[k, g] * (rx * vx + ry * vy)  # eta_a wEA (G . Ed)
                for a in range(4):
                    D = dS[k, g, a]
                    fo[2 * a] += sa * D * rx
                    fo[2 * a + 1] += sa * D * ry
            if bend:
                px, py = _slope(ev, d2S, k, g)
                wx, wy = _slope(evd, d2S, k, g)
                A = rx * rx + ry * ry
                cdot = vx * py - vy * px + rx * wy - ry * wx  # gc . Ed
                sb = eta_b * wEI[k, g] * cdot / (A * A * A)
                for a in range(4):
                    D = dS[k, g, a]
                    D2 = d2S[k, g, a]
                    fo[2 * a] += sb * (D * py - D2 * ry)
                    fo[2 * a + 1] += sb * (D2 * rx - D * px)
    if curvature == _LINEAR and eta_b != 0.0:
        _add_kb(evd, Kb, k, eta_b, fo)


@njit(cache=True)
def _damping_matrix_one(ev, k, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, Co, w):
    """Co (8, 8) = d fd / d Ed of element k at ev (8,); w (16,) scratch."""
    for i in range(8):
        for j in range(8):
            Co[i, j] = 0.0
    bend = eta_b != 0.0 and curvature == _EXACT
    if eta_a != 0.0 or bend:
        for g in range(dS.shape[1]):
            rx, ry = _slope(ev, dS, k, g)
            ca = eta_a * wEA[k, g]
            cb = 0.0
            if bend:
                px, py = _slope(ev, d2S, k, g)
                A = rx * rx + ry * ry
                cb = eta_b * wEI[k, g] / (A * A * A)
            for a in range(4):
                D = dS[k, g, a]
                w[2 * a] = D * rx
                w[2 * a + 1] = D * ry
                if bend:
                    D2 = d2S[k, g, a]
                    w[8 + 2 * a] = D * py - D2 * ry
                    w[9 + 2 * a] = D2 * rx - D * px
            for i in range(8):
                gi = ca * w[i]
                for j in range(i, 8):
                    Co[i, j] += gi * w[j]
            if bend:
                for i in range(8):
                    hi = cb * w[8 + i]
                    for j in range(i, 8):
                        Co[i, j] += hi * w[8 + j]
    if curvature == _LINEAR and eta_b != 0.0:
        for i in range(8):
            for j in range(i, 8):
                Co[i, j] += eta_b * Kb[k, i, j]
    _mirror_upper(Co)


# ------------------------------------------------------------------------------------ element sets
@njit(cache=True)
def element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, f):
    """f (n, 8) = dU/de at E (n, 8), as `ancf.internal_forces` (Eq. 14 + Eq. 17 or Eq. 16)."""
    for k in range(E.shape[0]):
        _force_one(E[k], k, dS, d2S, wEA, wEI, Kb, curvature, f[k])


@njit(cache=True)
def element_forces_tangent(E, dS, d2S, wEA, wEI, Kb, curvature, f, K):
    """f (n, 8) = dU/de and K (n, 8, 8) = df/de (exactly symmetric) at E (n, 8), as
    `ancf.internal_forces_and_tangent`."""
    w = np.empty(16)
    for k in range(E.shape[0]):
        _force_tangent_one(E[k], k, dS, d2S, wEA, wEI, Kb, curvature, f[k], K[k], w)


@njit(cache=True)
def element_damping(E, Ed, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fd):
    """fd (n, 8) Kelvin-Voigt belt damping force at E, Ed (n, 8) (module docstring); zeros when
    eta_a == eta_b == 0."""
    n = E.shape[0]
    if eta_a == 0.0 and eta_b == 0.0:
        fd[:, :] = 0.0
        return
    for k in range(n):
        _damping_one(E[k], Ed[k], k, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fd[k])


@njit(cache=True)
def element_damping_matrix(E, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, C):
    """C (n, 8, 8) = d fd / d Ed at E (n, 8): eta_a sum_q wEA G G^T + eta_b B (module docstring),
    symmetric positive semi-definite for eta_a, eta_b >= 0."""
    n = E.shape[0]
    if eta_a == 0.0 and eta_b == 0.0:
        C[:, :, :] = 0.0
        return
    w = np.empty(16)
    for k in range(n):
        _damping_matrix_one(E[k], k, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, C[k], w)


@njit(cache=True)
def element_strain_energy(E, dS, d2S, wEA, wEI, Kb, curvature, U):
    """U (n,) element strain energy at E (n, 8), as `ancf.strain_energy` (Eq. 13 + Eq. 16/17)."""
    n, nq, _ = dS.shape
    for k in range(n):
        ev = E[k]
        u = 0.0
        for g in range(nq):
            rx, ry = _slope(ev, dS, k, g)
            A = rx * rx + ry * ry
            eps = 0.5 * (A - 1.0)
            u += 0.5 * wEA[k, g] * (eps * eps)
            if curvature == _EXACT:
                px, py = _slope(ev, d2S, k, g)
                c = rx * py - ry * px
                u += 0.5 * wEI[k, g] * (c * c / (A * A * A))
        if curvature == _LINEAR:
            ub = 0.0
            for i in range(8):
                acc = 0.0
                for j in range(8):
                    acc += Kb[k, i, j] * ev[j]
                ub += ev[i] * acc
            u += 0.5 * ub
        U[k] = u


@njit(cache=True)
def element_min_axial_force(E, dS, EA, out):
    """out (n,) smallest second Piola-Kirchhoff axial force EA eps over each element's Gauss points
    at E (n, 8) (slack detection: < 0 means compression somewhere in the element)."""
    n, nq, _ = dS.shape
    for k in range(n):
        lo = np.inf
        for g in range(nq):
            rx, ry = _slope(E[k], dS, k, g)
            v = EA[k] * 0.5 * (rx * rx + ry * ry - 1.0)
            if v < lo:
                lo = v
        out[k] = lo


# ------------------------------------------------------------------------------------ reduced coordinates
def joint_selection(T: np.ndarray, idx: np.ndarray, n_dof: int) -> np.ndarray:
    """tsel (n_elem,) int64: -1 where element k has T[k] == [I8 | 0] exactly and idx[k, 8:] all
    equal the padding index n_dof (identity fast path), else k (its own row of T).

    T (n_elem, 8, m) and idx (n_elem, m) with m >= 8.
    """
    T = np.asarray(T)
    idx = np.asarray(idx)
    if T.ndim != 3 or T.shape[1] != 8 or T.shape[2] < 8:
        raise ValueError(f"T must have shape (n_elem, 8, m >= 8), got {T.shape}")
    if idx.shape != (T.shape[0], T.shape[2]):
        raise ValueError(f"idx must have shape {(T.shape[0], T.shape[2])}, got {idx.shape}")
    ident = np.zeros(T.shape[1:])
    ident[:, :8] = np.eye(8)
    ok = np.all(T == ident, axis=(1, 2)) & np.all(idx[:, 8:] == n_dof, axis=1)
    return np.where(ok, -1, np.arange(T.shape[0])).astype(np.int64)


@njit(cache=True)
def _gather_row(q_ext, T, idx, tsel, k, out):
    """out (8,) = T[k] q_ext[idx[k]] (identity path: q_ext[idx[k, :8]])."""
    if tsel[k] < 0:
        for i in range(8):
            out[i] = q_ext[idx[k, i]]
    else:
        m = T.shape[2]
        for i in range(8):
            acc = 0.0
            for j in range(m):
                acc += T[k, i, j] * q_ext[idx[k, j]]
            out[i] = acc


@njit(cache=True)
def _scatter_row(fk, T, idx, tsel, k, out):
    """out[idx[k]] += T[k]^T fk (identity path: out[idx[k, :8]] += fk)."""
    if tsel[k] < 0:
        for i in range(8):
            out[idx[k, i]] += fk[i]
    else:
        for j in range(T.shape[2]):
            acc = 0.0
            for i in range(8):
                acc += T[k, i, j] * fk[i]
            out[idx[k, j]] += acc


@njit(cache=True)
def _reduce_row(Kk, T, tsel, k, out, W):
    """out (m, m) = T[k]^T Kk T[k] for a symmetric Kk (8, 8), exactly symmetric; W (8, m) scratch.
    Identity path: Kk in the leading 8 x 8 block, zeros elsewhere."""
    m = T.shape[2]
    if tsel[k] < 0:
        for p in range(m):
            for j in range(m):
                out[p, j] = Kk[p, j] if (p < 8 and j < 8) else 0.0
        return
    for i in range(8):  # W = Kk T[k], skipping the zeros of T
        for j in range(m):
            W[i, j] = 0.0
    for l in range(8):
        for j in range(m):
            t = T[k, l, j]
            if t != 0.0:
                for i in range(8):
                    W[i, j] += Kk[i, l] * t
    for p in range(m):
        for j in range(p, m):
            acc = 0.0
            for i in range(8):
                acc += T[k, i, p] * W[i, j]
            out[p, j] = acc
            out[j, p] = acc


@njit(cache=True)
def gather(q_ext, e0, T, idx, tsel, E):
    """E (n, 8) = e0 + T q_ext[idx] per element (q_ext (n_dof + 1,), q_ext[n_dof] = 0)."""
    for k in range(E.shape[0]):
        row = E[k]
        _gather_row(q_ext, T, idx, tsel, k, row)
        for i in range(8):
            row[i] += e0[k, i]


@njit(cache=True)
def gather_velocity(v_ext, T, idx, tsel, Ed):
    """Ed (n, 8) = T v_ext[idx] per element (element velocities: `gather` without the offset)."""
    for k in range(Ed.shape[0]):
        _gather_row(v_ext, T, idx, tsel, k, Ed[k])


@njit(cache=True)
def scatter_vector(fe, T, idx, tsel, out):
    """out (n_dof + 1,) += T^T fe per element, fe (n, 8) (accumulates; out[n_dof] is padding)."""
    for k in range(fe.shape[0]):
        _scatter_row(fe[k], T, idx, tsel, k, out)


@njit(cache=True)
def reduce_blocks(Ke, T, tsel, out):
    """out (n, m, m) = T^T Ke T per element for symmetric Ke (n, 8, 8); out is exactly symmetric."""
    W = np.empty((8, T.shape[2]))
    for k in range(Ke.shape[0]):
        _reduce_row(Ke[k], T, tsel, k, out[k], W)


@njit(cache=True)
def reduced_force(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out):
    """f_out (n_dof + 1,) = sum_e T^T f_e(e0 + T q_ext[idx]), the reduced elastic force
    (overwritten; f_out[n_dof] is padding)."""
    ev = np.empty(8)
    fk = np.empty(8)
    f_out[:] = 0.0
    for k in range(T.shape[0]):
        _gather_row(q_ext, T, idx, tsel, k, ev)
        for i in range(8):
            ev[i] += e0[k, i]
        _force_one(ev, k, dS, d2S, wEA, wEI, Kb, curvature, fk)
        _scatter_row(fk, T, idx, tsel, k, f_out)


@njit(cache=True)
def reduced_force_and_tangent_blocks(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out,
                                     blocks_out):
    """The reduced elastic force f_out (n_dof + 1,) (overwritten, as `reduced_force`) and the
    tangent blocks blocks_out (n, m, m) = T^T K_e T, fused per element (no (n, 8, 8) temporaries)."""
    ev = np.empty(8)
    fk = np.empty(8)
    Kk = np.empty((8, 8))
    w = np.empty(16)
    W = np.empty((8, T.shape[2]))
    f_out[:] = 0.0
    for k in range(T.shape[0]):
        _gather_row(q_ext, T, idx, tsel, k, ev)
        for i in range(8):
            ev[i] += e0[k, i]
        _force_tangent_one(ev, k, dS, d2S, wEA, wEI, Kb, curvature, fk, Kk, w)
        _scatter_row(fk, T, idx, tsel, k, f_out)
        _reduce_row(Kk, T, tsel, k, blocks_out[k], W)
