"""HDF5 results files: the only module that imports h5py (lazily, so that the CLI starts fast).

Layout (schema version `beltdyn.SCHEMA_VERSION`):

* root attributes `beltdyn_version`, `schema_version`, `created_utc` (ISO 8601, UTC, kept from the
  file's creation), `modified_utc` (last write), `config_sha256` and, from the CLI,
  `base_config_sha256`;
* `/provenance/config_toml`: the resolved configuration, a scalar UTF-8 string dataset;
* one group per analysis (`/geometry`, `/static`, `/modal`, `/transient`, `/sweep`) with a string
  attribute `status` (`running|complete|failed|interrupted`) and, when the analysis failed or was
  interrupted, an `error` attribute with the message.

Inside a group every dimension has a 1-D coordinate dataset of the same name that is an HDF5
dimension scale (integer index 0..n-1 when no values are given); every axis of every other dataset
is attached to the scale of its dimension. Every dataset has a `units` attribute ("1" for
dimensionless values and for string labels) and optionally a `description`. Strings are
variable-length UTF-8; there are no bool (stored as int8) or complex (refused: store real and
imaginary parts separately) datasets. Such files open in h5py, in HDFView and in xarray
(`xarray.open_datatree(path, engine="h5netcdf")`).

Writes are atomic: the target is copied to `<name>.tmp-<pid>-<token>` in the same directory, the
copy is modified, flushed, fsync'ed and `os.replace`d over the target. A failed or interrupted
write leaves the target as it was. Writing results of a different configuration (other
`config_sha256`, or another schema version) into an existing file raises `OutputError` unless
`force=True`, in which case the file is started afresh; so is a file that is not a beltdyn results
file (not HDF5, unreadable, or another program's HDF5), which is refused without `force`. A
read-only file is refused even with `force` ("permission denied"). A root attribute
`base_config_sha256` records the configuration as given when the results are of a configuration
derived from it (`modal --rtol` records the chosen mesh as `config_sha256`).
"""

from __future__ import annotations

import os
import secrets
import shutil
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from . import SCHEMA_VERSION, __version__
from .errors import OutputError

__all__ = [
    "GroupData",
    "StreamWriter",
    "Variable",
    "check_target",
    "read_group",
    "read_root_attrs",
    "write_group",
    "write_groups",
]

_STATUSES = ("running", "complete", "failed", "interrupted")
_FINAL_STATUSES = ("complete", "failed", "interrupted")
_TIME_DIM = "time"

_PROVENANCE = "provenance"
_RESERVED_GROUP_ATTRS = frozenset({"status", "error"})
# Attribute names used by the HDF5 dimension-scale API and by netCDF-4; never set by callers.
_RESERVED_ATTRS = frozenset(
    {"CLASS", "NAME", "DIMENSION_LIST", "REFERENCE_LIST", "DIMENSION_LABELS", "_Netcdf4Dimid",
     "_Netcdf4Coordinates", "_NCProperties", "_FillValue"}
)
_MAX_ERROR_CHARS = 10_000  # attributes live in the object header (64 KiB limit): keep them short
_CHUNK_ROWS = 256  # rows per chunk of a growable time series ("a few hundred")
_CHUNK_BYTES = 1 << 20  # at most ~1 MiB per chunk (the HDF5 default chunk cache size)
_BUFFER_BYTES = 4 << 20  # at most ~4 MiB of rows buffered in memory by StreamWriter


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
        _check_name(self.name, "variable name")
        object.__setattr__(self, "dims", _check_dims(self.dims, f"variable {self.name!r}"))
        _check_units(self.units, f"variable {self.name!r}")
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
        _check_name(self.name, "group name")
        if self.status not in _STATUSES:
            raise ValueError(f"group {self.name!r}: status must be one of {_STATUSES}, not {self.status!r}")
        object.__setattr__(self, "variables", tuple(self.variables))
        for var in self.variables:
            if not isinstance(var, Variable):
                raise TypeError(f"group {self.name!r}: variables must be Variable instances")


# --------------------------------------------------------------------------------------------
# Public functions
# --------------------------------------------------------------------------------------------


HELD_LOCKS: set[int] = set()  # lock descriptors of this process (closed in forked sweep workers)
_OUTPUT_LOCKS: dict[str, int] = {}  # results-file lock path -> its descriptor


class LockBusy(Exception):
    """`take_lock`: another process holds the lock (its pid, if it wrote one)."""

    def __init__(self, pid: int | None) -> None:
        super().__init__(pid)
        self.pid = pid

    @property
    def who(self) -> str:
        return f"pid {self.pid}" if self.pid else "another process"


def take_lock(lock: Path) -> int | None:
    """flock the file `lock` (exclusive, no waiting) and write this process's pid into it; the descriptor
    (in HELD_LOCKS), or None when the holder removed the lock file between our open and flock (take it
    again). LockBusy(pid) when another process holds it; an OSError of the open propagates."""
    import fcntl

    fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = lock_pid(fd)
        os.close(fd)
        raise LockBusy(pid) from None
    try:
        same = os.stat(lock).st_ino == os.fstat(fd).st_ino
    except FileNotFoundError:
        same = False
    if not same:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    HELD_LOCKS.add(fd)
    return fd


def lock_output(path: Path) -> None:
    """Hold `<path>.lock` (flock, exclusive, no waiting) for the rest of this process: a second beltdyn
    command writing the same results file is refused (OutputError, exit 2, naming the holder's pid)
    instead of replacing it when it ends (its results would be lost). Released when the process exits
    (the lock file is removed then)."""
    import atexit

    lock = Path(str(path) + ".lock")
    key = os.path.abspath(lock)
    if _OUTPUT_LOCKS.get(key) in HELD_LOCKS:  # this process holds it already
        return
    for _ in range(20):
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)  # as the writer would (results/ by default)
            fd = take_lock(lock)
        except OSError:
            return  # no lock possible here (a read-only folder): the write itself will say why
        except LockBusy as busy:
            raise OutputError(f"results file {path} is being written by {busy.who} (another beltdyn command on the "
                              f"same output); wait for it to finish or write to another file with -o") from None
        if fd is None:  # the holder finished and removed the lock file between our open and flock
            continue
        _OUTPUT_LOCKS[key] = fd
        pid = os.getpid()

        def release() -> None:
            if os.getpid() == pid and fd in HELD_LOCKS:  # not in a forked child
                try:
                    lock.unlink()
                except OSError:
                    pass
                HELD_LOCKS.discard(fd)
                os.close(fd)

        atexit.register(release)
        return
    raise OutputError(f"cannot lock the results file {path}: its lock keeps disappearing")


def lock_pid(fd: int) -> int | None:
    """The pid a lock holder wrote into its lock file (it writes it right after locking)."""
    import time

    for _ in range(20):
        try:
            text = os.pread(fd, 32, 0).decode().strip()
        except OSError:
            return None
        if text.isdigit():
            return int(text)
        time.sleep(0.01)
    return None


def check_target(path: Path, *, config_sha256: str, force: bool = False,
                 base_config_sha256: str | None = None) -> None:
    """Raise `OutputError` early (before any analysis runs) if `path` cannot receive the results.

    Refused: a directory; a read-only file (even with `force`); a file that is not a beltdyn results
    file (not HDF5, unreadable, or HDF5 of another program) or a beltdyn file of another
    configuration or schema version, unless `force` (which replaces it); a parent directory that
    cannot be created or written. With `base_config_sha256`, a file whose root attribute
    `base_config_sha256` equals it is accepted too (`modal --rtol` re-run on its own output).
    """
    path = _resolve_target(path)
    _inspect_target(path, config_sha256=config_sha256, force=force, base_config_sha256=base_config_sha256)
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{path}: cannot create the output directory: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write to directory {parent} (permission denied)")


def write_group(
    path: Path, group: GroupData, *, config_toml: str, config_sha256: str, force: bool = False
) -> None:
    """Atomically add or replace one group of the results file at `path` (see `write_groups`)."""
    write_groups(path, [group], config_toml=config_toml, config_sha256=config_sha256, force=force)


def write_groups(
    path: Path, groups: list[GroupData], *, config_toml: str, config_sha256: str, force: bool = False,
    base_config_sha256: str | None = None,
) -> None:
    """Atomically add or replace several groups of the results file at `path` in one transaction.

    The existing file (if any) is copied to a temporary file in the same directory; if it holds
    another configuration, `OutputError` is raised unless `force` (then a fresh file is started).
    The groups are replaced, the root attributes and `/provenance/config_toml` are written, and the
    temporary file is flushed, fsync'ed and renamed over `path`. On any exception the temporary file
    is removed and `path` is untouched. Parent directories are created. `base_config_sha256` (the
    configuration as given when the results are of a derived one, `modal --rtol`) is stored as a
    root attribute; the file's own check stays on `config_sha256`.
    """
    path = _resolve_target(path)
    _check_provenance_args(config_toml, config_sha256)
    ready = []
    for group in groups:
        if not isinstance(group, GroupData):
            raise TypeError("write_groups: groups must be GroupData")
        if group.name == _PROVENANCE:
            raise ValueError(f"group name {_PROVENANCE!r} is reserved")
        prepared = _prepare(group.coords, group.coord_units, group.variables, where=f"group {group.name!r}")
        ready.append((group, prepared, _prepare_attrs(group.attrs, where=f"group {group.name!r}")))

    tmp, f, fresh = _open_temp(path, config_sha256=config_sha256, force=force)
    names = ", ".join(f"/{g.name}" for g in groups)
    try:
        _write_root(f, config_toml=config_toml, config_sha256=config_sha256, fresh=fresh)
        if base_config_sha256 is not None:
            f.attrs["base_config_sha256"] = base_config_sha256
        for group, prepared, attrs in ready:
            if group.name in f:
                del f[group.name]
            g = f.create_group(group.name)
            for key, value in attrs.items():
                g.attrs[key] = value
            _write_prepared(g, prepared)
            _set_status(g, group.status, group.error)
        _commit(f, tmp, path)
    except BaseException as exc:
        _discard(f, tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"{path}: cannot write {names}: {exc}") from exc
        raise


def read_group(path: Path, name: str) -> dict:
    """Read a group (`name` may be nested, e.g. "transient/spectrum").

    Returns {"attrs": {...}, "coords": {dim: array}, "variables": {name: array},
    "dims": {dataset: (dim, ...)}, "units": {dataset: units}}; strings are decoded to `str`
    (string arrays have a numpy unicode dtype). Subgroups are not included: read them by name.
    """
    h5py = _h5py()
    path = Path(path)
    key = str(name).strip("/")
    with _open_read(path) as f:
        obj = f.get(key) if key else None
        if not isinstance(obj, h5py.Group):
            raise OutputError(f"{path}: no group /{name.strip('/')} in this results file")
        out: dict[str, Any] = {
            "attrs": {k: _decode_attr(v) for k, v in obj.attrs.items()},
            "coords": {},
            "variables": {},
            "dims": {},
            "units": {},
        }
        for key, ds in obj.items():
            if not isinstance(ds, h5py.Dataset):
                continue
            kind = "coords" if h5py.h5ds.is_scale(ds.id) else "variables"
            out[kind][key] = _read_dataset(ds)
            out["dims"][key] = (key,) if kind == "coords" else _dataset_dims(ds)
            out["units"][key] = _decode_attr(ds.attrs.get("units", ""))
        return out


def group_names(path: Path) -> list[str]:
    """The analysis groups of a results file (top level, /provenance left out); `OutputError` if unreadable."""
    with _open_read(Path(path)) as f:
        return [k for k in f.keys() if k != _PROVENANCE]


def read_root_attrs(path: Path) -> dict:
    """The root attributes of a results file (strings decoded); `OutputError` if unreadable."""
    path = Path(path)
    with _open_read(path) as f:
        return {k: _decode_attr(v) for k, v in f.attrs.items()}


# --------------------------------------------------------------------------------------------
# Streaming writer for long transient runs
# --------------------------------------------------------------------------------------------


class StreamWriter:
    """Write a group whose time series grow along a first, unlimited, chunked `time` axis.

    Works on a temporary copy of the target (same rules as `write_group`). At open the group is
    created with status "running", the fixed coordinates and variables, an empty `time`
    coordinate (the dimension scale of axis 0 of every series) and one growable float64 dataset
    per series. `append` buffers rows in memory (bounded: at most 256 rows and about 4 MiB) and
    writes them in whole chunks; every `flush_every` appends the buffer is written and the file flushed.
    `close(status)` sets the status and renames the temporary file over the target. If the process
    dies without `close`, the target is untouched and only the temporary file remains.

    As a context manager, leaving the block normally closes with "complete"; an exception closes
    with "failed" (and `error` = str(exc)); KeyboardInterrupt (or another non-`Exception`, e.g.
    SystemExit) closes with "interrupted". In both cases every row appended so far is kept and
    the exception propagates.
    """

    def __init__(
        self,
        path: Path,
        name: str,
        *,
        series: dict[str, tuple[tuple[int, ...], str, tuple[str, ...]]],
        coords: dict[str, np.ndarray | list[str]],
        time_units: str = "s",
        variables: tuple[Variable, ...] = (),
        attrs: dict | None = None,
        coord_units: dict[str, str] | None = None,
        config_toml: str,
        config_sha256: str,
        force: bool = False,
        flush_every: int = 50,
    ) -> None:
        self._path = _resolve_target(path)
        self._name = _check_name(name, "group name")
        self._closed = True  # until the file is open
        if name == _PROVENANCE:
            raise ValueError(f"group name {_PROVENANCE!r} is reserved")
        _check_provenance_args(config_toml, config_sha256)
        _check_units(time_units, "time coordinate")
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 1:
            raise ValueError("flush_every must be a positive int")
        where = f"group {name!r}"
        if _TIME_DIM in coords:
            raise ValueError(f"{where}: {_TIME_DIM!r} is the growable axis; do not pass it in coords")
        self._series = _check_series(series, where)
        if not self._series:
            raise ValueError(f"{where}: StreamWriter needs at least one series")
        trailing_sizes: dict[str, int] = {}
        for sname, (shape, _units, sdims) in self._series.items():
            for dim, n in zip(sdims, shape):
                if trailing_sizes.setdefault(dim, n) != n:
                    raise ValueError(f"{where}: dimension {dim!r} has sizes {trailing_sizes[dim]} and {n} "
                                     f"(series {sname!r})")
        variables = tuple(variables)
        for var in variables:
            if _TIME_DIM in var.dims:
                raise ValueError(f"{where}: fixed variable {var.name!r} may not use the {_TIME_DIM!r} "
                                 "dimension; append it as a series")
        prepared = _prepare(coords, coord_units or {}, variables, where=where, extra_sizes=trailing_sizes,
                            taken=set(self._series) | {_TIME_DIM})
        user_attrs = _prepare_attrs(attrs or {}, where=where)
        self._flush_every = flush_every
        self._appends = 0
        self._rows = 0  # rows written to the file
        self._fill = 0  # rows waiting in the buffer

        row_bytes = {s: 8 * int(np.prod(shape, dtype=np.int64)) for s, (shape, _, _) in self._series.items()}
        total = 8 + sum(row_bytes.values())
        self._capacity = max(1, min(_CHUNK_ROWS, _BUFFER_BYTES // total))
        self._tbuf = np.empty(self._capacity, dtype=np.float64)
        self._bufs = {s: np.empty((self._capacity, *shape), dtype=np.float64)
                      for s, (shape, _, _) in self._series.items()}

        self._tmp, self._f, fresh = _open_temp(self._path, config_sha256=config_sha256, force=force)
        try:
            f = self._f
            _write_root(f, config_toml=config_toml, config_sha256=config_sha256, fresh=fresh)
            if name in f:
                del f[name]
            g = self._g = f.create_group(name)
            g.attrs["status"] = "running"
            for key, value in user_attrs.items():
                g.attrs[key] = value
            self._scales = _write_prepared(g, prepared)
            self._coord_values = {dim: c[0] for dim, c in prepared.coords.items()}
            self._coord_units = {dim: c[2] for dim, c in prepared.coords.items()}
            tds = g.create_dataset(_TIME_DIM, shape=(0,), maxshape=(None,), dtype=np.float64,
                                   chunks=(max(_CHUNK_ROWS, 1024),))
            tds.attrs["units"] = time_units
            tds.attrs["description"] = "time"
            tds.make_scale(_TIME_DIM)
            self._tds = tds
            self._sds = {}
            for sname, (shape, units, sdims) in self._series.items():
                rows = max(1, min(_CHUNK_ROWS, _CHUNK_BYTES // max(1, row_bytes[sname])))
                ds = g.create_dataset(sname, shape=(0, *shape), maxshape=(None, *shape), dtype=np.float64,
                                      chunks=(rows, *shape))
                ds.attrs["units"] = units
                ds.dims[0].attach_scale(tds)
                for axis, dim in enumerate(sdims, start=1):
                    ds.dims[axis].attach_scale(self._scales[dim])
                self._sds[sname] = ds
            f.flush()
        except BaseException as exc:
            _discard(self._f, self._tmp)
            if isinstance(exc, OSError):
                raise OutputError(f"{self._path}: cannot start group /{name}: {exc}") from exc
            raise
        self._closed = False

    # -- context manager ----------------------------------------------------------------------

    def __enter__(self) -> StreamWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self._closed:
            return False
        if exc is None:
            self.close("complete")
            return False
        if isinstance(exc, Exception):
            status, message = "failed", str(exc) or type(exc).__name__
        else:
            status, message = "interrupted", f"interrupted ({type(exc).__name__})"
        try:
            self.close(status, message)
        except BaseException as close_exc:  # keep the original exception; say what was lost
            exc.add_note(f"partial results could not be saved to {self._path}: {close_exc}")
        return False

    # -- public methods -----------------------------------------------------------------------

    @property
    def rows(self) -> int:
        """Number of time steps appended so far."""
        return self._rows + self._fill

    def append(self, time: np.ndarray, values: dict[str, np.ndarray]) -> None:
        """Append rows: `time` of shape (n,) (or a scalar for one row) and, for every series,
        an array of shape (n, *trailing) (or (*trailing) with a scalar time)."""
        self._check_open()
        t = np.asarray(time)
        if np.iscomplexobj(t) or t.dtype.kind not in "iuf":
            raise ValueError("append: time must be real numbers")
        single = t.ndim == 0
        t = t.astype(np.float64, copy=False).reshape(-1) if single else t.astype(np.float64, copy=False)
        if t.ndim != 1:
            raise ValueError(f"append: time must have shape (n,), got {t.shape}")
        n = t.shape[0]
        if set(values) != set(self._series):
            missing = sorted(set(self._series) - set(values))
            unknown = sorted(set(values) - set(self._series))
            raise ValueError(f"append: every series must be given once (missing {missing}, unknown {unknown})")
        rows: dict[str, np.ndarray] = {}
        for sname, (shape, _, _) in self._series.items():
            a = np.asarray(values[sname])
            if np.iscomplexobj(a) or a.dtype.kind not in "biuf":
                raise ValueError(f"append: series {sname!r} must be real numbers (got dtype {a.dtype})")
            if single and a.shape == shape:
                a = a.reshape((1, *shape))
            if a.shape != (n, *shape):
                raise ValueError(f"append: series {sname!r} has shape {a.shape}, expected {(n, *shape)}")
            rows[sname] = a
        if n == 0:
            return
        try:
            if self._fill + n <= self._capacity:
                self._to_buffer(t, rows)
                if self._fill == self._capacity:
                    self._drain()
            else:
                self._drain()
                if n >= self._capacity:
                    self._write_rows(t, rows)
                else:
                    self._to_buffer(t, rows)
            self._appends += 1
            if self._appends % self._flush_every == 0:
                self._drain()
                self._f.flush()
        except OSError as exc:
            raise OutputError(f"{self._path}: cannot append to /{self._name}: {exc}") from exc

    def read(self, name: str, start_row: int = 0) -> np.ndarray:
        """The rows of series `name` (or "time") appended so far, from `start_row` (reads the file,
        so a caller need not keep its own copy while streaming)."""
        self._check_open()
        self._drain()
        ds = self._tds if name == _TIME_DIM else self._sds[name]
        return ds[start_row:]

    def set_attrs(self, **attrs) -> None:
        """Set group attributes (str, int, float; bool is stored as int8). `status`/`error` are
        reserved: use `close`."""
        self._check_open()
        for key, value in _prepare_attrs(attrs, where=f"group {self._name!r}").items():
            self._g.attrs[key] = value

    def add_variables(
        self, variables: tuple[Variable, ...], coords: dict | None = None, coord_units: dict | None = None
    ) -> None:
        """Add fixed (non-time) variables to the group, e.g. summaries at the end of the run.

        New dimensions get their values from `coords` (or an integer index); a dimension that
        already exists must keep its size (and values, if given again). `coord_units` as in
        `GroupData` (default "1")."""
        self._check_open()
        where = f"group {self._name!r}"
        variables = tuple(variables)
        coords = dict(coords or {})
        for var in variables:
            if not isinstance(var, Variable):
                raise TypeError(f"{where}: variables must be Variable instances")
            if _TIME_DIM in var.dims:
                raise ValueError(f"{where}: fixed variable {var.name!r} may not use the {_TIME_DIM!r} "
                                 "dimension; append it as a series")
            if var.name in self._g:
                raise ValueError(f"{where}: {var.name!r} exists already")
        if _TIME_DIM in coords:
            raise ValueError(f"{where}: the {_TIME_DIM!r} coordinate cannot be replaced")
        existing = {dim: len(vals) for dim, vals in self._coord_values.items()}
        for dim, vals in list(coords.items()):
            if dim in self._coord_values:
                arr, _ = _to_array(vals, f"{where}: coordinate {dim!r}")
                if not _same_values(arr, self._coord_values[dim]):
                    raise ValueError(f"{where}: coordinate {dim!r} exists already with other values")
                del coords[dim]
        coord_units = {k: v for k, v in dict(coord_units or {}).items() if k not in existing}
        prepared = _prepare(coords, coord_units, variables, where=where, extra_sizes=existing,
                            existing=set(existing), taken=set(self._g.keys()))
        try:
            new_scales = _write_prepared(self._g, prepared, scales=self._scales)
            self._scales.update(new_scales)
            for dim, c in prepared.coords.items():
                self._coord_values[dim] = c[0]
                self._coord_units[dim] = c[2]
        except OSError as exc:
            raise OutputError(f"{self._path}: cannot write to /{self._name}: {exc}") from exc

    def add_subgroup(self, group: GroupData) -> None:
        """Write `group` as a subgroup, e.g. GroupData(name="spectrum", ...) -> /transient/spectrum.

        A dimension shared with the parent group must have the same coordinate values (xarray's
        DataTree requires child nodes to align with their parents); when the subgroup gives no
        values for such a dimension, the parent's coordinate is copied. The growable `time`
        dimension cannot be used in a subgroup. The subgroup has no `status` attribute (the
        parent's status applies), and a subgroup of the same name is replaced."""
        self._check_open()
        if not isinstance(group, GroupData):
            raise TypeError("add_subgroup: group must be a GroupData")
        where = f"group {self._name + '/' + group.name!r}"
        existing = self._g.get(group.name)
        h5py = _h5py()
        if existing is not None and not isinstance(existing, h5py.Group):
            raise ValueError(f"{where}: a dataset of that name exists in /{self._name}")
        used = {d for v in group.variables for d in v.dims} | set(group.coords)
        if _TIME_DIM in used:
            raise ValueError(f"{where}: the growable {_TIME_DIM!r} dimension cannot be used in a subgroup")
        coords = dict(group.coords)
        coord_units = dict(group.coord_units)
        for dim in used:
            if dim not in self._coord_values:
                continue
            if dim in coords:
                arr, _ = _to_array(coords[dim], f"{where}: coordinate {dim!r}")
                if not _same_values(arr, self._coord_values[dim]):
                    raise ValueError(f"{where}: coordinate {dim!r} differs from the parent group's; "
                                     "use another dimension name")
            else:
                coords[dim] = self._coord_values[dim]
                coord_units.setdefault(dim, self._coord_units[dim])
        prepared = _prepare(coords, coord_units, group.variables, where=where)
        attrs = _prepare_attrs(group.attrs, where=where)
        try:
            if existing is not None:
                del self._g[group.name]
            sub = self._g.create_group(group.name)
            for key, value in attrs.items():
                sub.attrs[key] = value
            _write_prepared(sub, prepared)
        except OSError as exc:
            raise OutputError(f"{self._path}: cannot write /{self._name}/{group.name}: {exc}") from exc

    def close(self, status: str = "complete", error: str = "") -> None:
        """Write buffered rows, set `status` (and `error`) and rename the temporary file over the
        target. A second call does nothing."""
        if self._closed:
            return
        if status not in _FINAL_STATUSES:
            raise ValueError(f"close: status must be one of {_FINAL_STATUSES}, not {status!r}")
        self._closed = True
        try:
            self._drain()
            _set_status(self._g, status, error)
            self._f.attrs["modified_utc"] = _now_utc()
            _commit(self._f, self._tmp, self._path)
        except BaseException as exc:
            _discard(self._f, self._tmp)
            if isinstance(exc, OSError):
                raise OutputError(f"{self._path}: cannot finish group /{self._name}: {exc}") from exc
            raise

    # -- internals ------------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"StreamWriter for {self._path} is closed")

    def _to_buffer(self, t: np.ndarray, rows: dict[str, np.ndarray]) -> None:
        i, n = self._fill, t.shape[0]
        self._tbuf[i:i + n] = t
        for sname, a in rows.items():
            self._bufs[sname][i:i + n] = a
        self._fill += n

    def _drain(self) -> None:
        if self._fill:
            k = self._fill
            self._write_rows(self._tbuf[:k], {s: b[:k] for s, b in self._bufs.items()})
            self._fill = 0

    def _write_rows(self, t: np.ndarray, rows: dict[str, np.ndarray]) -> None:
        start, stop = self._rows, self._rows + t.shape[0]
        for sname, a in rows.items():
            ds = self._sds[sname]
            ds.resize(stop, axis=0)
            ds[start:stop] = a
        self._tds.resize((stop,))
        self._tds[start:stop] = t
        self._rows = stop


# --------------------------------------------------------------------------------------------
# Internals: validation
# --------------------------------------------------------------------------------------------


@dataclass
class _Prepared:
    # dim -> (values, is_str, units, description)
    coords: dict[str, tuple[np.ndarray, bool, str, str]]
    # (name, values, is_str, dims, units, description)
    variables: list[tuple[str, np.ndarray, bool, tuple[str, ...], str, str]]


def _h5py():
    import h5py  # noqa: PLC0415 - lazy on purpose (CLI start-up time)

    return h5py


def _check_name(name: Any, what: str) -> str:
    if not isinstance(name, str) or not name or "/" in name or name in (".", "..") or "\x00" in name:
        raise ValueError(f"{what} must be a non-empty str without '/', got {name!r}")
    return name


def _check_dims(dims: Any, where: str) -> tuple[str, ...]:
    if isinstance(dims, str):
        raise TypeError(f"{where}: dims must be a tuple of names, not the str {dims!r}")
    dims = tuple(dims)
    for dim in dims:
        _check_name(dim, f"{where}: dimension name")
    if len(set(dims)) != len(dims):
        raise ValueError(f"{where}: repeated dimension in {dims} (xarray/netCDF need distinct names, "
                         "e.g. 'dof_i', 'dof_j')")
    return dims


def _check_units(units: Any, where: str) -> str:
    if not isinstance(units, str) or not units:
        raise ValueError(f"{where}: units must be a non-empty str (\"1\" for dimensionless)")
    return units


def _check_provenance_args(config_toml: Any, config_sha256: Any) -> None:
    if not isinstance(config_toml, str):
        raise TypeError("config_toml must be a str")
    if not isinstance(config_sha256, str) or not config_sha256:
        raise ValueError("config_sha256 must be a non-empty str")


def _check_series(series: Any, where: str) -> dict[str, tuple[tuple[int, ...], str, tuple[str, ...]]]:
    out = {}
    for sname, spec in dict(series).items():
        _check_name(sname, f"{where}: series name")
        if sname == _TIME_DIM:
            raise ValueError(f"{where}: series may not be called {_TIME_DIM!r}")
        try:
            shape, units, sdims = spec
        except (TypeError, ValueError):
            raise ValueError(f"{where}: series {sname!r} must be (trailing shape, units, trailing dims)") from None
        shape = tuple(int(n) for n in shape)
        if any(n < 1 for n in shape):
            raise ValueError(f"{where}: series {sname!r} has a trailing shape {shape} with an empty axis")
        sdims = _check_dims(sdims, f"{where}: series {sname!r}")
        if len(sdims) != len(shape):
            raise ValueError(f"{where}: series {sname!r} has {len(shape)} trailing axes but dims {sdims}")
        if _TIME_DIM in sdims:
            raise ValueError(f"{where}: series {sname!r} uses {_TIME_DIM!r} as a trailing dimension")
        out[sname] = (shape, _check_units(units, f"{where}: series {sname!r}"), sdims)
    return out


def _to_array(data: Any, where: str) -> tuple[np.ndarray, bool]:
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


def _same_values(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape:
        return False
    if (a.dtype.kind == "O") != (b.dtype.kind == "O"):
        return False
    if a.dtype.kind == "O":
        return bool(np.all(a == b))
    return bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f" or b.dtype.kind == "f"))


def _prepare(
    coords: dict,
    coord_units: dict,
    variables: tuple[Variable, ...],
    *,
    where: str,
    extra_sizes: dict[str, int] | None = None,
    existing: set[str] | None = None,
    taken: set[str] | None = None,
) -> _Prepared:
    """Validate coordinates and variables of one group; add integer index coordinates.

    `extra_sizes`: sizes of further dimensions (e.g. series' trailing axes) that need coordinates;
    `existing`: dimensions whose coordinates are in the file already; `taken`: names in use."""
    taken = set(taken or ())
    sizes: dict[str, int] = dict(extra_sizes or {})
    known = set(existing or ())
    pcoords: dict[str, tuple[np.ndarray, bool, str, str]] = {}
    for dim, values in dict(coords).items():
        _check_name(dim, f"{where}: coordinate name")
        if dim in taken:
            raise ValueError(f"{where}: coordinate {dim!r} clashes with an existing name")
        arr, is_str = _to_array(values, f"{where}: coordinate {dim!r}")
        if arr.ndim != 1:
            raise ValueError(f"{where}: coordinate {dim!r} must be 1-D, got shape {arr.shape}")
        if sizes.setdefault(dim, arr.shape[0]) != arr.shape[0]:
            raise ValueError(f"{where}: coordinate {dim!r} has {arr.shape[0]} values, dimension size is {sizes[dim]}")
        units = _check_units(dict(coord_units).get(dim, "1"), f"{where}: coordinate {dim!r}")
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
        arr, is_str = _to_array(var.data, vwhere)
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
        units = _check_units(dict(coord_units).get(dim, "1"), f"{where}: coordinate {dim!r}")
        pcoords[dim] = (np.arange(n, dtype=np.int64), False, units, "integer index")
    return _Prepared(coords=pcoords, variables=pvars)


def _prepare_attrs(attrs: dict, *, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in dict(attrs).items():
        if not isinstance(key, str) or not key or "\x00" in key:
            raise ValueError(f"{where}: attribute names must be non-empty str, got {key!r}")
        if key in _RESERVED_GROUP_ATTRS or key in _RESERVED_ATTRS:
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
            out[key] = np.array([], dtype=_h5py().string_dtype())
        elif isinstance(value, (list, tuple, np.ndarray)):
            arr, is_str = _to_array(value, f"{where}: attribute {key!r}")
            if arr.ndim != 1:
                raise ValueError(f"{where}: attribute {key!r} must be a scalar or 1-D")
            if is_str:
                out[key] = [str(x) for x in arr]
            else:
                out[key] = arr
        else:
            raise ValueError(f"{where}: attribute {key!r} has unsupported type {type(value).__name__}")
    return out


# --------------------------------------------------------------------------------------------
# Internals: writing
# --------------------------------------------------------------------------------------------


def _now_utc() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _write_dataset(g, name: str, arr: np.ndarray, is_str: bool, units: str, description: str):
    h5py = _h5py()
    if is_str:
        ds = g.create_dataset(name, shape=arr.shape, dtype=h5py.string_dtype())
        if arr.size:
            ds[()] = arr
    else:
        ds = g.create_dataset(name, data=arr)
    ds.attrs["units"] = units
    if description:
        ds.attrs["description"] = description
    return ds


def _write_prepared(g, prepared: _Prepared, *, scales: dict | None = None) -> dict:
    """Coordinates first (made dimension scales), then variables attached to them."""
    scales = dict(scales or {})
    new = {}
    for dim, (arr, is_str, units, description) in prepared.coords.items():
        ds = _write_dataset(g, dim, arr, is_str, units, description)
        ds.make_scale(dim)
        scales[dim] = new[dim] = ds
    for name, arr, is_str, dims, units, description in prepared.variables:
        ds = _write_dataset(g, name, arr, is_str, units, description)
        for axis, dim in enumerate(dims):
            ds.dims[axis].attach_scale(scales[dim])
    return new


def _set_status(g, status: str, error: str) -> None:
    if status not in _STATUSES:
        raise ValueError(f"status must be one of {_STATUSES}, not {status!r}")
    g.attrs["status"] = status
    if status in ("failed", "interrupted") or error:
        message = str(error) or ("unknown error" if status == "failed" else status)
        if len(message) > _MAX_ERROR_CHARS:
            message = message[: _MAX_ERROR_CHARS - 15] + " ... (truncated)"
        g.attrs["error"] = message
    elif "error" in g.attrs:
        del g.attrs["error"]


def _write_root(f, *, config_toml: str, config_sha256: str, fresh: bool) -> None:
    h5py = _h5py()
    now = _now_utc()
    if fresh or "created_utc" not in f.attrs:
        f.attrs["created_utc"] = now
    f.attrs["modified_utc"] = now
    f.attrs["beltdyn_version"] = __version__
    f.attrs["schema_version"] = SCHEMA_VERSION
    f.attrs["config_sha256"] = config_sha256
    prov = f.require_group(_PROVENANCE)
    if "config_toml" in prov:
        del prov["config_toml"]
    ds = prov.create_dataset("config_toml", data=config_toml, dtype=h5py.string_dtype())
    ds.attrs["units"] = "1"
    ds.attrs["description"] = "resolved configuration (TOML)"


# --------------------------------------------------------------------------------------------
# Internals: files
# --------------------------------------------------------------------------------------------


def _resolve_target(path: Path) -> Path:
    path = Path(path)
    if path.is_symlink():  # replace the file the link points to, not the link
        path = Path(os.path.realpath(path))
    return path


def _open_read(path: Path):
    h5py = _h5py()
    if not path.is_file():
        raise OutputError(f"{path}: no such results file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise OutputError(f"{path}: cannot be read as an HDF5 file ({exc})") from exc


def _read_only(path: Path) -> bool:
    """No write permission for this user; for root (who may write anyway) no write bit at all: a
    read-only results file is the user's protection and is not replaced."""
    if not os.access(path, os.W_OK):
        return True
    return hasattr(os, "geteuid") and os.geteuid() == 0 and not path.stat().st_mode & 0o222


def _inspect_target(path: Path, *, config_sha256: str, force: bool, base_config_sha256: str | None = None) -> bool:
    """True if `path` is a beltdyn file to be updated (copied), False if a fresh file is to be
    started (none there, or `force` replaces it); OutputError if the file must not be touched.

    The file is accepted when its `config_sha256` is `config_sha256`, or when `base_config_sha256`
    is given and equals the file's `base_config_sha256` (the configuration as given, before
    `modal --rtol` chose the mesh)."""
    h5py = _h5py()
    if not path.exists():
        return False
    if not path.is_file():
        raise OutputError(f"{path}: exists and is not a regular file; choose another output path")
    if _read_only(path):
        raise OutputError(f"cannot write results to {path}: permission denied (the file is read-only; make it "
                          "writable or choose another output path)")
    try:
        ok = h5py.is_hdf5(path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot be read ({exc})") from exc
    if not ok:
        if force:
            return False
        raise OutputError(f"{path}: exists and is not an HDF5 file; it is not overwritten: --force replaces it "
                          "(or choose another output path)")
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: _decode_attr(v) for k, v in f.attrs.items()}
    except OSError as exc:
        if force:
            return False
        raise OutputError(f"{path}: cannot be read as an HDF5 file ({exc}); it is not overwritten: --force "
                          "replaces it (or choose another output path)") from exc
    if "config_sha256" not in attrs or "beltdyn_version" not in attrs:
        if force:
            return False
        raise OutputError(f"{path}: exists and is not a beltdyn results file; it is not overwritten: --force "
                          "replaces it (or choose another output path)")
    if str(attrs.get("schema_version")) != SCHEMA_VERSION:
        if force:
            return False
        raise OutputError(f"{path}: was written with results schema {attrs.get('schema_version')!r}, this "
                          f"beltdyn writes schema {SCHEMA_VERSION!r}; use --force to start the file afresh "
                          "or choose another output path")
    same_base = base_config_sha256 is not None and attrs.get("base_config_sha256") == base_config_sha256
    if attrs["config_sha256"] != config_sha256 and not same_base:
        if force:
            return False
        raise OutputError(f"{path}: holds results of a different configuration (config_sha256 "
                          f"{str(attrs['config_sha256'])[:12]}..., now {config_sha256[:12]}...); use --force "
                          "to start the file afresh or choose another output path")
    return True


def _open_temp(path: Path, *, config_sha256: str, force: bool):
    """Check the target, create the temporary file (copy or fresh) and open it: (tmp, file, fresh)."""
    h5py = _h5py()
    copy_existing = _inspect_target(path, config_sha256=config_sha256, force=force)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create the output directory: {exc}") from exc
    tmp = None
    try:
        for _ in range(100):
            tmp = path.with_name(f"{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                break
            except FileExistsError:
                tmp = None
        if tmp is None:
            raise OutputError(f"{path}: cannot create a temporary file next to it")
        if copy_existing:
            shutil.copyfile(path, tmp)
            try:
                shutil.copymode(path, tmp)
            except OSError:
                pass
            f = h5py.File(tmp, "r+")
        else:
            # Default (earliest) file format for the widest reader compatibility. The space of a
            # replaced group is freed and reused within the same session, so files do not grow.
            f = h5py.File(tmp, "w")
    except BaseException as exc:
        if tmp is not None:
            _unlink_quietly(tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"{path}: cannot create a temporary file next to it: {exc}") from exc
        raise
    return tmp, f, not copy_existing


def _commit(f, tmp: Path, path: Path) -> None:
    f.flush()
    f.close()
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    fsync_dir(path.parent)


def fsync_dir(directory: Path) -> None:
    """fsync a folder (its entries: a rename into it is durable); best effort."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _discard(f, tmp: Path) -> None:
    try:
        f.close()
    except Exception:  # noqa: BLE001 - best effort while another error propagates
        pass
    _unlink_quietly(tmp)


def _unlink_quietly(p: Path) -> None:
    try:
        Path(p).unlink(missing_ok=True)
    except OSError:
        pass


# --------------------------------------------------------------------------------------------
# Internals: reading
# --------------------------------------------------------------------------------------------


def _decode_attr(value: Any) -> Any:
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


def _read_dataset(ds) -> Any:
    h5py = _h5py()
    if h5py.check_string_dtype(ds.dtype) is not None:
        value = ds.asstr()[()]
        if isinstance(value, np.ndarray):
            return np.array(value.tolist(), dtype=str).reshape(value.shape)
        return str(value)
    return ds[()]


def _dataset_dims(ds) -> tuple[str, ...]:
    dims = []
    for axis in range(ds.ndim):
        names = list(ds.dims[axis].keys())
        dims.append(names[0] if names else "")
    return tuple(dims)
