"""beltdyn's own cleanup list: what must happen before the process ends (a results-file lock released).

`at_exit(callback)` adds a callback; `run_all()` runs every one added so far, newest first, once each.
The list runs at the interpreter's normal exit (one `atexit.register` of `run_all`, done on the first
`at_exit`) and is what the console script runs itself before it ends the process quickly with
`os._exit` (`beltdyn.cli.main.run`), where the interpreter's own exit handlers are skipped.
"""

from __future__ import annotations

import atexit
from collections.abc import Callable

_CALLBACKS: list[Callable[[], None]] = []  # the list itself; run_all empties it
_registered = False  # run_all registered with atexit


def at_exit(callback: Callable[[], None]) -> None:
    """Run `callback` (no arguments) before the process ends."""
    _CALLBACKS.append(callback)
    global _registered
    if not _registered:
        atexit.register(run_all)
        _registered = True


def run_all() -> None:
    """Every callback added so far, newest first, each once (an exception of one does not stop the rest;
    the first is re-raised at the end)."""
    first: BaseException | None = None
    while _CALLBACKS:
        callback = _CALLBACKS.pop()
        try:
            callback()
        except BaseException as exc:  # noqa: BLE001 - the others still run
            first = first or exc
    if first is not None:
        raise first
