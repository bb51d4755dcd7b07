"""Compiled (numba) belt kernel: the planar ANCF element of `ancf`, element by element, and the
reduced-coordinate gather/scatter of the drive model.

`ancf` is the reference implementation (vectorized numpy); this module computes the same quantities
with plain loops, one element at a time, without allocating in the element loop, so that Newton
solvers and the compiled time stepper (`integrator`) can call it.  Every function is
``@njit(**KERNEL)`` except the set-up helpers `tables_from_elements` and `joint_selection`.

Nomenclature (as `ancf`, paper "Modelling and dynamic analysis of belt drive system by hybrid
flexible multibody method"):

* Eq. 1-6   r(x) = S(x) e, e = [r(0), r'(0), r(L), r'(L)] (8,); ``E`` (n_elem, 8) holds one e per
            row, index ``2 a + i`` for shape function a in 0..3 and component i in 0..1.
* ``D = dS[k, q]`` (4,) ds/dx and ``D2 = d2S[k, q]`` (4,) d2s/dx2 at Gauss point q of element k,
  so r' = sum_a D_a e_a and r'' = sum_a D2_a e_a with e_a = (e[2a], e[2a+1]).
* ``wEA[k, q]`` = Gauss weight * L * EA, ``wEI[k, q]`` = Gauss weight * L * EI (integration weights
  in x), ``Kb[k]`` the constant bending matrix EI int S''^T S'' dx of Eq. 17 (zeros unless "linear"),
  kb (x) I2 like every matrix of the planar element: the force and energy loops read only its entries
  (2a + c, 2b + c) (`tables_from_elements` checks the others are zeros).
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

Axial laws (`AXIAL_LAW_CODE`, the trailing argument ``law`` of the force, tangent and energy kernels,
default 0): 0 "green-lagrange" (Eqs. 12-14 above), 1 "linear", N = EA (lambda - 1), lambda = sqrt(A):
the virtual work of N d lambda (d lambda = G . de / lambda) gives f_l = sum_q s G_q with
s = wEA (1 - 1/lambda), K_l = sum_q [cG G_q G_q^T + s P_q] with cG = 2 ds/dA = wEA / lambda^3, and
U_l = sum_q wEA (lambda - 1)^2 / 2 (as `ancf` with axial_law="linear"). The Kelvin-Voigt damping
and the slack test (`element_min_axial_force`, its sign is N's for both laws) stay as written.

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

from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from beltdyn.jitcache import configure, kernel_options


configure()  # where numba caches the kernels (the package folder, else a user cache folder): before numba loads
from numba import njit  # noqa: E402

from beltdyn.model import ancf
from beltdyn.model.joints import joint_selection  # noqa: F401  (set-up helper, pure numpy)

KERNEL = kernel_options()  # the njit options of this module's kernels (numba loaded)

__all__ = [
    "CURVATURE_CODE",
    "AXIAL_LAW_CODE",
    "KernelTables",
    "Scratch",
    "scratch",
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
AXIAL_LAW_CODE = {"green-lagrange": 0, "linear": 1}
_LINEAR_LAW = 1
_LINEAR = 1
_EXACT = 2


@dataclass(frozen=True, kw_only=True, eq=False)
class KernelTables:
    """The kernel's tables of an `ancf.ElementSet` (writable float64 C-contiguous copies).

    Shapes (n = n_elem, q = n_gauss): ``dS``, ``d2S`` (n, q, 4); ``wEA``, ``wEI`` (n, q) Gauss weight
    * L * EA and * EI; ``EA`` (n,); ``Kb`` (n, 8, 8) linear bending matrix (zeros unless curvature
    "linear"); ``curvature`` the code of `CURVATURE_CODE`; ``axial_law`` the code of `AXIAL_LAW_CODE`
    (the ``law`` argument of the force, tangent and energy kernels).
    """

    dS: np.ndarray
    d2S: np.ndarray
    wEA: np.ndarray
    wEI: np.ndarray
    EA: np.ndarray
    Kb: np.ndarray
    curvature: int
    axial_law: int = 0

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
    if np.any(el.K_bend[:, 0::2, 1::2]) or np.any(el.K_bend[:, 1::2, 0::2]):
        raise ValueError("the bending matrix couples x and y components: not kb (x) I2")
    return KernelTables(dS=_plain(el.dS), d2S=_plain(el.d2S), wEA=_plain(el.wL * el.EA[:, None]),
                        wEI=_plain(el.wL * el.EI[:, None]), EA=_plain(el.EA), Kb=_plain(el.K_bend),
                        curvature=int(CURVATURE_CODE[el.curvature]), axial_law=int(AXIAL_LAW_CODE[el.axial_law]))


# The functions allocate nothing: a cached numba library whose code allocates (np.empty) makes numba
# import its array modules when it is loaded (~30 ms of a short command's start); the callers hand
# in this scratch. E, fe (n_elem, 8), Ke (n_elem, 8, 8): element states, forces, matrices; cf (5, n_gauss),
# ce (6, n_gauss), h (n_gauss, 8): per-element Gauss-point coefficients; W (8, m): T^T Ke T's product.
Scratch = namedtuple("Scratch", ["E", "fe", "Ke", "cf", "ce", "h", "W"])


def scratch(n_elem: int, n_gauss: int, m: int = 8) -> Scratch:
    """The kernels' `Scratch` for n_elem elements of n_gauss Gauss points and m reduced coordinates each."""
    return Scratch(E=np.empty((n_elem, 8)), fe=np.empty((n_elem, 8)), Ke=np.empty((n_elem, 8, 8)),
                   cf=np.empty((5, n_gauss)), ce=np.empty((6, n_gauss)), h=np.empty((n_gauss, 8)), W=np.empty((8, m)))


# ------------------------------------------------------------------------------------ element sets
# Implementation note (measured with numba 0.68): helpers that take arrays and contain loops or
# branches kept reference-count operations inside the element loop (inlined or not), 2-6x slower
# than flat code; so the loops are written out flat and only the branch- and loop-free `_slope`
# is shared.  Scratch arrays come from the caller (`Scratch`), never allocated here.
@njit(inline="always", **KERNEL)
def _slope(E, r, tab, k, g):
    """sum_a tab[k, g, a] e_a for e = E[r]: r' (tab = dS) or r'' (tab = d2S) at Gauss point g."""
    x = tab[k, g, 0] * E[r, 0] + tab[k, g, 1] * E[r, 2] + tab[k, g, 2] * E[r, 4] + tab[k, g, 3] * E[r, 6]
    y = tab[k, g, 0] * E[r, 1] + tab[k, g, 1] * E[r, 3] + tab[k, g, 2] * E[r, 5] + tab[k, g, 3] * E[r, 7]
    return x, y


@njit(inline="always", **KERNEL)
def _axial_coefficients(wEA, A, law):
    """(s, cG) of one Gauss point: the coefficient of G in the axial force and of G G^T in its tangent
    (module docstring: wEA eps and wEA for "green-lagrange", wEA (1 - 1/lambda) and wEA / lambda^3 for
    "linear")."""
    if law == _LINEAR_LAW:
        il = 1.0 / np.sqrt(A)
        return wEA * (1.0 - il), wEA * (il * il * il)
    return 0.5 * wEA * (A - 1.0), wEA


@njit(inline="always", **KERNEL)
def _add_gauss_force(out, k, g, dS, d2S, s, u, rx, ry, px, py, bend):
    """out[k] (8,) += the Gauss point g's part of an element force: s G + u gc (bend) or s G, with
    G = D (x) r' the axial gradient and gc = D (x) (r''_y, -r''_x) + D2 (x) (-r'_y, r'_x) the
    curvature's (`element_forces`: s = wEA eps, u = wEI c / A^3; `element_damping`: their rates)."""
    for a in range(4):
        D = dS[k, g, a]
        if bend:
            D2 = d2S[k, g, a]
            out[k, 2 * a] += s * D * rx + u * (D * py - D2 * ry)
            out[k, 2 * a + 1] += s * D * ry + u * (D2 * rx - D * px)
        else:
            out[k, 2 * a] += s * D * rx
            out[k, 2 * a + 1] += s * D * ry


@njit(inline="always", **KERNEL)
def _kronecker_blocks(dS, k, nq, cf, row, out):
    """out[k] (8, 8) = sum_g (c_g (x) D_g D_g^T), both triangles: the 2 x 2 block of shape functions
    (a, b) is sum_g D_ga D_gb [[cxx, cxy], [cxy, cyy]]_g, with cxx, cxy, cyy = cf[row], cf[row + 1],
    cf[row + 2] (nq,) the Gauss-point coefficients of element k (an axial stiffness or damping matrix:
    `element_forces_tangent`, `element_damping_matrix`)."""
    for a in range(4):
        for b in range(a, 4):
            kxx = 0.0
            kxy = 0.0
            kyy = 0.0
            for g in range(nq):
                DD = dS[k, g, a] * dS[k, g, b]
                kxx += cf[row, g] * DD
                kxy += cf[row + 1, g] * DD
                kyy += cf[row + 2, g] * DD
            out[k, 2 * a, 2 * b] = kxx
            out[k, 2 * a, 2 * b + 1] = kxy
            out[k, 2 * a + 1, 2 * b] = kxy
            out[k, 2 * a + 1, 2 * b + 1] = kyy
            if b > a:
                out[k, 2 * b, 2 * a] = kxx
                out[k, 2 * b + 1, 2 * a] = kxy
                out[k, 2 * b, 2 * a + 1] = kxy
                out[k, 2 * b + 1, 2 * a + 1] = kyy


@njit(**KERNEL)
def element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, f, law=0):
    """f (n, 8) = dU/de at E (n, 8), as `ancf.internal_forces` (Eq. 14 + Eq. 17 or Eq. 16; law: the
    axial law's code, `AXIAL_LAW_CODE`)."""
    n, nq, _ = dS.shape
    for k in range(n):
        for i in range(8):
            f[k, i] = 0.0
        for g in range(nq):
            rx, ry = _slope(E, k, dS, k, g)
            A = rx * rx + ry * ry
            s = _axial_coefficients(wEA[k, g], A, law)[0]  # wEA eps (green-lagrange)
            if curvature == _EXACT:
                px, py = _slope(E, k, d2S, k, g)
                c = rx * py - ry * px
                iA = 1.0 / A
                uc = wEI[k, g] * c * (iA * iA * iA)
                s -= 3.0 * uc * c * iA  # + 2 u_A (gA = 2 G)
                _add_gauss_force(f, k, g, dS, d2S, s, uc, rx, ry, px, py, True)
            else:
                _add_gauss_force(f, k, g, dS, d2S, s, 0.0, rx, ry, 0.0, 0.0, False)
        if curvature == _LINEAR:
            for i in range(8):
                acc = 0.0
                for j in range(i % 2, 8, 2):  # Kb = kb (x) I2: the other parity is zeros
                    acc += Kb[k, i, j] * E[k, j]
                f[k, i] += acc


@njit(**KERNEL)
def element_forces_tangent(E, dS, d2S, wEA, wEI, Kb, curvature, f, K, work, law=0):
    """f (n, 8) = dU/de and K (n, 8, 8) = df/de (exactly symmetric) at E (n, 8), as
    `ancf.internal_forces_and_tangent` (work: `Scratch`, its cf, ce, h).

    Per element, a first pass over the Gauss points stores their coefficients; then every entry is
    one sum over the Gauss points.  The axial part has Kronecker structure: the (i, j) component
    block of sum_q [cG G G^T + s P_q] is sum_q (cG r'_i r'_j + s delta_ij) D D^T.
    """
    n, nq, _ = dS.shape
    exact = curvature == _EXACT
    cf = work.cf  # s r'_x, s r'_y, cG r'_x r'_x + s, cG r'_x r'_y, cG r'_y r'_y + s
    ce = work.ce  # "exact": u_c, a = wEI/A^3, u_c r''_y, u_c r'_y, u_c r'_x, u_c r''_x
    h = work.h  # "exact": h = gc - 6 c/A G
    for k in range(n):
        for g in range(nq):
            rx, ry = _slope(E, k, dS, k, g)
            A = rx * rx + ry * ry
            # s: coefficient of P_q in the secant matrix, cG of G G^T (wEA eps, wEA: green-lagrange)
            s, cG = _axial_coefficients(wEA[k, g], A, law)
            if exact:
                px, py = _slope(E, k, d2S, k, g)
                c = rx * py - ry * px
                iA = 1.0 / A
                ca = wEI[k, g] * (iA * iA * iA)
                uc = ca * c
                s -= 3.0 * uc * c * iA
                cG -= 12.0 * uc * c * iA * iA  # wEA - 12 wEI c^2 / A^5
                t = 6.0 * c * iA
                for a in range(4):
                    D = dS[k, g, a]
                    D2 = d2S[k, g, a]
                    h[g, 2 * a] = D * py - D2 * ry - t * D * rx
                    h[g, 2 * a + 1] = D2 * rx - D * px - t * D * ry
                ce[0, g] = uc
                ce[1, g] = ca
                ce[2, g] = uc * py
                ce[3, g] = uc * ry
                ce[4, g] = uc * rx
                ce[5, g] = uc * px
            cf[0, g] = s * rx
            cf[1, g] = s * ry
            cf[2, g] = cG * rx * rx + s
            cf[3, g] = cG * rx * ry
            cf[4, g] = cG * ry * ry + s
        for a in range(4):
            fx = 0.0
            fy = 0.0
            for g in range(nq):
                fx += dS[k, g, a] * cf[0, g]
                fy += dS[k, g, a] * cf[1, g]
            f[k, 2 * a] = fx
            f[k, 2 * a + 1] = fy
        _kronecker_blocks(dS, k, nq, cf, 2, K)
        if curvature == _LINEAR:
            for i in range(8):
                fi = 0.0
                for j in range(8):
                    fi += Kb[k, i, j] * E[k, j]
                f[k, i] += fi
                for j in range(i, 8):
                    kb = Kb[k, i, j]
                    K[k, i, j] += kb
                    if j > i:
                        K[k, j, i] += kb
        elif exact:
            for a in range(4):  # f += u_c gc
                fx = 0.0
                fy = 0.0
                for g in range(nq):
                    D = dS[k, g, a]
                    D2 = d2S[k, g, a]
                    fx += D * ce[2, g] - D2 * ce[3, g]
                    fy += D2 * ce[4, g] - D * ce[5, g]
                f[k, 2 * a] += fx
                f[k, 2 * a + 1] += fy
            for i in range(8):  # a h h^T
                for j in range(i, 8):
                    v = 0.0
                    for g in range(nq):
                        v += ce[1, g] * h[g, i] * h[g, j]
                    K[k, i, j] += v
                    if j > i:
                        K[k, j, i] += v
            # u_c (Q + Q^T): (2a, 2b+1) and (2b+1, 2a) += q_ab, (2a+1, 2b) and (2b, 2a+1) -= q_ab,
            # q_ab = sum_q u_c (D_a D2_b - D2_a D_b) (zero for a == b)
            for a in range(4):
                for b in range(a + 1, 4):
                    qq = 0.0
                    for g in range(nq):
                        qq += ce[0, g] * (dS[k, g, a] * d2S[k, g, b] - d2S[k, g, a] * dS[k, g, b])
                    K[k, 2 * a, 2 * b + 1] += qq
                    K[k, 2 * b + 1, 2 * a] += qq
                    K[k, 2 * a + 1, 2 * b] -= qq
                    K[k, 2 * b, 2 * a + 1] -= qq


@njit(**KERNEL)
def element_damping(E, Ed, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fd):
    """fd (n, 8) Kelvin-Voigt belt damping force at E, Ed (n, 8) (module docstring); zeros when
    eta_a == eta_b == 0."""
    n, nq, _ = dS.shape
    fd[:, :] = 0.0
    if eta_a == 0.0 and eta_b == 0.0:
        return
    bend = eta_b != 0.0 and curvature == _EXACT
    if eta_a != 0.0 or bend:
        for k in range(n):
            for g in range(nq):
                rx, ry = _slope(E, k, dS, k, g)
                vx, vy = _slope(Ed, k, dS, k, g)
                sa = eta_a * wEA[k, g] * (rx * vx + ry * vy)  # eta_a wEA (G . Ed)
                if bend:
                    px, py = _slope(E, k, d2S, k, g)
                    wx, wy = _slope(Ed, k, d2S, k, g)
                    A = rx * rx + ry * ry
                    cdot = vx * py - vy * px + rx * wy - ry * wx  # gc . Ed
                    sb = eta_b * wEI[k, g] * cdot / (A * A * A)
                    _add_gauss_force(fd, k, g, dS, d2S, sa, sb, rx, ry, px, py, True)
                else:
                    _add_gauss_force(fd, k, g, dS, d2S, sa, 0.0, rx, ry, 0.0, 0.0, False)
    if curvature == _LINEAR and eta_b != 0.0:
        for k in range(n):
            for i in range(8):
                acc = 0.0
                for j in range(i % 2, 8, 2):  # Kb = kb (x) I2
                    acc += Kb[k, i, j] * Ed[k, j]
                fd[k, i] += eta_b * acc


@njit(**KERNEL)
def element_damping_matrix(E, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, C, work):
    """C (n, 8, 8) = d fd / d Ed at E (n, 8): eta_a sum_q wEA G G^T + eta_b B (module docstring),
    exactly symmetric, positive semi-definite for eta_a, eta_b >= 0 (same scheme as
    `element_forces_tangent`; work: `Scratch`, its cf and h)."""
    n, nq, _ = dS.shape
    if eta_a == 0.0 and eta_b == 0.0:
        C[:, :, :] = 0.0
        return
    bend = eta_b != 0.0 and curvature == _EXACT
    cf = work.cf  # eta_a wEA r'_x r'_x, .. r'_x r'_y, .. r'_y r'_y; eta_b wEI/A^3 (rows 0-3)
    gc = work.h
    for k in range(n):
        for g in range(nq):
            rx, ry = _slope(E, k, dS, k, g)
            ca = eta_a * wEA[k, g]
            cf[0, g] = ca * rx * rx
            cf[1, g] = ca * rx * ry
            cf[2, g] = ca * ry * ry
            if bend:
                px, py = _slope(E, k, d2S, k, g)
                A = rx * rx + ry * ry
                cf[3, g] = eta_b * wEI[k, g] / (A * A * A)
                for a in range(4):
                    D = dS[k, g, a]
                    D2 = d2S[k, g, a]
                    gc[g, 2 * a] = D * py - D2 * ry
                    gc[g, 2 * a + 1] = D2 * rx - D * px
        _kronecker_blocks(dS, k, nq, cf, 0, C)
        if curvature == _LINEAR and eta_b != 0.0:
            for i in range(8):
                for j in range(i, 8):
                    kb = eta_b * Kb[k, i, j]
                    C[k, i, j] += kb
                    if j > i:
                        C[k, j, i] += kb
        elif bend:
            for i in range(8):
                for j in range(i, 8):
                    v = 0.0
                    for g in range(nq):
                        v += cf[3, g] * gc[g, i] * gc[g, j]
                    C[k, i, j] += v
                    if j > i:
                        C[k, j, i] += v


@njit(**KERNEL)
def element_strain_energy(E, dS, d2S, wEA, wEI, Kb, curvature, U, law=0):
    """U (n,) element strain energy at E (n, 8), as `ancf.strain_energy` (Eq. 13 + Eq. 16/17)."""
    n, nq, _ = dS.shape
    for k in range(n):
        u = 0.0
        for g in range(nq):
            rx, ry = _slope(E, k, dS, k, g)
            A = rx * rx + ry * ry
            eps = np.sqrt(A) - 1.0 if law == _LINEAR_LAW else 0.5 * (A - 1.0)  # (linear: lambda - 1)
            u += 0.5 * wEA[k, g] * (eps * eps)
            if curvature == _EXACT:
                px, py = _slope(E, k, d2S, k, g)
                c = rx * py - ry * px
                u += 0.5 * wEI[k, g] * (c * c / (A * A * A))
        if curvature == _LINEAR:
            ub = 0.0
            for i in range(8):
                acc = 0.0
                for j in range(i % 2, 8, 2):  # Kb = kb (x) I2
                    acc += Kb[k, i, j] * E[k, j]
                ub += E[k, i] * acc
            u += 0.5 * ub
        U[k] = u


@njit(**KERNEL)
def element_min_axial_force(E, dS, EA, out):
    """out (n,) smallest second Piola-Kirchhoff axial force EA eps over each element's Gauss points
    at E (n, 8) (slack detection: < 0 means compression somewhere in the element)."""
    n, nq, _ = dS.shape
    for k in range(n):
        lo = np.inf
        for g in range(nq):
            rx, ry = _slope(E, k, dS, k, g)
            v = EA[k] * 0.5 * (rx * rx + ry * ry - 1.0)
            if v < lo:
                lo = v
        out[k] = lo


# ------------------------------------------------------------------------------------ reduced coordinates
@njit(**KERNEL)
def gather(q_ext, e0, T, idx, tsel, E):
    """E (n, 8) = e0 + T q_ext[idx] per element (q_ext (n_dof + 1,), q_ext[n_dof] = 0)."""
    n, _, m = T.shape
    for k in range(n):
        if tsel[k] < 0:
            for i in range(8):
                E[k, i] = e0[k, i] + q_ext[idx[k, i]]
        else:
            for i in range(8):
                acc = 0.0
                for j in range(m):
                    acc += T[k, i, j] * q_ext[idx[k, j]]
                E[k, i] = e0[k, i] + acc


@njit(**KERNEL)
def gather_velocity(v_ext, T, idx, tsel, Ed):
    """Ed (n, 8) = T v_ext[idx] per element (element velocities: `gather` without the offset)."""
    n, _, m = T.shape
    for k in range(n):
        if tsel[k] < 0:
            for i in range(8):
                Ed[k, i] = v_ext[idx[k, i]]
        else:
            for i in range(8):
                acc = 0.0
                for j in range(m):
                    acc += T[k, i, j] * v_ext[idx[k, j]]
                Ed[k, i] = acc


@njit(**KERNEL)
def scatter_vector(fe, T, idx, tsel, out):
    """out (n_dof + 1,) += T^T fe per element, fe (n, 8) (accumulates; out[n_dof] is padding)."""
    n, _, m = T.shape
    for k in range(n):
        if tsel[k] < 0:
            for i in range(8):
                out[idx[k, i]] += fe[k, i]
        else:
            for j in range(m):
                acc = 0.0
                for i in range(8):
                    acc += T[k, i, j] * fe[k, i]
                out[idx[k, j]] += acc


@njit(**KERNEL)
def reduce_blocks(Ke, T, tsel, out, W):
    """out (n, m, m) = T^T Ke T per element for symmetric Ke (n, 8, 8), exactly symmetric (W (8, m):
    scratch). Identity path: Ke in the leading 8 x 8 block, zeros elsewhere."""
    n, _, m = T.shape
    for k in range(n):
        if tsel[k] < 0:
            for p in range(8):
                for j in range(8):
                    out[k, p, j] = Ke[k, p, j]
                for j in range(8, m):
                    out[k, p, j] = 0.0
            for p in range(8, m):
                for j in range(m):
                    out[k, p, j] = 0.0
            continue
        for i in range(8):  # W = Ke T, skipping the zeros of T
            for j in range(m):
                W[i, j] = 0.0
        for l in range(8):
            for j in range(m):
                t = T[k, l, j]
                if t != 0.0:
                    for i in range(8):
                        W[i, j] += Ke[k, i, l] * t
        for p in range(m):
            for j in range(p, m):
                acc = 0.0
                for i in range(8):
                    acc += T[k, i, p] * W[i, j]
                out[k, p, j] = acc
                out[k, j, p] = acc


@njit(**KERNEL)
def reduced_force(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out, work, law=0):
    """f_out (n_dof + 1,) = sum_e T^T f_e(e0 + T q_ext[idx]), the reduced elastic force
    (overwritten; f_out[n_dof] is padding); work: `Scratch`, its E and fe."""
    E = work.E
    fe = work.fe
    gather(q_ext, e0, T, idx, tsel, E)
    element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, fe, law)
    f_out[:] = 0.0
    scatter_vector(fe, T, idx, tsel, f_out)


@njit(**KERNEL)
def reduced_force_and_tangent_blocks(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out,
                                     blocks_out, work, law=0):
    """The reduced elastic force f_out (n_dof + 1,) (overwritten, as `reduced_force`) and the
    tangent blocks blocks_out (n, m, m) = T^T K_e T of the Newton solvers, in one call (work:
    `Scratch`)."""
    E = work.E
    fe = work.fe
    Ke = work.Ke
    gather(q_ext, e0, T, idx, tsel, E)
    element_forces_tangent(E, dS, d2S, wEA, wEI, Kb, curvature, fe, Ke, work, law)
    f_out[:] = 0.0
    scatter_vector(fe, T, idx, tsel, f_out)
    reduce_blocks(Ke, T, tsel, blocks_out, work.W)
