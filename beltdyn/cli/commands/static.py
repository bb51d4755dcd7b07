"""`beltdyn static`: the nonlinear static equilibrium."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job, announce_cost, choose_spans, ladder_not_met, static_pipeline
from beltdyn.cli.options import ConfigArg, FmaxOpt, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.tables import print_static


def static(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
           unset: Optional[List[str]] = UnsetOpt,
           force: bool = ForceOpt, fmax: Optional[float] = FmaxOpt,
           rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                                help="With --fmax: the relative tolerance of the span choice.")) -> None:
    """Nonlinear static equilibrium: span tensions, hub loads, solved pulley positions."""

    def body() -> None:
        job = Job(config, output, overrides(set_, unset), force)
        choose_spans(job, fmax, rtol, command="static")
        announce_cost(job.cfg)
        run = static_pipeline(job, modal=False)
        print_static(run.layout, run.system, run.static)
        console().print(f"wrote [bold]/geometry /static[/] to {job.output}")
        ladder_not_met(job)

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(static)
