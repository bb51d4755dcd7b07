"""File safety of results files: the one-writer lock, the writer's identity and liveness, durable
renames, the names of temporary and part files, the checks before a file is touched, and the
removal of what an earlier, killed writer left behind.

Nothing here knows the HDF5 layout beyond the root attributes (see `results_io` for the design).
"""

from __future__ import annotations

import os
import re
import secrets
import socket
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from beltdyn import SCHEMA_VERSION
from beltdyn import cleanup
from beltdyn.errors import OutputError
from beltdyn.results.schema import decode_attr, h5py_module

HELD_LOCKS: set[int] = set()  # lock descriptors of this process (closed in forked sweep workers)
_OUTPUT_LOCKS: dict[str, int] = {}  # results-file lock path -> its descriptor
PARTS_SUFFIX = ".parts"  # <name>.parts/: the folder of a results file's part files and stream journals
_TOKEN_HEX = 8


# --------------------------------------------------------------------------------------------
# One writer per file: <name>.lock (flock)
# --------------------------------------------------------------------------------------------


class WriteFailure(OutputError):
    """An I/O error (a full disk, a failing device) while the results were being written: not bad input,
    so exit 1 (a solver-like failure), naming the file and the error."""

    exit_code = 1


class OutputBusy(OutputError):
    """The results-file lock is held by another process (a live beltdyn command writing the file)."""


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


def _lock_path(path: Path) -> Path:
    return Path(str(path) + ".lock")


def holds_lock(path: Path) -> bool:
    """This process holds the results-file lock of `path`."""
    return _OUTPUT_LOCKS.get(os.path.abspath(_lock_path(path))) in HELD_LOCKS


def _acquire(path: Path) -> int | None:
    """Take `<path>.lock`: its descriptor, or None when no lock is possible there (a read-only folder:
    the write itself will say why). OutputError (exit 2) naming the holder's pid when it is taken."""
    lock = _lock_path(path)
    for _ in range(20):
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)  # as the writer would (results/ by default)
            fd = take_lock(lock)
        except OSError:
            return None
        except LockBusy as busy:
            raise OutputBusy(f"results file {path} is being written by {busy.who} (another beltdyn command on the "
                              f"same output); wait for it to finish or write to another file with -o") from None
        if fd is not None:
            _OUTPUT_LOCKS[os.path.abspath(lock)] = fd
            return fd
    raise OutputError(f"cannot lock the results file {path}: its lock keeps disappearing")


def _release(path: Path, fd: int) -> None:
    if fd in HELD_LOCKS:
        try:
            _lock_path(path).unlink()
        except OSError:
            pass
        HELD_LOCKS.discard(fd)
        _OUTPUT_LOCKS.pop(os.path.abspath(_lock_path(path)), None)
        os.close(fd)


def lock_output(path: Path) -> None:
    """Hold `<path>.lock` (flock, exclusive, no waiting) for the rest of this process: a second beltdyn
    command writing the same results file is refused (OutputError, exit 2, naming the holder's pid)
    instead of racing it. Readers never take it. Released when the process exits (the lock file is
    removed then, by beltdyn's cleanup list); after a kill -9 the kernel releases the flock and the stale
    file is simply reused."""
    if holds_lock(path):
        return
    fd = _acquire(path)
    if fd is None:
        return
    pid = os.getpid()

    def release() -> None:
        if os.getpid() == pid:  # not in a forked child
            _release(path, fd)

    cleanup.at_exit(release)


@contextmanager
def writing(path: Path, *, if_free: bool = False) -> Iterator[bool]:
    """Hold the results-file lock of `path` for the block, unless this process holds it already (the
    CLI takes it for the whole command with `lock_output`). Every write of the library runs inside.
    Yields True; when another process holds the lock, OutputBusy (exit 2, naming its pid), or with
    `if_free` a block that yields False and holds nothing (a reader never waits for a writer)."""
    if holds_lock(path):
        yield True
        return
    try:
        fd = _acquire(path)
    except OutputBusy:
        if not if_free:
            raise
        yield False
        return
    try:
        yield True
    finally:
        if fd is not None:
            _release(path, fd)


# --------------------------------------------------------------------------------------------
# The writer's identity: is the process that marked a group "running" still alive?
# --------------------------------------------------------------------------------------------


def _boot_id() -> str:
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return ""


def _start_ticks(pid: int) -> str | None:
    """The start time of process `pid` (clock ticks since boot, /proc/<pid>/stat field 22); None if
    there is no such process, "" where /proc does not exist."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return None if Path("/proc/self/stat").exists() else ""
    except OSError:
        return ""
    return text[text.rindex(")") + 2:].split()[19]


def writer_identity() -> dict[str, str | int]:
    """This process as a writer: host name, pid and a start token (boot id and start time), so that a
    reader can tell a live writer from a dead one whose pid was reused."""
    ticks = _start_ticks(os.getpid()) or ""
    return {"writer_host": socket.gethostname(), "writer_pid": os.getpid(), "writer_start": f"{_boot_id()}:{ticks}"}


def writer_alive(host: str, pid: int, start: str) -> bool | None:
    """True if the writer (as recorded by `writer_identity`) still runs, False if it does not, None if
    that cannot be told from here (another host)."""
    if host != socket.gethostname():
        return None
    ticks = _start_ticks(int(pid))
    if ticks is None:
        return False
    if ticks:
        return f"{_boot_id()}:{ticks}" == start
    try:  # no /proc: the pid alone
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def same_boot(start: str) -> bool:
    """The writer ran since the last boot of this machine: what it wrote (not necessarily synced) is in
    the page cache, i.e. in the file; after a reboot (power loss) only what it synced counts."""
    boot = _boot_id()
    return bool(boot) and start.split(":")[0] == boot


# --------------------------------------------------------------------------------------------
# Names, durability
# --------------------------------------------------------------------------------------------


def resolve_target(path: Path) -> Path:
    path = Path(path)
    if path.is_symlink():  # replace the file the link points to, not the link
        path = Path(os.path.realpath(path))
    return path


def parts_folder(path: Path) -> str:
    """The part folder's name (beside the results file) for a new results file at `path`."""
    return Path(path).name + PARTS_SUFFIX


def new_file_id() -> str:
    return secrets.token_hex(6)


def part_name(group: str, file_id: str, suffix: str) -> str:
    """`<group>-<file id>-<token><suffix>`: a new part (".h5") or stream journal (".stream") name."""
    return f"{group}-{file_id}-{secrets.token_hex(_TOKEN_HEX // 2)}{suffix}"


_PART = re.compile(r".+-([0-9a-f]{12})-[0-9a-f]{8}\.(?:h5|stream)")


def temp_name(path: Path, file_id: str) -> Path:
    """A temporary root beside `path`, named with the writer's pid and the file id of the parts it may
    write, so that the next run can remove both if the writer dies before renaming it."""
    return path.with_name(f"{path.name}.tmp-{os.getpid()}-{file_id}-{secrets.token_hex(_TOKEN_HEX // 2)}")


def fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


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


def unlink_quietly(p: Path) -> None:
    try:
        Path(p).unlink(missing_ok=True)
    except OSError:
        pass


def remove_leftovers(path: Path, *, folders: set[str], file_ids: set[str], referenced: set[str]) -> list[str]:
    """Remove what belongs to the results file `path` but is not referenced by it: its temporary roots
    `<name>.tmp-<pid>-<file id>-<token>` (a writer died before renaming one; also the older form
    without the file id), and, in `folders`, the part files and stream journals of `file_ids` (those
    of the file and of the temporary roots removed) that `referenced` does not name: parts of replaced
    groups, or of a writer that died before its commit. Call only under the lock (no other writer can
    be using them). Returns the names removed (`folder/name` for parts), sorted."""
    removed = []
    ids = set(file_ids)
    temp = re.compile(rf"{re.escape(path.name)}\.tmp-\d+-([0-9a-f]+)(?:-([0-9a-f]+))?")
    if path.parent.is_dir():
        for p in sorted(path.parent.iterdir()):
            m = temp.fullmatch(p.name)
            if m:
                if m[2]:
                    ids.add(m[1])
                unlink_quietly(p)
                removed.append(p.name)
    for folder in sorted(folders):
        parts = path.parent / folder
        if not parts.is_dir():
            continue
        for p in sorted(parts.iterdir()):
            rel = f"{folder}/{p.name}"
            m = _PART.fullmatch(p.name)
            if m and m[1] in ids and rel not in referenced:
                unlink_quietly(p)
                removed.append(rel)
        try:
            parts.rmdir()  # only if empty
        except OSError:
            pass
    return sorted(removed)


# --------------------------------------------------------------------------------------------
# Before a file is touched
# --------------------------------------------------------------------------------------------


def open_read(path: Path):
    h5py = h5py_module()
    if not path.is_file():
        raise OutputError(f"{path}: no such results file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise OutputError(f"{path}: cannot be read as an HDF5 file ({exc})") from exc


def read_only(path: Path) -> bool:
    """No write permission for this user; for root (who may write anyway) no write bit at all: a
    read-only results file is the user's protection and is not replaced."""
    if not os.access(path, os.W_OK):
        return True
    return hasattr(os, "geteuid") and os.geteuid() == 0 and not path.stat().st_mode & 0o222


def inspect_target(path: Path, *, config_sha256: str, force: bool,
                   base_config_sha256: str | None = None) -> dict | None:
    """The root attributes of `path` if it is a beltdyn file to be updated, None if a fresh file is to
    be started (none there, or `force` replaces it); OutputError if the file must not be touched.

    The file is accepted when its `config_sha256` is `config_sha256`, or when `base_config_sha256`
    is given and equals the file's `base_config_sha256` (the configuration as given, before
    `modal --rtol` chose the mesh)."""
    h5py = h5py_module()
    if not path.exists():
        return None
    if not path.is_file():
        raise OutputError(f"{path}: exists and is not a regular file; choose another output path")
    if read_only(path):
        raise OutputError(f"cannot write results to {path}: permission denied (the file is read-only; make it "
                          "writable or choose another output path)")
    try:
        ok = h5py.is_hdf5(path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot be read ({exc})") from exc
    if not ok:
        if force:
            return None
        raise OutputError(f"{path}: exists and is not an HDF5 file; it is not overwritten: --force replaces it "
                          "(or choose another output path)")
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: decode_attr(v) for k, v in f.attrs.items()}
    except OSError as exc:
        if force:
            return None
        raise OutputError(f"{path}: cannot be read as an HDF5 file ({exc}); it is not overwritten: --force "
                          "replaces it (or choose another output path)") from exc
    if "config_sha256" not in attrs or "beltdyn_version" not in attrs:
        if force:
            return None
        raise OutputError(f"{path}: exists and is not a beltdyn results file; it is not overwritten: --force "
                          "replaces it (or choose another output path)")
    if str(attrs.get("schema_version")) != SCHEMA_VERSION:
        if force:
            return None
        raise OutputError(f"{path}: was written with results schema {attrs.get('schema_version')!r}, this "
                          f"beltdyn writes schema {SCHEMA_VERSION!r}; use --force to start the file afresh "
                          "or choose another output path")
    same_base = base_config_sha256 is not None and attrs.get("base_config_sha256") == base_config_sha256
    if attrs["config_sha256"] != config_sha256 and not same_base:
        if force:
            return None
        raise OutputError(f"{path}: holds results of a different configuration (config_sha256 "
                          f"{str(attrs['config_sha256'])[:12]}..., now {config_sha256[:12]}...); use --force "
                          "to start the file afresh or choose another output path")
    return attrs


def check_target(path: Path, *, config_sha256: str, force: bool = False,
                 base_config_sha256: str | None = None) -> None:
    """Raise `OutputError` early (before any analysis runs) if `path` cannot receive the results.

    Refused: a directory; a read-only file (even with `force`); a file that is not a beltdyn results
    file (not HDF5, unreadable, or HDF5 of another program) or a beltdyn file of another
    configuration or schema version, unless `force` (which replaces it); a parent directory that
    cannot be created or written. With `base_config_sha256`, a file whose root attribute
    `base_config_sha256` equals it is accepted too (`modal --rtol` re-run on its own output).
    """
    path = resolve_target(path)
    inspect_target(path, config_sha256=config_sha256, force=force, base_config_sha256=base_config_sha256)
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{path}: cannot create the output directory: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write to directory {parent} (permission denied)")
