"""TOML drive description -> frozen, validated dataclasses.

Every error is a `ConfigError` naming the file and the dotted key path, e.g.
``drive.toml: pulleys[1].radius: must be > 0, got -0.05``. Overrides (``--set KEY=VALUE``) are
applied to the parsed TOML before validation; VALUE is parsed as a TOML literal (never eval), a bare
word being taken as a string. Units are SI everywhere; keys carry no unit suffixes.

One declaration: each dataclass below is the schema of its TOML table. A field declared with
``key(KIND, default, doc=..., units=...)`` is a TOML key of that name; KIND checks and converts the
TOML value (`parse`) and writes it back (`dump`). Parsing (unknown keys with the closest valid key
suggested, missing keys, type and range errors with the key path), the defaults, `valid_keys`,
`key_docs` and the resolved TOML (`config_to_dict`, `resolved_toml`) are all derived from these
declarations. Checks that involve several keys (one adjustable pulley, slide_range only on slides,
the default tension mode, the transient's cross-checks, the CSV load tables, ...) are explicit code
after the generic parse, in `config_from_dict`.
"""

from __future__ import annotations

import difflib
import functools
import hashlib
import math
import re
import tomllib
from collections.abc import Iterator
from dataclasses import MISSING, Field, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, NamedTuple

from beltdyn.errors import ConfigError

DEFAULT_STEP = 1e-4  # s: transient.step when neither it nor transient.accuracy and fmax are given

SIDES = ("inside", "backside")
SUPPORTS = ("fixed", "slide", "bearing", "arm")
TENSION_MODES = ("adjust", "prestrain", "spring")
CURVATURES = ("linear", "exact", "none")
SPAN_MODELS = ("ancf", "string", "spring")  # the fidelity ladder of one span, richest first
MAX_GAUSS_POINTS = 64  # beltdyn.model.ancf's quadrature table (not imported: it would load numba at start-up)


# ------------------------------------------------------------------------------- the value kinds
class _Kind:
    """How one TOML value is checked and converted (`parse`) and written back (`dump`)."""

    label = "value"  # what the value must be, for key_docs
    is_table = False  # a table or array of tables: written after the plain values, as TOML does
    names: tuple[str, ...] = ()  # a group: several TOML keys of the parent table read into one field

    def parse(self, chk: _Checker, key: str, value: Any) -> Any:
        raise AssertionError(f"{type(self).__name__} declares no parse")

    def dump(self, value: Any) -> Any:
        return value

    def missing(self, key: str) -> str:
        return "missing key"


class _Number(_Kind):
    """A finite float, optionally bounded: lo/hi, each open or closed (an int is taken as a float)."""

    def __init__(self, lo: float | None = None, hi: float | None = None, *, open_lo: bool = False,
                 open_hi: bool = False) -> None:
        self.lo, self.hi, self.open_lo, self.open_hi = lo, hi, open_lo, open_hi
        if lo is None:
            self.rule = ""
        elif hi is None:
            self.rule = f"{'>' if open_lo else '>='} {lo:g}"
        else:
            self.rule = f"in {'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}"
        self.label = f"number {self.rule}".strip()

    def parse(self, chk: _Checker, key: str, value: Any) -> float:
        x = chk.number(key, value)
        lo, hi = self.lo, self.hi
        if (lo is not None and (x <= lo if self.open_lo else x < lo)) or \
                (hi is not None and (x >= hi if self.open_hi else x > hi)):
            raise chk.fail(key, f"must be {self.rule}, got {_num(x)}")
        return x


class _Int(_Kind):
    def __init__(self, lo: int = 1, hi: int | None = None) -> None:
        self.lo, self.hi = lo, hi
        self.rule = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        self.label = f"integer {self.rule}"

    def parse(self, chk: _Checker, key: str, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise chk.fail(key, f"must be an integer, got {_show(value)}")
        if value < self.lo or (self.hi is not None and value > self.hi):
            raise chk.fail(key, f"must be {self.rule}, got {value}")
        return value


class _Text(_Kind):
    """Any string (the title)."""

    label = "string"

    def parse(self, chk: _Checker, key: str, value: Any) -> str:
        if not isinstance(value, str):
            raise chk.fail(key, f"must be a string, got {_show(value)}")
        return value


class _Str(_Kind):
    """A string with something in it besides white space."""

    label = "non-empty string"

    def parse(self, chk: _Checker, key: str, value: Any) -> str:
        if not isinstance(value, str) or not value.strip():
            raise chk.fail(key, f"must be a non-empty string, got {_show(value)}")
        return value


class _Name(_Str):
    """A name that other keys refer to: no white space around it (so "A" and "A " cannot both exist)."""

    label = "name (non-empty, no white space around it)"

    def parse(self, chk: _Checker, key: str, value: Any) -> str:
        value = super().parse(chk, key, value)
        if value != value.strip():
            raise chk.fail(key, f"must not begin or end with white space, got {_show(value)}")
        return value


class _Choice(_Kind):
    def __init__(self, *choices: str) -> None:
        self.choices = choices
        self.label = f"one of {', '.join(map(repr, choices))}"

    def parse(self, chk: _Checker, key: str, value: Any) -> str:
        if value not in self.choices:
            close = difflib.get_close_matches(value, self.choices, n=1, cutoff=0.6) if isinstance(value, str) else []
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise chk.fail(key, f"must be {self.label}, got {_show(value)}{hint}")
        return value


class _Bool(_Kind):
    label = "true or false"

    def parse(self, chk: _Checker, key: str, value: Any) -> bool:
        if not isinstance(value, bool):
            raise chk.fail(key, f"must be true or false, got {_show(value)}")
        return value


class _Pair(_Kind):
    """[x, y] of finite numbers; `ordered`: [min, max] with min < max."""

    def __init__(self, ordered: bool = False) -> None:
        self.ordered = ordered
        self.label = "[min, max], min < max" if ordered else "[x, y]"

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple[float, float]:
        if not isinstance(value, list) or len(value) != 2:
            raise chk.fail(key, f"must be a list of 2 numbers, got {_show(value)}")
        x, y = (chk.number(f"{key}[{i}]", v) for i, v in enumerate(value))
        if self.ordered and not x < y:
            raise chk.fail(key, f"must be [min, max] with min < max, got {_show(value)}")
        return (x, y)

    def dump(self, value: tuple[float, float]) -> list[float]:
        return list(value)


class _Numbers(_Kind):
    """A non-empty list of distinct numbers > 0, in increasing order as given."""

    label = "list of numbers > 0, increasing"

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple[float, ...]:
        if not isinstance(value, list) or not value:
            raise chk.fail(key, f"must be a non-empty list of numbers, got {_show(value)}")
        xs = tuple(chk.number(f"{key}[{i}]", v) for i, v in enumerate(value))
        for i, x in enumerate(xs):
            if not x > 0:
                raise chk.fail(f"{key}[{i}]", f"must be > 0, got {_num(x)}")
            if i and not x > xs[i - 1]:
                raise chk.fail(f"{key}[{i}]", f"must be larger than {key}[{i - 1}] = {_num(xs[i - 1])} "
                                              f"(increasing, no repeats)")
        return xs

    def dump(self, value: tuple[float, ...]) -> list[float]:
        return list(value)


class _Stiffness(_Kind):
    """A number k >= 0 (taken as (k, k)) or a pair [kx, ky] of numbers >= 0."""

    label = "number >= 0 or [kx, ky]"

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple[float, float]:
        if isinstance(value, list):
            if len(value) != 2:
                raise chk.fail(key, f"must be a number or a list of 2 numbers, got {_show(value)}")
            pair = tuple(chk.number(f"{key}[{i}]", v) for i, v in enumerate(value))
        else:
            x = chk.number(key, value)
            pair = (x, x)
        for k in pair:
            if k < 0:
                raise chk.fail(key, f"must be >= 0, got {_num(k)}")
        return pair

    def dump(self, value: tuple[float, float]) -> list[float]:
        return list(value)


class _Table(_Kind):
    """A nested table declared by a dataclass."""

    is_table = True

    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.label = "table"

    def parse(self, chk: _Checker, key: str, value: Any) -> Any:
        return _parse(chk, key, value, self.cls)

    def dump(self, value: Any) -> dict[str, Any]:
        return _dump(value)

    def missing(self, key: str) -> str:
        return f"missing table [{key}]"


class _Array(_Kind):
    """An array of tables [[key]], each declared by the dataclass `cls`; a tuple in Python."""

    is_table = True

    def __init__(self, cls: type, *, min_items: int = 0, noun: str = "", missing: str = "") -> None:
        self.cls, self.min_items, self.noun, self.missing_text = cls, min_items, noun, missing
        self.label = "array of tables"

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple:
        if not isinstance(value, list) or not all(isinstance(x, dict) for x in value):
            raise chk.fail(key, f"must be an array of tables [[{key}]]")
        if len(value) < self.min_items:
            raise chk.fail(key, f"need at least {self.min_items} {self.noun}, got {len(value)}")
        return tuple(_parse(chk, f"{key}[{i}]", x, self.cls) for i, x in enumerate(value))

    def dump(self, value: tuple) -> list[dict[str, Any]]:
        return [_dump(x) for x in value]

    def missing(self, key: str) -> str:
        return self.missing_text or f"missing [[{key}]]"


class _Params(_Kind):
    """[sweep.params]: "dotted.key" = "SPEC" or [values] -> ((key, SPEC), ...), a list as "v1,v2,..."."""

    is_table = True
    label = 'table of "dotted.key" = "SPEC" or [values]'

    def parse(self, chk: _Checker, key: str, value: Any) -> tuple[tuple[str, str], ...]:
        if not isinstance(value, dict):
            raise chk.fail(key, "must be a table of \"dotted.key\" = \"SPEC\" or [values]")
        out = []
        for name, spec in value.items():
            if isinstance(spec, list) and all(isinstance(x, (bool, int, float, str)) for x in spec):
                spec = ",".join(str(x).lower() if isinstance(x, bool) else (f'"{x}"' if isinstance(x, str)
                                                                              else repr(x)) for x in spec)
            if not isinstance(spec, str):
                raise chk.fail(f"{key}.{name}", f"must be a SPEC string or a list of numbers, strings or "
                                                f"booleans, got {_show(spec)}")
            out.append((name, spec))
        return tuple(out)

    def dump(self, value: tuple[tuple[str, str], ...]) -> dict[str, str]:
        return dict(value)


class _Key(NamedTuple):
    kind: _Kind
    doc: str
    units: str
    omit_default: bool  # left out of the resolved TOML while it has its default value


def key(kind: _Kind, default: Any = MISSING, *, doc: str, units: str = "", factory: Any = None,
        omit_default: bool = False) -> Any:
    """Declare a dataclass field as a TOML key: its kind, its default (none: the key is required; or
    `factory`), a one-line doc and its units. A None value is never written to the resolved TOML;
    `omit_default` also leaves the key out while it has its default (new keys keep old hashes)."""
    meta = {"key": _Key(kind, doc, units, omit_default)}
    if factory is not None:
        return field(default_factory=factory, metadata=meta)
    return field(default=default, metadata=meta)


FLOAT = _Number()
POSFLOAT = _Number(0.0, open_lo=True)
NONNEGFLOAT = _Number(0.0)
UNIT = _Number(0.0, 1.0)
POSINT = _Int(1)
TEXT = _Text()
STR = _Str()
NAME = _Name()
BOOL = _Bool()
VEC2 = _Pair()
RANGE2 = _Pair(ordered=True)
STIFFNESS = _Stiffness()


# ------------------------------------------------------------------------------ the declarations
@dataclass(frozen=True, kw_only=True)
class Belt:
    """Belt properties. length: undeformed loop length L0 (m); EA (N); EI (N m^2); kg/m."""

    length: float = key(POSFLOAT, doc="undeformed loop length L0", units="m")
    EA: float = key(POSFLOAT, doc="axial stiffness", units="N")
    EI: float = key(NONNEGFLOAT, doc="bending stiffness", units="N m^2")
    mass_per_length: float = key(POSFLOAT, doc="mass per unit length", units="kg/m")


@dataclass(frozen=True, kw_only=True)
class Pulley:
    """A rigid pulley. center (m, x right / y up); radius (m); mass (kg); inertia (kg m^2).

    side: the belt touches it from the inside of the loop or on its backside.
    support: "fixed" centre (rotation only), "slide" (moves along slide_direction against
    bearing_stiffness, N/m), "bearing" (moves in x and y against bearing_stiffness (kx, ky), N/m) or
    "arm" (a tensioner: the centre turns about arm_pivot on an arm of length |center - arm_pivot|,
    angle phi counter-clockwise from +x, against the torsion spring arm_stiffness (zero torque at
    arm_free_angle), viscous arm_damping and the dry friction torque arm_friction; the pulley's mass
    adds m l^2 to arm_inertia through the kinematics).
    adjustable: the pulley moved along its slide (turned on its arm) to fit L0 and to set the tension.
    friction: effective coefficient of friction belt-pulley (V-ribbed: the wedge-effective value), for
    the slip margin.
    driver: its rotation is held in the static analysis and reacts the applied torques.
    slide_range: (min, max) travel along the slide from `center`, m (None: unbounded).
    """

    name: str = key(NAME, doc="name, unique; loads and rotations refer to it")
    center: tuple[float, float] = key(VEC2, doc="centre (x right, y up); a slide's origin", units="m")
    radius: float = key(POSFLOAT, doc="radius at the belt's neutral line", units="m")
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
                              doc="dry friction torque of the arm's pivot damper (transient only)", units="N m")
    arm_range: tuple[float, float] | None = key(RANGE2, None, doc="[min, max] arm angle between the stops",
                                                units="rad")
    friction: float | None = key(POSFLOAT, None, doc="effective belt-pulley friction coefficient (slip margin)",
                                 units="1")

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
    tension is an output (no target).
    """

    target: float | None = key(POSFLOAT, None, doc="static span tension (not set: the geometry alone decides)",
                               units="N")
    mode: str = key(_Choice(*TENSION_MODES), "adjust",
                    doc="move the adjustable pulley, prestrain the spans, or let the tensioner arm's spring "
                        "set it (default: adjust if a pulley is adjustable)")


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

    @functools.cached_property  # a frozen config: computed once (its __dict__, not a field)
    def adjustable_index(self) -> int | None:
        for i, p in enumerate(self.pulleys):
            if p.adjustable:
                return i
        return None

    @functools.cached_property
    def driver_index(self) -> int:
        for i, p in enumerate(self.pulleys):
            if p.driver:
                return i
        return 0

    @functools.cached_property
    def span_names(self) -> tuple[str, ...]:
        """Span i runs from pulley i to pulley i + 1: "A-C" (as the console names it)."""
        return span_names(self.pulleys)

    @functools.cached_property
    def span_models(self) -> tuple[str, ...]:
        """The resolved model of each span: "ancf", "string" or "spring" ([spans], else "ancf", or
        "string" where model.curvature = "none")."""
        given = dict(self.spans)
        default = "string" if self.model.curvature == "none" else "ancf"
        return tuple((given[n].model if n in given and given[n].model else default) for n in self.span_names)

    @functools.cached_property
    def span_elements(self) -> tuple[int, ...]:
        """The resolved elements of each span (0 for a spring span)."""
        given = dict(self.spans)
        return tuple(0 if m == "spring" else (given[n].elements if n in given and given[n].elements
                                              else self.mesh.elements_per_span)
                     for n, m in zip(self.span_names, self.span_models))


def span_names(pulleys) -> tuple[str, ...]:
    """"A-C" for the span from pulley A to the next pulley C, in belt order."""
    names = [p.name for p in pulleys]
    return tuple(f"{names[i]}-{names[(i + 1) % len(names)]}" for i in range(len(names)))


# ------------------------------------------------------------------- parsing and serialization
@functools.cache
def _schema(cls: type) -> tuple[tuple[Field, _Key], ...]:
    """The declared keys of a dataclass, in TOML order: plain values first, then the tables and
    arrays of tables (as tomli_w writes them), each in declaration order."""
    keyed = [(f, f.metadata["key"]) for f in fields(cls) if "key" in f.metadata]
    return tuple(sorted(keyed, key=lambda fk: fk[1].kind.is_table))


@functools.cache
def _names(cls: type) -> tuple[str, ...]:
    """The TOML key names of a declared table."""
    return tuple(n for f, k in _schema(cls) for n in (k.kind.names or (f.name,)))


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _parse(chk: _Checker, path: str, raw: Any, cls: type) -> Any:
    """A TOML table -> an instance of the dataclass declaring it (checks every key's kind)."""
    if not isinstance(raw, dict):
        raise chk.fail(path, f"must be a table, got {_show(raw)}")
    allowed = _names(cls)
    for name in raw:
        if name not in allowed:
            raise chk.unknown(_join(path, name), name, list(allowed))
    values = {}
    for f, k in _schema(cls):
        if k.kind.names:
            values[f.name] = k.kind.parse(chk, path, raw)
        elif f.name in raw:
            values[f.name] = k.kind.parse(chk, _join(path, f.name), raw[f.name])
        elif f.default is MISSING and f.default_factory is MISSING:
            raise chk.fail(_join(path, f.name), k.kind.missing(_join(path, f.name)))
    return cls(**values)


def _dump(obj: Any) -> dict[str, Any]:
    """A declared dataclass instance -> its TOML table (None values and omitted defaults left out)."""
    out: dict[str, Any] = {}
    for f, k in _schema(type(obj)):
        value = getattr(obj, f.name)
        if value is None or (k.omit_default and value == f.default):
            continue
        if k.kind.names:
            out.update(k.kind.dump(value))
        else:
            out[f.name] = k.kind.dump(value)
    return out


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


class _Checker:
    """Raises ConfigError with the file and key path."""

    def __init__(self, file: str, tables: dict[str, bytes] | None = None) -> None:
        self.file = file
        self.tables = tables or {}  # table file name -> its bytes, instead of reading the file

    def fail(self, key: str, message: str) -> ConfigError:
        return ConfigError(message, file=self.file, key=key)

    def unknown(self, key: str, name: Any, allowed: list[str]) -> ConfigError:
        name = str(name)  # an override can put an integer key into a table (--set belt.0=1)
        close = difflib.get_close_matches(name, allowed, n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else f"; valid keys: {', '.join(allowed)}"
        return self.fail(key, f"unknown key '{name}'{hint}")

    def number(self, key: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"must be a number, got {_show(value)}")
        try:
            value = float(value)
        except OverflowError:  # an integer beyond the float range
            value = math.inf if value > 0 else -math.inf
        if not math.isfinite(value):
            raise self.fail(key, f"must be finite, got {value}")
        return value


def _show(value: Any) -> str:
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, dict):
        return "a table"
    return str(value).replace("True", "true").replace("False", "false")


def _num(x: float) -> str:
    return f"{x:g}"


def parse_toml_file(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte order mark (some Windows editors) is skipped
    except FileNotFoundError:
        raise ConfigError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", file=str(path)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", file=str(path)) from None


def _split_key(key: str) -> list[str | int]:
    """'pulleys[1].radius' / 'pulleys.1.radius' / 'pulleys.A.radius' -> ['pulleys', 1, 'radius']."""
    parts: list[str | int] = []
    for piece in key.split("."):
        if not piece:
            raise ValueError("empty key part")
        m = re.fullmatch(r"([^\[\]]+)((?:\[\d+\])*)", piece)
        if not m:
            raise ValueError(f"cannot parse '{piece}'")
        head = m.group(1)
        parts.append(int(head) if head.isdigit() else head)
        parts += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return parts


def _parse_literal(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", text):
            return text  # a bare word is a string
        raise


def apply_override(raw: dict[str, Any], assignment: str, *, file: str) -> None:
    """Apply one ``KEY=VALUE`` override in place (VALUE a TOML literal; never eval). An empty VALUE
    (``KEY=``, what the CLI's ``--unset KEY`` passes) removes the key: ConfigError if it is not there."""
    where = f"--set {assignment}"
    if "=" not in assignment:
        raise ConfigError("expected KEY=VALUE", file=file, key=where)
    key, text = (s.strip() for s in assignment.split("=", 1))
    remove = text == ""
    where = f"--unset {key}" if remove else where
    try:
        parts = _split_key(key)
    except ValueError as exc:
        raise ConfigError(f"bad key '{key}': {exc}", file=file, key=where) from None
    try:
        value = None if remove else _parse_literal(text)
    except tomllib.TOMLDecodeError:
        raise ConfigError(f"value '{text}' is not a TOML literal", file=file, key=where) from None
    node: Any = raw
    for i, part in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(node, list):
            if isinstance(part, str):  # pulleys.A.radius: look up by name
                match = [x for x in node if isinstance(x, dict) and x.get("name") == part]
                if not match:
                    raise ConfigError(f"no entry named '{part}'", file=file, key=where)
                node = match[0]
                continue
            if part >= len(node):
                raise ConfigError(f"index {part} out of range (have {len(node)})", file=file, key=where)
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise ConfigError(f"'{part}' is not a table", file=file, key=where)
        if part not in node:
            if i == 0 and part not in _names(DriveConfig):
                raise _Checker(file).unknown(where, str(part), list(_names(DriveConfig)))
            if remove:
                raise ConfigError(f"no '{part}' in the configuration: nothing to remove", file=file, key=where)
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        if not isinstance(last, int) or last >= len(node):
            raise ConfigError(f"bad index '{last}'", file=file, key=where)
        if remove:
            del node[last]
        else:
            node[last] = value
    elif isinstance(node, dict):
        if len(parts) == 1 and last not in _names(DriveConfig):
            raise _Checker(file).unknown(where, str(last), list(_names(DriveConfig)))
        if remove and last not in node:
            raise ConfigError(f"no '{key}' in the configuration: nothing to remove", file=file, key=where)
        if remove:
            del node[last]
        else:
            node[last] = value
    else:
        raise ConfigError(f"'{parts[-2]}' is not a table", file=file, key=where)


def load_config(path: Path | str, overrides: tuple[str, ...] | list[str] = ()) -> DriveConfig:
    """Read, override and validate a drive description."""
    path = Path(path)
    raw = parse_toml_file(path)
    for assignment in overrides:
        apply_override(raw, assignment, file=str(path))
    return config_from_dict(raw, file=str(path))


def config_from_dict(raw: dict[str, Any], *, file: str = "<config>", tables: dict[str, bytes] | None = None
                     ) -> DriveConfig:
    """Validate a parsed TOML drive description: the declared keys first, then the checks that
    involve several keys. tables: the CSV tables' bytes by the name the configuration gives them
    (`table_bytes`), for a process that cannot read them next to `file` (a remote sweep worker)."""
    chk = _Checker(file, tables)
    cfg = _parse(chk, "", raw, DriveConfig)
    pulleys = _check_pulleys(chk, raw["pulleys"], cfg.pulleys)
    adjustable = any(p.adjustable for p in pulleys)
    tension = cfg.tension
    if "mode" not in raw.get("tension", {}):  # default: move the adjustable pulley if there is one
        tension = replace(tension, mode="adjust" if adjustable else "prestrain")
    if tension.target is not None and tension.mode == "adjust" and not adjustable:
        raise chk.fail("tension.mode", "mode \"adjust\" needs one pulley with adjustable = true "
                       "(or use mode = \"prestrain\")")
    if tension.mode == "spring":
        _check_spring_tension(chk, tension, pulleys)
    _check_static_torques(chk, cfg.static, pulleys)
    _check_spans(chk, cfg.spans, pulleys)
    transient = cfg.transient
    if transient is not None:
        transient = _check_transient(chk, transient, pulleys, file)
    if cfg.response is not None:
        _check_response(chk, cfg.response, pulleys)
    if cfg.running is not None and cfg.running.belt_speed is not None and cfg.running.driver_speed is not None:
        raise chk.fail("running.driver_speed", "give either running.belt_speed or running.driver_speed, not both")
    return replace(cfg, pulleys=pulleys, tension=tension, transient=transient, source=file)


def _check_spring_tension(chk: _Checker, tension: Tension, pulleys: tuple[Pulley, ...]) -> None:
    """mode "spring": an arm pulley with a spring and its free angle sets the tension (no target)."""
    if tension.target is not None:
        raise chk.fail("tension.target", "with mode = \"spring\" the arm's spring sets the tension (an output): "
                                         "remove tension.target, or use mode = \"adjust\"")
    arms = [i for i, p in enumerate(pulleys) if p.support == "arm"]
    if not arms:
        raise chk.fail("tension.mode", "mode \"spring\" needs a pulley with support = \"arm\"")
    for i in arms:
        p = pulleys[i]
        if p.arm_free_angle is None:
            raise chk.fail(f"pulleys[{i}].arm_free_angle", "missing key: tension mode \"spring\" needs the angle "
                                                          "at which the arm's spring torque is zero (rad)")
        if not p.arm_stiffness > 0:
            raise chk.fail(f"pulleys[{i}].arm_stiffness", "tension mode \"spring\" needs arm_stiffness > 0")


def _check_spans(chk: _Checker, spans: tuple[tuple[str, SpanSetting], ...], pulleys: tuple[Pulley, ...]) -> None:
    """Every [spans] entry names a span of the drive (the closest name suggested)."""
    valid = span_names(pulleys)
    for name, _ in spans:
        if valid.count(name) == 1:
            continue
        key = f"spans.{span_name_key(name)}"
        if valid.count(name) > 1:
            raise chk.fail(key, f"span name '{name}' is ambiguous (pulley names with '-'); rename the pulleys")
        close = difflib.get_close_matches(name, valid, n=1, cutoff=0.4)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise chk.fail(key, f"no span named '{name}'; {hint}the spans are {', '.join(valid)} (from each pulley "
                            f"to the next in belt order)")


def _check_static_torques(chk: _Checker, opts: StaticOptions, pulleys: tuple[Pulley, ...]) -> None:
    names = [p.name for p in pulleys]
    driver = next((i for i, p in enumerate(pulleys) if p.driver), 0)
    for i, tq in enumerate(opts.torque):
        j = _pulley_index(chk, f"static.torque[{i}].pulley", tq.pulley, names)
        if j == driver:
            raise chk.fail(f"static.torque[{i}].pulley", f"'{tq.pulley}' is the driver: its rotation is held and "
                                                         f"reacts the torques; put the torque on an accessory")


def _check_pulleys(chk: _Checker, raw: list[dict[str, Any]], pulleys: tuple[Pulley, ...]) -> tuple[Pulley, ...]:
    out = []
    for i, (p, praw) in enumerate(zip(pulleys, raw)):
        key = f"pulleys[{i}]"
        dx, dy = p.slide_direction
        norm = math.hypot(dx, dy)
        if norm == 0:
            raise chk.fail(f"{key}.slide_direction", "must not be the zero vector")
        if abs(norm - 1.0) > 4 * 2.0**-52:  # a unit vector (to rounding) is kept as given, so that
            p = replace(p, slide_direction=(dx / norm, dy / norm))  # the resolved TOML round-trips
        if p.support == "fixed" and any(p.bearing_stiffness):
            raise chk.fail(f"{key}.bearing_stiffness", "a fixed-centre pulley has no bearing spring; "
                           "use support = \"slide\" or \"bearing\"")
        if p.support == "slide" and isinstance(praw.get("bearing_stiffness"), list):
            raise chk.fail(f"{key}.bearing_stiffness", "a slide has one stiffness (N/m along the slide)")
        if p.adjustable and p.support not in ("slide", "arm"):
            raise chk.fail(f"{key}.adjustable", "the adjustable pulley needs support = \"slide\" or \"arm\"")
        arm_keys = [k for k in ("arm_pivot", "arm_inertia", "arm_stiffness", "arm_free_angle", "arm_damping",
                                "arm_friction", "arm_range") if k in praw]
        if p.support != "arm" and arm_keys:
            raise chk.fail(f"{key}.{arm_keys[0]}", "only a pulley with support = \"arm\" has arm settings")
        if p.support == "arm":
            if p.arm_pivot is None:
                raise chk.fail(f"{key}.arm_pivot", "missing key: an arm pulley needs arm_pivot = [x, y] (m)")
            if any(p.bearing_stiffness):
                raise chk.fail(f"{key}.bearing_stiffness", "an arm pulley has no bearing spring: its arm has "
                                                          "arm_stiffness (N m/rad)")
            if p.arm_length <= p.radius:
                raise chk.fail(f"{key}.arm_pivot", f"the pivot lies inside the pulley (arm length "
                                                  f"{p.arm_length:.6g} m <= radius {p.radius:g} m)")
        if p.slide_range is not None and p.support != "slide":
            raise chk.fail(f"{key}.slide_range", "only a slide pulley has a slide range")
        out.append(p)
    names = [p.name for p in out]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise chk.fail(f"pulleys[{i}].name", f"duplicate pulley name '{n}'")
    adjustable = [i for i, p in enumerate(out) if p.adjustable]
    if len(adjustable) > 1:
        raise chk.fail(f"pulleys[{adjustable[1]}].adjustable",
                       f"only one pulley may be adjustable (pulleys[{adjustable[0]}] already is)")
    drivers = [i for i, p in enumerate(out) if p.driver]
    if len(drivers) > 1:
        raise chk.fail(f"pulleys[{drivers[1]}].driver", "only one pulley may be the driver")
    return tuple(out)


def _check_response(chk: _Checker, r: ResponseOptions, pulleys: tuple[Pulley, ...]) -> None:
    names = [p.name for p in pulleys]
    driver = next((i for i, p in enumerate(pulleys) if p.driver), 0)
    if not r.speed[0] > 0:
        raise chk.fail("response.speed", f"the driver's speeds must be > 0 (an excitation at order x speed), "
                                         f"got [{_num(r.speed[0])}, {_num(r.speed[1])}]")
    prescribed = {driver} | {names.index(e.pulley) for e in r.excitation if e.kind == "speed" and e.pulley in names}
    for i, e in enumerate(r.excitation):
        key = f"response.excitation[{i}]"
        j = _pulley_index(chk, f"{key}.pulley", e.pulley, names)
        if e.kind == "torque" and j in prescribed:
            raise chk.fail(f"{key}.pulley", f"pulley '{e.pulley}' has a prescribed rotation (the driver, or a speed "
                                            f"excitation): a torque on it goes into that prescription")
        if e.order and e.order not in r.orders:
            raise chk.fail(f"{key}.order", f"order {_num(e.order)} is not one of response.orders "
                                           f"{list(r.orders)}: it would never act")


def _pulley_index(chk: _Checker, key: str, name: str, names: list[str]) -> int:
    if name not in names:
        raise chk.fail(key, f"no pulley named {_show(name)}; pulleys are {', '.join(names)}")
    return names.index(name)


def _check_transient(chk: _Checker, t: TransientOptions, pulleys: tuple[Pulley, ...], file: str) -> TransientOptions:
    names = [p.name for p in pulleys]
    for i, r in enumerate(t.rotation):
        key = f"transient.rotation[{i}]"
        _pulley_index(chk, f"{key}.pulley", r.pulley, names)
        if r.amplitude and r.speed_amplitude:
            raise chk.fail(f"{key}.speed_amplitude", "give either amplitude (angle) or speed_amplitude, not both")
        if r.order > 0:
            if r.frequency:
                raise chk.fail(f"{key}.frequency", "give either order (follows the speed) or frequency, not both")
            if r.speed == 0.0:
                raise chk.fail(f"{key}.order", "an engine-order fluctuation needs a mean speed (speed != 0)")
        elif (r.amplitude or r.speed_amplitude) and not r.frequency > 0:
            raise chk.fail(f"{key}.frequency", "a fluctuation needs frequency > 0 (or an engine order)")
    if len(t.rotation) > 1:
        raise chk.fail("transient.rotation[1]", "only one pulley rotation can be prescribed")
    loads = []
    count = {"torque": 0, "hub_force": 0}
    for load in t.loads:
        key = f"transient.{load.kind}[{count[load.kind]}]"
        count[load.kind] += 1
        j = _pulley_index(chk, f"{key}.pulley", load.pulley, names)
        if load.kind == "hub_force" and pulleys[j].support == "fixed":
            raise chk.fail(f"{key}.pulley", f"pulley '{load.pulley}' has a fixed centre: a hub force "
                                            f"on it goes straight into the ground (give it a slide or bearing)")
        s0 = load.signals[0]
        if any(s.amplitude for s in load.signals) and not s0.frequency > 0:
            raise chk.fail(f"{key}.frequency", "a harmonic load needs frequency > 0")
        if s0.table:
            sha, cols = _read_table(chk, f"{key}.table", s0.table, file, len(load.signals), s0.table_sha256)
            load = replace(load, signals=tuple(replace(s, table_sha256=sha, table_time=cols[0], table_value=cols[1 + c])
                                               for c, s in enumerate(load.signals)))
        elif s0.table_sha256:
            raise chk.fail(f"{key}.table_sha256", "given without a table")
        loads.append(load)
    t = replace(t, loads=tuple(loads))
    if t.spectrum.enabled and t.spectrum.start >= t.duration:
        raise chk.fail("transient.spectrum.start", f"must be < transient.duration ({t.duration:g} s), got "
                                                   f"{t.spectrum.start:g}; or set transient.spectrum.enabled = false")
    if t.step is not None and t.min_step > t.step:
        raise chk.fail("transient.min_step", f"must be <= transient.step ({t.step:g} s)")
    if (t.accuracy is None) != (t.fmax is None):
        given, missing = ("accuracy", "fmax") if t.fmax is None else ("fmax", "accuracy")
        raise chk.fail(f"transient.{missing}", f"missing key: transient.{given} is given; give accuracy and "
                                               f"fmax together or neither")
    return t


def table_bytes(cfg: DriveConfig, names: tuple[str, ...] = ()) -> dict[str, bytes]:
    """The bytes of every CSV table the configuration reads, and of the tables `names` (a sweep's other
    table values), by the name it gives them (read next to cfg.source now; the sha256 check on
    parsing still holds them to the configuration's version)."""
    wanted = [load.signals[0].table for load in cfg.transient.loads] if cfg.transient is not None else []
    base = Path(cfg.source).parent if cfg.source and not cfg.source.startswith("<") else Path(".")
    out: dict[str, bytes] = {}
    for name in [*wanted, *names]:
        if name and name not in out:
            out[name] = ((base / name) if not Path(name).is_absolute() else Path(name)).read_bytes()
    return out


def _read_table(chk: _Checker, key: str, name: str, file: str, n_values: int,
                expect_sha: str = "") -> tuple[str, tuple[tuple, ...]]:
    """CSV (comma or whitespace separated, '#' comments): time, value(s); path relative to the config.
    Returns the sha256 of the file's bytes and the columns; expect_sha (from a resolved configuration)
    must match, so results never mix two versions of a table."""
    base = Path(file).parent if file and not file.startswith("<") else Path(".")
    path = (base / name) if not Path(name).is_absolute() else Path(name)
    try:
        data = chk.tables[name] if name in chk.tables else path.read_bytes()
        lines = data.decode("utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise chk.fail(key, f"cannot read table '{name}': {getattr(exc, 'strerror', None) or exc}") from None
    sha = hashlib.sha256(data).hexdigest()
    if expect_sha and expect_sha != sha:
        raise chk.fail(key, f"table '{name}' changed since this configuration was resolved (sha256 differs)")
    rows = []
    for i, line in enumerate(lines, 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p for p in re.split(r"[,\s;]+", line) if p]
        vals = [_float_or_none(p) for p in parts]
        if None in vals:
            if not rows and all(v is None for v in vals):  # a header line: no number in it
                continue
            raise chk.fail(key, f"table '{name}' line {i}: not numbers: {line!r}")
        if len(vals) != 1 + n_values or not all(math.isfinite(v) for v in vals):
            raise chk.fail(key, f"table '{name}' line {i}: expected {1 + n_values} finite numbers (time, "
                                f"value{'s' if n_values > 1 else ''}), got {line!r}")
        rows.append(vals)
    if len(rows) < 2:
        raise chk.fail(key, f"table '{name}' needs at least 2 rows")
    cols = tuple(zip(*rows))
    if any(b <= a for a, b in zip(cols[0], cols[0][1:])):
        raise chk.fail(key, f"table '{name}': times must increase")
    return sha, cols


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def config_to_dict(cfg: DriveConfig) -> dict[str, Any]:
    """The resolved configuration (defaults filled in) as a TOML-ready dict."""
    out = _dump(cfg)
    for p, d in zip(cfg.pulleys, out["pulleys"]):
        if p.support != "bearing":  # one stiffness (a slide's, or none): written as one number
            d["bearing_stiffness"] = p.bearing_stiffness[0]
    return out


def resolved_toml(cfg: DriveConfig) -> str:
    import tomli_w

    return tomli_w.dumps(config_to_dict(cfg))


def config_hash(cfg: DriveConfig) -> str:
    return hashlib.sha256(resolved_toml(cfg).encode()).hexdigest()


def with_overrides(cfg: DriveConfig, assignments: list[str] | tuple[str, ...]) -> DriveConfig:
    """A new config with dotted-key overrides applied (used by sweeps)."""
    raw = config_to_dict(cfg)
    for a in assignments:
        apply_override(raw, a, file=cfg.source)
    return config_from_dict(raw, file=cfg.source)


__all__ = [
    "Belt", "Pulley", "Tension", "Mesh", "ModelOptions", "StaticOptions", "ModalOptions", "DriveConfig",
    "load_config", "config_from_dict", "config_to_dict", "resolved_toml", "config_hash",
    "apply_override", "with_overrides", "valid_keys", "key_docs", "key", "replace",
]
