"""Band solvers of the stepper's iteration matrix S, compiled with numba (called by `integrator`'s
Newton corrections; `band_lu_nopivot` also by `transient.band_factor`): band Cholesky, band LU
without row exchanges, LAPACK dgbtrf's band LU (solve only), and `factor_solve` choosing by
`stepper_data.Factor.kind` (0 band Cholesky, 1 band LU with partial pivoting, 2 without)."""

from __future__ import annotations

from beltdyn.jitcache import configure, kernel_options

configure()  # where numba caches the kernels: before numba loads
from numba import njit  # noqa: E402

KERNEL = kernel_options()


@njit(**KERNEL)
def band_cholesky_solve(ab, perm, b, x, work):
    """Solve S x = b with S[perm][:, perm] = U^T U, U in upper band storage ab (u+1, n), column-major:
    U^T y = b by columns of U (dot products, 4 partial sums: no chain of dependent additions), U x = y
    by column updates (`band_upper_solve`)."""
    u = ab.shape[0] - 1
    n = ab.shape[1]
    for i in range(n):
        work[i] = b[perm[i]]
    for j in range(n):  # U^T y = b: y_j = (b_j - sum_{i<j} U_ij y_i) / U_jj
        lo = max(0, j - u)
        m = j - lo
        col = ab[u - m:u, j]  # U[lo:j, j], and y[lo:j]: views from 0 (indices provably >= 0)
        ys = work[lo:j]
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        i = 0
        while i + 3 < m:
            s0 += col[i] * ys[i]
            s1 += col[i + 1] * ys[i + 1]
            s2 += col[i + 2] * ys[i + 2]
            s3 += col[i + 3] * ys[i + 3]
            i += 4
        while i < m:
            s0 += col[i] * ys[i]
            i += 1
        work[j] = (work[j] - ((s0 + s1) + (s2 + s3))) / ab[u, j]
    band_upper_solve(ab, u, work)  # U x = y
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def band_upper_solve(ab, u, work):
    """U x = y in place (work (n,)), U upper with u superdiagonals, U[i, j] = ab[u + i - j, j]
    (column-major): x_j, then its column leaves the rows above (column updates)."""
    n = ab.shape[1]
    for j in range(n - 1, -1, -1):
        xj = work[j] / ab[u, j]
        work[j] = xj
        lo = max(0, j - u)
        m = j - lo
        col = ab[u - m:u, j]  # U[lo:j, j], x[lo:j]: views from 0 (the update vectorizes)
        xs = work[lo:j]
        for i in range(m):
            xs[i] -= col[i] * xj


@njit(**KERNEL)
def band_lu_nopivot(ab, u):
    """LU factor without row exchanges, in place, of the band matrix A (n, n) held in ab (2u + 1, n)
    column-major, A[i, j] = ab[u + i - j, j] for |i - j| <= u: L unit lower (its multipliers below the
    diagonal), U on and above (u superdiagonals: no fill beyond the band, as partial pivoting's 2u).
    Exists and needs no exchanges when the symmetric part of A is positive definite (every pivot is
    then positive): the iteration matrix c_m M + ... with the running belt's small skew terms. Returns
    the number of columns eliminated: n, or the first column whose pivot is not positive (the caller
    falls back to partial pivoting)."""
    n = ab.shape[1]
    for k in range(n):
        p = ab[u, k]
        if not p > 0.0:
            return k
        lm = min(u, n - 1 - k)
        for i in range(1, lm + 1):
            ab[u + i, k] /= p
        for j in range(1, lm + 1):  # A[k+i, k+j] -= l_{k+i,k} u_{k,k+j}
            ukj = ab[u - j, k + j]
            if ukj != 0.0:
                off = u - j
                for i in range(1, lm + 1):
                    ab[off + i, k + j] -= ab[u + i, k] * ukj
    return n


@njit(**KERNEL)
def band_lu_nopivot_solve(ab, perm, b, x, work):
    """Solve S x = b with the `band_lu_nopivot` factor of S[perm][:, perm] in ab (2u + 1, n)."""
    u = (ab.shape[0] - 1) // 2
    n = ab.shape[1]
    for i in range(n):
        work[i] = b[perm[i]]
    for j in range(n - 1):  # L y = b (unit lower), by columns
        wj = work[j]
        lm = min(u, n - 1 - j)
        for i in range(1, lm + 1):
            work[j + i] -= ab[u + i, j] * wj
    band_upper_solve(ab, u, work)  # U x = y
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def band_lu_solve(ab, piv, perm, kl, ku, b, x, work):
    """Solve S x = b with the LAPACK dgbtrf factor of S[perm][:, perm] (band storage ab
    (2 kl + ku + 1, n), 0-based pivots piv): the dgbtrs algorithm for no transpose."""
    n = ab.shape[1]
    kd = kl + ku
    for i in range(n):
        work[i] = b[perm[i]]
    if kl > 0:
        for j in range(n - 1):
            lm = min(kl, n - 1 - j)
            p = piv[j]
            if p != j:
                tmp = work[p]
                work[p] = work[j]
                work[j] = tmp
            wj = work[j]
            for i in range(1, lm + 1):
                work[j + i] -= ab[kd + i, j] * wj
    for j in range(n - 1, -1, -1):  # U x = y, U with kd superdiagonals: U[i, j] = ab[kd + i - j, j]
        work[j] /= ab[kd, j]
        wj = work[j]
        lo = max(0, j - kd)
        for i in range(lo, j):
            work[i] -= ab[kd + i - j, j] * wj
    for i in range(n):
        x[perm[i]] = work[i]


@njit(**KERNEL)
def factor_solve(fac, b, x, work):
    if fac.kind == 0:
        band_cholesky_solve(fac.ab, fac.perm, b, x, work)
    elif fac.kind == 2:
        band_lu_nopivot_solve(fac.ab, fac.perm, b, x, work)
    else:
        band_lu_solve(fac.ab, fac.piv, fac.perm, fac.kl, fac.ku, b, x, work)
