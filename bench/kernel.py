"""Timings of the belt kernel: numpy reference (`ancf`) against the compiled kernel (`belt_kernel`).

Two spans of N uniform elements (L = 0.067 m, EA = 1.2e5 N, EI = 0.02 N m^2, rho = 0.119 kg/m,
5 Gauss points), a model-like layout (interior elements T = [I8 | 0], the span-end elements joints
with 3 pulley columns, m = 11), a stretched straight state with small random perturbations.
Medians over repeats after a warm-up (compilation excluded), microseconds per call.
BLAS single-threaded, as in the CLI.

Columns:
  np f+K      ancf.internal_forces_and_tangent
  nb f+K      belt_kernel.element_forces_tangent
  np red      numpy gather + ancf f, K + T^T f (bincount) + T^T K T (matmul), as System did
  nb red      belt_kernel.reduced_force_and_tangent_blocks (gather, f, K, scatter, blocks fused)
  np f        ancf.internal_forces
  nb f        belt_kernel.element_forces
  nb red f    belt_kernel.reduced_force

Usage: python bench/kernel.py [--curvature linear|exact|none ...]
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from beltdyn.model import ancf  # noqa: E402
from beltdyn.model import belt_kernel as bk  # noqa: E402

L_EL, EA, EI, RHO = 0.067, 1.2e5, 0.02, 0.119


def layout(n_per_span: int, n_span: int = 2, seed: int = 0):
    """T (n, 8, 11), idx (n, 11), n_dof, e0 (n, 8), q_ext (n_dof + 1,) of n_span chains."""
    rng = np.random.default_rng(seed)
    n_pulley, m = 3 * n_span, 11
    n_dof = n_pulley + n_span * 4 * (n_per_span + 1)
    pad = n_dof
    T = np.zeros((n_span * n_per_span, 8, m))
    idx = np.full((n_span * n_per_span, m), pad, dtype=np.int64)
    e0 = np.zeros((n_span * n_per_span, 8))
    x = L_EL * np.arange(n_per_span + 1)
    for s in range(n_span):
        base = n_pulley + s * 4 * (n_per_span + 1)
        for k in range(n_per_span):
            row = s * n_per_span + k
            T[row, :, :8] = np.eye(8)
            idx[row, :8] = base + 4 * k + np.arange(8)
            e0[row] = [x[k], 0.1 * s, 0.0, 0.0, x[k + 1], 0.1 * s, 0.0, 0.0]  # q holds the gradients
            if k in (0, n_per_span - 1):
                side = 0 if k == 0 else 1
                rows = slice(4 * side, 4 * side + 2)
                T[row, rows, rows] = 0.0
                idx[row, 4 * side: 4 * side + 2] = pad
                idx[row, 8:] = 3 * s + np.arange(3)
                T[row, rows, 8:] = rng.standard_normal((2, 3))
    q = np.zeros(n_dof)
    for s in range(n_span):
        base = n_pulley + s * 4 * (n_per_span + 1)
        q[base + 0: base + 4 * (n_per_span + 1): 4] = 0.01 * np.arange(n_per_span + 1) * L_EL  # 1 % stretch
        q[base + 2: base + 4 * (n_per_span + 1): 4] = 1.01
    q += 1e-4 * rng.standard_normal(n_dof)
    return T, idx, n_dof, e0, np.append(q, 0.0)


def median_us(fn, min_time: float = 0.02, repeats: int = 15) -> float:
    fn()
    fn()
    number = 1
    while True:  # calls per sample so that one sample takes >= min_time
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        if time.perf_counter() - t0 >= min_time:
            break
        number *= 2
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        samples.append((time.perf_counter() - t0) / number)
    return 1e6 * statistics.median(samples)


def row(n_per_span: int, curvature: str) -> list[float]:
    T, idx, n_dof, e0, q_ext = layout(n_per_span)
    n = T.shape[0]
    el = ancf.make_elements(np.full(n, L_EL), EA, EI, RHO, curvature=curvature, n_gauss=5)
    tab = bk.tables_from_elements(el)
    tsel = bk.joint_selection(T, idx, n_dof)
    Tt = np.ascontiguousarray(T.transpose(0, 2, 1))
    E = np.empty((n, 8))
    bk.gather(q_ext, e0, T, idx, tsel, E)
    f = np.empty((n, 8))
    K = np.empty((n, 8, 8))
    f_red = np.empty(n_dof + 1)
    blocks = np.empty((n, T.shape[2], T.shape[2]))
    work = bk.scratch(n, tab.dS.shape[1], T.shape[2])

    def np_reduced():
        Ee = e0 + np.matmul(T, q_ext[idx][:, :, None])[:, :, 0]
        fe, Ke = ancf.internal_forces_and_tangent(el, Ee)
        fr = np.matmul(Tt, fe[:, :, None])[:, :, 0]
        np.bincount(idx.ravel(), weights=fr.ravel(), minlength=n_dof + 1)
        np.matmul(np.matmul(Tt, Ke), T)

    return [
        median_us(lambda: ancf.internal_forces_and_tangent(el, E)),
        median_us(lambda: bk.element_forces_tangent(E, *tab.args, f, K, work)),
        median_us(np_reduced),
        median_us(lambda: bk.reduced_force_and_tangent_blocks(q_ext, e0, T, idx, tsel, *tab.args, f_red, blocks, work)),
        median_us(lambda: ancf.internal_forces(el, E)),
        median_us(lambda: bk.element_forces(E, *tab.args, f)),
        median_us(lambda: bk.reduced_force(q_ext, e0, T, idx, tsel, *tab.args, f_red, work)),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curvature", nargs="+", default=["linear", "exact"], choices=list(bk.CURVATURE_CODE))
    args = parser.parse_args()
    cols = ["np f+K", "nb f+K", "np red", "nb red", "np f", "nb f", "nb red f"]
    print("microseconds per call (median), 2 spans, 5 Gauss points")
    print(f"{'curvature':>9} {'el/span':>7} " + " ".join(f"{c:>9}" for c in cols))
    for curvature in args.curvature:
        for n_per_span in (10, 40, 160):
            vals = row(n_per_span, curvature)
            print(f"{curvature:>9} {n_per_span:>7} " + " ".join(f"{v:9.1f}" for v in vals))


if __name__ == "__main__":
    main()
