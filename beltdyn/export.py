"""Result dataclasses -> HDF5 group descriptions (names, dimensions, units; DESIGN section 4).

No h5py here: `results_io` writes what these functions describe.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .results_io import GroupData, Variable

if TYPE_CHECKING:  # keep `beltdyn geometry` from importing the solvers
    from .geometry import Layout
    from .modal import ModalResult
    from .system import System as DriveModel
    from .static import StaticResult

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
    "pulleys.*.arm_free_angle": "rad", "pulleys.*.arm_damping": "N m s/rad", "pulleys.*.arm_friction": "N m",
    "pulleys.*.arm_range": "rad", "pulleys.*.friction": "1", "static.torque.*.value": "N m",
    "tension.target": "N", "mesh.elements_per_span": "1",
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
                "dof": list(model.dof_labels), "iteration": np.arange(1, len(res.residual_history) + 1)},
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
        ),
        attrs={"iterations": int(res.iterations), "tension_mode": res.tension_mode, "warnings": static_warnings(model, res),
               "tension_target_N": float(target) if target is not None else float("nan"),
               "n_dof": int(model.n_dof)},
    )


STRAIN_WARNING = 0.05  # belt strain above which the constant-EA axial law is flagged (real belts: ~1 % at most)


SLACK_WARNING = 0.1  # a span whose smaller end tension is below this share of the mean tension is flagged


def strain_warning(T: float, EA: float, when: str = "") -> list[str]:
    """[a warning] if the largest span tension T (N) stretches the belt beyond STRAIN_WARNING, else [].
    when: where in a run (e.g. " at t = 0.2 s"), empty for a static result."""
    from .system import stretch_for_tension

    strain = stretch_for_tension(T, EA) - 1.0 if np.isfinite(T) and T > 0 else 0.0  # engineering strain
    if strain <= STRAIN_WARNING:
        return []
    return [f"the belt is stretched by {strain:.1%}{when} (tension {T:.4g} N on EA = {EA:.4g} N): far beyond a "
            f"belt's working strain, where the axial law (constant EA) no longer describes it; check "
            f"tension.target and belt.EA"]


def static_warnings(model: DriveModel, res: StaticResult) -> list[str]:
    """What makes a static result doubtful for the engineer: a strain far beyond a belt's (the axial
    law with a constant EA means nothing there), a span close to slack (its smaller end tension below
    10 % of the mean), a pulley that slips (margin < 1)."""
    out = strain_warning(float(np.max(res.span_tension)), float(np.max(model.belt.elements.EA)))
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
    )


def modal_group(model: DriveModel, res: ModalResult) -> GroupData:
    from .modal import KINDS

    lay = model.layout
    return GroupData(
        name="modal",
        coords={"mode": np.arange(1, len(res.frequency) + 1), "dof": list(model.dof_labels),
                "energy_kind": list(KINDS), "belt_span": [lay.span_name(i) for i in range(lay.n)],
                "rigid": np.arange(1, res.n_rigid + 1)},
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
            Variable(name="midspan_displacement", data=res.midspan_displacement, dims=("mode", "belt_span"),
                     units="m per sqrt(kg m^2)",
                     description="mid-span displacement of each mass-normalized shape across the chord between the "
                                 "span's moving end points (the definition of /transient midspan_displacement)"),
            Variable(name="shape", data=res.shapes, dims=("mode", "dof"), units=MIXED,
                     description="mass-normalized mode shapes (phi^T M phi = 1): entry i in dof_unit[i] "
                                 "per sqrt(kg m^2)"),
            dof_unit_variable(model),
            Variable(name="rigid_frequency", data=res.rigid_frequency, dims=("rigid",), units="Hz"),
        ),
        attrs={"n_rigid": int(res.n_rigid), "solver": res.solver, "n_dof": int(model.n_dof), "warnings": []},
    )


def sweep_group(cfg, result) -> GroupData:
    """/sweep: a `case` axis, the swept parameters as per-case variables, tracked frequencies."""
    import json

    from .sweep import var_name

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
    dims_of = {"mean_tension": ((), "N"), "span_tension": (("belt_span", "end"), "N"),
               "hub_load": (("pulley", "component"), "N"), "pulley_center": (("pulley", "component"), "m"),
               "n_slack_events": ((), "1"), "arm_angle": (("pulley",), "rad"), "arm_torque": (("pulley",), "N m"),
               "slip_margin": (("pulley",), "1")}
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
            from .supports import support_of

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


def response_group(system, res) -> GroupData:
    """/response: a `speed` axis (the driver's mean speed) and an `order` axis; every output as its
    amplitude and phase (y(t) = amplitude cos(omega t + phase), omega = order x speed)."""
    from .response import coordinates

    variables = [
        Variable(name="frequency", data=res.frequency, dims=("speed", "order"), units="Hz",
                 description="excitation frequency order x speed / (2 pi)"),
        Variable(name="belt_speed", data=res.belt_speed, dims=("speed",), units="m/s",
                 description="belt speed speed x R_driver"),
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
               "model": "linearized about the static equilibrium; transport terms of the running belt not included"},
    )
