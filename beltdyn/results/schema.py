"""The results schema: what a group holds and the rules it must follow (no file access here).

`Variable` and `GroupData` describe one analysis group; `prepare` validates them (names, dims and
their sizes, units, dtypes: numbers or str, bool stored as int8, no complex) and adds integer index
coordinates for dimensions given without values; `prepare_attrs` validates group attributes. The
layout these describe is documented in `results_io`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

STATUSES = ("running", "complete", "failed", "interrupted")
FINAL_STATUSES = ("complete", "failed", "interrupted")
TIME_DIM = "time"
PROVENANCE = "provenance"
# the writer's bookkeeping of a group (status, error, the running writer and its stream journal)
WRITER_ATTRS = ("writer_pid", "writer_host", "writer_start", "stream_journal", "started_utc")
RESERVED_GROUP_ATTRS = frozenset({"status", "error", "parts", *WRITER_ATTRS})  # parts: the group's part files
# Attribute names used by the HDF5 dimension-scale API and by netCDF-4; never set by callers.
RESERVED_ATTRS = frozenset(
    {"CLASS", "NAME", "DIMENSION_LIST", "REFERENCE_LIST", "DIMENSION_LABELS", "_Netcdf4Dimid",
     "_Netcdf4Coordinates", "_NCProperties", "_FillValue"}
)
MAX_ERROR_CHARS = 10_000  # attributes live in the object header (64 KiB limit): keep them short
CHUNK_ROWS = 256  # rows per chunk of a growable time series ("a few hundred")
CHUNK_BYTES = 1 << 20  # at most ~1 MiB per chunk (the HDF5 default chunk cache size)


# --------------------------------------------------------------------------------------------
# Public data classes
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class Variable:
    """One dataset: numeric array (float/int; bool is stored as int8) or strings, with its dims."""

    name: str
    data: np.ndarray | list[str]
    dims: tuple[str, ...]
    units: str
    description: str = ""

    def __post_init__(self) -> None:
        check_name(self.name, "variable name")
        object.__setattr__(self, "dims", check_dims(self.dims, f"variable {self.name!r}"))
        check_units(self.units, f"variable {self.name!r}")
        if not isinstance(self.description, str):
            raise TypeError(f"variable {self.name!r}: description must be a str")


@dataclass(frozen=True, kw_only=True)
class GroupData:
    """The content of one analysis group (see the module docstring for the layout)."""

    name: str
    coords: dict[str, np.ndarray | list[str]]
    coord_units: dict[str, str] = field(default_factory=dict)
    variables: tuple[Variable, ...] = ()
    attrs: dict[str, str | int | float] = field(default_factory=dict)
    status: str = "complete"
    error: str = ""

    def __post_init__(self) -> None:
        check_name(self.name, "group name")
        if self.status not in STATUSES:
            raise ValueError(f"group {self.name!r}: status must be one of {STATUSES}, not {self.status!r}")
        object.__setattr__(self, "variables", tuple(self.variables))
        for var in self.variables:
            if not isinstance(var, Variable):
                raise TypeError(f"group {self.name!r}: variables must be Variable instances")


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


@dataclass
class Prepared:
    """A validated group content, ready to be written."""

    # dim -> (values, is_str, units, description)
    coords: dict[str, tuple[np.ndarray, bool, str, str]]
    # (name, values, is_str, dims, units, description)
    variables: list[tuple[str, np.ndarray, bool, tuple[str, ...], str, str]]


def h5py_module():
    """h5py, imported on first use (the CLI starts without it)."""
    import h5py  # noqa: PLC0415 - lazy on purpose (CLI start-up time)

    return h5py


def check_name(name: Any, what: str) -> str:
    if not isinstance(name, str) or not name or "/" in name or name in (".", "..") or "\x00" in name:
        raise ValueError(f"{what} must be a non-empty str without '/', got {name!r}")
    return name


def check_dims(dims: Any, where: str) -> tuple[str, ...]:
    if isinstance(dims, str):
        raise TypeError(f"{where}: dims must be a tuple of names, not the str {dims!r}")
    dims = tuple(dims)
    for dim in dims:
        check_name(dim, f"{where}: dimension name")
    if len(set(dims)) != len(dims):
        raise ValueError(f"{where}: repeated dimension in {dims} (xarray/netCDF need distinct names, "
                         "e.g. 'dof_i', 'dof_j')")
    return dims


def check_units(units: Any, where: str) -> str:
    if not isinstance(units, str) or not units:
        raise ValueError(f"{where}: units must be a non-empty str (\"1\" for dimensionless)")
    return units


def check_provenance_args(config_toml: Any, config_sha256: Any) -> None:
    if not isinstance(config_toml, str):
        raise TypeError("config_toml must be a str")
    if not isinstance(config_sha256, str) or not config_sha256:
        raise ValueError("config_sha256 must be a non-empty str")


def check_series(series: Any, where: str) -> dict[str, tuple[tuple[int, ...], str, tuple[str, ...]]]:
    out = {}
    for sname, spec in dict(series).items():
        check_name(sname, f"{where}: series name")
        if sname == TIME_DIM:
            raise ValueError(f"{where}: series may not be called {TIME_DIM!r}")
        try:
            shape, units, sdims = spec
        except (TypeError, ValueError):
            raise ValueError(f"{where}: series {sname!r} must be (trailing shape, units, trailing dims)") from None
        shape = tuple(int(n) for n in shape)
        if any(n < 1 for n in shape):
            raise ValueError(f"{where}: series {sname!r} has a trailing shape {shape} with an empty axis")
        sdims = check_dims(sdims, f"{where}: series {sname!r}")
        if len(sdims) != len(shape):
            raise ValueError(f"{where}: series {sname!r} has {len(shape)} trailing axes but dims {sdims}")
        if TIME_DIM in sdims:
            raise ValueError(f"{where}: series {sname!r} uses {TIME_DIM!r} as a trailing dimension")
        out[sname] = (shape, check_units(units, f"{where}: series {sname!r}"), sdims)
    return out


def to_array(data: Any, where: str) -> tuple[np.ndarray, bool]:
    """Numeric data -> numpy array (bool -> int8); strings -> object array of str. (array, is_str)."""
    if isinstance(data, (list, tuple)) and len(data) == 0:
        return np.array([], dtype=object), True
    if isinstance(data, str):
        return np.array(data, dtype=object), True
    arr = np.asarray(data)
    kind = arr.dtype.kind
    if kind == "b":
        return arr.astype(np.int8), False
    if kind in "iuf":
        return arr, False
    if kind == "c":
        raise ValueError(f"{where}: complex data is not stored; write real and imaginary parts as "
                         "separate variables")
    if kind == "U":
        return arr.astype(object), True
    if kind == "S":
        return np.vectorize(lambda b: b.decode("utf-8"), otypes=[object])(arr), True
    if kind == "O" and all(isinstance(x, str) for x in arr.flat):
        return arr, True
    raise ValueError(f"{where}: unsupported data of dtype {arr.dtype} (numbers or str only)")


def same_values(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape:
        return False
    if (a.dtype.kind == "O") != (b.dtype.kind == "O"):
        return False
    if a.dtype.kind == "O":
        return bool(np.all(a == b))
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f" or b.dtype.kind == "f"))


def prepare(
    coords: dict,
    coord_units: dict,
    variables: tuple[Variable, ...],
    *,
    where: str,
    extra_sizes: dict[str, int] | None = None,
    existing: set[str] | None = None,
    taken: set[str] | None = None,
) -> Prepared:
    """Validate coordinates and variables of one group; add integer index coordinates.

    `extra_sizes`: sizes of further dimensions (e.g. series' trailing axes) that need coordinates;
    `existing`: dimensions whose coordinates are in the file already; `taken`: names in use."""
    taken = set(taken or ())
    sizes: dict[str, int] = dict(extra_sizes or {})
    known = set(existing or ())
    pcoords: dict[str, tuple[np.ndarray, bool, str, str]] = {}
    for dim, values in dict(coords).items():
        check_name(dim, f"{where}: coordinate name")
        if dim in taken:
            raise ValueError(f"{where}: coordinate {dim!r} clashes with an existing name")
        arr, is_str = to_array(values, f"{where}: coordinate {dim!r}")
        if arr.ndim != 1:
            raise ValueError(f"{where}: coordinate {dim!r} must be 1-D, got shape {arr.shape}")
        if sizes.setdefault(dim, arr.shape[0]) != arr.shape[0]:
            raise ValueError(f"{where}: coordinate {dim!r} has {arr.shape[0]} values, dimension size is {sizes[dim]}")
        units = check_units(dict(coord_units).get(dim, "1"), f"{where}: coordinate {dim!r}")
        pcoords[dim] = (arr, is_str, units, "")
    pvars = []
    names: set[str] = set()
    for var in variables:
        if not isinstance(var, Variable):
            raise TypeError(f"{where}: variables must be Variable instances")
        vwhere = f"{where}: variable {var.name!r}"
        if var.name in names or var.name in pcoords or var.name in taken:
            raise ValueError(f"{vwhere}: the name is used twice (variables, coordinates and series "
                             "share one namespace)")
        names.add(var.name)
        arr, is_str = to_array(var.data, vwhere)
        if arr.ndim != len(var.dims):
            raise ValueError(f"{vwhere}: data has {arr.ndim} axes but dims are {var.dims}")
        for dim, n in zip(var.dims, arr.shape):
            if sizes.setdefault(dim, n) != n:
                raise ValueError(f"{vwhere}: dimension {dim!r} has size {n}, elsewhere {sizes[dim]}")
        pvars.append((var.name, arr, is_str, var.dims, var.units, var.description))
    for dim in dict(coord_units):
        if dim not in sizes:
            raise ValueError(f"{where}: coord_units names {dim!r}, which is not a dimension")
    for dim, n in sizes.items():
        if dim in pcoords or dim in known:
            continue
        if dim in names or dim in taken:
            raise ValueError(f"{where}: {dim!r} is both a dimension and a variable; pass its values in coords")
        units = check_units(dict(coord_units).get(dim, "1"), f"{where}: coordinate {dim!r}")
        pcoords[dim] = (np.arange(n, dtype=np.int64), False, units, "integer index")
    return Prepared(coords=pcoords, variables=pvars)


def prepare_attrs(attrs: dict, *, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in dict(attrs).items():
        if not isinstance(key, str) or not key or "\x00" in key:
            raise ValueError(f"{where}: attribute names must be non-empty str, got {key!r}")
        if key in RESERVED_GROUP_ATTRS or key in RESERVED_ATTRS:
            raise ValueError(f"{where}: attribute {key!r} is reserved")
        if isinstance(value, (bool, np.bool_)):
            out[key] = np.int8(value)
        elif isinstance(value, str):
            out[key] = value
        elif isinstance(value, (int, np.integer)):
            out[key] = np.int64(value)
        elif isinstance(value, (float, np.floating)):
            out[key] = np.float64(value)
        elif isinstance(value, (list, tuple)) and len(value) == 0:  # an empty list of strings (warnings)
            out[key] = np.array([], dtype=h5py_module().string_dtype())
        elif isinstance(value, (list, tuple, np.ndarray)):
            arr, is_str = to_array(value, f"{where}: attribute {key!r}")
            if arr.ndim != 1:
                raise ValueError(f"{where}: attribute {key!r} must be a scalar or 1-D")
            if is_str:
                out[key] = [str(x) for x in arr]
            else:
                out[key] = arr
        else:
            raise ValueError(f"{where}: attribute {key!r} has unsupported type {type(value).__name__}")
    return out


def decode_attr(value: Any) -> Any:
    """An attribute as read by h5py -> str / numpy array of str / Python scalar / array."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "OS":
            return np.array([v.decode("utf-8", "replace") if isinstance(v, bytes) else str(v)
                             for v in value.reshape(-1)], dtype=str).reshape(value.shape)
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def var_name(key: str) -> str:
    """A dotted configuration key as an HDF5 variable name (tension.target -> tension_target)."""
    return re.sub(r"[^A-Za-z0-9_]", "_", key).strip("_")
