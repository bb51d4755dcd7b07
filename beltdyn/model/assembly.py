"""Assembly: the one pattern that scatters element blocks and component matrices into the reduced
matrices, dense (small models) or CSR (large ones).

Nomenclature: n the joint coordinates p; element blocks (n_elem, m, m) of the ANCF spans on their
coordinate indices idx (n_elem, m) (the padding index n marks a column that belongs to no coordinate);
a component's constant matrices (k, k) on its coordinates `dofs` (k,).

Reduced matrices (paper Eqs. 20-23, 26): A = sum_e T_e^T A_e T_e + sum_c P_c^T A_c P_c, P_c the
selection of a component's coordinates. Every entry goes through one `Pattern`: a dense pattern
sums into (n + 1)^2 slots (row * (n + 1) + column; the padding row and column cut off), a sparse one
into the data slots of one CSR structure that holds every element entry, the diagonal and every
component entry. `component_sums` gives the components' stiffness, damping, mass, offset K_c free_c
and weight W_c g on the pattern: one implementation for dense and sparse.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beltdyn.model.components import LinearComponent

DENSE_LIMIT = 200  # models up to this many DOFs use dense linear algebra

NO_INDEX = np.zeros(0, dtype=np.int64)  # an empty index array (no entries), shared: nothing can change it


def sorted_unique(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct keys ascending (u,), the index of each key among them (k,)) of integer keys (k,):
    np.unique(keys, return_inverse=True)'s answer, by a stable sort, which is quick on keys that come mostly
    in order (a pattern's, element after element; numpy's unique sorts them as if they were random)."""
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    first = np.empty(len(ordered), dtype=bool)
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    inverse = np.empty(len(ordered), dtype=np.intp)
    inverse[order] = np.cumsum(first) - 1
    return ordered[first], inverse


@dataclass(frozen=True, kw_only=True)
class Pattern:
    """Scatter indices for assembling (n_elem, m, m) blocks and component entries.

    flat (n_elem*m*m,): row*(n+1)+col of every block entry; for the sparse path `slot` maps each entry
    to its CSR data slot (-1 for the dummy row/column) and indices/indptr give the pattern, which
    also holds the diagonal and every component entry; keys (nnz,) row*(n+1)+col of every CSR slot,
    ascending (derived).
    """

    n: int
    flat: np.ndarray
    slot: np.ndarray | None = None
    indices: np.ndarray | None = None
    indptr: np.ndarray | None = None
    diag_slot: np.ndarray | None = None
    nnz: int = 0
    keys: np.ndarray | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        keys = None
        if self.indptr is not None:  # rows in order, columns sorted within a row: ascending
            keys = np.repeat(np.arange(self.n, dtype=np.int64), np.diff(self.indptr)) * (self.n + 1) + self.indices
            keys.setflags(write=False)
        object.__setattr__(self, "keys", keys)

    @property
    def sparse(self) -> bool:
        return self.slot is not None

    def slots_of(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """CSR data slots of entries (rows, cols) that the pattern holds (sparse path)."""
        return np.searchsorted(self.keys, np.asarray(rows, dtype=np.int64) * (self.n + 1) + cols)

    def scatter(self, rows: np.ndarray, cols: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Entries (rows, cols, values) (r,) each summed on the pattern: a dense (n, n) array, or the
        data (nnz,) of a CSR matrix on the pattern (sparse)."""
        n = self.n
        if self.sparse:
            return np.bincount(self.slots_of(rows, cols), weights=values, minlength=self.nnz)
        return np.bincount(np.asarray(rows, dtype=np.int64) * n + cols, weights=values, minlength=n * n).reshape(n, n)

    def matrix(self, data: np.ndarray):
        """A CSR matrix (n, n) of data (nnz,) on the (sparse) pattern."""
        from scipy.sparse import csr_matrix  # (measured: scipy.sparse is not on the import path of a dense model)

        return csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def element_pairs(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column index of every entry of the (n_elem, m, m) element blocks, flattened; the
    padding index n marks entries that belong to no DOF."""
    m = idx.shape[1]
    return (np.repeat(idx[:, :, None], m, axis=2).ravel(), np.repeat(idx[:, None, :], m, axis=1).ravel())


def pattern_key(idx: np.ndarray, n: int, *, sparse: bool, extra: tuple[np.ndarray, np.ndarray] | None = None) -> tuple:
    """What `make_pattern` reads, as a key (hashable, compared by value: the arrays' shapes and bytes):
    equal keys make equal patterns (`reuse.Reuse`: a study's analyses of one drive share theirs)."""
    parts = [idx] if extra is None else [idx, *extra]
    return (n, sparse, *[(a.dtype.str, a.shape, np.ascontiguousarray(a).tobytes()) for a in parts])


def make_pattern(idx: np.ndarray, n: int, *, sparse: bool, extra: tuple[np.ndarray, np.ndarray] | None = None) -> Pattern:
    """The pattern of element blocks on idx (n_elem, m) over n coordinates; sparse: also holding the
    diagonal and the entries extra (rows, cols) (the components' and the spring spans'). Its arrays are
    read-only: a study's analyses share a pattern (`reuse.Reuse`)."""
    rows, cols = element_pairs(idx)
    flat = rows * (n + 1) + cols
    flat.setflags(write=False)
    if not sparse:
        return Pattern(n=n, flat=flat)
    keep = (rows < n) & (cols < n)
    diag_keys = np.arange(n) * (n + 1) + np.arange(n)
    more = [] if extra is None else [extra[0].astype(np.int64) * (n + 1) + extra[1]]
    keys, inverse = sorted_unique(np.concatenate([flat[keep], diag_keys, *more]))
    slot = np.full(flat.shape, -1, dtype=np.int64)
    slot[keep] = inverse[: keep.sum()]
    r, c = np.divmod(keys, n + 1)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(r, minlength=n), out=indptr[1:])  # (entries per row)
    diag_slot = np.searchsorted(keys, diag_keys)
    indices, indptr = c.astype(np.int32), indptr.astype(np.int32)
    for a in (slot, indices, indptr, diag_slot):
        a.setflags(write=False)
    return Pattern(n=n, flat=flat, slot=slot, indices=indices, indptr=indptr, diag_slot=diag_slot, nnz=len(keys))


def assemble_blocks(pattern: Pattern, blocks: np.ndarray | None, springs: np.ndarray | None,
                    scatter: np.ndarray | None, linear, diagonal: np.ndarray | None):
    """Element blocks (n_elem, m, m) (None or empty: none), the spring spans' blocks (k, m_s, m_s) through
    `scatter` (their flat index (dense) or CSR slot (sparse); None: none), + the constant stiffness
    `linear` (dense (n, n) or CSR data; None: none), + a diagonal (n,): dense (n, n) or CSR."""
    n = pattern.n
    has_blocks = blocks is not None and len(blocks) > 0
    if not pattern.sparse:
        if springs is None:
            flat, weights = (pattern.flat, blocks.ravel()) if has_blocks else (pattern.flat[:0], np.zeros(0))
        elif has_blocks:
            flat, weights = np.concatenate([pattern.flat, scatter]), np.concatenate([blocks.ravel(), springs.ravel()])
        else:
            flat, weights = scatter, springs.ravel()
        K = np.bincount(flat, weights=weights, minlength=(n + 1) ** 2).reshape(n + 1, n + 1)[:n, :n]
        if linear is not None:
            K += linear
        if diagonal is not None:
            K[np.diag_indices(n)] += diagonal
        return K
    if has_blocks:
        keep = pattern.slot >= 0
        data = np.bincount(pattern.slot[keep], weights=blocks.ravel()[keep], minlength=pattern.nnz)
    else:
        data = np.zeros(pattern.nnz)
    if springs is not None:
        live = scatter >= 0
        data += np.bincount(scatter[live], weights=springs.ravel()[live], minlength=pattern.nnz)
    if linear is not None:
        data += linear
    if diagonal is not None:
        data[pattern.diag_slot] += diagonal
    return pattern.matrix(data)


def component_entries(components: tuple[LinearComponent, ...], attr: str
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Every entry (rows, cols, values) (r,) each of the components' matrices `attr` ("stiffness",
    "damping" or "mass") on the joint coordinates; None without any."""
    mats = [(c.dofs, mat) for c in components if (mat := getattr(c, attr)) is not None]
    if not mats:
        return None
    rows = np.concatenate([np.repeat(d, len(d)) for d, _ in mats])
    cols = np.concatenate([np.tile(d, len(d)) for d, _ in mats])
    values = np.concatenate([np.asarray(mat, dtype=float).ravel() for _, mat in mats])
    return rows, cols, values


def component_nonzeros(components: tuple[LinearComponent, ...]) -> tuple[np.ndarray, np.ndarray] | None:
    """(rows, cols) of every nonzero entry of the components' stiffness, damping and mass (what a
    sparse pattern must hold); None without any."""
    rows, cols = [], []
    for c in components:
        for mat in (c.stiffness, c.damping, c.mass):
            if mat is not None:
                r, cc = np.nonzero(mat)
                rows.append(c.dofs[r])
                cols.append(c.dofs[cc])
    return (np.concatenate(rows), np.concatenate(cols)) if rows else None


@dataclass(frozen=True, kw_only=True)
class ComponentSums:
    """The components summed on a pattern: stiffness K_c and mass M_c (dense (n, n) or CSR data (nnz,)),
    damping C_c (dense (n, n) or CSR), each None without any; offset sum K_c free_c (n,) (None without a
    free value) and weight sum W_c g (n,)."""

    stiffness: np.ndarray | None
    damping: object
    mass: np.ndarray | None
    offset: np.ndarray | None
    weight: np.ndarray


def component_sums(components: tuple[LinearComponent, ...], pattern: Pattern, gravity: np.ndarray) -> ComponentSums:
    """The components' matrices, offsets and weights (gravity g (2,)) on the pattern (`ComponentSums`)."""
    n = pattern.n
    summed = {}
    for attr in ("stiffness", "damping", "mass"):
        entries = component_entries(components, attr)
        summed[attr] = None if entries is None else pattern.scatter(*entries)
    damping = summed["damping"]
    if damping is not None and pattern.sparse:
        damping = pattern.matrix(damping)
    freed = [c for c in components if c.free is not None and c.stiffness is not None]
    offset = None
    if freed:
        offset = np.bincount(np.concatenate([c.dofs for c in freed]), minlength=n,
                             weights=np.concatenate([c.stiffness @ np.asarray(c.free, dtype=float) for c in freed]))
    weighed = [c for c in components if c.weight is not None]
    weight = np.zeros(n)
    if weighed:
        weight = np.bincount(np.concatenate([c.dofs for c in weighed]), minlength=n,
                             weights=np.concatenate([np.asarray(c.weight, dtype=float) @ gravity for c in weighed]))
    return ComponentSums(stiffness=summed["stiffness"], damping=damping, mass=summed["mass"], offset=offset,
                         weight=weight)
