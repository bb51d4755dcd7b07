"""The drive as a system of components: one DOF map, components that own DOFs and contribute.

Nomenclature (paper section 2.2):
- q (n_dof,): independent coordinates, measured from the reference configuration (q = 0 is the
  stress-free L0 geometry, or the prestrained one). A pulley carries only the DOFs its support
  allows: rotation theta (rad, counter-clockwise), plus the slide offset u (m) or the bearing
  displacements (x, y) (m). A span carries every coordinate of its interior nodes (r1, r2, r1', r2')
  and the gradients of its end nodes; the end-node positions are dependent (the joints).
- Joint (DESIGN section 2): r_end = c + R n + R theta (z x n) + translation, n the outward normal at
  the tangent point, z x n the pulley surface direction for a positive rotation; the gradients of
  the end nodes are free (pinned, "bi-articulated"). This joint has a constant Jacobian, so the
  paper's transformation B is constant: element coordinates e = e0 + T q[idx] element by element,
  with T (n_elem, 8, m) and idx (n_elem, m) (padding points at the dummy index n_dof). Interior
  elements have T = [I8 | 0]: the kernel skips their transform.

The seam. A `System` is the DOF map, the belt (`BeltSpans`, the ANCF spans, evaluated by the
compiled kernel of `belt_kernel` in the time stepper; and `SpringSpans`, the spans modelled as axial
springs between their tangent points, [spans] model = "spring", `spring_kernel` in the stepper: the
nonlinear components) and any number of `LinearComponent`s: pulley
inertia, pulley mass, bearing springs, or anything a user writes (a rotational spring between two
pulleys is one in the tests). Every component owns its DOF indices and gives its contribution to
the internal force and tangent (K q, K), to the damping (C v), to the mass (M) and to the weight,
its kinetic-energy kind for the classification of modes, and its own output series. The analyses
(static, modal, transient) see only the system: adding a component touches no analysis.

Reduced matrices: M = sum_e T^T M_e T + component masses; K_t = sum_e T^T K_e T + component
stiffness (paper Eqs. 20-23, 26). Assembly scatters (n_elem, m, m) blocks and the components'
constant matrices through one precomputed pattern into a dense array (small models) or a CSR
matrix (large models).
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field

import numpy as np

from beltdyn.model import ancf
from beltdyn.config import DriveConfig
from beltdyn.errors import ConfigError
from beltdyn.model.components import ENERGY_KINDS, BearingSprings, LinearComponent
from beltdyn.model.barlaw import stretch_for_tension
from beltdyn.model.frozen import set_at_once
from beltdyn.model.joints import joint_selection
from beltdyn.model.geometry import Layout, layout_from_config
from beltdyn.model.geometry import belt_speed_of
from beltdyn.model.supports import SUPPORT_CLASSES, Support, support_of

DENSE_LIMIT = 200  # models up to this many DOFs use dense linear algebra
_EYE2 = np.eye(2)
_EYE2.setflags(write=False)
_PAD = np.zeros(1)  # the padding coordinate (index n_dof) appended to p
_PAD.setflags(write=False)
# the tables of a belt without elements (every span a spring), shared: empty, so nothing can change them (and
# writable: numba types a read-only array apart, and the transient's kernels would compile anew)
_NO_ELEMENT, _NO_INDEX, _NO_T, _NO_IDX, _NO_E = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 8, 8)),
                                                 np.zeros((0, 8), dtype=np.int64), np.zeros((0, 8)))
DOF_GROUPS = ("span", "rotation", "translation", "arm")


def _z_cross(n: np.ndarray) -> np.ndarray:
    return np.array([-n[1], n[0]])


# ------------------------------------------------------------------------------------ DOF map
@dataclass(frozen=True, kw_only=True)
class DofMap:
    """Every independent coordinate: label, unit and group, and the pulleys' and spans' DOFs.

    labels/units (n_dof,); group (n_dof,) int index into DOF_GROUPS; rot_dof (n_pulley,);
    trans_dof[j] the translation DOFs of pulley j with trans_dir[j] (k, 2) their directions (m per
    unit q); span_slices[s] the contiguous DOF range of span s's own coordinates; arm_dof (n_pulley,)
    the arm angle DOF of a tensioner pulley (-1 for other supports).

    Joint coordinates p: the independent coordinates q (the first n_q) followed by `dependent` ones,
    the centre offsets (x, y) of the arm pulleys, u = c(phi) - c(phi_ref), which the belt and the
    pulley's mass see as a bearing's translations (`ArmJoints` gives them from q).
    """

    labels: tuple[str, ...]
    units: tuple[str, ...]
    group: np.ndarray
    rot_dof: np.ndarray
    trans_dof: tuple[tuple[int, ...], ...]
    trans_dir: tuple[np.ndarray, ...]
    span_slices: tuple[slice, ...]
    arm_dof: np.ndarray | None = None
    dependent: int = 0

    @property
    def n(self) -> int:
        """Joint coordinates p (independent and dependent)."""
        return len(self.labels)

    @property
    def n_q(self) -> int:
        """Independent coordinates q."""
        return len(self.labels) - self.dependent


_DOFMAPS: dict = {}  # number_dofs memo: a DofMap depends only on the pulleys' names and supports and the mesh


def number_dofs(cfg: DriveConfig) -> DofMap:
    """DOF order along the loop: pulley j (its support's DOFs, rotation), then span j (start
    gradients, interior nodes, end gradients; none for a spring span); the supports' dependent DOFs
    after all of them."""
    # the support's class too: a registered class (tests/test_system.py) may replace a kind's
    key = (cfg.span_elements, tuple([(p.name, p.support, SUPPORT_CLASSES[p.support], tuple(p.slide_direction))
                                     for p in cfg.pulleys]))
    hit = _DOFMAPS.get(key)
    if hit is None:
        if len(_DOFMAPS) > 64:
            _DOFMAPS.clear()
        hit = _DOFMAPS[key] = _number_dofs(cfg)
    return hit


def _number_dofs(cfg: DriveConfig) -> DofMap:
    counts = cfg.span_elements  # elements of each span (0: a spring span, no DOFs of its own)
    labels: list[str] = []
    units: list[str] = []
    group: list[int] = []
    rot_dof = np.zeros(len(cfg.pulleys), dtype=int)
    trans_dof: list[tuple[int, ...]] = []
    trans_dir: list[np.ndarray] = []
    span_slices: list[slice] = []

    def add(label: str, unit: str, grp: str) -> int:
        labels.append(label)
        units.append(unit)
        group.append(DOF_GROUPS.index(grp))
        return len(labels) - 1

    comp = (("r1", "m"), ("r2", "m"), ("r1'", "1"), ("r2'", "1"))
    arm_dof = np.full(len(cfg.pulleys), -1, dtype=int)
    supports = [support_of(p) for p in cfg.pulleys]
    for j, (p, sup) in enumerate(zip(cfg.pulleys, supports)):
        own = [(add(f"pulley {p.name} {suffix}", unit, grp), grp) for suffix, unit, grp in sup.independent()]
        trans_dof.append(tuple(d for d, grp in own if grp == "translation"))  # dependent ones: below
        trans_dir.append(sup.directions())
        arm_dof[j] = next((d for d, grp in own if grp == "arm"), -1)
        rot_dof[j] = add(f"pulley {p.name} rotation", "rad", "rotation")
        start = len(labels)
        s = j + 1
        n_e = counts[j]
        for node in range(1, n_e + 2 if n_e else 1):
            for c, unit in (comp[2:] if node in (1, n_e + 1) else comp):
                add(f"span {s} node {node} {c}", unit, "span")
        span_slices.append(slice(start, len(labels)))
    n_q = len(labels)
    for j, (p, sup) in enumerate(zip(cfg.pulleys, supports)):  # dependent DOFs (arm offsets): after q
        if sup.dependent():
            trans_dof[j] = tuple(add(f"pulley {p.name} {suffix}", unit, grp) for suffix, unit, grp in sup.dependent())
    group = np.array(group, dtype=np.int64)
    for a in (group, rot_dof, arm_dof, *trans_dir):  # (read-only: a DOF map is shared, `number_dofs`)
        a.setflags(write=False)
    return DofMap(labels=tuple(labels), units=tuple(units), group=group, rot_dof=rot_dof,
                  trans_dof=tuple(trans_dof), trans_dir=tuple(trans_dir), span_slices=tuple(span_slices),
                  arm_dof=arm_dof, dependent=len(labels) - n_q)


# ------------------------------------------------------------------------------------ components


# ------------------------------------------------------------------------------------ the belt
_NORMAL = np.array([-1.0, 1.0])  # (t_y, t_x) -> z x t = (-t_y, t_x)


def _plus(a: np.ndarray | None, b: np.ndarray) -> np.ndarray:
    """a + b, or b without a (the flexible spans' and the spring spans' parts of a per-span output:
    every span is one or the other)."""
    return b if a is None else a + b


def _cached(obj, key: str, make):
    """obj's `key` entry, made by make() at first use: a per-object cache on a frozen dataclass (a "_" key,
    which the field copies of `System.with_belt` and `with_speed` leave out)."""
    value = obj.__dict__.get(key)
    if value is None:
        value = make()
        object.__setattr__(obj, key, value)
    return value


def _transposed(spans) -> np.ndarray:
    """spans.T (k, r, m) transposed to (k, m, r), contiguous, cached on the (frozen) spans object."""
    return _cached(spans, "_Tt", lambda: np.ascontiguousarray(spans.T.transpose(0, 2, 1)))


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

    @property
    def n_span(self) -> int:
        return len(self.span_elements)

    @property
    def reference_normal(self) -> np.ndarray:
        """(n_span, 2) unit normal z x t = (-t_y, t_x) of each span at q = 0 (cached)."""
        return _cached(self, "_normal", lambda: self.reference_direction[:, ::-1] * _NORMAL)

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
    def Tt(self) -> np.ndarray:
        """(n_elem, m, 8) transposed element transformation (cached)."""
        return _transposed(self)

    @property
    def kernel_tables(self):
        """The compiled kernel's tables of these elements (cached)."""
        tab = self.__dict__.get("_tables")
        if tab is None:
            from beltdyn.model.belt_kernel import tables_from_elements

            tab = tables_from_elements(self.elements)
            object.__setattr__(self, "_tables", tab)
        return tab

    def kernel_scratch(self):
        """New scratch arrays for the compiled kernel's functions on these elements (`belt_kernel.Scratch`)."""
        from beltdyn.model.belt_kernel import scratch

        return scratch(self.T.shape[0], self.elements.dS.shape[1], self.T.shape[2])

    def sampling_table(self, n_pts: int) -> np.ndarray:
        """(n_elem, n_pts, 4) shape functions s1..s4 at xi = 0, 1/n_pts, ... (cached)."""
        key = f"_samp{n_pts}"
        tab = self.__dict__.get(key)
        if tab is None:
            tab, _, _ = ancf.shape_functions(np.arange(n_pts) / n_pts, self.elements.length)
            object.__setattr__(self, key, tab)
        return tab

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
    @property
    def midspan_point(self) -> tuple[np.ndarray, np.ndarray]:
        """(elements (n_flex,), shape functions (n_flex, 4)) of each flexible span's mid-span point: the
        middle node (an even count of elements) or the middle of the middle element (odd). Cached."""
        mid = self.__dict__.get("_mid")
        if mid is None:  # per flexible span: its middle node, or the middle of its middle element
            els, xis = [], []
            for span in self.span_elements:
                n_e = len(span)
                if n_e:
                    k, xi = (n_e // 2, 0.0) if n_e % 2 == 0 else ((n_e - 1) // 2, 0.5)
                    els.append(span[k])
                    xis.append(xi)
            els = np.array(els, dtype=np.int64)
            s_fun, _, _ = ancf.shape_functions(np.array([0.0, 0.5]), self.elements.length[els])
            mid = (els, s_fun[np.arange(len(els)), (np.array(xis) > 0).astype(int), :])
            object.__setattr__(self, "_mid", mid)
        return mid

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
            sub_el = self.__dict__.get("_end_elements")
            if sub_el is None:  # the span-end elements' tables (cached)
                sub_el = ancf.subset(el, ends)
                object.__setattr__(self, "_end_elements", sub_el)
            ge = ancf.gravity_forces(sub_el, gravity)
            F = np.stack([ancf.internal_forces(sub_el, E[b, ends]) for b in range(B)]) - ge
            return self.on_spans(np.stack([F[:, :n, 0:2], F[:, n:, 4:6]], axis=2))
        from beltdyn.model import belt_kernel as bk

        # the whole batch in one kernel call: the end elements' tables tiled over the batch (cached per size)
        cached = self.__dict__.get("_end_tables")
        if cached is None or cached[0] != B:
            cached = (B, _sub_tables(self.kernel_tables, np.tile(ends, B)))
            object.__setattr__(self, "_end_tables", cached)
        sub = cached[1]
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
    def transport_blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The axial-transport terms of the running belt (`ancf.transport_matrices`) on the joint
        coordinates: blocks T^T A_e T and T^T B_e T (n_elem, m, m), and the reduced vectors
        a0 = sum_e T^T A_e e0 and b0 = sum_e T^T B_e e0 (n_dof,), so that sum_e T^T A_e e = A p + a0 and
        sum_e T^T B_e e = B p + b0 for e = e0 + T p. Per unit speed; cached."""
        got = self.__dict__.get("_transport")
        if got is None:
            A_e, B_e = ancf.transport_matrices(self.elements)
            got = (self.reduce_blocks(A_e), self.reduce_blocks(B_e),
                   self.reduce_vector(np.matmul(A_e, self.e0[:, :, None])[:, :, 0]),
                   self.reduce_vector(np.matmul(B_e, self.e0[:, :, None])[:, :, 0]))
            object.__setattr__(self, "_transport", got)
            object.__setattr__(self, "_transport_e", (A_e, B_e))
        return got

    def transport_end_forces(self, E: np.ndarray, Ed: np.ndarray | None, speed, acceleration=0.0) -> np.ndarray:
        """(B, n_span, 2 ends, 2) the transport forces of the end elements on the span-end nodes for element
        states E, Ed (B, n_elem, 8) at the belt speed c (m/s) and its rate c' (m/s^2), each a number or one
        per state (B,): c (A_e - A_e^T) e' - c^2 B_e e + c' A_e e (rows of the end nodes' positions). With
        the elastic forces (`end_forces`) and the inertia (`end_inertia`) they make the force the pulley
        holds the node with: the running belt's momentum flux, which lowers the hub loads by
        rho c^2 lambda per span end."""
        self.transport_blocks()
        A_e, B_e = self.__dict__["_transport_e"]
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


# ------------------------------------------------------------------------------------ spring spans
@dataclass(frozen=True, kw_only=True)
class SpringSpans:
    """The spans modelled as axial springs (model = "spring"): the rotational (discrete) model of a span.

    Nomenclature, per spring span (k of them): end positions x = [r_a, r_b] (4,) = x0 + T p[idx], the
    span's tangent points on its two pulleys through the same constant-Jacobian joints as an ANCF
    span's end nodes (`joint_pairs`; T (k, 4, m), idx (k, m), padding index n_dof); chord d = r_b - r_a,
    l = |d|, u = d / l; reference length L; stretch lam = l / L; Green-Lagrange strain
    eps = (lam^2 - 1) / 2 (the ANCF law of a uniformly stretched span); strain energy U = EA L eps^2 / 2;
    true axial force N = dU/dl = EA eps lam, on the ends f = dU/dx = N [-u, u]. Tangent
    K = [[K2, -K2], [-K2, K2]], K2 = k_a u u^T + (N / l) (I - u u^T), k_a = dN/dl = EA (3 lam^2 - 1) / (2 L)
    along the chord and N / l (the string's geometric stiffness) across it. Kelvin-Voigt damping as the
    belt's: N_d = EA eta lam d(eps)/dt = EA eta lam^2 (u . d') / L along u. Mass: the span's rho L lumped
    at its ends, rho L / 2 on each tangent point, which moves with its pulley (no DOFs of its own, no
    transverse modes). A spring also carries compression, where a belt would go slack: the static
    analysis refuses a compressed span, the transient records it as a slack event. Evaluated in numpy
    here (static, modal) and by `spring_kernel` in the time stepper, held equal by the tests.

    Running belt (`running`): the material flows through the chord at c (m/s of undeformed length), so
    each lumped end moves at x' + c d / L. Its kinetic energy's terms in c are those of the ANCF span
    on the linear interpolation between the ends: c x'^T (A x) with A = rho / 2 [[-I, I], [-I, I]]
    (gyroscopic c (A - A^T) = c rho [[0, I], [-I, 0]], the axial inertia c' A x) and the centripetal
    c^2 x^T B x / 2 with B = rho / L [[I, -I], [-I, I]]: the ends feel -c^2 B x = rho c^2 lam [u, -u],
    so a pulley receives N - rho c^2 lam from the span, as from an ANCF span (`transport_blocks`).
    """

    span: np.ndarray  # (k,) span index of each spring span
    T: np.ndarray  # (k, 4, m) end positions per joint coordinate
    idx: np.ndarray  # (k, m) joint coordinate indices (n_dof = padding)
    x0: np.ndarray  # (k, 4) end positions at p = 0
    reference_length: np.ndarray  # (k,) L, m
    reference_direction: np.ndarray  # (k, 2) chord direction at p = 0
    EA: float  # N
    rho: float  # kg/m
    n_dof: int  # joint coordinates p
    n_span: int  # spans of the drive (spring and flexible)
    damping_axial: float = 0.0  # Kelvin-Voigt retardation time (s), set by the transient options
    EI: float = 0.0  # the belt's bending stiffness (N m^2) and model.curvature: not used by the springs, only
    curvature: str = "linear"  # to name the modes of the span they leave out (`ladder.unrepresented_modes`)

    @property
    def end_mass(self) -> np.ndarray:
        """(k,) the mass lumped on each end, rho L / 2 (kg) (cached)."""
        return _cached(self, "_end_mass", lambda: 0.5 * self.rho * self.reference_length)

    @property
    def Tt(self) -> np.ndarray:
        """(k, m, 4) transposed end transformation (cached)."""
        return _transposed(self)

    def positions(self, p: np.ndarray) -> np.ndarray:
        """x (k, 4) at the joint coordinates p (n_dof,)."""
        return self.x0 + np.matmul(self.T, np.concatenate([p, _PAD])[self.idx][:, :, None])[:, :, 0]

    def positions_batch(self, P: np.ndarray, *, offset: bool = True) -> np.ndarray:
        """(B, k, 4) end positions (velocities, accelerations with offset=False) of states P (B, n_dof)."""
        Pe = np.concatenate([P, np.zeros((P.shape[0], 1))], axis=1)[:, self.idx]
        X = np.einsum("kim,bkm->bki", self.T, Pe)
        return X + self.x0 if offset else X

    @staticmethod
    def chord(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u (..., k, 2), l (..., k): the chords' unit direction and length at end positions X (..., k, 4)."""
        d = X[..., 2:4] - X[..., 0:2]
        l = np.sqrt(np.einsum("...d,...d->...", d, d))
        return d / l[..., None], l

    def axial(self, X: np.ndarray):
        """u (..., k, 2), l, lam, eps, N (..., k) at end positions X (..., k, 4)."""
        u, l = self.chord(X)
        lam = l / self.reference_length
        eps = 0.5 * (lam * lam - 1.0)
        return u, l, lam, eps, self.EA * eps * lam

    def damping_force(self, X: np.ndarray, Xd: np.ndarray) -> np.ndarray:
        """N_d (..., k) of end velocities Xd."""
        u, l, lam, _, _ = self.axial(X)
        rate = np.einsum("...d,...d->...", u, Xd[..., 2:4] - Xd[..., 0:2])
        return self.EA * self.damping_axial * lam * lam * rate / self.reference_length

    def reduce_vector(self, fe: np.ndarray) -> np.ndarray:
        """sum_k T^T fe (k, 4) -> (n_dof,)."""
        fr = np.matmul(self.Tt, fe[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def reduce_blocks(self, Ke: np.ndarray) -> np.ndarray:
        """(k, m, m) blocks T^T Ke T of (k, 4, 4) end-position blocks."""
        return np.matmul(np.matmul(self.Tt, Ke), self.T)

    @staticmethod
    def _pair(A: np.ndarray) -> np.ndarray:
        """[[A, -A], [-A, A]] (k, 4, 4) of (k, 2, 2)."""
        return np.concatenate([np.concatenate([A, -A], axis=2), np.concatenate([-A, A], axis=2)], axis=1)

    def force(self, p: np.ndarray) -> np.ndarray:
        """Reduced elastic force (n_dof,)."""
        return self._force(p)[0]

    def _force(self, p: np.ndarray):
        """The reduced elastic force (n_dof,) T^T [-N u, N u] = D^T (N u) through the chord's map D = dd/dp
        (`chord_map`), and u, l, lam, N (`axial`)."""
        u, l, lam, _, N = self.axial(self.positions(p))
        fr = np.matmul(self.chord_map_t, (N[:, None] * u)[:, :, None])[:, :, 0]
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof], u, l, lam, N

    def force_and_blocks(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reduced elastic force (n_dof,) and the tangent blocks T^T K_e T (k, m, m), through the chord's
        map D: T^T [[K2, -K2], [-K2, K2]] T = D^T K2 D."""
        f, u, l, lam, N = self._force(p)
        k_a = self.EA * (3.0 * lam * lam - 1.0) / (2.0 * self.reference_length)
        uu = u[:, :, None] * u[:, None, :]
        K2 = k_a[:, None, None] * uu + (N / l)[:, None, None] * (_EYE2 - uu)
        return f, np.matmul(np.matmul(self.chord_map_t, K2), self.chord_map)

    @property
    def chord_map(self) -> np.ndarray:
        """D = T[:, 2:4] - T[:, 0:2] (k, 2, m): the chord d = r_b - r_a per joint coordinate (cached)."""
        return _cached(self, "_D", lambda: self.T[:, 2:4] - self.T[:, 0:2])

    @property
    def chord_map_t(self) -> np.ndarray:
        """D^T (k, m, 2), contiguous (cached)."""
        return _cached(self, "_Dt", lambda: np.ascontiguousarray(self.chord_map.transpose(0, 2, 1)))

    def damping_blocks(self, p: np.ndarray) -> np.ndarray:
        """(k, m, m) the damping matrix dN_d/d(x') through the joints at p (Kelvin-Voigt)."""
        u, _, lam, _, _ = self.axial(self.positions(p))
        c = self.EA * self.damping_axial * lam * lam / self.reference_length
        return self.reduce_blocks(self._pair(c[:, None, None] * u[:, :, None] * u[:, None, :]))

    def mass_blocks(self) -> np.ndarray:
        """(k, m, m) T^T (rho L / 2 I4) T, constant."""
        return self.end_mass[:, None, None] * np.matmul(self.T.transpose(0, 2, 1), self.T)

    def transport_end_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(A_s, B_s) (k, 4, 4) per unit speed on the end positions (class docstring)."""
        eye = np.broadcast_to(np.eye(2), (len(self.span), 2, 2))
        half = 0.5 * self.rho * eye
        A = np.concatenate([np.concatenate([-half, half], axis=2), np.concatenate([-half, half], axis=2)], axis=1)
        return A, self._pair((self.rho / self.reference_length)[:, None, None] * eye)

    def transport_blocks(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """As `BeltSpans.transport_blocks`: T^T A_s T, T^T B_s T (k, m, m) and the reduced A_s x0, B_s x0
        (n_dof,). Cached."""
        got = self.__dict__.get("_transport")
        if got is None:
            A, B = self.transport_end_matrices()
            got = (self.reduce_blocks(A), self.reduce_blocks(B), self.reduce_vector(np.matmul(A, self.x0[:, :, None])[:, :, 0]),
                   self.reduce_vector(np.matmul(B, self.x0[:, :, None])[:, :, 0]))
            object.__setattr__(self, "_transport", got)
        return got

    def centripetal_force(self, p: np.ndarray, speed: float) -> np.ndarray:
        """-c^2 T^T B_s x (n_dof,) at the joint coordinates p."""
        B = self.transport_end_matrices()[1]
        return -(speed * speed) * self.reduce_vector(np.matmul(B, self.positions(p)[:, :, None])[:, :, 0])

    def transport_end_forces(self, X: np.ndarray, Xd: np.ndarray | None, speed, acceleration=0.0) -> np.ndarray:
        """(B, n_span, 2, 2) as `BeltSpans.transport_end_forces` for end states X, Xd (B, k, 4):
        c (A_s - A_s^T) x' - c^2 B_s x + c' A_s x on each end (zeros for the other spans)."""
        A, Bm = self.transport_end_matrices()
        c = np.broadcast_to(np.asarray(speed, dtype=float), (X.shape[0],))[:, None, None]
        cd = np.broadcast_to(np.asarray(acceleration, dtype=float), (X.shape[0],))[:, None, None]
        f = -c * c * np.einsum("kij,bkj->bki", Bm, X) + cd * np.einsum("kij,bkj->bki", A, X)
        if Xd is not None:
            f = f + c * np.einsum("kij,bkj->bki", A - A.transpose(0, 2, 1), Xd)
        return self.scatter(f.reshape(X.shape[0], -1, 2, 2))

    def gravity_force(self, g: np.ndarray) -> np.ndarray:
        """(n_dof,) the generalized weight of the lumped masses for the gravity vector g (2,)."""
        fe = self.end_mass[:, None] * np.concatenate([g, g], dtype=float)  # (k, 4): both ends
        fr = np.matmul(fe[:, None, :], self.T)  # (k, 1, m): T^T fe
        return np.bincount(self.idx.ravel(), weights=fr.ravel(), minlength=self.n_dof + 1)[: self.n_dof]

    def strain_energy(self, p: np.ndarray) -> float:
        _, _, _, eps, _ = self.axial(self.positions(p))
        return float((0.5 * self.EA * self.reference_length * eps * eps).sum())

    def tension_integral(self, p: np.ndarray, *, gradient: bool = True) -> tuple[float, np.ndarray | None]:
        """sum_k N_k L_k (N m) and its gradient (n_dof,) (None without gradient): the springs' share of the
        length-weighted mean."""
        u, _, lam, _, N = self.axial(self.positions(p))
        if not gradient:
            return float((N * self.reference_length).sum()), None
        k_a = self.EA * (3.0 * lam * lam - 1.0) / (2.0 * self.reference_length)
        g = (k_a * self.reference_length)[:, None] * u
        return float((N * self.reference_length).sum()), self.reduce_vector(np.concatenate([-g, g], axis=1))

    @property
    def span_rows(self) -> slice | np.ndarray:
        """Where the springs' rows go among the spans: `span`, or a slice when every span is a spring
        (cached)."""
        return self._spans

    @functools.cached_property  # (a "_" name: not a field, which `System.with_belt` copies)
    def _spans(self) -> slice | np.ndarray:
        return slice(None) if len(self.span) == self.n_span else self.span  # (span: ascending, distinct)

    def scatter(self, x: np.ndarray) -> np.ndarray:
        """(B, k, ...) -> (B, n_span, ...), zeros for the other spans (x's dtype)."""
        if isinstance(self._spans, slice):
            return x
        out = np.zeros((x.shape[0], self.n_span) + x.shape[2:], dtype=x.dtype)
        out[:, self.span] = x
        return out

    def end_forces(self, X: np.ndarray, Xd: np.ndarray | None, gravity: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) force of each spring span on its end points (as `BeltSpans.end_forces`:
        internal + damping - weight of the lumped masses; zeros for the other spans), from end states
        X, Xd (B, k, 4)."""
        u, _, _, _, N = self.axial(X)
        if Xd is not None and self.damping_axial > 0.0:
            N = N + self.damping_force(X, Xd)
        w = self.end_mass[None, :, None] * np.asarray(gravity, dtype=float)
        Nu = N[..., None] * u
        out = np.zeros((X.shape[0], self.n_span, 2, 2))
        out[:, self._spans, 0] = -Nu - w
        out[:, self._spans, 1] = Nu - w
        return out

    def end_inertia(self, Xa: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) inertia forces of the lumped masses, end accelerations Xa (B, k, 4)."""
        m = self.end_mass[None, :, None]
        return self.scatter(np.stack([m * Xa[..., 0:2], m * Xa[..., 2:4]], axis=2))

    def end_tensions(self, X: np.ndarray, F_end: np.ndarray) -> np.ndarray:
        """(B, n_span, 2) span tensions at the ends of the spring spans (zeros elsewhere) from the end
        forces F_end (B, n_span, 2, 2): N_start = -F_start . u, N_end = F_end . u."""
        u = self.chord(X)[0]
        F = F_end[:, self._spans]
        out = np.zeros((X.shape[0], self.n_span, 2))
        out[:, self._spans, 0] = -np.einsum("bkd,bkd->bk", F[:, :, 0], u)
        out[:, self._spans, 1] = np.einsum("bkd,bkd->bk", F[:, :, 1], u)
        return out

    def static_ends(self, p: np.ndarray, gravity: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """At the joint coordinates p (n_dof,), the chord evaluated once: the spring spans' end forces
        (n_span, 2, 2) (`end_forces` without damping), their end tensions (n_span, 2) (`end_tensions`),
        zeros for the other spans, and sum_k N_k L_k (N m) (`tension_integral`)."""
        gx, gy = (float(g) for g in gravity)
        EA, half_rho = self.EA, 0.5 * self.rho
        F, T, NL = [], [], 0.0
        for (xa, ya, xb, yb), L in zip(self.positions(p).tolist(), self.reference_length.tolist()):  # (a few spans)
            dx, dy = xb - xa, yb - ya
            l = math.sqrt(dx * dx + dy * dy)
            ux, uy = dx / l, dy / l
            lam = l / L
            N = EA * (0.5 * (lam * lam - 1.0)) * lam
            m = half_rho * L  # the lumped ends' weight m g
            wx, wy, Nux, Nuy = m * gx, m * gy, N * ux, N * uy
            f0x, f0y, f1x, f1y = -Nux - wx, -Nuy - wy, Nux - wx, Nuy - wy
            F.append(((f0x, f0y), (f1x, f1y)))
            T.append((-(f0x * ux + f0y * uy), f1x * ux + f1y * uy))
            NL += N * L
        if isinstance(self._spans, slice):
            return np.array(F), np.array(T), NL
        F_all, T_all = np.zeros((self.n_span, 2, 2)), np.zeros((self.n_span, 2))
        F_all[self.span], T_all[self.span] = F, T
        return F_all, T_all, NL

    def kinetic_energy_split(self, P: np.ndarray) -> np.ndarray:
        """(k, 2, B): the lumped masses' quadratic energy form dX^T M dX along (0) and across (1) the chord
        at p = 0 for joint motions P (B, n_dof) (as the belt's share splits, `System.kinetic_energies`):
        the end motions' components along t and n = z x t straight from P through the joints
        (frame x T, (k, end x t|n, m); T is zero in the padding columns, so the padding index may take any
        coordinate of P)."""
        k, m = self.idx.shape
        t = self.reference_direction
        frame = np.concatenate([t, t[:, ::-1] * _NORMAL], axis=1).reshape(k, 1, 2, 2)  # (k, 1, t|n, 2), n = z x t
        tn = np.matmul(frame, self.T.reshape(k, 2, 2, m)).reshape(k, 4, m)  # rows: end 0 t, n, end 1 t, n
        ab = np.matmul(tn, P.take(self.idx, axis=1, mode="clip").transpose(1, 2, 0))  # (k, 4, B)
        ab *= ab
        e = ab[:, 0:2] + ab[:, 2:4]  # (k, t|n, B): both ends
        e *= self.end_mass[:, None, None]
        return e


def build_springs(cfg: DriveConfig, layout: Layout, dofs: DofMap, *,
                  prestrain_stretch: float | np.ndarray = 1.0, direction: np.ndarray | None = None,
                  reference_length: np.ndarray | None = None) -> SpringSpans | None:
    """The spring spans of the configuration (None without any), on the layout's tangent points.
    direction: the layout's `span_direction`; reference_length (n_span,): every span's reference length at
    this prestrain_stretch (`BeltSpans.reference_length`); each if at hand."""
    spans = tuple([s for s, m in enumerate(cfg.span_models) if m == "spring"])
    if not spans:
        return None
    n = layout.n
    idx, T, (at, pulley) = _spring_joints(dofs, spans, n)
    direction = layout.span_direction if direction is None else direction
    if reference_length is None:
        reference_length = layout.span_length / _span_stretch(prestrain_stretch, n)
    start, end, start_normal, end_normal = layout.span_start, layout.span_end, layout.start_normal, layout.end_normal
    sp = np.arange(n) if len(spans) == n else np.array(spans, dtype=np.int64)  # (writable: `spring_kernel`)
    if len(spans) < n:  # (every span a spring: the layout's arrays as they are)
        reference_length, direction = reference_length[sp], direction[sp]
        start, end, start_normal, end_normal = start[sp], end[sp], start_normal[sp], end_normal[sp]
    T = T.copy()  # the rotation columns R (z x n) = R (-n_y, n_x) of each end (`joint_pairs`): the layout's
    normal = np.concatenate([start_normal, end_normal])  # (2k, 2)
    T.ravel()[at] = (normal[:, ::-1] * _NORMAL * layout.radius[pulley][:, None]).ravel()
    return set_at_once(SpringSpans, span=sp, T=T, idx=idx, x0=np.concatenate([start, end], axis=1),
                        reference_length=reference_length, reference_direction=direction, EA=float(cfg.belt.EA),
                        rho=float(cfg.belt.mass_per_length), n_dof=dofs.n, n_span=n, damping_axial=0.0,
                        EI=float(cfg.belt.EI), curvature=cfg.model.curvature)


def _span_stretch(prestrain_stretch: float | np.ndarray, n: int) -> np.ndarray:
    """(n,) the spans' stretch at q = 0 of one number for all or one per span (a new array)."""
    if isinstance(prestrain_stretch, np.ndarray) and prestrain_stretch.shape == (n,):
        return prestrain_stretch.astype(float)
    if isinstance(prestrain_stretch, (float, int)) or np.ndim(prestrain_stretch) == 0:
        return np.full(n, float(prestrain_stretch))
    lam = np.array(prestrain_stretch, dtype=float)
    return lam if lam.shape == (n,) else np.broadcast_to(lam, (n,)).copy()


def _spring_joints(dofs: DofMap, spans: tuple[int, ...], n: int) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The parts of the spring spans' joints that the DOF map fixes (`joint_pairs`), cached on it (read-only):
    idx (k, m) the joint coordinates of each span, its start's columns (rotation, then the pulley's
    translations) before its end's, padded with n_dof; T (k, 4, m) with the translations' directions and
    zero rotation columns; and where the rotation columns' entries are in T's flat order ((4k,): the x and
    y rows of each end) and their pulleys (2k,), the k starts, then the k ends."""
    cache = dofs.__dict__.setdefault("_spring_joints", {})
    hit = cache.get(spans)
    if hit is not None:
        return hit
    k = len(spans)
    ends = [(s, (s + 1) % n) for s in spans]
    m = max(2 + len(dofs.trans_dof[a]) + len(dofs.trans_dof[b]) for a, b in ends)
    T = np.zeros((k, 4, m))
    idx = np.full((k, m), dofs.n, dtype=np.int64)
    rot_col = np.zeros((2, k), dtype=np.int64)
    for i, pair in enumerate(ends):
        col = 0
        for side, j in enumerate(pair):
            rot_col[side, i] = col
            idx[i, col] = dofs.rot_dof[j]
            for col, (dof, v) in enumerate(zip(dofs.trans_dof[j], dofs.trans_dir[j]), start=col + 1):
                idx[i, col] = dof
                T[i, 2 * side: 2 * side + 2, col] = v
            col += 1
    for a in (idx, T):
        a.setflags(write=False)
    sp = np.array(spans, dtype=np.int64)
    rows = np.repeat([0, 2], k)
    at = np.ravel_multi_index((np.repeat(np.tile(np.arange(k), 2), 2), np.stack([rows, rows + 1], axis=1).ravel(),
                               np.repeat(rot_col.ravel(), 2)), T.shape)
    hit = cache[spans] = (idx, T, (at, np.concatenate([sp, (sp + 1) % n])))
    return hit


def _sub_tables(tab, els: np.ndarray) -> tuple:
    """Kernel table arguments (dS, d2S, wEA, wEI, Kb, curvature) of a subset of elements."""
    return (np.ascontiguousarray(tab.dS[els]), np.ascontiguousarray(tab.d2S[els]), np.ascontiguousarray(tab.wEA[els]),
            np.ascontiguousarray(tab.wEI[els]), np.ascontiguousarray(tab.Kb[els]), tab.curvature)


# ------------------------------------------------------------------------------------ assembly pattern
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


_PATTERNS: dict = {}  # make_pattern memo: re-laid systems of one drive share their pattern


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


# ------------------------------------------------------------------------------------ the system
@dataclass(frozen=True, kw_only=True)
class TensionSetting:
    """How the belt tension is set: target N (None: the geometry decides), mode "adjust" (the
    adjustable DOF moves until the mean tension meets the target) or "prestrain"."""

    target: float | None
    mode: str
    adjust_dof: int  # -1 when no DOF is moved
    adjust_range: tuple[float, float] | None = None  # allowed total travel of the adjustable pulley (slide_range), m
    adjust_name: str = ""  # name of the adjustable pulley


def _last_pair(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """x and y (same shape) stacked on a new last axis of 2: np.stack(..., axis=-1) without its overhead."""
    out = np.empty(np.shape(x) + (2,))
    out[..., 0] = x
    out[..., 1] = y
    return out


@dataclass(frozen=True, kw_only=True)
class ArmJoints:
    """Exact kinematics of the tensioner arms: joint coordinates p = P(q) from the independent q.

    Arm k turns about pivot[k]; its angle is phi = angle[k] + q[dof[k]] (angle: the arm angle of the
    layout, q = 0), and its pulley's centre c(phi) = pivot + l (cos phi, sin phi). The dependent
    coordinates p[slot[k]], p[slot[k] + 1] are the centre offsets u = c(phi) - c(angle), which the belt
    joints and the pulley's mass and weight see as a bearing's translations. So the pulley's mass adds
    m l^2 to the arm's inertia through J^T M J, its weight the moment m g . c'(phi), and every force on
    the pulley the geometric stiffness F . c''(phi) (paper Eq. 24 with the constraint eliminated).

    J = dp/dq (n_p, n_q): the identity on q, and dc/dphi = l (-sin phi, cos phi) in the arm columns.
    """

    dof: np.ndarray  # (a,) q index of each arm angle
    slot: np.ndarray  # (a,) p index of each arm pulley's x offset (y: slot + 1)
    pivot: np.ndarray  # (a, 2) m
    length: np.ndarray  # (a,) m
    angle: np.ndarray  # (a,) rad, arm angle at q = 0
    n_q: int
    n_p: int
    friction: np.ndarray | None = None  # (a,) N m, dry friction torque of each arm's pivot damper (transient)
    stops: np.ndarray | None = None  # (a, 2) rad, arm_range (NaN: none)
    names: tuple[str, ...] = ()  # the arm pulleys' names
    pulleys: tuple[int, ...] = ()  # the arm pulleys' indices

    def phi(self, q: np.ndarray) -> np.ndarray:
        """(..., a) arm angles."""
        return self.angle + q[..., self.dof]

    def first(self, phi: np.ndarray) -> np.ndarray:
        """dc/dphi (..., a, 2)."""
        return self.length[:, None] * _last_pair(-np.sin(phi), np.cos(phi))

    def second(self, phi: np.ndarray) -> np.ndarray:
        """d2c/dphi2 (..., a, 2)."""
        return -self.length[:, None] * _last_pair(np.cos(phi), np.sin(phi))

    def expand(self, q: np.ndarray) -> np.ndarray:
        """p (..., n_p) from q (..., n_q) (one state: arm by arm on Python floats)."""
        if q.ndim == 1:
            out = np.empty(self.n_p)
            out[: self.n_q] = q
            for slot, dof, length, angle, cos0, sin0 in self._arm_floats:
                phi = angle + q.item(dof)
                out[slot], out[slot + 1] = length * (math.cos(phi) - cos0), length * (math.sin(phi) - sin0)
            return out
        phi = self.phi(q)
        cos0, sin0 = self._reference_cos_sin
        u = self.length[:, None] * _last_pair(np.cos(phi) - cos0, np.sin(phi) - sin0)
        return np.concatenate([q, u.reshape(*q.shape[:-1], -1)], axis=-1)

    @functools.cached_property
    def _arm_floats(self) -> list[tuple[int, int, float, float, float, float]]:
        """(slot, dof, length, angle, cos angle, sin angle) of each arm, Python numbers (the one-state paths
        `expand`, `dense_jacobian`, `project_both`)."""
        return list(zip(self.slot.tolist(), self.dof.tolist(), self.length.tolist(), self.angle.tolist(),
                        *(x.tolist() for x in self._reference_cos_sin)))

    @functools.cached_property
    def _reference_cos_sin(self) -> tuple[np.ndarray, np.ndarray]:
        """cos and sin (a,) of the arm angles at q = 0."""
        return np.cos(self.angle), np.sin(self.angle)

    @functools.cached_property
    def reference_slopes(self) -> np.ndarray:
        """dc/dphi (a, 2) at q = 0 (`first`(angle); read-only)."""
        cos0, sin0 = self._reference_cos_sin
        out = self.length[:, None] * _last_pair(-sin0, cos0)
        out.setflags(write=False)
        return out

    def expand_motion(self, q: np.ndarray, dq: np.ndarray, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J(q) dq (..., n_p): velocities, or mode shapes about q (slopes: `first` at q, if at hand)."""
        du = (self.first(self.phi(q)) if slopes is None else slopes) * dq[..., self.dof, None]
        return np.concatenate([dq, du.reshape(*dq.shape[:-1], -1)], axis=-1)

    def expand_acceleration(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """J a + (d2c/dphi2) phidot^2 (..., n_p)."""
        phi = self.phi(q)
        w = v[..., self.dof]
        du = np.einsum("...kd,...k->...kd", self.first(phi), a[..., self.dof]) + \
            np.einsum("...kd,...k->...kd", self.second(phi), w * w)
        return np.concatenate([a, du.reshape(*a.shape[:-1], -1)], axis=-1)

    def project(self, q: np.ndarray | None, f: np.ndarray) -> np.ndarray:
        """J(q)^T f: a force (..., n_p) on the joint coordinates -> (..., n_q) (q None: at q = 0)."""
        out = f[..., : self.n_q].copy()
        fu = f[..., self.n_q:].reshape(*f.shape[:-1], len(self.dof), 2)
        if q is None:
            dc = self.reference_slopes
            out[..., self.dof] += dc[:, 0] * fu[..., 0] + dc[:, 1] * fu[..., 1]
            return out
        phi = self.phi(q)
        out[..., self.dof] += -(self.length * np.sin(phi)) * fu[..., 0] + (self.length * np.cos(phi)) * fu[..., 1]
        return out

    def jacobian(self, q: np.ndarray):
        """J(q) (n_p, n_q) CSR."""
        from scipy.sparse import coo_matrix

        dc = self.first(self.phi(q))
        rows = np.concatenate([np.arange(self.n_q), self.slot, self.slot + 1])
        cols = np.concatenate([np.arange(self.n_q), self.dof, self.dof])
        vals = np.concatenate([np.ones(self.n_q), dc[:, 0], dc[:, 1]])
        return coo_matrix((vals, (rows, cols)), shape=(self.n_p, self.n_q)).tocsr()

    def project_matrix(self, q: np.ndarray, K, f: np.ndarray | None = None, *, dense: bool):
        """J^T K J (+ the geometric term sum_k (f_u,k . c''(phi_k)) on (phi_k, phi_k) for the force f
        (n_p,) on the joint coordinates whose derivative K (n_p, n_p) is; none for f = None)."""
        if f is None:
            return self._project_matrix(self.first(self.phi(q)), K, None, dense=dense)
        return self.project_both(q, f, K, dense=dense)[1]

    def project_both(self, q: np.ndarray, f: np.ndarray, K, *, dense: bool):
        """(`project`(q, f), `project_matrix`(q, K, f)): the arm's sine and cosine evaluated once (a dense
        K: arm by arm on Python floats, from the dense jacobian's `dense_jacobian`)."""
        if dense and not hasattr(K, "tocsr"):
            J = self.dense_jacobian(q)
            out = f[: self.n_q].copy()
            geo = []
            for slot, dof, *_ in self._arm_floats:
                dx, dy, fx, fy = J.item(slot, dof), J.item(slot + 1, dof), f.item(slot), f.item(slot + 1)
                out[dof] += dx * fx + dy * fy
                geo.append((-dy) * fx + dx * fy)  # f_u . d2c/dphi2, d2c/dphi2 = (-dy, dx)
            Kq = J.T @ np.asarray(K) @ J
            Kq[self.dof, self.dof] += geo
            return out, Kq
        phi = self.angle + q[self.dof]
        L = self.length
        dx, dy = -(L * np.sin(phi)), L * np.cos(phi)  # dc/dphi (`first`); d2c/dphi2 = (-dy, dx) (`second`)
        fu = f[self.n_q:].reshape(len(self.dof), 2)
        fx, fy = fu[:, 0], fu[:, 1]
        out = f[: self.n_q].copy()
        out[self.dof] += dx * fx + dy * fy
        return out, self._project_matrix(None, K, (-dy) * fx + dx * fy, dense=dense, dxy=(dx, dy))

    def _project_matrix(self, dc: np.ndarray | None, K, geo: np.ndarray | None, *, dense: bool, dxy=None):
        """J^T K J + geo on the arms' diagonal, dc = dc/dphi (a, 2) (`project_matrix`; or its columns dxy)."""
        dx, dy = (dc[:, 0], dc[:, 1]) if dxy is None else dxy
        if dense and not hasattr(K, "tocsr"):
            J = self._jacobian_of(dx, dy)
            out = J.T @ np.asarray(K) @ J
            if geo is not None:
                out[self.dof, self.dof] += geo
            return out
        from scipy.sparse import csr_matrix

        K = csr_matrix(K)
        fold, ptr, idx, diag = self._folding(K)
        w = np.ones(self.n_p)
        w[self.slot], w[self.slot + 1] = dx, dy
        rows = np.repeat(np.arange(self.n_p), np.diff(K.indptr))
        data = np.bincount(fold, weights=K.data * w[rows] * w[K.indices], minlength=len(idx))
        if geo is not None:
            data[diag] += geo
        return csr_matrix((data, idx, ptr), shape=(self.n_q, self.n_q))

    def dense_jacobian(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J = dp/dq (n_p, n_q) dense at q: the identity on q, the arms' slopes dc/dphi in the arm columns,
        from `first` (a, 2) at q if given (slopes), else from q arm by arm on Python floats (`first`'s
        formula: a drive has a few arms)."""
        if slopes is not None:
            return self._jacobian_of(slopes[:, 0], slopes[:, 1])
        n_q = self.n_q
        J = np.zeros((self.n_p, n_q))
        J.ravel()[: n_q * (n_q + 1): n_q + 1] = 1.0  # the identity on q
        for slot, dof, length, angle, _, _ in self._arm_floats:
            phi = angle + q.item(dof)
            J[slot, dof], J[slot + 1, dof] = -(length * math.sin(phi)), length * math.cos(phi)
        return J

    def _jacobian_of(self, dx: np.ndarray, dy: np.ndarray) -> np.ndarray:
        """The dense jacobian (n_p, n_q) of the arms' slopes dc/dphi = (dx, dy) (a,) each."""
        J = self._eye.copy()
        J[self.slot, self.dof], J[self.slot + 1, self.dof] = dx, dy
        return J

    @functools.cached_property
    def _eye(self) -> np.ndarray:
        """np.eye(n_p, n_q), the dense jacobian's identity part (a copy is taken)."""
        return np.eye(self.n_p, self.n_q)

    def _folding(self, K):
        """For a CSR pattern on p: the slot of each entry in the pattern on q (rows and columns of the
        dependent offsets folded onto their arm angle), that pattern, and the arms' diagonal slots.
        Cached per pattern."""
        cache = self.__dict__.setdefault("_fold_cache", {})
        key = (K.shape, K.nnz)
        hit = cache.get(key)
        if hit is not None and np.array_equal(hit[0], K.indptr) and np.array_equal(hit[1], K.indices):
            return hit[2:]
        to = np.arange(self.n_p)
        to[self.slot], to[self.slot + 1] = self.dof, self.dof
        rows = np.repeat(np.arange(self.n_p), np.diff(K.indptr))
        keys = to[rows] * self.n_q + to[K.indices]
        uniq, fold = np.unique(keys, return_inverse=True)
        r, c = uniq // self.n_q, uniq % self.n_q
        ptr = np.zeros(self.n_q + 1, dtype=np.int64)
        np.add.at(ptr, r + 1, 1)
        ptr = np.cumsum(ptr)
        diag = np.searchsorted(uniq, self.dof * self.n_q + self.dof)
        out = (fold.ravel(), ptr, c.astype(np.int64), diag)
        cache[key] = (K.indptr.copy(), K.indices.copy(), *out)
        return out


@dataclass(frozen=True, kw_only=True)
class System:
    """The drive: DOF map, belt, components, assembled constant matrices. n = n_dof."""

    layout: Layout
    dofs: DofMap
    belt: BeltSpans
    components: tuple[LinearComponent, ...]
    pulley_names: tuple[str, ...]
    driver: int  # pulley index held in statics (reacts the applied torques)
    tension: TensionSetting
    gravity: np.ndarray  # (2,) m/s^2
    dense: bool
    pattern: Pattern
    mass: object  # (n, n) dense array or CSR
    gravity_force: np.ndarray  # (n,) generalized weight at gravity factor 1
    linear_stiffness: object  # (n, n) dense, or CSR data (nnz,) in the pattern, or None
    linear_damping: object  # (n, n) dense array or CSR, or None (constant component damping)
    linear_offset: np.ndarray | None = None  # (n,) sum of K_c free_c: the components' force is K q - offset
    loads: np.ndarray | None = None  # (n_p,) constant applied forces of the static load case (accessory torques)
    arms: ArmJoints | None = None  # tensioner arms: p = P(q); None: p = q
    pulley_friction: np.ndarray | None = None  # (n_pulley,) belt-pulley friction coefficient, NaN if not given
    belt_speed: float = 0.0  # m/s, the running belt's transport speed c (`running`); 0: the drive at rest
    springs: SpringSpans | None = None  # the spans modelled as axial springs (None: every span flexible)
    spring_scatter: np.ndarray | None = None  # (k m m,) where the springs' blocks go: flat (dense) or CSR slot

    # The belt, the components, mass, pattern, gravity_force, loads and the linear matrices live on the
    # joint coordinates p (n_p); the analyses see the independent q (n_dof). Without arms p = q.

    # -------------------------------------------------------------------- names kept from the model
    @property
    def n_dof(self) -> int:
        return self.dofs.n_q

    @property
    def n_p(self) -> int:
        return self.dofs.n

    @property
    def dof_labels(self) -> tuple[str, ...]:
        return self.dofs.labels[: self.dofs.n_q]

    @property
    def dof_units(self) -> tuple[str, ...]:
        return self.dofs.units[: self.dofs.n_q]

    @property
    def dof_groups(self) -> np.ndarray:
        return self.dofs.group[: self.dofs.n_q]

    def expand(self, q: np.ndarray) -> np.ndarray:
        """The joint coordinates p (..., n_p) of q (..., n_dof)."""
        return q if self.arms is None else self.arms.expand(q)

    def expand_motion(self, q: np.ndarray, dq: np.ndarray, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """Velocities or mode shapes dq (..., n_dof) about q on the joint coordinates (slopes: the arms'
        dc/dphi at q, `arm_slopes`, if at hand)."""
        return dq if self.arms is None else self.arms.expand_motion(q, dq, slopes=slopes)

    def arm_slopes(self, q: np.ndarray) -> np.ndarray | None:
        """dc/dphi (a, 2) of the arm pulleys' centres at q (`ArmJoints.first`); None without arms."""
        return None if self.arms is None else self.arms.first(self.arms.phi(q))

    @property
    def rot_dof(self) -> np.ndarray:
        return self.dofs.rot_dof

    @property
    def trans_dof(self) -> tuple[tuple[int, ...], ...]:
        return self.dofs.trans_dof

    @property
    def trans_dir(self) -> tuple[np.ndarray, ...]:
        return self.dofs.trans_dir

    @property
    def driver_dof(self) -> int:
        return int(self.dofs.rot_dof[self.driver])

    def pulley_index(self, name: str) -> int:
        return self.pulley_names.index(name)

    def with_components(self, *extra: LinearComponent) -> "System":
        """A system with more components (matrices and pattern rebuilt)."""
        out = _assemble(self.layout, self.dofs, self.belt, self.components + tuple(extra), pulley_names=self.pulley_names,
                        driver=self.driver, tension=self.tension, gravity=self.gravity, dense=self.dense,
                        loads=self.loads, arms=self.arms, friction=self.pulley_friction, springs=self.springs)
        return out.with_speed(self.belt_speed) if self.belt_speed else out

    def with_belt(self, **changes) -> "System":
        """The same system with belt fields changed (e.g. damping_axial, compiled); the spring spans
        take the axial damping too."""
        belt = BeltSpans(**{**{k: v for k, v in self.belt.__dict__.items() if not k.startswith("_")}, **changes})
        springs = self.springs
        if springs is not None and "damping_axial" in changes:
            springs = SpringSpans(**{**{k: v for k, v in springs.__dict__.items() if not k.startswith("_")},
                                     "damping_axial": float(changes["damping_axial"])})
        return System(**{**{k: v for k, v in self.__dict__.items() if not k.startswith("_")}, "belt": belt,
                         "springs": springs})

    def with_belt_damping(self, axial: float, bending: float) -> "System":
        return self.with_belt(damping_axial=float(axial), damping_bending=float(bending))

    def with_speed(self, belt_speed: float) -> "System":
        """The same drive with its belt running at belt_speed (m/s; see `running`)."""
        return System(**{**{k: v for k, v in self.__dict__.items() if not k.startswith("_")},
                         "belt_speed": float(belt_speed)})

    # -------------------------------------------------------------------- the running belt
    def transport_matrices(self):
        """(A, B, a0, b0) of the running belt per unit speed on the joint coordinates (dense (n_p, n_p) or
        CSR; `BeltSpans.transport_blocks`): the gyroscopic matrix is c (A - A^T), the centripetal stiffness
        -c^2 B, the centripetal force -c^2 (B p + b0). Cached."""
        got = self.__dict__.get("_transport")
        if got is None:
            Ab, Bb, a0, b0 = self.belt.transport_blocks()
            sp = self.springs
            if sp is None:
                got = (self.assemble(Ab, linear=False), self.assemble(Bb, linear=False), a0, b0)
            else:  # + the spring spans' (their blocks on the same joint coordinates)
                As, Bs, a0s, b0s = sp.transport_blocks()
                got = (self.assemble(Ab, linear=False, springs=As), self.assemble(Bb, linear=False, springs=Bs),
                       a0 + a0s, b0 + b0s)
            object.__setattr__(self, "_transport", got)
        return got

    def centripetal_force(self, p: np.ndarray) -> np.ndarray:
        """-c^2 (B p + b0) (n_p,) at the joint coordinates p: the running belt's centripetal term of the
        internal force, the gradient of the centripetal potential V = -c^2/2 sum_e e^T B_e e (the force on
        the belt is its negative, outward along the spans' ends: the momentum flux)."""
        belt = self.belt
        c = self.belt_speed
        f = self.springs.centripetal_force(p, c) if self.springs is not None else 0.0
        if not belt.elements.n_elem:
            return f if self.springs is not None else np.zeros(self.n_p)
        belt.transport_blocks()
        B_e = belt.__dict__["_transport_e"][1]
        e = belt.element_coordinates(p)
        return f - (c * c) * belt.reduce_vector(np.matmul(B_e, e[:, :, None])[:, :, 0])

    def _running_blocks(self, blocks: np.ndarray) -> np.ndarray:
        """The element tangent blocks (n_elem, m, m) with the centripetal stiffness -c^2 T^T B_e T added."""
        return blocks - (self.belt_speed * self.belt_speed) * self.belt.transport_blocks()[1]

    def _running_spring_blocks(self, blocks: np.ndarray) -> np.ndarray:
        """The spring spans' tangent blocks (k, m, m) with their centripetal stiffness -c^2 T^T B_s T."""
        return blocks - (self.belt_speed * self.belt_speed) * self.springs.transport_blocks()[1]

    def gyroscopic_matrix(self, q: np.ndarray | None = None):
        """The gyroscopic matrix G = J^T c (A - A^T) J on q at the state q (skew-symmetric; zeros at rest)."""
        A = self.transport_matrices()[0]
        G = self.belt_speed * (A - A.T)
        return self.project_matrix(np.zeros(self.n_dof) if q is None else q, G)

    # -------------------------------------------------------------------- assembly
    def assemble(self, blocks: np.ndarray | None, *, linear: bool = True, diagonal: np.ndarray | None = None,
                 springs: np.ndarray | None = None):
        """Element blocks (n_elem, m, m) (None: none) (+ the spring spans' blocks (k, m_s, m_s), + the
        components' constant stiffness, + a diagonal) -> dense (n_p, n_p) or CSR, on the joint coordinates."""
        return _assembled(self.n_p, self.dense, self.pattern, blocks, springs if self.springs is not None else None,
                          self.spring_scatter, self.linear_stiffness if linear else None, diagonal)

    def linear_force(self, q: np.ndarray) -> np.ndarray:
        """The components' force K p - offset (joint coordinates p)."""
        if self.linear_stiffness is None:
            return np.zeros(self.n_p)
        f = self.linear_stiffness @ q if self.dense else self.linear_matrix() @ q
        return f - self.linear_offset if self.linear_offset is not None else f

    def linear_matrix(self):
        """The components' constant stiffness as a matrix (dense or CSR), zeros if none."""
        n = self.n_p
        if self.dense:
            return self.linear_stiffness if self.linear_stiffness is not None else np.zeros((n, n))
        A = self.__dict__.get("_linear_csr")
        if A is None:  # constant: built once (callers only read it)
            from scipy.sparse import csr_matrix

            data = self.linear_stiffness if self.linear_stiffness is not None else np.zeros(self.pattern.nnz)
            A = csr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=(n, n))
            object.__setattr__(self, "_linear_csr", A)
        return A

    # -------------------------------------------------------------------- forces
    def belt_force(self, p: np.ndarray) -> np.ndarray:
        """The belt's elastic force on the joint coordinates (n_p,): ANCF spans + spring spans, with the
        running belt's centripetal force at speed."""
        if self.springs is None:
            f = self.belt.force(p)
        elif self.belt.elements.n_elem == 0:
            f = self.springs.force(p)
        else:
            f = self.springs.force(p) + self.belt.force(p)
        return f + self.centripetal_force(p) if self.belt_speed else f

    def belt_force_and_tangent(self, p: np.ndarray, *, linear: bool = True):
        """The belt's elastic force (n_p,) and its tangent (+ the components' constant stiffness with
        linear=True) on the joint coordinates, assembled (dense or CSR); at speed with the spans'
        centripetal force and stiffness."""
        running = bool(self.belt_speed)
        if self.springs is not None:
            fs, bs = self.springs.force_and_blocks(p)
            if running:
                bs = self._running_spring_blocks(bs)
        if self.springs is not None and self.belt.elements.n_elem == 0:  # every span a spring
            f = fs + self.centripetal_force(p) if running else fs
            return f, self.assemble(None, linear=linear, springs=bs)
        f, blocks = self.belt.force_and_blocks(p)
        if running:
            f, blocks = f + self.centripetal_force(p), self._running_blocks(blocks)
        if self.springs is None:
            return f, self.assemble(blocks, linear=linear)
        return f + fs, self.assemble(blocks, linear=linear, springs=bs)

    def span_transport_forces(self, E: np.ndarray, Ed: np.ndarray | None, speed, acceleration=0.0, *,
                              p: np.ndarray, vp: np.ndarray | None = None) -> np.ndarray:
        """(B, n_span, 2, 2) the running belt's transport forces on the span ends (`BeltSpans.
        transport_end_forces`, `SpringSpans.transport_end_forces`) for the states p, vp (B, n_p) (E, Ed:
        the belt's element states of them)."""
        if self.belt.elements.n_elem == 0:
            F = np.zeros((p.shape[0], self.belt.n_span, 2, 2))
        else:
            F = self.belt.on_spans(self.belt.transport_end_forces(E, Ed, speed, acceleration))
        sp = self.springs
        if sp is not None:
            F = F + sp.transport_end_forces(sp.positions_batch(p), None if vp is None else sp.positions_batch(vp, offset=False),
                                            speed, acceleration)
        return F

    def internal_force(self, q: np.ndarray) -> np.ndarray:
        """f(q) (n_dof,): belt elastic force + components' K q (preloads excluded), and the running belt's
        centripetal force at speed."""
        p = self.expand(q)
        f = self.belt_force(p) + self.linear_force(p)
        return f if self.arms is None else self.arms.project(q, f)

    def force_and_tangent(self, q: np.ndarray):
        """Internal force (n_dof,) and tangent stiffness K_t = df/dq (dense or CSR). With arms the
        geometric term is that of the internal force alone (see `equilibrium` for the loaded one)."""
        if self.arms is None:
            f, K = self.belt_force_and_tangent(q)
            return f + self.linear_force(q), K
        return self.equilibrium(q, 0.0)

    def external_force(self, load_factor: float = 1.0) -> np.ndarray:
        """(n_p,) the static load case on the joint coordinates: weight and accessory torques."""
        F = load_factor * self.gravity_force
        return F + load_factor * self.loads if self.loads is not None else F

    def equilibrium(self, q: np.ndarray, load_factor: float = 1.0, *, tangent: bool = True, joint: bool = False):
        """r(q) = J^T (f(p) - F) (n_dof,) and its tangent dr/dq: the static residual before the spring
        preloads, F the static load case scaled by load_factor. Without arms r = f - F, dr/dq = K_t.
        tangent=False: (r, None). joint: also p = P(q) (n_p,), (r, dr/dq, p)."""
        p = self.expand(q)
        if not tangent:
            f = self.belt_force(p) + self.linear_force(p) - self.external_force(load_factor)
            r, K = (f if self.arms is None else self.arms.project(q, f)), None
        else:
            f, K = self.belt_force_and_tangent(p)
            f += self.linear_force(p)
            f -= self.external_force(load_factor)
            r, K = (f, K) if self.arms is None else self.arms.project_both(q, f, K, dense=self.dense)
        return (r, K, p) if joint else (r, K)

    def tangent_on_joints(self, q: np.ndarray):
        """The internal force's tangent on the joint coordinates p at P(q) (n_p, n_p)."""
        return self.belt_force_and_tangent(self.expand(q))[1]

    def belt_damping_matrix(self, q: np.ndarray, Ce: np.ndarray):
        """The belt's Kelvin-Voigt damping on the joint coordinates at P(q), from the ANCF elements'
        damping blocks Ce (n_elem, 8, 8) and the spring spans' own (dense or CSR, no components)."""
        blocks = self.belt.reduce_blocks(Ce)
        springs = None if self.springs is None else self.springs.damping_blocks(self.expand(q))
        return self.assemble(blocks, linear=False, springs=springs)

    def project_matrix(self, q: np.ndarray, A):
        """J(q)^T A J(q) for a matrix A on the joint coordinates (A itself without arms)."""
        if self.arms is None:
            return A
        return self.arms.project_matrix(q, A, None, dense=self.dense)

    def mass_matrix(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None):
        """The mass matrix on q at the state q: J^T M J (constant without arms; slopes: the arms'
        `arm_slopes` at q, if at hand)."""
        if self.arms is None:
            return self.mass
        if slopes is None:
            slopes = self.arm_slopes(np.zeros(self.n_dof) if q is None else q)
        return self.arms._project_matrix(slopes, self.mass, None, dense=self.dense)

    def arm_jacobian(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J = dp/dq (n_p, n_dof) dense at q: the identity on q, the arms' slopes dc/dphi in the arm
        columns, from `arm_slopes` (a, 2) if given, else from q on Python floats (`ArmJoints.first`'s
        formula arm by arm: a drive has a few arms)."""
        return self.arms.dense_jacobian(q, slopes=slopes)

    def mean_tension_and_gradient(self, q: np.ndarray, *, gradient: bool = True, p: np.ndarray | None = None
                                  ) -> tuple[float, np.ndarray | None]:
        """Length-weighted mean true axial force over all spans (N), ANCF and spring, and its gradient
        (n_dof,) (None without gradient). p: q on the joint coordinates, if at hand."""
        p = self.expand(q) if p is None else p
        if self.springs is None:
            T, g = self.belt.mean_tension_and_gradient(p)
        else:
            L_b = float(self.belt.elements.length.sum())
            NL, g = self.springs.tension_integral(p, gradient=gradient)
            if L_b > 0.0:
                T_b, g_b = self.belt.mean_tension_and_gradient(p)
                NL, g = NL + T_b * L_b, (g + g_b * L_b if gradient else None)
            total = L_b + float(self.springs.reference_length.sum())
            T, g = NL / total, (g / total if gradient else None)
        if not gradient:
            return T, None
        return T, (g if self.arms is None else self.arms.project(q, g))

    def span_models(self) -> tuple[tuple[str, ...], np.ndarray]:
        """(model of each span: "ancf", "string" or "spring"; elements of each span (n_span,), 0 for a
        spring span), as the system was built."""
        el = self.belt.elements
        models, counts = [], np.array([len(e) for e in self.belt.span_elements], dtype=np.int64)
        for els in self.belt.span_elements:
            if not len(els):
                models.append("spring")
            else:
                models.append("string" if el.curvature == "none" or not np.any(el.EI[els] > 0) else "ancf")
        return tuple(models), counts

    @property
    def EA(self) -> float:
        """The belt's axial stiffness (N): the largest of its elements and springs."""
        ea = [float(self.belt.elements.EA.max(initial=0.0))]
        if self.springs is not None:
            ea.append(self.springs.EA)
        return max(ea)

    def span_end_forces(self, p: np.ndarray, vp: np.ndarray | None, E: np.ndarray | None = None,
                        Ed: np.ndarray | None = None, X: np.ndarray | None = None) -> np.ndarray:
        """(B, n_span, 2, 2) force of each span on its end points for states p, vp (B, n_p) (as
        `BeltSpans.end_forces`; E, Ed the belt's element states, X the spring spans' end positions, if
        at hand)."""
        b = self.belt
        F = None
        if b.elements.n_elem:
            E = b.element_coordinates_batch(p) if E is None else E
            if vp is not None and Ed is None and (b.damping_axial > 0.0 or b.damping_bending > 0.0):
                Ed = b.element_coordinates_batch(vp, offset=False)
            F = b.end_forces(E, Ed, self.gravity)  # (Ed is read with belt damping only)
        if self.springs is not None:
            sp = self.springs
            F = _plus(F, sp.end_forces(sp.positions_batch(p) if X is None else X,
                                       None if vp is None else sp.positions_batch(vp, offset=False), self.gravity))
        return F

    def span_end_tensions(self, p: np.ndarray, F: np.ndarray, E: np.ndarray | None = None,
                          X: np.ndarray | None = None) -> np.ndarray:
        """(B, n_span, 2) tensions at the span ends from their end forces F (`span_end_forces`; E, X as
        there)."""
        T = None
        if self.belt.elements.n_elem:
            T = self.belt.end_tensions(self.belt.element_coordinates_batch(p) if E is None else E, F)
        if self.springs is not None:
            T = _plus(T, self.springs.end_tensions(self.springs.positions_batch(p) if X is None else X, F))
        return T

    def span_end_inertia(self, ap: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) inertia forces of the span-end masses for accelerations ap (B, n_p)."""
        F = None
        if self.belt.elements.n_elem:
            F = self.belt.end_inertia(self.belt.element_coordinates_batch(ap, offset=False))
        if self.springs is not None:
            F = _plus(F, self.springs.end_inertia(self.springs.positions_batch(ap, offset=False)))
        return F

    def joint_reactions(self, q: np.ndarray, *, p: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Static hub loads (n_pulley, 2), N, the force of the belt on each pulley, and span tensions
        (n_span, 2), N, at the start and end of each span, from the joint reactions (exact for the
        discrete equilibrium even where the strain is tiny). p: q on the joint coordinates, if at hand."""
        return self.static_span_outputs(q, p=p, mean=False)[:2]

    def static_span_outputs(self, q: np.ndarray, *, p: np.ndarray | None = None, mean: bool = True
                            ) -> tuple[np.ndarray, np.ndarray, float | None]:
        """`joint_reactions` (hub loads (n_pulley, 2), span tensions (n_span, 2)) and the mean tension
        (`mean_tension_and_gradient`, None without mean) at q, each span's state evaluated once."""
        p = self.expand(q) if p is None else p
        b, sp = self.belt, self.springs
        F = T = None
        NL = L_b = 0.0
        if b.elements.n_elem:
            E = b.element_coordinates(p)[None]
            F = b.end_forces(E, None, self.gravity)[0]
            T = b.end_tensions(E, F[None])[0]
            if mean:
                T_b = b.mean_tension_and_gradient(p)[0]
                L_b = float(b.elements.length.sum())
                NL = T_b * L_b
        else:
            E = None
        if sp is not None:
            F_s, T_s, NL_s = sp.static_ends(p, self.gravity)
            F, T = _plus(F, F_s), _plus(T, T_s)
            NL = NL_s + NL if L_b > 0.0 else NL_s
        hub = F if not self.belt_speed else F + self.span_transport_forces(E, None, self.belt_speed, p=p[None])[0]
        n = self.layout.n
        hub = -(hub[:, 0] + hub[np.arange(-1, len(hub) - 1), 1])[:n]  # span s ends on pulley s + 1
        if not mean:
            return hub, T, None
        if sp is None:
            return hub, T, T_b
        return hub, T, NL / (L_b + float(sp.reference_length.sum()))

    def hub_loads(self, F_end: np.ndarray) -> np.ndarray:
        """(B, n_pulley, 2) force of the belt on each pulley from the span end-node forces."""
        n = self.layout.n
        hub = -F_end[:, :, 0]
        hub[:, 1:] -= F_end[:, :-1, 1]  # span s ends on pulley s + 1
        hub[:, 0] -= F_end[:, -1, 1]
        return hub[:, :n]

    @property
    def arm_statics(self) -> tuple[tuple[int, LinearComponent | None, np.ndarray], ...]:
        """Per tensioner arm: its pulley's index, the arm's spring (the component on the arm angle alone
        with a stiffness; None: none) and the weight (2,) N of what the arm carries (its pulley's
        components' weight on the pulley's offsets at this gravity). Cached."""
        return self._arm_statics

    @functools.cached_property  # (a "_" name: not a field, which `with_belt` and `with_speed` copy)
    def _arm_statics(self) -> tuple[tuple[int, LinearComponent | None, np.ndarray], ...]:
        arms = self.arms
        if arms is None:
            return ()
        out = []
        comps = [(c, c.dofs.tolist()) for c in self.components]
        g = self.gravity
        for d, slot, j in zip(arms.dof.tolist(), arms.slot.tolist(), arms.pulleys):
            spring = next((c for c, cd in comps if cd == [d] and c.stiffness is not None), None)
            weight = np.zeros(2)
            for c, cd in comps:
                if c.weight is not None and (slot in cd or slot + 1 in cd):
                    for i, dd in enumerate(cd):
                        if dd == slot or dd == slot + 1:
                            weight += c.weight[i] * g[dd - slot]
            out.append((j, spring, weight))
        return tuple(out)

    def pulley_centers(self, q: np.ndarray, *, p: np.ndarray | None = None) -> np.ndarray:
        """(n_pulley, 2) the pulley centres at q (m); p: q on the joint coordinates, if at hand."""
        q = self.expand(q) if p is None else p
        c = self.layout.center.copy()
        dirs = self.dofs.trans_dir
        for j, dofs in enumerate(self.dofs.trans_dof):
            if dofs:
                for d, v in zip(dofs, dirs[j]):
                    c[j] += q[d] * v
        return c

    # -------------------------------------------------------------------- energy
    def kinetic_energies(self, shapes: np.ndarray, q: np.ndarray | None = None, *,
                         motion: np.ndarray | None = None, joint: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Kinetic-energy split of shapes (n_modes, n_dof) about the state q by kind and span (motion:
        their element coordinates, joint: the shapes on the joint coordinates p, if at hand).

        Returns E (n_modes, len(ENERGY_KINDS) + 2 n_span) absolute (not normalized): the kinds, then each
        span's motion along its chord, then across it; and the transverse nodal motion b (n_modes, n_elem,
        4; None without elements). The belt's share splits exactly into motion along and across each span's chord
        (M_e = M_s (x) I2); every component's mass counts for its energy kind.
        """
        belt = self.belt
        el = belt.elements
        n_modes, nk = shapes.shape[0], len(ENERGY_KINDS)
        if joint is not None:
            shapes = joint
        elif self.arms is not None:
            shapes = self.arms.expand_motion(np.zeros(self.n_dof) if q is None else q, shapes)
        E = np.zeros((n_modes, nk + 2 * belt.n_span))
        dofs, mass, kind_of = self._energy_components
        if dofs is not None:  # x^T M_c x of every component at once, summed by kind
            x = shapes.take(dofs, axis=1)
            np.matmul(np.matmul(x, mass) * x, kind_of, out=E[:, :nk])
        span = E[:, nk:].reshape(n_modes, 2, belt.n_span)  # (modes, along|across, span), a view of E
        if el.n_elem:
            de = (belt.element_coordinates_batch(shapes, offset=False) if motion is None else motion).reshape(
                n_modes, el.n_elem, 4, 2)
            t = belt.reference_direction[belt.elem_span]
            nrm = belt.reference_normal[belt.elem_span]
            a = np.einsum("kejd,ed->kej", de, t)
            b = np.einsum("kejd,ed->kej", de, nrm)
            Ms = el.mass.reshape(el.n_elem, 4, 2, 4, 2)[:, :, 0, :, 0]
            ka = np.einsum("kei,eij,kej->ke", a, Ms, a)
            kb = np.einsum("kei,eij,kej->ke", b, Ms, b)
            np.add.at(span[:, 0].T, belt.elem_span, ka.T)
            np.add.at(span[:, 1].T, belt.elem_span, kb.T)
        else:  # every span a spring
            b = None
        if self.springs is not None:  # the lumped masses of the spring spans (the other spans: every span is one or the other)
            sp = self.springs
            e = sp.kinetic_energy_split(shapes)  # (k, along|across, modes)
            span[:, :, sp.span_rows] = e.T
        totals = E[:, 2:4]  # (a view: += on it, not on E's slice, which would copy back)
        totals += np.add.reduce(span, axis=2) if el.n_elem else np.add.reduce(e, axis=0).T  # (contiguous e: all springs)
        return E, b

    @functools.cached_property
    def _energy_components(self) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """The components whose mass counts for a kind, side by side: their DOFs (r,), their mass
        matrices block-diagonal (r, r) and each DOF's kind (r, len(ENERGY_KINDS)), 1 in the column of its
        component's kind; Nones without such components."""
        comps = [c for c in self.components if c.mass is not None and c.energy_kind]
        if not comps:
            return None, None, None
        dofs = np.concatenate([c.dofs for c in comps])
        mass, kind_of = np.zeros((len(dofs), len(dofs))), np.zeros((len(dofs), len(ENERGY_KINDS)))
        start = 0
        for c in comps:
            end = start + len(c.dofs)
            mass[start:end, start:end] = c.mass
            kind_of[start:end, ENERGY_KINDS.index(c.energy_kind)] = 1.0
            start = end
        return dofs, mass, kind_of


def _assemble(layout: Layout, dofs: DofMap, belt: BeltSpans, components: tuple[LinearComponent, ...], *,
              pulley_names: tuple[str, ...], driver: int, tension: TensionSetting, gravity: np.ndarray,
              dense: bool | None, loads: np.ndarray | None = None, arms: ArmJoints | None = None,
              friction: np.ndarray | None = None, springs: SpringSpans | None = None) -> System:
    """Pattern, mass, weight and the components' constant matrices of a system."""
    n = dofs.n
    use_dense = n <= DENSE_LIMIT if dense is None else dense
    if springs is not None and not use_dense:  # the spring spans' blocks: entries of the pattern like the components'
        s_rows, s_cols = element_pairs(springs.idx)
    extra = None
    if not use_dense:  # (a dense pattern holds every entry)
        rows, cols = [], []
        if springs is not None:
            live = (s_rows < n) & (s_cols < n)
            rows.append(s_rows[live])
            cols.append(s_cols[live])
        for c in components:
            for mat in (c.stiffness, c.damping, c.mass):
                if mat is not None:
                    r, cc = np.nonzero(mat)
                    rows.append(c.dofs[r])
                    cols.append(c.dofs[cc])
        extra = (np.concatenate(rows), np.concatenate(cols)) if rows else None
    # (dense without elements: nothing to scatter but the springs, which bring their own indices)
    pattern = set_at_once(Pattern, n=n, flat=_NO_INDEX, slot=None, indices=None, indptr=None, diag_slot=None, nnz=0) \
        if use_dense and not len(belt.idx) else \
        make_pattern(belt.idx, n, sparse=not use_dense, extra=extra)
    g = np.asarray(gravity, dtype=float)
    has_elements = belt.elements.n_elem > 0
    weighs = bool(g.any())  # (without gravity the belt's weight is zeros)
    fg = belt.reduce_vector(ancf.gravity_forces(belt.elements, g)) if has_elements and weighs else None
    scatter = None
    if springs is not None:
        if weighs:
            fg = springs.gravity_force(g) if fg is None else fg + springs.gravity_force(g)
        if use_dense:  # row * (n + 1) + column of each block entry (`element_pairs`)
            idx = springs.idx
            scatter = (idx[:, :, None] * (n + 1) + idx[:, None, :]).ravel()
        else:
            scatter = np.full(s_rows.shape, -1, dtype=np.int64)
            scatter[live] = pattern.slots_of(s_rows[live], s_cols[live])
    fg = np.zeros(n) if fg is None else fg
    M = _assembled(n, use_dense, pattern, belt.reduce_blocks(belt.elements.mass) if has_elements else None,
                   None if springs is None else springs.mass_blocks(), scatter, None, None)
    if use_dense:  # the components' matrices added in place, their weights too
        K_lin, C, offset = _add_components(components, n, M, fg, g)
    else:
        from scipy.sparse import csr_matrix

        K_lin, C_lin, M_comp = (_summed_sparse(components, pattern, attr) for attr in ("stiffness", "damping", "mass"))
        if M_comp is not None:  # M is already on the pattern: add the components' entries
            M.data += M_comp
        C = csr_matrix((C_lin, pattern.indices, pattern.indptr), shape=(n, n)) if C_lin is not None else None
        offset = None
        for c in components:
            if c.free is not None and c.stiffness is not None:
                offset = np.zeros(n) if offset is None else offset
                offset[c.dofs] += c.stiffness @ np.asarray(c.free, dtype=float)
            if c.weight is not None:
                fg[c.dofs] += c.weight @ g
    return set_at_once(System, layout=layout, dofs=dofs, belt=belt, components=components, pulley_names=pulley_names,
                        driver=driver, tension=tension, gravity=g, dense=use_dense, pattern=pattern, mass=M,
                        gravity_force=fg, linear_stiffness=K_lin, linear_damping=C, linear_offset=offset, loads=loads,
                        arms=arms, pulley_friction=friction, belt_speed=0.0, springs=springs, spring_scatter=scatter)


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


# ------------------------------------------------------------------------------------ building
def build_belt(cfg: DriveConfig, layout: Layout, dofs: DofMap, *,
               prestrain_stretch: float | np.ndarray = 1.0) -> BeltSpans:
    """Mesh each span and join its end nodes to the pulleys (constant-Jacobian joints).

    Span s gets cfg.span_elements[s] elements (none for a spring span: `build_springs`); a "string"
    span's elements have no bending stiffness (EI = 0).
    prestrain_stretch: the stretch of the spans at q = 0 (chord length / reference length), one
    number for all spans or one per span (n_span,)."""
    n_p = layout.n
    n_dof = dofs.n
    pad = n_dof
    lam_s = _span_stretch(prestrain_stretch, n_p)
    L_ref = layout.span_length / lam_s
    if isinstance(prestrain_stretch, (float, int)):  # (one number: uniform)
        lam = float(prestrain_stretch)
    else:
        lam_list = lam_s.tolist()
        uniform = lam_list.count(lam_list[0]) == n_p  # (the sums by np.add.reduce: ndarray.sum's own)
        lam = lam_list[0] if uniform else float(np.add.reduce(layout.span_length) / np.add.reduce(L_ref))
    t_dir = layout.span_direction
    n_elem = sum(cfg.span_elements)
    if n_elem == 0:  # every span a spring (`build_springs`): no elements, no joints of the belt's own
        return set_at_once(BeltSpans, elements=span_element_set(cfg, _NO_ELEMENT, _NO_ELEMENT), elem_span=_NO_INDEX,
                            span_elements=(_NO_INDEX,) * n_p, T=_NO_T, idx=_NO_IDX, tsel=_NO_INDEX, e0=_NO_E,
                            n_dof=n_dof, reference_length=L_ref, reference_direction=t_dir, prestrain_stretch=lam,
                            span_stretch=lam_s, damping_axial=0.0, damping_bending=0.0, compiled=False)
    counts = np.array(cfg.span_elements, dtype=np.int64)  # (n_span,) elements of each span
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
                          np.repeat([cfg.belt.EI if m == "ancf" else 0.0 for m in cfg.span_models], counts))
    return BeltSpans(elements=el, elem_span=elem_span, span_elements=span_elements, T=T, idx=idx,
                     tsel=joint_selection(T, idx, n_dof), e0=e0, n_dof=n_dof, reference_length=L_ref,
                     reference_direction=t_dir, prestrain_stretch=lam, span_stretch=lam_s)


def joint_pairs(layout: Layout, dofs: DofMap, s: int, side: int) -> list[tuple[int, np.ndarray]]:
    """The joint of span s's start (side 0, on pulley s) or end (side 1, on pulley s + 1): the
    (joint coordinate, d r_end / d coordinate (2,)) pairs, r_end = c + R n + R theta (z x n) + u."""
    j = s if side == 0 else (s + 1) % layout.n
    normal = layout.start_normal[s] if side == 0 else layout.end_normal[s]
    pairs = [(int(dofs.rot_dof[j]), layout.radius[j] * _z_cross(normal))]
    return pairs + list(zip(dofs.trans_dof[j], dofs.trans_dir[j]))


@functools.lru_cache(maxsize=8)
def _no_elements(EA: float, rho: float, curvature: str, n_gauss: int) -> ancf.ElementSet:
    """An empty element set (every span a spring), its tables of the right shapes (read-only, shared)."""
    one = ancf.make_elements(np.ones(1), EA, 0.0, rho, curvature=curvature, n_gauss=n_gauss)
    return ancf.subset(one, np.zeros(0, dtype=np.int64))


def span_element_set(cfg: DriveConfig, length: np.ndarray, EI: np.ndarray) -> ancf.ElementSet:
    """The ANCF elements of the flexible spans: lengths and bending stiffnesses (n_elem,); the tables
    computed once per distinct (length, EI) and gathered. The bending law is model.curvature
    ("linear" when that is "none" but a span asks for "ancf"); without an "ancf" span, none. No
    elements (every span a spring): an empty set."""
    curvature = cfg.model.curvature
    if "ancf" in cfg.span_models:
        curvature = curvature if curvature != "none" else "linear"
    else:
        curvature = "none"
    b = cfg.belt
    if len(length) == 0:
        return _no_elements(float(b.EA), float(b.mass_per_length), curvature, cfg.model.gauss_points)
    # the distinct (length, EI) pairs: one complex key each (exact; np.unique's 1-D path, not its slow axis=0)
    uniq, inverse = np.unique(np.asarray(length, dtype=float) + 1j * np.asarray(EI, dtype=float), return_inverse=True)
    if len(uniq) == len(length):  # every element distinct: no gathering
        uniq, inverse = np.asarray(length, dtype=float) + 1j * np.asarray(EI, dtype=float), None
    base = ancf.make_elements(uniq.real.copy(), b.EA, uniq.imag.copy(), b.mass_per_length, curvature=curvature,
                              n_gauss=cfg.model.gauss_points)
    return base if inverse is None else ancf.subset(base, inverse.ravel())


def pulley_components(cfg: DriveConfig, dofs: DofMap, layout: Layout | None = None, *,
                      spring_free: np.ndarray | None = None, parts: "PulleyParts | None" = None
                      ) -> tuple[LinearComponent, ...]:
    """Pulley inertia (rotation DOFs), pulley mass and weight (translation DOFs, paper Eq. 20), the
    bearing springs (Eq. 21): only on the DOFs the supports allow; and each tensioner arm's inertia,
    torsion spring and viscous damper on its angle (the arm pulley's mass sits on its dependent
    centre offsets: its m l^2 comes through the arm kinematics).

    spring_free (n_dof,): the value of each translation DOF at which its bearing spring is relaxed
    (None: 0, the pulley at its layout centre). A layout whose pulleys sit displaced from their given
    centres (`geometry.relay`) anchors the springs at the given centres with it. parts: the
    configuration's own share (`pulley_parts` of cfg and dofs), if at hand."""
    fixed, bearing, own = pulley_parts(cfg, dofs) if parts is None else parts
    out = list(fixed)
    if bearing is not None:
        d, K, supported, names = bearing
        free = None if spring_free is None or not np.any(spring_free[d]) else np.asarray(spring_free, dtype=float)[d]
        out.append(BearingSprings(name="bearing springs", dofs=d, stiffness=K, free=free, pulleys=supported,
                                  pulley_names=names))
    for sup, first, j in own:
        out += sup.own_components(first, layout, j, spring_free)
    return tuple(out)


_MASS_NAMES = {"translational": "pulley mass", "tensioner": "arm pulley mass"}  # the pulley mass components' names


def _diagonal(values: list) -> np.ndarray:
    """np.diag(values) of floats (k, k) without its generic set-up."""
    k = len(values)
    out = np.zeros((k, k))
    out.ravel()[:: k + 1] = values
    return out


PulleyParts = tuple  # (fixed components, bearing springs' (dofs, K, pulleys, names) or None, ((support, first DOF, j), ...))


def pulley_parts(cfg: DriveConfig, dofs: DofMap) -> PulleyParts:
    """What `pulley_components` takes from the configuration alone: the pulley inertia and the pulleys'
    masses (components), the bearing springs' DOFs (k,), stiffness (k, k), pulleys and their names (None
    without any), and the supports with own components (support, its first DOF, pulley index)."""
    pulleys = cfg.pulleys
    fixed: list[LinearComponent] = [set_at_once(
        LinearComponent, name="pulley inertia", dofs=dofs.rot_dof, stiffness=None, damping=None,
        mass=_diagonal([p.inertia for p in pulleys]), weight=None, free=None, energy_kind="rotational")]
    masses: dict[str, tuple[list, list, list]] = {}  # energy kind -> translational DOFs, masses, weights
    t_dofs, k_spring, supported = [], [], []
    own = []
    for j, (p, t_dof) in enumerate(zip(pulleys, dofs.trans_dof)):
        if not t_dof and SUPPORT_CLASSES[p.support] is Support:  # a fixed centre: nothing of its own (its mass
            if "translational" not in masses:  # kind still takes its place in the order)
                masses["translational"] = ([], [], [])
            continue
        sup = support_of(p)
        d_m, m_m, w_m = masses.setdefault(sup.mass_kind, ([], [], []))
        if t_dof:
            d_m += t_dof
            for vx, vy in dofs.trans_dir[j].tolist():  # (floats: a direction or two)
                m_m.append(p.mass * (vx * vx + vy * vy))  # m |v|^2 (1 for the unit directions)
                w_m.append((p.mass * vx, p.mass * vy))
        springs = sup.springs()
        if springs:
            t_dofs += t_dof
            k_spring += springs
            supported.append(j)
        if sup.independent():
            own.append((sup, t_dof[0] if t_dof and not sup.translation_is_dependent() else int(dofs.arm_dof[j]), j))
    for kind, (d_m, m_m, w_m) in masses.items():
        if d_m:
            fixed.append(set_at_once(LinearComponent, name=_MASS_NAMES.get(kind) or f"{kind} pulley mass",
                                      dofs=np.array(d_m, dtype=np.int64), stiffness=None, damping=None,
                                      mass=_diagonal(m_m), weight=np.array(w_m), free=None, energy_kind=kind))
    bearing = None
    if t_dofs:
        bearing = (np.array(t_dofs, dtype=np.int64), _diagonal(k_spring), tuple(supported),
                   tuple(pulleys[j].name for j in supported))
    return tuple(fixed), bearing, tuple(own)


def arm_joints(cfg: DriveConfig, layout: Layout, dofs: DofMap, *, like: ArmJoints | None = None) -> ArmJoints | None:
    """The arms' kinematics about the layout's arm angles (None without arms). like: the same drive's
    arms on another layout (what the configuration fixes taken from it)."""
    if like is not None:
        length, angle = _arm_geometry(cfg, layout, like.pulleys, like.pivot.tolist())
        return set_at_once(ArmJoints, dof=like.dof, slot=like.slot, pivot=like.pivot, length=length, angle=angle,
                            n_q=like.n_q, n_p=like.n_p, friction=like.friction, stops=like.stops, names=like.names,
                            pulleys=like.pulleys)
    arms = [j for j, p in enumerate(cfg.pulleys) if p.support == "arm"]
    if not arms:
        return None
    ps = [cfg.pulleys[j] for j in arms]
    pivots = [p.arm_pivot for p in ps]
    length, angle = _arm_geometry(cfg, layout, arms, pivots)
    return set_at_once(ArmJoints, dof=dofs.arm_dof[arms],
                        slot=np.array([dofs.trans_dof[j][0] for j in arms], dtype=np.int64),
                        pivot=np.array(pivots, dtype=float), length=length, angle=angle, n_q=dofs.n_q, n_p=dofs.n,
                        friction=np.array([p.arm_friction for p in ps], dtype=float),
                        stops=np.array([p.arm_range or (np.nan, np.nan) for p in ps], dtype=float),
                        names=tuple(p.name for p in ps), pulleys=tuple(arms))


def _arm_geometry(cfg: DriveConfig, layout: Layout, arms, pivots: list) -> tuple[np.ndarray, np.ndarray]:
    """The arms' lengths |c - pivot| and working angles (a,) on a layout (pulley indices arms, pivots [(x, y)]),
    arm by arm on floats."""
    center = layout.center.tolist()
    length, angle = [], []
    for j, (px, py) in zip(arms, pivots):
        x, y = center[j]
        length.append(np.hypot(x - px, y - py))
        angle.append(support_of(cfg.pulleys[j]).angle_at(x, y))  # (its `working_angle`)
    return np.array(length), np.array(angle)


def static_loads(cfg: DriveConfig, dofs: DofMap) -> np.ndarray | None:
    """(n_p,) the accessory torques of [[static.torque]] on the pulley rotations (None if none)."""
    if not cfg.static.torque:
        return None
    F = [0.0] * dofs.n  # (floats: a few entries)
    names, rot = [p.name for p in cfg.pulleys], dofs.rot_dof.tolist()
    for tq in cfg.static.torque:
        F[rot[names.index(tq.pulley)]] += tq.value
    return np.array(F)


def reference_stretch(cfg: DriveConfig, layout: Layout) -> float:
    """The spans' stretch at q = 0 that the tension mode asks for (1: stress-free)."""
    target = cfg.tension.target
    if target is not None and cfg.tension.mode == "prestrain":
        return stretch_for_tension(target, cfg.belt.EA)
    if target is None and cfg.adjustable_index is None:
        lam = layout.belt_length / cfg.belt.length  # the belt of length L0 stretched onto the path
        if lam < 1.0:
            raise ConfigError(
                f"the belt is {cfg.belt.length - layout.belt_length:.6g} m longer than its path "
                f"({layout.belt_length:.6g} m): it is slack; set tension.target or make a pulley adjustable",
                file=cfg.source, key="belt.length")
        return lam
    return 1.0


BYTES_PER_DOF = 10_000  # a generous bound on the memory of static + modal + transient per DOF (bench: ~4.4 kB)


@functools.lru_cache(maxsize=1)
def memory_limit() -> int:
    """Bytes this process may use: the smaller of the physical memory and a cgroup (container) limit."""
    limit = 1 << 62
    try:
        limit = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        pass
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = open(path).read().strip()
        except OSError:
            continue
        if text.isdigit():
            limit = min(limit, int(text))
    return limit


def model_dofs(cfg: DriveConfig) -> int:
    """The DOF count of a configuration's model, known before anything is built: per span 4 per
    element (the interior nodes and the end slopes) and 3 per pulley (rotation and translations, at most)."""
    return 3 * len(cfg.pulleys) + 4 * sum(cfg.span_elements)


def check_model_size(cfg: DriveConfig) -> None:
    """A mesh whose model cannot fit in memory is a configuration error before any work (exit 2),
    not a run that is killed or fails after minutes."""
    n_e = max(cfg.span_elements)
    n_dof = model_dofs(cfg)
    need = n_dof * BYTES_PER_DOF
    have = memory_limit()
    if need > 0.5 * have:
        most = max(1, int((0.5 * have / BYTES_PER_DOF / len(cfg.pulleys) - 3) // 4))
        raise ConfigError(f"{n_e} elements per span make a model of {n_dof:,} DOFs, about {need / 1e9:.3g} GB: more "
                          f"than half of this machine's {have / 1e9:.3g} GB; use at most {most:,} elements per span",
                          file=cfg.source, key="mesh.elements_per_span")


@dataclass(frozen=True, kw_only=True)
class DriveFacts:
    """What a build takes from the configuration alone, whatever the layout: computed once per analysis
    (`drive_facts`), by `DeferredSystem`, and handed to each `build_system` of that analysis (not kept
    across analyses). arms: the arms on `layout`, the L0 fit (`arm_joints`; the builds on other layouts
    take what the configuration fixes from them)."""

    layout: Layout
    dofs: DofMap
    tension: TensionSetting
    loads: np.ndarray | None  # (n_p,) `static_loads`
    friction: np.ndarray  # (n_pulley,) belt-pulley friction coefficients, NaN if not given
    pulley_names: tuple[str, ...]
    gravity: np.ndarray  # (2,) m/s^2
    pulleys: PulleyParts  # `pulley_parts`
    arms: ArmJoints | None


def drive_facts(cfg: DriveConfig, layout: Layout) -> DriveFacts:
    """The `DriveFacts` of a configuration (`layout`: its L0 fit, where the arms are taken)."""
    dofs = number_dofs(cfg)
    pulleys = cfg.pulleys
    return set_at_once(DriveFacts, layout=layout, dofs=dofs, tension=tension_setting(cfg, dofs),
                        loads=static_loads(cfg, dofs),
                        friction=np.array([np.nan if p.friction is None else p.friction for p in pulleys]),
                        pulley_names=tuple([p.name for p in pulleys]), gravity=np.asarray(cfg.model.gravity, dtype=float),
                        pulleys=pulley_parts(cfg, dofs), arms=arm_joints(cfg, layout, dofs))


def build_system(cfg: DriveConfig, layout: Layout | None = None, *,
                 prestrain_stretch: float | np.ndarray | None = None, spring_free: np.ndarray | None = None,
                 dense: bool | None = None, extra: tuple[LinearComponent, ...] = (),
                 belt_speed: float | None = None, facts: DriveFacts | None = None) -> System:
    """The one place a system is built from a configuration: geometry, DOFs, belt, pulleys, springs.

    layout: the belt path (default: the L0 fit of the configuration); prestrain_stretch: the spans'
    stretch at q = 0, one number or one per span (default: what the tension mode asks for,
    `reference_stretch`); spring_free (n_dof,): where the bearing springs are relaxed (default: the
    layout's centres; see `pulley_components`); belt_speed (m/s): the running belt's speed (default:
    [running] of the configuration, `running.belt_speed_of`); facts: the configuration's `DriveFacts`,
    if at hand (one analysis's builds share them)."""
    if facts is None:
        check_model_size(cfg)
        layout = layout or layout_from_config(cfg)
        facts = drive_facts(cfg, layout)
    layout = layout or layout_from_config(cfg)
    lam = reference_stretch(cfg, layout) if prestrain_stretch is None else prestrain_stretch
    dofs = facts.dofs
    arms = facts.arms
    if arms is not None and layout is not facts.layout:
        arms = arm_joints(cfg, layout, dofs, like=arms)
    belt = build_belt(cfg, layout, dofs, prestrain_stretch=lam)
    springs = build_springs(cfg, layout, dofs, prestrain_stretch=lam, direction=belt.reference_direction,
                            reference_length=belt.reference_length)
    system = _assemble(layout, dofs, belt, pulley_components(cfg, dofs, layout, spring_free=spring_free,
                                                             parts=facts.pulleys) + tuple(extra),
                       pulley_names=facts.pulley_names, driver=cfg.driver_index, tension=facts.tension,
                       gravity=facts.gravity, dense=dense, loads=facts.loads, arms=arms, friction=facts.friction,
                       springs=springs)
    if belt_speed is None:
        belt_speed = belt_speed_of(cfg, layout)
    return system.with_speed(belt_speed) if belt_speed else system


def tension_setting(cfg: DriveConfig, dofs: DofMap) -> TensionSetting:
    """How the configuration sets the tension, on the DOF map."""
    target = cfg.tension.target
    adjust = target is not None and cfg.tension.mode == "adjust"
    a = cfg.adjustable_index
    adjust_dof = -1
    adjust_range = None
    if a is not None:  # the adjustable pulley's first own DOF (a slide's offset, an arm's angle) sets the tension
        sup = support_of(cfg.pulleys[a])
        if adjust:
            adjust_dof = int(dofs.arm_dof[a]) if dofs.arm_dof[a] >= 0 else int(dofs.trans_dof[a][0])
        adjust_range = sup.travel_limits()
    mode = "spring" if cfg.tension.mode == "spring" else (cfg.tension.mode if target is not None else "geometry")
    return set_at_once(TensionSetting, target=target, mode=mode, adjust_dof=adjust_dof, adjust_range=adjust_range,
                        adjust_name=cfg.pulleys[a].name if a is not None else "")


class DeferredSystem:
    """The drive on a layout whose full build waits until something needs it: `pipeline.analyse` hands
    this to the static analysis, which lays the belt out anew at the predicted solved positions and
    usually never solves on the L0 fit. Cheap facts (tension, DOF map, layout, arms, the belt's
    reference lengths, stretch and EA) come without a build; anything else builds (`full`)."""

    def __init__(self, cfg: DriveConfig, layout: Layout, build, *, facts: DriveFacts | None = None) -> None:
        """facts: the configuration's `DriveFacts` on this layout (default: computed here); the `facts`
        attribute either way, for the builds of the same analysis."""
        from types import SimpleNamespace

        facts = drive_facts(cfg, layout) if facts is None else facts
        dofs = facts.dofs
        lam = reference_stretch(cfg, layout)
        self.__dict__.update({  # the facts as plain attributes (`__getattr__` only for the rest)
            "layout": layout, "dofs": dofs, "tension": facts.tension, "arms": facts.arms,
            "trans_dof": dofs.trans_dof, "trans_dir": dofs.trans_dir, "rot_dof": dofs.rot_dof,
            "loads": facts.loads, "driver": cfg.driver_index, "driver_dof": int(dofs.rot_dof[cfg.driver_index]),
            "belt": SimpleNamespace(reference_length=layout.span_length / lam, prestrain_stretch=float(lam),
                                    span_stretch=None, elements=SimpleNamespace(EA=np.array([cfg.belt.EA]))),
            "EA": float(cfg.belt.EA), "dof_labels": dofs.labels[: dofs.n_q],
            "pulley_friction": facts.friction, "pulley_index": facts.pulley_names.index, "facts": facts,
        })
        self._build, self._full, self._cfg = build, None, cfg

    @property
    def built(self) -> bool:
        return self._full is not None

    def full(self) -> System:
        if self._full is None:
            self._full = self._build(self.layout)
        return self._full

    def __getattr__(self, name: str):  # (only for what __init__ did not set)
        if name in ("_build", "_full", "_cfg"):  # (its own state, before __init__ set it: no build)
            raise AttributeError(name)
        if name == "components":  # the pulleys' own components: cheap, no belt
            self.components = pulley_components(self._cfg, self.dofs, self.layout, parts=self.facts.pulleys)
            return self.components
        return getattr(self.full(), name)


__all__ = ["System", "DofMap", "BeltSpans", "SpringSpans", "build_springs", "TensionSetting",
           "build_system", "DriveFacts", "drive_facts", "number_dofs", "element_pairs", "DENSE_LIMIT"]
