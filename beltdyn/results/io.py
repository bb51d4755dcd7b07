"""HDF5 results files: the public face of the results modules, which are the only ones importing
h5py (lazily, so that the CLI starts fast). The seams: `results_schema` (what a group holds),
`results_write` (transactions, whole groups), `results_stream` (growing groups, recovery),
`results_journal` (the stream journal format), `results_read` (readers), `results_files` (the lock,
writer liveness, names, durability, target checks, leftovers), `results_copy` (copying groups from
one root into another).

Layout (schema version `beltdyn.SCHEMA_VERSION`)
------------------------------------------------
* root attributes `beltdyn_version`, `schema_version`, `created_utc` (ISO 8601, UTC, kept from the
  file's creation), `modified_utc` (last write), `config_sha256` and, from the CLI,
  `base_config_sha256`; `file_id` and `parts_folder` (see below);
* `/provenance/config_toml`: the resolved configuration, a scalar UTF-8 string dataset;
* one group per analysis (`/geometry`, `/static`, `/modal`, `/transient`, `/sweep`, ...) with a
  string attribute `status` (`running|complete|failed|interrupted`) and, when the analysis failed or
  was interrupted, an `error` attribute with the message. A `running` group also names its writer
  (`writer_pid`, `writer_host`, `writer_start`: boot id and process start time) and its stream
  journal (`stream_journal`), and has the `started_utc` of the run.

Inside a group every dimension has a 1-D coordinate dataset of the same name that is an HDF5
dimension scale (integer index 0..n-1 when no values are given); every axis of every other dataset
is attached to the scale of its dimension. Every dataset has a `units` attribute ("1" for
dimensionless values and for string labels) and optionally a `description`. Strings are
variable-length UTF-8; there are no bool (stored as int8) or complex (refused: store real and
imaginary parts separately) datasets. Time series (`/transient`) have `time` as their first axis,
unlimited and chunked. Such files open in h5py, in HDFView and in xarray
(`xarray.open_datatree(path, engine="h5netcdf")`).

Files: a small root and the parts of large groups
-------------------------------------------------
`OUT.h5` is the results file (the root). A numeric dataset above `INLINE_BYTES` (1 MiB) is stored
in a part file of its group, `OUT.h5.parts/<group>-<file id>-<token>.h5`, and the root holds an HDF5
virtual dataset of the same name, shape, dims and units mapping onto it (a relative path: HDF5
resolves it against the root's folder, whatever the reader's working directory; virtual datasets
need HDF5 >= 1.10 in the reader). Readers see one file; keep `OUT.h5.parts` beside `OUT.h5` when
copying or moving results (`read_group` names a missing part; a plain HDF5 reader would see NaN). A
copy made beside the original (`cp OUT.h5 COPY.h5`) shares the original's parts: a later write that
replaces a large group of either removes that part for both. Small results (geometry, static,
modal, short transients) stay entirely in the root.

Why: the root is small whatever the file holds, so every change is a copy of the root (a few kB to a
few MB) plus what the change itself writes: adding `/modal` next to a 1 GB `/transient` writes
/modal and copies the root only (`make bench` measures it; it was a copy of the whole 1 GB file).
Rejected: modifying one HDF5 file in place (not crash safe: a kill -9 during a metadata flush can
leave the whole file unreadable, destroying earlier results; and readers with the file open see
a moving structure); HDF5 SWMR (a file being written, or whose writer died, cannot be opened by
ordinary readers at all: "file is already open for write", until `h5clear`); external links to
per-group files (xarray/h5netcdf resolve dimension-scale references in the wrong file and fail).

Writes: one transaction per change (`results_write.Transaction`)
----------------------------------------------------------------
Under the results-file lock: (1) a new root `OUT.h5.tmp-<pid>-<file id>-<token>` is started beside
it, (2) the groups are written into it, large datasets to a new part file, (3) the new parts are
fsync'ed, then the new root, (4) it is renamed over `OUT.h5` (the commit) and the folder fsync'ed,
(5) parts no longer referenced (those of replaced groups) are removed. A part is never modified
after its commit (nor opened for writing). A change that replaces groups of the file starts the new
root empty, with the old root's attributes, and copies in the old root's other groups (HDF5 H5Ocopy;
virtual datasets keep naming their parts, dimension scales are attached again: `results_copy`); a
change that only adds to it (a streamed group's close, a recovery, a group of a new name) starts
from a byte copy. Never a byte copy with groups deleted: HDF5 does not reclaim the space of a
deleted object, so each replaced group would stay in the root as garbage, copied by every later
write (the root grew by the size of /transient on every rerun of `beltdyn transient`).

Writing results of a different configuration (other `config_sha256`, or another schema version)
into an existing file raises `OutputError` unless `force=True`, in which case the file is started
afresh (its old parts removed after the commit); so is a file that is not a beltdyn results file
(not HDF5, unreadable, or another program's HDF5), which is refused without `force`. A read-only file is refused even with `force` ("permission denied"). `base_config_sha256`
records the configuration as given when the results are of a configuration derived from it
(`modal --rtol` records the chosen mesh as `config_sha256`).

Streaming (`StreamWriter`) and what is lost after a kill
--------------------------------------------------------
A transient first commits `/transient` with status `running` (its coordinates, fixed variables,
attributes, writer and journal name), then appends its samples to the stream journal
`OUT.h5.parts/transient-<file id>-<token>.stream` (fixed-size rows, see `results_journal`):
written to the OS at the first append `WRITE_SECONDS` (0.05 s) after the last write, and fsync'ed
at least every `SYNC_SECONDS` (0.5 s) of wall time; the stepper hands its samples over at least every
0.2 s (`transient.HANDOVER_SECONDS`). At `close` the samples are copied into the file (root or part,
as above) with the final status, in one commit, and the journal is removed. SIGINT and SIGTERM end a
run through `close` ("interrupted", every sample kept). After a kill -9 the samples lost are those
computed in at most the last ~0.4 s of wall time (not yet handed over: <= 0.2 s; handed over but
still buffered: until the next hand-over, <= 0.2 s; usually each hand-over is written at once);
after a power loss, in at most the last ~0.9 s (not yet synced: the sync comes with the first
hand-over 0.5 s after the last one).

What a reader sees after a kill -9 at any moment: before a commit's rename, the previous file,
complete (the temporary root and new parts are invisible leftovers); after it, the new one. During
a run: the group `running`, its writer dead (`group_states(...)[name].orphaned`, `read_group(...)
["writer"]["alive"] is False`), and its samples so far read from the journal by `read_group`. The
next beltdyn command on the file (`recover`, which the CLI runs first and reports, keyed on the file
alone: a writer of any configuration before it checks the file, and the readers `info`, `plot`,
`report` when no live writer holds the lock) copies the
journal's samples into the file and marks the group `interrupted` with an `error` saying what
happened, and removes the temporary roots, journals and parts that the file does not reference
(saying so); a power loss also leaves at most these, as every commit is fsync'ed in order.

One writer, any number of readers
---------------------------------
Every write holds `OUT.h5.lock` (flock; `lock_output` for a whole command): a second writer gets
`OutputError` (exit 2) naming the holder's pid. Readers take no lock and are never blocked: the root
they open is never modified (a commit renames a new one over it; an open reader keeps the old one),
parts and journals are only appended to or created. A reader whose root was replaced while it read
(a part or journal it names is gone) reads the new one (`read_group`).
"""

from __future__ import annotations

from beltdyn.results.files import (
    HELD_LOCKS,
    LockBusy,
    check_target,
    fsync_dir,
    lock_output,
    lock_pid,
    WriteFailure,
    take_lock,
)
from beltdyn.results.read import (
    FileSummary,
    GroupState,
    file_summary,
    group_names,
    group_states,
    read_group,
    read_root_attrs,
)
from beltdyn.results.schema import GroupData, Variable
from beltdyn.results.stream import SYNC_SECONDS, WRITE_SECONDS, StreamWriter, recover
from beltdyn.results.write import INLINE_BYTES, write_group, write_groups

__all__ = [
    "HELD_LOCKS",
    "INLINE_BYTES",
    "SYNC_SECONDS",
    "WRITE_SECONDS",
    "FileSummary",
    "GroupData",
    "GroupState",
    "LockBusy",
    "StreamWriter",
    "Variable",
    "check_target",
    "file_summary",
    "fsync_dir",
    "group_states",
    "lock_output",
    "lock_pid",
    "read_group",
    "read_root_attrs",
    "group_names",
    "recover",
    "take_lock",
    "write_group",
    "write_groups",
    "WriteFailure",
]
