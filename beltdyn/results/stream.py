"""Streaming a group whose time series grow (the transient), and recovering one whose writer died.

`StreamWriter` commits the group with status `running` at once (coordinates, fixed variables,
attributes, the writer's identity and the name of its stream journal), appends the samples to the
journal (`results_journal`: written to the OS at the first append `WRITE_SECONDS` after the last
write, synced to the disk at the first append `SYNC_SECONDS` after the last sync) and, at `close`,
copies them into the file as growable chunked datasets in one more commit. `recover` does that same
copy for a group whose writer died, marking it `interrupted`.
"""

from __future__ import annotations

import os
import time as _time
from pathlib import Path

import numpy as np

from beltdyn import SCHEMA_VERSION
from beltdyn.errors import OutputError
from beltdyn.results.files import (
    WriteFailure,
    parts_folder,
    read_only,
    remove_leftovers,
    resolve_target,
    same_boot,
    unlink_quietly,
    writer_alive,
    writer_identity,
    writing,
)
from beltdyn.results.journal import JournalLayout, JournalView, JournalWriter, read_journal
from beltdyn.results.schema import (
    CHUNK_ROWS,
    FINAL_STATUSES,
    PROVENANCE,
    TIME_DIM,
    GroupData,
    Variable,
    check_name,
    check_provenance_args,
    check_series,
    check_units,
    decode_attr,
    h5py_module,
    prepare,
    prepare_attrs,
    same_values,
    to_array,
)
from beltdyn.results.write import (
    Transaction,
    new_group,
    now_utc,
    references,
    set_status,
    write_prepared,
    write_root,
    write_series,
)

WRITE_SECONDS = 0.05  # rows reach the journal (the OS: safe from a kill -9) at the first append this long
# after the last write (coalescing tiny appends)
SYNC_SECONDS = 0.5  # ... and the disk (safe from a power loss) at least this often
_BUFFER_BYTES = 4 << 20  # at most ~4 MiB of rows buffered in memory between journal writes


def _journal_series(tx: Transaction, g, view: JournalView) -> None:
    """The journal's rows as the group's `time` coordinate (a dimension scale) and growable series,
    attached to `time` and to the group's coordinates of their trailing dims."""
    data = view.data
    tds = write_series(tx, g, TIME_DIM, rows=view.rows, shape=(), units=view.layout.time_units, description="time",
                       rows_of=lambda a, b: np.ascontiguousarray(data[a:b, 0]), chunk_rows=max(CHUNK_ROWS, 1024))
    tds.make_scale(TIME_DIM)
    for name, (first, last, shape) in view.layout.spans().items():
        units, dims = next((u, d) for n, _s, u, d in view.layout.series if n == name)
        ds = write_series(tx, g, name, rows=view.rows, shape=shape, units=units,
                          rows_of=lambda a, b, i=first, j=last, s=shape: np.ascontiguousarray(data[a:b, i:j]).reshape(
                              b - a, *s))
        ds.dims[0].attach_scale(tds)
        for axis, dim in enumerate(dims, start=1):
            ds.dims[axis].attach_scale(g[dim])


class StreamWriter:
    """Write a group whose time series grow along a first, unlimited, chunked `time` axis.

    At open (same target rules as `write_group`; the results-file lock is held until `close`) the
    group is committed with status "running", its fixed coordinates and variables and attributes;
    from then on every reader of the file sees it so, with the writer's pid, host and start token and
    the name of its stream journal (`read_group` reads the samples so far from it). `append` buffers
    rows in memory (at most 256 rows and about 4 MiB, until an append `WRITE_SECONDS` after the
    last write, or `flush_every` appends) and writes them to the journal; every `SYNC_SECONDS` the journal is synced to the disk.
    `close(status)` copies the samples into the file (growable chunked datasets with `time` as the
    dimension scale of axis 0), writes the summaries added meanwhile (`set_attrs`, `add_variables`,
    `add_subgroup`) and the status in one commit, and removes the journal. If the process dies before
    `close`, the group stays "running" with its journal; the next beltdyn command on the file
    recovers it (`recover`).

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
        self._path = resolve_target(path)
        self._name = check_name(name, "group name")
        self._closed = True  # until the file is open
        if name == PROVENANCE:
            raise ValueError(f"group name {PROVENANCE!r} is reserved")
        check_provenance_args(config_toml, config_sha256)
        check_units(time_units, "time coordinate")
        if isinstance(flush_every, bool) or not isinstance(flush_every, int) or flush_every < 1:
            raise ValueError("flush_every must be a positive int")
        where = f"group {name!r}"
        if TIME_DIM in coords:
            raise ValueError(f"{where}: {TIME_DIM!r} is the growable axis; do not pass it in coords")
        self._series = check_series(series, where)
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
            if TIME_DIM in var.dims:
                raise ValueError(f"{where}: fixed variable {var.name!r} may not use the {TIME_DIM!r} "
                                 "dimension; append it as a series")
        prepared = prepare(coords, coord_units or {}, variables, where=where, extra_sizes=trailing_sizes,
                           taken=set(self._series) | {TIME_DIM})
        user_attrs = prepare_attrs(attrs or {}, where=where)
        self._flush_every = flush_every
        self._appends = 0
        self._fill = 0  # rows waiting in the buffer
        self._sha = config_sha256
        self._layout = JournalLayout(group=name, time_units=time_units,
                                     series=tuple((s, shape, u, d) for s, (shape, u, d) in self._series.items()))
        self._spans = self._layout.spans()
        columns = self._layout.columns
        self._capacity = max(1, min(CHUNK_ROWS, _BUFFER_BYTES // (8 * columns)))
        self._buf = np.empty((self._capacity, columns), dtype=np.float64)
        self._coord_values = {dim: c[0] for dim, c in prepared.coords.items()}
        self._coord_units = {dim: c[2] for dim, c in prepared.coords.items()}
        self._names = set(prepared.coords) | {v[0] for v in prepared.variables} | set(self._series) | {TIME_DIM}
        self._pending_attrs: dict = {}
        self._pending_variables: list = []
        self._pending_groups: dict = {}

        self._lock = writing(self._path)
        self._lock.__enter__()
        try:
            self.notes = self._start(prepared, user_attrs, config_toml=config_toml, force=force)
        except BaseException:
            self._lock.__exit__(None, None, None)
            raise
        self._last_write = self._last_sync = _time.monotonic()
        self._closed = False

    def _start(self, prepared, user_attrs, *, config_toml: str, force: bool) -> list[str]:
        """The journal created and the group committed with status running."""
        self._journal = None
        tx = Transaction(self._path, config_sha256=self._sha, force=force, replaces=[self._name],
                         config_toml=config_toml)
        try:
            write_root(tx.f, config_toml=config_toml, config_sha256=self._sha, fresh=tx.fresh)
            self._journal_rel, journal_path = tx.new_part_path(self._name, ".stream")
            self._journal = JournalWriter(journal_path, self._layout)
            g = new_group(tx.f, self._name, user_attrs)
            g.attrs["status"] = "running"
            for key, value in writer_identity().items():
                g.attrs[key] = value
            g.attrs["stream_journal"] = self._journal_rel
            g.attrs["started_utc"] = now_utc()
            write_prepared(tx, g, prepared)
            return tx.commit()
        except BaseException as exc:
            tx.abort()
            if self._journal is not None and not tx.committed:
                self._journal.close()
                unlink_quietly(self._journal.path)
            elif self._journal is not None:  # committed: the file names the journal; the next run recovers it
                self._journal.close()
            if isinstance(exc, OSError):
                raise WriteFailure(f"{self._path}: cannot start group /{self._name}: {exc}") from exc
            raise

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
        return self._journal.written + self._fill

    @property
    def journal_path(self) -> Path:
        """The stream journal (the samples until `close`)."""
        return self._path.parent / self._journal_rel

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
                self._to_rows(self._buf[self._fill:self._fill + n], t, rows)
                self._fill += n
                if self._fill == self._capacity:
                    self._drain()
            else:
                self._drain()
                if n >= self._capacity:
                    block = np.empty((n, self._buf.shape[1]))
                    self._to_rows(block, t, rows)
                    self._journal.write(block)
                else:
                    self._to_rows(self._buf[:n], t, rows)
                    self._fill = n
            self._appends += 1
            now = _time.monotonic()
            if self._appends % self._flush_every == 0 or now - self._last_write >= WRITE_SECONDS:
                self._drain()
            if now - self._last_sync >= SYNC_SECONDS:
                self._drain()
                self._journal.sync()
                self._last_sync = now
        except OSError as exc:
            raise WriteFailure(f"{self._path}: cannot append to /{self._name} (journal {self.journal_path}): "
                               f"{exc}") from exc

    def flush(self) -> None:
        """Write the buffered rows to the stream journal now: from here on they survive the writer's
        death (as `append`'s own writes do; a checkpoint that names them needs them there)."""
        self._check_open()
        try:
            self._drain()
        except OSError as exc:
            raise WriteFailure(f"{self._path}: cannot append to /{self._name} (journal {self.journal_path}): "
                               f"{exc}") from exc

    def read(self, name: str, start_row: int = 0) -> np.ndarray:
        """The rows of series `name` (or "time") appended so far, from `start_row` (read from the journal,
        so a caller need not keep its own copy while streaming)."""
        self._check_open()
        self._drain()
        view = read_journal(self.journal_path)
        return view.time(start_row) if name == TIME_DIM else view.series(name, start_row)

    def set_attrs(self, **attrs) -> None:
        """Set group attributes (str, int, float; bool is stored as int8), written at `close`.
        `status`/`error` are reserved: use `close`."""
        self._check_open()
        self._pending_attrs.update(prepare_attrs(attrs, where=f"group {self._name!r}"))

    def add_variables(
        self, variables: tuple[Variable, ...], coords: dict | None = None, coord_units: dict | None = None
    ) -> None:
        """Add fixed (non-time) variables to the group (written at `close`), e.g. summaries at the end.

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
            if TIME_DIM in var.dims:
                raise ValueError(f"{where}: fixed variable {var.name!r} may not use the {TIME_DIM!r} "
                                 "dimension; append it as a series")
            if var.name in self._names:
                raise ValueError(f"{where}: {var.name!r} exists already")
        if TIME_DIM in coords:
            raise ValueError(f"{where}: the {TIME_DIM!r} coordinate cannot be replaced")
        existing = {dim: len(vals) for dim, vals in self._coord_values.items()}
        for dim, vals in list(coords.items()):
            if dim in self._coord_values:
                arr, _ = to_array(vals, f"{where}: coordinate {dim!r}")
                if not same_values(arr, self._coord_values[dim]):
                    raise ValueError(f"{where}: coordinate {dim!r} exists already with other values")
                del coords[dim]
        coord_units = {k: v for k, v in dict(coord_units or {}).items() if k not in existing}
        prepared = prepare(coords, coord_units, variables, where=where, extra_sizes=existing,
                           existing=set(existing), taken=self._names)
        self._pending_variables.append(prepared)
        for dim, c in prepared.coords.items():
            self._coord_values[dim] = c[0]
            self._coord_units[dim] = c[2]
        self._names |= set(prepared.coords) | {v[0] for v in prepared.variables}

    def add_subgroup(self, group: GroupData) -> None:
        """Write `group` as a subgroup (at `close`), e.g. GroupData(name="spectrum", ...) -> /transient/spectrum.

        A dimension shared with the parent group must have the same coordinate values (xarray's
        DataTree requires child nodes to align with their parents); when the subgroup gives no
        values for such a dimension, the parent's coordinate is copied. The growable `time`
        dimension cannot be used in a subgroup. The subgroup has no `status` attribute (the
        parent's status applies), and a subgroup of the same name is replaced."""
        self._check_open()
        if not isinstance(group, GroupData):
            raise TypeError("add_subgroup: group must be a GroupData")
        where = f"group {self._name + '/' + group.name!r}"
        if group.name in self._names:
            raise ValueError(f"{where}: a dataset of that name exists in /{self._name}")
        used = {d for v in group.variables for d in v.dims} | set(group.coords)
        if TIME_DIM in used:
            raise ValueError(f"{where}: the growable {TIME_DIM!r} dimension cannot be used in a subgroup")
        coords = dict(group.coords)
        coord_units = dict(group.coord_units)
        for dim in used:
            if dim not in self._coord_values:
                continue
            if dim in coords:
                arr, _ = to_array(coords[dim], f"{where}: coordinate {dim!r}")
                if not same_values(arr, self._coord_values[dim]):
                    raise ValueError(f"{where}: coordinate {dim!r} differs from the parent group's; "
                                     "use another dimension name")
            else:
                coords[dim] = self._coord_values[dim]
                coord_units.setdefault(dim, self._coord_units[dim])
        prepared = prepare(coords, coord_units, group.variables, where=where)
        self._pending_groups[group.name] = (prepared, prepare_attrs(group.attrs, where=where))

    def close(self, status: str = "complete", error: str = "") -> None:
        """Copy the samples into the file, write the summaries and `status` (and `error`) in one commit,
        remove the journal and release the lock. A second call does nothing. If this fails (or is
        interrupted), the group stays "running" with its journal, for the next run to recover."""
        if self._closed:
            return
        if status not in FINAL_STATUSES:
            raise ValueError(f"close: status must be one of {FINAL_STATUSES}, not {status!r}")
        self._closed = True
        try:
            self._drain()  # (not synced: the commit makes the samples durable in the results file)
            self._finish(status, error)
        except OSError as exc:
            marked = self._mark(status, error, exc)
            raise WriteFailure(f"{self._path}: cannot finish group /{self._name}: {exc}; {marked}") from exc
        finally:
            self._journal.close()
            self._lock.__exit__(None, None, None)

    def _mark(self, status: str, error: str, exc: OSError) -> str:
        """After the samples could not be copied into the file (`exc`, e.g. a full disk): the group marked
        "failed" (or "interrupted") in one small commit without them, its stream journal still named by
        the group (so it is kept until the group is written anew); if even that cannot be
        written, the group stays "running" with its journal, which the next beltdyn command on the file
        recovers (status "interrupted"). Returns what was done, for the message."""
        self._journal.trim()  # the rows of a write that failed half-way: their space back
        why = f"{error + '; ' if error else ''}its samples could not be copied into the file ({exc})"
        final = "interrupted" if status == "interrupted" else "failed"
        tx = None
        try:
            tx = Transaction(self._path, config_sha256=self._sha)
            g = tx.group(self._name)
            if g is None or str(decode_attr(g.attrs.get("stream_journal", ""))) != self._journal_rel:
                tx.abort()
                return f"its samples are in {self.journal_path}"
            set_status(g, final, f"{why}; they are kept in the stream journal {self._journal_rel}")
            g.attrs["stream_journal"] = self._journal_rel  # (set_status drops it): the journal stays referenced
            tx.commit()
        except (OSError, OutputError):
            if tx is not None:
                tx.abort()
            return (f"/{self._name} stays marked 'running' with its samples in {self.journal_path}; the next beltdyn "
                    f"command on this file recovers them (marked 'interrupted')")
        return f"/{self._name} is marked '{final}', its samples kept in {self.journal_path}"

    # -- internals ------------------------------------------------------------------------------

    def _finish(self, status: str, error: str) -> None:
        tx = Transaction(self._path, config_sha256=self._sha)
        try:
            g = tx.group(self._name)
            if g is None or str(decode_attr(g.attrs.get("stream_journal", ""))) != self._journal_rel:
                raise OutputError(f"{self._path}: the file was replaced while /{self._name} was being written; its "
                                  f"samples are in {self.journal_path}")
            _journal_series(tx, g, read_journal(self.journal_path))
            scales = {dim: g[dim] for dim in g if dim in self._coord_values}
            for prepared in self._pending_variables:
                scales.update(write_prepared(tx, g, prepared, scales=scales))
            for sub_name, (prepared, attrs) in self._pending_groups.items():
                sub = new_group(g, sub_name, attrs)
                write_prepared(tx, sub, prepared)
            for key, value in self._pending_attrs.items():
                g.attrs[key] = value
            set_status(g, status, error)
            tx.commit()
        except BaseException:
            tx.abort()
            raise

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"StreamWriter for {self._path} is closed")

    def _to_rows(self, out: np.ndarray, t: np.ndarray, rows: dict[str, np.ndarray]) -> None:
        n = t.shape[0]
        out[:, 0] = t
        for sname, a in rows.items():
            first, last, _ = self._spans[sname]
            out[:, first:last] = a.reshape(n, -1)

    def _drain(self) -> None:
        if self._fill:
            self._journal.write(self._buf[:self._fill])
            self._fill = 0
        self._last_write = _time.monotonic()


# --------------------------------------------------------------------------------------------
# Recovery: the next run after a writer died
# --------------------------------------------------------------------------------------------


def _dead_groups(f) -> list[tuple[str, dict]]:
    """Top-level groups marked running whose writer is not (known to be) alive."""
    out = []
    for name, obj in f.items():
        attrs = {k: decode_attr(v) for k, v in obj.attrs.items()}
        if attrs.get("status") != "running":
            continue
        alive = writer_alive(str(attrs.get("writer_host", "")), int(attrs.get("writer_pid", 0) or 0),
                             str(attrs.get("writer_start", "")))
        if alive is not True:
            out.append((name, attrs))
    return out


def recover(path: Path, *, if_free: bool = False) -> list[str]:
    """What a killed writer left in the results file at `path`, put right (under the results-file lock):
    a group left "running" by a process that is gone gets the samples of its stream journal (those
    written before the kill, or only those synced if the machine restarted since) and is marked
    "interrupted" with an `error` saying so; temporary roots and unreferenced parts of a writer that
    died before its commit are removed. Returns one message per thing done (empty: nothing to do).

    Keyed on the file alone: whatever configuration the killed command had, and whatever the caller
    is about to do with the file (write another configuration, or only read it). A file that is
    missing, unreadable or not a beltdyn results file of this schema is left alone; a read-only one
    too (a note says so: readers still read the samples from the journal). With `if_free`, a file
    whose lock another process holds is left alone (that live writer recovered it when it started)
    instead of OutputBusy (exit 2): what a command that only reads the file calls."""
    h5py = h5py_module()
    path = resolve_target(path)
    if not path.parent.is_dir() or (path.exists() and not path.is_file()):
        return []
    with writing(path, if_free=if_free) as held:
        if not held:
            return []
        attrs: dict = {}
        dead: list = []
        refs: set[str] = set()
        if path.exists():  # else: only what a killed first write of this file may have left
            try:
                with h5py.File(path, "r") as f:
                    attrs = {k: decode_attr(v) for k, v in f.attrs.items()}
                    if "config_sha256" not in attrs or str(attrs.get("schema_version")) != SCHEMA_VERSION:
                        return []
                    dead = _dead_groups(f)
                    refs = references(f)
            except OSError:
                return []
            if dead and (read_only(path) or not os.access(path.parent, os.W_OK | os.X_OK)):
                return [f"{path}: /{name} was left 'running' by pid {gattrs.get('writer_pid', '?')}, which no longer "
                        "runs; the file (or its folder) is read-only, so it is not recovered (readers get its samples "
                        f"from the stream journal {gattrs.get('stream_journal', '') or '(none)'})"
                        for name, gattrs in dead]
        folder = str(attrs.get("parts_folder", parts_folder(path)))
        file_id = str(attrs.get("file_id", ""))
        notes = []
        if dead:
            tx = Transaction(path, config_sha256=str(attrs["config_sha256"]))
            try:
                for name, gattrs in dead:
                    notes.append(_recover_group(tx, path, name, gattrs))
                removed = tx.commit()
            except BaseException:
                tx.abort()
                raise
        else:
            removed = remove_leftovers(path, folders={folder, parts_folder(path)}, file_ids={file_id} - {""},
                                       referenced=refs)
        if removed:
            notes.append(f"{path}: removed {len(removed)} leftover file(s) of an earlier beltdyn command that was "
                         f"killed before it finished writing: {', '.join(removed)}")
        return notes


def _recover_group(tx: Transaction, path: Path, name: str, attrs: dict) -> str:
    g = tx.group(name)
    who = f"pid {attrs.get('writer_pid', '?')} on {attrs.get('writer_host', '?')}"
    journal = path.parent / str(attrs.get("stream_journal", ""))
    got = "no stream journal, so no samples"
    if attrs.get("stream_journal") and journal.is_file():
        rebooted = not same_boot(str(attrs.get("writer_start", "")))
        try:
            view = read_journal(journal, trust_written=not rebooted)
        except OutputError as exc:
            got = f"an unreadable stream journal ({exc}), so no samples"
        else:
            _journal_series(tx, g, view)
            span = f" (t = {view.data[0, 0]:.6g} to {view.data[-1, 0]:.6g} s)" if view.rows else ""
            synced = " synced to the disk before the machine restarted" if rebooted else ""
            got = f"{view.rows} samples{span}{synced} from its stream journal"
    message = (f"the writing process ({who}) ended without closing /{name} (killed, crashed or the machine lost "
               f"power); recovered {got} on {now_utc()}")
    set_status(g, "interrupted", message)
    g.attrs["recovered_utc"] = now_utc()
    return f"{path}: /{name} was left 'running' by {who}, which no longer runs: recovered {got}; /{name} is now " \
           "marked 'interrupted'"
