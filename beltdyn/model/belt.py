"""The ANCF belt spans on their joints: element tables, forces, tangents, outputs.

Joint (DESIGN section 2): r_end = c + R n + R theta (z x n) + translation, n the outward normal at the
tangent point, z x n the pulley surface direction for a positive rotation; the gradients of the end nodes
are free (pinned, "bi-articulated"). This joint has a constant Jacobian, so the paper's transformation B
is constant: element coordinates e = e0 + T p[idx] element by element, with T (n_elem, 8, m) and idx
(n_elem, m) (padding points at the dummy index n_p). Interior elements have T = [I8 | 0]: the kernel
skips their transform (tsel < 0). Reduced force sum_e T^T f_e(e), tangent blocks T^T K_e T (n_elem, m, m)
(paper Eqs. 20-23, 26), assembled by `assembly`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from beltdyn.model import ancf
from beltdyn.config import DriveConfig, resolved_spans
from beltdyn.model.dofs import DofMap
from beltdyn.model.geometry import Layout
from beltdyn.model.joints import joint_selection

NORMAL_SIGNS = np.array([-1.0, 1.0])  # (t_y, t_x) * NORMAL_SIGNS = z x t = (-t_y, t_x)
NORMAL_SIGNS.setflags(write=False)


def plus(a: np.ndarray | None, b: np.ndarray) -> np.ndarray:
    """a + b, or b without a (the flexible spans' and the spring spans' parts of a per-span output:
    every span is one or the other)."""
    return b if a is None else a + b


def z_cross(n: np.ndarray) -> np.ndarray:
    """z x n = (-n_y, n_x) of a vector n (2,)."""
    return np.array([-n[1], n[0]])


def transposed(T: np.ndarray) -> np.ndarray:
    """T (k, r, m) transposed to (k, m, r), contiguous."""
    return np.ascontiguousarray(T.transpose(0, 2, 1))


@dataclass(frozen=True, kw_only=True)
class BeltSpans:
    """The belt's free spans: ANCF elements joined to the pulleys by constant-Jacobian joints.

    Shapes: n_elem elements (span-major), m columns of the element transformation.
    """

    elements: ancf.ElementSet
    elem_span: np.ndarray  # (n_elem,) span index of each element
    span_elements: tuple[np.ndarray, ...]  # element indices of each span, in order
    T: np.ndarray  # (n_elem, 8, m) element coordinates per independent coordinate
    idx: np.ndarray  # (n_elem, m) independent coordinate indices (n_dof = padding)
    tsel: np.ndarray  # (n_elem,) -1 where T = [I8 | 0] (interior elements), else the element index
    e0: np.ndarray  # (n_elem, 8) element coordinates at q = 0
    n_dof: int
    reference_length: np.ndarray  # (n_span,) reference (unstretched) length of each span
    reference_direction: np.ndarray  # (n_span, 2) unit direction of each span at q = 0
    prestrain_stretch: float = 1.0  # mean stretch of the spans at q = 0: sum of chord lengths / sum of reference lengths
    span_stretch: np.ndarray | None = None  # (n_span,) stretch of each span at q = 0 (None: prestrain_stretch for all)
    damping_axial: float = 0.0  # Kelvin-Voigt retardation times (s), set by the transient options
    damping_bending: float = 0.0
    compiled: bool = False  # forces by the compiled kernel (`belt_kernel`) instead of the numpy `ancf`
    # derived in the constructor (`__post_init__`), never passed: T transposed (n_elem, m, 8), the spans'
    # normals (n_span, 2), the mid-span points (`midspan_point`), the compiled kernel's tables (compiled only)
    Tt: np.ndarray = field(init=False, repr=False, compare=False)
    reference_normal: np.ndarray = field(init=False, repr=False, compare=False)
    midspan_point: tuple = field(init=False, repr=False, compare=False)
    compiled_tables: object = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        derived = {"Tt": transposed(self.T), "reference_normal": self.reference_direction[:, ::-1] * NORMAL_SIGNS,
                   "midspan_point": self._midspan_point(),
                   "compiled_tables": self._kernel_tables() if self.compiled else None}
        for name, value in derived.items():  # (a frozen dataclass: its derived fields set once, here)
            object.__setattr__(self, name, value)

    @property
    def n_span(self) -> int:
        return len(self.span_elements)

    @property
    def flexible(self) -> np.ndarray:
        """(n_flex,) the spans that have elements (a spring span has none), ascending."""
        return np.array([s for s, els in enumerate(self.span_elements) if len(els)], dtype=np.int64)

    @property
    def first(self) -> np.ndarray:
        """(n_flex,) the first element of each flexible span."""
        return np.array([s[0] for s in self.span_elements if len(s)], dtype=np.int64)

    @property
    def last(self) -> np.ndarray:
        """(n_flex,) the last element of each flexible span."""
        return np.array([s[-1] for s in self.span_elements if len(s)], dtype=np.int64)

    def on_spans(self, x: np.ndarray) -> np.ndarray:
        """(B, n_flex, ...) per flexible span -> (B, n_span, ...), zeros for the spans without elements (x's
        dtype: a running belt's complex mode shapes keep their imaginary part)."""
        if x.shape[1] == self.n_span:
            return x
        out = np.zeros((x.shape[0], self.n_span) + x.shape[2:], dtype=x.dtype)
        out[:, self.flexible] = x
        return out

    @property
    def kernel_tables(self):
        """The compiled kernel's tables of these elements (`belt_kernel.tables_from_elements`): held by a
        compiled belt, made anew otherwise."""
        return self.compiled_tables if self.compiled_tables is not None else self._kernel_tables()

    def _kernel_tables(self):
        from beltdyn.model.belt_kernel import tables_from_elements  # (numba: only where the kernel runs)

        return tables_from_elements(self.elements)

    def kernel_scratch(self):
        """New scratch arrays for the compiled kernel's functions on these elements (`belt_kernel.Scratch`)."""
        from beltdyn.model.belt_kernel import scratch

        return scratch(self.T.shape[0], self.elements.dS.shape[1], self.T.shape[2])

    def sampling_table(self, n_pts: int) -> np.ndarray:
        """(n_elem, n_pts, 4) shape functions s1..s4 at xi = 0, 1/n_pts, ..."""
        return ancf.shape_functions(np.arange(n_pts) / n_pts, self.elements.length)[0]

    # -------------------------------------------------------------------- coordinates
    def element_coordinates(self, q: np.ndarray) -> np.ndarray:
        """e (n_elem, 8) = e0 + T q[idx]."""
        if not len(self.idx):  # every span a spring
            return np.zeros((0, 8))
        qe = np.append(q, 0.0)[self.idx]
        return self.e0 + np.matmul(self.T, qe[:, :, None])[:, :, 0]

    def element_coordinates_batch(self, q: np.ndarray, *, offset: bool = True) -> np.ndarray:
        """(B, n_elem, 8) element coordinates (velocities with offset=False) of states q (B, n_dof): the
        interior elements' (T = [I8 | 0], tsel < 0) gathered, the joint elements' through T."""
        if not len(self.idx):  # every span a spring
            return np.zeros((q.shape[0], 0, 8))
        q_ext = np.concatenate([q, np.zeros((q.shape[0], 1))], axis=1)
        E = q_ext[:, self.idx[:, :8]]
        joint = np.flatnonzero(self.tsel >= 0)
        if len(joint):
            E[:, joint] = np.einsum("eim,bem->bei", self.T[joint], q_ext[:, self.idx[joint]])
        if offset:
            E += self.e0  # (in place: a new batch-sized array costs its page faults again, ~5x the addition)
        return E

    def reduce_vector(self, fe: np.ndarray) -> np.ndarray:
        """sum_e T^T fe (n_elem, 8) -> (n_dof,)."""
        fr = np.matmul(self.Tt, fe[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def reduce_blocks(self, Ke: np.ndarray) -> np.ndarray:
        """(n_elem, m, m) blocks T^T Ke T."""
        return np.matmul(np.matmul(self.Tt, Ke), self.T)

    # -------------------------------------------------------------------- forces
    # Two implementations of one element, held equal to 1e-12 by tests/test_belt_kernel.py: the
    # vectorized numpy `ancf` (no compilation: static and modal, a few dozen evaluations, where numba's
    # ~0.3 s start-up is never paid back) and the compiled `belt_kernel` (`compiled=True`: the time
    # stepper, thousands of evaluations). bench/run.py measures both.
    def force(self, q: np.ndarray) -> np.ndarray:
        """Reduced elastic force of the belt (n_dof,)."""
        if not self.compiled:
            return self.reduce_vector(ancf.internal_forces(self.elements, self.element_coordinates(q)))
        from beltdyn.model import belt_kernel as bk

        tab = self.kernel_tables
        out = np.zeros(self.n_dof + 1)
        bk.reduced_force(np.append(q, 0.0), self.e0, self.T, self.idx, self.tsel, tab.dS, tab.d2S, tab.wEA, tab.wEI,
                         tab.Kb, tab.curvature, out, self.kernel_scratch())
        return out[: self.n_dof]

    def force_and_blocks(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reduced elastic force (n_dof,) and the tangent blocks T^T K_e T (n_elem, m, m)."""
        if not self.compiled:
            fe, Ke = ancf.internal_forces_and_tangent(self.elements, self.element_coordinates(q))
            return self.reduce_vector(fe), self.reduce_blocks(Ke)
        from beltdyn.model import belt_kernel as bk

        tab = self.kernel_tables
        out = np.zeros(self.n_dof + 1)
        blocks = np.empty((self.T.shape[0], self.T.shape[2], self.T.shape[2]))
        bk.reduced_force_and_tangent_blocks(np.append(q, 0.0), self.e0, self.T, self.idx, self.tsel, tab.dS, tab.d2S,
                                            tab.wEA, tab.wEI, tab.Kb, tab.curvature, out, blocks, self.kernel_scratch())
        return out[: self.n_dof], blocks

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

    # -------------------------------------------------------------------- mid-span motion
    def _midspan_point(self) -> tuple[np.ndarray, np.ndarray]:
        """The field `midspan_point`: (elements (n_flex,), shape functions (n_flex, 4)) of each flexible
        span's mid-span point: the middle node (an even count of elements) or the middle of the middle
        element (odd)."""
        els, xis = [], []
        for span in self.span_elements:
            n_e = len(span)
            if n_e:
                k, xi = (n_e // 2, 0.0) if n_e % 2 == 0 else ((n_e - 1) // 2, 0.5)
                els.append(span[k])
                xis.append(xi)
        els = np.array(els, dtype=np.int64)
        s_fun, _, _ = ancf.shape_functions(np.array([0.0, 0.5]), self.elements.length[els])
        return els, s_fun[np.arange(len(els)), (np.array(xis) > 0).astype(int), :]

    def midspan_displacement(self, E: np.ndarray) -> np.ndarray:
        """(B, n_span) transverse displacement of the mid-span point from the chord between the span's
        current end points, along the chord's normal z x t (m), for element states E (B, n_elem, 8).
        Rigid motion of the span (its ends moving with the pulleys) and axial motion give none; a span
        without elements (a spring span) none either."""
        p, r0, c = self._midspan_terms(E)
        n = np.stack([-c[..., 1], c[..., 0]], axis=-1) / np.linalg.norm(c, axis=-1, keepdims=True)
        return self.on_spans(np.einsum("bsd,bsd->bs", p - r0, n))

    def midspan_displacement_linear(self, E: np.ndarray, dE: np.ndarray) -> np.ndarray:
        """(B, n_span) the first-order change of `midspan_displacement` at the state E (n_elem, 8) for
        element motions dE (B, n_elem, 8) (mode shapes). With the chord c = r1 - r0, n = J c / |c|:
        d(delta) = (dp - dr0) . n + (p - r0) . dn,  dn = J dc / |c| - J c (c . dc) / |c|^3."""
        if self.elements.n_elem == 0:  # every span a spring: no transverse motion anywhere
            return np.zeros((dE.shape[0], self.n_span))
        p, r0, c = self._midspan_terms(E[None])
        dp, dr0, dc = self._midspan_terms(dE, offset=False)
        cx, cy = c[..., 0], c[..., 1]
        norm = np.hypot(cx, cy)
        ux, uy = p[..., 0] - r0[..., 0], p[..., 1] - r0[..., 1]
        dux, duy = dp[..., 0] - dr0[..., 0], dp[..., 1] - dr0[..., 1]
        # (du . Jc + u . J dc) / |c| - (u . Jc)(c . dc) / |c|^3, J v = (-v_y, v_x)
        uJc = -ux * cy + uy * cx
        return self.on_spans(((-dux * cy + duy * cx) + (-ux * dc[..., 1] + uy * dc[..., 0])) / norm
                             - uJc * (cx * dc[..., 0] + cy * dc[..., 1]) / norm ** 3)

    def _midspan_terms(self, E: np.ndarray, offset: bool = True):
        """Mid-span point p, start r0 and chord c = r_end - r0, each (B, n_flex, 2)."""
        els, sfun = self.midspan_point
        B = E.shape[0]
        p = np.einsum("sk,bskd->bsd", sfun, E[:, els].reshape(B, len(els), 4, 2))
        r0 = E[:, self.first, 0:2]
        return p, r0, E[:, self.last, 4:6] - r0

    def end_forces(self, E: np.ndarray, Ed: np.ndarray | None, gravity: np.ndarray) -> np.ndarray:
        """Force of each span on its end nodes, (B, n_span, 2 ends, 2), from element states
        E, Ed (B, n_elem, 8): internal (elastic + belt damping) - weight of the end elements, position
        rows. The pulley holds the node with this force (plus `end_inertia`); the belt pushes back.
        Zeros for a span without elements (a spring span: `SpringSpans.end_forces`)."""
        el = self.elements
        ends = np.concatenate([self.first, self.last])
        B = E.shape[0]
        damped = self.damping_axial > 0.0 or self.damping_bending > 0.0
        n = len(self.first)
        if not self.compiled and not (damped and Ed is not None):
            sub_el = ancf.subset(el, ends)  # the span-end elements' tables
            ge = ancf.gravity_forces(sub_el, gravity)
            F = np.stack([ancf.internal_forces(sub_el, E[b, ends]) for b in range(B)]) - ge
            return self.on_spans(np.stack([F[:, :n, 0:2], F[:, n:, 4:6]], axis=2))
        from beltdyn.model import belt_kernel as bk

        # the whole batch in one kernel call: the end elements' tables tiled over the batch
        sub = _sub_tables(self.kernel_tables, np.tile(ends, B))
        Eb = np.ascontiguousarray(E[:, ends].reshape(B * len(ends), 8))
        fe = np.empty((B * len(ends), 8))
        bk.element_forces(Eb, *sub, fe)
        F = fe.reshape(B, len(ends), 8) - ancf.gravity_forces(el, gravity)[ends]
        if damped and Ed is not None:
            fd = np.empty_like(fe)
            bk.element_damping(Eb, np.ascontiguousarray(Ed[:, ends].reshape(B * len(ends), 8)), sub[0], sub[1],
                               sub[2], sub[3], sub[4], sub[5], self.damping_axial, self.damping_bending, fd)
            F = F + fd.reshape(B, len(ends), 8)
        return self.on_spans(np.stack([F[:, :n, 0:2], F[:, n:, 4:6]], axis=2))

    # -------------------------------------------------------------------- the running belt (transport)
    def transport_element_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(A_e, B_e) (n_elem, 8, 8) the elements' axial-transport matrices per unit speed
        (`ancf.transport_matrices`)."""
        return ancf.transport_matrices(self.elements)

    def transport_blocks(self, A_e: np.ndarray | None = None, B_e: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The axial-transport terms of the running belt on the joint coordinates: blocks T^T A_e T and
        T^T B_e T (n_elem, m, m), and the reduced vectors a0 = sum_e T^T A_e e0 and b0 = sum_e T^T B_e e0
        (n_dof,), so that sum_e T^T A_e e = A p + a0 and sum_e T^T B_e e = B p + b0 for e = e0 + T p. Per
        unit speed; A_e, B_e: `transport_element_matrices` if at hand."""
        if A_e is None or B_e is None:
            A_e, B_e = self.transport_element_matrices()
        return (self.reduce_blocks(A_e), self.reduce_blocks(B_e),
                self.reduce_vector(np.matmul(A_e, self.e0[:, :, None])[:, :, 0]),
                self.reduce_vector(np.matmul(B_e, self.e0[:, :, None])[:, :, 0]))

    def transport_end_forces(self, E: np.ndarray, Ed: np.ndarray | None, speed, acceleration=0.0, *,
                             matrices: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """(B, n_span, 2 ends, 2) the transport forces of the end elements on the span-end nodes for element
        states E, Ed (B, n_elem, 8) at the belt speed c (m/s) and its rate c' (m/s^2), each a number or one
        per state (B,): c (A_e - A_e^T) e' - c^2 B_e e + c' A_e e (rows of the end nodes' positions). With
        the elastic forces (`end_forces`) and the inertia (`end_inertia`) they make the force the pulley
        holds the node with: the running belt's momentum flux, which lowers the hub loads by
        rho c^2 lambda per span end. matrices: (A_e, B_e), `transport_element_matrices`, if at hand."""
        A_e, B_e = self.transport_element_matrices() if matrices is None else matrices
        c = np.broadcast_to(np.asarray(speed, dtype=float), (E.shape[0],))[:, None, None]
        cd = np.broadcast_to(np.asarray(acceleration, dtype=float), (E.shape[0],))[:, None, None]
        out = []
        for els, rows in ((self.first, slice(0, 2)), (self.last, slice(4, 6))):
            A, B = A_e[els][:, rows], B_e[els][:, rows]
            f = -c * c * np.einsum("eij,bej->bei", B, E[:, els]) + cd * np.einsum("eij,bej->bei", A, E[:, els])
            if Ed is not None:
                G = A - A_e[els].transpose(0, 2, 1)[:, rows]
                f += c * np.einsum("eij,bej->bei", G, Ed[:, els])
            out.append(f)
        return np.stack(out, axis=2)

    def end_inertia(self, Ea: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) inertia forces M_e a_e of the end elements on the span-end nodes."""
        m = self.elements.mass
        f0 = np.einsum("eij,bej->bei", m[self.first], Ea[:, self.first])[:, :, 0:2]
        f1 = np.einsum("eij,bej->bei", m[self.last], Ea[:, self.last])[:, :, 4:6]
        return self.on_spans(np.stack([f0, f1], axis=2))

    def end_tensions(self, E: np.ndarray, F_end: np.ndarray) -> np.ndarray:
        """Span tensions (B, n_span, 2) at the start/end of each span from the end-node forces F_end
        (B, n_span, 2, 2): the span pulls its start node along its tangent t and its end node against
        it, so N_start = -F . t and N_end = F . t with t = r'/|r'| at the node."""
        t0 = E[:, self.first, 2:4]
        t1 = E[:, self.last, 6:8]
        t0 = t0 / np.linalg.norm(t0, axis=-1, keepdims=True)
        t1 = t1 / np.linalg.norm(t1, axis=-1, keepdims=True)
        F_end = F_end[:, self.flexible]
        return self.on_spans(np.stack([-np.einsum("bsd,bsd->bs", F_end[:, :, 0], t0),
                                       np.einsum("bsd,bsd->bs", F_end[:, :, 1], t1)], axis=-1))


def build_belt(cfg: DriveConfig, layout: Layout, dofs: DofMap, *, prestrain_stretch: float | np.ndarray = 1.0,
               no_elements: ancf.ElementSet | None = None,
               spans: tuple[tuple[str, ...], tuple[int, ...]] | None = None) -> BeltSpans:
    """Mesh each span and join its end nodes to the pulleys (constant-Jacobian joints).

    Span s gets cfg.span_elements[s] elements (none for a spring span: `build_springs`); a "string"
    span's elements have no bending stiffness (EI = 0).
    prestrain_stretch: the stretch of the spans at q = 0 (chord length / reference length), one
    number for all spans or one per span (n_span,). no_elements: `empty_element_set` of cfg, if at hand
    (every span a spring); spans: `config.resolved_spans` of cfg (models, elements), if at hand."""
    n_p = layout.n
    n_dof = dofs.n
    pad = n_dof
    lam_s = span_stretch_of(prestrain_stretch, n_p)
    L_ref = layout.span_length / lam_s
    if isinstance(prestrain_stretch, (float, int)):  # (one number: uniform)
        lam = float(prestrain_stretch)
    else:  # one per span: the mean stretch, sum of chords / sum of reference lengths (their own if all equal)
        lam = float(lam_s[0]) if (lam_s == lam_s[0]).all() else float(layout.span_length.sum() / L_ref.sum())
    t_dir = layout.span_direction
    models, span_counts = resolved_spans(cfg) if spans is None else spans  # (derived from cfg: once here)
    n_elem = sum(span_counts)
    if n_elem == 0:  # every span a spring (`build_springs`): no elements, no joints of the belt's own
        # (new empty arrays, writable: numba types a read-only array apart, and the transient's kernels would
        # compile anew)
        none = np.zeros(0, dtype=np.int64)
        return BeltSpans(elements=empty_element_set(cfg) if no_elements is None else no_elements, elem_span=none,
                         span_elements=(none,) * n_p, T=np.zeros((0, 8, 8)), idx=np.zeros((0, 8), dtype=np.int64),
                         tsel=none, e0=np.zeros((0, 8)), n_dof=n_dof, reference_length=L_ref,
                         reference_direction=t_dir, prestrain_stretch=lam, span_stretch=lam_s)
    counts = np.array(span_counts, dtype=np.int64)  # (n_span,) elements of each span
    # Per element, columns 0-3 / 4-7 carry the coordinates of its first / second node, 8-10 / 11-13
    # the joint DOFs of a span end; padding columns are squeezed out afterwards.
    T = np.zeros((n_elem, 8, 14))
    idx = np.full((n_elem, 14), pad, dtype=int)
    elem_span = np.repeat(np.arange(n_p), counts)
    offsets = np.concatenate([[0], np.cumsum(counts)])
    span_elements = tuple(np.arange(offsets[s], offsets[s + 1]) for s in range(n_p))
    # every element at once: its span, its place k in the span (nodes k and k + 1 of n_e + 1)
    k = np.arange(n_elem) - offsets[elem_span]
    n_of = counts[elem_span]
    a, ab = layout.span_start[elem_span], (layout.span_end - layout.span_start)[elem_span]
    e0 = np.empty((n_elem, 8))
    e0[:, 0:2] = a + (k / n_of)[:, None] * ab  # the nodes evenly along the chord
    e0[:, 4:6] = a + ((k + 1) / n_of)[:, None] * ab
    e0[:, 2:4] = e0[:, 6:8] = (lam_s[:, None] * t_dir)[elem_span]
    # first DOF of node j of a span whose DOFs start at `base`: base - 2 + 4 j (the first node owns only its
    # gradient, at +2, +3; the interior nodes four each), the last node base - 4 + 4 n_e (its gradient after them)
    base = np.array([sl.start for sl in dofs.span_slices], dtype=np.int64)[elem_span]
    first_dof = base - 2 + 4 * k
    second_dof = np.where(k + 1 == n_of, base - 4 + 4 * n_of, base + 2 + 4 * k)
    rows = np.arange(n_elem)
    for side, node in ((0, first_dof), (1, second_dof)):
        T[rows, 4 * side: 4 * side + 4, 4 * side: 4 * side + 4] = np.eye(4)
        idx[:, 4 * side: 4 * side + 4] = node[:, None] + np.arange(4)
    for s in range(n_p):  # end nodes: positions dependent (the joints), gradients independent
        els = span_elements[s]
        if not len(els):
            continue
        for el, side in ((els[0], 0), (els[-1], 1)):
            T[el, 4 * side: 4 * side + 2, 4 * side: 4 * side + 2] = 0.0
            idx[el, 4 * side: 4 * side + 2] = pad
            for j, (dof, v) in enumerate(joint_pairs(layout, dofs, s, side)):
                c = 8 + 3 * side + j
                idx[el, c] = dof
                T[el, 4 * side: 4 * side + 2, c] = v
    order = np.argsort(idx == pad, axis=1, kind="stable")
    idx = np.take_along_axis(idx, order, axis=1)
    T = np.take_along_axis(T, order[:, None, :], axis=2)
    used = max(int((idx != pad).sum(axis=1).max(initial=0)), 8)
    T, idx = np.ascontiguousarray(T[:, :, :used]), np.ascontiguousarray(idx[:, :used]).astype(np.int64)
    el = span_element_set(cfg, np.repeat(L_ref / np.maximum(counts, 1), counts),
                          np.repeat([cfg.belt.EI if m == "ancf" else 0.0 for m in models], counts), models=models)
    return BeltSpans(elements=el, elem_span=elem_span, span_elements=span_elements, T=T, idx=idx,
                     tsel=joint_selection(T, idx, n_dof), e0=e0, n_dof=n_dof, reference_length=L_ref,
                     reference_direction=t_dir, prestrain_stretch=lam, span_stretch=lam_s)


def joint_pairs(layout: Layout, dofs: DofMap, s: int, side: int) -> list[tuple[int, np.ndarray]]:
    """The joint of span s's start (side 0, on pulley s) or end (side 1, on pulley s + 1): the
    (joint coordinate, d r_end / d coordinate (2,)) pairs, r_end = c + R n + R theta (z x n) + u."""
    j = s if side == 0 else (s + 1) % layout.n
    normal = layout.start_normal[s] if side == 0 else layout.end_normal[s]
    pairs = [(int(dofs.rot_dof[j]), layout.radius[j] * z_cross(normal))]
    return pairs + list(zip(dofs.trans_dof[j], dofs.trans_dir[j]))


def empty_element_set(cfg: DriveConfig) -> ancf.ElementSet:
    """The element set of a belt without elements (every span a spring): empty, its tables of the right
    shapes (the bending law "none")."""
    return ancf.empty_elements(curvature="none", n_gauss=cfg.model.gauss_points, axial_law=cfg.belt.axial_law)


def span_element_set(cfg: DriveConfig, length: np.ndarray, EI: np.ndarray,
                     models: tuple[str, ...] | None = None) -> ancf.ElementSet:
    """The ANCF elements of the flexible spans: lengths and bending stiffnesses (n_elem,); the tables
    computed once per distinct (length, EI) and gathered. The bending law is model.curvature
    ("linear" when that is "none" but a span asks for "ancf"); without an "ancf" span, none. No
    elements (every span a spring): an empty set. models: cfg.span_models, if at hand."""
    curvature = cfg.model.curvature
    if "ancf" in (cfg.span_models if models is None else models):
        curvature = curvature if curvature != "none" else "linear"
    else:
        curvature = "none"
    b = cfg.belt
    if len(length) == 0:
        return empty_element_set(cfg)
    # the distinct (length, EI) pairs: one complex key each (exact; np.unique's 1-D path, not its slow axis=0)
    uniq, inverse = np.unique(np.asarray(length, dtype=float) + 1j * np.asarray(EI, dtype=float), return_inverse=True)
    if len(uniq) == len(length):  # every element distinct: no gathering
        uniq, inverse = np.asarray(length, dtype=float) + 1j * np.asarray(EI, dtype=float), None
    base = ancf.make_elements(uniq.real.copy(), b.EA, uniq.imag.copy(), b.mass_per_length, curvature=curvature,
                              n_gauss=cfg.model.gauss_points, axial_law=b.axial_law)
    return base if inverse is None else ancf.subset(base, inverse.ravel())


def span_stretch_of(prestrain_stretch: float | np.ndarray, n: int) -> np.ndarray:
    """(n,) the spans' stretch at q = 0 of one number for all or one per span (a new array)."""
    if isinstance(prestrain_stretch, np.ndarray) and prestrain_stretch.shape == (n,):
        return prestrain_stretch.astype(float)
    if isinstance(prestrain_stretch, (float, int)) or np.ndim(prestrain_stretch) == 0:
        return np.full(n, float(prestrain_stretch))
    lam = np.array(prestrain_stretch, dtype=float)
    return lam if lam.shape == (n,) else np.broadcast_to(lam, (n,)).copy()


def _sub_tables(tab, els: np.ndarray) -> tuple:
    """Kernel table arguments (dS, d2S, wEA, wEI, Kb, curvature) of a subset of elements."""
    return (np.ascontiguousarray(tab.dS[els]), np.ascontiguousarray(tab.d2S[els]), np.ascontiguousarray(tab.wEA[els]),
            np.ascontiguousarray(tab.wEI[els]), np.ascontiguousarray(tab.Kb[els]), tab.curvature)
