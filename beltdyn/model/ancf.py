"""Planar ANCF beam element (Berzeri & Shabana 2000), vectorized over elements x Gauss points.

Nomenclature follows the paper "Modelling and dynamic analysis of belt drive system by hybrid
flexible multibody method":

* Eq. 1   r(x) = S(x) e                      position of the material point at reference x
* Eq. 2   S = [s1 I, s2 I, s3 I, s4 I]       I = 2x2 identity, S is 2 x 8
* Eq. 3   s1 = 1 - 3 xi^2 + 2 xi^3,  s2 = L (xi - 2 xi^2 + xi^3),
          s3 = 3 xi^2 - 2 xi^3,      s4 = L (xi^3 - xi^2),        xi = x / L
* Eq. 4-6 e = [r(0), r'(0), r(L), r'(L)] (8,), so ``e.reshape(4, 2)`` has rows pos0, grad0,
          pos1, grad1 that pair with s1..s4
* Eq. 7   M = int rho S^T S dx               constant mass matrix
* Eq. 8   Q_g = int rho S^T g dx             generalized gravity force
* Eq. 12  eps = (r'.r' - 1) / 2              Green-Lagrange axial strain, r' = dr/dx
* Eq. 13-14  U_l = 1/2 int EA eps^2 dx,  Q_l = int EA eps S'^T S' e dx
* Eq. 15-16  kappa = (r' x r'') / |r'|^3,  U_t = 1/2 int EI kappa^2 dx   ("exact" model)
* Eq. 17  Q_t = EI int S''^T S'' dx e        ("linear" model, constant matrix, the default)

Axial transport (the running belt, beyond the paper; `transport_matrices`). A span is fixed in space
between its tangent points while the material flows through it at the rate c (undeformed length per
second, so the mass flow is rho c): x is a mesh (Eulerian/ALE) coordinate, and the material point at
x moves with V = dr/dt + c r'. The kinetic energy of an element is then

    T = 1/2 int rho |S e' + c S' e|^2 dx = 1/2 e'^T M e' + c e'^T A e + 1/2 c^2 e^T B e,
    A = int rho S^T S' dx,   B = int rho S'^T S' dx          (constant 8 x 8 matrices),

and Lagrange's equations give the transport terms of the element's equation of motion

    M e'' + c G e' + c' A e - c^2 B e + dU/de = Q,     G = A - A^T  (skew: gyroscopic, no work),

-c^2 B the centripetal ("rho v^2") stiffness. The boundary momentum flux rho c V at the span's ends is
left out on purpose: it is the flux into the next control volume (the wrap), and summed over the belt
loop the fluxes cancel (the material velocity is continuous at a tangent point), so this is the
closed loop's Lagrangian (see `running` for what that means for the span tension and hub loads).

Conventions: ``n_elem`` elements, ``n_qp`` Gauss points per element, ``n_pts`` evaluation points.
Every 8-vector is ordered like ``e`` (node-major, then x/y), i.e. index ``2 * a + i`` for shape
function ``a`` in 0..3 and component ``i`` in 0..1; an 8 x 8 matrix uses the same order on both
sides.  The Kronecker product ``B (x) I2`` of a 4 x 4 matrix ``B`` therefore places ``B[a, b]`` at
``[2a + i, 2b + i]``.

Implementation notes (the tangent is the hot kernel of the Newton solver and time integrator):
with ``D`` the ``(n_elem, n_qp, 4)`` table of ds/dx and ``E = e.reshape(n_elem, 4, 2)``,
``r' = D @ E``.  Writing ``P_q = (D_q D_q^T) (x) I2`` (precomputed, Gauss weight not included) and
``G_q = S'^T r' = D_q (x) r'_q = P_q e``, the axial part is

    f_l = sum_q w_q EA eps_q G_q = (sum_q w_q EA eps_q P_q) e
    K_l = sum_q w_q EA [ G_q G_q^T + eps_q P_q ]

so the force is the "secant" matrix applied to ``e`` and the tangent adds one rank-n_qp term.
The axial integrand eps S'^T r' is a polynomial of degree 8 in xi: 5 Gauss points integrate it
exactly.  The exact-curvature energy density u = EI/2 c^2/A^3 (c = r'^T J r'', J = [[0, 1],
[-1, 0]], A = r'.r') is not polynomial; it is integrated with the same ``n_gauss`` points.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field

import numpy as np

from beltdyn.model import barlaw

__all__ = [
    "CURVATURE_MODELS",
    "ElementSet",
    "make_elements",
    "empty_elements",
    "shape_functions",
    "mass_matrices",
    "transport_matrices",
    "gravity_forces",
    "internal_forces",
    "internal_forces_and_tangent",
    "strain_energy",
    "positions",
    "slopes",
    "axial_strain",
    "axial_force",
    "axial_force_gradient",
]

CURVATURE_MODELS = ("linear", "exact", "none")

# Gauss rule used for the constant matrices (mass: degree 6, bending: degree 2, gravity: degree 3).
# Four points integrate degree 7 exactly, independent of the user's n_gauss.
_N_GAUSS_CONST = 4
_MAX_GAUSS = 64


@functools.lru_cache(maxsize=None)
def _gauss01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1] (weights sum to 1); cached, read-only."""
    x, w = np.polynomial.legendre.leggauss(n)
    return _readonly(0.5 * (x + 1.0)), _readonly(0.5 * w)


def _kron_i2(a: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """(..., 4, 4) (x) (2, 2) -> (..., 8, 8) with index order (a, i, b, j)."""
    return (a[..., :, None, :, None] * m2[None, :, None, :]).reshape(*a.shape[:-2], 8, 8)


def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only C-contiguous copy (never freezes an array the caller still owns)."""
    a = np.array(a, dtype=float, order="C", copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, kw_only=True, eq=False)
class ElementSet:
    """``n_elem`` planar ANCF beam elements; all arrays are precomputed by `make_elements`.

    Arrays are read-only.  Shapes (``n = n_elem``, ``q = n_gauss``):

    * ``length, EA, EI, rho``: ``(n,)`` reference length [m], axial stiffness [N], bending
      stiffness [N m^2], mass per unit reference length [kg/m].
    * ``curvature``: one of `CURVATURE_MODELS`; "linear" = Eq. 17 (default), "exact" = Eq. 15-16,
      "none" = no bending energy (a cable).
    * ``n_gauss``: Gauss points per element for the axial and exact-curvature integrals.
    * ``gauss_xi``: ``(q,)`` Gauss abscissae in [0, 1].
    * ``wL``: ``(n, q)`` Gauss weight times element length (integration weight in x).
    * ``dS``: ``(n, q, 4)`` ds/dx at the Gauss points (the ``D`` table).
    * ``d2S``: ``(n, q, 4)`` d2s/dx2 at the Gauss points.
    * ``K_bend``: ``(n, 8, 8)`` constant linear bending matrix EI int S''^T S'' dx (Eq. 17); zeros
      unless ``curvature == "linear"``.
    * ``mass``: ``(n, 8, 8)`` constant mass matrix (Eq. 7).
    * ``gravity_shape``: ``(n, 4)`` int rho s dx, so Q_g = gravity_shape (x) g (Eq. 8).
    """

    length: np.ndarray
    EA: np.ndarray
    EI: np.ndarray
    rho: np.ndarray
    curvature: str
    n_gauss: int
    gauss_xi: np.ndarray
    wL: np.ndarray
    dS: np.ndarray
    d2S: np.ndarray
    K_bend: np.ndarray
    mass: np.ndarray
    gravity_shape: np.ndarray
    # Kernel tables (private; see the module docstring for the algebra):
    # _wEA, _wEI: (n, q) w L EA and w L EI;  _half_wEA = 0.5 * _wEA.
    # _D8: (n, q, 8) ds/dx repeated per component ([D0, D0, D1, D1, ...]), so that
    #      G_q = D_q (x) r'_q = _D8 * tile(r'_q, 4);  _D8_sqrt_wEA = sqrt(w L EA) * _D8.
    # _D2_8: (n, q, 8) d2s/dx2 repeated likewise ("exact" only, else (n, 0, 8)).
    # _DT, _D2T: (n, 4, q) contiguous transposes of dS and d2S.
    # _PQ: (n, q, 64) flattened P_q = (D_q D_q^T) (x) I2; for "exact" (n, 2q, 64) with the
    #      q matrices Q_q + Q_q^T appended, Q_q = (D_q D2_q^T) (x) J.
    _wEA: np.ndarray = field(repr=False)
    _half_wEA: np.ndarray = field(repr=False)
    _wEI: np.ndarray = field(repr=False)
    _D8: np.ndarray = field(repr=False)
    _D8_sqrt_wEA: np.ndarray = field(repr=False)
    _D2_8: np.ndarray = field(repr=False)
    _DT: np.ndarray = field(repr=False)
    _D2T: np.ndarray = field(repr=False)
    _PQ: np.ndarray = field(repr=False)
    # the axial law (`barlaw.LAWS`): "green-lagrange" (Eqs. 12-14) or "linear" (N = EA (|r'| - 1))
    axial_law: str = "green-lagrange"

    @property
    def n_elem(self) -> int:
        """Number of elements."""
        return self.length.shape[0]


def _broadcast_property(name: str, value, n: int) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    elif a.shape != (n,):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    return a


def _make_elements_all(
    length, EA, EI, rho, *, curvature: str = "linear", n_gauss: int = 5, axial_law: str = "green-lagrange"
) -> ElementSet:
    """`make_elements` computing every element's tables (the parameters and errors are its)."""
    L = np.asarray(length, dtype=float)
    if L.ndim != 1 or L.shape[0] == 0:
        raise ValueError(f"length must be a non-empty 1-D array, got shape {L.shape}")
    if not np.all(np.isfinite(L)) or np.any(L <= 0.0):
        raise ValueError("element lengths must be finite and > 0")
    n = L.shape[0]
    EA_ = _broadcast_property("EA", EA, n)
    EI_ = _broadcast_property("EI", EI, n)
    rho_ = _broadcast_property("rho", rho, n)
    if np.any(EA_ <= 0.0):
        raise ValueError("EA must be > 0")
    if np.any(EI_ < 0.0):
        raise ValueError("EI must be >= 0")
    if np.any(rho_ < 0.0):
        raise ValueError("rho must be >= 0")
    if curvature not in CURVATURE_MODELS:
        raise ValueError(f"curvature must be one of {CURVATURE_MODELS}, got {curvature!r}")
    if axial_law not in barlaw.LAWS:
        raise ValueError(f"axial_law must be one of {barlaw.LAWS}, got {axial_law!r}")
    if isinstance(n_gauss, bool) or not isinstance(n_gauss, (int, np.integer)):
        raise ValueError(f"n_gauss must be an integer, got {n_gauss!r}")
    n_gauss = int(n_gauss)
    if not 1 <= n_gauss <= _MAX_GAUSS:
        raise ValueError(f"n_gauss must be in 1..{_MAX_GAUSS}, got {n_gauss}")

    eye2 = np.eye(2)
    J = np.array([[0.0, 1.0], [-1.0, 0.0]])

    # Quadrature tables for the deformation-dependent terms.
    xi_q, w_q = _gauss01(n_gauss)
    _, D, D2 = shape_functions(xi_q, L)
    wL = w_q[None, :] * L[:, None]
    DD = D[:, :, :, None] * D[:, :, None, :]  # (n, q, 4, 4)
    PQ = _kron_i2(DD, eye2).reshape(n, n_gauss, 64)
    if curvature == "exact":
        DD2 = D[:, :, :, None] * D2[:, :, None, :]
        Q = _kron_i2(DD2, J)
        Q = (Q + np.swapaxes(Q, 2, 3)).reshape(n, n_gauss, 64)
        PQ = np.concatenate((PQ, Q), axis=1)
        D2_8 = np.repeat(D2, 2, axis=-1)
    else:
        D2_8 = np.zeros((n, 0, 8))
    D8 = np.repeat(D, 2, axis=-1)

    # Constant matrices with a rule exact for their polynomial degree.
    xi_c, w_c = _gauss01(_N_GAUSS_CONST)
    s_c, _, d2_c = shape_functions(xi_c, L)
    wL_c = w_c[None, :] * L[:, None]
    m4 = np.einsum("nq,nqa,nqb->nab", wL_c * rho_[:, None], s_c, s_c)
    mass = _kron_i2(m4, eye2)
    grav = np.einsum("nq,nqa->na", wL_c * rho_[:, None], s_c)
    if curvature == "linear":
        kb4 = np.einsum("nq,nqa,nqb->nab", wL_c * EI_[:, None], d2_c, d2_c)
        K_bend = _kron_i2(kb4, eye2)
    else:
        K_bend = np.zeros((n, 8, 8))

    wEA = wL * EA_[:, None]
    return ElementSet(
        length=_readonly(L),
        EA=_readonly(EA_),
        EI=_readonly(EI_),
        rho=_readonly(rho_),
        curvature=curvature,
        n_gauss=n_gauss,
        gauss_xi=_readonly(xi_q),
        wL=_readonly(wL),
        dS=_readonly(D),
        d2S=_readonly(D2),
        K_bend=_readonly(K_bend),
        mass=_readonly(mass),
        gravity_shape=_readonly(grav),
        _wEA=_readonly(wEA),
        _half_wEA=_readonly(0.5 * wEA),
        _wEI=_readonly(wL * EI_[:, None]),
        _D8=_readonly(D8),
        _D8_sqrt_wEA=_readonly(D8 * np.sqrt(wEA)[:, :, None]),
        _D2_8=_readonly(D2_8),
        _DT=_readonly(np.swapaxes(D, 1, 2)),
        _D2T=_readonly(np.swapaxes(D2, 1, 2)),
        _PQ=_readonly(PQ),
        axial_law=axial_law,
    )


@functools.lru_cache(maxsize=32)
def _unit_shape_tables(xi_bytes: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit-element tables of Eq. 3 in xi (n_pts, 4) and their xi-derivatives (cached per point set)."""
    xi = np.frombuffer(xi_bytes, dtype=float)
    x2 = xi * xi
    x3 = x2 * xi
    s_u = np.column_stack([1.0 - 3.0 * x2 + 2.0 * x3, xi - 2.0 * x2 + x3, 3.0 * x2 - 2.0 * x3, x3 - x2])
    ds_u = np.column_stack([6.0 * x2 - 6.0 * xi, 1.0 - 4.0 * xi + 3.0 * x2, 6.0 * xi - 6.0 * x2, 3.0 * x2 - 2.0 * xi])
    d2s_u = np.column_stack([12.0 * xi - 6.0, 6.0 * xi - 4.0, 6.0 - 12.0 * xi, 6.0 * xi - 2.0])
    return _readonly(s_u), _readonly(ds_u), _readonly(d2s_u)


def shape_functions(
    xi: np.ndarray, length: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape functions of Eq. 3 and their x-derivatives.

    Parameters
    ----------
    xi : (n_pts,) local coordinates x / L in [0, 1].
    length : (n_elem,) reference element lengths L.

    Returns
    -------
    s, ds_dx, d2s_dx2 : each (n_elem, n_pts, 4), columns s1..s4.
    """
    xi = np.asarray(xi, dtype=float)
    L = np.asarray(length, dtype=float)
    if xi.ndim != 1:
        raise ValueError(f"xi must be 1-D (n_pts,), got shape {xi.shape}")
    if L.ndim != 1:
        raise ValueError(f"length must be 1-D (n_elem,), got shape {L.shape}")
    s_u, ds_u, d2s_u = _unit_shape_tables(xi.tobytes())
    inv = 1.0 / L
    s = np.empty((L.shape[0], xi.shape[0], 4))
    ds = np.empty_like(s)
    d2s = np.empty_like(s)
    # the powers of L that Eq. 3 and d/dx = (1/L) d/dxi bring, column by column
    s[:, :, 0::2] = s_u[None, :, 0::2]
    np.multiply(s_u[None, :, 1::2], L[:, None, None], out=s[:, :, 1::2])
    np.multiply(ds_u[None, :, 0::2], inv[:, None, None], out=ds[:, :, 0::2])
    ds[:, :, 1::2] = ds_u[None, :, 1::2]
    np.multiply(d2s_u[None, :, 0::2], (inv * inv)[:, None, None], out=d2s[:, :, 0::2])
    np.multiply(d2s_u[None, :, 1::2], inv[:, None, None], out=d2s[:, :, 1::2])
    return s, ds, d2s


def mass_matrices(el: ElementSet) -> np.ndarray:
    """Constant element mass matrices M = int rho S^T S dx (Eq. 7), (n_elem, 8, 8).

    Integrated exactly (4-point Gauss rule on a degree-6 integrand).  Returns a read-only array.
    """
    return el.mass


def transport_matrices(el: ElementSet) -> tuple[np.ndarray, np.ndarray]:
    """The axial-transport matrices of the running belt (module docstring), each (n_elem, 8, 8):

    A = int rho S^T S' dx (the gyroscopic matrix per unit speed is A - A^T) and B = int rho S'^T S' dx
    (symmetric positive semi-definite; the centripetal stiffness is -c^2 B). Integrated exactly (the
    4-point rule of the constant matrices: degrees 5 and 4). New arrays owned by the caller.
    """
    xi_c, w_c = _gauss01(_N_GAUSS_CONST)
    s_c, d_c, _ = shape_functions(xi_c, el.length)
    wr = w_c[None, :] * (el.length * el.rho)[:, None]
    a4 = np.einsum("nq,nqa,nqb->nab", wr, s_c, d_c)
    b4 = np.einsum("nq,nqa,nqb->nab", wr, d_c, d_c)
    b4 = 0.5 * (b4 + np.swapaxes(b4, 1, 2))  # symmetric to the last bit
    eye2 = np.eye(2)
    return _kron_i2(a4, eye2), _kron_i2(b4, eye2)


def gravity_forces(el: ElementSet, g: np.ndarray) -> np.ndarray:
    """Generalized gravity forces Q_g = int rho S^T g dx (Eq. 8), (n_elem, 8).

    ``g`` is the (2,) gravitational acceleration vector [m/s^2].
    """
    g = np.asarray(g, dtype=float)
    if g.shape != (2,):
        raise ValueError(f"g must have shape (2,), got {g.shape}")
    return (el.gravity_shape[:, :, None] * g).reshape(el.n_elem, 8)


def _check_e(el: ElementSet, e: np.ndarray) -> np.ndarray:
    e = np.asarray(e, dtype=float)
    if e.shape != (el.length.shape[0], 8):
        raise ValueError(f"e must have shape ({el.length.shape[0]}, 8), got {e.shape}")
    return e


def _exact_terms(el: ElementSet, rp: np.ndarray, E: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """r'' (n, q, 2) at the Gauss points and c = r' x r'' = r'^T J r'' (n, q) (Eq. 15 numerator)."""
    rpp = el.d2S @ E
    c = rp[..., 0] * rpp[..., 1] - rp[..., 1] * rpp[..., 0]
    return rpp, c


def _axial_terms(el: ElementSet, e: np.ndarray):
    """Checked e, n_elem, E (n, 4, 2), r' (n, q, 2) and its components, A = r'.r', s the coefficient of
    G_q in the axial force f_l = sum_q s_q G_q: w L EA eps (green-lagrange), w L EA (1 - 1/|r'|) (linear:
    the virtual work of N d|r'| with d|r'| = G . de / |r'|)."""
    e = _check_e(el, e)
    n = e.shape[0]
    E = e.reshape(n, 4, 2)
    rp = el.dS @ E  # (n, q, 2)
    r0 = rp[..., 0]
    r1 = rp[..., 1]
    A = r0 * r0 + r1 * r1
    if el.axial_law == "linear":
        return e, n, E, rp, r0, r1, A, el._wEA * (1.0 - 1.0 / np.sqrt(A))
    return e, n, E, rp, r0, r1, A, el._half_wEA * (A - 1.0)


def _axial_rank_weight(el: ElementSet, A: np.ndarray) -> np.ndarray | None:
    """(n, q) the factor on w L EA of the axial rank term G_q G_q^T of the tangent, 2 ds/dA / (w L EA):
    None for green-lagrange (1), A^(-3/2) for the linear law."""
    return A ** -1.5 if el.axial_law == "linear" else None


def internal_forces(el: ElementSet, e: np.ndarray) -> np.ndarray:
    """Generalized elastic forces f = dU/de = Q_l + Q_t (Eq. 14 plus Eq. 17 or Eq. 16), (n_elem, 8).

    ``e`` is (n_elem, 8) element coordinates (Eq. 4-6).
    """
    e, n, E, rp, r0, r1, A, s = _axial_terms(el, e)
    if el.curvature == "exact":
        rpp, c = _exact_terms(el, rp, E)
        iA = 1.0 / A
        u_c = el._wEI * c * (iA * iA * iA)  # du/dc with u = w L EI/2 c^2 / A^3
        s = s - 3.0 * u_c * c * iA  # + 2 du/dA
        # grad c = D (x) J r'' + D2 (x) J^T r';  J r'' = (r''_y, -r''_x), J^T r' = (-r'_y, r'_x)
        v1 = s[..., None] * rp
        v1[..., 0] += u_c * rpp[..., 1]
        v1[..., 1] -= u_c * rpp[..., 0]
        v2 = np.stack((-u_c * r1, u_c * r0), axis=-1)
        return (el._DT @ v1 + el._D2T @ v2).reshape(n, 8)
    f = (el._DT @ (s[..., None] * rp)).reshape(n, 8)
    if el.curvature == "linear":
        f += (el.K_bend @ e[:, :, None])[:, :, 0]
    return f


def internal_forces_and_tangent(el: ElementSet, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elastic forces and their analytic tangent.

    Returns ``f`` (n_elem, 8) = dU/de and ``K`` (n_elem, 8, 8) = df/de (symmetric), for element
    coordinates ``e`` (n_elem, 8).  Both are new arrays owned by the caller.
    """
    e, n, E, rp, r0, r1, A, s = _axial_terms(el, e)  # s: coefficient of P_q in the secant matrix
    if el.curvature != "exact":
        # Axial rank term sum_q wEA G_q G_q^T = Gs^T Gs with Gs_q = sqrt(wEA) D_q (x) r'_q.
        Gs = el._D8_sqrt_wEA * np.tile(rp, 4)
        weight = _axial_rank_weight(el, A)
        if weight is not None:
            Gs = Gs * np.sqrt(weight)[:, :, None]
        K = np.ascontiguousarray(np.swapaxes(Gs, 1, 2)) @ Gs
        Ks = (s[:, None, :] @ el._PQ).reshape(n, 8, 8)  # secant matrix: f = Ks e
        if el.curvature == "linear":
            Ks += el.K_bend
        f = (Ks @ e[:, :, None])[:, :, 0]
        K += Ks
        return f, K

    # Exact curvature, u = w L EI/2 c^2/A^3 per Gauss point.  With gc = dc/de, gA = dA/de = 2 G:
    #   f += u_c gc + u_A gA,   u_c = wEI c/A^3,  u_A = -3/2 wEI c^2/A^4
    #   K += a gc gc^T + b (gc gA^T + gA gc^T) + d gA gA^T + u_c d2c + u_A d2A
    # with a = wEI/A^3, b = -3 wEI c/A^4, d = 6 wEI c^2/A^5, d2A = 2 P_q, d2c = Q_q + Q_q^T.
    # The rank terms are rewritten a h h^T - 3 wEI c^2/A^5 gA gA^T with h = gc - 3 c/A gA.
    rpp, c = _exact_terms(el, rp, E)
    iA = 1.0 / A
    iA3 = iA * iA * iA
    wEI = el._wEI
    u_c = wEI * c * iA3
    s = s - 3.0 * u_c * c * iA  # + 2 u_A
    Ks = (np.concatenate((s, u_c), axis=1)[:, None, :] @ el._PQ).reshape(n, 8, 8)
    f = (Ks @ e[:, :, None])[:, :, 0]  # c and A are quadratic forms in e
    G = el._D8 * np.tile(rp, 4)
    Jrpp = np.stack((rpp[..., 1], -rpp[..., 0]), axis=-1)
    JTrp = np.stack((-r1, r0), axis=-1)
    h = el._D8 * np.tile(Jrpp, 4) + el._D2_8 * np.tile(JTrp, 4)  # gc
    h -= (6.0 * c * iA)[..., None] * G
    weight = _axial_rank_weight(el, A)
    wEA = el._wEA if weight is None else el._wEA * weight
    coef_G = wEA - 12.0 * wEI * c * c * iA3 * iA * iA  # axial wEA + 4 (-3 wEI c^2/A^5)
    Z = np.concatenate((G, h), axis=1)  # (n, 2q, 8)
    W = Z * np.concatenate((coef_G, wEI * iA3), axis=1)[:, :, None]
    K = np.ascontiguousarray(np.swapaxes(Z, 1, 2)) @ W
    K += np.swapaxes(K, 1, 2)  # Z^T W is symmetric up to round-off: make it exactly so
    K *= 0.5
    K += Ks
    return f, K


def strain_energy(el: ElementSet, e: np.ndarray) -> np.ndarray:
    """Element strain energy U_l + U_t, shape (n_elem,).

    Eq. 13 plus Eq. 16 ("exact") or the quadratic form 1/2 e^T K_bend e of Eq. 17 ("linear").
    """
    e = _check_e(el, e)
    n = e.shape[0]
    E = e.reshape(n, 4, 2)
    rp = el.dS @ E
    A = np.einsum("nqi,nqi->nq", rp, rp)
    eps = np.sqrt(A) - 1.0 if el.axial_law == "linear" else 0.5 * (A - 1.0)  # (linear: EA (lambda - 1)^2 / 2)
    U = np.einsum("nq,nq->n", el._half_wEA, eps * eps)
    if el.curvature == "linear":
        U = U + 0.5 * np.einsum("ni,nij,nj->n", e, el.K_bend, e)
    elif el.curvature == "exact":
        _, c = _exact_terms(el, rp, E)
        U = U + 0.5 * np.einsum("nq,nq->n", el._wEI, c * c / (A * A * A))
    return U


def _at(el: ElementSet, e: np.ndarray, xi: np.ndarray, which: int) -> np.ndarray:
    e = _check_e(el, e)
    tables = shape_functions(xi, el.length)
    return tables[which] @ e.reshape(e.shape[0], 4, 2)


def positions(el: ElementSet, e: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Positions r = S e (Eq. 1) at local coordinates ``xi`` (n_pts,), shape (n_elem, n_pts, 2)."""
    return _at(el, e, xi, 0)


def slopes(el: ElementSet, e: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Slopes r' = dr/dx = S' e at ``xi`` (n_pts,), shape (n_elem, n_pts, 2)."""
    return _at(el, e, xi, 1)


def axial_strain(el: ElementSet, e: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Green-Lagrange axial strain eps = (r'.r' - 1)/2 (Eq. 12) at ``xi`` (n_pts,).

    Returns shape (n_elem, n_pts).
    """
    rp = slopes(el, e, xi)
    return 0.5 * (np.einsum("npi,npi->np", rp, rp) - 1.0)


def axial_force(el: ElementSet, e: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """True (Cauchy) axial force N = EA eps |r'| at ``xi`` (n_pts,), shape (n_elem, n_pts) [N].

    With the St. Venant-Kirchhoff law the second Piola-Kirchhoff force EA eps is pushed forward
    by the stretch |r'| = sqrt(1 + 2 eps).
    """
    rp = slopes(el, e, xi)
    return barlaw.bar_law(el.axial_law).axial_force(np.sqrt(np.einsum("npi,npi->np", rp, rp)), el.EA[:, None])


def axial_force_gradient(el: ElementSet, e: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """Analytic gradient dN/de of `axial_force` at ``xi`` (n_pts,), shape (n_elem, n_pts, 8).

    dN/de = dN/dlambda dlambda/de = dN/dlambda S'^T r' / |r'| (`barlaw.axial_stiffness`), with
    S'^T r' = ds/dx (x) r'.
    """
    e = _check_e(el, e)
    n = e.shape[0]
    _, D, _ = shape_functions(xi, el.length)
    rp = D @ e.reshape(n, 4, 2)
    lam = np.sqrt(np.einsum("npi,npi->np", rp, rp))
    coef = barlaw.bar_law(el.axial_law).axial_stiffness(lam, el.EA[:, None]) / lam
    return ((coef[..., None] * D)[:, :, :, None] * rp[:, :, None, :]).reshape(n, -1, 8)


def make_elements(length, EA, EI, rho, *, curvature: str = "linear", n_gauss: int = 5,
                  axial_law: str = "green-lagrange") -> ElementSet:
    """Build an `ElementSet` and precompute its quadrature tables and constant matrices.

    Parameters
    ----------
    length : array_like, (n_elem,)
        Reference (undeformed) element lengths L > 0 [m].
    EA, EI, rho : float or array_like (n_elem,)
        Axial stiffness EA > 0 [N], bending stiffness EI >= 0 [N m^2], mass per unit reference
        length rho >= 0 [kg/m]; scalars are broadcast to all elements.
    curvature : str
        "linear" (Eq. 17, default), "exact" (Eq. 15-16) or "none" (no bending energy).
    n_gauss : int
        Gauss points per element for the axial term (5 integrate it exactly; fewer points give
        reduced integration) and for the exact-curvature term.
    axial_law : str
        "green-lagrange" (Eqs. 12-14, default) or "linear" (N = EA (|r'| - 1), `barlaw`).

    Elements with identical (L, EA, EI, rho) — all the elements of a uniformly meshed span — share
    their tables: they are computed once per distinct element and gathered.

    Raises
    ------
    ValueError
        On a bad shape, a non-finite or out-of-range value, or an unknown curvature model.
    """
    L = np.asarray(length, dtype=float)
    scalar = all(np.ndim(x) == 0 for x in (EA, EI, rho))
    if L.ndim != 1 or L.shape[0] < 8 or not scalar or not np.all(np.isfinite(L)):
        return _make_elements_all(length, EA, EI, rho, curvature=curvature, n_gauss=n_gauss, axial_law=axial_law)
    uniq, inverse = np.unique(L, return_inverse=True)
    if len(uniq) == L.shape[0]:
        return _make_elements_all(length, EA, EI, rho, curvature=curvature, n_gauss=n_gauss, axial_law=axial_law)
    base = _make_elements_all(uniq, EA, EI, rho, curvature=curvature, n_gauss=n_gauss, axial_law=axial_law)
    return subset(base, inverse.ravel())


_NO_ELEMENT = np.zeros(0)  # no element's values: every table of `empty_elements` a view of it (read-only, shared)
_NO_ELEMENT.setflags(write=False)


def empty_elements(*, curvature: str = "linear", n_gauss: int = 5, axial_law: str = "green-lagrange") -> ElementSet:
    """An `ElementSet` of no element (a belt whose spans are all springs): every table of the class
    docstring's shape with n = 0 (what `subset` of a made set to no index gives, without making one:
    tests/test_ancf_empty.py holds the two equal)."""
    q = int(n_gauss)

    def none(*shape: int) -> np.ndarray:  # (a view of the one empty array: read-only as it is)
        return _NO_ELEMENT.reshape((0, *shape))

    exact = curvature == "exact"
    return ElementSet(length=none(), EA=none(), EI=none(), rho=none(), curvature=curvature, n_gauss=q,
                      gauss_xi=_gauss01(q)[0], wL=none(q), dS=none(q, 4), d2S=none(q, 4), K_bend=none(8, 8),
                      mass=none(8, 8), gravity_shape=none(4), _wEA=none(q), _half_wEA=none(q), _wEI=none(q),
                      _D8=none(q, 8), _D8_sqrt_wEA=none(q, 8), _D2_8=none(q if exact else 0, 8), _DT=none(4, q),
                      _D2T=none(4, q), _PQ=none(2 * q if exact else q, 64), axial_law=axial_law)


def subset(el: ElementSet, index: np.ndarray) -> ElementSet:
    """The elements ``index`` (k,) of ``el`` (repeats allowed), tables gathered, not recomputed."""
    index = np.asarray(index, dtype=np.int64)
    n = el.n_elem
    fields_ = {}
    for f in dataclasses.fields(el):
        value = getattr(el, f.name)
        if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == n:
            value = value[index]  # (a new C-contiguous array of the same dtype: frozen, not copied again)
            value.setflags(write=False)
        fields_[f.name] = value
    return ElementSet(**fields_)
