"""beltdyn's own pool of local worker processes for a sweep (issue 24: no executor internals).

`run_pool` forks `n_workers` processes (multiprocessing's public API: a "fork" context, `Process`, one
duplex `Pipe` per worker) and hands each one job at a time: a worker that sends back a result gets the
next job, until none is left. The parent thus knows its workers (their pids) and their state, and stops
them itself: on any exception in the parent (Ctrl-C, SIGTERM raised as `Terminated`, a journal write
error, a job that failed in a worker) every worker is terminated (SIGTERM, then SIGKILL after a grace
period) and reaped before the exception goes on; none outlives the sweep. A worker killed while it
sends a result only breaks its own pipe, which the parent no longer reads.

Each worker dies with its parent even when the parent is killed outright (SIGKILL): it asks the kernel
for SIGKILL when its parent dies (Linux `prctl(PR_SET_PDEATHSIG)`, through libc), ignores Ctrl-C (a
terminal sends it to the whole process group; the parent handles it), restores the default SIGTERM
action (fork copies the parent's Python handler) and closes the parent's lock descriptors (the journal's
flock is the parent's: a worker must not keep it alive).
"""

from __future__ import annotations

import os
import signal
import sys
from multiprocessing.connection import Connection, wait
from typing import Any, Callable

from beltdyn.results.io import HELD_LOCKS

PR_SET_PDEATHSIG = 1  # linux/prctl.h
STOP_GRACE = 5.0  # s a terminated worker gets before it is killed


class WorkerDied(RuntimeError):
    """A worker process ended without sending its job's result (killed, out of memory)."""


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity, else the core count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _die_with(parent_pid: int) -> None:
    """In a forked worker: SIGKILL when the parent dies, no Ctrl-C, the default SIGTERM, no parent locks."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    for fd in list(HELD_LOCKS):
        try:
            os.close(fd)
        except OSError:
            pass
    HELD_LOCKS.clear()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the request took effect
        os._exit(1)


def _serve(conn: Connection, parent_pid: int, task: Callable[..., Any]) -> None:
    """A worker's life: jobs (argument tuples) in, ("ok", result) or ("error", exception) out, until None."""
    _die_with(parent_pid)
    while True:
        try:
            job = conn.recv()
        except EOFError:  # the parent closed its end
            return
        if job is None:
            return
        try:
            reply = ("ok", task(*job))
        except Exception as exc:  # noqa: BLE001 - sent to the parent, which raises it
            reply = ("error", exc)
        conn.send(reply)


def stop_workers(workers: list) -> None:
    """Terminate the worker processes (SIGTERM, SIGKILL after STOP_GRACE s) and reap them."""
    for proc in workers:
        if proc.is_alive():
            proc.terminate()
    for proc in workers:
        proc.join(timeout=STOP_GRACE)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=STOP_GRACE)


def run_pool(task: Callable[..., Any], jobs: list[tuple], n_workers: int, on_result: Callable[[Any], None]) -> None:
    """Run task(*job) for every job in `n_workers` forked processes, one job per worker at a time, and
    call `on_result` in this process with each result as it arrives (any order). A job that raised in a
    worker raises here (the same exception); a worker that died raises WorkerDied. The workers are gone
    when this returns or raises."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    todo = list(reversed(jobs))  # popped from the end: in order
    workers, conns = [], {}
    try:
        for _ in range(min(n_workers, len(jobs))):
            parent_end, child_end = ctx.Pipe(duplex=True)
            proc = ctx.Process(target=_serve, args=(child_end, os.getpid(), task), daemon=True,
                               name=f"beltdyn-sweep-worker-{len(workers)}")
            proc.start()
            child_end.close()  # the worker's end lives in the worker only (its death closes the pipe)
            workers.append(proc)
            conns[parent_end] = proc
            parent_end.send(todo.pop())
        while conns:
            for conn in wait(list(conns)):
                proc = conns[conn]
                try:
                    status, value = conn.recv()
                except (EOFError, OSError):
                    proc.join(timeout=STOP_GRACE)
                    raise WorkerDied(f"sweep worker pid {proc.pid} died (exit code {proc.exitcode})") from None
                if status == "error":
                    raise value
                if todo:
                    conn.send(todo.pop())
                else:
                    conn.send(None)
                    del conns[conn]
                    conn.close()
                on_result(value)
                del value
    except BaseException:
        stop_workers(workers)
        for conn in conns:
            conn.close()
        raise
    for proc in workers:
        proc.join()
