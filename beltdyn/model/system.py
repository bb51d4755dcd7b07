"""The drive as a system of components: one DOF map, components that own DOFs and contribute; its
build from a configuration (`build_system`, `drive_facts`) and the drive before its build
(`DeferredSystem`).

Nomenclature: q (n_dof,) the independent coordinates and p (n_p,) the joint coordinates (`dofs`);
element coordinates e = e0 + T p[idx] through the span-pulley joints (`belt`); components (`components`,
`pulleys`); the assembly pattern (`assembly`); tensioner arms p = P(q), J = dP/dq (`arms`). Static
residual r(q) = J^T (f(P(q)) - F), f the internal force (belt + K_c p - K_c free_c), F the load case
(weight W g and accessory torques); mass J^T M J; running belt at speed c: gyroscopic c J^T (A - A^T) J,
centripetal stiffness -c^2 B and force -c^2 (B p + b0) (`RunningTerms`).

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

import dataclasses
import functools
import os
from dataclasses import dataclass, field

import numpy as np

from beltdyn.model import ancf
from beltdyn.config import DriveConfig, resolved_spans
from beltdyn.errors import ConfigError
from beltdyn.model.components import ENERGY_KINDS, LinearComponent, arm_spring, belt_rotation_rates
from beltdyn.model.pulleys import PulleyParts, pulley_components, pulley_parts
from beltdyn.model.barlaw import bar_law
from beltdyn.model.geometry import Layout, layout_from_config
from beltdyn.model.geometry import belt_speed_of
from beltdyn.model.supports import support_of
from beltdyn.model.arms import ArmFolding, ArmJoints, arm_folding, arm_joints
from beltdyn.model.assembly import (DENSE_LIMIT, NO_INDEX, Pattern, assemble_blocks, component_entries,
                                    component_nonzeros, component_sums, element_pairs, make_pattern)
from beltdyn.model.belt import BeltSpans, build_belt, empty_element_set, plus
from beltdyn.model.dofs import DofMap, number_dofs
from beltdyn.model.reuse import Reuse
from beltdyn.model.springs import SpringSpans, build_springs, spring_joints
from beltdyn.model.wraps import WrapModel


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


@dataclass(frozen=True, kw_only=True)
class RunningTerms:
    """The running belt's transport terms per unit speed (`BeltSpans.transport_blocks`, `SpringSpans.
    transport_blocks`) on the joint coordinates: A, B (dense (n_p, n_p) or CSR) and a0, b0 (n_p,), so
    that the gyroscopic matrix is c (A - A^T), the centripetal stiffness -c^2 B and the centripetal force
    -c^2 (B p + b0); element_A, element_B (n_elem, 8, 8) the ANCF elements' own, blocks_B (n_elem, m, m)
    their T^T B_e T and spring_blocks_B (k, m_s, m_s) the spring spans' (None without)."""

    A: object
    B: object
    a0: np.ndarray
    b0: np.ndarray
    element_A: np.ndarray
    element_B: np.ndarray
    blocks_B: np.ndarray
    spring_blocks_B: np.ndarray | None = None


EnergyComponents = tuple  # (DOFs (r,), block-diagonal mass (r, r), kind of each DOF (r, len(ENERGY_KINDS))) or Nones
ArmStatics = tuple  # per arm: (pulley index, its spring (LinearComponent or None), carried weight (2,) N)


class DofNames:
    """The DOF map's names a `System` and a `DeferredSystem` share (both hold `dofs` and `driver`)."""

    dofs: DofMap
    driver: int

    @property
    def n_dof(self) -> int:
        """The independent coordinates q."""
        return self.dofs.n_q

    @property
    def n_p(self) -> int:
        """The joint coordinates p (q and the arm pulleys' centre offsets)."""
        return self.dofs.n

    @property
    def dof_labels(self) -> tuple[str, ...]:
        return self.dofs.labels[: self.dofs.n_q]

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


@dataclass(frozen=True, kw_only=True)
class System(DofNames):
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
    wraps: WrapModel | None = None  # the belt on the pulleys (belt.wraps, belt.axial_law); None: creep, green-lagrange
    spring_scatter: np.ndarray | None = None  # (k m m,) where the springs' blocks go: flat (dense) or CSR slot
    arm_folding: ArmFolding | None = None  # the sparse pattern folded onto q (`arms.arm_folding`), with arms and CSR
    # derived in the constructor (`__post_init__`), never passed: the running belt's terms (at speed only,
    # None at rest), the components' stiffness as a CSR matrix (sparse only), the mode classification's
    # component masses, the tensioner arms' statics
    running_terms: RunningTerms | None = field(init=False, repr=False, compare=False)
    linear_csr: object = field(init=False, repr=False, compare=False)
    energy_components: EnergyComponents = field(init=False, repr=False, compare=False)
    arm_statics: ArmStatics = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        derived = {"running_terms": self._running_terms() if self.belt_speed else None,
                   "linear_csr": None if self.dense else self.pattern.matrix(
                       self.linear_stiffness if self.linear_stiffness is not None else np.zeros(self.pattern.nnz)),
                   "energy_components": self._energy_components(), "arm_statics": self._arm_statics()}
        for name, value in derived.items():  # (a frozen dataclass: its derived fields set once, here)
            object.__setattr__(self, name, value)

    # The belt, the components, mass, pattern, gravity_force, loads and the linear matrices live on the
    # joint coordinates p (n_p); the analyses see the independent q (n_dof). Without arms p = q.

    # -------------------------------------------------------------------- names kept from the model
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

    def pulley_index(self, name: str) -> int:
        return self.pulley_names.index(name)

    def with_components(self, *extra: LinearComponent) -> "System":
        """A system with more components (matrices and pattern rebuilt)."""
        out = assemble_system(self.layout, self.dofs, self.belt, self.components + tuple(extra),
                              pulley_names=self.pulley_names, driver=self.driver, tension=self.tension,
                              gravity=self.gravity, dense=self.dense, loads=self.loads, arms=self.arms,
                              friction=self.pulley_friction, springs=self.springs, belt_speed=self.belt_speed,
                              wraps=self.wraps)
        return out

    def with_belt(self, **changes) -> "System":
        """The same system with belt fields changed (e.g. damping_axial, compiled); the spring spans
        take the axial damping too."""
        belt = dataclasses.replace(self.belt, **changes)
        springs = self.springs
        if springs is not None and "damping_axial" in changes:
            springs = dataclasses.replace(springs, damping_axial=float(changes["damping_axial"]))
        return dataclasses.replace(self, belt=belt, springs=springs)

    def with_belt_damping(self, axial: float, bending: float) -> "System":
        return self.with_belt(damping_axial=float(axial), damping_bending=float(bending))

    def with_speed(self, belt_speed: float) -> "System":
        """The same drive with its belt running at belt_speed (m/s; see `running`)."""
        return dataclasses.replace(self, belt_speed=float(belt_speed))

    # -------------------------------------------------------------------- the running belt
    def transport_matrices(self):
        """(A, B, a0, b0) of the running belt per unit speed on the joint coordinates (dense (n_p, n_p) or
        CSR; `RunningTerms`): the gyroscopic matrix is c (A - A^T), the centripetal stiffness -c^2 B, the
        centripetal force -c^2 (B p + b0). Held by a running system, computed anew at rest."""
        t = self.running_terms if self.running_terms is not None else self._running_terms()
        return t.A, t.B, t.a0, t.b0

    def _running_terms(self) -> RunningTerms:
        A_e, B_e = self.belt.transport_element_matrices()
        Ab, Bb, a0, b0 = self.belt.transport_blocks(A_e, B_e)
        sp = self.springs
        if sp is None:
            return RunningTerms(A=self.assemble(Ab, linear=False), B=self.assemble(Bb, linear=False), a0=a0, b0=b0,
                                element_A=A_e, element_B=B_e, blocks_B=Bb)
        As, Bs, a0s, b0s = sp.transport_blocks()  # + the spring spans' (their blocks on the same coordinates)
        return RunningTerms(A=self.assemble(Ab, linear=False, springs=As), B=self.assemble(Bb, linear=False, springs=Bs),
                            a0=a0 + a0s, b0=b0 + b0s, element_A=A_e, element_B=B_e, blocks_B=Bb, spring_blocks_B=Bs)

    def centripetal_force(self, p: np.ndarray) -> np.ndarray:
        """-c^2 (B p + b0) (n_p,) at the joint coordinates p: the running belt's centripetal term of the
        internal force, the gradient of the centripetal potential V = -c^2/2 sum_e e^T B_e e (the force on
        the belt is its negative, outward along the spans' ends: the momentum flux)."""
        belt = self.belt
        c = self.belt_speed
        f = self.springs.centripetal_force(p, c) if self.springs is not None else 0.0
        if not belt.elements.n_elem:
            return f if self.springs is not None else np.zeros(self.n_p)
        B_e = (self.running_terms or self._running_terms()).element_B
        e = belt.element_coordinates(p)
        return f - (c * c) * belt.reduce_vector(np.matmul(B_e, e[:, :, None])[:, :, 0])

    def _running_blocks(self, blocks: np.ndarray) -> np.ndarray:
        """The element tangent blocks (n_elem, m, m) with the centripetal stiffness -c^2 T^T B_e T added."""
        return blocks - (self.belt_speed * self.belt_speed) * self.running_terms.blocks_B

    def _running_spring_blocks(self, blocks: np.ndarray) -> np.ndarray:
        """The spring spans' tangent blocks (k, m, m) with their centripetal stiffness -c^2 T^T B_s T."""
        return blocks - (self.belt_speed * self.belt_speed) * self.running_terms.spring_blocks_B

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
        return assemble_blocks(self.pattern, blocks, springs if self.springs is not None else None,
                               self.spring_scatter, self.linear_stiffness if linear else None, diagonal)

    def linear_force(self, q: np.ndarray) -> np.ndarray:
        """The components' force K p - offset (joint coordinates p)."""
        if self.linear_stiffness is None:
            return np.zeros(self.n_p)
        f = (self.linear_stiffness if self.dense else self.linear_csr) @ q
        return f - self.linear_offset if self.linear_offset is not None else f

    def linear_matrix(self):
        """The components' constant stiffness as a matrix (dense or CSR), zeros if none."""
        if self.dense:
            return self.linear_stiffness if self.linear_stiffness is not None else np.zeros((self.n_p, self.n_p))
        return self.linear_csr

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
            t = self.running_terms or self._running_terms()
            F = self.belt.on_spans(self.belt.transport_end_forces(E, Ed, speed, acceleration,
                                                                  matrices=(t.element_A, t.element_B)))
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
        """(n_p,) the static load case on the joint coordinates: weight and accessory torques, and at speed
        the components' damping forces -C v_run at the steady running velocity (`running_damping_force`)."""
        F = load_factor * self.gravity_force
        F = F + load_factor * self.loads if self.loads is not None else F
        return F - load_factor * self.running_damping_force() if self.belt_speed else F

    def running_damping_force(self) -> np.ndarray:
        """(n_p,) C v_run: the components' damping forces at the steady running velocity v_run = belt_speed
        times `belt_rotation_rates` (the pulleys turning at omega_j = +-v / R_j; a pulley's
        rotational_damping d gives d omega); 0 at rest or without damping components."""
        if not self.belt_speed or self.linear_damping is None:
            return np.zeros(self.n_p)
        v_run = self.belt_speed * belt_rotation_rates(self.layout, self.rot_dof, self.n_p, self.dofs.rotor_dof)
        return np.asarray(self.linear_damping @ v_run, dtype=float).ravel()

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
            r, K = (f, K) if self.arms is None else self.arms.project_both(q, f, K, dense=self.dense,
                                                                       folding=self.arm_folding)
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
        return self.arms.project_matrix(q, A, None, dense=self.dense, folding=self.arm_folding)

    def mass_matrix(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None):
        """The mass matrix on q at the state q: J^T M J (constant without arms; slopes: the arms'
        `arm_slopes` at q, if at hand)."""
        if self.arms is None:
            return self.mass
        if slopes is None:
            slopes = self.arm_slopes(np.zeros(self.n_dof) if q is None else q)
        return self.arms.project_matrix_at(slopes, self.mass, dense=self.dense, folding=self.arm_folding)

    def arm_jacobian(self, q: np.ndarray | None = None, *, slopes: np.ndarray | None = None) -> np.ndarray:
        """J = dp/dq (n_p, n_dof) dense at q: the identity on q, the arms' slopes dc/dphi in the arm
        columns, from `arm_slopes` (a, 2) if given, else from q (`ArmJoints.first`)."""
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
            F = plus(F, sp.end_forces(sp.positions_batch(p) if X is None else X,
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
            T = plus(T, self.springs.end_tensions(self.springs.positions_batch(p) if X is None else X, F))
        return T

    def span_end_inertia(self, ap: np.ndarray) -> np.ndarray:
        """(B, n_span, 2, 2) inertia forces of the span-end masses for accelerations ap (B, n_p)."""
        F = None
        if self.belt.elements.n_elem:
            F = self.belt.end_inertia(self.belt.element_coordinates_batch(ap, offset=False))
        if self.springs is not None:
            F = plus(F, self.springs.end_inertia(self.springs.positions_batch(ap, offset=False)))
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
            F, T = plus(F, F_s), plus(T, T_s)
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

    def arm_spring(self, dof: int) -> LinearComponent | None:
        """The torsion spring of the tensioner arm on the angle `dof` (`components.arm_spring`)."""
        return arm_spring(self.components, dof)

    def _arm_statics(self) -> ArmStatics:
        """Per tensioner arm: its pulley's index, the arm's spring (`arm_spring`; None: none) and the weight
        (2,) N of what the arm carries (its pulley's components' weight on the pulley's offsets at this
        gravity): the field `arm_statics`."""
        arms = self.arms
        if arms is None:
            return ()
        out = []
        comps = [(c, c.dofs.tolist()) for c in self.components]
        g = self.gravity
        for d, slot, j in zip(arms.dof.tolist(), arms.slot.tolist(), arms.pulleys):
            spring = self.arm_spring(d)
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
        dofs, mass, kind_of = self.energy_components
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

    def _energy_components(self) -> EnergyComponents:
        """The field `energy_components`: the components whose mass counts for a kind, side by side: their DOFs (r,), their mass
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


# ------------------------------------------------------------------------------------ building


def static_loads(cfg: DriveConfig, dofs: DofMap) -> np.ndarray | None:
    """(n_p,) the accessory torques of [[static.torque]] on the pulley rotations, a decoupler's on its rotor
    (None if none)."""
    if not cfg.static.torque:
        return None
    names = [p.name for p in cfg.pulleys]
    at = dofs.torque_dof[[names.index(tq.pulley) for tq in cfg.static.torque]]
    return np.bincount(at, weights=[tq.value for tq in cfg.static.torque], minlength=dofs.n).astype(float)


MAX_FIT_STRETCH = 1.2  # the largest stretch path / L0 a belt is fitted with (20 % strain: beyond, a wrong length)


def reference_stretch(cfg: DriveConfig, layout: Layout) -> float:
    """The spans' stretch at q = 0 that the tension mode asks for (1: stress-free)."""
    target = cfg.tension.target
    if target is not None and cfg.tension.mode == "prestrain":
        return bar_law(cfg.belt.axial_law).stretch_for_tension(target, cfg.belt.EA)
    if target is None and cfg.adjustable_index is None:
        lam = layout.belt_length / cfg.belt.length  # the belt of length L0 stretched onto the path
        if lam < 1.0:
            raise ConfigError(
                f"the belt is {cfg.belt.length - layout.belt_length:.6g} m longer than its path "
                f"({layout.belt_length:.6g} m): it is slack; set tension.target or make a pulley adjustable",
                file=cfg.source, key="belt.length")
        if lam - 1.0 > MAX_FIT_STRETCH - 1.0:
            raise ConfigError(
                f"the belt is {layout.belt_length - cfg.belt.length:.6g} m shorter than its path "
                f"({layout.belt_length:.6g} m): it would need a stretch of {lam:.4g} (above {MAX_FIT_STRETCH:g}) "
                f"to fit", file=cfg.source, key="belt.length")
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


def model_dofs(cfg: DriveConfig, counts: tuple[int, ...] | None = None) -> int:
    """The DOF count of a configuration's model, known before anything is built: per span 4 per
    element (the interior nodes and the end slopes), 3 per pulley (rotation and translations, at most) and a
    decoupler's rotor. counts: cfg.span_elements, if at hand."""
    counts = cfg.span_elements if counts is None else counts
    return 3 * len(cfg.pulleys) + 4 * sum(counts) + sum(p.decoupler is not None for p in cfg.pulleys)


def check_model_size(cfg: DriveConfig) -> None:
    """A mesh whose model cannot fit in memory is a configuration error before any work (exit 2),
    not a run that is killed or fails after minutes."""
    counts = cfg.span_elements
    n_e = max(counts)
    n_dof = model_dofs(cfg, counts)
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
    (`drive_facts`), by `DeferredSystem`, and handed to each `build_system` of that analysis; a caller that
    analyses one configuration on one L0 fit several times (`response_of`, at each belt speed) computes them
    once and passes them on (`pipeline.analyse`'s facts). arms: the arms on `layout`, the L0 fit (`arm_joints`; the builds on other layouts
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
    no_elements: ancf.ElementSet | None = None  # `belt.empty_element_set` when every span is a spring, else None
    spring_joints: tuple | None = None  # `springs.spring_joints` (None without spring spans)
    wraps: WrapModel | None = None  # `wrap_model`: belt.wraps and belt.axial_law with the belt's facts
    spans: tuple | None = None  # `config.resolved_spans`: (models, elements) of each span


def drive_facts(cfg: DriveConfig, layout: Layout, *, reuse: Reuse | None = None) -> DriveFacts:
    """The `DriveFacts` of a configuration (`layout`: its L0 fit, where the arms are taken); reuse: the
    study's store the DOF map is taken from (`reuse.Reuse`), if any."""
    spans = models, counts = resolved_spans(cfg)
    dofs = number_dofs(cfg, counts) if reuse is None else reuse.dof_map(cfg, counts)
    pulleys = cfg.pulleys
    friction = np.array([np.nan if p.friction is None else p.friction for p in pulleys])
    return DriveFacts(layout=layout, dofs=dofs, tension=tension_setting(cfg, dofs), loads=static_loads(cfg, dofs),
                      friction=friction, wraps=wrap_model(cfg, friction),
                      pulley_names=tuple([p.name for p in pulleys]), gravity=np.asarray(cfg.model.gravity, dtype=float),
                      pulleys=pulley_parts(cfg, dofs), arms=arm_joints(cfg, layout, dofs),
                      no_elements=empty_element_set(cfg) if sum(counts) == 0 else None,
                      spring_joints=spring_joints(cfg, dofs, models), spans=spans)


def build_system(cfg: DriveConfig, layout: Layout | None = None, *,
                 prestrain_stretch: float | np.ndarray | None = None, spring_free: np.ndarray | None = None,
                 dense: bool | None = None, extra: tuple[LinearComponent, ...] = (),
                 belt_speed: float | None = None, facts: DriveFacts | None = None, reuse: Reuse | None = None) -> System:
    """The one place a system is built from a configuration: geometry, DOFs, belt, pulleys, springs.

    layout: the belt path (default: the L0 fit of the configuration); prestrain_stretch: the spans'
    stretch at q = 0, one number or one per span (default: what the tension mode asks for,
    `reference_stretch`); spring_free (n_dof,): where the bearing springs are relaxed (default: the
    layout's centres; see `pulley_components`); belt_speed (m/s): the running belt's speed (default:
    [running] of the configuration, `running.belt_speed_of`); facts: the configuration's `DriveFacts`,
    if at hand (one analysis's builds share them); reuse: the study's store of L0 fits, DOF maps and
    assembly patterns (`reuse.Reuse`), if any."""
    if facts is None:
        check_model_size(cfg)
        layout = layout or (layout_from_config(cfg) if reuse is None else reuse.fit(cfg))
        facts = drive_facts(cfg, layout, reuse=reuse)
    layout = layout or layout_from_config(cfg)
    lam = reference_stretch(cfg, layout) if prestrain_stretch is None else prestrain_stretch
    dofs = facts.dofs
    arms = facts.arms
    if arms is not None and layout is not facts.layout:
        arms = arm_joints(cfg, layout, dofs, like=arms)
    if belt_speed is None:
        belt_speed = belt_speed_of(cfg, layout)
    belt = build_belt(cfg, layout, dofs, prestrain_stretch=lam, no_elements=facts.no_elements, spans=facts.spans)
    springs = build_springs(cfg, layout, dofs, prestrain_stretch=lam, direction=belt.reference_direction,
                            reference_length=belt.reference_length, joints=facts.spring_joints,
                            models=None if facts.spans is None else facts.spans[0])
    system = assemble_system(layout, dofs, belt, pulley_components(cfg, dofs, layout, spring_free=spring_free,
                                                                   parts=facts.pulleys) + tuple(extra),
                             pulley_names=facts.pulley_names, driver=cfg.driver_index, tension=facts.tension,
                             gravity=facts.gravity, dense=dense, loads=facts.loads, arms=arms, friction=facts.friction,
                             springs=springs, belt_speed=float(belt_speed), wraps=facts.wraps, reuse=reuse)
    return system


def wrap_model(cfg: DriveConfig, friction: np.ndarray) -> WrapModel:
    """The belt on the pulleys of a configuration: belt.wraps, belt.axial_law, EA, the mass per length
    and the pulleys' friction coefficients (n,; NaN: none)."""
    b = cfg.belt
    return WrapModel(kind=b.wraps, axial_law=b.axial_law, EA=float(b.EA), mass_per_length=float(b.mass_per_length),
                     friction=np.array(friction, dtype=float))


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
    return TensionSetting(target=target, mode=mode, adjust_dof=adjust_dof, adjust_range=adjust_range,
                          adjust_name=cfg.pulleys[a].name if a is not None else "")


@dataclass(frozen=True, kw_only=True)
class BeltFacts:
    """What the belt of a drive is before it is built: the spans' reference lengths (n_span,) m, their
    stretch at q = 0 (one for all) and the axial stiffness EA, N."""

    reference_length: np.ndarray
    prestrain_stretch: float
    EA: float


class DeferredSystem(DofNames):
    """The drive on a layout before its full build: `pipeline.analyse` hands this to the static analysis,
    which lays the belt out anew at the predicted solved positions and usually never solves on the L0 fit.
    It holds the facts a build starts from (DOF map, layout, tension setting, arms, loads, the pulleys'
    components, the belt's reference lengths, stretch and EA: `BeltFacts`) and builds the `System` on its
    layout when asked (`full`, once)."""

    def __init__(self, cfg: DriveConfig, layout: Layout, build, *, facts: DriveFacts | None = None,
                 belt_speed: float | None = None) -> None:
        """build: layout -> System; facts: the configuration's `DriveFacts` on this layout (default: computed
        here), the builds of the same analysis share them; belt_speed (m/s): the running belt's speed the
        builds take (default: [running]'s, `belt_speed_of`)."""
        facts = drive_facts(cfg, layout) if facts is None else facts
        dofs = facts.dofs
        lam = reference_stretch(cfg, layout)
        self.facts = facts
        self.layout = layout
        self.dofs = dofs
        self.tension = facts.tension
        self.arms = facts.arms
        self.loads = facts.loads
        self.pulley_friction = facts.friction
        self.wraps = facts.wraps
        self.pulley_names = facts.pulley_names
        self.driver = cfg.driver_index
        self.EA = float(cfg.belt.EA)
        self.belt_speed = belt_speed_of(cfg, layout) if belt_speed is None else float(belt_speed)
        self.belt = BeltFacts(reference_length=layout.span_length / lam, prestrain_stretch=float(lam), EA=self.EA)
        self.components = pulley_components(cfg, dofs, layout, parts=facts.pulleys)  # the pulleys': no belt
        self._build = build
        self._system: System | None = None


    @property
    def gravity_force(self) -> np.ndarray:
        """(n_p,) the generalized weight, the belt's share included: of the system built (`full`)."""
        return self.full().gravity_force

    def pulley_index(self, name: str) -> int:
        return self.pulley_names.index(name)

    def arm_spring(self, dof: int) -> LinearComponent | None:
        """As `System.arm_spring`, among the pulleys' components."""
        return arm_spring(self.components, dof)

    def linear_matrix(self):
        """The components' constant stiffness (n_p, n_p) as `System.linear_matrix` gives it (dense up to
        `DENSE_LIMIT` coordinates, CSR above), from the pulleys' components alone: no belt built."""
        n = self.n_p
        entries = component_entries(self.components, "stiffness")
        if n <= DENSE_LIMIT:
            return Pattern(n=n, flat=NO_INDEX).scatter(*entries) if entries is not None else np.zeros((n, n))
        from scipy.sparse import csr_matrix

        rows, cols, values = entries if entries is not None else (NO_INDEX, NO_INDEX, np.zeros(0))
        return csr_matrix((values, (rows, cols)), shape=(n, n))

    @property
    def built(self) -> bool:
        return self._system is not None

    def full(self) -> System:
        """The system built on this layout (once)."""
        if self._system is None:
            self._system = self._build(self.layout)
        return self._system


__all__ = ["System", "DofMap", "BeltSpans", "SpringSpans", "build_springs", "TensionSetting",
           "build_system", "DriveFacts", "drive_facts", "number_dofs", "element_pairs", "DENSE_LIMIT"]


def assemble_system(layout: Layout, dofs: DofMap, belt: BeltSpans, components: tuple[LinearComponent, ...], *,
                    pulley_names: tuple[str, ...], driver: int, tension: TensionSetting, gravity: np.ndarray,
                    dense: bool | None, loads: np.ndarray | None = None, arms: ArmJoints | None = None,
                    friction: np.ndarray | None = None, springs: SpringSpans | None = None,
                    belt_speed: float = 0.0, wraps: WrapModel | None = None, reuse: Reuse | None = None) -> System:
    """The system of a belt and components: its pattern, mass, weight and the components' constant
    matrices, one assembly for dense and sparse (`assembly`); belt_speed (m/s): the running belt's speed
    (the system built at that speed at once, its derived fields computed once); reuse: the study's store
    the pattern is taken from (`reuse.Reuse`), if any."""
    n = dofs.n
    use_dense = n <= DENSE_LIMIT if dense is None else dense
    if springs is not None:  # the spring spans' blocks: entries of the pattern like the components'
        s_rows, s_cols = element_pairs(springs.idx)
        live = (s_rows < n) & (s_cols < n)
    extra = None
    if not use_dense:  # (a dense pattern holds every entry)
        parts = ([(s_rows[live], s_cols[live])] if springs is not None else []) + \
            [nz for nz in [component_nonzeros(components)] if nz is not None]
        extra = (np.concatenate([r for r, _ in parts]), np.concatenate([c for _, c in parts])) if parts else None
    # (dense without elements: nothing to scatter but the springs, which bring their own indices)
    pattern = Pattern(n=n, flat=NO_INDEX) if use_dense and not len(belt.idx) else \
        (make_pattern if reuse is None else reuse.pattern)(belt.idx, n, sparse=not use_dense, extra=extra)
    g = np.asarray(gravity, dtype=float)
    has_elements = belt.elements.n_elem > 0
    weighs = bool(g.any())  # (without gravity the belt's weight is zeros)
    fg = belt.reduce_vector(ancf.gravity_forces(belt.elements, g)) if has_elements and weighs else np.zeros(n)
    scatter = None
    if springs is not None:
        if weighs:
            fg = fg + springs.gravity_force(g)
        if use_dense:  # row * (n + 1) + column of each block entry (`element_pairs`)
            scatter = s_rows * (n + 1) + s_cols
        else:
            scatter = np.full(s_rows.shape, -1, dtype=np.int64)
            scatter[live] = pattern.slots_of(s_rows[live], s_cols[live])
    sums = component_sums(components, pattern, g)
    M = assemble_blocks(pattern, belt.reduce_blocks(belt.elements.mass) if has_elements else None,
                        None if springs is None else springs.mass_blocks(), scatter, sums.mass, None)
    return System(layout=layout, dofs=dofs, belt=belt, components=components, pulley_names=pulley_names,
                  driver=driver, tension=tension, gravity=g, dense=use_dense, pattern=pattern, mass=M,
                  gravity_force=fg + sums.weight, linear_stiffness=sums.stiffness, linear_damping=sums.damping,
                  linear_offset=sums.offset, loads=loads, arms=arms, pulley_friction=friction, belt_speed=belt_speed,
                  springs=springs, spring_scatter=scatter, wraps=wraps,
                  arm_folding=arm_folding(arms, pattern.indptr, pattern.indices) if arms is not None and pattern.sparse
                  else None)
