"""The stream journal of a running group: fixed-size float64 rows appended to a plain file.

While a transient runs, its samples go to `<name>.parts/<group>-<file id>-<token>.stream`, named by
the `stream_journal` attribute of the group (status `running`) in the results file. Layout:

* bytes 0-31, the head: magic `BDSTREAM`, rows written (u64), rows synced (u64), CRC-32 of these two
  counts (u32), length L of the layout (u32); little-endian;
* bytes 32-(32 + L): the layout, JSON: group name, time units, the series (name, trailing shape, units,
  trailing dims) and the number of columns;
* from the next multiple of 4096 bytes: the rows, C order, one row = [time, series 1 flattened, ...].

Appending writes the rows (`pwrite` after the rows counted so far) and then the `written` count (a
`pwrite` of the 20 bytes of counts and CRC, inside one disk sector): once written, rows survive the
writer's death (kill -9: they are in the page cache). `sync` makes them durable: fdatasync, then the `synced` count, then
fdatasync again; only synced rows count after a reboot (power loss), as rows not yet on the disk may
read back as zeros. Nothing is ever overwritten but the counts, so a reader (or the next run) reads
`count` complete rows at any moment.
"""

from __future__ import annotations

import json
import os
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from beltdyn.errors import OutputError
from beltdyn.results.files import fsync_dir

MAGIC = b"BDSTREAM"
_HEAD = struct.Struct("<8sQQII")  # magic, written, synced, crc32(written, synced), layout length
_COUNTS = struct.Struct("<QQ")
_PAGE = 4096


@dataclass(frozen=True, kw_only=True)
class JournalLayout:
    """What a row holds: time, then each series flattened (trailing shape, units, trailing dims)."""

    group: str
    time_units: str
    series: tuple[tuple[str, tuple[int, ...], str, tuple[str, ...]], ...]

    @property
    def columns(self) -> int:
        return 1 + sum(int(np.prod(shape, dtype=np.int64)) for _, shape, _, _ in self.series)

    def spans(self) -> dict[str, tuple[int, int, tuple[int, ...]]]:
        """series name -> (first column, last column + 1, trailing shape)."""
        out, col = {}, 1
        for name, shape, _, _ in self.series:
            n = int(np.prod(shape, dtype=np.int64))
            out[name] = (col, col + n, tuple(shape))
            col += n
        return out

    def to_json(self) -> bytes:
        return json.dumps({"format": 1, "group": self.group, "time_units": self.time_units, "columns": self.columns,
                           "series": [[n, list(s), u, list(d)] for n, s, u, d in self.series]}).encode()

    @staticmethod
    def from_json(text: bytes) -> JournalLayout:
        obj = json.loads(text)
        return JournalLayout(group=obj["group"], time_units=obj["time_units"],
                             series=tuple((n, tuple(s), u, tuple(d)) for n, s, u, d in obj["series"]))


def _data_offset(layout_bytes: int) -> int:
    return -(-(_HEAD.size + layout_bytes) // _PAGE) * _PAGE


def _counts(written: int, synced: int) -> bytes:
    packed = _COUNTS.pack(written, synced)
    return packed + struct.pack("<I", zlib.crc32(packed))


class JournalWriter:
    """Append rows to a new journal file (created exclusively; its folder must exist)."""

    def __init__(self, path: Path, layout: JournalLayout) -> None:
        self.path = Path(path)
        self.layout = layout
        self.columns = layout.columns
        text = layout.to_json()
        self._offset = _data_offset(len(text))
        self.written = self.synced = 0
        self._entry_synced = False
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        try:
            head = _HEAD.pack(MAGIC, 0, 0, 0, len(text))
            head = head[:8] + _counts(0, 0) + head[28:]
            self._write_all(head + text + bytes(self._offset - _HEAD.size - len(text)), 0)
        except BaseException:
            self.close()
            raise

    def _write_all(self, data, offset: int) -> None:
        view = memoryview(data).cast("B")
        while view.nbytes:
            n = os.pwrite(self._fd, view, offset)
            view, offset = view[n:], offset + n

    def write(self, rows: np.ndarray) -> None:
        """Append rows (n, columns) float64 after the rows written so far, then record them as written
        (an interrupt in between: the same rows written again land at the same place)."""
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        if rows.ndim != 2 or rows.shape[1] != self.columns:
            raise ValueError(f"journal rows must have shape (n, {self.columns}), got {rows.shape}")
        if not len(rows):
            return
        self._write_all(rows, self._offset + 8 * self.columns * self.written)
        self.written += len(rows)
        os.pwrite(self._fd, _counts(self.written, self.synced), 8)

    def sync(self) -> None:
        """Make every written row durable, then record them as synced (durable too); the first time also
        the journal's entry in its folder."""
        if self.synced == self.written:
            return
        os.fdatasync(self._fd)
        if not self._entry_synced:
            fsync_dir(self.path.parent)
            self._entry_synced = True
        self.synced = self.written
        os.pwrite(self._fd, _counts(self.written, self.synced), 8)
        os.fdatasync(self._fd)

    def trim(self) -> None:
        """Cut the file after the rows recorded as written (a write that failed half-way, on a full disk,
        leaves bytes beyond them: their space is given back). Errors are ignored (nothing is lost)."""
        if self._fd >= 0:
            try:
                os.ftruncate(self._fd, self._offset + 8 * self.columns * self.written)
            except OSError:
                pass

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


@dataclass(frozen=True, kw_only=True)
class JournalView:
    """The complete rows of a journal, read-only (`rows` of them, memory-mapped)."""

    layout: JournalLayout
    rows: int
    written: int
    synced: int
    data: np.ndarray  # (rows, columns) float64

    def time(self, start: int = 0) -> np.ndarray:
        return np.array(self.data[start:, 0])

    def series(self, name: str, start: int = 0) -> np.ndarray:
        first, last, shape = self.layout.spans()[name]
        return np.array(self.data[start:, first:last]).reshape(-1, *shape)


def read_journal(path: Path, *, trust_written: bool = True) -> JournalView:
    """Open a journal: its rows recorded as written (the writer is alive, or died on a machine that
    did not restart since) or only those recorded as synced (`trust_written=False`: after a reboot).
    OutputError if it is not a journal."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_HEAD.size)
            if len(head) < _HEAD.size or head[:8] != MAGIC:
                raise OutputError(f"{path}: not a beltdyn stream journal")
            _, written, synced, crc, n_layout = _HEAD.unpack(head)
            layout = JournalLayout.from_json(fh.read(n_layout))
        size = path.stat().st_size
    except (OSError, ValueError, KeyError) as exc:
        raise OutputError(f"{path}: cannot read the stream journal ({exc})") from exc
    if zlib.crc32(_COUNTS.pack(written, synced)) != crc:
        written = synced = 0  # a torn count (cannot happen within one sector; then nothing is trusted)
    offset = _data_offset(n_layout)
    columns = layout.columns
    complete = max(0, size - offset) // (8 * columns)
    rows = min(written if trust_written else synced, complete)
    if rows:
        data = np.memmap(path, dtype=np.float64, mode="r", offset=offset, shape=(rows, columns))
    else:
        data = np.zeros((0, columns))
    return JournalView(layout=layout, rows=rows, written=written, synced=synced, data=data)
