"""The running belt: axial transport in the spans, the running equilibrium, gyroscopic modes, critical
speeds and the Campbell diagram's engine-order crossings.

Kinematics (Eulerian/ALE spans). Each span stays fixed in space between its tangent points while the
belt's material flows through it at the rate c (m/s of undeformed belt length, so the mass flow is
rho c; `belt_speed`, positive along the direction of travel A -> B -> ...; a driver speed omega gives
c = omega R_driver with the sign of the travel there). A span's coordinate x is a mesh coordinate; the
material point at x moves with V = dr/dt + c r', so the physical speed in a span of stretch lambda is
lambda c. The coordinates q are, as at rest, the departure from the reference configuration: a
pulley's rotation q is its departure from the nominal rotation c t / R.

Equations of motion (`ancf.transport_matrices`, assembled by `System.transport_matrices`):

    M q'' + c G q' + c' (A q + a0) + K(q) q - c^2 (B q + b0) = F,     G = A - A^T,

G skew-symmetric (gyroscopic: it does no work), -c^2 B the centripetal ("rho v^2") stiffness, c' A the
belt's axial inertia while its speed changes. They follow from the kinetic energy 1/2 int rho |V|^2 dx
of the spans by Lagrange's equations, i.e. from Hamilton's principle for the closed belt loop: the
momentum flux rho c V that leaves a span at a tangent point enters the wrap there (the material
velocity is continuous), so the fluxes cancel over the loop. The wraps are not meshed (the joints hold
them rigid on their pulleys, as at rest), so their kinetic energy does not change with q: the loop's
Lagrangian is the spans' alone. At rest (c = 0) every matrix, force and result is what it was before.

Running span tension (the model's choice, and why). A straight span of stretch lambda and true tension
N at speed c holds its end nodes with (N - rho c^2 lambda) t: the spans carry their tension N, and the
pulley receives only N - rho c^2 lambda from each span end (the centripetal force that turns the
material round the wrap, rho c^2 lambda / R per unit length, is carried by the belt's own tension,
not by the contact pressure). So

    hub load on pulley j = (N_j - rho c^2 lambda_j) t_j - (N_(j-1) - rho c^2 lambda_(j-1)) t_(j-1),

and the span tension follows from the supports like any other load: with fixed centres the belt's
length and path hold its strain, N does not change with speed and the hub loads drop by rho c^2 per
span end; a dead-weight (constant-force) tensioner keeps N - rho c^2 lambda, so the tension rises by
the full centrifugal tension rho c^2 lambda; springs and arms lie between. tension.target is the mean
span tension of the running drive (modes "adjust" and "prestrain" set it at the speed of [running]);
mode "spring" and a belt without a target give the running tension as an output. tests/test_running.py
checks these closed forms (fixed centres, dead weight, the wrap's momentum balance above).

Linearization. About the running equilibrium q0: M s^2 + G s + K = 0 (`modal.solve_modes` at speed),
K the loaded tangent with the centripetal stiffness; frequencies are the imaginary parts of s, shapes
complex. K loses its positive definiteness at a critical speed: a frequency reaches zero and the span
diverges (buckles) there; above it s is real and positive (divergence) and the mode's growth rate is
reported with frequency 0. `linearized_matrices` gives M, G, K (and C) to other analyses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from beltdyn.config import Damping
    from beltdyn.model.dofs import DofMap
    from beltdyn.model.system import System


@dataclass(frozen=True, kw_only=True)
class RunningMatrices:
    """The drive linearized about its running equilibrium q0: M x'' + (C + G) x' + K x = f.

    On the independent coordinates q (n = n_dof), each dense (n, n) or CSR as the system:
    M the mass (J^T M J), G the gyroscopic matrix (skew-symmetric, zero at rest), K the loaded tangent
    (belt, components, the arms' geometric terms and the centripetal stiffness -c^2 B), C the damping
    (the components' dampers, and with `damping` Rayleigh alpha M + beta K_0 and the belt's Kelvin-Voigt
    matrix at q0; K_0 the tangent without the loads' geometric and centripetal terms, as the transient's).
    dofs: the DOF map (labels, units, groups, pulley and span DOFs); belt_speed c in m/s.
    """

    M: object
    G: object
    K: object
    C: object
    q0: np.ndarray
    dofs: "DofMap"
    belt_speed: float


def linearized_matrices(system: "System", q0: np.ndarray, damping: "Damping | None" = None) -> RunningMatrices:
    """M, G, K, C of the drive (at its belt speed, `System.belt_speed`) about the state q0 (n_dof,), usually
    its running equilibrium (`pipeline.analyse` with [running], `StaticResult.q`). See `RunningMatrices`."""
    _, K = system.equilibrium(q0)
    M = system.mass_matrix(q0)
    G = system.gyroscopic_matrix(q0) if system.belt_speed else 0.0 * M
    C_p = system.linear_damping
    if damping is not None and (damping.rayleigh_mass or damping.rayleigh_stiffness):
        # (a zero coefficient's term is not evaluated: adding its zeros changes no entry, and K_0 is a tangent)
        ray = damping.rayleigh_mass * system.mass if damping.rayleigh_mass else None
        if damping.rayleigh_stiffness:
            stiff = damping.rayleigh_stiffness * system.tangent_on_joints(q0)
            ray = stiff if ray is None else ray + stiff
        C_p = ray if C_p is None else C_p + ray
    if damping is not None and (damping.belt_axial or damping.belt_bending):
        from beltdyn.model import belt_kernel as bk

        belt = system.belt
        tab = belt.kernel_tables
        E = belt.element_coordinates(system.expand(q0))
        Ce = np.empty((E.shape[0], 8, 8))
        bk.element_damping_matrix(E, tab.dS, tab.d2S, tab.wEA, tab.wEI, tab.Kb, tab.curvature,
                                  float(damping.belt_axial), float(damping.belt_bending), Ce, belt.kernel_scratch())
        Cb = system.with_belt(damping_axial=float(damping.belt_axial)).belt_damping_matrix(q0, Ce)  # + spring spans
        C_p = Cb if C_p is None else C_p + Cb
    C = system.project_matrix(q0, C_p) if C_p is not None else 0.0 * M
    return RunningMatrices(M=M, G=G, K=K, C=C, q0=np.asarray(q0, dtype=float), dofs=system.dofs,
                           belt_speed=float(system.belt_speed))


# ------------------------------------------------------------------------------------ Campbell diagram
SPEED_KEYS = ("running.driver_speed", "running.belt_speed")


@dataclass(frozen=True, kw_only=True)
class Crossing:
    """A tracked mode meeting an engine-order line f = order x |Omega| / (2 pi) (linear interpolation
    between the two cases that bracket it): a resonance of the running drive."""

    order: float
    mode: int  # 0-based index of the tracked mode
    label: str  # the mode's classification at the nearer case
    driver_speed: float  # rad/s
    belt_speed: float  # m/s
    frequency: float  # Hz


@dataclass(frozen=True, kw_only=True)
class Instability:
    """A tracked mode losing its stability between two cases: "divergence" (its frequency reaches zero, a
    real eigenvalue s > 0 beyond) or "flutter" (Re s > 0 at a nonzero frequency). A divergence speed
    interpolates omega^2 - sigma^2 (s = sigma + i omega), linear in the squared speed near it; a flutter
    speed is that of the first case where the growth is seen."""

    kind: str
    mode: int
    label: str
    driver_speed: float  # rad/s
    belt_speed: float  # m/s


def mode_label(kind: str, order: int, span: int, span_names: list[str]) -> str:
    """"2nd transverse, span 1 (A-C)" from a tracked mode's classification."""
    from beltdyn.analysis.modal import ordinal

    if kind in ("", "lost"):
        return kind or "?"
    text = f"{ordinal(int(order))} {kind}"
    return text + (f", span {int(span)} ({span_names[int(span) - 1]})" if int(span) > 0 else "")


def speed_axis(result) -> bool:
    """Whether a sweep result is a Campbell diagram: one swept (or zipped) parameter, a running speed,
    modal, with the per-case speeds recorded."""
    spec = result.spec
    return (result.frequency is not None and "driver_speed" in result.extras
            and (len(spec.params) == 1 or spec.zip) and any(p.key in SPEED_KEYS for p in spec.params))


def campbell(result, orders, span_names: list[str]) -> tuple[tuple[Crossing, ...], tuple[Instability, ...]]:
    """The engine-order crossings (for each order, each tracked mode) and the critical speeds of a speed
    sweep (`speed_axis`), cases taken in the order of increasing |driver speed|; failed cases and lost
    modes break the lines."""
    Om = np.abs(np.asarray(result.extras["driver_speed"], dtype=float))
    c = np.abs(np.asarray(result.extras["belt_speed"], dtype=float))
    f = result.frequency
    g = result.growth_rate if result.growth_rate is not None else np.zeros_like(f)
    idx = np.argsort(Om, kind="stable")
    idx = idx[result.failed[idx] == 0]
    crossings, unstable = [], []

    def label(i: int, j: int) -> str:
        return mode_label(str(result.kind[i, j]), result.order[i, j], result.span[i, j], span_names)

    for a, b in zip(idx[:-1], idx[1:]):
        for j in range(f.shape[1]):
            fa, fb, ga, gb = f[a, j], f[b, j], g[a, j], g[b, j]
            if not (np.isfinite(fa) and np.isfinite(fb)) or Om[b] == Om[a]:
                continue
            if fa > 0 and fb > 0:
                for k in orders:
                    ya, yb = fa - k * Om[a] / (2 * np.pi), fb - k * Om[b] / (2 * np.pi)
                    if ya > 0 >= yb or ya < 0 <= yb:
                        t = ya / (ya - yb)
                        W = Om[a] + t * (Om[b] - Om[a])
                        crossings.append(Crossing(order=float(k), mode=j, label=label(a if t < 0.5 else b, j),
                                                  driver_speed=float(W), belt_speed=float(c[a] + t * (c[b] - c[a])),
                                                  frequency=float(k * W / (2 * np.pi))))
            if (ga if np.isfinite(ga) else 0.0) <= 0 < (gb if np.isfinite(gb) else 0.0):
                kind = "divergence" if fb == 0 else "flutter"
                ya, yb = (2 * np.pi * fa) ** 2 - ga ** 2, (2 * np.pi * fb) ** 2 - gb ** 2
                t = ya / (ya - yb) if kind == "divergence" and ya > 0 > yb else 1.0  # flutter: where first seen
                unstable.append(Instability(kind=kind, mode=j, label=label(a, j),
                                            driver_speed=float(np.sqrt(Om[a] ** 2 + t * (Om[b] ** 2 - Om[a] ** 2))),
                                            belt_speed=float(np.sqrt(c[a] ** 2 + t * (c[b] ** 2 - c[a] ** 2)))))
    crossings.sort(key=lambda x: (x.order, x.driver_speed))
    return tuple(crossings), tuple(unstable)
