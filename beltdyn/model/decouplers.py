"""Decouplers (overrunning alternator pulleys, OAD): the accessory's rotor behind a torsion spring and a
one-way clutch on the pulley's hub, a component with its own rotation DOF (the rotor's).

Nomenclature: theta_p the pulley's (hub's) rotation, theta_r the rotor's (rad, counter-clockwise, the
DOF `DofMap.rotor_dof`), phi = theta_p - theta_r the relative angle (the spring's wind-up while the
clutch holds; phi > 0: the belt drives the rotor), J_r the rotor's inertia (kg m^2), k the spring's
stiffness (N m/rad), c the viscous damping across it (N m s/rad), d_r the accessory's own viscous load
to ground (the pulley's `rotational_damping`, moved onto the rotor). With the clutch engaged the
decoupler is linear: torque tau = k phi + c phi' on the hub (-tau on the rotor), mass J_r on
theta_r; that is the component the static, modal and response analyses see (the clutch held engaged).
The one-way clutch (transient only, `analysis.friction_kernel.clutch_torques`) sits in series with the spring and
damper: it slips by an angle z when the torque would fall below -DRAG (overrunning: the rotor runs
ahead), tau = max(k (phi - z) + c (phi' - z'), -DRAG).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from beltdyn.model.components import LinearComponent

CLUTCH_DRAG = 0.0  # N m: the torque an overrunning clutch still transmits (its bound: the torque never falls below -this)


@dataclass(frozen=True, kw_only=True)
class Decoupler(LinearComponent):
    """One decoupler, engaged: dofs (2,) = (pulley rotation, rotor rotation), stiffness k [[1, -1], [-1, 1]],
    damping c [[1, -1], [-1, 1]] plus d_r on the rotor, mass diag(0, J_r) (energy kind "rotational")."""

    pulley: int = -1  # pulley index
    pulley_name: str = ""
    spring: float = 0.0  # k, N m/rad
    viscous: float = 0.0  # c, N m s/rad
    one_way: bool = True


def decoupler_component(*, pulley: int, pulley_name: str, rot_dof: int, rotor_dof: int, inertia: float,
                        stiffness: float, damping: float, rotor_damping: float, one_way: bool) -> Decoupler:
    """The engaged decoupler of pulley `pulley` (module docstring) on its DOFs rot_dof (hub) and rotor_dof."""
    rel = np.array([[1.0, -1.0], [-1.0, 1.0]])
    C = damping * rel + np.diag([0.0, rotor_damping])
    return Decoupler(name=f"decoupler {pulley_name}", dofs=np.array([rot_dof, rotor_dof], dtype=np.int64),
                     stiffness=stiffness * rel, damping=C if C.any() else None, mass=np.diag([0.0, inertia]),
                     weight=None, free=None, energy_kind="rotational", pulley=pulley, pulley_name=pulley_name,
                     spring=float(stiffness), viscous=float(damping), one_way=bool(one_way))


def decouplers_of(components) -> tuple[Decoupler, ...]:
    """The system's decouplers, in pulley order."""
    return tuple(sorted((c for c in components if isinstance(c, Decoupler)), key=lambda c: c.pulley))
