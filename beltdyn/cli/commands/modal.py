"""`beltdyn modal`: the modes about the static equilibrium (or with --rtol a mesh refined until they converge)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job, add_results, announce_cost, choose_spans, ladder_not_met, refined_modal, static_pipeline
from beltdyn.cli.options import ConfigArg, FmaxOpt, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.tables import print_modal, print_static, print_unrepresented


def modal(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
          unset: Optional[List[str]] = UnsetOpt,
          force: bool = ForceOpt,
          modes: Optional[int] = typer.Option(None, "--modes", min=1, help="Number of elastic modes [default: modal.modes]."),
          rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                               help="Refine mesh.elements_per_span (doubling) until the modes' estimated relative error is below RTOL; the cheapest such mesh is used. With --fmax: the tolerance of the span choice."),
          fmax: Optional[float] = FmaxOpt) -> None:
    """Natural frequencies and classified mode shapes about the static equilibrium."""

    def body() -> None:
        job = Job(config, output, overrides(set_, unset), force)
        if rtol is not None and fmax is None:
            refined_modal(job, modes or job.cfg.modal.modes, rtol)
            return
        chosen = choose_spans(job, fmax, rtol, command="modal")
        if chosen is not None:  # the choice solved the chosen drive already
            from beltdyn.results.export import geometry_group

            job.add(geometry_group(job.layout))
            add_results(job, chosen)
            job.write()
            run = chosen
        else:
            announce_cost(job.cfg)
            run = static_pipeline(job, modal=True, n_modes=modes)
        print_static(run.layout, run.system, run.static)
        print_modal(run.modal)
        print_unrepresented(job)
        console().print(f"wrote [bold]/geometry /static /modal[/] to {job.output}")
        ladder_not_met(job)

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(modal)
