"""TOML drive description -> frozen, validated dataclasses.

Every error is a `ConfigError` naming the file and the dotted key path, e.g.
``drive.toml: pulleys[1].radius: must be > 0, got -0.05``. Overrides (``--set KEY=VALUE``) are
applied to the parsed TOML before validation; VALUE is parsed as a TOML literal (never eval), a bare
word being taken as a string. Units are SI everywhere; keys carry no unit suffixes.
"""

from __future__ import annotations

import difflib
import hashlib
import math
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from .errors import ConfigError

SIDES = ("inside", "backside")
SUPPORTS = ("fixed", "slide", "bearing")
TENSION_MODES = ("adjust", "prestrain")
CURVATURES = ("linear", "exact", "none")


@dataclass(frozen=True, kw_only=True)
class Belt:
    """Belt properties. length: undeformed loop length L0 (m); EA (N); EI (N m^2); kg/m."""

    length: float
    EA: float
    EI: float
    mass_per_length: float


@dataclass(frozen=True, kw_only=True)
class Pulley:
    """A rigid pulley. center (m, x right / y up); radius (m); mass (kg); inertia (kg m^2).

    side: the belt touches it from the inside of the loop or on its backside.
    support: "fixed" centre (rotation only), "slide" (moves along slide_direction against
    bearing_stiffness, N/m) or "bearing" (moves in x and y against bearing_stiffness (kx, ky), N/m).
    adjustable: the pulley moved along its slide to fit L0 and to set the tension.
    driver: its rotation is held in the static analysis and reacts the applied torques.
    slide_range: (min, max) travel along the slide from `center`, m (None: unbounded).
    """

    name: str
    center: tuple[float, float]
    radius: float
    mass: float
    inertia: float
    side: str = "inside"
    support: str = "fixed"
    slide_direction: tuple[float, float] = (1.0, 0.0)
    bearing_stiffness: tuple[float, float] = (0.0, 0.0)
    adjustable: bool = False
    driver: bool = False
    slide_range: tuple[float, float] | None = None

    @property
    def n_translation(self) -> int:
        return {"fixed": 0, "slide": 1, "bearing": 2}[self.support]


@dataclass(frozen=True, kw_only=True)
class Tension:
    """target: static span tension (N) reached as `mode` says; None: the geometry alone decides.
    Default mode: "adjust" when a pulley is adjustable, else "prestrain".

    mode "adjust": spans stress-free in the L0 geometry, the adjustable pulley moved along its slide
    until the mean span tension equals the target (the paper's bench). mode "prestrain": pulley
    centres kept, the spans' reference length shortened so that their initial tension is the target.
    """

    target: float | None = None
    mode: str = "adjust"


@dataclass(frozen=True, kw_only=True)
class Mesh:
    elements_per_span: int = 10


@dataclass(frozen=True, kw_only=True)
class ModelOptions:
    """gravity (m/s^2, vector in the drive plane); curvature: "linear" (paper Eq. 17), "exact"
    (Eq. 15) or "none" (string); gauss_points per element for the axial force."""

    gravity: tuple[float, float] = (0.0, 0.0)
    curvature: str = "linear"
    gauss_points: int = 5


@dataclass(frozen=True, kw_only=True)
class StaticOptions:
    """Newton settings: relative force tolerance, iterations per load step, number of load steps."""

    tolerance: float = 1e-10
    max_iterations: int = 40
    load_steps: int = 1


@dataclass(frozen=True, kw_only=True)
class ModalOptions:
    """modes: number of elastic modes wanted; solver: "auto" | "dense" | "sparse"."""

    modes: int = 12
    solver: str = "auto"


@dataclass(frozen=True, kw_only=True)
class Signal:
    """A scalar time function: ramp(t) * (constant + amplitude sin(2 pi frequency t + phase)), or a
    table (time s, value) linearly interpolated (held constant outside). ramp(t) = min(t / ramp_time, 1)."""

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

    pulley: str
    speed: float = 0.0
    ramp_time: float = 0.0
    amplitude: float = 0.0
    speed_amplitude: float = 0.0
    frequency: float = 0.0
    phase: float = 0.0
    fluctuation_ramp: float = 0.0


@dataclass(frozen=True, kw_only=True)
class Load:
    """An applied torque (N m, on the pulley's rotation) or hub force (N, x and y, on its support)."""

    pulley: str
    kind: str  # "torque" | "hub_force"
    signals: tuple[Signal, ...]  # one (torque) or two (x, y)


@dataclass(frozen=True, kw_only=True)
class Record:
    pulley_angles: bool = True
    pulley_speeds: bool = True
    span_tension: bool = True
    hub_load: bool = True
    bearing_force: bool = True
    midspan_displacement: bool = True
    energy: bool = True
    full_state: bool = False


@dataclass(frozen=True, kw_only=True)
class Damping:
    """Rayleigh C = rayleigh_mass M + rayleigh_stiffness K_t(static) (1/s, s); belt material damping
    (Kelvin-Voigt retardation times, s): axial force EA (eps + belt_axial d eps/dt), bending EI likewise."""

    rayleigh_mass: float = 0.0
    rayleigh_stiffness: float = 0.0
    belt_axial: float = 0.0
    belt_bending: float = 0.0


@dataclass(frozen=True, kw_only=True)
class SpectrumOptions:
    enabled: bool = True
    start: float = 0.0
    window: str = "hann"
    peaks: int = 8


@dataclass(frozen=True, kw_only=True)
class TransientOptions:
    """Generalized-alpha time integration (Chung-Hulbert) of the nonlinear drive.

    duration, step, output_interval in s; rho_inf the spectral radius at infinite frequency (1: no
    numerical damping); start "static" (equilibrium) or "rest" (the stress-free reference state).
    """

    duration: float = 1.0
    step: float = 1e-4
    min_step: float = 1e-9
    output_interval: float = 1e-3
    rho_inf: float = 0.9
    start: str = "static"
    tolerance: float = 1e-8
    max_iterations: int = 12
    record: Record = field(default_factory=Record)
    damping: Damping = field(default_factory=Damping)
    spectrum: SpectrumOptions = field(default_factory=SpectrumOptions)
    rotation: tuple[Rotation, ...] = ()
    loads: tuple[Load, ...] = ()


@dataclass(frozen=True, kw_only=True)
class SweepTable:
    """[sweep]: analysis, zip, and params = {"dotted.key" = "SPEC" or [values]} (see `beltdyn sweep`)."""

    analysis: str = "modal"
    zip: bool = False
    params: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True, kw_only=True)
class DriveConfig:
    belt: Belt
    pulleys: tuple[Pulley, ...]
    tension: Tension = field(default_factory=Tension)
    mesh: Mesh = field(default_factory=Mesh)
    model: ModelOptions = field(default_factory=ModelOptions)
    static: StaticOptions = field(default_factory=StaticOptions)
    modal: ModalOptions = field(default_factory=ModalOptions)
    transient: TransientOptions | None = None
    sweep: SweepTable | None = None
    title: str = ""
    source: str = ""  # file the config came from (not part of the resolved TOML)

    @property
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


# ----------------------------------------------------------------------------------------------
# Schema: key -> (kind, default). Kinds: "float", "posfloat", "nonnegfloat", "int", "str:<choices>",
# "bool", "vec2", "posvec2|scalar", "range2", "table", "array-of-tables".
_BELT_KEYS = {
    "length": ("posfloat", None),
    "EA": ("posfloat", None),
    "EI": ("nonnegfloat", None),
    "mass_per_length": ("posfloat", None),
}
_PULLEY_KEYS = {
    "name": ("str", None),
    "center": ("vec2", None),
    "radius": ("posfloat", None),
    "mass": ("posfloat", None),
    "inertia": ("posfloat", None),
    "side": ("choice", SIDES),
    "support": ("choice", SUPPORTS),
    "slide_direction": ("vec2", (1.0, 0.0)),
    "bearing_stiffness": ("stiffness", 0.0),
    "adjustable": ("bool", False),
    "driver": ("bool", False),
    "slide_range": ("range2", None),
}
_TABLES = {
    "tension": {"target": ("posfloat?", None), "mode": ("choice", TENSION_MODES)},
    "mesh": {"elements_per_span": ("posint", 10)},
    "model": {
        "gravity": ("vec2", (0.0, 0.0)),
        "curvature": ("choice", CURVATURES),
        "gauss_points": ("posint", 5),
    },
    "static": {
        "tolerance": ("posfloat", 1e-10),
        "max_iterations": ("posint", 40),
        "load_steps": ("posint", 1),
    },
    "modal": {"modes": ("posint", 12), "solver": ("choice", ("auto", "dense", "sparse"))},
}
_TRANSIENT_KEYS = {
    "duration": ("posfloat", 1.0),
    "step": ("posfloat", 1e-4),
    "min_step": ("posfloat", 1e-9),
    "output_interval": ("posfloat", 1e-3),
    "rho_inf": ("unit", 0.9),
    "start": ("choice", ("static", "rest")),
    "tolerance": ("posfloat", 1e-8),
    "max_iterations": ("posint", 12),
}
_TRANSIENT_SUB = {
    "record": {k: ("bool", None) for k in ("pulley_angles", "pulley_speeds", "span_tension", "hub_load",
                                          "bearing_force", "midspan_displacement", "energy", "full_state")},
    "damping": {k: ("nonnegfloat", 0.0) for k in ("rayleigh_mass", "rayleigh_stiffness", "belt_axial",
                                                 "belt_bending")},
    "spectrum": {"enabled": ("bool", True), "start": ("nonnegfloat", 0.0),
                 "window": ("choice", ("hann", "rect", "flattop")), "peaks": ("posint", 8)},
}
_ROTATION_KEYS = {
    "pulley": ("str", None), "speed": ("float", 0.0), "ramp_time": ("nonnegfloat", 0.0),
    "amplitude": ("float", 0.0), "speed_amplitude": ("float", 0.0), "frequency": ("nonnegfloat", 0.0),
    "phase": ("float", 0.0), "fluctuation_ramp": ("nonnegfloat", 0.0),
}
_SIGNAL_KEYS = {"constant": ("float", 0.0), "amplitude": ("float", 0.0), "frequency": ("nonnegfloat", 0.0),
                "phase": ("float", 0.0), "ramp_time": ("nonnegfloat", 0.0), "table": ("str", None),
                "table_sha256": ("str", None)}
_LOAD_KEYS = {"torque": {"pulley": ("str", None), **_SIGNAL_KEYS},
              "hub_force": {"pulley": ("str", None), **_SIGNAL_KEYS, "constant": ("vec2", None),
                            "amplitude": ("vec2", None)}}
_TOP_KEYS = ["title", "belt", "pulleys", *_TABLES, "transient", "sweep"]
_REQUIRED_PULLEY = ("name", "center", "radius", "mass", "inertia")


def valid_keys() -> list[str]:
    """All dotted keys of the schema (pulley keys as pulleys[i].key)."""
    keys = ["title"] + [f"belt.{k}" for k in _BELT_KEYS] + [f"pulleys[i].{k}" for k in _PULLEY_KEYS]
    for table, spec in _TABLES.items():
        keys += [f"{table}.{k}" for k in spec]
    return keys


class _Checker:
    """Validates raw TOML values, raising ConfigError with the file and key path."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, key: str, message: str) -> ConfigError:
        return ConfigError(message, file=self.file, key=key)

    def unknown(self, key: str, name: str, allowed: list[str]) -> ConfigError:
        close = difflib.get_close_matches(name, allowed, n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else f"; valid keys: {', '.join(allowed)}"
        return self.fail(key, f"unknown key '{name}'{hint}")

    def number(self, key: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"must be a number, got {_show(value)}")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(key, f"must be finite, got {value}")
        return value

    def value(self, key: str, kind: str, arg: Any, value: Any) -> Any:
        if kind == "unit":
            x = self.number(key, value)
            if not 0.0 <= x <= 1.0:
                raise self.fail(key, f"must be in [0, 1], got {_num(x)}")
            return x
        if kind in ("float", "posfloat", "nonnegfloat", "posfloat?"):
            x = self.number(key, value)
            if kind in ("posfloat", "posfloat?") and not x > 0:
                raise self.fail(key, f"must be > 0, got {_num(x)}")
            if kind == "nonnegfloat" and x < 0:
                raise self.fail(key, f"must be >= 0, got {_num(x)}")
            return x
        if kind == "posint":
            if isinstance(value, bool) or not isinstance(value, int):
                raise self.fail(key, f"must be an integer, got {_show(value)}")
            if value < 1:
                raise self.fail(key, f"must be >= 1, got {value}")
            return value
        if kind == "table":
            return value
        if kind == "str":
            if not isinstance(value, str) or not value.strip():
                raise self.fail(key, f"must be a non-empty string, got {_show(value)}")
            return value
        if kind == "choice":
            if value not in arg:
                raise self.fail(key, f"must be one of {', '.join(map(repr, arg))}, got {_show(value)}")
            return value
        if kind == "bool":
            if not isinstance(value, bool):
                raise self.fail(key, f"must be true or false, got {_show(value)}")
            return value
        if kind in ("vec2", "range2"):
            if not isinstance(value, list) or len(value) != 2:
                raise self.fail(key, f"must be a list of 2 numbers, got {_show(value)}")
            x, y = (self.number(f"{key}[{i}]", v) for i, v in enumerate(value))
            if kind == "range2" and not x < y:
                raise self.fail(key, f"must be [min, max] with min < max, got {_show(value)}")
            return (x, y)
        if kind == "stiffness":
            if isinstance(value, list):
                if len(value) != 2:
                    raise self.fail(key, f"must be a number or a list of 2 numbers, got {_show(value)}")
                pair = tuple(self.number(f"{key}[{i}]", v) for i, v in enumerate(value))
            else:
                x = self.number(key, value)
                pair = (x, x)
            for i, k in enumerate(pair):
                if k < 0:
                    raise self.fail(key, f"must be >= 0, got {_num(k)}")
            return pair
        raise AssertionError(kind)

    def table(self, key: str, raw: Any, spec: dict[str, tuple[str, Any]]) -> dict[str, Any]:
        if not isinstance(raw, dict):
            raise self.fail(key, f"must be a table, got {_show(raw)}")
        for name in raw:
            if name not in spec:
                raise self.unknown(f"{key}.{name}" if key else name, name, list(spec))
        out = {}
        for name, (kind, arg) in spec.items():
            if name in raw:
                out[name] = self.value(f"{key}.{name}", kind, arg, raw[name])
        return out


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
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError("file not found", file=str(path)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read: {exc}", file=str(path)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"TOML syntax error: {exc}", file=str(path)) from None


_PATH_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]|\.")


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
    """Apply one ``KEY=VALUE`` override in place (VALUE a TOML literal; never eval)."""
    where = f"--set {assignment}"
    if "=" not in assignment:
        raise ConfigError("expected KEY=VALUE", file=file, key=where)
    key, text = (s.strip() for s in assignment.split("=", 1))
    try:
        parts = _split_key(key)
    except ValueError as exc:
        raise ConfigError(f"bad key '{key}': {exc}", file=file, key=where) from None
    try:
        value = _parse_literal(text)
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
            if i == 0 and part not in _TOP_KEYS:
                raise _Checker(file).unknown(where, str(part), _TOP_KEYS)
            node[part] = [] if isinstance(nxt, int) else {}
        node = node[part]
    last = parts[-1]
    if isinstance(node, list):
        if not isinstance(last, int) or last >= len(node):
            raise ConfigError(f"bad index '{last}'", file=file, key=where)
        node[last] = value
    elif isinstance(node, dict):
        if len(parts) == 1 and last not in _TOP_KEYS:
            raise _Checker(file).unknown(where, str(last), _TOP_KEYS)
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


def config_from_dict(raw: dict[str, Any], *, file: str = "<config>") -> DriveConfig:
    chk = _Checker(file)
    for name in raw:
        if name not in _TOP_KEYS:
            raise chk.unknown(name, name, _TOP_KEYS)
    title = raw.get("title", "")
    if not isinstance(title, str):
        raise chk.fail("title", f"must be a string, got {_show(title)}")
    if "belt" not in raw:
        raise chk.fail("belt", "missing table [belt]")
    belt_raw = chk.table("belt", raw["belt"], _BELT_KEYS)
    for name in _BELT_KEYS:
        if name not in belt_raw:
            raise chk.fail(f"belt.{name}", "missing key")
    belt = Belt(**belt_raw)

    plist = raw.get("pulleys")
    if plist is None:
        raise chk.fail("pulleys", "missing: give at least 2 [[pulleys]] in belt order")
    if not isinstance(plist, list) or not all(isinstance(p, dict) for p in plist):
        raise chk.fail("pulleys", "must be an array of tables [[pulleys]]")
    if len(plist) < 2:
        raise chk.fail("pulleys", f"need at least 2 pulleys, got {len(plist)}")
    pulleys = []
    for i, praw in enumerate(plist):
        key = f"pulleys[{i}]"
        vals = chk.table(key, praw, _PULLEY_KEYS)
        for name in _REQUIRED_PULLEY:
            if name not in vals:
                raise chk.fail(f"{key}.{name}", "missing key")
        support = vals.get("support", "fixed")
        if "slide_direction" in vals:
            dx, dy = vals["slide_direction"]
            norm = math.hypot(dx, dy)
            if norm == 0:
                raise chk.fail(f"{key}.slide_direction", "must not be the zero vector")
            if abs(norm - 1.0) > 4 * 2.0**-52:  # a unit vector (to rounding) is kept as given, so that
                vals["slide_direction"] = (dx / norm, dy / norm)  # the resolved TOML round-trips
        if support == "fixed" and "bearing_stiffness" in vals and any(vals["bearing_stiffness"]):
            raise chk.fail(f"{key}.bearing_stiffness", "a fixed-centre pulley has no bearing spring; "
                           "use support = \"slide\" or \"bearing\"")
        if support == "slide" and isinstance(praw.get("bearing_stiffness"), list):
            raise chk.fail(f"{key}.bearing_stiffness", "a slide has one stiffness (N/m along the slide)")
        if vals.get("adjustable") and support != "slide":
            raise chk.fail(f"{key}.adjustable", "the adjustable pulley needs support = \"slide\"")
        if "slide_range" in vals and support != "slide":
            raise chk.fail(f"{key}.slide_range", "only a slide pulley has a slide range")
        pulleys.append(Pulley(**vals))
    names = [p.name for p in pulleys]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise chk.fail(f"pulleys[{i}].name", f"duplicate pulley name '{n}'")
    adjustable = [i for i, p in enumerate(pulleys) if p.adjustable]
    if len(adjustable) > 1:
        raise chk.fail(f"pulleys[{adjustable[1]}].adjustable",
                       f"only one pulley may be adjustable (pulleys[{adjustable[0]}] already is)")
    drivers = [i for i, p in enumerate(pulleys) if p.driver]
    if len(drivers) > 1:
        raise chk.fail(f"pulleys[{drivers[1]}].driver", "only one pulley may be the driver")

    tables = {}
    for tname, spec in _TABLES.items():
        tables[tname] = chk.table(tname, raw.get(tname, {}), spec)
    if "mode" not in tables["tension"]:  # default: move the adjustable pulley if there is one
        tables["tension"]["mode"] = "adjust" if adjustable else "prestrain"
    tension = Tension(**tables["tension"])
    if tension.target is not None and tension.mode == "adjust" and not adjustable:
        raise chk.fail("tension.mode", "mode \"adjust\" needs one pulley with adjustable = true "
                       "(or use mode = \"prestrain\")")
    transient = None
    if "transient" in raw:
        transient = _parse_transient(chk, raw["transient"], names, pulleys, file)
    sweep = None
    if "sweep" in raw:
        sweep = _parse_sweep(chk, raw["sweep"])
    cfg = DriveConfig(
        sweep=sweep,
        transient=transient,
        belt=belt,
        pulleys=tuple(pulleys),
        tension=tension,
        mesh=Mesh(**tables["mesh"]),
        model=ModelOptions(**tables["model"]),
        static=StaticOptions(**tables["static"]),
        modal=ModalOptions(**tables["modal"]),
        title=title,
        source=file,
    )
    return cfg


def _read_table(chk: _Checker, key: str, name: str, file: str, n_values: int,
                expect_sha: str | None = None) -> tuple[str, tuple[tuple, ...]]:
    """CSV (comma or whitespace separated, '#' comments): time, value(s); path relative to the config.
    Returns the sha256 of the file's bytes and the columns; expect_sha (from a resolved configuration)
    must match, so results never mix two versions of a table."""
    base = Path(file).parent if file and not file.startswith("<") else Path(".")
    path = (base / name) if not Path(name).is_absolute() else Path(name)
    try:
        data = path.read_bytes()
        lines = data.decode("utf-8").splitlines()
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
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            if not rows:  # a header line
                continue
            raise chk.fail(key, f"table '{name}' line {i}: not numbers: {line!r}") from None
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


def _pulley_index(chk: _Checker, key: str, name: Any, names: list[str]) -> int:
    if not isinstance(name, str) or name not in names:
        raise chk.fail(key, f"no pulley named {_show(name)}; pulleys are {', '.join(names)}")
    return names.index(name)


def _parse_transient(chk: _Checker, raw: Any, names: list[str], pulleys: list[Pulley], file: str) -> TransientOptions:
    spec = {**_TRANSIENT_KEYS, **{k: ("table", None) for k in _TRANSIENT_SUB},
            "rotation": ("list", None), "torque": ("list", None), "hub_force": ("list", None)}
    if not isinstance(raw, dict):
        raise chk.fail("transient", "must be a table")
    for name in raw:
        if name not in spec:
            raise chk.unknown(f"transient.{name}", name, list(spec))
    top = chk.table("transient", {k: v for k, v in raw.items() if k in _TRANSIENT_KEYS}, _TRANSIENT_KEYS)
    subs = {k: chk.table(f"transient.{k}", raw.get(k, {}), v) for k, v in _TRANSIENT_SUB.items()}
    record = Record(**subs["record"])
    damping = Damping(**subs["damping"])
    spectrum = SpectrumOptions(**subs["spectrum"])

    def entries(kind: str) -> list[dict]:
        lst = raw.get(kind, [])
        if not isinstance(lst, list) or not all(isinstance(x, dict) for x in lst):
            raise chk.fail(f"transient.{kind}", f"must be an array of tables [[transient.{kind}]]")
        return lst

    rotations = []
    for i, r in enumerate(entries("rotation")):
        key = f"transient.rotation[{i}]"
        vals = chk.table(key, r, _ROTATION_KEYS)
        if "pulley" not in vals:
            raise chk.fail(f"{key}.pulley", "missing key")
        _pulley_index(chk, f"{key}.pulley", vals["pulley"], names)
        if vals.get("amplitude", 0.0) and vals.get("speed_amplitude", 0.0):
            raise chk.fail(f"{key}.speed_amplitude", "give either amplitude (angle) or speed_amplitude, not both")
        if (vals.get("amplitude", 0.0) or vals.get("speed_amplitude", 0.0)) and not vals.get("frequency", 0.0) > 0:
            raise chk.fail(f"{key}.frequency", "a fluctuation needs frequency > 0")
        rotations.append(Rotation(**vals))
    if len(rotations) > 1:
        raise chk.fail("transient.rotation[1]", "only one pulley rotation can be prescribed")
    loads = []
    for kind in ("torque", "hub_force"):
        n_val = 1 if kind == "torque" else 2
        for i, r in enumerate(entries(kind)):
            key = f"transient.{kind}[{i}]"
            vals = chk.table(key, r, _LOAD_KEYS[kind])
            if "pulley" not in vals:
                raise chk.fail(f"{key}.pulley", "missing key")
            j = _pulley_index(chk, f"{key}.pulley", vals["pulley"], names)
            if kind == "hub_force" and pulleys[j].support == "fixed":
                raise chk.fail(f"{key}.pulley", f"pulley '{vals['pulley']}' has a fixed centre: a hub force "
                                                f"on it goes straight into the ground (give it a slide or bearing)")
            if vals.get("amplitude") and any(vals["amplitude"] if n_val == 2 else [vals["amplitude"]]) \
                    and not vals.get("frequency", 0.0) > 0:
                raise chk.fail(f"{key}.frequency", "a harmonic load needs frequency > 0")
            tab: tuple[tuple, ...] = ()
            sha = ""
            if vals.get("table"):
                sha, tab = _read_table(chk, f"{key}.table", vals["table"], file, n_val, vals.get("table_sha256"))
            elif vals.get("table_sha256"):
                raise chk.fail(f"{key}.table_sha256", "given without a table")
            sigs = []
            for c in range(n_val):
                pick = (lambda v: v) if n_val == 1 else (lambda v, c=c: v[c])
                sigs.append(Signal(
                    constant=pick(vals.get("constant", 0.0 if n_val == 1 else (0.0, 0.0))),
                    amplitude=pick(vals.get("amplitude", 0.0 if n_val == 1 else (0.0, 0.0))),
                    frequency=vals.get("frequency", 0.0), phase=vals.get("phase", 0.0),
                    ramp_time=vals.get("ramp_time", 0.0), table=vals.get("table", ""), table_sha256=sha,
                    table_time=tab[0] if tab else (), table_value=tab[1 + c] if tab else ()))
            loads.append(Load(pulley=vals["pulley"], kind=kind, signals=tuple(sigs)))
    opts = TransientOptions(**top, record=record, damping=damping, spectrum=spectrum,
                            rotation=tuple(rotations), loads=tuple(loads))
    if spectrum.enabled and spectrum.start >= opts.duration:
        raise chk.fail("transient.spectrum.start", f"must be < transient.duration ({opts.duration:g} s), got "
                                                   f"{spectrum.start:g}; or set transient.spectrum.enabled = false")
    if opts.min_step > opts.step:
        raise chk.fail("transient.min_step", f"must be <= transient.step ({opts.step:g} s)")
    return opts


def _parse_sweep(chk: _Checker, raw: Any) -> SweepTable:
    vals = chk.table("sweep", raw, {"analysis": ("choice", ("static", "modal", "transient")), "zip": ("bool", False),
                                    "params": ("table", None)})
    params = vals.pop("params", {})
    if not isinstance(params, dict):
        raise chk.fail("sweep.params", "must be a table of \"dotted.key\" = \"SPEC\" or [values]")
    out = []
    for key, spec in params.items():
        if isinstance(spec, list):
            spec = ",".join(str(x).lower() if isinstance(x, bool) else (f'"{x}"' if isinstance(x, str) else repr(x))
                            for x in spec)
        if not isinstance(spec, str):
            raise chk.fail(f"sweep.params.{key}", f"must be a SPEC string or a list, got {_show(spec)}")
        out.append((key, spec))
    return SweepTable(**vals, params=tuple(out))


def _transient_to_dict(t: TransientOptions) -> dict[str, Any]:
    out: dict[str, Any] = {k: getattr(t, k) for k in _TRANSIENT_KEYS}
    out["record"] = {f.name: getattr(t.record, f.name) for f in fields(t.record)}
    out["damping"] = {f.name: getattr(t.damping, f.name) for f in fields(t.damping)}
    out["spectrum"] = {f.name: getattr(t.spectrum, f.name) for f in fields(t.spectrum)}
    out["rotation"] = [{f.name: getattr(r, f.name) for f in fields(r)} for r in t.rotation]
    for kind in ("torque", "hub_force"):
        items = []
        for load in t.loads:
            if load.kind != kind:
                continue
            s0 = load.signals[0]
            d: dict[str, Any] = {"pulley": load.pulley}
            if kind == "torque":
                d.update(constant=s0.constant, amplitude=s0.amplitude)
            else:
                d.update(constant=[x.constant for x in load.signals], amplitude=[x.amplitude for x in load.signals])
            d.update(frequency=s0.frequency, phase=s0.phase, ramp_time=s0.ramp_time)
            if s0.table:
                d["table"] = s0.table
                d["table_sha256"] = s0.table_sha256
            items.append(d)
        out[kind] = items
    return out


def config_to_dict(cfg: DriveConfig) -> dict[str, Any]:
    """The resolved configuration (defaults filled in) as a TOML-ready dict."""

    def clean(obj: Any) -> Any:
        if isinstance(obj, tuple):
            return [clean(x) for x in obj]
        return obj

    out: dict[str, Any] = {}
    if cfg.title:
        out["title"] = cfg.title
    out["belt"] = {f.name: getattr(cfg.belt, f.name) for f in fields(cfg.belt)}
    out["pulleys"] = []
    for p in cfg.pulleys:
        d = {}
        for f in fields(p):
            v = getattr(p, f.name)
            if v is None:
                continue
            if f.name == "bearing_stiffness" and p.support != "bearing":
                v = v[0]
            d[f.name] = clean(v)
        out["pulleys"].append(d)
    for tname in _TABLES:
        obj = getattr(cfg, tname)
        out[tname] = {f.name: clean(getattr(obj, f.name)) for f in fields(obj)
                      if getattr(obj, f.name) is not None}
    if cfg.transient is not None:
        out["transient"] = _transient_to_dict(cfg.transient)
    if cfg.sweep is not None:
        out["sweep"] = {"analysis": cfg.sweep.analysis, "zip": cfg.sweep.zip, "params": dict(cfg.sweep.params)}
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
    "apply_override", "with_overrides", "valid_keys", "replace",
]
