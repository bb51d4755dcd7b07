"""Writing results files: one atomic transaction per change, costing what the change writes.

`Transaction` writes a new root beside the root file, lets the caller write groups in it (datasets
above `INLINE_BYTES` go to a new part file of their group; the root gets a virtual dataset mapping
onto it), then makes the parts durable, renames the new root over the old one (the commit) and
removes the parts no longer referenced. See `results_io` for the layout and for what a reader sees
at every moment.

The new root holds the old root's live content and the change, never the old root's garbage: HDF5
never reclaims the space of a deleted object, so a group replaced in a byte copy of the old root
would stay in it, and every later transaction would copy it again (the root grew by the size of
/transient on every rerun of `beltdyn transient`). So a transaction that replaces groups of the old
root (the caller declares which: `replaces`) starts a fresh root and copies in the groups it does not
replace (`carry_over`; `group(name)` copies one in to be changed). One that only adds (new groups,
datasets, attributes: a stream's close, a recovery) edits a byte copy, cheaper: it deletes no group,
so what it leaves unreclaimed is only HDF5's slack of its own writes (overwritten attribute values,
grown object headers: a fraction of what it adds), and the next replacing transaction drops that.
"""

from __future__ import annotations

import os
import shutil
from datetime import datetime, timezone
from pathlib import Path
from typing import Callable, Collection

import numpy as np

from beltdyn import SCHEMA_VERSION
from beltdyn import __version__
from beltdyn.errors import OutputError
from beltdyn.results.copy import copy_attrs, copy_group
from beltdyn.results.files import (
    WriteFailure,
    fsync_dir,
    fsync_file,
    inspect_target,
    new_file_id,
    part_name,
    parts_folder,
    remove_leftovers,
    resolve_target,
    temp_name,
    unlink_quietly,
    writing,
)
from beltdyn.results.schema import (
    CHUNK_BYTES,
    CHUNK_ROWS,
    MAX_ERROR_CHARS,
    PROVENANCE,
    STATUSES,
    WRITER_ATTRS,
    GroupData,
    Prepared,
    check_provenance_args,
    decode_attr,
    h5py_module,
    prepare,
    prepare_attrs,
)

INLINE_BYTES = 1 << 20  # a numeric dataset above 1 MiB goes to its group's part file
_BLOCK_BYTES = 16 << 20  # rows copied per block from a stream journal


def now_utc() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def source_file(vds_map) -> str:
    """The part file a virtual dataset maps onto, relative to the root's folder (unescaped)."""
    return vds_map.file_name.replace("%%", "%")


def references(f) -> set[str]:
    """The files an open root names (relative to its folder): each top-level group lists its part files
    in its `parts` attribute (the sources of its virtual datasets) and, while running, its stream
    journal in `stream_journal`."""
    refs: set[str] = set()
    for obj in f.values():
        attrs = obj.attrs
        if "parts" in attrs:
            refs.update(str(p) for p in decode_attr(attrs["parts"]))
        if "stream_journal" in attrs:
            refs.add(str(decode_attr(attrs["stream_journal"])))
    return refs


def _identity(attrs: dict | None) -> tuple[str, str] | None:
    """(parts folder, file id) from a root's attributes, None if it has none."""
    if not attrs or "parts_folder" not in attrs or "file_id" not in attrs:
        return None
    return str(attrs["parts_folder"]), str(attrs["file_id"])


def _replaced(old, replaces: Collection[str], config_toml: str | None) -> bool:
    """The open root `old` holds a top-level group in `replaces`, or a configuration text other than
    `config_toml` (when given)."""
    if any(name in old for name in replaces):
        return True
    stored = old.get(f"{PROVENANCE}/config_toml")
    return config_toml is not None and stored is not None and stored.asstr()[()] != config_toml


def _old_identity(path: Path) -> tuple[str, str] | None:
    """(parts folder, file id) of the beltdyn root at `path` that `force` replaces, if readable."""
    h5py = h5py_module()
    try:
        with h5py.File(path, "r") as f:
            return _identity({k: decode_attr(v) for k, v in f.attrs.items()})
    except (OSError, ValueError):
        return None


class Transaction:
    """One atomic change of the results file at `path` (the caller holds its lock).

    `f` is the open temporary root. When the change replaces a top-level group of the old root (one
    named in `replaces`) or its configuration text (`config_toml`, if given and not the one stored),
    `f` is a fresh file holding the old root's attributes (`rebuilt`): a group the caller creates
    replaces the old one of that name, `group(name)` copies the old one in to be changed, and at
    `commit` every other group of the old root is copied in unchanged (`carry_over`). Otherwise `f` is
    a byte copy of the old root, to be added to (a top-level group created in it must be new). With no
    old root (or when `force` replaces it: another configuration, not a beltdyn file) `f` is a fresh,
    empty file. `part(group)` opens the group's new part file. `commit()` makes everything durable and
    visible at once; `abort()` removes what was written. Either way the root at `path` is never
    modified in place."""

    def __init__(self, path: Path, *, config_sha256: str, force: bool = False, replaces: Collection[str] = (),
                 config_toml: str | None = None) -> None:
        h5py = h5py_module()
        self.path = path = resolve_target(path)
        attrs = inspect_target(path, config_sha256=config_sha256, force=force)
        update = attrs is not None
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"{path}: cannot create the output directory: {exc}") from exc
        self._dropped = None if update or not path.exists() else _old_identity(path)  # force replaces it
        self.folder, self.file_id = _identity(attrs) or (parts_folder(path), new_file_id())
        self._parts: dict[str, tuple[Path, object]] = {}
        self.committed = False
        self.old = None  # a rebuilt root's old root, open read-only until the commit
        self.rebuilt = False
        self.tmp = temp_name(path, self.file_id)
        try:
            self.old_refs: set[str] = set()
            if update:
                self.old = h5py.File(path, "r")
                self.rebuilt = _replaced(self.old, replaces, config_toml)
                self.old_refs = references(self.old)
            if update and not self.rebuilt:
                self._close_old()
                shutil.copyfile(path, self.tmp)
                self.f = h5py.File(self.tmp, "r+")
            else:  # the default (earliest) file format, for the widest reader compatibility
                self.f = h5py.File(self.tmp, "w-")
            if update:
                try:
                    shutil.copymode(path, self.tmp)
                except OSError:
                    pass
            if self.rebuilt:
                copy_attrs(self.old, self.f)
            self.f.attrs["parts_folder"] = self.folder
            self.f.attrs["file_id"] = self.file_id
        except BaseException as exc:
            self.abort()
            if isinstance(exc, OSError):
                raise WriteFailure(f"{path}: cannot create a temporary file next to it: {exc}") from exc
            raise
        self.fresh = not update

    # -- the old root's groups -------------------------------------------------------------------

    def group(self, name: str):
        """Top-level group `name` to be changed: the old root's (in a rebuilt root, copied in first unless
        the transaction created one of that name), None if there is none."""
        if self.old is not None and name not in self.f and name in self.old:
            copy_group(self.old, self.f, name)
        return self.f.get(name)

    def carry_over(self) -> None:
        """In a rebuilt root: copy in every top-level object of the old root that the transaction
        neither replaced nor copied (run by `commit`)."""
        if self.old is not None:
            for name in self.old:
                if name not in self.f:
                    copy_group(self.old, self.f, name)

    # -- parts ---------------------------------------------------------------------------------

    def new_part_path(self, group: str, suffix: str) -> tuple[str, Path]:
        """(name relative to the root's folder, path) of a new part (".h5") or journal (".stream")."""
        (self.path.parent / self.folder).mkdir(exist_ok=True)
        rel = f"{self.folder}/{part_name(group, self.file_id, suffix)}"
        return rel, self.path.parent / rel

    def part(self, group: str):
        """(relative name, open h5py File) of this transaction's part file of top-level `group`."""
        if group not in self._parts:
            rel, p = self.new_part_path(group, ".h5")
            self._parts[group] = (rel, h5py_module().File(p, "w-"))
            attrs = self.f[group].attrs  # the group lists its parts (what `references` finds)
            attrs["parts"] = [*(str(x) for x in decode_attr(attrs.get("parts", np.array([], dtype=object)))), rel]
        return self._parts[group][0], self._parts[group][1]

    def _close_old(self) -> None:
        if getattr(self, "old", None) is not None:
            try:
                self.old.close()
            except Exception:  # noqa: BLE001 - read-only: nothing to lose
                pass
            self.old = None

    # -- end -----------------------------------------------------------------------------------

    def commit(self) -> list[str]:
        """Parts closed and fsync'ed, the root copy fsync'ed and renamed over the root, the folder
        fsync'ed; then the files it no longer references are removed. Returns the removed files that
        the previous root did not reference either (leftovers of a writer that died)."""
        try:
            for _rel, part in self._parts.values():
                part.close()
            for _group, (rel, _part) in self._parts.items():
                fsync_file(self.path.parent / rel)
            if self._parts:
                fsync_dir(self.path.parent / self.folder)
            self.carry_over()
            self._close_old()
            self.f.attrs["modified_utc"] = now_utc()
            self.f.flush()
            refs = references(self.f)
            self.f.close()
            fsync_file(self.tmp)
            os.replace(self.tmp, self.path)
            self.committed = True  # from here on nothing is undone (abort does nothing)
        except BaseException:
            self.abort()
            raise
        fsync_dir(self.path.parent)
        removed = remove_leftovers(self.path, folders={self.folder, parts_folder(self.path)},
                                   file_ids={self.file_id}, referenced=refs)
        if self._dropped is not None:  # the file that --force replaced: its parts go with it
            remove_leftovers(self.path, folders={self._dropped[0]}, file_ids={self._dropped[1]}, referenced=refs)
        return [r for r in removed if r not in self.old_refs]

    def abort(self) -> None:
        """Close and remove the temporary root and the new parts; the root stays as it was. Nothing
        after the commit's rename (an interrupt during the removal of old parts leaves leftovers that
        the next run removes)."""
        if self.committed:
            return
        for _rel, part in self._parts.values():
            try:
                part.close()
            except Exception:  # noqa: BLE001 - best effort while another error propagates
                pass
        for rel, _part in self._parts.values():
            unlink_quietly(self.path.parent / rel)
        self._parts.clear()
        self._close_old()
        f = getattr(self, "f", None)
        if f is not None:
            try:
                f.close()
            except Exception:  # noqa: BLE001
                pass
        unlink_quietly(self.tmp)
        try:
            (self.path.parent / self.folder).rmdir()  # only if empty
        except OSError:
            pass


# --------------------------------------------------------------------------------------------
# Datasets: inline in the root, or in the group's part file behind a virtual dataset
# --------------------------------------------------------------------------------------------


def _top_group(g) -> str:
    return g.name.strip("/").split("/")[0]


def _virtual(tx: Transaction, g, name: str, src, *, growable: bool):
    """A virtual dataset `g/name` mapping the whole of `src` (a dataset in a part file); fill value NaN
    (floats) or 0: what a reader sees if the part is missing (`read_group` refuses that instead)."""
    h5py = h5py_module()
    rel = tx._parts[_top_group(g)][0]
    shape = src.shape
    maxshape = (None, *shape[1:]) if growable else shape
    # "%" starts a printf-like pattern in source names (HDF5): escaped as "%%"
    vsrc = h5py.VirtualSource(rel.replace("%", "%%"), src.name.replace("%", "%%"), shape=shape, dtype=src.dtype,
                              maxshape=maxshape)
    layout = h5py.VirtualLayout(shape=shape, dtype=src.dtype, maxshape=maxshape)
    if growable:
        unlimited = h5py.h5s.UNLIMITED
        layout[0:unlimited, ...] = vsrc[0:unlimited, ...]
    else:
        layout[...] = vsrc[...]
    fill = np.nan if src.dtype.kind == "f" else 0
    return g.create_virtual_dataset(name, layout, fillvalue=fill)


def write_dataset(tx: Transaction, g, name: str, arr: np.ndarray, is_str: bool, units: str, description: str):
    """A fixed dataset: in the root when small (or strings), else in the part file, mapped."""
    h5py = h5py_module()
    if is_str:
        ds = g.create_dataset(name, shape=arr.shape, dtype=h5py.string_dtype())
        if arr.size:
            ds[()] = arr
    elif arr.nbytes > INLINE_BYTES:
        _, part = tx.part(_top_group(g))
        src = part.require_group(g.name).create_dataset(name, data=arr)
        ds = _virtual(tx, g, name, src, growable=False)
    else:
        ds = g.create_dataset(name, data=arr)
    ds.attrs["units"] = units
    if description:
        ds.attrs["description"] = description
    return ds


def write_series(tx: Transaction, g, name: str, *, rows: int, shape: tuple[int, ...], rows_of: Callable,
                 units: str, description: str = "", chunk_rows: int | None = None):
    """A growable time series (first axis unlimited, chunked: a few hundred rows, at most ~1 MiB),
    filled in blocks from `rows_of(start, stop)` (an array (stop - start, *shape)); in the root when
    small, else in the part file behind a virtual dataset of unlimited first axis."""
    row_bytes = 8 * int(np.prod(shape, dtype=np.int64))
    if chunk_rows is None:
        chunk_rows = max(1, min(CHUNK_ROWS, CHUNK_BYTES // max(1, row_bytes)))
    big = rows * row_bytes > INLINE_BYTES
    target = tx.part(_top_group(g))[1].require_group(g.name) if big else g
    ds = target.create_dataset(name, shape=(rows, *shape), maxshape=(None, *shape), dtype=np.float64,
                               chunks=(chunk_rows, *shape))
    block = max(chunk_rows, (_BLOCK_BYTES // max(1, row_bytes)) // chunk_rows * chunk_rows)
    for start in range(0, rows, block):
        stop = min(rows, start + block)
        ds[start:stop] = rows_of(start, stop)
    if big:
        ds = _virtual(tx, g, name, ds, growable=True)
    ds.attrs["units"] = units
    if description:
        ds.attrs["description"] = description
    return ds


def write_prepared(tx: Transaction, g, prepared: Prepared, *, scales: dict | None = None) -> dict:
    """Coordinates first (made dimension scales), then variables attached to them."""
    scales = dict(scales or {})
    new = {}
    for dim, (arr, is_str, units, description) in prepared.coords.items():
        ds = write_dataset(tx, g, dim, arr, is_str, units, description)
        ds.make_scale(dim)
        scales[dim] = new[dim] = ds
    for name, arr, is_str, dims, units, description in prepared.variables:
        ds = write_dataset(tx, g, name, arr, is_str, units, description)
        for axis, dim in enumerate(dims):
            ds.dims[axis].attach_scale(scales[dim])
    return new


def set_status(g, status: str, error: str) -> None:
    """Status (and error, for failed/interrupted runs); the running writer's bookkeeping removed."""
    if status not in STATUSES:
        raise ValueError(f"status must be one of {STATUSES}, not {status!r}")
    g.attrs["status"] = status
    if status in ("failed", "interrupted") or error:
        message = str(error) or ("unknown error" if status == "failed" else status)
        if len(message) > MAX_ERROR_CHARS:
            message = message[: MAX_ERROR_CHARS - 15] + " ... (truncated)"
        g.attrs["error"] = message
    elif "error" in g.attrs:
        del g.attrs["error"]
    if status != "running":
        for key in WRITER_ATTRS:
            if key in g.attrs:
                del g.attrs[key]


def write_root(f, *, config_toml: str, config_sha256: str, fresh: bool) -> None:
    h5py = h5py_module()
    now = now_utc()
    if fresh or "created_utc" not in f.attrs:
        f.attrs["created_utc"] = now
    f.attrs["modified_utc"] = now
    f.attrs["beltdyn_version"] = __version__
    f.attrs["schema_version"] = SCHEMA_VERSION
    f.attrs["config_sha256"] = config_sha256
    prov = f.require_group(PROVENANCE)
    if "config_toml" in prov:
        if prov["config_toml"].asstr()[()] == config_toml:
            return  # (a byte copy of the root: rewriting it would leave the old text as garbage)
        del prov["config_toml"]
    ds = prov.create_dataset("config_toml", data=config_toml, dtype=h5py.string_dtype())
    ds.attrs["units"] = "1"
    ds.attrs["description"] = "resolved configuration (TOML)"


def new_group(parent, name: str, attrs: dict):
    """Replace group `name` of `parent` (an open root or group) by an empty one with `attrs`."""
    if name in parent:
        del parent[name]
    g = parent.create_group(name)
    for key, value in attrs.items():
        g.attrs[key] = value
    return g


# --------------------------------------------------------------------------------------------
# Public: whole groups
# --------------------------------------------------------------------------------------------


def write_group(
    path: Path, group: GroupData, *, config_toml: str, config_sha256: str, force: bool = False
) -> list[str]:
    """Atomically add or replace one group of the results file at `path` (see `write_groups`)."""
    return write_groups(path, [group], config_toml=config_toml, config_sha256=config_sha256, force=force)


def write_groups(
    path: Path, groups: list[GroupData], *, config_toml: str, config_sha256: str, force: bool = False,
    base_config_sha256: str | None = None,
) -> list[str]:
    """Atomically add or replace several groups of the results file at `path` in one transaction.

    If the file holds another configuration, `OutputError` is raised unless `force` (then a fresh file
    is started). The groups are replaced, the root attributes and `/provenance/config_toml` written;
    nothing is visible until the commit, and on any exception (or a kill) the file is as it was.
    Parent directories are created. `base_config_sha256` (the configuration as given when the results
    are of a derived one, `modal --rtol`) is stored as a root attribute; the file's own check stays on
    `config_sha256`. Holds the results-file lock meanwhile (OutputError if another process writes the
    file). Returns the leftover files of an earlier, killed writer that were removed (normally none:
    the CLI recovers first, see `recover`)."""
    path = resolve_target(path)
    check_provenance_args(config_toml, config_sha256)
    ready = []
    for group in groups:
        if not isinstance(group, GroupData):
            raise TypeError("write_groups: groups must be GroupData")
        if group.name == PROVENANCE:
            raise ValueError(f"group name {PROVENANCE!r} is reserved")
        prepared = prepare(group.coords, group.coord_units, group.variables, where=f"group {group.name!r}")
        ready.append((group, prepared, prepare_attrs(group.attrs, where=f"group {group.name!r}")))

    names = ", ".join(f"/{g.name}" for g in groups)
    with writing(path):
        tx = Transaction(path, config_sha256=config_sha256, force=force, replaces=[g.name for g in groups],
                         config_toml=config_toml)
        try:
            write_root(tx.f, config_toml=config_toml, config_sha256=config_sha256, fresh=tx.fresh)
            if base_config_sha256 is not None:
                tx.f.attrs["base_config_sha256"] = base_config_sha256
            for group, prepared, attrs in ready:
                g = new_group(tx.f, group.name, attrs)
                write_prepared(tx, g, prepared)
                set_status(g, group.status, group.error)
            removed = tx.commit()
        except BaseException as exc:
            tx.abort()
            if isinstance(exc, OSError):
                raise WriteFailure(f"{path}: cannot write {names}: {exc}") from exc
            raise
    return [f"{path}: removed {len(removed)} leftover file(s) of an earlier write that did not finish: "
            + ", ".join(removed)] if removed else []
