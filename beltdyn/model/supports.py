"""Pulley supports, one small class each: the DOFs a support gives its pulley, the directions in which
the pulley's centre moves with them, its springs, dampers and inertias, its nonlinear kinematics (an
arm), how it is adjusted to fit L0 and set the tension, and its travel limits.

`system.number_dofs`, `system.pulley_components`, `system.arm_joints`, `system.build_system` and
`geometry.layout_from_config` ask the support of each pulley (`support_of`) and stay generic: a new
support is a class here (plus its keys in `config.Pulley`).

DOFs. A support's own DOFs come before the pulley's rotation. `independent` ones are coordinates q;
`dependent` ones are joint coordinates p computed from q (an arm pulley's centre offsets, exact in
the arm angle; see `system.ArmJoints`), placed after all of q. `directions` (k, 2): the centre's
motion per unit of each translational DOF (the ones the belt joints and the pulley's mass see).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from beltdyn.config import Pulley
from beltdyn.model.angles import pivot_angle, unwrap_near
from beltdyn.model.components import LinearComponent

Dof = tuple[str, str, str]  # label suffix, unit, DOF group


@dataclass(frozen=True)
class Support:
    """A fixed centre: rotation only."""

    kind: ClassVar[str] = "fixed"
    pulley: Pulley

    def independent(self) -> tuple[Dof, ...]:
        """The support's own independent DOFs (before the pulley's rotation)."""
        return ()

    def dependent(self) -> tuple[Dof, ...]:
        """Translational DOFs computed from the independent ones (after all of q)."""
        return ()

    def directions(self) -> np.ndarray:
        """(k, 2) centre motion per unit of each translational DOF."""
        return np.zeros((0, 2))

    def translation_is_dependent(self) -> bool:
        return False

    def springs(self) -> tuple[float, ...]:
        """Spring stiffness (N/m) on each translational DOF (the bearing springs, paper Eq. 21)."""
        return ()

    @property
    def mass_kind(self) -> str:
        """The kinetic-energy kind of the pulley's translation (mode classification)."""
        return "translational"

    def own_components(self, dof: int, layout, index: int, spring_free: np.ndarray | None = None) -> tuple:
        """Components on the support's own independent DOFs (an arm's inertia, spring, damper);
        spring_free (n_p,): where a spring without a given free position is relaxed (see
        `system.pulley_components`)."""
        return ()

    def fit_motion(self) -> dict:
        """How `geometry.fit_adjustable` moves the pulley to fit L0 (keyword arguments)."""
        raise ValueError(f"a {self.kind} support cannot be adjusted")

    def travel_limits(self) -> tuple[float, float] | None:
        """Allowed travel of the adjustable pulley from its given (drawn) position, in its DOF's unit."""
        return None


@dataclass(frozen=True)
class SlideSupport(Support):
    """A slide along slide_direction against a spring (N/m)."""

    kind: ClassVar[str] = "slide"

    def independent(self) -> tuple[Dof, ...]:
        return (("slide", "m", "translation"),)

    def directions(self) -> np.ndarray:
        return np.array([self.pulley.slide_direction], dtype=float)

    def springs(self) -> tuple[float, ...]:
        return (self.pulley.bearing_stiffness[0],)

    def fit_motion(self) -> dict:
        return {"direction": np.array(self.pulley.slide_direction, dtype=float),
                "slide_range": self.pulley.slide_range}

    def travel_limits(self) -> tuple[float, float] | None:
        return self.pulley.slide_range


@dataclass(frozen=True)
class BearingSupport(Support):
    """A bearing moving in x and y against springs (kx, ky) (N/m)."""

    kind: ClassVar[str] = "bearing"

    def independent(self) -> tuple[Dof, ...]:
        return (("x", "m", "translation"), ("y", "m", "translation"))

    def directions(self) -> np.ndarray:
        return np.eye(2)

    def springs(self) -> tuple[float, ...]:
        return tuple(self.pulley.bearing_stiffness)


@dataclass(frozen=True)
class ArmSupport(Support):
    """A tensioner arm: the centre turns about arm_pivot; its angle is the independent DOF, the centre's
    offsets (x, y) dependent (exact kinematics, `system.ArmJoints`); torsion spring, viscous damper
    and the arm's inertia on the angle (the pulley's mass adds m l^2 through the kinematics); dry
    friction in the transient (`integrator`)."""

    kind: ClassVar[str] = "arm"

    def independent(self) -> tuple[Dof, ...]:
        return (("arm", "rad", "arm"),)

    def dependent(self) -> tuple[Dof, ...]:
        return (("x (arm)", "m", "translation"), ("y (arm)", "m", "translation"))

    def directions(self) -> np.ndarray:
        return np.eye(2)

    def translation_is_dependent(self) -> bool:
        return True

    @property
    def mass_kind(self) -> str:
        return "tensioner"

    def working_angle(self, layout, index: int) -> float:
        """The arm angle on a layout, on the branch of its stops (arm_range) when given: angles are taken
        literally then, so a spring wound by more than half a turn is expressed (free angle and stops
        on one branch); without stops, the angle of atan2."""

        x, y = layout.center[index].tolist()
        return self.angle_at(x, y)

    def angle_at(self, x: float, y: float) -> float:
        """`working_angle` with the pulley's centre at (x, y) (m)."""
        p = self.pulley
        phi = pivot_angle((x, y), p.arm_pivot)
        return unwrap_near(phi, 0.5 * (p.arm_range[0] + p.arm_range[1])) if p.arm_range is not None else phi

    def own_components(self, dof: int, layout, index: int, spring_free: np.ndarray | None = None) -> tuple:
        p = self.pulley
        free = None
        if p.arm_stiffness > 0 and layout is not None:
            ref = self.working_angle(layout, index)
            if p.arm_free_angle is not None:  # literal on the stops' branch; else the nearest turn
                fa = p.arm_free_angle if p.arm_range is not None else unwrap_near(p.arm_free_angle, ref)
                free = np.array([fa - ref])
            elif spring_free is not None and spring_free[dof] != 0.0:  # relaxed where it was on the L0 fit
                free = np.array([float(spring_free[dof])])
        name, dofs, mass, stiffness, damping = self._arm_parts(dof)
        return (LinearComponent(name=name, dofs=dofs, stiffness=stiffness, damping=damping, mass=mass, weight=None,
                                free=free, energy_kind="tensioner"),)

    def _arm_parts(self, dof: int) -> tuple:
        """The arm component's name, DOFs (1,) and inertia, torsion spring and damper (1, 1) each (None where
        zero), read-only."""
        p = self.pulley
        values = (p.arm_inertia, p.arm_stiffness, p.arm_damping)
        every, dofs = np.array(values).reshape(3, 1, 1), np.array([dof], dtype=np.int64)
        every.setflags(write=False)
        dofs.setflags(write=False)
        return (f"tensioner arm {p.name}", dofs, *(every[i] if v > 0 else None for i, v in enumerate(values)))

    def fit_motion(self) -> dict:
        return {"direction": np.zeros(2), "slide_range": self.travel_limits(),
                "pivot": np.array(self.pulley.arm_pivot, dtype=float)}

    def travel_limits(self) -> tuple[float, float] | None:
        """The stops (arm_range) about the drawn arm angle, rad (None without stops)."""
        p = self.pulley
        if p.arm_range is None:
            return None
        drawn = unwrap_near(p.arm_angle, 0.5 * (p.arm_range[0] + p.arm_range[1]))
        return (p.arm_range[0] - drawn, p.arm_range[1] - drawn)


SUPPORT_CLASSES: dict[str, type[Support]] = {c.kind: c for c in (Support, SlideSupport, BearingSupport, ArmSupport)}


def support_of(pulley: Pulley) -> Support:
    """The support object of a pulley (by its `support` key)."""
    return SUPPORT_CLASSES[pulley.support](pulley)
