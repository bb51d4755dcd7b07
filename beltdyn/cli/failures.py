"""Error handling and exit codes: a command's body runs inside `guarded`.

Exit codes: 0 ok, 1 solver failure, I/O failure or internal error, 2 bad configuration or usage, 130
interrupted (Ctrl-C), 143 terminated (SIGTERM). No traceback: an unexpected exception is one line naming
its type (the traceback only with `beltdyn --debug COMMAND ...`).
"""

from __future__ import annotations

import sys

import typer

from beltdyn.cli.console import console, one_line
from beltdyn.cli.signals import install, interruption

STATE: dict = {"debug": False}  # --debug: the traceback of an internal error

# POSIX convention: 128 + signal number
EXIT_INTERRUPTED = 130  # SIGINT (Ctrl-C)
EXIT_TERMINATED = 143  # SIGTERM


def fail(exc: BaseException) -> None:
    from rich.text import Text

    from beltdyn.errors import BeltdynError, Terminated

    err = console(stderr=True)
    exc = interruption(exc) or exc
    if isinstance(exc, KeyboardInterrupt):
        what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        err.print(Text.assemble((what, "bold red"), ": finished groups are unchanged; a running transient keeps "
                                "its samples so far, marked 'interrupted'"))
        raise typer.Exit(EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED)
    if isinstance(exc, BeltdynError):
        said = "; ".join([str(exc), *getattr(exc, "__notes__", ())])  # (a note: what closing the output did)
        err.print(Text.assemble(("error", "bold red"), f": {one_line(said)}"))
        raise typer.Exit(exc.exit_code)
    if STATE["debug"]:
        import traceback

        traceback.print_exception(exc, file=sys.stderr)
    hint = "" if STATE["debug"] else "; rerun with --debug for the traceback"
    err.print(Text.assemble(("internal error", "bold red"), f": {type(exc).__name__}: {one_line(str(exc))}; please "
                            f"file it with the command line and config{hint}"))
    raise typer.Exit(1)


def out_of_memory(detail: str) -> None:
    from rich.text import Text

    detail = f" ({one_line(detail)})" if detail else ""
    console(stderr=True).print(Text.assemble(
        ("error", "bold red"), f": out of memory{detail}; the model is too large for this machine: use a smaller "
        "mesh.elements_per_span (e.g. --set mesh.elements_per_span=40), fewer modes or fewer sweep --workers"))
    raise typer.Exit(1)




def guarded(body) -> None:
    """Run a command's body: a BeltdynError is one line and its exit code; Ctrl-C exit 130 and SIGTERM
    (handled like Ctrl-C: atomic writes discarded, a transient's samples and a sweep's journal kept)
    exit 143; anything else is an internal error, one line and exit 1 (the traceback with --debug)."""
    install()
    import rich.console  # noqa: F401 - loaded before the body, so the handlers below need no memory to import
    import rich.text  # noqa: F401

    from beltdyn import errors  # noqa: F401

    memory_error = None
    try:
        body()
    except typer.Exit:
        raise
    except MemoryError as exc:
        if STATE["debug"]:
            import traceback

            try:
                traceback.print_exception(exc, file=sys.stderr)
            except MemoryError:
                pass
        memory_error = str(exc)  # leaving this block frees the frames, and the memory they hold
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - the top-level handler
        fail(exc)
    if memory_error is not None:
        import gc

        gc.collect()
        out_of_memory(memory_error)

