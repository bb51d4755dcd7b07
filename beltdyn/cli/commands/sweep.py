"""`beltdyn sweep`: a grid or zip of cases in parallel."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job
from beltdyn.cli.options import ConfigArg, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.signals import interruption
from beltdyn.cli.tables import print_campbell, print_sweep


def sweep(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
          unset: Optional[List[str]] = UnsetOpt,
          force: bool = ForceOpt,
          param: Optional[List[str]] = typer.Option(None, "--param", metavar="KEY=SPEC",
                                                    help="Swept key: a list 0.02,1,100; a range 100:600:26; a log range 0.02:100:9:log."),
          analysis: Optional[str] = typer.Option(None, "--analysis", help="static | modal | transient [default: modal]."),
          zip_: bool = typer.Option(False, "--zip", help="Zip the parameter lists instead of the grid product."),
          workers: Optional[int] = typer.Option(None, "--workers", min=1, help="Local processes [default: the core count]."),
          scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Dask distributed scheduler address."),
          resume: bool = typer.Option(False, "--resume", help="Continue an interrupted sweep from its journal."),
          modes: Optional[int] = typer.Option(None, "--modes", min=1, help="Tracked modes [default: modal.modes].")) -> None:
    """A grid (or zip) of cases in parallel, modes tracked across the grid by MAC."""

    def body() -> None:
        from beltdyn.study.sweep import Journal, assemble, available_cores, make_spec, merge_params

        job = Job(config, output, overrides(set_, unset), force)
        cfg = job.cfg
        params = []
        for item in param or []:
            if "=" not in item:
                from beltdyn.errors import ConfigError

                raise ConfigError("expected KEY=SPEC", file=cfg.source, key=f"--param {item}")
            k, v = item.split("=", 1)
            params.append((k.strip(), v.strip()))
        zip_flag = zip_
        kind = analysis
        overridden: tuple[str, ...] = ()
        if cfg.sweep is not None and cfg.sweep.params:  # --param overrides the file's table key by key
            params, overridden = merge_params(cfg.sweep.params, params)
        if cfg.sweep is not None:  # the table's analysis and zip are defaults for --analysis / --zip
            zip_flag = zip_flag or cfg.sweep.zip
            kind = kind or cfg.sweep.analysis
        spec = make_spec(cfg, params, analysis=kind or "modal", zip_=zip_flag, n_modes=modes)
        con = console()
        for k in overridden:
            con.print(f"note: --param {k} overrides [sweep.params] {k} of {cfg.source}", markup=False)
        if workers is not None and scheduler is None and workers > available_cores():
            con.print(f"note: --workers {workers} is more than the {available_cores()} available cores; "
                      f"using {available_cores()}")
        journal = Journal(job.output)
        with journal:  # exclusive: a second sweep on the same output is refused, not raced
            assembly = sweep_cases(con, cfg, spec, journal, resume=resume, workers=workers, scheduler=scheduler,
                                    force=force)
            result = assemble(spec, journal, assembly)
            from beltdyn.results.export import sweep_group

            job.add(sweep_group(cfg, result))
            job.write()
            journal.remove()
        print_sweep(con, result, [p.name for p in cfg.pulleys])
        print_campbell(con, cfg, result)
        if result.failed.all():
            from beltdyn.errors import SolverError

            raise SolverError(f"all {spec.n_cases} cases failed (first: {result.errors[0]})", analysis="sweep")
        con.print(f"wrote [bold]/sweep[/] ({spec.n_cases} cases, {int(result.failed.sum())} failed) to {job.output}")

    guarded(body)


def sweep_cases(con, cfg, spec, journal, *, resume, workers, scheduler, force):
    """Run the missing cases with a progress bar (their Assembly returned); on Ctrl-C / SIGTERM say
    what is journaled."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from beltdyn.errors import Terminated
    from beltdyn.study.sweep import run_sweep

    bar = Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(), console=con,
                   disable=not con.is_terminal, transient=True)
    task = bar.add_task("sweep", total=spec.n_cases)
    try:
        with bar:
            return run_sweep(cfg, spec, journal=journal, resume=resume, workers=workers, scheduler=scheduler,
                             progress=lambda k, n: bar.update(task, completed=k), restart=force,
                             on_resume=lambda k, n: con.print(f"resuming: {k} of {n} cases reused from {journal.dir}",
                                                              markup=False))
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - an interruption is told apart below
        stop = interruption(exc)
        if stop is None:
            raise
        n_done = len(journal.done()) if journal.exists() else 0
        what = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted"
        console(stderr=True).print(f"sweep {what}: {n_done} of {spec.n_cases} cases are journaled in "
                                    f"{journal.dir}; continue with --resume")
        if stop is exc:
            raise
        raise stop from exc


def register(app: typer.Typer) -> None:
    app.command()(sweep)
