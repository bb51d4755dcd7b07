"""`beltdyn transient`: the nonlinear time response, streamed into the results file (`beltdyn.workflow`)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from beltdyn.cli.console import console, print_notes, progress_bar, spinner, warn
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job, announce_cost, check_output_volume, choose_spans, ladder_not_met, static_pipeline
from beltdyn.cli.options import ConfigArg, FmaxOpt, ForceLargeOpt, ForceOpt, OutOpt, SetOpt, UnsetOpt, overrides
from beltdyn.cli.signals import held_back
from beltdyn.cli.tables import print_transient


def transient(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
              unset: Optional[List[str]] = UnsetOpt,
              force: bool = ForceOpt, force_large: bool = ForceLargeOpt,
              duration: Optional[float] = typer.Option(None, "--duration", min=0.0, help="Simulated time, s [default: transient.duration]."),
              step: Optional[float] = typer.Option(None, "--step", min=0.0, help="Time step, s, used as given [default: transient.step, or from transient.accuracy and fmax]."),
              fmax: Optional[float] = FmaxOpt,
              rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                                   help="With --fmax: the relative tolerance of the span choice."),
              resume: bool = typer.Option(False, "--resume",
                                          help="Continue the interrupted transient of the output (Ctrl-C, SIGTERM, "
                                               "kill -9) from its last checkpoint; the same configuration and "
                                               "options as the interrupted run."),
              checkpoint_every: Optional[float] = typer.Option(
                  None, "--checkpoint-every", min=0.0,
                  help="Wall time between checkpoints of the resume journal, s (0: after every step) "
                       "[default: workflow.CHECKPOINT_SECONDS, 1 s].")) -> None:
    """Nonlinear time response (generalized-alpha) with streamed histories and their spectra."""

    def body() -> None:
        sets = overrides(set_, unset)
        window = ""
        if duration is not None:
            moved = spectrum_window(config, sets, duration)
            if moved is not None:
                start, window = moved
                sets.append(f"transient.spectrum.start={start!r}")
            sets.append(f"transient.duration={duration!r}")
        if step is not None:
            sets.append(f"transient.step={step!r}")
        # --resume: the output's own configuration is checked against the resume journal below (not
        # refused here as a different file: the journal's message names both hashes)
        job = Job(config, output, sets, force or resume)
        cfg = job.cfg
        if cfg.transient is None:
            from beltdyn.errors import ConfigError

            raise ConfigError("no [transient] table: add one (duration, step, excitations)", file=cfg.source,
                              key="transient")
        from beltdyn.analysis.timestep import resolve_step

        resolved, origin = resolve_step(cfg.transient, manual=step)
        if resolved.step != cfg.transient.step:  # the chosen step goes into the resolved configuration
            job = Job(config, output, sets + [f"transient.step={resolved.step!r}"], force or resume)  # (provenance)
        job.step_origin = origin
        choose_spans(job, fmax, rtol, command="transient")
        if resume:  # before any work: a journal of this configuration, or exit 2
            from beltdyn.workflow import read_checkpoint

            read_checkpoint(job.output, job.sha, source=str(job.cfg.source))
        announce_cost(job.cfg, resolved)
        check_output_volume(job, force_large)
        spec_opts = cfg.transient.spectrum
        run = static_pipeline(job, modal=spec_opts.enabled)
        run_transient_command(job, run, (window,) if window else (), resume=resume,
                              checkpoint_seconds=checkpoint_every)
        ladder_not_met(job)

    guarded(body)


COMPILE_SECONDS = 120  # numba's first compile of the transient kernels: 20 s alone, up to 2 min on a busy 2-core machine


def warm_kernels(con) -> None:
    """Compile the transient kernels before any output file is opened when they are not in numba's
    cache yet (`jitcache.is_warm`), with a spinner and the elapsed time, and with Ctrl-C and SIGTERM
    held back until the compiler is done (`signals.held_back`). Cached kernels are loaded as the run
    first calls them."""
    from beltdyn import jitcache, pipeline
    from beltdyn.analysis.transient import entry_kernels

    if jitcache.is_warm(*entry_kernels()):
        return  # in numba's cache: loaded as the run first calls them (~0.2 s)
    with held_back(), spinner(con, "compiling the transient kernels, once (numba; up to "
                                   f"{COMPILE_SECONDS // 60} min on a busy machine; later runs load them from its cache)"):
        pipeline.warm_up()


def moved_start(start: float, configured: float, duration: float) -> float:
    """The start of the spectral window moved to the same fraction of a run of `duration` s as `start` is
    of the `configured` duration (`--duration` shorter than the window's start)."""
    return start * duration / configured


def spectrum_window(config: Path, sets: List[str], duration: float) -> tuple[float, str] | None:
    """With `--duration`: (the new transient.spectrum.start, the warning that says so) when the
    configuration's start is not before the end of the shorter run; None when it is, when spectra are
    off, or when `--set` gives the start itself (then the configuration's check speaks)."""
    if any(s.split("=", 1)[0].strip() == "transient.spectrum.start" for s in sets):
        return None
    from beltdyn.config import load_config

    t = load_config(config, sets).transient
    if t is None or not t.spectrum.enabled or t.spectrum.start < duration:
        return None
    start = moved_start(t.spectrum.start, t.duration, duration)
    return start, (f"--duration {duration:g} s ends before transient.spectrum.start = {t.spectrum.start:g} s: the "
                   f"spectral window is moved to start at {start:g} s, the same fraction "
                   f"({t.spectrum.start / t.duration:.3g}) of the run as in the configuration (set "
                   "transient.spectrum.start to choose it)")


def run_transient_command(job: Job, run, warnings: tuple[str, ...] = (), *, resume: bool = False,
                          checkpoint_seconds: float | None = None) -> None:
    """The transient of an analysed drive into the job's output (`workflow`), said on the console;
    `warnings` (the CLI's own, e.g. a moved spectral window) go with the step's to /transient `warnings`;
    resume: continue the output's interrupted transient from its last checkpoint; checkpoint_seconds: the
    wall time between its checkpoints (None: the workflow's default)."""
    from dataclasses import replace

    from beltdyn.workflow import plan_transient, transient_to_file

    opts = job.cfg.transient
    plan = plan_transient(run, step_origin=job.step_origin)
    plan = replace(plan, warnings=tuple(warnings) + plan.warnings)
    for w in plan.warnings:  # before the work: a step that resolves nothing is said at once
        warn(w)
    con = console()
    warm_kernels(con)
    progress, update = progress_bar(con, opts.duration)
    with progress:
        done = transient_to_file(plan, opts, output=job.output, config_toml=job.toml, config_sha256=job.sha,
                                 notes=print_notes, progress=update, resume=resume, source=str(job.cfg.source),
                                 **({} if checkpoint_seconds is None else {"checkpoint_seconds": checkpoint_seconds}))
    con.print(f"time step ({plan.attrs['step_origin']}): {plan.step_text}")
    print_transient(con, done.summary, done.spans, done.peaks, done.excitation_frequency, shown=plan.warnings)
    con.print(f"wrote [bold]/transient[/] ({done.summary.n_outputs} samples) to {job.output}")


def register(app: typer.Typer) -> None:
    app.command()(transient)
