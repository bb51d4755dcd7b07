"""`beltdyn response`: the steady forced response over speed and engine orders."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job, failed_group, static_pipeline
from beltdyn.cli.options import ConfigArg, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.tables import print_response


def response(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
             unset: Optional[List[str]] = UnsetOpt,
             force: bool = ForceOpt) -> None:
    """Steady forced response over driver speed and engine orders: amplitudes and phases of tensions,
    hub loads, pulley and arm angles, mid-span displacements (the drive linearized about its static
    equilibrium; one complex solve per frequency)."""

    def body() -> None:
        job = Job(config, output, overrides(set_, unset), force)
        cfg = job.cfg
        if cfg.response is None:
            from beltdyn.errors import ConfigError

            raise ConfigError("no [response] table: add one (speed range, orders, [[response.excitation]])",
                              file=cfg.source, key="response")
        run = static_pipeline(job, modal=False)
        from beltdyn.errors import SolverError
        from beltdyn.results.export import response_group
        from beltdyn.pipeline import response_of

        try:
            res = response_of(cfg, run)
        except SolverError as exc:
            job.add(failed_group("response", exc))
            job.write()
            raise
        job.add(response_group(run.system, res))
        job.write()
        print_response(console(), res)
        console().print(f"wrote [bold]/geometry /static /response[/] to {job.output}")

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(response)
