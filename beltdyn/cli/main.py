"""The typer app (its callback: --version, --debug), every command of `beltdyn.cli.commands` added to
it, and `run`, the `beltdyn` console script."""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys

import typer

from beltdyn import __version__, cleanup
from beltdyn.cli import commands
from beltdyn.cli.failures import STATE

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Dynamics of belt drives: ANCF belt spans on rigid pulleys.\n\n"
    "Exit codes: 0 ok, 1 solver failure, I/O failure (a full disk) or internal error, 2 bad configuration or "
    "usage, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).",
)


def show_version(value: bool) -> None:
    if value:
        typer.echo(f"beltdyn {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=show_version, is_eager=True, help="Print the version."),
    debug: bool = typer.Option(False, "--debug", help="Show the Python traceback of an internal error."),
) -> None:
    """beltdyn command-line tool."""
    STATE["debug"] = debug


def command_modules() -> list[str]:
    """The modules of `beltdyn.cli.commands`, by name (each adds one command)."""
    return sorted(m.name for m in pkgutil.iter_modules(commands.__path__))


for _name in command_modules():
    importlib.import_module(f"{commands.__name__}.{_name}").register(app)


def _children_alive() -> bool:
    """Whether a process this one started through `multiprocessing` still runs (finished ones reaped)."""
    mp = sys.modules.get("multiprocessing")
    return mp is not None and bool(mp.active_children())


def run() -> None:
    """The app, then a quick exit (what the `beltdyn` console script, `beltdyn.cli.run`, runs once it
    has set the garbage collector's threshold). The interpreter's teardown (freeing
    every module numba, scipy and h5py loaded) takes ~0.2 s of a short command; it is skipped once the
    command is over: output flushed, beltdyn's own cleanup list run (`beltdyn.cleanup`: results-file
    locks released; the results files are closed by then), no other thread alive and no child process
    (`multiprocessing.active_children`: a sweep's workers are joined by `study.pool.run_pool` before it
    returns; a child still running takes the normal exit, whose handlers join it). Measured: a sweep's
    normal exit took 0.4-0.6 s after its last output. The exit code is the app's."""
    import threading

    code: int | str | None = 0
    try:
        app()
    except SystemExit as exc:
        code = exc.code
    if threading.active_count() > 1 or _children_alive():  # the normal way, every exit handler
        sys.exit(code)
    if code is not None and not isinstance(code, int):  # sys.exit("message"): printed, exit 1
        print(code, file=sys.stderr)
        code = 1
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed pipe: nothing more to say
        pass
    cleanup.run_all()
    os._exit(code or 0)
