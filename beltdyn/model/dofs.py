"""The DOF map: the independent coordinates of the drive, their labels, units and groups.

Nomenclature (paper section 2.2): q (n_dof,) the independent coordinates, measured from the reference
configuration (q = 0 is the stress-free L0 geometry, or the prestrained one). A pulley carries only the
DOFs its support allows: rotation theta (rad, counter-clockwise), plus the slide offset u (m), the bearing
displacements (x, y) (m) or an arm angle phi (rad); a pulley with a decoupler also its rotor's rotation
(rad, right after the pulley's, `model.decouplers`). A span carries every coordinate of its interior nodes
(r1, r2, r1', r2') and the gradients of its end nodes; the end-node positions are dependent (the joints,
`belt`). The joint coordinates p (n_p,) are q followed by the dependent ones (an arm pulley's centre
offsets).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from beltdyn.config import DriveConfig
from beltdyn.model.supports import support_of

DOF_GROUPS = ("span", "rotation", "translation", "arm")


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
    rotor_dof: np.ndarray | None = None  # (n_pulley,) the rotation DOF of a decoupler's rotor (-1: no decoupler)

    @property
    def torque_dof(self) -> np.ndarray:
        """(n_pulley,) the DOF an accessory torque on pulley j acts on: its decoupler's rotor, else its rotation."""
        if self.rotor_dof is None:
            return self.rot_dof
        return np.where(self.rotor_dof >= 0, self.rotor_dof, self.rot_dof)

    @property
    def n(self) -> int:
        """Joint coordinates p (independent and dependent)."""
        return len(self.labels)

    @property
    def n_q(self) -> int:
        """Independent coordinates q."""
        return len(self.labels) - self.dependent


def dof_inputs(cfg: DriveConfig, counts: tuple[int, ...]) -> tuple:
    """What `number_dofs` reads of a configuration with counts elements per span, as a key (hashable,
    compared by value): the pulleys (their names, supports, decouplers) and the counts. Equal keys number
    the DOFs alike (`reuse.Reuse`: a study's analyses of one drive and mesh share the map)."""
    return cfg.pulleys, tuple(counts)


def number_dofs(cfg: DriveConfig, counts: tuple[int, ...] | None = None) -> DofMap:
    """DOF order along the loop: pulley j (its support's DOFs, rotation), then span j (start
    gradients, interior nodes, end gradients; none for a spring span); the supports' dependent DOFs
    after all of them. counts: cfg.span_elements, if at hand."""
    counts = cfg.span_elements if counts is None else counts  # elements of each span (0: a spring span)
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

    names, node_units = ["r1", "r2", "r1'", "r2'"], ["m", "m", "1", "1"]  # a node's coordinates (r, r') and units
    span_group = DOF_GROUPS.index("span")
    arm_dof = np.full(len(cfg.pulleys), -1, dtype=int)
    rotor_dof = np.full(len(cfg.pulleys), -1, dtype=int)
    supports = [support_of(p) for p in cfg.pulleys]
    for j, (p, sup) in enumerate(zip(cfg.pulleys, supports)):
        own = [(add(f"pulley {p.name} {suffix}", unit, grp), grp) for suffix, unit, grp in sup.independent()]
        trans_dof.append(tuple(d for d, grp in own if grp == "translation"))  # dependent ones: below
        trans_dir.append(sup.directions())
        arm_dof[j] = next((d for d, grp in own if grp == "arm"), -1)
        rot_dof[j] = add(f"pulley {p.name} rotation", "rad", "rotation")
        if p.decoupler is not None:
            rotor_dof[j] = add(f"pulley {p.name} rotor", "rad", "rotation")
        start = len(labels)
        s = j + 1
        n_e = counts[j]
        if n_e:  # the first node's gradient, the interior nodes (r, r'), the last node's gradient (a list each,
            # from each node's prefix: a span of many elements has thousands of coordinates)
            nodes = [f"span {s} node {node} " for node in range(1, n_e + 2)]
            labels.extend([nodes[0] + c for c in names[2:]])
            labels.extend([node + c for node in nodes[1:-1] for c in names])
            labels.extend([nodes[-1] + c for c in names[2:]])
            units.extend(node_units[2:] + node_units * (n_e - 1) + node_units[2:])
            group.extend([span_group] * (4 * n_e))
        span_slices.append(slice(start, len(labels)))
    n_q = len(labels)
    for j, (p, sup) in enumerate(zip(cfg.pulleys, supports)):  # dependent DOFs (arm offsets): after q
        if sup.dependent():
            trans_dof[j] = tuple(add(f"pulley {p.name} {suffix}", unit, grp) for suffix, unit, grp in sup.dependent())
    group = np.array(group, dtype=np.int64)
    for a in (group, rot_dof, arm_dof, rotor_dof, *trans_dir):  # (read-only: a DOF map is immutable)
        a.setflags(write=False)
    return DofMap(labels=tuple(labels), units=tuple(units), group=group, rot_dof=rot_dof,
                  trans_dof=tuple(trans_dof), trans_dir=tuple(trans_dir), span_slices=tuple(span_slices),
                  arm_dof=arm_dof, dependent=len(labels) - n_q, rotor_dof=rotor_dof)
