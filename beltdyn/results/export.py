"""Result dataclasses -> HDF5 group descriptions (names, dimensions, units; DESIGN section 4).

No h5py here: `results_io` writes what these functions describe.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from beltdyn.analysis.result_warnings import SLACK_WARNING, STRAIN_WARNING, strain_warning  # noqa: F401
from beltdyn.model.slip import ROUND_OFF
from beltdyn.results.io import GroupData, Variable

if TYPE_CHECKING:  # keep `beltdyn geometry` from importing the solvers
    from beltdyn.model.geometry import Layout
    from beltdyn.analysis.modal import ModalResult
    from beltdyn.model.system import System as DriveModel
    from beltdyn.analysis.static import StaticResult

XY = ["x", "y"]
MIXED = "mixed (see dof_unit)"


def dof_units(model: DriveModel) -> list[str]:
    """Unit of each generalized coordinate (the system's DOF map): pulley rotation rad, pulley slide /
    x / y m, tensioner arm rad, span node position r1 / r2 m, span node slope r1' / r2' 1."""
    return list(model.dof_units)


def dof_force_unit(unit: str) -> str:
    """Unit of the generalized force conjugate to a DOF of unit `unit` (force times DOF is work, J)."""
    return "N" if unit == "m" else "N m"


def dof_unit_variable(model: DriveModel) -> Variable:
    return Variable(name="dof_unit", data=dof_units(model), dims=("dof",), units="1",
                    description="unit of each generalized coordinate (rad, m, or 1 for a slope)")


# Units of swept keys (pulley and excitation entries by any index or name: "*"); others "unknown".
PARAM_UNITS = {
    "belt.length": "m", "belt.EA": "N", "belt.EI": "N m^2", "belt.mass_per_length": "kg/m",
    "pulleys.*.center": "m", "pulleys.*.radius": "m", "pulleys.*.mass": "kg", "pulleys.*.inertia": "kg m^2",
    "pulleys.*.slide_direction": "1", "pulleys.*.bearing_stiffness": "N/m", "pulleys.*.slide_range": "m",
    "pulleys.*.arm_pivot": "m", "pulleys.*.arm_inertia": "kg m^2", "pulleys.*.arm_stiffness": "N m/rad",
    "pulleys.*.arm_free_angle": "rad", "pulleys.*.arm_damping": "N m s/rad", "pulleys.*.arm_friction": "N m", "pulleys.*.arm_friction_unloading": "N m",
    "pulleys.*.arm_range": "rad", "pulleys.*.friction": "1", "static.torque.*.value": "N m",
    "tension.target": "N", "mesh.elements_per_span": "1", "running.belt_speed": "m/s", "running.driver_speed": "rad/s",
    "model.gravity": "m/s^2", "model.gauss_points": "1",
    "static.tolerance": "1", "static.max_iterations": "1", "static.load_steps": "1", "modal.modes": "1",
    "transient.duration": "s", "transient.step": "s", "transient.min_step": "s", "transient.output_interval": "s",
    "transient.rho_inf": "1", "transient.tolerance": "1", "transient.max_iterations": "1",
    "transient.damping.rayleigh_mass": "1/s", "transient.damping.rayleigh_stiffness": "s",
    "transient.damping.belt_axial": "s", "transient.damping.belt_bending": "s",
    "transient.spectrum.start": "s", "transient.spectrum.peaks": "1",
    "transient.rotation.*.speed": "rad/s", "transient.rotation.*.ramp_time": "s",
    "transient.rotation.*.amplitude": "rad", "transient.rotation.*.speed_amplitude": "rad/s",
    "transient.rotation.*.frequency": "Hz", "transient.rotation.*.phase": "rad",
    "transient.rotation.*.fluctuation_ramp": "s",
    "transient.torque.*.constant": "N m", "transient.torque.*.amplitude": "N m",
    "transient.hub_force.*.constant": "N", "transient.hub_force.*.amplitude": "N",
    **{f"transient.{kind}.*.{key}": unit for kind in ("torque", "hub_force")
       for key, unit in (("frequency", "Hz"), ("phase", "rad"), ("ramp_time", "s"))},
}


def param_units(key: str) -> str:
    """Units of a swept dotted key (`pulleys[1].radius`, `pulleys.A.radius`, `pulleys.1.center[0]`,
    `transient.hub_force[0].frequency` ...); "unknown" for a key not in PARAM_UNITS."""
    import re

    k = re.sub(r"\[\d+\]$", "", key.strip())  # one component of a vector value
    k = re.sub(r"\[(\d+)\]", r".\1", k)
    k = re.sub(r"^(pulleys|transient\.rotation|transient\.torque|transient\.hub_force)\.[^.]+\.", r"\1.*.", k)
    return PARAM_UNITS.get(k, "unknown")


def geometry_group(layout: Layout) -> GroupData:
    spans = [layout.span_name(i) for i in range(layout.n)]
    return GroupData(
        name="geometry",
        coords={"pulley": list(layout.names), "component": XY, "span": spans},
        variables=(
            Variable(name="pulley_center", data=layout.center, dims=("pulley", "component"), units="m",
                     description="solved pulley centres (the adjustable pulley placed so that the belt fits L0)"),
            Variable(name="pulley_radius", data=layout.radius, dims=("pulley",), units="m"),
            Variable(name="side", data=["inside" if s > 0 else "backside" for s in layout.side_sign],
                     dims=("pulley",), units="1", description="side of the belt that touches the pulley"),
            Variable(name="wrap_angle", data=layout.wrap_angle, dims=("pulley",), units="rad"),
            Variable(name="arc_length", data=layout.arc_length, dims=("pulley",), units="m"),
            Variable(name="span_length", data=layout.span_length, dims=("span",), units="m"),
            Variable(name="span_angle", data=np.pi - np.mod(np.pi - np.asarray(layout.span_angle), 2 * np.pi),
                     dims=("span",), units="rad",
                     description="direction of belt travel along the span, counter-clockwise from +x, in (-pi, pi]"),
            Variable(name="span_start", data=layout.span_start, dims=("span", "component"), units="m",
                     description="tangent point where the span leaves its first pulley"),
            Variable(name="span_end", data=layout.span_end, dims=("span", "component"), units="m",
                     description="tangent point where the span reaches its second pulley"),
            Variable(name="belt_length", data=np.array(layout.belt_length), dims=(), units="m"),
        ),
        attrs={"orientation": "counter-clockwise" if layout.orientation > 0 else "clockwise", "warnings": [],
               **({"adjust_turn_rad": float(layout.adjust_offset)} if layout.adjust_kind == "arm"
                  else {"adjust_offset_m": float(layout.adjust_offset)})},
    )


def static_group(model: DriveModel, res: StaticResult, target: float | None) -> GroupData:
    lay = model.layout
    spans = [lay.span_name(i) for i in range(lay.n)]
    return GroupData(
        name="static",
        coords={"pulley": list(lay.names), "component": XY, "span": spans, "end": ["start", "end"],
                "dof": list(model.dof_labels), "iteration": np.arange(1, len(res.residual_history) + 1),
                "node": np.arange(len(node_spans(model)))},
        variables=(
            Variable(name="span_tension", data=res.span_tension, dims=("span", "end"), units="N",
                     description="true axial force at the start and end of each span"),
            Variable(name="mean_tension", data=np.array(res.mean_tension), dims=(), units="N",
                     description="length-weighted mean span tension"),
            Variable(name="hub_load", data=res.hub_load, dims=("pulley", "component"), units="N",
                     description="force of the belt on each pulley (bearing load without the pulley's weight)"),
            Variable(name="hub_load_magnitude", data=np.hypot(*res.hub_load.T), dims=("pulley",), units="N"),
            Variable(name="pulley_center", data=res.pulley_center, dims=("pulley", "component"), units="m",
                     description="solved pulley centres"),
            Variable(name="span_length", data=lay.span_length, dims=("span",), units="m",
                     description="tangent-to-tangent length of each span, laid out at the solved pulley centres"),
            Variable(name="wrap_angle", data=lay.wrap_angle, dims=("pulley",), units="rad",
                     description="wrap angle of each pulley, laid out at the solved pulley centres"),
            Variable(name="pulley_rotation", data=res.pulley_rotation, dims=("pulley",), units="rad"),
            Variable(name="driver_torque", data=np.array(res.driver_torque), dims=(), units="N m",
                     description="torque the driver pulley's support applies to hold it"),
            Variable(name="adjust_offset", data=np.array(res.adjust_offset), dims=(),
                     units="rad" if lay.adjust_kind == "arm" else "m",
                     description="travel of the adjustable pulley from its given centre (an arm: the angle it turned)"),
            *_static_extras(res),
            Variable(name="node_position", data=belt_nodes(model, model.belt.element_coordinates(model.expand(res.q))),
                     dims=("node", "component"), units="m",
                     description="the belt's nodes at equilibrium, span after span from its start to its end "
                                 "(the figures draw the belt from them)"),
            Variable(name="node_span", data=node_spans(model), dims=("node",), units="1",
                     description="0-based span of each node"),
            Variable(name="node_slope", data=belt_nodes(model, model.belt.element_coordinates(model.expand(res.q)),
                                                     slope=True),
                     dims=("node", "component"), units="1",
                     description="the belt's slope r' = dr/dx at each node (x the reference arc length), with "
                                 "node_position the Hermite data of the elements' cubic shape functions"),
            Variable(name="span_element_length", data=_element_lengths(model), dims=("span",), units="m",
                     description="reference length of each span's ANCF elements (0 for a spring span: no elements)"),
            Variable(name="q", data=res.q, dims=("dof",), units=MIXED,
                     description="independent coordinates from the reference state, each in its dof_unit"),
            dof_unit_variable(model),
            Variable(name="dof_force_unit", data=[dof_force_unit(u) for u in dof_units(model)], dims=("dof",),
                     units="1", description="unit of the generalized force on each DOF (N for m, N m for rad or 1)"),
            Variable(name="spring_preload", data=res.spring_preload, dims=("dof",), units="mixed (see dof_force_unit)",
                     description="preload of the support spring on each DOF, in its dof_force_unit (0 if none)"),
            Variable(name="residual", data=res.residual_history, dims=("iteration",), units="1",
                     description="residual norm divided by the allowed residual (converged <= 1) after each Newton iteration"),
            Variable(name="load_factor", data=res.load_factor_history, dims=("iteration",), units="1"),
            *span_model_variables(model),
        ),
        attrs={"iterations": int(res.iterations), "tension_mode": res.tension_mode, "warnings": static_warnings(model, res),
               "tension_target_N": float(target) if target is not None else float("nan"),
               "n_dof": int(model.n_dof), **_running_attrs(model)},
    )


def _running_attrs(model: DriveModel) -> dict:
    """The running belt's speed (attributes of /static and /modal; none at rest)."""
    if not model.belt_speed:
        return {}
    from beltdyn.model.geometry import driver_speed_of

    return {"belt_speed_m_per_s": float(model.belt_speed),
            "driver_speed_rad_per_s": driver_speed_of(model.belt_speed, model.layout, model.driver)}


def span_model_variables(model: DriveModel) -> tuple[Variable, ...]:
    """The model and elements of each span ([spans], the fidelity ladder), dims (span,)."""
    models, counts = model.span_models()
    return (Variable(name="span_model", data=list(models), dims=("span",), units="1",
                     description='model of each span: "ancf", "string" (no bending) or "spring" (axial spring)'),
            Variable(name="span_elements", data=counts, dims=("span",), units="1",
                     description="ANCF elements of each span (0 for a spring span)"))


def ladder_variables(choice) -> tuple[Variable, ...]:
    """The automatic choice of the span models (`ladder.choose_models`), dims (span,)."""
    return (Variable(name="span_dofs", data=np.array([c.dofs for c in choice.spans], dtype=np.int64), dims=("span",),
                     units="1", description="the span's own DOFs (4 per element; a spring span none)"),
            Variable(name="span_estimated_error", data=np.array([c.estimate for c in choice.spans]), dims=("span",),
                     units="1", description="estimated relative frequency error of the modes below ladder_fmax_Hz "
                                            "that the span's model causes"))


def ladder_attrs(choice) -> dict:
    return {"ladder_fmax_Hz": float(choice.fmax), "ladder_rtol": float(choice.rtol),
            "ladder_estimated_error": float(choice.estimate), "ladder_met": int(choice.met),
            "ladder_solves": int(choice.solves)}


def unrepresented_variables(model: DriveModel, modes) -> tuple[dict, tuple[Variable, ...]]:
    """(coords, variables) of the modes below the band that spring spans leave out
    (`ladder.unrepresented_modes`); none when there are none."""
    if not modes:
        return {}, ()
    lay = model.layout
    return ({"unrepresented": np.arange(1, len(modes) + 1)}, (
        Variable(name="unrepresented_frequency", data=np.array([m[3] for m in modes]), dims=("unrepresented",),
                 units="Hz", description="a mode a spring span cannot represent (its own transverse or "
                                         "longitudinal mode, the span pinned at its ends): NOT among the modes"),
        Variable(name="unrepresented_span", data=[lay.span_name(m[0]) for m in modes], dims=("unrepresented",),
                 units="1"),
        Variable(name="unrepresented_kind", data=[m[1] for m in modes], dims=("unrepresented",), units="1"),
        Variable(name="unrepresented_order", data=np.array([m[2] for m in modes], dtype=np.int64),
                 dims=("unrepresented",), units="1")))


def static_warnings(model: DriveModel, res: StaticResult) -> list[str]:
    """What makes a static result doubtful for the engineer: a strain far beyond a belt's (the axial
    law with a constant EA means nothing there), a span close to slack (its smaller end tension below
    10 % of the mean), a pulley that slips (margin < 1)."""
    out = strain_warning(float(np.max(res.span_tension)), float(model.EA))
    T_min = res.span_tension.min(axis=1)  # (span,) the smaller end tension of each span
    for s_, t in enumerate(T_min):
        if t < SLACK_WARNING * abs(res.mean_tension):
            out.append(f"span {model.layout.span_name(s_)} is close to slack: {t:.4g} N at one end, "
                       f"{t / abs(res.mean_tension):.1%} of the mean tension {res.mean_tension:.4g} N (a "
                       f"dynamic load or a speed fluctuation can slacken it: the belt then flaps and slips)")
    if res.slip_margin is not None:
        for j, m in enumerate(res.slip_margin):
            if m < 1.0:
                out.append(f"pulley {model.layout.names[j]} slips: slip margin {m:.3g} < 1 "
                           f"(needs friction {res.required_friction[j]:.4g})")
    if res.wraps is not None:
        w, friction = res.wraps, model.pulley_friction
        step = np.abs(w.entry_tension - w.exit_tension) > ROUND_OFF * np.maximum(np.abs(w.entry_tension),
                                                                                 np.abs(w.exit_tension))
        for j in np.flatnonzero(step):
            if friction is None or friction[j] != friction[j]:
                torque = float(model.layout.radius[j] * abs(w.entry_tension[j] - w.exit_tension[j]))
                out.append(f"pulley {model.layout.names[j]} transmits {torque:.4g} N m but has no friction value: "
                           f"its wrap is taken as never slipping (no slip arc, no creep loss)")
    return out


def _static_extras(res: StaticResult) -> tuple[Variable, ...]:
    """Arm angles and torques, pivot reactions, the static load case and the slip margins (NaN where a
    pulley has no arm or no friction value)."""
    n = len(res.pulley_rotation)
    nan, nan2 = np.full(n, np.nan), np.full((n, 2), np.nan)

    def val(x, empty):
        return empty if x is None else x

    return (
        Variable(name="arm_angle", data=val(res.arm_angle, nan), dims=("pulley",), units="rad",
                 description="tensioner arm angle, counter-clockwise from +x (NaN: no arm)"),
        Variable(name="arm_torque", data=val(res.arm_torque, nan), dims=("pulley",), units="N m",
                 description="torque of the arm's spring on the arm, counter-clockwise positive (NaN: no arm)"),
        Variable(name="arm_free_angle", data=val(res.arm_free_angle, nan), dims=("pulley",), units="rad",
                 description="free angle of the arm's spring that gives this equilibrium (NaN: no arm or no spring)"),
        Variable(name="pivot_reaction", data=val(res.pivot_reaction, nan2), dims=("pulley", "component"), units="N",
                 description="force of the pivot on the arm (NaN: no arm)"),
        Variable(name="applied_torque", data=val(res.applied_torque, np.zeros(n)), dims=("pulley",), units="N m",
                 description="accessory torques of the static load case ([[static.torque]])"),
        Variable(name="required_friction", data=val(res.required_friction, nan), dims=("pulley",), units="1",
                 description="ln(T_tight / T_slack) / wrap angle (capstan); inf where a span is slack"),
        Variable(name="slip_margin", data=val(res.slip_margin, nan), dims=("pulley",), units="1",
                 description="friction / required_friction (< 1: slips; NaN: no friction given)"),
    ) + _wrap_variables(res)


def _wrap_variables(res: StaticResult) -> tuple[Variable, ...]:
    """The wraps' creep state (`beltdyn.model.wraps`), none without it."""
    w = res.wraps
    if w is None:
        return ()
    return (
        Variable(name="slip_arc", data=w.slip_arc, dims=("pulley",), units="rad",
                 description="capstan slip arc at the wrap's exit, |ln((T_e - c)/(T_x - c))| / friction (0: no "
                             "tension step or no friction given; above the wrap: gross slip)"),
        Variable(name="adhesion_arc", data=w.adhesion_arc, dims=("pulley",), units="rad",
                 description="adhesion arc at the wrap's entry, max(wrap - slip_arc, 0)"),
        Variable(name="rim_speed_ratio", data=w.rim_speed_ratio, dims=("pulley",), units="1",
                 description="rim speed over the driver's: stretch at this wrap's entry / stretch at the driver's"),
        Variable(name="creep_power_loss", data=w.creep_power_loss, dims=("pulley",), units="W",
                 description="power lost to creep in the slip arc at the belt speed (0 at rest)"),
        Variable(name="gross_slip", data=w.gross_slip.astype(np.int8), dims=("pulley",), units="1",
                 description="1 where the slip arc would exceed the wrap (slip margin < 1)"),
        Variable(name="wrap_reference_length", data=w.stress_free_length, dims=("pulley",), units="m",
                 description="stress-free belt length on the wrap (belt.wraps = creep: adhesion arc at the entry "
                             "stretch, slip arc integrated over the capstan profile, what the belt-length budget "
                             "counts; rigid: the arc length R wrap)"),
    )


def belt_nodes(model: DriveModel, E: np.ndarray, *, slope: bool = False) -> np.ndarray:
    """(..., n_node, 2) the belt's node positions (or motions) of element states E (..., n_elem, 8): each
    span's element start nodes and its last element's end node, span after span; with slope=True the
    nodes' slopes r' = dr/dx (or their motions) instead."""
    k = 2 if slope else 0
    parts = [E[..., :0, 0:2]]
    for els in model.belt.span_elements:  # a spring span has no nodes (no elements)
        parts.append(E[..., els, k:k + 2])
        parts.append(E[..., els[-1:], 4 + k:6 + k])
    return np.concatenate(parts, axis=-2)


def _element_lengths(model: DriveModel) -> np.ndarray:
    """(n_span,) reference length of each span's (equal) elements, 0 for a spring span (none)."""
    counts = np.array([len(els) for els in model.belt.span_elements], dtype=float)
    length = np.asarray(model.belt.reference_length, dtype=float)
    return np.divide(length, counts, out=np.zeros_like(length), where=counts > 0)


def node_spans(model: DriveModel) -> np.ndarray:
    """(n_node,) 0-based span of each node of `belt_nodes`."""
    return np.concatenate([np.zeros(0)] + [np.full(len(els) + 1 if len(els) else 0, s)
                                           for s, els in enumerate(model.belt.span_elements)]).astype(np.int64)


def modal_group(model: DriveModel, res: ModalResult, q: np.ndarray | None = None, unrepresented=()) -> GroupData:
    """/modal; with the equilibrium q also the shapes' motion of the belt's nodes (`node_shape`);
    unrepresented: the modes spring spans leave out (`ladder.unrepresented_modes`)."""
    from beltdyn.analysis.modal import KINDS

    lay = model.layout
    extra = ()
    if q is not None:
        motion = model.belt.element_coordinates_batch(model.expand_motion(q, res.shapes), offset=False)
        nodes = belt_nodes(model, motion)
        turns = belt_nodes(model, motion, slope=True)
        extra = (Variable(name="node_shape", data=np.real(nodes), dims=("mode", "node", "component"),
                          units="m per sqrt(kg m^2)",
                          description="motion of the belt's nodes (/static node_position) in each mass-normalized "
                                      "shape (at a belt speed the real part, see node_shape_imag)"),
                 Variable(name="node_shape_slope", data=np.real(turns), dims=("mode", "node", "component"),
                          units="1 per sqrt(kg m^2)",
                          description="motion of the belt's slopes (/static node_slope) in each mass-normalized "
                                      "shape (real part): the Hermite data of the elements' shape functions"),)
        if np.iscomplexobj(nodes):
            extra += (Variable(name="node_shape_imag", data=np.imag(nodes), dims=("mode", "node", "component"),
                               units="m per sqrt(kg m^2)", description="imaginary part of node_shape"),)
    u_coords, u_vars = unrepresented_variables(model, unrepresented)
    return GroupData(
        name="modal",
        coords={"mode": np.arange(1, len(res.frequency) + 1), "dof": list(model.dof_labels),
                "energy_kind": list(KINDS), "belt_span": [lay.span_name(i) for i in range(lay.n)],
                "rigid": np.arange(1, res.n_rigid + 1),
                **({"node": np.arange(len(node_spans(model)))} if q is not None else {}), **u_coords},
        variables=(
            Variable(name="frequency", data=res.frequency, dims=("mode",), units="Hz"),
            Variable(name="kind", data=list(res.kind), dims=("mode",), units="1"),
            Variable(name="order", data=res.order.astype(np.int64), dims=("mode",), units="1",
                     description="half-wave count for transverse modes, rank within the kind otherwise"),
            Variable(name="span", data=res.span.astype(np.int64), dims=("mode",), units="1",
                     description="1-based span number of the mode, 0 if none"),
            Variable(name="label", data=list(res.label), dims=("mode",), units="1"),
            Variable(name="energy_share", data=res.energy_share, dims=("mode", "energy_kind"), units="1",
                     description="share of the modal kinetic energy"),
            Variable(name="span_share", data=res.span_share, dims=("mode", "belt_span"), units="1"),
            Variable(name="midspan_displacement", data=np.real(res.midspan_displacement), dims=("mode", "belt_span"),
                     units="m per sqrt(kg m^2)",
                     description="mid-span displacement of each mass-normalized shape across the chord between the "
                                 "span's moving end points (the definition of /transient midspan_displacement)"),
            Variable(name="shape", data=np.real(res.shapes), dims=("mode", "dof"), units=MIXED,
                     description="mass-normalized mode shapes (phi^T M phi = 1): entry i in dof_unit[i] "
                                 "per sqrt(kg m^2); at a belt speed the real part (see shape_imag)"),
            dof_unit_variable(model),
            Variable(name="rigid_frequency", data=res.rigid_frequency, dims=("rigid",), units="Hz"),
            *extra,
            *_running_modal(res),
            *u_vars,
        ),
        attrs={"n_rigid": int(res.n_rigid), "solver": res.solver, "n_dof": int(model.n_dof), "warnings": [],
               **_running_attrs(model), **({"critical_belt_speed_m_per_s": float(res.critical_speed)}
                                          if np.isfinite(res.critical_speed) else {})},
    )


def _running_modal(res: ModalResult) -> tuple:
    """The running belt's modes: complex shapes stored as `shape` (real part) and `shape_imag` (imaginary
    part), phi = shape + 1j shape_imag with phi^H M phi = 1 and the largest entry real and positive, the
    motion Re(phi e^(s t)); likewise `midspan_displacement(_imag)`; `growth_rate` Re s and `stability`."""
    if res.growth_rate is None:
        return ()
    return (
        Variable(name="shape_imag", data=np.imag(res.shapes), dims=("mode", "dof"), units=MIXED,
                 description="imaginary part of the complex mode shapes (shape + 1j shape_imag, phi^H M phi = 1)"),
        Variable(name="midspan_displacement_imag", data=np.imag(res.midspan_displacement), dims=("mode", "belt_span"),
                 units="m per sqrt(kg m^2)", description="imaginary part of midspan_displacement"),
        Variable(name="growth_rate", data=res.growth_rate, dims=("mode",), units="1/s",
                 description="real part of the eigenvalue s (0: stable; > 0: divergence (frequency 0) or flutter)"),
        Variable(name="stability", data=list(res.stability), dims=("mode",), units="1",
                 description="stable, divergence or flutter"),
    )


def sweep_group(cfg, result) -> GroupData:
    """/sweep: a `case` axis, the swept parameters as per-case variables, tracked frequencies."""
    import json

    from beltdyn.results.schema import var_name

    spec = result.spec
    n = spec.n_cases
    names = [p.name for p in cfg.pulleys]
    spans = [f"{names[i]}-{names[(i + 1) % len(names)]}" for i in range(len(names))]
    coords: dict = {"case": np.arange(1, n + 1)}
    variables = []
    for k, p in enumerate(spec.params):
        vals = [v[k] for v in result.values]
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals)
        variables.append(Variable(name=f"param_{var_name(p.key)}", data=np.array(vals, dtype=float) if numeric
                                  else [str(v) for v in vals], dims=("case",),
                                  units=param_units(p.key) if numeric else "1",
                                  description=f"swept key {p.key}"))
    variables += [
        Variable(name="wall_time", data=result.wall_time, dims=("case",), units="s",
                 description="wall time of the case in its worker (not reproducible)"),
        Variable(name="failed", data=result.failed, dims=("case",), units="1", description="1: the case failed"),
        Variable(name="error", data=result.errors, dims=("case",), units="1"),
    ]
    if result.frequency is not None:
        k = result.frequency.shape[1]
        coords["mode"] = np.arange(1, k + 1)
        variables += [
            Variable(name="frequency", data=result.frequency, dims=("case", "mode"), units="Hz",
                     description="tracked natural frequencies (NaN for failed cases)"),
            Variable(name="label", data=[str(x) for x in result.label] + [""] * (k - len(result.label)),
                     dims=("mode",), units="1", description="classification of each tracked mode at the first case"),
            Variable(name="kind", data=result.kind, dims=("case", "mode"), units="1"),  # (shared str objects)
            Variable(name="order", data=result.order, dims=("case", "mode"), units="1"),
            Variable(name="span", data=result.span, dims=("case", "mode"), units="1"),
            Variable(name="mac", data=result.mac, dims=("case", "mode"), units="1",
                     description="MAC with the tracked mode of the parent case (1 at the first case)"),
        ]
    if result.growth_rate is not None and result.extras.get("belt_speed") is not None:
        variables.append(Variable(name="growth_rate", data=result.growth_rate, dims=("case", "mode"), units="1/s",
                                  description="real part of the tracked eigenvalue s (0: stable; > 0 with "
                                              "frequency 0: divergence, with a frequency: flutter)"))
    variables += _campbell_variables(cfg, result, coords, spans)
    dims_of = {"mean_tension": ((), "N"), "span_tension": (("belt_span", "end"), "N"),
               "hub_load": (("pulley", "component"), "N"), "pulley_center": (("pulley", "component"), "m"),
               "n_slack_events": ((), "1"), "arm_angle": (("pulley",), "rad"), "arm_torque": (("pulley",), "N m"),
               "slip_margin": (("pulley",), "1"), "belt_speed": ((), "m/s"), "driver_speed": ((), "rad/s")}
    for key, arr in result.extras.items():
        base = key.replace("_first_harmonic", "").replace("_half_range", "")
        if key in dims_of:
            dims, units = dims_of[key]
        elif base == "span_tension":
            dims, units = ("belt_span", "end"), "N"
        elif base == "hub_load":
            dims, units = ("pulley", "component"), "N"
        elif base == "bearing_force":
            dims, units = ("bearing", "component"), "N"
            from beltdyn.model.supports import support_of

            coords["bearing"] = [p.name for p in cfg.pulleys if support_of(p).springs()]
        else:
            continue
        variables.append(Variable(name=key, data=arr, dims=("case", *dims), units=units))
    coords.update({"belt_span": spans, "end": ["start", "end"], "pulley": names, "component": ["x", "y"]})
    used = {d for v in variables for d in v.dims}
    coords = {d: c for d, c in coords.items() if d in used}
    return GroupData(name="sweep", coords=coords, variables=tuple(variables),
                     attrs={"analysis": spec.analysis, "zip": int(spec.zip), "shape": json.dumps(list(spec.shape)),
                            "params": json.dumps(spec.to_json()["params"]), "n_failed": int(result.failed.sum())})


def _campbell_variables(cfg, result, coords: dict, spans: list[str]) -> list:
    """A speed sweep's resonance table (`running.campbell`): each crossing of a tracked mode with an
    engine-order line of [running] orders on a `crossing` axis, and each loss of stability on an
    `instability` axis (added to coords)."""
    from beltdyn.analysis.running import campbell, speed_axis

    if not speed_axis(result):
        return []
    orders = cfg.running.orders if cfg.running is not None else ()
    crossings, unstable = campbell(result, orders, spans)
    coords["crossing"] = np.arange(1, len(crossings) + 1)
    coords["instability"] = np.arange(1, len(unstable) + 1)
    return [
        Variable(name="crossing_order", data=np.array([x.order for x in crossings], dtype=float), dims=("crossing",),
                 units="1", description="engine order k of the line f = k |Omega| / (2 pi) ([running] orders)"),
        Variable(name="crossing_mode", data=np.array([x.mode + 1 for x in crossings], dtype=np.int64),
                 dims=("crossing",), units="1", description="tracked mode (the sweep's mode axis, 1-based)"),
        Variable(name="crossing_label", data=[x.label for x in crossings], dims=("crossing",), units="1"),
        Variable(name="crossing_driver_speed", data=np.array([x.driver_speed for x in crossings], dtype=float),
                 dims=("crossing",), units="rad/s", description="driver speed of the crossing (interpolated)"),
        Variable(name="crossing_belt_speed", data=np.array([x.belt_speed for x in crossings], dtype=float),
                 dims=("crossing",), units="m/s"),
        Variable(name="crossing_frequency", data=np.array([x.frequency for x in crossings], dtype=float),
                 dims=("crossing",), units="Hz"),
        Variable(name="instability_kind", data=[x.kind for x in unstable], dims=("instability",), units="1",
                 description="divergence (a frequency reaching zero: critical speed) or flutter"),
        Variable(name="instability_mode", data=np.array([x.mode + 1 for x in unstable], dtype=np.int64),
                 dims=("instability",), units="1"),
        Variable(name="instability_label", data=[x.label for x in unstable], dims=("instability",), units="1"),
        Variable(name="instability_driver_speed", data=np.array([x.driver_speed for x in unstable], dtype=float),
                 dims=("instability",), units="rad/s", description="critical driver speed (interpolated)"),
        Variable(name="instability_belt_speed", data=np.array([x.belt_speed for x in unstable], dtype=float),
                 dims=("instability",), units="m/s", description="critical belt speed (interpolated)"),
    ]


def response_group(system, res) -> GroupData:
    """/response: a `speed` axis (the driver's mean speed) and an `order` axis; every output as its
    amplitude and phase (y(t) = amplitude cos(omega t + phase), omega = order x speed)."""
    from beltdyn.analysis.response import coordinates

    variables = [
        Variable(name="frequency", data=res.frequency, dims=("speed", "order"), units="Hz",
                 description="excitation frequency order x speed / (2 pi)"),
        Variable(name="belt_speed", data=res.belt_speed, dims=("speed",), units="m/s",
                 description="belt speed speed x R_driver"),
        Variable(name="static_span_tension", data=res.static_tension, dims=("speed", "span", "end"), units="N",
                 description="span-end tensions of the equilibrium each speed is linearized about (a span goes "
                             "slack where span_tension_amplitude exceeds them)"),
    ]
    for name, y in res.outputs.items():
        dims = ("speed", "order", *res.dims[name])
        variables.append(Variable(name=f"{name}_amplitude", data=np.abs(y), dims=dims, units=res.units[name],
                                  description=f"amplitude of the harmonic {name}"))
        variables.append(Variable(name=f"{name}_phase", data=np.angle(y), dims=dims, units="rad",
                                  description=f"phase of the harmonic {name} (the excitation's phases as given)"))
    return GroupData(
        name="response",
        coords={"speed": res.speed, "order": res.orders, **coordinates(system)},
        coord_units={"speed": "rad/s", "order": "1"},
        variables=tuple(variables),
        attrs={"prescribed": list(res.prescribed), "warnings": list(res.warnings),
               "model": "linearized about the static equilibrium; the running belt's transport terms only at the "
                        "speed of [running] (its running equilibrium), none without it"},
    )
