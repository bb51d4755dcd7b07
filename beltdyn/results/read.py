"""Reading results files. Readers take no lock and are never blocked: writers never modify a file a
reader may have open (the root is replaced by a rename, parts are never rewritten). A reader that
finds a part or journal gone (a writer replaced the root meanwhile) reads the new root again, at once
and then after pauses that grow (`_retry`): a writer that replaces the file faster than it is read (a
loop of commits on a busy machine) is given time to finish, within `PATIENCE` seconds.
"""

from __future__ import annotations

import os
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from beltdyn.errors import OutputError
from beltdyn.results.files import open_read, same_boot, writer_alive
from beltdyn.results.journal import read_journal
from beltdyn.results.schema import TIME_DIM, decode_attr, h5py_module
from beltdyn.results.write import source_file

PATIENCE = 10.0  # s: how long a reader keeps reading a file that keeps being replaced (`_retry`)
_PAUSE = (0.0, 0.001, 0.004, 0.016, 0.064, 0.25)  # s, before the attempts; then _PAUSE[-1] until PATIENCE


class _Replaced(Exception):
    """The root was replaced while being read (what it named is gone): read the new one."""


@dataclass(frozen=True, kw_only=True)
class GroupState:
    """The status of one analysis group and, while it is `running`, its writer."""

    name: str
    status: str
    error: str = ""
    writer_pid: int | None = None
    writer_host: str = ""
    writer_alive: bool | None = None  # None: not running, or the writer is on another host
    samples: int = 0  # rows of its `time` axis (of the stream journal while it is running); 0 without one
    warnings: tuple[str, ...] = ()  # its `warnings` attribute

    @property
    def orphaned(self) -> bool:
        """Marked running, but its writer is gone (killed, crashed, power lost): the next beltdyn command
        writing this file recovers it (status interrupted, the journal's samples kept)."""
        return self.status == "running" and self.writer_alive is False


def _read_dataset(ds) -> Any:
    h5py = h5py_module()
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


def _check_sources(path: Path, ds, replaced) -> None:
    """After reading a virtual dataset: its part file existed (else the reader saw fill values)."""
    for src in ds.virtual_sources():
        name = source_file(src)
        if not (path.parent / name).is_file():
            if replaced():
                raise _Replaced
            raise OutputError(f"{path}: {ds.name} is stored in the part file {path.parent / name}, which is "
                              f"missing: keep the folder {Path(name).parent} beside the results file "
                              "(copy or move both)")


def _writer(attrs: dict) -> tuple[bool | None, bool]:
    """(writer alive?, trust the rows written and not only those synced?) of a running group."""
    start = str(attrs.get("writer_start", ""))
    alive = writer_alive(str(attrs.get("writer_host", "")), int(attrs.get("writer_pid", 0) or 0), start)
    return alive, alive is not False or same_boot(start)


def _journal_of(path: Path, attrs: dict, replaced):
    """The stream journal of a running group (None if it has none yet)."""
    rel = attrs.get("stream_journal")
    if not rel:
        return None
    journal = path.parent / str(rel)
    if not journal.is_file():
        if replaced():
            raise _Replaced
        return None
    return read_journal(journal, trust_written=_writer(attrs)[1])


def _retry(read, path: Path):
    """read(), again while it finds the root replaced (`_Replaced`): at once, then after the pauses of `_PAUSE`,
    for up to PATIENCE seconds (a pause moves the next attempt off the writer's rhythm)."""
    deadline = time.monotonic() + PATIENCE
    attempt = 0
    while True:
        try:
            return read()
        except _Replaced:
            pass
        if time.monotonic() >= deadline:
            break
        time.sleep(_PAUSE[min(attempt, len(_PAUSE) - 1)])
        attempt += 1
    raise OutputError(f"{path}: the file kept being replaced while it was read (another command writes it); "
                      "read it again when that command has finished")


def _replaced_since(path: Path):
    try:
        ino = os.stat(path).st_ino
    except OSError:
        ino = None

    def replaced() -> bool:
        try:
            return os.stat(path).st_ino != ino
        except OSError:
            return True

    return replaced


def read_group(path: Path, name: str) -> dict:
    """Read a group (`name` may be nested, e.g. "transient/spectrum").

    Returns {"attrs": {...}, "coords": {dim: array}, "variables": {name: array},
    "dims": {dataset: (dim, ...)}, "units": {dataset: units}}; strings are decoded to `str`
    (string arrays have a numpy unicode dtype). Subgroups are not included: read them by name.
    A group that is still `running` has, in addition, "writer": {"pid", "host", "alive" (True,
    False: it died and left the group so, None: another host), "journal"}, and its samples so far
    (time and series) read from its stream journal. OutputError if a part file of the group is
    missing (the results file was copied without its `.parts` folder).
    """
    path = Path(path)
    return _retry(lambda: _read_group(path, str(name)), path)


def _read_group(path: Path, name: str) -> dict:
    h5py = h5py_module()
    replaced = _replaced_since(path)
    key = name.strip("/")
    with open_read(path) as f:
        obj = f.get(key) if key else None
        if not isinstance(obj, h5py.Group):
            raise OutputError(f"{path}: no group /{key} in this results file")
        out: dict[str, Any] = {
            "attrs": {k: decode_attr(v) for k, v in obj.attrs.items()},
            "coords": {},
            "variables": {},
            "dims": {},
            "units": {},
        }
        for dname, ds in obj.items():
            if not isinstance(ds, h5py.Dataset):
                continue
            kind = "coords" if h5py.h5ds.is_scale(ds.id) else "variables"
            try:
                out[kind][dname] = _read_dataset(ds)
            except OSError as exc:  # a virtual dataset's part removed while HDF5 opened it
                if replaced():
                    raise _Replaced from None
                raise OutputError(f"{path}: cannot read {ds.name} ({exc})") from exc
            if ds.is_virtual:
                _check_sources(path, ds, replaced)
            out["dims"][dname] = (dname,) if kind == "coords" else _dataset_dims(ds)
            out["units"][dname] = decode_attr(ds.attrs.get("units", ""))
        attrs = out["attrs"]
        if attrs.get("status") == "running" and "writer_pid" in attrs:
            alive, _ = _writer(attrs)
            out["writer"] = {"pid": int(attrs["writer_pid"]), "host": str(attrs.get("writer_host", "")),
                             "alive": alive, "journal": str(attrs.get("stream_journal", ""))}
            view = _journal_of(path, attrs, replaced)
            if view is not None:
                out["coords"][TIME_DIM] = view.time()
                out["dims"][TIME_DIM] = (TIME_DIM,)
                out["units"][TIME_DIM] = view.layout.time_units
                for sname, _shape, units, dims in view.layout.series:
                    out["variables"][sname] = view.series(sname)
                    out["dims"][sname] = (TIME_DIM, *dims)
                    out["units"][sname] = units
        return out


def read_root_attrs(path: Path) -> dict:
    """The root attributes of a results file (strings decoded); `OutputError` if unreadable."""
    path = Path(path)
    with open_read(path) as f:
        return {k: decode_attr(v) for k, v in f.attrs.items()}


def group_names(path: Path) -> list[str]:
    """The analysis groups of a results file (top level, /provenance left out); `OutputError` if unreadable."""
    with open_read(Path(path)) as f:
        return [k for k in f.keys() if k != "provenance"]


def _strings(value: Any) -> tuple[str, ...]:
    """A string or string-array attribute as a tuple of str."""
    if isinstance(value, str):
        return (value,) if value else ()
    return tuple(str(v) for v in np.asarray(value).reshape(-1))


@dataclass(frozen=True, kw_only=True)
class FileSummary:
    """What a results file holds, at a glance (`beltdyn info`): its root attributes, the title of the
    configuration it records, and the state of each analysis group (`group_states`)."""

    path: Path
    title: str
    config_sha256: str
    beltdyn_version: str
    schema_version: str
    created_utc: str
    modified_utc: str
    groups: tuple[GroupState, ...]


def file_summary(path: Path) -> FileSummary:
    """The `FileSummary` of the results file at `path` (read only: a group left running by a dead writer
    is reported so; `stream.recover` puts it right). OutputError if the file is missing or unreadable."""
    path = Path(path)
    attrs = read_root_attrs(path)
    if "config_sha256" not in attrs:
        raise OutputError(f"{path}: is not a beltdyn results file (no config_sha256 attribute)")
    states = group_states(path)
    with open_read(path) as f:
        text = f["provenance/config_toml"].asstr()[()] if "provenance/config_toml" in f else ""
    try:
        title = str(tomllib.loads(text).get("title", ""))
    except tomllib.TOMLDecodeError:
        title = ""
    return FileSummary(path=path, title=title, config_sha256=str(attrs["config_sha256"]),
                       beltdyn_version=str(attrs.get("beltdyn_version", "")),
                       schema_version=str(attrs.get("schema_version", "")),
                       created_utc=str(attrs.get("created_utc", "")), modified_utc=str(attrs.get("modified_utc", "")),
                       groups=tuple(states.values()))


def group_states(path: Path) -> dict[str, GroupState]:
    """The analysis groups of a results file and their status; for a `running` group whether its
    writer still runs (`GroupState.orphaned`: it does not) and how many samples its journal holds."""
    path = Path(path)
    return _retry(lambda: _group_states(path), path)


def _group_states(path: Path) -> dict[str, GroupState]:
    h5py = h5py_module()
    replaced = _replaced_since(path)
    out = {}
    with open_read(path) as f:
        for name, obj in f.items():
            if not isinstance(obj, h5py.Group) or "status" not in obj.attrs:
                continue
            attrs = {k: decode_attr(v) for k, v in obj.attrs.items()}
            time = obj.get(TIME_DIM)
            state = dict(name=name, status=str(attrs["status"]), error=str(attrs.get("error", "")),
                         samples=int(time.shape[0]) if isinstance(time, h5py.Dataset) and time.ndim == 1 else 0,
                         warnings=_strings(attrs.get("warnings", ())))
            if attrs["status"] == "running" and "writer_pid" in attrs:
                view = _journal_of(path, attrs, replaced)
                state.update(writer_pid=int(attrs["writer_pid"]), writer_host=str(attrs.get("writer_host", "")),
                             writer_alive=_writer(attrs)[0], samples=view.rows if view is not None else 0)
            out[name] = GroupState(**state)
    return out
