"""The hybrid drive model: ANCF belt spans on rigid pulleys, in independent coordinates.

Nomenclature (paper section 2.2):
- q (n_dof,): independent coordinates, measured from the reference configuration (q = 0 is the
  stress-free L0 geometry, or the prestrained one). A pulley carries only the DOFs its support
  allows: rotation theta (rad, counter-clockwise), plus the slide offset u (m) or the bearing
  displacements (x, y) (m). A span carries every coordinate of its interior nodes (r1, r2, r1', r2')
  and the gradients of its end nodes; the end-node positions are dependent (the joints).
- Joint (DESIGN section 2): r_end = c + R n + R theta (z x n) + translation, n the outward normal at
  the tangent point, z x n the pulley surface direction for a positive rotation; the gradients of
  the end nodes are free (pinned, "bi-articulated"). The constraint is linear, so the paper's
  transformation matrix B is constant: element coordinates e = e0 + T q[idx] element by element,
  with T (n_elem, 8, m) and idx (n_elem, m) (padding points at the dummy index n_dof).
- Reduced matrices: M = sum_e T^T M_e T + pulley masses; K_t = sum_e T^T K_e T + bearing springs
  (paper Eqs. 20-23, 26). Assembly scatters (n_elem, m, m) blocks through precomputed indices into a
  dense array (small models) or a CSR matrix with a fixed pattern (large models).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import ancf
from .config import DriveConfig
from .geometry import Layout

DENSE_LIMIT = 200  # models up to this many DOFs use dense linear algebra


def _z_cross(n: np.ndarray) -> np.ndarray:
    return np.array([-n[1], n[0]])


@dataclass(frozen=True, kw_only=True)
class Pattern:
    """Scatter indices for assembling (n_elem, m, m) blocks into an (n+1) x (n+1) matrix.

    flat (n_elem*m*m,): row*(n+1)+col of every block entry; for the sparse path `slot` maps each entry
    to its CSR data slot (-1 for the dummy row/column) and indices/indptr give the pattern.
    """

    n: int
    flat: np.ndarray
    slot: np.ndarray | None = None
    indices: np.ndarray | None = None
    indptr: np.ndarray | None = None
    diag_slot: np.ndarray | None = None
    nnz: int = 0


@dataclass(frozen=True, kw_only=True)
class DriveModel:
    """The assembled model. Shapes: n_dof reduced DOFs, n_elem span elements, n_p pulleys."""

    layout: Layout
    elements: ancf.ElementSet
    elem_span: np.ndarray  # (n_elem,) span index of each element
    span_elements: tuple[np.ndarray, ...]  # element indices of each span, in order
    T: np.ndarray  # (n_elem, 8, m) element coordinates per independent coordinate
    idx: np.ndarray  # (n_elem, m) independent coordinate indices (n_dof = padding)
    e0: np.ndarray  # (n_elem, 8) element coordinates at q = 0
    n_dof: int
    dof_labels: tuple[str, ...]
    rot_dof: np.ndarray  # (n_p,) rotation DOF index of each pulley
    trans_dof: tuple[tuple[int, ...], ...]  # translation DOF indices of each pulley
    trans_dir: tuple[np.ndarray, ...]  # (k, 2) direction of each translation DOF (m per unit q)
    span_dof_slices: tuple[slice, ...]  # contiguous DOF range of each span's own coordinates
    spring: np.ndarray  # (n_dof,) bearing spring stiffness on translation DOFs (diagonal)
    mass: np.ndarray | object  # (n_dof, n_dof) dense array or scipy CSR matrix
    gravity_force: np.ndarray  # (n_dof,) generalized weight of belt and pulleys
    pattern: Pattern
    dense: bool
    reference_length: np.ndarray  # (n_span,) reference (unstretched) length of each span
    reference_direction: np.ndarray  # (n_span, 2) unit direction of each span at q = 0
    reference_normal: np.ndarray  # (n_span, 2) unit normal (z x t) of each span at q = 0
    prestrain_stretch: float = 1.0
    pulley_mass: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pulley_inertia: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def Tt(self) -> np.ndarray:
        """(n_elem, m, 8) transposed element transformation (cached)."""
        tt = self.__dict__.get("_Tt")
        if tt is None:
            tt = np.ascontiguousarray(self.T.transpose(0, 2, 1))
            object.__setattr__(self, "_Tt", tt)
        return tt

    def sampling_table(self, n_pts: int) -> np.ndarray:
        """(n_elem, n_pts, 4) shape functions s1..s4 at xi = 0, 1/n_pts, ... (cached)."""
        key = f"_samp{n_pts}"
        tab = self.__dict__.get(key)
        if tab is None:
            tab, _, _ = ancf.shape_functions(np.arange(n_pts) / n_pts, self.elements.length)
            object.__setattr__(self, key, tab)
        return tab

    # ------------------------------------------------------------------ coordinates
    def element_coordinates(self, q: np.ndarray) -> np.ndarray:
        """e (n_elem, 8) = e0 + T q[idx]."""
        qe = np.append(q, 0.0)[self.idx]
        return self.e0 + np.matmul(self.T, qe[:, :, None])[:, :, 0]

    def reduce_vector(self, fe: np.ndarray) -> np.ndarray:
        """sum_e T^T fe (n_elem, 8) -> (n_dof,)."""
        fr = np.matmul(self.Tt, fe[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def reduce_matrix(self, Ke: np.ndarray, diagonal: np.ndarray | None = None):
        """sum_e T^T Ke T (+ diag) -> dense (n_dof, n_dof) or CSR."""
        Kr = np.matmul(np.matmul(self.Tt, Ke), self.T)
        return self.assemble(Kr, diagonal)

    def assemble(self, blocks: np.ndarray, diagonal: np.ndarray | None = None):
        n, pat = self.n_dof, self.pattern
        if self.dense:
            K = np.bincount(pat.flat, weights=blocks.ravel(), minlength=(n + 1) ** 2).reshape(n + 1, n + 1)
            K = K[:n, :n]
            if diagonal is not None:
                K[np.diag_indices(n)] += diagonal
            return K
        from scipy.sparse import csr_matrix

        keep = pat.slot >= 0
        data = np.bincount(pat.slot[keep], weights=blocks.ravel()[keep], minlength=pat.nnz)
        if diagonal is not None:
            data[pat.diag_slot] += diagonal
        return csr_matrix((data, pat.indices, pat.indptr), shape=(n, n))

    # ------------------------------------------------------------------ forces
    def internal_force(self, q: np.ndarray) -> np.ndarray:
        return self.reduce_vector(ancf.internal_forces(self.elements, self.element_coordinates(q))) + self.spring * q

    def force_and_tangent(self, q: np.ndarray):
        """Reduced internal force (belt + bearing springs, spring preload excluded) and tangent."""
        fe, Ke = ancf.internal_forces_and_tangent(self.elements, self.element_coordinates(q))
        return self.reduce_vector(fe) + self.spring * q, self.reduce_matrix(Ke, self.spring)

    def mean_tension_and_gradient(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """Length-weighted mean true axial force over all spans (N) and its gradient (n_dof,)."""
        el = self.elements
        E = self.element_coordinates(q).reshape(-1, 4, 2)
        rp = np.matmul(el.dS, E)  # (n_elem, n_qp, 2) r' at the Gauss points
        a2 = np.einsum("eqd,eqd->eq", rp, rp)
        a = np.sqrt(a2)
        eps = 0.5 * (a2 - 1.0)
        N = el.EA[:, None] * eps * a
        # dN/de = EA (a + eps / a) S'^T r'
        c = el.wL * el.EA[:, None] * (a + eps / a)
        g = np.einsum("eq,eqk,eqd->ekd", c, el.dS, rp).reshape(-1, 8)
        total = float(el.length.sum())
        return float((el.wL * N).sum() / total), self.reduce_vector(g) / total

    def joint_reactions(self, q: np.ndarray, gravity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Static joint reactions: hub loads (n_pulley, 2), N, the force of the belt on each pulley, and
        span tensions (n_span, 2), N, at the start and end of each span.

        The pulley holds each end node with the force F = f_int - f_ext (node position rows); the belt
        pushes back with -F. The span pulls the start node along its tangent t and the end node
        against it, so N_start = -F . t and N_end = F . t with t = r'/|r'| at the node. Unlike strain
        recovery (EA eps |r'| at the element end), this is exact for the discrete equilibrium even
        where the strain is tiny.
        """
        el = self.elements
        e = self.element_coordinates(q)
        F = ancf.internal_forces(el, e) - ancf.gravity_forces(el, gravity)
        first = np.array([s[0] for s in self.span_elements])
        last = np.array([s[-1] for s in self.span_elements])
        n = self.layout.n
        hub = np.zeros((n, 2))
        np.add.at(hub, np.arange(n), -F[first, 0:2])
        np.add.at(hub, (np.arange(n) + 1) % n, -F[last, 4:6])
        t0 = e[first, 2:4] / np.linalg.norm(e[first, 2:4], axis=1, keepdims=True)
        t1 = e[last, 6:8] / np.linalg.norm(e[last, 6:8], axis=1, keepdims=True)
        N0 = -np.einsum("sd,sd->s", F[first, 0:2], t0)
        N1 = np.einsum("sd,sd->s", F[last, 4:6], t1)
        return hub, np.column_stack([N0, N1])

    def pulley_centers(self, q: np.ndarray) -> np.ndarray:
        c = self.layout.center.copy()
        for j, (dofs, dirs) in enumerate(zip(self.trans_dof, self.trans_dir)):
            for d, v in zip(dofs, dirs):
                c[j] += q[d] * v
        return c


def build_model(cfg: DriveConfig, layout: Layout, *, prestrain_stretch: float = 1.0,
                dense: bool | None = None) -> DriveModel:
    """Mesh each span, place the pulley DOFs their supports allow, build joints and matrices.

    prestrain_stretch lambda > 1 makes the reference (unstretched) span length L_geom / lambda, so
    the spans carry axial strain (lambda^2 - 1)/2 at q = 0 (tension mode "prestrain").
    """
    n_p = layout.n
    n_e = cfg.mesh.elements_per_span
    labels: list[str] = []
    rot_dof = np.zeros(n_p, dtype=int)
    trans_dof: list[tuple[int, ...]] = []
    trans_dir: list[np.ndarray] = []
    spring: list[float] = []
    span_slices: list[slice] = []
    # DOF order along the loop: pulley j, then span j (start gradients, interior nodes, end gradients).
    span_first_dof = np.zeros(n_p, dtype=int)
    comp = ("r1", "r2", "r1'", "r2'")
    for j, p in enumerate(cfg.pulleys):
        tdofs = []
        if p.support == "slide":
            tdofs.append(len(labels))
            labels.append(f"pulley {p.name} slide")
            spring.append(p.bearing_stiffness[0])
            trans_dir.append(np.array([p.slide_direction], dtype=float))
        elif p.support == "bearing":
            for k, axis in enumerate("xy"):
                tdofs.append(len(labels))
                labels.append(f"pulley {p.name} {axis}")
                spring.append(p.bearing_stiffness[k])
            trans_dir.append(np.eye(2))
        else:
            trans_dir.append(np.zeros((0, 2)))
        trans_dof.append(tuple(tdofs))
        rot_dof[j] = len(labels)
        labels.append(f"pulley {p.name} rotation")
        spring.append(0.0)
        span_first_dof[j] = len(labels)
        start = len(labels)
        s = j + 1
        labels += [f"span {s} node 1 {c}" for c in comp[2:]]
        for node in range(2, n_e + 1):
            labels += [f"span {s} node {node} {c}" for c in comp]
        labels += [f"span {s} node {n_e + 1} {c}" for c in comp[2:]]
        spring += [0.0] * (len(labels) - start)
        span_slices.append(slice(start, len(labels)))
    n_dof = len(labels)
    pad = n_dof

    # Elements: span-major. Per element, columns 0-3 / 4-7 carry the coordinates of its first / second
    # node, 8-10 / 11-13 the joint DOFs of a span end; padding columns are squeezed out afterwards.
    lam = prestrain_stretch
    L_ref = layout.span_length / lam
    t_dir = layout.span_direction
    normals = np.column_stack([-t_dir[:, 1], t_dir[:, 0]])
    n_elem = n_p * n_e
    T = np.zeros((n_elem, 8, 14))
    idx = np.full((n_elem, 14), pad, dtype=int)
    elem_span = np.repeat(np.arange(n_p), n_e)
    span_elements = tuple(np.arange(s * n_e, (s + 1) * n_e) for s in range(n_p))
    frac = np.arange(n_e + 1) / n_e
    e0 = np.zeros((n_elem, 8))
    eye4 = np.eye(4)
    for s in range(n_p):
        els = span_elements[s]
        a, b = layout.span_start[s], layout.span_end[s]
        nodes = a + np.outer(frac, b - a)  # (n_e+1, 2)
        e0[els, 0:2], e0[els, 4:6] = nodes[:-1], nodes[1:]
        e0[els, 2:4] = e0[els, 6:8] = lam * t_dir[s]
        base = span_first_dof[s]
        node_dof = base + 2 + 4 * (np.arange(n_e + 1) - 1)  # first DOF of each node (interior nodes)
        node_dof[0], node_dof[-1] = base - 2, base + 2 + 4 * (n_e - 1) - 2  # so that +2, +3 are gradients
        for side, nodes_of in ((0, np.arange(n_e)), (1, np.arange(1, n_e + 1))):
            cols = slice(4 * side, 4 * side + 4)
            T[els, 4 * side: 4 * side + 4, cols] = eye4
            idx[els, cols] = node_dof[nodes_of, None] + np.arange(4)
        # End nodes: positions are dependent (joints), gradients stay independent.
        for el, side, j, normal in ((els[0], 0, s, layout.start_normal[s]),
                                    (els[-1], 1, (s + 1) % n_p, layout.end_normal[s])):
            T[el, 4 * side: 4 * side + 2, 4 * side: 4 * side + 2] = 0.0
            idx[el, 4 * side: 4 * side + 2] = pad
            R = layout.radius[j]
            pairs = [(int(rot_dof[j]), R * _z_cross(normal))]
            pairs += list(zip(trans_dof[j], trans_dir[j]))
            for k, (dof, v) in enumerate(pairs):
                c = 8 + 3 * side + k
                idx[el, c] = dof
                T[el, 4 * side: 4 * side + 2, c] = v
    order = np.argsort(idx == pad, axis=1, kind="stable")
    idx = np.take_along_axis(idx, order, axis=1)
    T = np.take_along_axis(T, order[:, None, :], axis=2)
    used = int((idx != pad).sum(axis=1).max())
    T, idx = np.ascontiguousarray(T[:, :, :used]), np.ascontiguousarray(idx[:, :used])

    el = ancf.make_elements(
        np.repeat(L_ref / n_e, n_e), cfg.belt.EA, cfg.belt.EI, cfg.belt.mass_per_length,
        curvature=cfg.model.curvature, n_gauss=cfg.model.gauss_points)
    use_dense = n_dof <= DENSE_LIMIT if dense is None else dense
    pattern = _make_pattern(idx, n_dof, sparse=not use_dense)
    pulley_mass = np.array([p.mass for p in cfg.pulleys])
    pulley_inertia = np.array([p.inertia for p in cfg.pulleys])
    model = DriveModel(
        layout=layout, elements=el, elem_span=elem_span, span_elements=span_elements, T=T, idx=idx, e0=e0,
        n_dof=n_dof, dof_labels=tuple(labels), rot_dof=rot_dof, trans_dof=tuple(trans_dof),
        trans_dir=tuple(trans_dir), span_dof_slices=tuple(span_slices), spring=np.array(spring),
        mass=None, gravity_force=np.zeros(n_dof), pattern=pattern, dense=use_dense,
        reference_length=L_ref, reference_direction=t_dir, reference_normal=normals,
        prestrain_stretch=lam, pulley_mass=pulley_mass, pulley_inertia=pulley_inertia)
    # Pulley inertia (paper Eq. 20) on the DOFs the support allows.
    diag = np.zeros(n_dof)
    diag[rot_dof] = pulley_inertia
    g = np.asarray(cfg.model.gravity, dtype=float)
    fg = model.reduce_vector(ancf.gravity_forces(el, g))
    for j, (dofs, dirs) in enumerate(zip(trans_dof, trans_dir)):
        for a_, da in zip(dofs, dirs):
            fg[a_] += pulley_mass[j] * float(g @ da)
            diag[a_] += pulley_mass[j] * float(da @ da)
    Mr = model.reduce_matrix(ancf.mass_matrices(el), diag)
    object.__setattr__(model, "mass", Mr)
    object.__setattr__(model, "gravity_force", fg)
    return model


def element_pairs(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column index of every entry of the (n_elem, m, m) element blocks, flattened; the
    padding index n marks entries that belong to no DOF."""
    m = idx.shape[1]
    return (np.repeat(idx[:, :, None], m, axis=2).ravel(), np.repeat(idx[:, None, :], m, axis=1).ravel())


def _make_pattern(idx: np.ndarray, n: int, *, sparse: bool) -> Pattern:
    rows, cols = element_pairs(idx)
    flat = rows * (n + 1) + cols
    if not sparse:
        return Pattern(n=n, flat=flat)
    keep = (rows < n) & (cols < n)
    diag_keys = np.arange(n) * (n + 1) + np.arange(n)
    keys, inverse = np.unique(np.concatenate([flat[keep], diag_keys]), return_inverse=True)
    slot = np.full(flat.shape, -1, dtype=np.int64)
    slot[keep] = inverse[: keep.sum()]
    r, c = np.divmod(keys, n + 1)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, r + 1, 1)
    indptr = np.cumsum(indptr)
    diag_slot = np.searchsorted(keys, diag_keys)
    return Pattern(n=n, flat=flat, slot=slot, indices=c.astype(np.int32), indptr=indptr.astype(np.int32),
                   diag_slot=diag_slot, nnz=len(keys))


def stretch_for_tension(tension: float, EA: float) -> float:
    """lambda with EA * eps * lambda = N, eps = (lambda^2 - 1)/2 (St. Venant-Kirchhoff bar)."""
    lam = 1.0 + tension / EA
    for _ in range(50):
        f = 0.5 * EA * (lam**3 - lam) - tension
        step = f / (0.5 * EA * (3 * lam**2 - 1))
        lam -= step
        if abs(step) < 1e-16:
            break
    return lam
