"""Components: items with constant matrices over their own DOFs (pulley inertia and mass, bearing
springs, anything a user adds), and the output series they offer.

A component owns its DOF indices and gives its contribution to the internal force and tangent
(K (q - free), K), to the damping (C v), to the mass (M) and to the weight, its kinetic-energy kind
for the classification of modes, and its own output series. The analyses see only the `System`:
adding a component touches no analysis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from beltdyn.model.geometry import Layout
    from beltdyn.model.system import System

ENERGY_KINDS = ("rotational", "translational", "longitudinal", "transverse", "tensioner")


@dataclass(frozen=True, kw_only=True)
class Observation:
    """One output series a component offers: trailing dims (coordinate names) and units."""

    name: str
    dims: tuple[str, ...]
    units: str
    description: str = ""


@dataclass(frozen=True, kw_only=True)
class LinearComponent:
    """A component with constant matrices over its own DOFs (k,): internal force
    K (q[dofs] - free), damping C v[dofs], mass M, weight W (k, 2) (generalized force per unit
    gravity vector); `free` (k,) the DOF values at which its force vanishes (default 0).

    energy_kind names the kinetic-energy kind of its mass for the mode classification
    (one of ENERGY_KINDS, or "" for none). Subclasses may offer output series (`observations`,
    `observe`).
    """

    name: str
    dofs: np.ndarray
    stiffness: np.ndarray | None = None
    damping: np.ndarray | None = None
    mass: np.ndarray | None = None
    weight: np.ndarray | None = None
    free: np.ndarray | None = None
    energy_kind: str = ""

    def observations(self, system: "System") -> tuple[Observation, ...]:
        return ()

    def observe(self, system: "System", q: np.ndarray, preload: np.ndarray) -> dict[str, np.ndarray]:
        """Series values for output states q (B, n_dof); preload (n_dof,) the static spring preload."""
        return {}


@dataclass(frozen=True, kw_only=True)
class BearingSprings(LinearComponent):
    """Bearing springs of the pulleys on slides and bearings (paper Eq. 21), diagonal."""

    pulleys: tuple[int, ...] = ()  # pulley index of each supported pulley
    pulley_names: tuple[str, ...] = ()

    def observations(self, system: "System") -> tuple[Observation, ...]:
        if not self.pulleys:
            return ()
        return (Observation(name="bearing_force", dims=("bearing", "component"), units="N",
                            description="force of the bearing spring on the pulley (preload included)"),)

    def observe(self, system: "System", q: np.ndarray, preload: np.ndarray) -> dict[str, np.ndarray]:
        d = system.dofs
        k_of = dict(zip(self.dofs.tolist(), np.diag(self.stiffness)))  # the springs are diagonal
        free = dict(zip(self.dofs.tolist(), self.free if self.free is not None else np.zeros(len(self.dofs))))
        rows = []
        for j in self.pulleys:
            F = np.zeros((q.shape[0], 2))
            for dof, vec in zip(d.trans_dof[j], d.trans_dir[j]):
                F += (preload[dof] - k_of[dof] * (q[:, dof] - free[dof]))[:, None] * vec
            rows.append(F)
        return {"bearing_force": np.stack(rows, axis=1)}


def rotation_component(rot_dof: np.ndarray, inertia, rotational_damping) -> LinearComponent:
    """The pulleys' rotations: inertia J_j (kg m^2) and the viscous torque to ground -d_j omega_j
    (`rotational_damping` d_j, N m s/rad: a generator or pump load growing with speed), both diagonal
    on the rotation DOFs rot_dof (n,); no damping matrix where every d_j is 0."""
    d = np.asarray(rotational_damping, dtype=float)
    return LinearComponent(name="pulley inertia", dofs=rot_dof, stiffness=None,
                           damping=np.diag(d) if d.any() else None, mass=np.diag(np.asarray(inertia, dtype=float)),
                           weight=None, free=None, energy_kind="rotational")


def belt_rotation_rates(layout: "Layout", rot_dof: np.ndarray, n: int,
                        rotor_dof: np.ndarray | None = None) -> np.ndarray:
    """(n,) the pulleys' rotations per metre of belt travel, +-1/R_j at their rotation DOFs rot_dof (the
    sign from the direction the belt leaves pulley j, (t x n_out-perp) / R: counter-clockwise positive),
    the same at a decoupler's rotor DOF (rotor_dof (n_pulley,), -1: none; the rotor turns with its pulley),
    0 elsewhere. The running drive at belt speed v turns pulley j at omega_j = v times this."""
    u = np.zeros(n)
    for j in range(layout.n):
        n_out = layout.start_normal[j]
        u[rot_dof[j]] = float(np.array([-n_out[1], n_out[0]]) @ layout.span_direction[j]) / layout.radius[j]
        if rotor_dof is not None and rotor_dof[j] >= 0:
            u[rotor_dof[j]] = u[rot_dof[j]]
    return u


def arm_spring(components: tuple[LinearComponent, ...], dof: int) -> LinearComponent | None:
    """The torsion spring of the tensioner arm whose angle is the coordinate `dof`: the component on that
    coordinate alone with a stiffness (None: the arm has no spring)."""
    return next((c for c in components if c.stiffness is not None and c.dofs.shape == (1,) and c.dofs[0] == dof),
                None)
