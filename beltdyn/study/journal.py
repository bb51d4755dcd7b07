"""The sweep's journal: `<output>.sweep/` holds `spec.json` (what the sweep is) and `cases.log`, the
finished cases appended as checksummed records, fsync'ed after a batch at most every SYNC_EVERY s and at
the end or on an interruption (a record torn by a crash is cut off on the next lock; see `Journal`);
`--resume` skips the cases found there. A running sweep holds an exclusive lock (`flock` on
`<output>.sweep/lock`, which records its pid): a second sweep on the same journal is refused at once
instead of racing it.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from beltdyn.errors import OutputError

from beltdyn.results.io import HELD_LOCKS as _HELD_LOCKS  # lock descriptors (closed in forked workers)
from beltdyn.results.io import LockBusy, fsync_dir, take_lock




class Journal:
    """`<output>.sweep/`: spec.json (written atomically) and `cases.log`, one append-only file of the
    finished cases; `lock` (flock) while a sweep runs on it.

    A record of cases.log is a 20-byte header, MAGIC (4 bytes), case index (uint32), payload length
    (uint64), CRC-32 of the header's first 16 bytes and the payload (uint32), then the payload: the
    case's arrays as raw buffers (see `_encode`; no pickles). Records are appended with plain writes
    (no temporary file, rename or folder fsync per case) and the log is fsync'ed per batch (`sync`;
    `run_sweep` at most every SYNC_EVERY seconds, and when it ends or is interrupted: a write reaches
    the kernel at once and survives the process, the fsync bounds what an operating-system crash can
    take). A record cut short by a crash, or failing its CRC, ends the valid log: it is cut off when
    the journal is next locked (or written to), and that case counts as not done. A write that fails
    midway (a full disk, an interrupt) is cut off at once. Logs of the previous format (MAGIC `BDC1`,
    .npz payloads) are still read, so an interrupted sweep of that version resumes.

    Nothing is cached here: the running sweep hands each case to its `Assembly` in memory, and the
    journal is read back (`read`, one case at a time) only for the cases of an earlier run."""

    LOCK = "lock"
    LOG = "cases.log"
    MAGIC = b"BDC2"
    MAGIC_NPZ = b"BDC1"  # the previous format: an .npz payload, CRC of the payload only
    _HEAD = struct.Struct("<4sIQI")
    ALIGN = 64  # every array's bytes start at a multiple of this in the payload (and in memory when read)

    def __init__(self, output: Path) -> None:
        self.dir = Path(str(output) + ".sweep")
        self._lock_fd: int | None = None
        self._made_dir = False
        self._discard = False  # remove the folder on unlock (removed while locked)
        self._index: dict[int, tuple[int, int, bytes]] | None = None  # case -> payload offset, length, magic
        self._end = 0  # end of the valid log (valid once _index is)
        self._fd: int | None = None  # the log, open for appending
        self._reader: int | None = None  # the log, open for reading

    def exists(self) -> bool:
        return (self.dir / "spec.json").exists()

    # -- the lock ---------------------------------------------------------------------------------
    def lock(self) -> None:
        """Take the exclusive lock of the journal without waiting; OutputError (exit 2) naming the pid
        of the holder if another sweep has it. The folder is created if needed (and removed again by
        `unlock` if nothing was journaled). Left-over temporary files of a killed run are removed, and
        a record torn by a crash is cut off the log."""
        if self._lock_fd is not None:
            return
        for _ in range(20):
            if not self.dir.is_dir():
                try:
                    self.dir.mkdir(parents=True)
                    self._made_dir = True
                except FileExistsError:
                    pass
                except OSError as exc:
                    raise OutputError(f"cannot create the sweep journal {self.dir}: {exc}") from exc
            try:
                fd = take_lock(self.dir / self.LOCK)
            except FileNotFoundError:  # the folder was removed meanwhile (a sweep finished): again
                continue
            except LockBusy as busy:
                raise OutputError(f"sweep journal {self.dir} is in use by {busy.who} (a sweep writing the same output "
                                  "is running); wait for it to finish or stop it, then use --resume") from None
            except OSError as exc:
                raise OutputError(f"cannot lock the sweep journal {self.dir}: {exc}") from exc
            if fd is None:  # the holder may have finished and removed the folder between our open and flock
                continue
            self._lock_fd = fd
            for stale in self.dir.glob("*.tmp*"):  # partial writes of a run that was killed
                stale.unlink(missing_ok=True)
            self._close()
            self._index = None
            self._scan(truncate=True)  # a record torn by a crash is cut off
            return
        raise OutputError(f"cannot lock the sweep journal {self.dir}: it keeps disappearing")

    def unlock(self) -> None:
        fd, self._lock_fd = self._lock_fd, None
        if fd is None:
            return
        self._close()
        _HELD_LOCKS.discard(fd)
        if self._discard or (self._made_dir and self.dir.is_dir() and not self.exists()):
            # removed while locked, or this run created the folder and journaled nothing (e.g. a usage
            # error): leave no trace. The folder goes before the lock is released; a process waiting
            # on the old lock file notices (inode check in `lock`).
            import shutil

            shutil.rmtree(self.dir, ignore_errors=True)
        os.close(fd)  # releases the flock

    def __enter__(self) -> "Journal":
        self.lock()
        return self

    def __exit__(self, *exc) -> None:
        self.unlock()

    def _close(self) -> None:
        for name in ("_fd", "_reader"):
            fd = getattr(self, name)
            setattr(self, name, None)
            if fd is not None:
                os.close(fd)

    def __del__(self) -> None:  # a journal used without the lock (library callers): no descriptor leaks
        try:
            self._close()
        except (OSError, AttributeError, TypeError):
            pass

    # -- content ----------------------------------------------------------------------------------
    def start(self, spec_json: dict, digest: str) -> None:
        self.dir.mkdir(parents=True, exist_ok=True)
        self._discard = False
        data = json.dumps({"sha256": digest, "spec": spec_json}, indent=1).encode()
        self._put("spec.json", lambda fh: fh.write(data))
        fsync_dir(self.dir)

    def digest(self) -> str:
        return json.loads((self.dir / "spec.json").read_text())["sha256"]

    def _scan(self, truncate: bool = False) -> dict[int, tuple[int, int, bytes]]:
        """The valid records of the log (case -> payload offset, length, magic), read one record at a
        time; with truncate, a torn or corrupt tail is cut off (only under the lock, or by the writer)."""
        if self._index is not None:
            return self._index
        import zlib

        index: dict[int, tuple[int, int, bytes]] = {}
        path = self.dir / self.LOG
        H = self._HEAD.size
        end = size = 0
        try:
            fh = open(path, "rb")
        except FileNotFoundError:
            fh = None
        if fh is not None:
            with fh:
                size = os.fstat(fh.fileno()).st_size
                while True:
                    head = fh.read(H)
                    if len(head) < H:
                        break
                    magic, case, length, crc = self._HEAD.unpack(head)
                    if magic not in (self.MAGIC, self.MAGIC_NPZ) or end + H + length > size:
                        break
                    payload = fh.read(length)
                    seed = zlib.crc32(head[:16]) if magic == self.MAGIC else 0
                    if len(payload) < length or zlib.crc32(payload, seed) != crc:
                        break
                    index[case] = (end + H, length, magic)
                    end += H + length
        if truncate and end < size:
            with open(path, "r+b") as fh:
                fh.truncate(end)
                fh.flush()
                os.fsync(fh.fileno())
        self._index, self._end = index, end
        return index

    def done(self) -> set[int]:
        """Finished cases (a record cut short by a crash does not count)."""
        return set(self._scan())

    def has(self, index: int) -> bool:
        return index in self._scan()

    def write(self, index: int, result: dict, *, sync_dir: bool = True) -> None:
        """Append one case to the log; durable after `sync` (called here unless sync_dir=False: callers
        writing several cases at once call `sync` after the last)."""
        import zlib

        parts = _encode(result, self.ALIGN)
        length = sum(len(p) for p in parts)
        head = self._HEAD.pack(self.MAGIC, index, length, 0)[:16]
        crc = zlib.crc32(head)
        for p in parts:
            crc = zlib.crc32(p, crc)
        record = [head + struct.pack("<I", crc), *parts]
        size = self._HEAD.size + length
        index_map = self._scan()
        if self._fd is None:
            path = self.dir / self.LOG
            new = not path.exists()
            fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o666)
            try:
                if os.fstat(fd).st_size != self._end:  # a torn tail not yet cut off (no lock held): cut it
                    os.ftruncate(fd, self._end)
                if new:
                    fsync_dir(self.dir)
            except BaseException:
                os.close(fd)
                raise
            self._fd = fd
        try:
            done = os.writev(self._fd, record)
            if done < size:  # a short write (rare): the rest in plain writes
                rest = memoryview(b"".join(record))[done:]
                while rest:
                    rest = rest[os.write(self._fd, rest):]
        except BaseException:  # a full disk, an interrupt: no half record left behind
            try:
                os.ftruncate(self._fd, self._end)
            except OSError:
                pass
            raise
        index_map[index] = (self._end + self._HEAD.size, length, self.MAGIC)
        self._end += size
        if sync_dir:
            self.sync()

    def sync(self) -> None:
        """Make the appended cases durable (fsync of the log)."""
        if self._fd is not None:
            os.fsync(self._fd)

    def _put(self, name: str, fill) -> None:
        stem, _, ext = name.partition(".")
        # unique per process: two writers never rename each other's temporary file
        tmp = self.dir / f"{stem}.tmp-{os.getpid()}-{os.urandom(3).hex()}.{ext}"
        try:
            with open(tmp, "wb") as fh:
                fill(fh)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, self.dir / name)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def read(self, index: int) -> dict:
        """One journaled case (its CRC checked again), as arrays; KeyError if it is not journaled."""
        import zlib

        start, length, magic = self._scan()[index]
        if self._reader is None:
            self._reader = os.open(self.dir / self.LOG, os.O_RDONLY | os.O_CLOEXEC)
        H = self._HEAD.size
        raw = np.empty(H + length + self.ALIGN, dtype=np.uint8)  # the payload at an aligned address
        skip = (-(raw.ctypes.data + H)) % self.ALIGN
        buf = raw[skip:skip + H + length]
        if os.preadv(self._reader, [buf], start - H) != H + length:
            raise OutputError(f"the sweep journal {self.dir} lost case {index} (cases.log was cut short)")
        head, payload = buf[:H].tobytes(), buf[H:]
        crc = self._HEAD.unpack(head)[3]
        if zlib.crc32(payload, zlib.crc32(head[:16]) if magic == self.MAGIC else 0) != crc:
            raise OutputError(f"the sweep journal {self.dir} is corrupt (case {index} fails its checksum); "
                              "remove it to start over")
        if magic == self.MAGIC_NPZ:
            import io

            with np.load(io.BytesIO(payload.tobytes()), allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        return _decode(payload)

    def remove(self) -> None:
        """Delete the journal. While locked, the lock file stays until `unlock` (which then removes
        the folder), so that no other sweep can start on it meanwhile."""
        import shutil

        self._close()
        self._index = None
        self._end = 0
        if self._lock_fd is None:
            shutil.rmtree(self.dir, ignore_errors=True)
            return
        for entry in list(self.dir.iterdir()) if self.dir.is_dir() else []:
            if entry.name == self.LOCK:
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)
        self._discard = True


def _encode(result: dict, align: int) -> list:
    """A case's arrays as the buffers of one payload (not joined: written with one writev): uint32
    length of a JSON header [[name, dtype, shape, order], ...], the header, then each array's raw bytes
    (C or Fortran order, as it is in memory, so that a case read back computes bit for bit as the one
    in memory) starting at a multiple of `align`."""
    arrays = {k: np.asarray(v) for k, v in result.items()}
    head, parts = [], []
    for k, a in arrays.items():
        if a.dtype.hasobject:
            raise TypeError(f"sweep case result {k!r} is an object array (not journaled)")
        order = "F" if a.ndim > 1 and a.flags.f_contiguous and not a.flags.c_contiguous else "C"
        head.append([k, a.dtype.str, list(a.shape), order])
        flat = np.ascontiguousarray(a.T if order == "F" else a)  # no copy if it already is
        parts.append(memoryview(flat.reshape(-1).view(np.uint8)) if flat.size else b"")
    text = json.dumps(head).encode()
    out = [struct.pack("<I", len(text)) + text]
    pos = len(out[0])
    for p in parts:
        pad = (-pos) % align
        if pad:
            out.append(bytes(pad))
        out.append(p)
        pos += pad + len(p)
    return out


def _decode(payload: np.ndarray) -> dict:
    """The arrays of a payload (`_encode`), as read-only views of it."""
    n = int(payload[:4].view("<u4")[0])
    head = json.loads(payload[4:4 + n].tobytes())
    out, pos = {}, 4 + n
    align = Journal.ALIGN
    for name, dt, shape, order in head:
        dtype = np.dtype(dt)
        if dtype.hasobject:
            raise OutputError(f"sweep journal: case array {name!r} has an object type")
        pos += (-pos) % align
        size = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        flat = payload[pos:pos + size].view(dtype)
        arr = flat.reshape(shape[::-1]).T if order == "F" else flat.reshape(shape)
        arr.flags.writeable = False
        out[name] = arr
        pos += size
    return out
