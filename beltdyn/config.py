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
class DriveConfig:
    belt: Belt
    pulleys: tuple[Pulley, ...]
    tension: Tension = field(default_factory=Tension)
    mesh: Mesh = field(default_factory=Mesh)
    model: ModelOptions = field(default_factory=ModelOptions)
    static: StaticOptions = field(default_factory=StaticOptions)
    modal: ModalOptions = field(default_factory=ModalOptions)
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
_TOP_KEYS = ["title", "belt", "pulleys", *_TABLES]
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
    cfg = DriveConfig(
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
