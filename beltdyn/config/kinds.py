"""The declarative schema's machinery: the value kinds (how one TOML value is checked, converted
(`parse`) and written back (`dump`)), `key()` that declares a dataclass field a TOML key, the generic
parse and dump of a declared table (`_parse`, `_dump`) and the checker that raises `ConfigError` with
the file and the key path."""

from __future__ import annotations

import difflib
import functools
import math
from dataclasses import MISSING, Field, field, fields
from typing import Any, NamedTuple

from beltdyn.errors import ConfigError


DEFAULT_STEP = 1e-4  # s: transient.step when neither it nor transient.accuracy and fmax are given

SIDES = ("inside", "backside")
SUPPORTS = ("fixed", "slide", "bearing", "arm")
TENSION_MODES = ("adjust", "prestrain", "spring", "length")
CURVATURES = ("linear", "exact", "none")
WRAP_MODELS = ("creep", "rigid")  # belt.wraps: adhesion + slip arc (model.wraps), or inextensible without slip
AXIAL_LAWS = ("green-lagrange", "linear")  # belt.axial_law: the laws of model.barlaw
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
