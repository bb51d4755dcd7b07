"""Signals: SIGINT and SIGTERM end a command like Ctrl-C (atomic writes discarded, a transient's samples
and a sweep's journal kept), and can be held back over a block that must not be cut (numba's compiler).

`STATE["signal"]`: the SIGINT / SIGTERM received during the current command, if any."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager

from beltdyn.errors import Terminated

STATE: dict = {"signal": None}


def on_sigterm(signum, frame) -> None:
    STATE["signal"] = signum
    raise Terminated()


def on_sigint(signum, frame) -> None:
    STATE["signal"] = signum
    raise KeyboardInterrupt


def interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM that `exc` stands for: exc itself if it is one; once either signal has arrived,
    any other exception too, as the library the handler's KeyboardInterrupt went through turned it into
    its own error (pybind11 reports one inside a module's initialization as ImportError "initialization
    failed": a sweep interrupted while scipy imported); else None."""
    if isinstance(exc, KeyboardInterrupt):
        return exc
    if STATE["signal"] is None:
        return None
    return Terminated() if STATE["signal"] == signal.SIGTERM else KeyboardInterrupt()


def install() -> None:
    """The handlers for the command about to run (SIGINT only where nobody ignores it); no signal so far."""
    STATE["signal"] = None
    try:
        signal.signal(signal.SIGTERM, on_sigterm)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # (not where the caller ignores it)
            signal.signal(signal.SIGINT, on_sigint)
    except ValueError:  # not the main thread (e.g. called from a test harness)
        pass


@contextmanager
def held_back() -> Iterator[None]:
    """Ctrl-C and SIGTERM deferred until the block is done, then raised (Terminated or KeyboardInterrupt)
    as if they arrived then (a signal inside numba's compiler was lost, or left a half-written cache entry)."""
    got: list = []
    olds = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            olds[sig] = signal.signal(sig, lambda signum, frame: got.append(signum))
        except ValueError:  # not the main thread
            pass
    try:
        yield
    finally:
        for sig, handler in olds.items():
            signal.signal(sig, handler)
    if signal.SIGTERM in got:
        raise Terminated()
    if got:
        raise KeyboardInterrupt
