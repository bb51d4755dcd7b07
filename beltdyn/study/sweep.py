"""Parameter sweeps: grids of cases run in parallel, journaled as they finish, modes tracked by MAC.

The jobs live in their own modules: the parameter grid and specs (`grid`), one case (`cases`), the local
worker processes (`pool`), the journal and --resume (`journal`), mode tracking by MAC and assignment
(`tracking`), the assembly of the results (`assembly`), mesh refinement with Richardson estimates
(`refine`). This module runs a sweep (`run_sweep`): the missing cases on a Dask cluster, serially in this
process, or on beltdyn's own local workers (at most one per available core), each journaled and
assembled as it finishes; the public names of the other modules are importable from here too.
"""

from __future__ import annotations

import math
import time
from typing import Callable


from beltdyn.config import DriveConfig, resolved_toml
from beltdyn.errors import ConfigError

from beltdyn.study.assembly import Assembly, Column, SweepResult, assemble, static_columns
from beltdyn.study.cases import load_case_modules, run_case, run_chunk
from beltdyn.study.grid import (ANALYSES, Param, SweepSpec, case_assignments, make_spec, merge_params, parse_values,
                                spec_hash, sweep_tables)
from beltdyn.study.journal import Journal
from beltdyn.study.pool import available_cores, run_pool
from beltdyn.study.refine import Refinement, refine_mesh, richardson
from beltdyn.study.tracking import MAC_LOST

__all__ = ["ANALYSES", "MAC_LOST", "Assembly", "Column", "Journal", "Param", "Refinement", "SweepResult", "SweepSpec",
           "assemble", "available_cores", "case_assignments", "make_spec", "merge_params", "parse_values", "refine_mesh",
           "richardson", "run_case", "run_sweep", "spec_hash", "static_columns", "sweep_tables"]

SYNC_EVERY = 0.5  # s: the journal is fsync'ed after a batch of cases at most this often (and at the end)

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


Progress = Callable[[int, int], None]


def run_sweep(cfg: DriveConfig, spec: SweepSpec, *, journal: Journal, resume: bool = False,
              workers: int | None = None, scheduler: str | None = None,
              progress: Progress | None = None, restart: bool = False,
              on_resume: Callable[[int, int], None] | None = None) -> "Assembly":
    """Run the missing cases of the sweep, journaling each as it finishes (any order), and assemble
    the results as they come (the returned Assembly, for `assemble`). restart discards an existing
    journal (--force without --resume). on_resume(reused, n_cases): called once a resumed sweep's journal
    is accepted, with the number of its finished cases that are reused (not recomputed)."""
    digest = spec_hash(cfg, spec)
    client = _connect(scheduler, cfg) if scheduler else None
    if journal.exists() and restart and not resume:
        journal.remove()
    resumed = journal.exists()
    if resumed:
        if not resume:
            raise ConfigError(f"an unfinished sweep is journaled in {journal.dir}: continue it with --resume "
                              f"(or remove the folder)", file=cfg.source, key="--resume")
        if journal.digest() != digest:
            raise ConfigError(f"{journal.dir} belongs to a different sweep or configuration; remove it to start over",
                              file=cfg.source, key="--resume")
    else:
        journal.start(spec.to_json(), digest)
    done = journal.done()
    if resume and on_resume is not None and resumed:
        on_resume(len(done), spec.n_cases)
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
    """Run the chunks on Dask, serially in this process, or on local worker processes; `record` each
    chunk's results as it finishes. tables: the CSV tables' bytes, sent with every chunk."""
    args = (base, source, tables or {})
    if client is not None:
        from distributed import as_completed

        with client:
            # a finished chunk's future is dropped once recorded, so that its results do not stay in memory
            pending = {client.submit(run_chunk, *args, c, spec.analysis, spec.n_modes, pure=False) for c in chunks}
            try:
                for fut in as_completed(list(pending)):
                    pending.discard(fut)
                    record(fut.result())
            finally:
                client.cancel(list(pending))
        return
    if n_workers == 1:
        for c in chunks:
            record(run_chunk(*args, c, spec.analysis, spec.n_modes))
        return
    # beltdyn's own worker processes (`pool.run_pool`): each chunk's results recorded as they arrive and
    # then dropped; on Ctrl-C, SIGTERM or a journal write error the workers are stopped, the journal kept.
    # The workers are forked with the cases' modules already imported (`load_case_modules`).
    load_case_modules(spec.analysis)
    run_pool(run_chunk, [(*args, c, spec.analysis, spec.n_modes) for c in chunks], n_workers, record)
