"""Parameter sweeps: grids of cases run in parallel, journaled as they finish, modes tracked by MAC.

A sweep is a base configuration plus parameters (dotted keys with value lists), combined as a grid
(C order, the last parameter fastest) or zipped. Each case is the base configuration with the
overrides applied (`config.with_overrides`), analysed by a top-level, picklable worker function, so
the same code runs in a local process pool and on Dask workers.

Mode tracking: every case has a parent, its neighbour one step back along the last axis that moved
(a spanning tree of the grid). The tracked modes of the parent are matched to the modes of the case
by the modal assurance criterion MAC_ij = (phi_i^T M phi_j)^2 of mass-normalized shapes (M of the
case), with an optimal one-to-one assignment (linear_sum_assignment), so crossings and the
near-degenerate upper/lower span pairs keep their identity. Where the DOF counts differ (a mesh
sweep) the match is by classification (kind, order, span), then by frequency.

Journal: `<output>.sweep/` holds `spec.json` (what the sweep is) and `cases.log`, the finished cases
appended as checksummed records, fsync'ed after a batch at most every SYNC_EVERY s and at the end or
on an interruption (a record torn by a crash is cut off on the next lock; see `Journal`); `--resume`
skips the cases found there. The results come back from the workers in memory and are assembled in
case order as they arrive (`Assembly`): only the small per-case quantities are kept for every case,
mode shapes only while a later case is still to be tracked from them; the journal is read back only
for the cases of an earlier run, one at a time, so an interrupted and resumed sweep gives the same
file. A running sweep holds an exclusive lock (`flock` on `<output>.sweep/lock`, which records its
pid): a second sweep on the same journal is refused at once instead of racing it.

Local workers are forked processes that die with the sweep: each asks the kernel for SIGKILL when its
parent dies (Linux `prctl(PR_SET_PDEATHSIG)`), ignores Ctrl-C (the parent handles it: the journal is
kept, the workers are stopped) and never holds the journal lock. At most one worker per available core.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import struct
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from beltdyn.config import DriveConfig, config_hash, resolved_toml
from beltdyn.errors import ConfigError, OutputError
from beltdyn.results.io import fsync_dir

ANALYSES = ("static", "modal", "transient")
MAC_LOST = 0.5  # below this MAC a tracked mode counts as lost (it left the computed modes)
SAFETY = 1.25  # safety factor of the Richardson error estimate (Roache's grid convergence index)
SYNC_EVERY = 0.5  # s: the journal is fsync'ed after a batch of cases at most this often (and at the end)


@dataclass(frozen=True, kw_only=True)
class Param:
    key: str
    values: tuple[Any, ...]


@dataclass(frozen=True, kw_only=True)
class SweepSpec:
    params: tuple[Param, ...]
    analysis: str
    zip: bool
    n_modes: int

    @property
    def shape(self) -> tuple[int, ...]:
        return (len(self.params[0].values),) if self.zip else tuple(len(p.values) for p in self.params)

    @property
    def n_cases(self) -> int:
        return int(np.prod(self.shape))

    def case_values(self, index: int) -> tuple[Any, ...]:
        if self.zip:
            return tuple(p.values[index] for p in self.params)
        multi = np.unravel_index(index, self.shape)
        return tuple(p.values[int(i)] for p, i in zip(self.params, multi))

    def parent(self, index: int) -> int:
        """Neighbour one step back along the last axis that moved; -1 for the first case."""
        if index == 0:
            return -1
        if self.zip:
            return index - 1
        multi = list(np.unravel_index(index, self.shape))
        for axis in range(len(multi) - 1, -1, -1):
            if multi[axis] > 0:
                multi[axis] -= 1
                return int(np.ravel_multi_index(multi, self.shape))
        return -1

    def parents(self) -> np.ndarray:
        """`parent` of every case, as an array."""
        n = self.n_cases
        idx = np.arange(n, dtype=np.int64)
        if self.zip:
            return idx - 1
        out = np.full(n, -1, dtype=np.int64)
        multi = np.unravel_index(idx, self.shape)
        stride = 1
        todo = idx > 0
        for axis in range(len(self.shape) - 1, -1, -1):
            hit = todo & (multi[axis] > 0)
            out[hit] = idx[hit] - stride
            todo &= ~hit
            stride *= self.shape[axis]
        return out

    def to_json(self) -> dict:
        return {"params": [{"key": p.key, "values": list(p.values)} for p in self.params],
                "analysis": self.analysis, "zip": self.zip, "n_modes": self.n_modes}


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_values(key: str, spec: str, *, where: str = "--param") -> tuple[Any, ...]:
    """'0.02,1,100' (list), '100:600:26' (26 values from 100 to 600), '0.02:100:9:log' (log-spaced)."""
    spec = spec.strip()
    m = re.fullmatch(rf"({_NUM}):({_NUM}):(\d+)(?::(lin|log))?", spec)
    if m:
        a, b, n, kind = float(m.group(1)), float(m.group(2)), int(m.group(3)), m.group(4) or "lin"
        if n < 1:
            raise ConfigError("a range needs at least 1 value", key=f"{where} {key}={spec}")
        if kind == "log":
            if a <= 0 or b <= 0:
                raise ConfigError("a log range needs positive bounds", key=f"{where} {key}={spec}")
            vals = np.geomspace(a, b, n)
        else:
            vals = np.linspace(a, b, n)
        if key.endswith("elements_per_span"):
            return tuple(int(round(v)) for v in vals)
        return tuple(float(v) for v in vals)
    import tomllib

    out = []
    for item in spec.split(","):
        item = item.strip()
        if not item:
            raise ConfigError("empty value in the list", key=f"{where} {key}={spec}")
        try:
            out.append(tomllib.loads(f"v = {item}")["v"])
        except tomllib.TOMLDecodeError:
            if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", item):
                out.append(item)
            else:
                raise ConfigError(f"'{item}' is not a TOML literal", key=f"{where} {key}={spec}") from None
    return tuple(out)


def make_spec(cfg: DriveConfig, params: list[tuple[str, str]], *, analysis: str, zip_: bool,
              n_modes: int | None = None) -> SweepSpec:
    """Validate the sweep: zipped, equal lengths; every case a valid configuration (`_check_cases`)."""
    if analysis not in ANALYSES:
        raise ConfigError(f"must be one of {', '.join(ANALYSES)}, got {analysis!r}", file=cfg.source, key="--analysis")
    if not params:
        raise ConfigError("give at least one --param KEY=SPEC (or a [sweep] table)", file=cfg.source, key="--param")
    ps = tuple(Param(key=k, values=parse_values(k, v)) for k, v in params)
    keys = [p.key for p in ps]
    if len(set(keys)) != len(keys):
        raise ConfigError("a key is swept twice", file=cfg.source, key="--param")
    if zip_ and len({len(p.values) for p in ps}) > 1:
        raise ConfigError("--zip needs value lists of equal length: "
                          + ", ".join(f"{p.key} has {len(p.values)}" for p in ps), file=cfg.source, key="--param")
    if analysis == "transient" and cfg.transient is None:
        raise ConfigError("a transient sweep needs a [transient] table", file=cfg.source, key="transient")
    spec = SweepSpec(params=ps, analysis=analysis, zip=zip_, n_modes=n_modes or cfg.modal.modes)
    _check_cases(cfg, spec)
    return spec


CHECK_EVERY_CASE = 5000  # larger grids: every value of every parameter (the others at their first value)


def _check_cases(cfg: DriveConfig, spec: SweepSpec) -> None:
    """Every case must be a valid configuration (ConfigError naming the key and the case before any
    case runs); cheap (~0.1 ms a case). Grids of more than CHECK_EVERY_CASE cases are checked value by
    value. A transient sweep measures its amplitudes after transient.spectrum.start, so that must
    come before transient.duration in every case, whether or not the spectrum is enabled."""
    import copy

    from beltdyn.config import apply_override, config_from_dict, config_to_dict

    raw = config_to_dict(cfg)
    tables = sweep_tables(cfg, spec)
    if spec.zip or spec.n_cases <= CHECK_EVERY_CASE:
        cases = [spec.case_values(i) for i in range(spec.n_cases)]
    else:
        first = [p.values[0] for p in spec.params]
        cases = [tuple(v if k == j else first[k] for k in range(len(spec.params)))
                 for j, p in enumerate(spec.params) for v in p.values]
    seen = set()
    for values in cases:
        assignments = case_assignments(spec, values, tables)
        marker = tuple(assignments)
        if marker in seen:
            continue
        seen.add(marker)
        where = ", ".join(assignments)
        case_raw = copy.deepcopy(raw)
        try:
            for a in assignments:
                apply_override(case_raw, a, file=cfg.source)
            c = config_from_dict(case_raw, file=cfg.source)
            from beltdyn.model.system import check_model_size

            check_model_size(c)
        except ConfigError as exc:
            raise ConfigError(f"{exc.detail} (in the sweep case {where})", file=exc.file, key=exc.key) from None
        if spec.analysis == "transient" and c.transient is not None \
                and not c.transient.spectrum.start < c.transient.duration:
            raise ConfigError(f"must be < transient.duration ({c.transient.duration:g} s) in every case of a "
                              f"transient sweep (the amplitudes are measured after it), got "
                              f"{c.transient.spectrum.start:g} (in the sweep case {where})",
                              file=cfg.source, key="transient.spectrum.start")


def _assign(key: str, value: Any) -> str:
    import tomli_w

    text = tomli_w.dumps({"v": value}).strip()[len("v = "):]
    return f"{key}={text}"


def case_assignments(spec: SweepSpec, values: tuple, tables: dict[str, bytes]) -> list[str]:
    """The overrides of one case. A swept table file (a key ending in .table) also sets its
    table_sha256 to that file's (`tables`, from `sweep_tables`), in place of the one the base
    configuration resolved for its own table: every case is held to the table version swept."""
    out = []
    for p, v in zip(spec.params, values):
        out.append(_assign(p.key, v))
        if p.key.endswith(".table"):
            out.append(_assign(f"{p.key}_sha256", hashlib.sha256(tables[str(v)]).hexdigest()))
    return out


def sweep_tables(cfg: DriveConfig, spec: SweepSpec) -> dict[str, bytes]:
    """The bytes of every CSV table the sweep's cases read (the configuration's and every swept table
    value), sent with the cases to the workers (`run_case`)."""
    from beltdyn.config import table_bytes

    swept = tuple(str(v) for p in spec.params if p.key.endswith(".table") for v in p.values)
    try:
        return table_bytes(cfg, swept)
    except OSError as exc:  # (the cases' check read them a moment ago)
        raise ConfigError(f"cannot read a table: {exc}", file=cfg.source, key="--param") from None


def spec_hash(cfg: DriveConfig, spec: SweepSpec) -> str:
    """The sweep's identity (a journal resumes only the same one): the configuration (its tables'
    sha256 included), the grid, and the sha256 of every swept table file."""
    tables = sweep_tables(cfg, spec)
    swept = {str(v): hashlib.sha256(tables[str(v)]).hexdigest()
             for p in spec.params if p.key.endswith(".table") for v in p.values}
    return hashlib.sha256((config_hash(cfg) + json.dumps(spec.to_json(), sort_keys=True)
                           + json.dumps(swept, sort_keys=True)).encode()).hexdigest()


# ------------------------------------------------------------------------------------ the worker
def run_case(base_toml: str, source: str, assignments: list[str], analysis: str, n_modes: int,
             tables: dict[str, bytes] | None = None) -> dict:
    """One case, self-contained (picklable arguments, plain-dict result) for any executor: the CSV
    tables travel with it (`config.table_bytes`), so a worker on another machine needs no files."""
    import tomllib

    from beltdyn.config import apply_override, config_from_dict
    from beltdyn.errors import BeltdynError

    t0 = time.perf_counter()
    out: dict[str, Any] = {"failed": 0, "error": ""}
    try:
        raw = tomllib.loads(base_toml)
        for a in assignments:
            apply_override(raw, a, file=source)
        cfg = config_from_dict(raw, file=source, tables=tables)
        if analysis == "transient" and cfg.transient is not None:
            from dataclasses import replace

            from beltdyn.analysis.timestep import resolve_step  # the step each case's accuracy (or step) asks for

            cfg = replace(cfg, transient=resolve_step(cfg.transient)[0])
        from beltdyn.pipeline import analyse

        run = analyse(cfg, modal=analysis == "modal", n_modes=n_modes + 4)
        model, st = run.system, run.static
        out["mean_tension"] = st.mean_tension
        out["span_tension"] = st.span_tension
        out["hub_load"] = st.hub_load
        out["pulley_center"] = st.pulley_center
        if model.arms is not None:  # the tensioner's working curve over the swept load
            out["arm_angle"] = st.arm_angle
            out["arm_torque"] = st.arm_torque
        if st.slip_margin is not None and not np.all(np.isnan(st.slip_margin)):
            out["slip_margin"] = st.slip_margin
        if model.belt_speed or cfg.running is not None:  # the running belt's speeds (a Campbell diagram)
            from beltdyn.model.geometry import driver_speed_of

            out["belt_speed"] = float(model.belt_speed)
            out["driver_speed"] = driver_speed_of(model.belt_speed, model.layout, model.driver)
        if analysis == "modal":
            md = run.modal
            out["frequency"] = md.frequency
            out["growth_rate"] = md.growth_rate if md.growth_rate is not None else np.zeros(len(md.frequency))
            out["shapes"] = md.shapes
            out["mshapes"] = np.asarray((model.mass_matrix(st.q) @ md.shapes.T).T)
            out["kind"] = np.array(md.kind)
            out["order"] = md.order
            out["span"] = md.span
            out["label"] = np.array(md.label)
        elif analysis == "transient":
            out.update(_transient_case(run))
    except BeltdynError as exc:
        out = {"failed": 1, "error": str(exc)}
    except Exception as exc:  # a defect in one case must not take the sweep down: record it
        out = {"failed": 1, "error": f"{type(exc).__name__}: {exc}"}
    out["wall_time"] = time.perf_counter() - t0
    return out


def _transient_case(run) -> dict:
    """Steady-state amplitudes (first harmonic of the excitation, and half peak-to-peak) of the
    span tensions, hub loads and bearing forces after transient.spectrum.start."""
    from beltdyn.analysis.spectrum import amplitude_spectrum, harmonic_content
    from beltdyn.analysis.transient import prepare, run_transient

    from beltdyn.pipeline import transient_start

    cfg = run.config
    system, static = transient_start(run)
    setup = prepare(system, static, cfg.transient)
    keep = ("span_tension", "hub_load", "bearing_force")
    got: dict[str, list] = {k: [] for k in keep if any(s.name == k for s in setup.series)}
    times: list = []

    def sink(t, batch):
        sel = t >= cfg.transient.spectrum.start
        times.append(t[sel])
        for k in got:
            got[k].append(batch[k][sel])

    summary = run_transient(system, static, cfg.transient, sink=sink, setup=setup)
    t = np.concatenate(times)
    out: dict[str, Any] = {"n_slack_events": len(summary.slack_events)}
    for k, parts in got.items():
        x = np.concatenate(parts)
        out[f"{k}_half_range"] = 0.5 * (x.max(axis=0) - x.min(axis=0))
        if setup.excitation_frequency and len(t) >= 8:
            spec = amplitude_spectrum(t, x, start=t[0])
            out[f"{k}_first_harmonic"] = harmonic_content(spec, setup.excitation_frequency, n_harmonics=1)[0]
    return out


def _connect(address: str, cfg: DriveConfig):
    """A Dask client, or a usage error naming --scheduler (before anything is journaled)."""
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("Dask is not installed: pip install 'beltdyn[dask]'", file=cfg.source,
                          key="--scheduler") from None
    try:
        return Client(address, timeout=10)
    except (OSError, ValueError, TypeError) as exc:
        raise ConfigError(f"cannot reach the Dask scheduler {address!r}: {exc}", file=cfg.source,
                          key="--scheduler") from None


def _run_chunk(base_toml: str, source: str, tables: dict[str, bytes], items: list[tuple[int, list[str]]],
               analysis: str, n_modes: int):
    return [(i, run_case(base_toml, source, a, analysis, n_modes, tables)) for i, a in items]


# ------------------------------------------------------------------------------------ the journal
from beltdyn.results.io import HELD_LOCKS as _HELD_LOCKS  # noqa: E402  lock descriptors (closed in forked workers)
from beltdyn.results.io import LockBusy, take_lock  # noqa: E402


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


# ------------------------------------------------------------------------------------ running
Progress = Callable[[int, int], None]


def run_sweep(cfg: DriveConfig, spec: SweepSpec, *, journal: Journal, resume: bool = False,
              workers: int | None = None, scheduler: str | None = None,
              progress: Progress | None = None, restart: bool = False) -> "Assembly":
    """Run the missing cases of the sweep, journaling each as it finishes (any order), and assemble
    the results as they come (the returned Assembly, for `assemble`). restart discards an existing
    journal (--force without --resume)."""
    digest = spec_hash(cfg, spec)
    client = _connect(scheduler, cfg) if scheduler else None
    if journal.exists() and restart and not resume:
        journal.remove()
    if journal.exists():
        if not resume:
            raise ConfigError(f"an unfinished sweep is journaled in {journal.dir}: continue it with --resume "
                              f"(or remove the folder)", file=cfg.source, key="--resume")
        if journal.digest() != digest:
            raise ConfigError(f"{journal.dir} belongs to a different sweep or configuration; remove it to start over",
                              file=cfg.source, key="--resume")
    else:
        journal.start(spec.to_json(), digest)
    done = journal.done()
    todo = [i for i in range(spec.n_cases) if i not in done]
    base = resolved_toml(cfg)
    tables = sweep_tables(cfg, spec)
    items = [(i, case_assignments(spec, spec.case_values(i), tables)) for i in todo]
    if progress:
        progress(len(done), spec.n_cases)
    assembly = Assembly(spec)
    assembly.advance(journal)  # the cases of an earlier run, as far as they reach
    if not items:
        return assembly
    n_workers = min(workers or available_cores(), available_cores())
    chunk = max(1, min(16, math.ceil(len(items) / (4 * n_workers))))
    chunks = [items[k:k + chunk] for k in range(0, len(items), chunk)]
    n_workers = min(n_workers, len(chunks))  # no idle processes
    finished = len(done)
    synced = time.monotonic()

    def record(results: list[tuple[int, dict]]) -> None:
        nonlocal finished, synced
        for i, res in results:
            journal.write(i, res, sync_dir=False)
            assembly.offer(i, res)
            finished += 1
        if time.monotonic() - synced >= SYNC_EVERY:  # an fsync per batch of cases, at most every SYNC_EVERY
            journal.sync()
            synced = time.monotonic()
        if progress:
            progress(finished, spec.n_cases)
        assembly.advance(journal)

    try:
        _execute(base, cfg.source, spec, chunks, n_workers, client, record, tables)
    except BaseException:  # Ctrl-C, SIGTERM, a failure: what is journaled is made durable, then it goes on
        try:
            journal.sync()
        except OSError:
            pass
        raise
    journal.sync()
    return assembly


def _execute(base: str, source: str, spec: SweepSpec, chunks: list, n_workers: int, client,
             record: Callable[[list], None], tables: dict[str, bytes] | None = None) -> None:
    """Run the chunks on Dask, serially in this process, or in a local process pool; `record` each
    chunk's results as it finishes. tables: the CSV tables' bytes, sent with every chunk."""
    args = (base, source, tables or {})
    if client is not None:
        from distributed import as_completed

        with client:
            # a finished chunk's future is dropped once recorded, so that its results do not stay in memory
            pending = {client.submit(_run_chunk, *args, c, spec.analysis, spec.n_modes, pure=False) for c in chunks}
            try:
                for fut in as_completed(list(pending)):
                    pending.discard(fut)
                    record(fut.result())
            finally:
                client.cancel(list(pending))
        return
    if n_workers == 1:
        for c in chunks:
            record(_run_chunk(*args, c, spec.analysis, spec.n_modes))
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed as cf_completed

    pool = ProcessPoolExecutor(max_workers=n_workers, mp_context=mp.get_context("fork"),
                               initializer=_worker_init, initargs=(os.getpid(),))
    try:
        # only as_completed holds the futures, and drops each as it yields it: a chunk's results are
        # not kept in memory once recorded
        for fut in cf_completed([pool.submit(_run_chunk, *args, c, spec.analysis, spec.n_modes) for c in chunks]):
            record(fut.result())
            del fut
    except BaseException:  # Ctrl-C, SIGTERM, a journal write error: stop the workers, keep the journal
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True)


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity, else the core count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


_PR_SET_PDEATHSIG = 1


def _worker_init(parent_pid: int) -> None:
    """In each forked worker: die with the parent, leave Ctrl-C and the journal lock to the parent."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C reaches the whole group
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # the parent's Python handler is inherited by fork
    for fd in list(_HELD_LOCKS):  # the flock is the parent's: a worker must not keep it alive
        try:
            os.close(fd)
        except OSError:
            pass
    _HELD_LOCKS.clear()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


def _stop_pool(pool) -> None:
    """Kill the workers (running chunks are lost, not journaled), reap them and shut the pool down.
    The futures are not cancelled here: the pool marks them broken itself (cancelling them first makes
    Python 3.11's pool thread fail with InvalidStateError and print its traceback)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    for proc in procs:
        proc.join(timeout=5)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=5)
    # A worker killed while sending its (large) result leaves a partial message in the result pipe, and
    # the pool's thread would wait for the rest forever (and the interpreter's exit with it): close
    # the parent's write end (only the dead workers wrote to it), so that it reads end-of-file instead.
    queue = getattr(pool, "_result_queue", None)
    writer = getattr(queue, "_writer", None)
    if writer is not None:
        try:
            writer.close()
        except OSError:
            pass
    pool.shutdown(wait=True)


# ------------------------------------------------------------------------------------ assembly
@dataclass(frozen=True, kw_only=True)
class SweepResult:
    spec: SweepSpec
    values: list[tuple]  # per case
    failed: np.ndarray  # (n_cases,) int8
    errors: list[str]
    wall_time: np.ndarray  # (n_cases,) s
    frequency: np.ndarray | None  # (n_cases, n_track) Hz, tracked
    kind: np.ndarray | None  # (n_cases, n_track) str
    order: np.ndarray | None
    span: np.ndarray | None
    label: np.ndarray | None  # (n_track,) labels at the first case
    mac: np.ndarray | None  # (n_cases, n_track) MAC with the parent's tracked mode (1 for the root)
    extras: dict[str, np.ndarray]  # per-case static / transient quantities (n_cases, ...)
    growth_rate: np.ndarray | None = None  # (n_cases, n_track) 1/s, tracked (> 0: divergence or flutter)


_MODAL_KEYS = ("frequency", "growth_rate", "shapes", "mshapes", "kind", "order", "span", "label")
_NOT_EXTRA = ("failed", "error", "wall_time", *_MODAL_KEYS)


class Assembly:
    """The /sweep results, built case by case in index order while the sweep runs.

    `offer` takes each finished case as it arrives (any order); `advance` assembles the cases from the
    next one on as far as they are there, from memory or else from the journal (the cases of an earlier
    run, or those arrived too far ahead of the next, of which only the index is kept: at most BUFFER
    cases wait whole in memory). Only the small per-case quantities are kept for every case; mode
    shapes are kept only while a later case may still be tracked from them: a case is tracked from its
    nearest tracked ancestor in the spanning tree of the grid (SweepSpec.parent, past failed cases), so
    a case's shapes are dropped once every case that can reach it that way is assembled (`_refs`
    counts those still to come). Between cases, at most one case per swept parameter is held (the
    last case, and the first of each line still to be continued), whatever the number of cases."""

    BUFFER = 64

    def __init__(self, spec: SweepSpec) -> None:
        n = spec.n_cases
        self.spec = spec
        self.next = 0
        self.failed = np.zeros(n, dtype=np.int8)
        self.errors = [""] * n
        self.wall = np.zeros(n)
        self.extras: dict[str, np.ndarray] | None = None  # from the first case that did not fail
        self.label: np.ndarray | None = None
        self._waiting: dict[int, dict] = {}
        self.modal = spec.analysis == "modal"
        if self.modal:
            k = spec.n_modes
            self.frequency = np.full((n, k), np.nan)
            self.growth = np.full((n, k), np.nan)
            self._kind = np.zeros((n, k), dtype=np.int16)  # codes into _kind_names (0: "")
            self._kind_names: list[str] = ["", "lost"]
            self.order = np.zeros((n, k), dtype=np.int64)
            self.span = np.zeros((n, k), dtype=np.int64)
            self.mac = np.full((n, k), np.nan)
            self._parent = spec.parents()
            self._children = np.bincount(self._parent[1:], minlength=n).astype(np.int64) if n > 1 \
                else np.zeros(n, dtype=np.int64)
            self._rep = np.full(n, -1, dtype=np.int64)  # nearest tracked ancestor-or-self of an assembled case
            self._refs = np.zeros(n, dtype=np.int64)  # cases still to come that will be tracked from this one
            self._kept: dict[int, dict] = {}  # tracked cases whose shapes may still be needed (and their pick)
            self._last = -1  # the last tracked case (a case without a tracked ancestor is tracked from it)

    @property
    def held(self) -> int:
        """Cases whose mode shapes are in memory (waiting or kept for tracking)."""
        return len(self._waiting) + (len(self._kept) if self.modal else 0)

    def offer(self, index: int, case: dict) -> None:
        if index >= self.next and len(self._waiting) < self.BUFFER:
            self._waiting[index] = case

    def advance(self, journal: "Journal") -> None:
        n = self.spec.n_cases
        while self.next < n:
            i = self.next
            case = self._waiting.pop(i, None)
            if case is None:
                if not journal.has(i):
                    return
                case = journal.read(i)
            self._add(i, case)
            self.next += 1

    def _add(self, i: int, c: dict) -> None:
        failed = int(c["failed"])
        self.failed[i] = failed
        self.errors[i] = str(c["error"])
        self.wall[i] = float(c["wall_time"])
        if not failed:
            if self.extras is None:
                n = self.spec.n_cases
                self.extras = {key: np.full((n, *np.shape(c[key])), np.nan) for key in c if key not in _NOT_EXTRA}
            for key, arr in self.extras.items():
                if key in c:
                    arr[i] = c[key]
        if self.modal:
            self._track(i, c, failed)

    def _track(self, i: int, c: dict, failed: int) -> None:
        """MAC tracking of case i from its nearest tracked ancestor (else the last tracked case)."""
        from scipy.optimize import linear_sum_assignment

        parent = self._parent[i]
        anc = int(self._rep[parent]) if parent >= 0 else -1
        if failed:
            self._rep[i] = anc
            if anc >= 0:  # this case's children will be tracked from its ancestor
                self._refs[anc] += self._children[i]
        else:
            k = self.spec.n_modes
            p = anc if anc >= 0 else self._last
            m = len(c["frequency"])
            if p < 0:
                sel = np.arange(k) if m >= k else np.r_[np.arange(m), np.full(k - m, -1)]
                macs = np.where(sel >= 0, 1.0, np.nan)
            else:
                cp = self._kept[p]
                prev = cp["sel"]
                alive = np.flatnonzero(prev >= 0)
                if cp["shapes"].shape[1] == c["shapes"].shape[1]:
                    # MAC_ij = |(phi_p^H M_c phi_c)(phi_c^H M_p phi_p)|: the usual MAC when the mass
                    # matrices are equal, insensitive to a change of mass scale between the cases, and to
                    # the phase of complex (running-belt) shapes
                    M = np.abs((np.conj(cp["shapes"][prev[alive]]) @ c["mshapes"].T)
                               * (cp["mshapes"][prev[alive]] @ np.conj(c["shapes"]).T))
                else:  # different meshes: match by classification, then frequency
                    M = np.zeros((len(alive), m))
                    for a, j in enumerate(prev[alive]):
                        for b in range(m):
                            same = (cp["kind"][j] == c["kind"][b] and cp["order"][j] == c["order"][b]
                                    and cp["span"][j] == c["span"][b])
                            M[a, b] = (1.0 if same else 0.0) + 1e-3 / (1.0 + abs(cp["frequency"][j] - c["frequency"][b]))
                rows, cols = linear_sum_assignment(-M)
                sel = np.full(k, -1, dtype=np.int64)
                macs = np.full(k, np.nan)
                for r, col in zip(rows, cols):
                    if M[r, col] >= MAC_LOST:  # else the mode left the computed window: lost from here on
                        sel[alive[r]] = col
                        macs[alive[r]] = M[r, col]
            ok = sel >= 0
            self.frequency[i, ok] = c["frequency"][sel[ok]]
            if "growth_rate" in c:
                self.growth[i, ok] = c["growth_rate"][sel[ok]]
            self._kind[i, ok] = [self._kind_code(str(x)) for x in c["kind"][sel[ok]]]
            self._kind[i, ~ok] = 1  # "lost"
            self.order[i, ok] = c["order"][sel[ok]]
            self.span[i, ok] = c["span"][sel[ok]]
            self.mac[i, ok] = np.minimum(macs[ok], 1.0)
            if self.label is None:
                self.label = np.array(c["label"][:k])
            self._rep[i] = i
            self._refs[i] += self._children[i]
            self._kept[i] = {key: c[key] for key in ("shapes", "mshapes", "kind", "order", "span", "frequency")}
            self._kept[i]["sel"] = sel
            last, self._last = self._last, i
            if last >= 0:
                self._release(last)
        if anc >= 0:  # this case no longer needs its ancestor
            self._refs[anc] -= 1
            self._release(anc)
        if not failed:
            self._release(i)

    def _kind_code(self, name: str) -> int:
        try:
            return self._kind_names.index(name)
        except ValueError:
            self._kind_names.append(name)
            return len(self._kind_names) - 1

    @property
    def kind(self) -> np.ndarray:
        """(n_cases, n_track) object array of str: a case's tracked modes' classification ("" for a
        failed case, "lost" for a mode that left the computed window), one shared str per kind (the
        codes are kept per case: 2 bytes a mode instead of a string object)."""
        return np.array(self._kind_names, dtype=object)[self._kind]

    def _release(self, j: int) -> None:
        if self._refs[j] <= 0 and j != self._last:
            self._kept.pop(j, None)

    def result(self) -> "SweepResult":
        spec, n = self.spec, self.spec.n_cases
        if self.next < n:
            raise OutputError(f"the sweep is not complete: case {self.next + 1} of {n} is not journaled")
        modal = self.modal
        label = self.label if self.label is not None else np.array([])
        return SweepResult(spec=spec, values=[spec.case_values(i) for i in range(n)], failed=self.failed,
                           errors=self.errors, wall_time=self.wall,
                           frequency=self.frequency if modal else None, kind=self.kind if modal else None,
                           order=self.order if modal else None, span=self.span if modal else None,
                           label=label if modal else None, mac=self.mac if modal else None,
                           extras=self.extras or {}, growth_rate=self.growth if modal else None)


def assemble(spec: SweepSpec, journal: Journal, assembly: Assembly | None = None) -> SweepResult:
    """The sweep's results: those assembled while it ran (`run_sweep` returns its Assembly) completed
    from the journal, or all of them streamed from the journal, one case at a time."""
    if assembly is None or assembly.spec != spec:
        assembly = Assembly(spec)
    assembly.advance(journal)
    return assembly.result()


# ------------------------------------------------------------------------------------ convergence
def richardson(frequency: np.ndarray, elements: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per mode: extrapolated frequency, error estimate of each mesh, observed order.

    frequency (n_mesh, n_mode) on meshes with elements per span `elements` (increasing). With
    h = 1/elements, the observed order p from the three finest meshes (capped to [1, 4], 4 being the
    order of cubic Hermite elements for eigenfrequencies, so the estimate is never optimistic), then
    f_inf = f_n + (f_n - f_{n-1}) / (r^p - 1) and the estimate of mesh k is
    SAFETY * |f_k - f_inf| / f_inf with Roache's three-grid safety factor 1.25 (grid convergence index).
    """
    f = np.asarray(frequency, dtype=float)
    e = np.asarray(elements, dtype=float)
    n_mesh, n_mode = f.shape
    order = np.full(n_mode, 4.0)
    if n_mesh >= 3:
        r1, r2 = e[-2] / e[-3], e[-1] / e[-2]
        d1, d2 = f[-2] - f[-3], f[-1] - f[-2]
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.log(np.abs(d1 / d2)) / np.log(0.5 * (r1 + r2))
        order = np.where(np.isfinite(p), np.clip(p, 1.0, 4.0), 4.0)
    if n_mesh >= 2:
        r = e[-1] / e[-2]
        f_inf = f[-1] + (f[-1] - f[-2]) / (r ** order - 1.0)
    else:
        f_inf = f[-1].copy()
    est = SAFETY * np.abs(f - f_inf) / np.abs(f_inf)
    return f_inf, est, order


# ------------------------------------------------------------------------------------ --rtol
@dataclass(frozen=True, kw_only=True)
class Refinement:
    """Meshes tried (elements per span), tracked frequencies (n_mesh, n_modes), error estimates, choice."""

    elements: np.ndarray
    frequency: np.ndarray
    estimate: np.ndarray
    order: np.ndarray
    labels: tuple[str, ...]
    chosen: int  # index into elements
    converged: bool


def _keys(md) -> list[tuple]:
    return [(md.kind[k], int(md.order[k]), int(md.span[k])) for k in range(len(md.frequency))]


def refine_mesh(cfg: DriveConfig, *, n_modes: int, rtol: float, max_elements: int = 640):
    """Double elements_per_span from the configured mesh until the Richardson error estimate of each
    of the first n_modes modes (matched by kind, order and span) is <= rtol; return the cheapest mesh
    whose estimate meets it, with its model, static and modal results, and the Refinement record.
    At least three meshes are computed, so that the estimate rests on an observed order."""
    from beltdyn.config import with_overrides
    from beltdyn.pipeline import analyse

    n_el = cfg.mesh.elements_per_span
    runs, elements = [], []
    while True:
        c = with_overrides(cfg, [f"mesh.elements_per_span={n_el}"])
        run = analyse(c, modal=True, n_modes=n_modes + 6)
        md = run.modal
        runs.append((c, run.system, run.static, md))
        elements.append(n_el)
        # the modes wanted are the first n_modes of the finest mesh; coarser meshes matched by label
        ref_keys = _keys(md)[:n_modes]
        labels = tuple(md.label[:n_modes])
        f = np.full((len(runs), n_modes), np.nan)
        for i, run in enumerate(runs):
            keys = _keys(run[3])
            for j, key in enumerate(ref_keys):
                if key in keys:
                    f[i, j] = run[3].frequency[keys.index(key)]
        if len(elements) >= 3 and np.all(np.isfinite(f[-3:])):  # three meshes: an observed order
            f_inf, est, p = richardson(f, np.array(elements, dtype=float))
            if np.all(est[-1] <= rtol):
                ok = [i for i in range(len(elements)) if np.all(est[i] <= rtol)]
                i = ok[0]
                ref = Refinement(elements=np.array(elements), frequency=f, estimate=est, order=p, labels=labels,
                                 chosen=i, converged=True)
                return runs[i], ref
        if 2 * n_el > max_elements:
            est = richardson(f, np.array(elements, dtype=float))[1] if len(elements) >= 2 else np.full_like(f, np.nan)
            ref = Refinement(elements=np.array(elements), frequency=f, estimate=est, order=np.full(n_modes, np.nan),
                             labels=labels, chosen=len(elements) - 1, converged=False)
            return runs[-1], ref
        n_el *= 2
