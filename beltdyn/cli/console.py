"""The console: rich consoles for stdout and stderr, one-line messages, notes, warnings and the
spinner of a long wait. Everything the CLI prints goes through here (the library never prints)."""

from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from collections.abc import Iterator

PIPE_WIDTH = 1000  # console width when the output is not a terminal: tables at their natural width


def is_tty(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def console(stderr: bool = False):
    """The rich console: in a terminal its width; piped or captured (make, CI, a file) wide, so that no
    table is squeezed or cut (also when FORCE_COLOR makes rich treat the pipe as a terminal of 80
    columns). Table cells fold instead of ending in an ellipsis when a terminal is too narrow."""
    from rich.console import Console
    from rich.table import Table

    class _FoldingConsole(Console):
        def print(self, *objects, **kwargs) -> None:
            for obj in objects:
                if isinstance(obj, Table):
                    for column in obj.columns:
                        column.overflow = "fold"
            super().print(*objects, **kwargs)

    width = None if is_tty(sys.stderr if stderr else sys.stdout) else PIPE_WIDTH
    if stderr:
        return _FoldingConsole(stderr=True, highlight=False, soft_wrap=True, width=width)
    return _FoldingConsole(file=PipeSafe(), highlight=False, soft_wrap=True, width=width)


class PipeSafe:
    """stdout for the console that outlives its reader: when the pipe closes (`beltdyn ... | head`), the
    rest of the output goes to /dev/null and the command finishes its work (results are written; exit
    status as without the pipe) instead of failing with BrokenPipeError."""

    def write(self, text: str) -> int:
        try:
            return sys.stdout.write(text)
        except BrokenPipeError:
            drop_stdout()
            return len(text)

    def flush(self) -> None:
        try:
            sys.stdout.flush()
        except BrokenPipeError:
            drop_stdout()

    def isatty(self) -> bool:
        return is_tty(sys.stdout)

    def fileno(self) -> int:
        return sys.stdout.fileno()

    @property
    def encoding(self) -> str:
        return getattr(sys.stdout, "encoding", "utf-8")


def drop_stdout() -> None:
    """Point stdout at /dev/null (its reader has gone; Python's final flush must not fail either)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    finally:
        os.close(devnull)


def one_line(text: str) -> str:
    """Line breaks and other control characters (from a quoted TOML key, a --set value) escaped."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)



def print_notes(notes: list[str]) -> None:
    """What the results modules did on their own (recovering a killed writer's group), on stderr."""
    from rich.text import Text

    for note in notes:
        console(stderr=True).print(Text.assemble(("note", "bold yellow"), f": {one_line(note)}"))



def warn(message: str, *, stderr: bool = False) -> None:
    """One warning line (bold yellow "warning:")."""
    console(stderr=stderr).print(f"[bold yellow]warning[/]: {message}")


def say_error(kind: str, message: str) -> None:
    """One error line on stderr: KIND (bold red): message (control characters escaped)."""
    from rich.text import Text

    console(stderr=True).print(Text.assemble((kind, "bold red"), f": {one_line(message)}"))


def plural(n: int, word: str, words: str | None = None) -> str:
    """'1 Newton iteration', '2 Newton iterations': n and the word in its number."""
    return f"{n} {word if n == 1 else (words or word + 's')}"


@contextmanager
def spinner(con, text: str) -> Iterator[None]:
    """A spinner with `text` and the elapsed time (h:mm:ss) on `con` in a terminal (rich's Progress);
    piped or captured, one line on stderr with `text` before and the time taken after (stdout keeps
    only the results)."""
    start = time.monotonic()
    if not con.is_terminal:
        err = console(stderr=True)
        err.print(f"note: {text} ...")
        yield
        err.print(f"note: done in {time.monotonic() - start:.0f} s")
        return
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=con,
                  transient=True) as bar:
        bar.add_task(text, total=None)
        yield
    con.print(f"{text}: done in {time.monotonic() - start:.0f} s")


def progress_bar(con, duration: float):
    """(context manager, update(t)) of the transient's progress bar: rich's in a terminal, nothing
    otherwise (piped or captured: not even its import)."""
    if not con.is_terminal:
        import contextlib

        return contextlib.nullcontext(), None
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    progress = Progress(TextColumn("transient"), BarColumn(), TextColumn("t = {task.completed:.4f} / {task.total:g} s"),
                        TimeRemainingColumn(), console=con, transient=True)
    task = progress.add_task("transient", total=duration)

    def update(t: float) -> None:
        progress.update(task, completed=t)

    return progress, update
