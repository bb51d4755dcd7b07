"""Modal analysis about the static equilibrium (paper Eq. 26) and automatic mode classification.

K_t = d(f_int + k_s q)/dq at the equilibrium, M the constant reduced mass matrix; the reduced
generalized eigenproblem K_t phi = omega^2 M phi is solved densely (LAPACK, small models) or with
ARPACK in shift-invert mode about a small negative shift (large models, lowest modes only).
Rigid-body modes (omega ~ 0, e.g. the belt turning with all pulleys) are detected and excluded.

Classification from the kinetic-energy distribution of each mass-normalized shape phi
(phi^T M phi = 1): pulley rotation, pulley translation, and for each span the motion along its
chord (longitudinal) and across it (transverse). Since M_e = M_s (x) I2, projecting the nodal
vectors of a span on its unit direction t and normal n splits the span's kinetic energy exactly.
The kind is the largest share ("mixed" when no share reaches 1/2); the order of a transverse mode is
its half-wave count along the dominant span, of any other kind its rank within that kind.

The running belt (`System.belt_speed` c != 0, see `running`): the gyroscopic eigenproblem
(s^2 M + s G + K) phi = 0 with G = -G^T. Dense: with M = L L^T and L^-1 K L^-T = R^T R (pivoted
Cholesky; positive semi-definite below the first critical speed, one zero for the belt turning with
the pulleys), the real skew-symmetric matrix H = [[0, R], [-R^T, -L^-1 G L^-T]] has the eigenvalues
s = +-i omega of the elastic modes exactly (s y = H y for y = (R xi, s xi), phi = L^-T xi); its
lowest eigenpairs come from the symmetric H^T H (LAPACK syevd) and a small Hermitian Rayleigh-Ritz
(`_gyroscopic_dense`), so the frequencies stay real and paired (the gyroscopic structure is kept).
Above a critical speed the companion linearization is solved in full (LAPACK geev). Sparse:
ARPACK in shift-invert mode on the companion linearization about a small negative real shift
(one sparse LU of K + sigma G + sigma^2 M). Frequencies are Im s / 2 pi, shapes complex,
normalized phi^H M phi = 1 with their largest entry real and positive. A real s > 0 is a divergent
mode (frequency 0, growth rate s: the span buckles), a complex s with Re s > 0 flutter; classification
uses the kinetic energy of Re phi and Im phi together and, for transverse modes, the number of humps of
the envelope |w(x)| (a travelling wave has no fixed nodes).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from beltdyn.errors import SolverError
from beltdyn.model.angles import TWO_PI
from beltdyn.model.components import ENERGY_KINDS
from beltdyn.model.system import System

KINDS = ENERGY_KINDS
ORDINAL = {1: "st", 2: "nd", 3: "rd"}
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True, kw_only=True)
class ModalResult:
    """Shapes: n_modes elastic modes (ascending), n_dof reduced coordinates."""

    frequency: np.ndarray  # (n_modes,) Hz
    shapes: np.ndarray  # (n_modes, n_dof) mass-normalized: phi^T M phi = 1
    kind: tuple[str, ...]
    order: np.ndarray  # (n_modes,) int
    span: np.ndarray  # (n_modes,) int, 1-based span number, 0 if none
    label: tuple[str, ...]
    energy_share: np.ndarray  # (n_modes, 4) kinetic-energy shares, columns as KINDS
    span_share: np.ndarray  # (n_modes, n_span) span (axial + transverse) share of the kinetic energy
    midspan_displacement: np.ndarray  # (n_modes, n_span) mid-span motion across the moving chord per shape
    n_rigid: int
    rigid_frequency: np.ndarray  # (n_rigid,) Hz (numerically ~0)
    solver: str
    # the running belt (belt_speed != 0): complex shapes (phi^H M phi = 1) and the eigenvalues' real parts
    belt_speed: float = 0.0  # m/s
    growth_rate: np.ndarray | None = None  # (n_modes,) 1/s, Re s (0 for a stable mode; > 0: divergence or flutter)
    stability: tuple[str, ...] = ()  # per mode: "stable", "divergence" (s real > 0) or "flutter" (Re s > 0)
    critical_speed: float = float("nan")  # m/s, the first critical (divergence) speed about this equilibrium


def zero_tolerance(lam_max: float) -> float:
    """omega^2 (1/s^2) at or below which an eigenvalue may be zero (a rigid turn, a mechanism): (2 pi
    1e-4 Hz)^2, or 1000 eps lam_max, the round-off of a pencil whose largest diagonal ratio K_ii / M_ii is
    lam_max. Measured: the belt's rigid turn comes out at 1e-5..0.9 eps lam_max (dense and sparse
    solvers, 10-640 el/span), a slack EI = 0 belt's zero modes at up to -400 eps lam_max (320 el/span;
    -200 at 160, -32 at 40).
    A fine mesh can put a true mode below it (the FEAD example's 52.8 Hz at 520 eps lam_max at 640
    el/span): `zero_modes` tells them apart by the gap."""
    return max((2 * np.pi * 1e-4) ** 2, 1000 * _EPS * lam_max)


ZERO_GAP = 1e3  # a factor between the zero cluster and the lowest true mode below the tolerance


def zero_modes(w: np.ndarray, tol: float) -> np.ndarray:
    """(k,) bool: the eigenvalues w (k,) that are zero: |w| <= tol, and below the first gap of more
    than ZERO_GAP between consecutive candidates (sorted by |w|), above which a candidate is a positive
    true mode that a fine mesh's round-off bound reaches (measured: rigid turn 2.7e-3, first mode 1.1e5,
    tolerance 2.1e5 1/s^2 for the FEAD example at 640 el/span), not a round-off zero."""
    zero = np.abs(w) <= tol
    if np.count_nonzero(zero) < 2:
        return zero
    idx = np.flatnonzero(zero)
    order = idx[np.argsort(np.abs(w[idx]))]
    size = np.maximum(np.abs(w[order]), (2 * np.pi * 1e-4) ** 2)
    jumps = np.flatnonzero(size[1:] > ZERO_GAP * size[:-1])
    if len(jumps) and np.all(w[order[jumps[0] + 1:]] > 0.0):
        zero[order[jumps[0] + 1:]] = False
    return zero


def ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else ORDINAL.get(n % 10, "th")
    return f"{n}{suffix}"


def solve_modes(model: System, q: np.ndarray, *, n_modes: int, solver: str = "auto", tangent=None) -> ModalResult:
    """The lowest `n_modes` elastic modes about the equilibrium q (tangent of the loaded residual:
    with tensioner arms the loads' geometric term and the mass J^T M J at q); at a belt speed the
    gyroscopic modes (module docstring). tangent: that tangent, if the static solve evaluated it at q
    (`SolvedDrive.tangent`), else it is evaluated here."""
    if model.belt_speed:
        return _solve_running(model, q, n_modes=n_modes, solver=solver, tangent=tangent)
    K = model.equilibrium(q)[1] if tangent is None else tangent
    slopes = J = None  # the arms' jacobian, dense, for a small dense model: J^T M J and the shapes' joint motion J phi
    if model.arms is not None and model.dense and model.n_p <= 64:
        J = model.arm_jacobian(q)
        M = J.T @ model.mass @ J
    else:
        slopes = model.arm_slopes(q)
        M = model.mass_matrix(q, slopes=slopes)
    n = model.n_dof
    use_dense = model.dense if solver == "auto" else solver == "dense"
    n_want = min(n, n_modes + 2)  # one rigid mode is expected; more raise a mechanism error
    if use_dense:
        Kd = K if model.dense else K.toarray()
        Md = M if model.dense else M.toarray()
        try:
            if n <= 200:  # divide and conquer on the full problem beats the subset driver here
                w, v = generalized_eigh(Kd, Md)
                w = w[:n_want]  # (v: the columns used below are among the first n_want)
            else:
                from scipy.linalg import eigh

                w, v = eigh(Kd, Md, subset_by_index=[0, n_want - 1], check_finite=False)
        except np.linalg.LinAlgError as exc:
            raise SolverError(f"dense eigen-solver failed: {exc}", analysis="modal") from None
        name = "dense"
    else:
        from scipy.sparse import csr_matrix
        from scipy.sparse.linalg import LinearOperator, eigsh, splu

        Ks, Ms = csr_matrix(K), csr_matrix(M)  # no copy for the model's CSR matrices
        scale = float(np.max(Ks.diagonal() / Ms.diagonal()))
        sigma = -1e-9 * scale - 1.0
        lu = splu((Ks - sigma * Ms).T)  # symmetric: the transpose of CSR is the CSC SuperLU wants
        n_want = min(n_want, n - 2)
        try:
            try:
                w, v = _symmetric_shift_invert(Ms, lu, sigma, n_want)
            except np.linalg.LinAlgError:  # M not positive definite (a massless DOF): the generalized mode
                op = LinearOperator((n, n), matvec=lu.solve, dtype=float)
                m_op = LinearOperator((n, n), matvec=Ms.dot, dtype=float)
                w, v = eigsh(Ks, k=n_want, M=m_op, sigma=sigma, which="LM", OPinv=op, tol=1e-12,
                             v0=_start_vector(n))
        except Exception as exc:  # ArpackNoConvergence and friends
            raise SolverError(f"sparse shift-invert eigen-solver failed: {exc}", analysis="modal") from None
        order = np.argsort(w)
        w, v = w[order], v[:, order]
        name = "sparse"
    tol = zero_tolerance(float(np.maximum.reduce(K.diagonal() / M.diagonal())))  # (dense or sparse)
    if w[0] < -tol:  # (w ascending)
        i = int(np.argmin(w))
        dof = model.dof_labels[int(np.argmax(np.abs(v[:, i])))]
        raise SolverError(
            f"the equilibrium is unstable: eigenvalue omega^2 = {w[i]:.4g} 1/s^2 < 0 (a compressed or "
            f"slack span?)", analysis="modal", item=dof)
    # the zero modes lead: w ascends from above -tol, so the candidates |w| <= tol come first, and
    # `zero_modes` keeps the smallest of them up to a gap
    small = np.abs(w) <= tol
    n_rigid = int(np.argmin(small)) if not small.all() else len(w)  # the leading run of |w| <= tol
    if n_rigid > 1:
        n_rigid = int(np.count_nonzero(zero_modes(w, tol)))
        if n_rigid > 1:  # beyond the belt turning with the pulleys: a mechanism (no stiffness somewhere)
            _mechanism(model, v[:, :n_rigid], np.asarray(M.diagonal()))
    shapes = v.T[n_rigid: n_rigid + n_modes].copy()
    # sqrt |omega^2| / 2 pi: the zero modes' round-off and the elastic modes' frequencies (their w > 0)
    root = np.sqrt(np.abs(w[: n_rigid + n_modes])) / TWO_PI
    freq = root[n_rigid:]
    kind, order, span, label, share, sshare, mid = _shape_outputs(
        model, q, shapes, freq, slopes=slopes, joint=None if J is None else shapes @ J.T)
    return ModalResult(
        frequency=freq, shapes=shapes, kind=kind, order=order, span=span, label=label, energy_share=share,
        span_share=sshare, midspan_displacement=mid, n_rigid=n_rigid, rigid_frequency=root[:n_rigid],
        solver=name)


def _shape_outputs(model: System, q: np.ndarray, shapes: np.ndarray, freq: np.ndarray, *,
                   slopes: np.ndarray | None = None, joint: np.ndarray | None = None):
    """`classify`'s outputs of the shapes (n_modes, n_dof) about q, and their mid-span displacements
    (n_modes, n_span) (slopes: `System.arm_slopes` at q, joint: the shapes on the joint coordinates,
    if at hand)."""
    belt = model.belt
    if joint is None:
        joint = model.expand_motion(q, shapes, slopes=slopes)  # (modes, n_p)
    if not belt.elements.n_elem:  # every span a spring: no mid-span motion
        return *classify(model, shapes, freq, q, joint=joint), np.zeros((len(shapes), belt.n_span))
    motion = belt.element_coordinates_batch(joint, offset=False)  # (modes, n_elem, 8)
    out = classify(model, shapes, freq, q, motion=motion, joint=joint)
    return *out, belt.midspan_displacement_linear(belt.element_coordinates(model.expand(q)), motion)


def generalized_eigh(K: np.ndarray, M: np.ndarray, *, vectors: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """All eigenpairs (ascending, x^T M x = 1) of K x = lam M x, K (n, n) symmetric, M positive definite
    (vectors=False: the eigenvalues, None): LAPACK dsygvd (divide and conquer), the call
    scipy.linalg.eigh(K, M, driver="gvd") makes, without its argument checks (a quarter of the modal
    analysis of an 8-DOF drive). Raises LinAlgError as eigh."""
    w, v, info = _dsygvd()(K, M) if vectors else _dsygvd()(K, M, jobz="N")  # (defaults: itype=1, uplo="L", jobz="V")
    if info == 0:
        return w, (v if vectors else None)
    n = K.shape[0]
    if info > n:
        raise np.linalg.LinAlgError(f"The leading minor of order {info - n} of B is not positive definite. The "
                                    f"factorization of B could not be completed and no eigenvalues or "
                                    f"eigenvectors were computed.")
    raise np.linalg.LinAlgError(f"The algorithm failed to compute an eigenvalue while working on the submatrix "
                                f"lying in rows and columns {info}/{n + 1} through mod({info},{n + 1}).")


@functools.cache
def _dsygvd():
    """LAPACK dsygvd from scipy, imported at the first use (not with this module) and kept."""
    from scipy.linalg.lapack import dsygvd

    return dsygvd


def _symmetric_shift_invert(M, lu, sigma: float, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The k eigenpairs of K x = lam M x nearest above sigma as a standard symmetric problem:
    with M = L L^T (banded Cholesky in reverse Cuthill-McKee order) and A = K - sigma M (factor `lu`),
    C = L^T A^-1 L is symmetric with C u = u / (lam - sigma), x = L^-T u. One operator call per Lanczos
    step (the generalized shift-invert mode also calls M every step): 20-25 % less time for 300-1300
    DOFs. Eigenvectors M-normalized. Raises LinAlgError when M is not positive definite."""
    from scipy.linalg import cholesky_banded, solve_banded
    from scipy.sparse import coo_matrix, csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee
    from scipy.sparse.linalg import LinearOperator, eigsh

    n = M.shape[0]
    perm = np.asarray(reverse_cuthill_mckee(csr_matrix(M), symmetric_mode=True), dtype=np.int64)
    Mp = csr_matrix(M)[perm][:, perm].tocoo()
    b = int(np.abs(Mp.row - Mp.col).max(initial=0))
    low = Mp.row >= Mp.col
    ab = np.zeros((b + 1, n))
    ab[Mp.row[low] - Mp.col[low], Mp.col[low]] = Mp.data[low]
    cb = cholesky_banded(ab, lower=True, check_finite=False)  # L_p, M[perm][:, perm] = L_p L_p^T
    rows = np.concatenate([np.arange(k_, n) for k_ in range(b + 1)])
    cols = np.concatenate([np.arange(n - k_) for k_ in range(b + 1)])
    vals = np.concatenate([cb[k_, : n - k_] for k_ in range(b + 1)])
    L = coo_matrix((vals, (perm[rows], cols)), shape=(n, n)).tocsr()  # L = P^T L_p: M = L L^T
    LT = L.T.tocsr()
    op = LinearOperator((n, n), matvec=lambda x: LT @ lu.solve(L @ x), dtype=float)
    mu, U = eigsh(op, k=k, which="LA", tol=1e-12, v0=np.ones(n))
    lam = sigma + 1.0 / mu
    # x = L^-T u: L = P^T L_p (rows permuted), so L^T x = L_p^T (P x) = u  ->  P x = L_p^-T u
    upper = np.zeros((b + 1, n))  # L_p^T in upper band storage
    for k_ in range(b + 1):
        upper[b - k_, k_:] = cb[k_, : n - k_]
    X = np.empty_like(U)
    X[perm] = solve_banded((0, b), upper, U, check_finite=False)
    return lam, X


def _mechanism(model: System, vecs: np.ndarray, Mdiag: np.ndarray) -> None:
    """Raise the error of a drive with more than one zero-frequency mode, naming the model item (a span
    or a pulley) with the largest kinetic energy in the zero modes vecs (n_dof, k)."""
    n = model.n_dof
    energy = (np.abs(vecs) ** 2 * Mdiag[:, None]).sum(axis=1)
    items = [" ".join(lab.split()[:2]) for lab in model.dof_labels]
    totals: dict[str, float] = {}
    for item, e in zip(items, energy):
        totals[item] = totals.get(item, 0.0) + float(e)
    worst = max(totals, key=totals.get)
    dof = max((k for k in range(n) if items[k] == worst), key=lambda k: energy[k])
    raise SolverError(
        f"{vecs.shape[1]} zero-frequency modes: besides the belt turning with the pulleys the drive is a "
        f"mechanism (no stiffness: slack belt without bending stiffness, or a free support)",
        analysis="modal", item=f"{worst} ({model.dof_labels[dof]})")


# ------------------------------------------------------------------------------------ the running belt
def _dense(A) -> np.ndarray:
    return np.asarray(A.toarray() if hasattr(A, "toarray") else A, dtype=float)


def _gyroscopic_dense(K, G, M, tol: float, n_want: int):
    """Eigenvalues s (k,) and shapes (n, k) of (s^2 M + s G + K) phi = 0, dense (module docstring):
    the lowest n_want elastic modes s = i omega and the zero modes (|s|^2 <= tol) while L^-1 K L^-T is
    positive semi-definite, else every eigenvalue of the companion linearization. Returns
    (s, phi, solver name).

    Below the critical speed, with K~ = L^-1 K L^-T = R^T R (pivoted Cholesky, rank r) and G~ likewise,
    H = [[0, R], [-R^T, -G~]] is real skew-symmetric: its eigenvalues are +-i omega, and those of the
    symmetric H^T H = [[R R^T, R G~], [-G~ R^T, R^T R - G~^2]] are omega^2, each twice. The lowest
    eigenpairs of H^T H (LAPACK syevr, real) span an invariant subspace Q of H, on which the small
    Hermitian i Q^T H Q gives the eigenvalues and eigenvectors of H exactly (Rayleigh-Ritz on an
    invariant subspace)."""
    from scipy.linalg import cholesky, eig, eigh, solve_triangular
    from scipy.linalg.lapack import dpstrf

    Kd, Gd, Md = _dense(K), _dense(G), _dense(M)
    n = Kd.shape[0]
    try:
        L = cholesky(Md, lower=True, check_finite=False)
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"the mass matrix is not positive definite: {exc}", analysis="modal") from None

    def congruent(A: np.ndarray) -> np.ndarray:  # L^-1 A L^-T
        X = solve_triangular(L, A, lower=True, check_finite=False)
        return solve_triangular(L, X.T, lower=True, check_finite=False).T

    Kt = congruent(Kd)
    Kt = 0.5 * (Kt + Kt.T)
    Gt = congruent(Gd)
    Gt = 0.5 * (Gt - Gt.T)
    back = lambda X: solve_triangular(L, X, lower=True, trans="T", check_finite=False)  # noqa: E731  L^-T X
    fac, piv, r, _ = dpstrf(Kt, lower=0, tol=tol)  # P^T K~ P = U^T U, U (r, n) upper trapezoidal
    U = np.triu(fac[:r])
    R = np.zeros((r, n))
    R[:, piv - 1] = U
    rest = piv[r:] - 1  # the pivots left: K~ is positive semi-definite iff their Schur complement vanishes
    schur = Kt[np.ix_(rest, rest)] - R[:, rest].T @ R[:, rest]
    if np.abs(schur).max(initial=0.0) <= 10.0 * tol and r > 0:
        N = r + n
        S = np.empty((N, N), order="F")  # (LAPACK's order: no copy on the way in)
        S[:r, :r] = R @ R.T
        S[:r, r:] = R @ Gt
        S[r:, :r] = S[:r, r:].T
        S[r:, r:] = Kt - Gt @ Gt  # R^T R = K~ up to the vanishing Schur complement
        m = min(r, n_want + 2)  # two more: a cut through a near-degenerate pair spoils only the discarded ones
        try:
            # all eigenpairs by divide and conquer: faster here than the subset driver (syevr) for ~40 of them
            Q = eigh(S, driver="evd", check_finite=False, overwrite_a=True)[1][:, n - r: n - r + 2 * m]
            HQ = np.empty((N, 2 * m))
            HQ[:r] = R @ Q[r:]
            HQ[r:] = -R.T @ Q[:r] - Gt @ Q[r:]
            mu, W = eigh(1j * (Q.T @ HQ), driver="evd", check_finite=False)
        except np.linalg.LinAlgError as exc:
            raise SolverError(f"dense gyroscopic eigen-solver failed: {exc}", analysis="modal") from None
        # i H z = mu z: H z = -i mu z; the conjugate is the eigenvector of s = +i mu, with y = (R xi, s xi)
        mu, W = mu[m:], W[:, m:]
        xi = np.conj(Q[r:] @ W)
        null = np.zeros((n, n - r))  # K~'s null directions (the belt turning with the pulleys): R x = 0
        y = np.eye(n - r)
        null[piv[r:] - 1] = y
        null[piv[:r] - 1] = -solve_triangular(U[:, :r], U[:, r:], check_finite=False) @ y
        s = np.concatenate([np.zeros(n - r, dtype=complex), 1j * mu])
        return s, back(np.concatenate([null.astype(complex), xi], axis=1)), "dense gyroscopic"
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Kt
    A[n:, n:] = -Gt
    try:
        s, Z = eig(A, check_finite=False)
    except np.linalg.LinAlgError as exc:
        raise SolverError(f"dense eigen-solver failed: {exc}", analysis="modal") from None
    return s, back(Z[:n]), "dense companion"


def _gyroscopic_sparse(K, G, M, tol: float, n_want: int):
    """As `_gyroscopic_dense` by ARPACK: shift-invert about sigma < 0 on the companion linearization
    z = (x, s x): (A - sigma B)^-1 B with one sparse LU of P = K + sigma G + sigma^2 M."""
    from scipy.sparse import csc_matrix, csr_matrix
    from scipy.sparse.linalg import LinearOperator, eigs, splu

    Ks, Gs, Ms = csr_matrix(K), csr_matrix(G), csr_matrix(M)
    n = Ks.shape[0]
    sigma = -np.sqrt(max(tol, 1e-12)) * 10.0 - 1.0
    try:
        lu = splu(csc_matrix(Ks + sigma * Gs + sigma * sigma * Ms))
    except RuntimeError as exc:
        raise SolverError(f"sparse shift-invert eigen-solver failed: {exc}", analysis="modal") from None
    GsM = (Gs + sigma * Ms).tocsr()

    def op(v: np.ndarray) -> np.ndarray:
        v1, v2 = v[:n], v[n:]
        x = -lu.solve(Ms @ v2 + GsM @ v1)
        return np.concatenate([x, v1 + sigma * x])

    k = min(2 * n - 2, 2 * n_want + 4)
    try:
        nu, Z = eigs(LinearOperator((2 * n, 2 * n), matvec=op, dtype=float), k=k, which="LM", tol=1e-12,
                     v0=_start_vector(2 * n))
    except Exception as exc:  # ArpackNoConvergence and friends
        raise SolverError(f"sparse gyroscopic eigen-solver failed: {exc}", analysis="modal") from None
    return sigma + 1.0 / nu, Z[:n], "sparse gyroscopic"


def _start_vector(n: int) -> np.ndarray:
    """ARPACK's start vector (n,): fixed pseudo-random numbers, so that a run repeats to the bit (ARPACK's
    own random start made two runs of one sparse gyroscopic problem differ by 1e-6 in a frequency), and
    with no symmetry a mode shape could be orthogonal to."""
    return np.random.default_rng(20261123).standard_normal(n)


def _normalized(phi: np.ndarray, M) -> np.ndarray:
    """Shapes (n, k) scaled to phi^H M phi = 1 with their largest entry real and positive."""
    Mphi = np.asarray(M @ phi)
    norm = np.sqrt(np.real(np.einsum("ik,ik->k", np.conj(phi), Mphi)))
    phi = phi / np.where(norm > 0, norm, 1.0)
    big = phi[np.argmax(np.abs(phi), axis=0), np.arange(phi.shape[1])]
    return phi * (np.conj(big) / np.where(np.abs(big) > 0, np.abs(big), 1.0))


def _solve_running(model: System, q: np.ndarray, *, n_modes: int, solver: str, tangent=None) -> ModalResult:
    """`solve_modes` of the running belt: the gyroscopic eigenproblem about q (module docstring);
    tangent: as `solve_modes`."""
    K = model.equilibrium(q)[1] if tangent is None else tangent
    M = model.mass_matrix(q)
    G = model.gyroscopic_matrix(q)
    n = model.n_dof
    use_dense = model.dense if solver == "auto" else solver == "dense"
    Kdiag = np.asarray(K.diagonal() if hasattr(K, "toarray") else np.diag(K))
    Mdiag = np.asarray(M.diagonal() if hasattr(M, "toarray") else np.diag(M))
    lam_max = float(np.max(np.abs(Kdiag) / Mdiag))
    tol = zero_tolerance(lam_max)  # on |s|^2, as at rest
    n_want = min(n - 1, n_modes)
    s, phi, name = (_gyroscopic_dense if use_dense else _gyroscopic_sparse)(K, G, M, tol, n_want)
    size = np.abs(s)
    rigid = zero_modes(size ** 2, tol)
    eps = 1e-7 * size + np.sqrt(tol) * 1e-3  # |Re s| and |Im s| below this are round-off
    oscillating = ~rigid & (s.imag > eps) & (s.real >= -eps)  # one of each conjugate pair; flutter's growing one
    diverging = ~rigid & (np.abs(s.imag) <= eps) & (s.real > eps)  # one of each +-s pair
    pick = np.flatnonzero(oscillating | diverging)
    order = np.lexsort((np.abs(s[pick].imag), ~diverging[pick]))  # divergent modes first, then by frequency
    pick = pick[order][:n_modes]
    # the companion linearization has two zero eigenvalues (a Jordan chain) per rigid mode, i H one
    n_rigid = int(rigid.sum()) if name == "dense gyroscopic" else (int(rigid.sum()) + 1) // 2
    if n_rigid > 1:
        _mechanism(model, phi[:, rigid], Mdiag)
    shapes = _normalized(phi[:, pick], M).T.copy()
    sel = s[pick]
    freq = np.where(diverging[pick], 0.0, np.abs(sel.imag)) / (2 * np.pi)
    growth = np.where(np.abs(sel.real) > eps[pick], sel.real, 0.0)
    stability = tuple("divergence" if d else ("flutter" if g > 0 else "stable")
                      for d, g in zip(diverging[pick], growth))
    kind, order_, span, label, share, sshare, mid = _shape_outputs(model, q, shapes, freq)
    label = tuple(lab if st == "stable" else f"{lab} ({st})" for lab, st in zip(label, stability))
    critical = critical_speed(model, q) if any(st != "stable" for st in stability) else float("nan")
    return ModalResult(
        frequency=freq, shapes=shapes, kind=kind, order=order_, span=span, label=label, energy_share=share,
        span_share=sshare, midspan_displacement=mid, n_rigid=n_rigid,
        rigid_frequency=np.sort(size[rigid])[:n_rigid] / (2 * np.pi), solver=name,
        belt_speed=float(model.belt_speed), growth_rate=growth, stability=stability, critical_speed=critical)


def critical_speed(model: System, q: np.ndarray) -> float:
    """The first critical belt speed (m/s) about the state q: the smallest c with K_0 - c^2 B singular
    besides the belt's rigid turn, K_0 the loaded tangent without the centripetal stiffness, B its
    matrix per unit speed squared (both on q). The tensions are those of q (frozen); inf if none."""
    from scipy.linalg import eigh, null_space

    c = model.belt_speed
    B = _dense(model.project_matrix(q, model.transport_matrices()[1]))
    _, K = model.equilibrium(q)
    K0 = _dense(K) + c * c * B
    M = _dense(model.mass_matrix(q))
    w, v = eigh(K0, M, driver="gvd", check_finite=False)
    lam_max = float(np.max(np.abs(np.diag(K0)) / np.diag(M)))
    tol = zero_tolerance(lam_max)
    Z = null_space((M @ v[:, zero_modes(w, tol)]).T)  # the complement of the rigid turn
    if w[0] < -tol:
        return 0.0  # unstable at rest
    nu = eigh(Z.T @ B @ Z, Z.T @ K0 @ Z, eigvals_only=True, check_finite=False)
    top = float(nu.max(initial=0.0))
    return float(1.0 / np.sqrt(top)) if top > 0 else float("inf")


def energy_shares(model: System, shapes: np.ndarray, q: np.ndarray | None = None, *, motion=None, joint=None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Kinetic-energy shares of mass-normalized shapes (n_modes, n_dof), from the system's components
    (motion, joint: the shapes' element coordinates and joint coordinates, if at hand).

    Returns shares (n_modes, len(KINDS)), span_long (n_modes, n_span), span_trans (n_modes, n_span)
    (all divided by the total) and the transverse nodal motion (n_modes, n_elem, 4; None without elements).
    """
    if shapes.dtype.kind == "c":  # the energy of Re phi and Im phi together (phi^H M phi), in one call
        k = shapes.shape[0]
        both = lambda x: None if x is None else np.concatenate([x.real, x.imag])  # noqa: E731
        E, b = model.kinetic_energies(both(shapes), q, motion=both(motion), joint=both(joint))
        E, b = E[:k] + E[k:], (None if b is None else b[:k] + 1j * b[k:])
    else:
        E, b = model.kinetic_energies(shapes, q, motion=motion, joint=joint)
    nk, n = len(KINDS), model.belt.n_span
    total = np.add.reduce(E[:, :nk], axis=1, keepdims=True)
    total[total == 0] = 1.0
    E /= total
    return E[:, :nk], E[:, nk: nk + n], E[:, nk + n:], b


def _parts(shares: np.ndarray, span_long: np.ndarray, span_trans: np.ndarray, layout) -> list[str]:
    """The parts of a mode's kinetic energy, largest first, as words: the pulley kinds as a whole,
    the belt per span and direction ("transverse span 2 (C-T) 34 %")."""
    parts = [(float(shares[i]), f"{KINDS[i]} {shares[i]:.0%}") for i in range(len(KINDS))
             if KINDS[i] not in ("longitudinal", "transverse")]
    for s in range(len(span_long)):
        parts.append((float(span_trans[s]), f"transverse span {s + 1} ({layout.span_name(s)}) {span_trans[s]:.0%}"))
        parts.append((float(span_long[s]), f"longitudinal span {s + 1} ({layout.span_name(s)}) {span_long[s]:.0%}"))
    return [text for _, text in sorted(parts, key=lambda x: -x[0])]


def half_waves(w: np.ndarray, threshold: float = 0.05) -> int:
    """Half-wave count of a sampled transverse displacement: sign changes between significant samples + 1.
    A complex (travelling) shape: the humps of its envelope |w|, i.e. 1 + the interior minima of |w| that
    dip below half of the smaller neighbouring maximum."""
    if np.iscomplexobj(w):
        return half_waves_envelope(w[None], threshold)[0]
    return int(half_waves_real(w[None], threshold)[0])


def half_waves_envelope(W: np.ndarray, threshold: float = 0.05) -> list[int]:
    """`half_waves` of each row of complex samples W (m, P): the humps of each envelope |w| (the array
    work for all rows at once, the count on each row's extrema)."""
    env = np.abs(W)
    floor = (threshold * env.max(axis=1)).tolist()
    slope = np.sign(np.diff(env, axis=1))
    turn = np.zeros(env.shape, dtype=bool)  # each row's extrema: its ends and where the slope's sign changes
    turn[:, 0] = turn[:, -1] = True
    turn[:, 1:-1] = slope[:, 1:] != slope[:, :-1]
    out = []
    for row, fl in zip(np.split(env[turn], np.cumsum(turn.sum(axis=1))[:-1]), floor):
        turns = row.tolist()
        humps, top, low = 1, turns[0], turns[0]  # the current hump's maximum and the lowest value after it
        for x in turns[1:]:
            if low < 0.5 * top and x > 2.0 * low and x > fl:  # a rise after a deep dip: a new hump
                humps, top, low = humps + 1, x, x
            elif x > top and low >= 0.5 * top:  # still climbing the same hump
                top = low = x
            else:
                low = min(low, x)
        out.append(humps)
    return out


def half_waves_real(W: np.ndarray, threshold: float = 0.05) -> np.ndarray:
    """`half_waves` of each row of real samples W (m, P), vectorized: (m,) sign changes between the
    significant samples (|w| above threshold x the row's largest) + 1. The sign of the last significant
    sample is carried over the insignificant ones, so a change is counted once, where it shows."""
    A = np.abs(W)
    big = A > threshold * A.max(axis=1, keepdims=True)
    last = np.maximum.accumulate(np.where(big, np.arange(W.shape[1]), 0), axis=1)  # last significant index
    s = np.take_along_axis(np.where(big, np.sign(W), 0.0), last, axis=1)  # 0 before the first significant one
    return np.count_nonzero((s[:, 1:] != s[:, :-1]) & (s[:, :-1] != 0.0), axis=1) + 1


def classify(model: System, shapes: np.ndarray, freq: np.ndarray, q: np.ndarray | None = None, *, motion=None,
             joint=None):
    """kind, order, span, label, energy shares and span shares of each mode. A mode whose largest
    share stays below 1/2 is "mixed" and its label names its two largest parts (e.g. the tensioner
    arm coupled with the transverse motion of an adjacent span). motion, joint: as `energy_shares`."""
    shares, span_long, span_trans, b = energy_shares(model, shapes, q, motion=motion, joint=joint)
    n_modes = shapes.shape[0]
    wsamp = (np.matmul(model.belt.sampling_table(8)[None], b[..., None])[..., 0]  # (k, n_elem, 8) samples
             if model.belt.elements.n_elem else None)
    orders, spans, labels = [], [], []
    rank: dict[str, int] = {}
    names = model.layout
    kind_of = []  # the largest share's kind (the first of equal ones), "mixed" below 1/2
    for row in shares.tolist():
        x = max(row)
        kind_of.append(KINDS[row.index(x)] if x >= 0.5 else "mixed")
    waves = [1] * n_modes  # a spring span has no transverse shape of its own: its lumped end masses swing with the pulleys
    if "transverse" in kind_of:
        trans_span = np.argmax(span_trans, axis=1)
        is_trans = np.array([k == "transverse" for k in kind_of], dtype=bool)
        for s in np.unique(trans_span[is_trans]).tolist():  # each span's transverse modes at once
            els = model.belt.span_elements[s]
            ks = np.flatnonzero(is_trans & (trans_span == s))
            if not len(els):
                continue
            W = wsamp[ks][:, els].reshape(len(ks), -1)
            got = half_waves_envelope(W) if np.iscomplexobj(W) else half_waves_real(W).tolist()  # travelling: envelopes
            for k, w in zip(ks.tolist(), got):
                waves[k] = w
    for k, kind in enumerate(kind_of):
        span = 0
        if kind == "transverse":
            span = int(trans_span[k]) + 1
            order = int(waves[k])
        else:
            order = rank[kind] = rank.get(kind, 0) + 1
            if kind == "longitudinal":
                s = int(np.argmax(span_long[k]))
                if span_long[k, s] >= 0.8 * span_long[k].sum():
                    span = s + 1
        orders.append(order)
        spans.append(span)
        text = f"{ordinal(order)} {kind}"
        if span:
            text += f", span {span} ({names.span_name(span - 1)})"
        if kind == "mixed":
            text += ": " + " + ".join(_parts(shares[k], span_long[k], span_trans[k], names)[:2])
        labels.append(text)
    order_span = np.array([orders, spans], dtype=int)
    return tuple(kind_of), order_span[0], order_span[1], tuple(labels), shares, span_long + span_trans
