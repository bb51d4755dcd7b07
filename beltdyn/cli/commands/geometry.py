"""`beltdyn geometry`: the L0 fit and the belt path."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job
from beltdyn.cli.options import ConfigArg, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.tables import print_geometry


def geometry(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
             unset: Optional[List[str]] = UnsetOpt,
             force: bool = ForceOpt) -> None:
    """Tangent points, spans, wrap angles, belt length and the L0 fit of the adjustable pulley."""

    def body() -> None:
        from beltdyn.results.export import geometry_group

        job = Job(config, output, overrides(set_, unset), force)
        layout = job.layout
        job.add(geometry_group(layout))
        job.write()
        print_geometry(layout)
        console().print(f"wrote [bold]/geometry[/] to {job.output}")

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(geometry)
