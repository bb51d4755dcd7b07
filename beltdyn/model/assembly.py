"""Assembly: the one pattern that scatters element blocks and component matrices into the reduced
matrices, dense (small models) or CSR (large ones)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.model.components import LinearComponent

_PATTERNS: dict = {}  # make_pattern memo: re-laid systems of one drive share their pattern


DENSE_LIMIT = 200  # models up to this many DOFs use dense linear algebra


@dataclass(frozen=True, kw_only=True)
class Pattern:
    """Scatter indices for assembling (n_elem, m, m) blocks and component entries.

    flat (n_elem*m*m,): row*(n+1)+col of every block entry; for the sparse path `slot` maps each entry
    to its CSR data slot (-1 for the dummy row/column) and indices/indptr give the pattern, which
    also holds the diagonal and every component entry.
    """

    n: int
    flat: np.ndarray
    slot: np.ndarray | None = None
    indices: np.ndarray | None = None
    indptr: np.ndarray | None = None
    diag_slot: np.ndarray | None = None
    nnz: int = 0

    def slots_of(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """CSR data slots of entries (rows, cols) that the pattern holds (sparse path)."""
        keys = self.__dict__.get("_keys")
        if keys is None:  # row * (n + 1) + col of every slot: ascending (rows in order, columns sorted)
            keys = np.repeat(np.arange(self.n, dtype=np.int64), np.diff(self.indptr)) * (self.n + 1) + self.indices
            object.__setattr__(self, "_keys", keys)
        return np.searchsorted(keys, np.asarray(rows, dtype=np.int64) * (self.n + 1) + cols)


def element_pairs(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column index of every entry of the (n_elem, m, m) element blocks, flattened; the
    padding index n marks entries that belong to no DOF."""
    m = idx.shape[1]
    return (np.repeat(idx[:, :, None], m, axis=2).ravel(), np.repeat(idx[:, None, :], m, axis=1).ravel())


def make_pattern(idx: np.ndarray, n: int, *, sparse: bool, extra: tuple[np.ndarray, np.ndarray] | None = None) -> Pattern:
    import hashlib

    h = hashlib.blake2b(np.ascontiguousarray(idx).tobytes(), digest_size=16)
    if extra is not None:
        h.update(np.ascontiguousarray(extra[0]).tobytes())
        h.update(np.ascontiguousarray(extra[1]).tobytes())
    key = (n, sparse, idx.shape, h.digest())
    hit = _PATTERNS.get(key)
    if hit is None:
        if len(_PATTERNS) > 16:
            _PATTERNS.clear()
        hit = _PATTERNS[key] = _make_pattern(idx, n, sparse=sparse, extra=extra)
    return hit


def _make_pattern(idx: np.ndarray, n: int, *, sparse: bool, extra: tuple[np.ndarray, np.ndarray] | None = None) -> Pattern:
    rows, cols = element_pairs(idx)
    flat = rows * (n + 1) + cols
    if not sparse:
        return Pattern(n=n, flat=flat)
    keep = (rows < n) & (cols < n)
    diag_keys = np.arange(n) * (n + 1) + np.arange(n)
    more = [] if extra is None else [extra[0].astype(np.int64) * (n + 1) + extra[1]]
    keys, inverse = np.unique(np.concatenate([flat[keep], diag_keys, *more]), return_inverse=True)
    slot = np.full(flat.shape, -1, dtype=np.int64)
    slot[keep] = inverse[: keep.sum()]
    r, c = np.divmod(keys, n + 1)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, r + 1, 1)
    indptr = np.cumsum(indptr)
    diag_slot = np.searchsorted(keys, diag_keys)
    return Pattern(n=n, flat=flat, slot=slot, indices=c.astype(np.int32), indptr=indptr.astype(np.int32),
                   diag_slot=diag_slot, nnz=len(keys))


def _assembled(n: int, dense: bool, pat: Pattern, blocks: np.ndarray | None, springs: np.ndarray | None,
               scatter: np.ndarray | None, linear, diagonal: np.ndarray | None):
    """`System.assemble` on its pattern: element blocks (n_elem, m, m) (None or empty: none), the spring
    spans' blocks (k, m_s, m_s) through `scatter` (None: none), + the constant stiffness `linear` (dense
    (n, n) or CSR data; None: none), + a diagonal (n,)."""
    has_blocks = blocks is not None and len(blocks) > 0
    if dense:
        if springs is None:
            flat, weights = (pat.flat, blocks.ravel()) if has_blocks else (pat.flat[:0], np.zeros(0))
        elif has_blocks:
            flat, weights = np.concatenate([pat.flat, scatter]), np.concatenate([blocks.ravel(), springs.ravel()])
        else:
            flat, weights = scatter, springs.ravel()
        K = np.bincount(flat, weights=weights, minlength=(n + 1) ** 2).reshape(n + 1, n + 1)[:n, :n]
        if linear is not None:
            K += linear
        if diagonal is not None:
            K[np.diag_indices(n)] += diagonal
        return K
    from scipy.sparse import csr_matrix

    if has_blocks:
        keep = pat.slot >= 0
        data = np.bincount(pat.slot[keep], weights=blocks.ravel()[keep], minlength=pat.nnz)
    else:
        data = np.zeros(pat.nnz)
    if springs is not None:
        live = scatter >= 0
        data += np.bincount(scatter[live], weights=springs.ravel()[live], minlength=pat.nnz)
    if linear is not None:
        data += linear
    if diagonal is not None:
        data[pat.diag_slot] += diagonal
    return csr_matrix((data, pat.indices, pat.indptr), shape=(n, n))


def _add_components(components: tuple[LinearComponent, ...], n: int, M: np.ndarray, fg: np.ndarray, g: np.ndarray):
    """The components' masses added into the dense mass M (n, n) and their weights into fg (n,) (gravity g
    (2,)), in place; their stiffness and damping summed (n, n) each (None without any) and the offset
    sum K_c free_c (n,) (None without any)."""
    K = C = offset = None
    for c in components:
        d = c.dofs
        if len(d) == 1:  # one DOF: its entries as scalars, [i, i] of [0, 0] (no fancy indexing)
            d = int(d[0])
            at, of = (d, d), (0, 0)
        else:  # the component's rows and columns, all of each matrix (`[()]`: the array itself)
            at, of = (d[:, None], d), ()
        if c.stiffness is not None:
            if K is None:
                K = np.zeros((n, n))
            K[at] += c.stiffness[of]
            if c.free is not None:
                if offset is None:
                    offset = np.zeros(n)
                offset[d] += c.stiffness[of] * c.free[0] if of else c.stiffness @ np.asarray(c.free, dtype=float)
        if c.damping is not None:
            if C is None:
                C = np.zeros((n, n))
            C[at] += c.damping[of]
        if c.mass is not None:
            M[at] += c.mass[of]
        if c.weight is not None:
            fg[d] += (c.weight @ g)[of[1:]]
    return K, C, offset


def _summed_sparse(components: tuple[LinearComponent, ...], pattern: Pattern, attr: str) -> np.ndarray | None:
    """The components' matrices `attr` summed: the data (nnz,) of a CSR matrix on the system's pattern
    (which holds every component entry); None without any."""
    mats = [(c.dofs, mat) for c in components if (mat := getattr(c, attr)) is not None]
    if not mats:
        return None
    r = np.concatenate([np.repeat(d, len(d)) for d, _ in mats])
    c = np.concatenate([np.tile(d, len(d)) for d, _ in mats])
    v = np.concatenate([np.asarray(mat, dtype=float).ravel() for _, mat in mats])
    data = np.zeros(pattern.nnz)
    np.add.at(data, pattern.slots_of(r, c), v)
    return data
