"""Belt kernel: element forces, tangents, damping, strain energy of the ANCF spans, and the joint
gather/scatter with an identity fast path for interior elements.

The stepper-facing functions (gather, scatter_vector, element_forces, element_damping,
element_strain_energy, element_min_axial_force) are compiled with numba (curvature models "none"
and "linear"); the tangent path used by static and modal analyses is vectorized numpy, with the
exact curvature (paper Eq. 15) taken from `ancf`, the reference implementation.
Curvature codes: 0 none, 1 linear (Eq. 17), 2 exact (Eq. 15-16).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from numba import njit

from . import ancf

CURVATURE_CODE = {"none": 0, "linear": 1, "exact": 2}


@dataclass(frozen=True, kw_only=True)
class KernelTables:
    dS: np.ndarray
    d2S: np.ndarray
    wEA: np.ndarray
    wEI: np.ndarray
    EA: np.ndarray
    Kb: np.ndarray
    curvature: int
    el: object = None


def tables_from_elements(el):
    c = lambda a: np.ascontiguousarray(a, dtype=np.float64)
    return KernelTables(dS=c(el.dS), d2S=c(el.d2S), wEA=c(el._wEA), wEI=c(el._wEI), EA=c(el.EA), Kb=c(el.K_bend),
                        curvature=CURVATURE_CODE[el.curvature], el=el)


def _axial(E, dS, wEA):
    n = E.shape[0]
    rp = dS @ E.reshape(n, 4, 2)
    A = (rp ** 2).sum(-1)
    return rp, A, 0.5 * wEA * (A - 1.0)


def element_forces_tangent(E, dS, d2S, wEA, wEI, Kb, curvature, f, K, el=None):
    n = E.shape[0]
    if el is not None:  # the tuned reference implementation (precomputed P_q tables, every curvature)
        f[:], K[:] = ancf.internal_forces_and_tangent(el, E)
        return
    rp, A, s = _axial(E, dS, wEA)
    nq = dS.shape[1]
    D8 = np.repeat(dS, 2, axis=-1)
    G = D8 * np.tile(rp, 4)  # (n, q, 8)
    K[:] = np.einsum("nq,nqi,nqj->nij", wEA, G, G)
    DD = dS[:, :, :, None] * dS[:, :, None, :]
    P = (DD[..., :, None, :, None] * np.eye(2)[None, None, None, :, None, :]).reshape(n, nq, 8, 8)
    Ks = np.einsum("nq,nqij->nij", s, P)
    if curvature == 1:
        Ks = Ks + Kb
    f[:] = (Ks @ E[:, :, None])[:, :, 0]
    K += Ks


def element_damping_matrix(E, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, C):
    rp, A, s = _axial(E, dS, wEA)
    D8 = np.repeat(dS, 2, axis=-1)
    G = D8 * np.tile(rp, 4)
    C[:] = eta_a * np.einsum("nq,nqi,nqj->nij", wEA, G, G)
    if curvature == 1:
        C += eta_b * Kb


def joint_selection(T, idx, n_dof):
    n, _, m = T.shape
    ident = np.zeros((8, m))
    ident[:, :8] = np.eye(8)
    ok = np.all(T == ident, axis=(1, 2)) & np.all(idx[:, 8:] == n_dof, axis=1)
    return np.where(ok, -1, np.arange(n)).astype(np.int64)


def reduce_blocks(Ke, T, tsel, out):
    out[:] = np.swapaxes(T, 1, 2) @ Ke @ T


def reduced_force(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out, el=None):
    n = T.shape[0]
    E = np.empty((n, 8))
    gather(q_ext, e0, T, idx, tsel, E)
    fe = np.empty((n, 8))
    if el is not None:
        fe = ancf.internal_forces(el, E)
    else:
        element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, fe)
    scatter_vector(fe, T, idx, tsel, f_out)


def reduced_force_and_tangent_blocks(q_ext, e0, T, idx, tsel, dS, d2S, wEA, wEI, Kb, curvature, f_out, blocks_out,
                                     el=None):
    n = T.shape[0]
    E = np.empty((n, 8))
    gather(q_ext, e0, T, idx, tsel, E)
    fe = np.empty((n, 8))
    Ke = np.empty((n, 8, 8))
    element_forces_tangent(E, dS, d2S, wEA, wEI, Kb, curvature, fe, Ke, el)
    scatter_vector(fe, T, idx, tsel, f_out)
    reduce_blocks(Ke, T, tsel, blocks_out)


@njit(cache=True)
def gather(q_ext, e0, T, idx, tsel, E):
    n, _, m = T.shape
    for e in range(n):
        if tsel[e] < 0:
            for i in range(8):
                E[e, i] = e0[e, i] + q_ext[idx[e, i]]
        else:
            for i in range(8):
                acc = e0[e, i]
                for j in range(m):
                    acc += T[e, i, j] * q_ext[idx[e, j]]
                E[e, i] = acc


@njit(cache=True)
def scatter_vector(fe, T, idx, tsel, out):
    n, _, m = T.shape
    for e in range(n):
        if tsel[e] < 0:
            for i in range(8):
                out[idx[e, i]] += fe[e, i]
        else:
            for j in range(m):
                acc = 0.0
                for i in range(8):
                    acc += T[e, i, j] * fe[e, i]
                out[idx[e, j]] += acc


@njit(cache=True)
def element_forces(E, dS, d2S, wEA, wEI, Kb, curvature, f):
    n, nq, _ = dS.shape
    for e in range(n):
        for i in range(8):
            f[e, i] = 0.0
        for g in range(nq):
            rx = 0.0
            ry = 0.0
            for k in range(4):
                rx += dS[e, g, k] * E[e, 2 * k]
                ry += dS[e, g, k] * E[e, 2 * k + 1]
            s = 0.5 * wEA[e, g] * (rx * rx + ry * ry - 1.0)
            for k in range(4):
                f[e, 2 * k] += s * dS[e, g, k] * rx
                f[e, 2 * k + 1] += s * dS[e, g, k] * ry
        if curvature == 1:
            for i in range(8):
                acc = 0.0
                for j in range(8):
                    acc += Kb[e, i, j] * E[e, j]
                f[e, i] += acc


@njit(cache=True)
def element_damping(E, Ed, dS, d2S, wEA, wEI, Kb, curvature, eta_a, eta_b, fd):
    n, nq, _ = dS.shape
    for e in range(n):
        for i in range(8):
            fd[e, i] = 0.0
        for g in range(nq):
            rx = 0.0
            ry = 0.0
            rdx = 0.0
            rdy = 0.0
            for k in range(4):
                rx += dS[e, g, k] * E[e, 2 * k]
                ry += dS[e, g, k] * E[e, 2 * k + 1]
                rdx += dS[e, g, k] * Ed[e, 2 * k]
                rdy += dS[e, g, k] * Ed[e, 2 * k + 1]
            s = wEA[e, g] * eta_a * (rx * rdx + ry * rdy)
            for k in range(4):
                fd[e, 2 * k] += s * dS[e, g, k] * rx
                fd[e, 2 * k + 1] += s * dS[e, g, k] * ry
        if curvature == 1:
            for i in range(8):
                acc = 0.0
                for j in range(8):
                    acc += Kb[e, i, j] * Ed[e, j]
                fd[e, i] += eta_b * acc


@njit(cache=True)
def element_strain_energy(E, dS, d2S, wEA, wEI, Kb, curvature, U):
    n, nq, _ = dS.shape
    for e in range(n):
        u = 0.0
        for g in range(nq):
            rx = 0.0
            ry = 0.0
            for k in range(4):
                rx += dS[e, g, k] * E[e, 2 * k]
                ry += dS[e, g, k] * E[e, 2 * k + 1]
            eps = 0.5 * (rx * rx + ry * ry - 1.0)
            u += 0.5 * wEA[e, g] * eps * eps
        if curvature == 1:
            for i in range(8):
                acc = 0.0
                for j in range(8):
                    acc += Kb[e, i, j] * E[e, j]
                u += 0.5 * E[e, i] * acc
        U[e] = u


@njit(cache=True)
def element_min_axial_force(E, dS, EA, out):
    n, nq, _ = dS.shape
    for e in range(n):
        lo = np.inf
        for g in range(nq):
            rx = 0.0
            ry = 0.0
            for k in range(4):
                rx += dS[e, g, k] * E[e, 2 * k]
                ry += dS[e, g, k] * E[e, 2 * k + 1]
            v = EA[e] * 0.5 * (rx * rx + ry * ry - 1.0)
            if v < lo:
                lo = v
        out[e] = lo
