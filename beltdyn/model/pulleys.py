"""The pulleys' components from the configuration: pulley inertia J (rotation DOFs), pulley mass m and
weight (translation DOFs, paper Eq. 20: M = m |v|^2 per direction v, W = m v), the bearing springs
(Eq. 21, diagonal k per translation DOF), the decouplers (`decouplers`: a rotor behind a spring), and each
support's own components (a tensioner arm's inertia,
torsion spring and damper on its angle)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from beltdyn.config import DriveConfig
from beltdyn.model.components import BearingSprings, LinearComponent, rotation_component
from beltdyn.model.decouplers import decoupler_component
from beltdyn.model.dofs import DofMap
from beltdyn.model.supports import SUPPORT_CLASSES, Support, support_of

if TYPE_CHECKING:
    from beltdyn.model.geometry import Layout

PulleyParts = tuple  # (fixed components, bearing springs' (dofs, K, pulleys, names) or None, ((support, first DOF, j), ...))


def pulley_components(cfg: DriveConfig, dofs: DofMap, layout: Layout | None = None, *,
                      spring_free: np.ndarray | None = None, parts: PulleyParts | None = None
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


def pulley_parts(cfg: DriveConfig, dofs: DofMap) -> PulleyParts:
    """What `pulley_components` takes from the configuration alone: the pulley inertia and the pulleys'
    masses (components), the bearing springs' DOFs (k,), stiffness (k, k), pulleys and their names (None
    without any), and the supports with own components (support, its first DOF, pulley index)."""
    pulleys = cfg.pulleys
    fixed: list[LinearComponent] = [rotation_component(dofs.rot_dof, [p.inertia for p in pulleys],
                                                       [0.0 if p.decoupler is not None else p.rotational_damping
                                                        for p in pulleys])]  # (a decoupler's: on its rotor)
    for j, p in enumerate(pulleys):  # decouplers: the rotor behind its spring (`model.decouplers`)
        dc = p.decoupler
        if dc is not None:
            fixed.append(decoupler_component(pulley=j, pulley_name=p.name, rot_dof=int(dofs.rot_dof[j]),
                                             rotor_dof=int(dofs.rotor_dof[j]), inertia=dc.inertia,
                                             stiffness=dc.stiffness, damping=dc.damping,
                                             rotor_damping=p.rotational_damping, one_way=dc.one_way))
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
            v = dofs.trans_dir[j]  # (k, 2) the directions of its translations
            m_m.extend(p.mass * np.einsum("kd,kd->k", v, v))  # m |v|^2 (1 for the unit directions)
            w_m.extend(p.mass * v)
        springs = sup.springs()
        if springs:
            t_dofs += t_dof
            k_spring += springs
            supported.append(j)
        if sup.independent():
            own.append((sup, t_dof[0] if t_dof and not sup.translation_is_dependent() else int(dofs.arm_dof[j]), j))
    for kind, (d_m, m_m, w_m) in masses.items():
        if d_m:
            fixed.append(LinearComponent(name=_MASS_NAMES.get(kind) or f"{kind} pulley mass",
                                      dofs=np.array(d_m, dtype=np.int64), stiffness=None, damping=None,
                                      mass=np.diag(m_m), weight=np.array(w_m), free=None, energy_kind=kind))
    bearing = None
    if t_dofs:
        bearing = (np.array(t_dofs, dtype=np.int64), np.diag(k_spring), tuple(supported),
                   tuple(pulleys[j].name for j in supported))
    return tuple(fixed), bearing, tuple(own)


