"""`beltdyn report`: the drive report of a results file, one self-contained HTML page."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from beltdyn.cli.console import console, print_notes
from beltdyn.cli.failures import guarded


def report(result: Path = typer.Argument(..., help="A beltdyn results file (HDF5)."),
           output: Optional[Path] = typer.Option(None, "-o", "--output",
                                                 help="Report file (.html) [default: RESULT with .html]")) -> None:
    """The drive report: one self-contained HTML page (figures inline, no script, printable on A4) of
    what the results file holds (needs the plot extra: pip install 'beltdyn[plot]')."""

    def body() -> None:
        from beltdyn.errors import ConfigError

        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ConfigError("matplotlib is not installed: pip install 'beltdyn[plot]'", file=str(result),
                              key="report") from None
        from beltdyn.report import write_report
        from beltdyn.results.io import recover

        print_notes(recover(result, if_free=True))  # a killed writer's group: recovered, as by any command
        console().print(f"wrote {write_report(result, output)}")

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(report)
