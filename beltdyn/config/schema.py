"""The schema: one frozen dataclass per TOML table, each field declared with `key(KIND, default,
doc=..., units=...)`; the keys and their docs derived from the declarations (`valid_keys`,
`key_docs`)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import MISSING, Field, dataclass, field
from typing import Any, NamedTuple

from beltdyn.config.kinds import (_Array, AXIAL_LAWS, BOOL, _Checker, _Choice, CURVATURES, DEFAULT_STEP, _dump, FLOAT, _Int,
                                  _join, _Key, key, _Kind, MAX_GAUSS_POINTS, NAME, NONNEGFLOAT, _Number, _Numbers,
                                  _Pair, _Params, _parse, POSFLOAT, POSINT, RANGE2, _schema, _show, SIDES,
                                  SPAN_MODELS, STIFFNESS, STR, SUPPORTS, _Table, TENSION_MODES, TEXT, UNIT, VEC2,
                                  WRAP_MODELS)


# ------------------------------------------------------------------------------ the declarations
@dataclass(frozen=True, kw_only=True)
class Belt:
    """Belt properties. length: undeformed loop length L0 (m); EA (N); EI (N m^2); kg/m.

    section: a V-ribbed section of the shipped table (`beltdyn/data/belt_sections.toml`: PH, PJ, PK, PL,
    PM), "6PK" or "PK" with ribs = 6; it gives EA, EI and mass_per_length (per rib x ribs) where they
    are not given (given ones win), and the offset of a pulley's effective_diameter. Once loaded, EA,
    EI and mass_per_length are always set, section is the bare section ("PK") and ribs the count;
    `derived` names the values that came from the section (not a TOML key: the resolved TOML leaves
    them out, so that a changed section or rib count gives them anew, and shows them in a comment).

    wraps: the belt on the pulleys, "creep" (an adhesion arc at each wrap's entry and a capstan slip arc
    at its exit, the wraps' stress-free length in the belt-length budget: `beltdyn.model.wraps`,
    docs/wraps.md) or "rigid" (inextensible wraps without slip: the paper's model). axial_law: the bar
    law of every span, spring and wrap (`beltdyn.model.barlaw`), "green-lagrange" (N = EA eps lambda,
    eps = (lambda^2 - 1)/2: paper Eqs. 12-14) or "linear" (N = EA (lambda - 1): catalog EA values).
    """

    length: float = key(POSFLOAT, doc="undeformed loop length L0", units="m")
    EA: float = key(POSFLOAT, None, doc="axial stiffness (not set: belt.section's EA per rib x ribs)", units="N")
    EI: float = key(NONNEGFLOAT, None, doc="bending stiffness (not set: belt.section's EI per rib x ribs)",
                    units="N m^2")
    mass_per_length: float = key(POSFLOAT, None, doc="mass per unit length (not set: belt.section's mass per "
                                                     "rib x ribs)", units="kg/m")
    section: str | None = key(STR, None, doc='V-ribbed section of the shipped table ("PK" or "6PK"; PH, PJ, PK, '
                                             "PL, PM): EA, EI, mass per length and the effective-diameter offset")
    ribs: int | None = key(POSINT, None, doc="number of ribs of belt.section (or in its name, \"6PK\")")
    wraps: str = key(_Choice(*WRAP_MODELS), "creep",
                     doc='the belt on the pulleys: "creep" (adhesion and slip arcs, stretched wraps; in the transient '
                         'a pulley with a friction value may slip, docs/wraps.md) or "rigid" (inextensible wraps '
                         'that never slip)')
    axial_law: str = key(_Choice(*AXIAL_LAWS), "green-lagrange",
                         doc='axial force of a stretch lambda: "green-lagrange" EA (lambda^2 - 1) lambda / 2 or '
                             '"linear" EA (lambda - 1)')
    derived: tuple[str, ...] = field(default=(), compare=False)  # the values taken from the section


@dataclass(frozen=True, kw_only=True)
class Decoupler:
    """pulleys[i].decoupler: a decoupler (overrunning alternator pulley, OAD) between the pulley's hub and the
    accessory's rotor: the rotor (inertia, kg m^2, its own rotation DOF) behind a torsion spring (stiffness,
    N m/rad) with viscous damping across it (N m s/rad); with one_way a one-way clutch in series that transmits
    only driving torque (the belt driving the rotor) and overruns otherwise (transient; static, modal and
    response hold the clutch engaged). The pulley's own inertia is then the hub's alone; the accessory torques
    and rotational_damping act on the rotor."""

    inertia: float = key(POSFLOAT, doc="inertia of the rotor behind the decoupler", units="kg m^2")
    stiffness: float = key(POSFLOAT, doc="torsion spring between the hub and the rotor", units="N m/rad")
    damping: float = key(NONNEGFLOAT, 0.0, doc="viscous damping across the spring", units="N m s/rad")
    one_way: bool = key(BOOL, True, doc="a one-way clutch in series: transmits only driving torque, overruns "
                                        "otherwise (transient)")


@dataclass(frozen=True, kw_only=True)
class Pulley:
    """A rigid pulley. center (m, x right / y up); radius (m); mass (kg); inertia (kg m^2).

    side: the belt touches it from the inside of the loop or on its backside.
    support: "fixed" centre (rotation only), "slide" (moves along slide_direction against
    bearing_stiffness, N/m), "bearing" (moves in x and y against bearing_stiffness (kx, ky), N/m) or
    "arm" (a tensioner: the centre turns about arm_pivot on an arm of length |center - arm_pivot|,
    angle phi counter-clockwise from +x, against the torsion spring arm_stiffness (zero torque at
    arm_free_angle), viscous arm_damping and the dry friction torques arm_friction (loading: turning away from
    arm_free_angle) and arm_friction_unloading (turning toward it); the pulley's mass
    adds m l^2 to arm_inertia through the kinematics).
    adjustable: the pulley moved along its slide (turned on its arm) to fit L0 and to set the tension.
    friction: effective coefficient of friction belt-pulley (V-ribbed: the wedge-effective value), for
    the slip margin.
    driver: its rotation is held in the static analysis and reacts the applied torques.
    slide_range: (min, max) travel along the slide from `center`, m (None: unbounded).
    """

    name: str = key(NAME, doc="name, unique; loads and rotations refer to it")
    center: tuple[float, float] = key(VEC2, doc="centre (x right, y up); a slide's origin", units="m")
    radius: float = key(POSFLOAT, None, doc="radius at the belt's neutral line (or effective_diameter)",
                        units="m")
    effective_diameter: float | None = key(POSFLOAT, None, doc="grooved pulley's effective diameter (ISO "
                                                               "9981/9982), instead of radius: radius = "
                                                               "(effective_diameter + belt.section's diameter "
                                                               "offset) / 2", units="m")
    mass: float = key(POSFLOAT, doc="mass", units="kg")
    inertia: float = key(POSFLOAT, doc="moment of inertia about its axis", units="kg m^2")
    side: str = key(_Choice(*SIDES), "inside", doc="the belt touches it from the inside of the loop or on its backside")
    support: str = key(_Choice(*SUPPORTS), "fixed",
                       doc="fixed centre, a slide along slide_direction, or a bearing moving in x and y")
    slide_direction: tuple[float, float] = key(VEC2, (1.0, 0.0), doc="direction of the slide (normalized)")
    bearing_stiffness: tuple[float, float] = key(STIFFNESS, (0.0, 0.0),
                                                 doc="spring of a slide (one number) or a bearing ([kx, ky])",
                                                 units="N/m")
    adjustable: bool = key(BOOL, False, doc="moved along its slide (turned on its arm) to fit L0 and to set "
                                            "the tension")
    driver: bool = key(BOOL, False, doc="rotation held in the static analysis, reacting the applied torques")
    slide_range: tuple[float, float] | None = key(RANGE2, None, doc="[min, max] travel along the slide from "
                                                                    "center (not set: unbounded)", units="m")
    arm_pivot: tuple[float, float] | None = key(VEC2, None, doc="fixed pivot of a tensioner arm (support = "
                                                                "\"arm\"); the arm runs to `center`", units="m")
    arm_inertia: float = key(NONNEGFLOAT, 0.0, omit_default=True,
                             doc="inertia of the arm alone about its pivot (the pulley's adds itself)", units="kg m^2")
    arm_stiffness: float = key(NONNEGFLOAT, 0.0, omit_default=True, doc="torsion spring of the arm",
                               units="N m/rad")
    arm_free_angle: float | None = key(FLOAT, None, doc="arm angle (counter-clockwise from +x) at which the "
                                                        "spring torque is zero (on the branch of arm_range when "
                                                        "given: a spring wound more than half a turn needs stops; "
                                                        "not set: relaxed at the L0-fit angle)", units="rad")
    arm_damping: float = key(NONNEGFLOAT, 0.0, omit_default=True, doc="viscous damping of the arm",
                             units="N m s/rad")
    arm_friction: float = key(NONNEGFLOAT, 0.0, omit_default=True,
                              doc="dry friction torque of the arm's pivot damper while the arm is loaded (turns "
                                  "away from arm_free_angle, winding its spring; transient only)", units="N m")
    arm_friction_unloading: float | None = key(NONNEGFLOAT, None,
                                               doc="dry friction torque while the arm is unloaded (turns toward "
                                                   "arm_free_angle, following the belt; needs arm_free_angle; "
                                                   "not set: arm_friction; transient only)", units="N m")
    arm_range: tuple[float, float] | None = key(RANGE2, None, doc="[min, max] arm angle between the stops",
                                                units="rad")
    friction: float | None = key(POSFLOAT, None, doc="effective belt-pulley friction coefficient (slip margin)",
                                 units="1")
    rotational_damping: float = key(NONNEGFLOAT, 0.0, omit_default=True,
                                    doc="viscous torque to ground -d omega on the pulley's rotation (a generator or "
                                        "pump load growing with speed; static at speed, transient, response)",
                                    units="N m s/rad")
    decoupler: Decoupler | None = key(_Table(Decoupler), None,
                                      doc="{ inertia, stiffness, damping, one_way }: a decoupler (OAD) between the "
                                          "hub and the accessory's rotor")

    @property
    def n_translation(self) -> int:
        return {"fixed": 0, "slide": 1, "bearing": 2, "arm": 0}[self.support]

    @property
    def arm_length(self) -> float:
        """l = |center - arm_pivot| (m), 0 without an arm."""
        if self.arm_pivot is None:
            return 0.0
        return math.hypot(self.center[0] - self.arm_pivot[0], self.center[1] - self.arm_pivot[1])

    @property
    def arm_angle(self) -> float:
        """The drawn arm angle (rad): direction arm_pivot -> center."""
        if self.arm_pivot is None:
            return 0.0
        return math.atan2(self.center[1] - self.arm_pivot[1], self.center[0] - self.arm_pivot[0])


@dataclass(frozen=True, kw_only=True)
class Tension:
    """target: static span tension (N) reached as `mode` says; None: the geometry alone decides.
    Default mode: "adjust" when a pulley is adjustable, else "prestrain".

    mode "adjust": spans stress-free in the L0 geometry, the adjustable pulley moved along its slide
    (or turned on its arm) until the mean span tension equals the target (the paper's bench). mode
    "prestrain": pulley centres kept, the spans' reference length shortened so that their initial
    tension is the target. mode "spring": spans stress-free in the L0 geometry (the adjustable arm
    turned to fit L0), then the arm's spring (arm_free_angle) turns the arm until equilibrium: the
    tension is an output (no target). mode "length": every centre as given (no adjustable pulley), the
    belt of undeformed length belt.length stretched onto the path (a stretch-fit belt on fixed centres):
    the tension is an output (no target); a belt longer than its path (slack) or one needing a stretch
    above 1.2 is an error naming belt.length.
    """

    target: float | None = key(POSFLOAT, None, doc="static span tension (not set: the geometry alone decides)",
                               units="N")
    mode: str = key(_Choice(*TENSION_MODES), "adjust",
                    doc="move the adjustable pulley, prestrain the spans, let the tensioner arm's spring set it, "
                        "or \"length\": the belt of belt.length on the centres as given, the tension an output "
                        "(default: adjust if a pulley is adjustable)")


@dataclass(frozen=True, kw_only=True)
class Mesh:
    elements_per_span: int = key(POSINT, 10, doc="ANCF beam elements per free span")


@dataclass(frozen=True, kw_only=True)
class SpanSetting:
    """[spans."A-C"]: the model and mesh of one span (the span from pulley A to pulley C, named as the
    console names it), overriding mesh.elements_per_span and model.curvature for that span.

    model "ancf": ANCF beam elements with the bending of model.curvature ("linear" when that is "none");
    "string": ANCF elements without bending (EI = 0); "spring": an axial spring between the span's
    tangent points (EA / L, Green-Lagrange law, the span's mass lumped at its ends), no transverse
    DOFs. Not set: the span follows [mesh] and [model] ("string" where model.curvature = "none")."""

    model: str | None = key(_Choice(*SPAN_MODELS), None,
                            doc='"ancf", "string" (no bending) or "spring" (axial spring, no transverse DOFs); not '
                                'set: ancf with model.curvature')
    elements: int | None = key(POSINT, None, doc="elements of this span (ancf, string); not set: "
                                                 "mesh.elements_per_span")


def span_name_key(name: str) -> str:
    """A span name as a TOML key: bare when TOML allows it (A-C), else quoted ("crank pulley-A")."""
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


class _Spans(_Kind):
    """[spans]: a table of span name -> SpanSetting (names checked against the pulleys afterwards)."""

    is_table = True
    label = 'table of span name -> {model, elements}'

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple[tuple[str, SpanSetting], ...]:
        if not isinstance(value, dict):
            raise chk.fail(key, 'must be a table of span tables, e.g. [spans."A-C"] with model and elements')
        out = []
        for name, entry in value.items():
            path = f"{key}.{span_name_key(str(name))}"
            if not isinstance(entry, dict):
                raise chk.fail(path, f'must be a table (model = "ancf" | "string" | "spring", elements), '
                                     f"got {_show(entry)}")
            setting = _parse(chk, path, entry, SpanSetting)
            if setting.model == "spring" and setting.elements is not None:
                raise chk.fail(f"{path}.elements", "a spring span has no elements (an axial spring between the "
                                                   'tangent points); remove elements or use model = "string"')
            out.append((str(name), setting))
        return tuple(out)

    def dump(self, value: tuple[tuple[str, SpanSetting], ...]) -> dict[str, dict[str, Any]]:
        return {name: _dump(setting) for name, setting in value}


@dataclass(frozen=True, kw_only=True)
class ModelOptions:
    """gravity (m/s^2, vector in the drive plane); curvature: "linear" (paper Eq. 17), "exact"
    (Eq. 15) or "none" (string); gauss_points per element for the axial force."""

    gravity: tuple[float, float] = key(VEC2, (0.0, 0.0), doc="gravity in the drive plane", units="m/s^2")
    curvature: str = key(_Choice(*CURVATURES), "linear",
                         doc="bending energy: linear (paper Eq. 17), exact (Eq. 15) or none")
    gauss_points: int = key(_Int(1, MAX_GAUSS_POINTS), 5, doc="Gauss points per element for the axial force")


@dataclass(frozen=True, kw_only=True)
class StaticTorque:
    """[[static.torque]]: an accessory torque in the static load case (the driver reacts it)."""

    pulley: str = key(STR, doc="name of the pulley it acts on (not the driver)")
    value: float = key(FLOAT, doc="torque on the pulley, counter-clockwise positive", units="N m")


@dataclass(frozen=True, kw_only=True)
class StaticOptions:
    """Newton settings: relative force tolerance, iterations per load step, number of load steps;
    torque: the static load case's accessory torques (they also act, constant, in a transient)."""

    tolerance: float = key(POSFLOAT, 1e-10, doc="Newton tolerance, relative to the force scale")
    max_iterations: int = key(POSINT, 40, doc="Newton iterations per load step")
    load_steps: int = key(POSINT, 1, doc="number of load steps")
    torque: tuple[StaticTorque, ...] = key(_Array(StaticTorque), (), omit_default=True,
                                           doc="[[static.torque]]: accessory torques of the static load case")


@dataclass(frozen=True, kw_only=True)
class ModalOptions:
    """modes: number of elastic modes wanted; solver: "auto" | "dense" | "sparse"."""

    modes: int = key(POSINT, 12, doc="elastic modes computed (rigid-body modes excluded)")
    solver: str = key(_Choice("auto", "dense", "sparse"), "auto", doc="eigensolver")


@dataclass(frozen=True, kw_only=True)
class Signal:
    """A scalar time function: ramp(t) * (constant + amplitude sin(2 pi frequency t + phase)), or a
    table (time s, value) linearly interpolated (held constant outside). ramp(t) = min(t / ramp_time, 1).
    Not a TOML table itself: [[transient.torque]] and [[transient.hub_force]] entries are read into
    one and two signals (see _TorqueEntry)."""

    constant: float = 0.0
    amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    ramp_time: float = 0.0
    table: str = ""
    table_sha256: str = ""  # of the table file's bytes: the table's content is part of the configuration
    table_time: tuple[float, ...] = field(default=(), repr=False, compare=False)
    table_value: tuple[float, ...] = field(default=(), repr=False, compare=False)


@dataclass(frozen=True, kw_only=True)
class Rotation:
    """Prescribed rotation of one pulley (counter-clockwise rad). The mean speed (rad/s) is reached
    by a linear speed ramp over ramp_time; on top, a harmonic fluctuation of the angle (amplitude, rad)
    or of the speed (speed_amplitude, rad/s) at `frequency` Hz, faded in smoothly over fluctuation_ramp s."""

    pulley: str = key(STR, doc="name of the pulley whose rotation is prescribed")
    speed: float = key(FLOAT, 0.0, doc="mean speed, counter-clockwise", units="rad/s")
    ramp_time: float = key(NONNEGFLOAT, 0.0, doc="linear speed ramp up to the mean speed", units="s")
    amplitude: float = key(FLOAT, 0.0, doc="angle amplitude of the fluctuation", units="rad")
    speed_amplitude: float = key(FLOAT, 0.0, doc="speed amplitude of the fluctuation (instead of amplitude)",
                                 units="rad/s")
    frequency: float = key(NONNEGFLOAT, 0.0, doc="frequency of the fluctuation", units="Hz")
    phase: float = key(FLOAT, 0.0, doc="phase of the fluctuation", units="rad")
    fluctuation_ramp: float = key(NONNEGFLOAT, 0.0, doc="smooth fade-in of the fluctuation", units="s")
    start_speed: float = key(FLOAT, 0.0, omit_default=True,
                             doc="nominal speed at t = 0, ramped linearly to `speed` over ramp_time (a run-up from "
                                 "idle: the run starts from the running equilibrium at this speed)", units="rad/s")
    order: float = key(NONNEGFLOAT, 0.0, omit_default=True,
                       doc="engine order: the fluctuation runs at order x the nominal rotation (phase order x "
                           "nominal angle, so it follows the speed ramp) instead of at `frequency`; a "
                           "4-cylinder crank fires at order 2", units="1")


@dataclass(frozen=True, kw_only=True)
class Load:
    """An applied torque (N m, on the pulley's rotation) or hub force (N, x and y, on its support)."""

    pulley: str
    kind: str  # "torque" | "hub_force"
    signals: tuple[Signal, ...]  # one (torque) or two (x, y)


@dataclass(frozen=True, kw_only=True)
class _TorqueEntry:
    """[[transient.torque]]: a torque on a pulley's rotation (read into a Load with one Signal)."""

    pulley: str = key(STR, doc="name of the pulley it acts on")
    constant: float = key(FLOAT, 0.0, doc="mean torque, counter-clockwise", units="N m")
    amplitude: float = key(FLOAT, 0.0, doc="harmonic amplitude", units="N m")
    frequency: float = key(NONNEGFLOAT, 0.0, doc="harmonic frequency", units="Hz")
    phase: float = key(FLOAT, 0.0, doc="harmonic phase", units="rad")
    ramp_time: float = key(NONNEGFLOAT, 0.0, doc="linear fade-in of the whole load", units="s")
    table: str = key(STR, "", omit_default=True,
                     doc="CSV file (time s, value) interpolated instead, relative to the config file")
    table_sha256: str = key(STR, "", omit_default=True,
                            doc="sha256 of the table file's bytes (written by the resolved configuration)")


@dataclass(frozen=True, kw_only=True)
class _HubForceEntry(_TorqueEntry):
    """[[transient.hub_force]]: a force on a slide or bearing pulley's centre (a Load with x and y Signals)."""

    constant: tuple[float, float] = key(VEC2, (0.0, 0.0), doc="mean force [Fx, Fy]", units="N")
    amplitude: tuple[float, float] = key(VEC2, (0.0, 0.0), doc="harmonic amplitudes [Fx, Fy]", units="N")


class _Loads(_Kind):
    """TransientOptions.loads: the [[transient.torque]] and [[transient.hub_force]] entries, in that order."""

    is_table = True
    label = "array of tables"
    entries = {"torque": _Array(_TorqueEntry), "hub_force": _Array(_HubForceEntry)}
    names = tuple(entries)

    def parse(self, chk: _Checker, key: str, table: dict[str, Any]) -> tuple[Load, ...]:
        loads = []
        for kind, array in self.entries.items():
            for e in array.parse(chk, f"{key}.{kind}", table.get(kind, [])):
                parts = [(e.constant, e.amplitude)] if kind == "torque" else zip(e.constant, e.amplitude)
                loads.append(Load(pulley=e.pulley, kind=kind, signals=tuple(
                    Signal(constant=c, amplitude=a, frequency=e.frequency, phase=e.phase, ramp_time=e.ramp_time,
                           table=e.table, table_sha256=e.table_sha256) for c, a in parts)))
        return tuple(loads)

    def dump(self, loads: tuple[Load, ...]) -> dict[str, list[dict[str, Any]]]:
        out: dict[str, list[dict[str, Any]]] = {kind: [] for kind in self.entries}
        for load in loads:
            s0 = load.signals[0]
            constant = tuple(s.constant for s in load.signals)  # hub force: (x, y); torque: one number
            amplitude = tuple(s.amplitude for s in load.signals)
            if load.kind == "torque":
                constant, amplitude = constant[0], amplitude[0]
            e = self.entries[load.kind].cls(pulley=load.pulley, constant=constant, amplitude=amplitude,
                                            frequency=s0.frequency, phase=s0.phase, ramp_time=s0.ramp_time,
                                            table=s0.table, table_sha256=s0.table_sha256)
            out[load.kind].append(_dump(e))
        return out


@dataclass(frozen=True, kw_only=True)
class Record:
    pulley_angles: bool = key(BOOL, True, doc="record the pulley angles")
    pulley_speeds: bool = key(BOOL, True, doc="record the pulley speeds")
    span_tension: bool = key(BOOL, True, doc="record the tension at both ends of each span")
    hub_load: bool = key(BOOL, True, doc="record the force of the belt on each pulley")
    bearing_force: bool = key(BOOL, True, doc="record the spring force on slide and bearing pulleys")
    midspan_displacement: bool = key(BOOL, True, doc="record the transverse displacement at mid-span")
    energy: bool = key(BOOL, True, doc="record kinetic and strain energy, work of loads, dissipation, balance")
    full_state: bool = key(BOOL, False, doc="record every DOF (large files)")


@dataclass(frozen=True, kw_only=True)
class Damping:
    """Rayleigh C = rayleigh_mass M + rayleigh_stiffness K_t(static) (1/s, s); belt material damping
    (Kelvin-Voigt retardation times, s): axial force EA (eps + belt_axial d eps/dt), bending EI likewise."""

    rayleigh_mass: float = key(NONNEGFLOAT, 0.0, doc="Rayleigh mass coefficient alpha (C = alpha M + beta K)",
                               units="1/s")
    rayleigh_stiffness: float = key(NONNEGFLOAT, 0.0, doc="Rayleigh stiffness coefficient beta", units="s")
    belt_axial: float = key(NONNEGFLOAT, 0.0, doc="Kelvin-Voigt retardation time of the belt's axial stress",
                            units="s")
    belt_bending: float = key(NONNEGFLOAT, 0.0, doc="Kelvin-Voigt retardation time of the belt's bending",
                              units="s")


@dataclass(frozen=True, kw_only=True)
class ResponseExcitation:
    """[[response.excitation]]: a harmonic excitation at an engine order of the driver's speed."""

    pulley: str = key(STR, doc="name of the pulley it acts on")
    kind: str = key(_Choice("speed", "torque"),
                    doc='"speed": a fluctuation of the pulley\'s speed, its rotation prescribed (amplitude in '
                        'rad/s); "torque": a harmonic torque on the pulley (amplitude in N m)')
    amplitude: float = key(FLOAT, doc="amplitude: rad/s (speed) or N m (torque, counter-clockwise)",
                           units="rad/s | N m")
    order: float = key(NONNEGFLOAT, 0.0, omit_default=True,
                       doc="the engine order it acts at (one of response.orders); 0: at every order")
    phase: float = key(FLOAT, 0.0, omit_default=True, doc="phase: speed B sin(w t + phase), torque "
                                                          "tau cos(w t + phase)", units="rad")


@dataclass(frozen=True, kw_only=True)
class ResponseOptions:
    """beltdyn response: the harmonic steady state of the drive linearized about its static equilibrium,
    for `points` driver speeds evenly spread over `speed` and each engine order: the excitation
    frequency is order x speed / (2 pi)."""

    speed: tuple[float, float] = key(_Pair(ordered=True), doc="[min, max] of the driver's mean speed",
                                     units="rad/s")
    points: int = key(POSINT, 100, doc="driver speeds in the range, evenly spaced")
    orders: tuple[float, ...] = key(_Numbers(), (1.0,), doc="engine orders", units="1")
    transport: bool = key(BOOL, True, doc="linearize about the running equilibrium at each speed (the belt at "
                                          "speed x R_driver, with its transport terms); false: once, about the "
                                          "equilibrium of [running] (or at rest): the travelling frame")
    damping: Damping = key(_Table(Damping), factory=Damping,
                             doc="[response.damping]: Rayleigh and belt damping, as [transient.damping]")
    excitation: tuple[ResponseExcitation, ...] = key(
        _Array(ResponseExcitation, min_items=1, noun="excitations",
               missing="missing: give at least one [[response.excitation]]"),
        doc="[[response.excitation]]: the driver's speed fluctuation and harmonic accessory torques")


@dataclass(frozen=True, kw_only=True)
class SpectrumOptions:
    enabled: bool = key(BOOL, True, doc="compute the spectra of the recorded series")
    start: float = key(NONNEGFLOAT, 0.0, doc="start of the analysed window (leave out the transient)", units="s")
    window: str = key(_Choice("hann", "rect", "flattop"), "hann", doc="window function")
    peaks: int = key(POSINT, 8, doc="spectral peaks reported per series")


@dataclass(frozen=True, kw_only=True)
class OrderOptions:
    """[transient.orders]: run-up order tracking (`beltdyn.analysis.orders`): the recorded span tensions,
    hub loads, arm angles and pulley speeds resampled against the reference pulley's angle and analysed
    per window of whole revolutions: /transient order_amplitude and order_phase (speed, order, channel)."""

    orders: tuple[float, ...] = key(_Numbers(), (), omit_default=True, units="1",
                                    doc="engine orders tracked (cycles per revolution of the reference; none: "
                                        "no tracking); each a multiple of 1/revolutions")
    reference: str | None = key(STR, None, doc="pulley whose angle the orders count (not set: the pulley of "
                                               "[[transient.rotation]])")
    revolutions: int = key(POSINT, 2, omit_default=True, doc="revolutions of the reference per analysed window")
    samples: int = key(POSINT, 64, omit_default=True, doc="samples per revolution of the angle grid (the "
                                                          "orders stay below half of it)")


@dataclass(frozen=True, kw_only=True)
class TransientOptions:
    """Generalized-alpha time integration (Chung-Hulbert) of the nonlinear drive.

    duration, step, output_interval in s; rho_inf the spectral radius at infinite frequency (1: no
    numerical damping); start "static" (equilibrium) or "rest" (the stress-free reference state).
    accuracy and fmax (given together or not at all): the time step must resolve frequencies up to
    fmax with a relative frequency error |e| <= accuracy, e the exact generalized-alpha error of a
    free oscillation (beltdyn.analysis.timestep; about -c(rho_inf) (2 pi f step)^2, c = 0.084 at rho_inf = 0.9).
    The step a run uses (`timestep.resolve_step`, called by the CLI, the sweeps and
    `pipeline.transient`):
      - `--step` on the command line: that step (a warning in /transient `warnings` if it misses the
        accuracy);
      - accuracy and fmax without step: the longest step that meets them;
      - accuracy and fmax with step: step is an upper bound, the shorter of the two is used;
      - neither: step (default 1e-4 s).
    `step` is None here only when accuracy and fmax are given without it (filled in by resolve_step).
    max_output_mb: a run writing more needs --force-large.
    """

    duration: float = key(POSFLOAT, 1.0, doc="simulated time", units="s")
    step: float | None = key(POSFLOAT, None, units="s",
                             doc="time step (halved when Newton fails, grown back after); default 1e-4 s, or "
                                 "with accuracy and fmax the step they ask for (then given: an upper bound)")
    min_step: float = key(POSFLOAT, 1e-9, doc="smallest step before the run fails", units="s")
    output_interval: float = key(POSFLOAT, 1e-3, doc="time between recorded samples", units="s")
    rho_inf: float = key(UNIT, 0.9, doc="spectral radius at infinite frequency (1: no numerical damping)")
    start: str = key(_Choice("static", "rest"), "static",
                     doc="start from the static equilibrium or the stress-free reference state")
    tolerance: float = key(POSFLOAT, 1e-8, doc="Newton tolerance per step, relative")
    max_iterations: int = key(POSINT, 12, doc="Newton iterations per step")
    accuracy: float | None = key(_Number(0.0, 0.1, open_lo=True), None,
                                 doc="relative frequency error the time step must meet up to fmax (with fmax)")
    fmax: float | None = key(POSFLOAT, None, doc="highest frequency the run must resolve (with accuracy)",
                             units="Hz")
    transport: bool = key(BOOL, True, omit_default=True,
                          doc="the running belt's transport terms (gyroscopic, centripetal); false: the former "
                              "travelling-frame approximation (the belt's nominal inertia only)")
    max_output_mb: float = key(POSFLOAT, 1000.0, omit_default=True,
                               doc="output volume above which a run needs --force-large", units="MB (1e6 bytes)")
    record: Record = key(_Table(Record), factory=Record, doc="[transient.record]: the series written")
    damping: Damping = key(_Table(Damping), factory=Damping, doc="[transient.damping]: Rayleigh and belt damping")
    spectrum: SpectrumOptions = key(_Table(SpectrumOptions), factory=SpectrumOptions,
                                    doc="[transient.spectrum]: spectra of the recorded series")
    orders: OrderOptions = key(_Table(OrderOptions), factory=OrderOptions,
                               doc="[transient.orders]: run-up order tracking against a reference pulley")
    rotation: tuple[Rotation, ...] = key(_Array(Rotation), (), doc="[[transient.rotation]]: at most one "
                                                                   "prescribed pulley rotation")
    loads: tuple[Load, ...] = key(_Loads(), (), doc="[[transient.torque]] and [[transient.hub_force]]: "
                                                    "applied torques and hub forces")

    def __post_init__(self) -> None:
        if self.step is None and (self.accuracy is None or self.fmax is None):  # no accuracy to choose it
            object.__setattr__(self, "step", DEFAULT_STEP)


@dataclass(frozen=True, kw_only=True)
class RunningOptions:
    """[running]: the belt running at a constant speed (static, modal and the transient's start; see
    `beltdyn.analysis.running`). One of belt_speed (m/s: undeformed belt length per second, the mass flow over
    rho; positive along the belt's direction of travel A -> B -> ...) or driver_speed (rad/s of the
    driver pulley, counter-clockwise; belt speed = omega R_driver with the sign of the travel); none:
    at rest. orders: engine orders whose lines a speed sweep crosses with the modes (the Campbell
    diagram's resonance table)."""

    belt_speed: float | None = key(FLOAT, None, units="m/s",
                                   doc="belt speed along the direction of travel (undeformed length per second)")
    driver_speed: float | None = key(FLOAT, None, units="rad/s",
                                     doc="driver pulley speed, counter-clockwise (instead of belt_speed)")
    orders: tuple[float, ...] = key(_Numbers(), (), omit_default=True, units="1",
                                    doc="engine orders: a speed sweep lists each mode's crossings with their lines")


@dataclass(frozen=True, kw_only=True)
class SweepTable:
    """[sweep]: analysis, zip, and params = {"dotted.key" = "SPEC" or [values]} (see `beltdyn sweep`)."""

    analysis: str = key(_Choice("static", "modal", "transient"), "modal", doc="analysis run for each case")
    zip: bool = key(BOOL, False, doc="vary the parameters together (equal lengths) instead of their product")
    params: tuple[tuple[str, str], ...] = key(_Params(), (), doc='"dotted.key" = "SPEC" or [values]')


@dataclass(frozen=True, kw_only=True)
class DriveConfig:
    """A whole drive description: the top level of the TOML file."""

    belt: Belt = key(_Table(Belt), doc="[belt]: the belt's properties")
    pulleys: tuple[Pulley, ...] = key(_Array(Pulley, min_items=2, noun="pulleys",
                                             missing="missing: give at least 2 [[pulleys]] in belt order"),
                                      doc="[[pulleys]]: at least 2, in the order the belt meets them")
    tension: Tension = key(_Table(Tension), factory=Tension, doc="[tension]: how the static tension is set")
    mesh: Mesh = key(_Table(Mesh), factory=Mesh, doc="[mesh]: discretization of the spans")
    spans: tuple[tuple[str, SpanSetting], ...] = key(
        _Spans(), (), omit_default=True,
        doc='[spans."A-C"]: per span model ("ancf", "string", "spring") and elements, overriding [mesh] and '
            "model.curvature")
    model: ModelOptions = key(_Table(ModelOptions), factory=ModelOptions, doc="[model]: model options")
    static: StaticOptions = key(_Table(StaticOptions), factory=StaticOptions, doc="[static]: Newton settings")
    modal: ModalOptions = key(_Table(ModalOptions), factory=ModalOptions, doc="[modal]: modal analysis")
    transient: TransientOptions | None = key(_Table(TransientOptions), None, doc="[transient]: time integration")
    sweep: SweepTable | None = key(_Table(SweepTable), None, doc="[sweep]: parameter sweep (beltdyn sweep)")
    response: ResponseOptions | None = key(_Table(ResponseOptions), None,
                                           doc="[response]: steady forced response (beltdyn response)")
    running: RunningOptions | None = key(_Table(RunningOptions), None,
                                         doc="[running]: the belt running at a constant speed")
    title: str = key(TEXT, "", omit_default=True, doc="a title for the results")
    source: str = ""  # file the config came from (not part of the resolved TOML)

    @property  # (derived on each use: a frozen config holds nothing but its fields)
    def adjustable_index(self) -> int | None:
        for i, p in enumerate(self.pulleys):
            if p.adjustable:
                return i
        return None

    @property
    def driver_index(self) -> int:
        for i, p in enumerate(self.pulleys):
            if p.driver:
                return i
        return 0

    @property
    def span_names(self) -> tuple[str, ...]:
        """Span i runs from pulley i to pulley i + 1: "A-C" (as the console names it)."""
        return span_names(self.pulleys)

    @property
    def span_models(self) -> tuple[str, ...]:
        """The resolved model of each span: "ancf", "string" or "spring" ([spans], else "ancf", or
        "string" where model.curvature = "none")."""
        return resolved_spans(self)[0]

    @property
    def span_elements(self) -> tuple[int, ...]:
        """The resolved elements of each span (0 for a spring span)."""
        return resolved_spans(self)[1]


def resolved_spans(cfg: "DriveConfig") -> tuple[tuple[str, ...], tuple[int, ...]]:
    """(`DriveConfig.span_models`, `DriveConfig.span_elements`) derived together: the resolved model of each
    span ([spans], else "ancf", or "string" where model.curvature = "none") and its elements (0 for a spring
    span; [spans], else mesh.elements_per_span). An analysis derives them once (`model.system.drive_facts`)."""
    given, names = dict(cfg.spans), cfg.span_names
    default = "string" if cfg.model.curvature == "none" else "ancf"
    models = tuple([(given[n].model if n in given and given[n].model else default) for n in names])
    each = cfg.mesh.elements_per_span
    return models, tuple([0 if m == "spring" else (given[n].elements if n in given and given[n].elements else each)
                          for n, m in zip(names, models)])


def span_names(pulleys) -> tuple[str, ...]:
    """"A-C" for the span from pulley A to the next pulley C, in belt order."""
    names = [p.name for p in pulleys]
    return tuple(f"{names[i]}-{names[(i + 1) % len(names)]}" for i in range(len(names)))


class KeyDoc(NamedTuple):
    key: str  # dotted path, array entries as [i]
    kind: str  # what the value must be
    default: str  # as TOML, or "required" / "not set"
    units: str
    doc: str


def _walk(cls: type, path: str) -> Iterator[tuple[str, Field, _Key]]:
    """(dotted path, field, key) of every plain value of a declared table, nested tables expanded."""
    for f, k in _schema(cls):
        kind = k.kind
        if isinstance(kind, _Table):
            yield from _walk(kind.cls, _join(path, f.name))
        elif isinstance(kind, _Array):
            yield from _walk(kind.cls, f"{_join(path, f.name)}[i]")
        elif isinstance(kind, _Loads):
            for name, array in kind.entries.items():
                yield from _walk(array.cls, f"{_join(path, name)}[i]")
        elif isinstance(kind, _Spans):
            yield from _walk(SpanSetting, f"{_join(path, f.name)}.<span>")
        else:
            yield _join(path, f.name), f, k


def valid_keys() -> list[str]:
    """All dotted keys of the schema (array entries as pulleys[i].key)."""
    return [path for path, _, _ in _walk(DriveConfig, "")]


def key_docs() -> list[KeyDoc]:
    """Every key of the schema with its kind, default, units and one-line doc."""
    import json

    rows = []
    for path, f, k in _walk(DriveConfig, ""):
        if f.default is MISSING:
            default = "required"
        elif f.default is None:
            default = "not set"
        else:
            default = json.dumps(k.kind.dump(f.default))
        rows.append(KeyDoc(path, k.kind.label, default, k.units, k.doc))
    return rows
