"""Command-line interface: wires config -> geometry -> model -> analysis -> HDF5 and owns the console.

Exit codes: 0 ok, 1 solver failure (or an internal error), 2 bad config or usage, 130 interrupted
(Ctrl-C), 143 terminated (SIGTERM). No traceback: an unexpected exception is one line naming its type
(the traceback only with `beltdyn --debug COMMAND ...`). Heavy modules are imported inside the commands so that `beltdyn --help` starts fast.
"""

from __future__ import annotations

import os

# Small dense matrices are solved fastest single-threaded; users can still override.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import List, Optional  # noqa: E402

import typer  # noqa: E402

from beltdyn import __version__  # noqa: E402
from beltdyn import cliparams

cliparams.install()  # command-line values coerced without importing pydantic (typer's common case)

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Dynamics of belt drives: ANCF belt spans on rigid pulleys.\n\n"
    "Exit codes: 0 ok, 1 solver failure or internal error, 2 bad configuration or usage, 130 interrupted "
    "(Ctrl-C), 143 terminated (SIGTERM).",
)

ConfigArg = typer.Argument(..., help="TOML drive description.", show_default=False)
OutOpt = typer.Option(None, "--output", "-o", help="HDF5 results file [default: results/<config stem>.h5].")
SetOpt = typer.Option(None, "--set", help="Override a dotted config key: KEY=VALUE (TOML literal).", metavar="KEY=VALUE")
ForceOpt = typer.Option(False, "--force", help="Replace a results file written for a different configuration.")
ForceLargeOpt = typer.Option(False, "--force-large",
                             help="Write histories larger than transient.max_output_mb (default 1000 MB).")
FmaxOpt = typer.Option(None, "--fmax", min=0.0,
                       help="With --rtol: choose each span's model and mesh (spring, string or ANCF) for the modes "
                            "below FMAX Hz: the cheapest whose estimated error is within RTOL of the converged ANCF "
                            "drive; the choice goes into the resolved configuration ([spans]).")


PIPE_WIDTH = 1000  # console width when the output is not a terminal: tables at their natural width


def _is_tty(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


def _console(stderr: bool = False):
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

    width = None if _is_tty(sys.stderr if stderr else sys.stdout) else PIPE_WIDTH
    if stderr:
        return _FoldingConsole(stderr=True, highlight=False, soft_wrap=True, width=width)
    return _FoldingConsole(file=_PipeSafe(), highlight=False, soft_wrap=True, width=width)


class _PipeSafe:
    """stdout for the console that outlives its reader: when the pipe closes (`beltdyn ... | head`), the
    rest of the output goes to /dev/null and the command finishes its work (results are written; exit
    status as without the pipe) instead of failing with BrokenPipeError."""

    def write(self, text: str) -> int:
        try:
            return sys.stdout.write(text)
        except BrokenPipeError:
            _drop_stdout()
            return len(text)

    def flush(self) -> None:
        try:
            sys.stdout.flush()
        except BrokenPipeError:
            _drop_stdout()

    def isatty(self) -> bool:
        return _is_tty(sys.stdout)

    def fileno(self) -> int:
        return sys.stdout.fileno()

    @property
    def encoding(self) -> str:
        return getattr(sys.stdout, "encoding", "utf-8")


def _drop_stdout() -> None:
    """Point stdout at /dev/null (its reader has gone; Python's final flush must not fail either)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    finally:
        os.close(devnull)


_STATE = {"debug": False, "signal": None}  # signal: the SIGINT / SIGTERM received, if any

# POSIX convention: 128 + signal number
EXIT_INTERRUPTED = 130  # SIGINT (Ctrl-C)
EXIT_TERMINATED = 143  # SIGTERM


def _one_line(text: str) -> str:
    """Line breaks and other control characters (from a quoted TOML key, a --set value) escaped."""
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def _fail(exc: BaseException) -> None:
    from rich.text import Text

    from beltdyn.errors import BeltdynError, Terminated

    err = _console(stderr=True)
    exc = _interruption(exc) or exc
    if isinstance(exc, KeyboardInterrupt):
        what = "terminated (SIGTERM)" if isinstance(exc, Terminated) else "interrupted"
        err.print(Text.assemble((what, "bold red"), ": finished groups are unchanged; a running transient keeps "
                                "its samples so far, marked 'interrupted'"))
        raise typer.Exit(EXIT_TERMINATED if isinstance(exc, Terminated) else EXIT_INTERRUPTED)
    if isinstance(exc, BeltdynError):
        err.print(Text.assemble(("error", "bold red"), f": {_one_line(str(exc))}"))
        raise typer.Exit(exc.exit_code)
    if _STATE["debug"]:
        import traceback

        traceback.print_exception(exc, file=sys.stderr)
    hint = "" if _STATE["debug"] else "; rerun with --debug for the traceback"
    err.print(Text.assemble(("internal error", "bold red"), f": {type(exc).__name__}: {_one_line(str(exc))}; please "
                            f"file it with the command line and config{hint}"))
    raise typer.Exit(1)


def _out_of_memory(detail: str) -> None:
    from rich.text import Text

    detail = f" ({_one_line(detail)})" if detail else ""
    _console(stderr=True).print(Text.assemble(
        ("error", "bold red"), f": out of memory{detail}; the model is too large for this machine: use a smaller "
        "mesh.elements_per_span (e.g. --set mesh.elements_per_span=40), fewer modes or fewer sweep --workers"))
    raise typer.Exit(1)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"beltdyn {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version."),
    debug: bool = typer.Option(False, "--debug", help="Show the Python traceback of an internal error."),
) -> None:
    """beltdyn command-line tool."""
    _STATE["debug"] = debug


class _Job:
    """One command's pipeline state: config, layout, output path, hash."""

    def __init__(self, config: Path, output: Optional[Path], sets: Optional[List[str]], force: bool) -> None:
        from beltdyn.config import config_hash, load_config, resolved_toml
        from beltdyn.model.geometry import layout_from_config

        self.cfg = load_config(config, sets or [])
        self.layout = layout_from_config(self.cfg)  # geometric config errors come before the output check
        self.toml = resolved_toml(self.cfg)
        self.sha = config_hash(self.cfg)
        # the configuration as given: `modal --rtol` replaces cfg/toml/sha by the chosen mesh's and
        # its file records both, so that the same command is accepted on its own output again
        self.base_sha = self.sha
        self.force = force
        self.ladder = None  # the automatic choice of the span models (--fmax/--rtol), if made
        self.output = output if output is not None else Path("results") / f"{config.stem}.h5"
        from beltdyn.results.io import check_target

        # early check (before any analysis); a file of a derived configuration (from this base) passes
        # here and is checked strictly, against the configuration actually written, by `write`
        check_target(self.output, config_sha256=self.sha, force=force, base_config_sha256=self.base_sha)
        from beltdyn.results.io import lock_output

        lock_output(self.output)  # held until this command ends: no other beltdyn command writes it meanwhile
        from beltdyn.results.io import recover

        _notes(recover(self.output))  # what a killed earlier command left: its samples recovered, leftovers removed
        self.groups: list = []

    def add(self, group) -> None:
        self.groups.append(group)

    def write(self) -> None:
        from beltdyn.results.io import write_groups

        _notes(write_groups(self.output, self.groups, config_toml=self.toml, config_sha256=self.sha,
                            force=self.force, base_config_sha256=self.base_sha))


def _notes(notes: list[str]) -> None:
    """What the results modules did on their own (recovering a killed writer's group), on stderr."""
    from rich.text import Text

    for note in notes:
        _console(stderr=True).print(Text.assemble(("note", "bold yellow"), f": {_one_line(note)}"))


def _on_sigterm(signum, frame) -> None:
    from beltdyn.errors import Terminated

    _STATE["signal"] = signum
    raise Terminated()


def _on_sigint(signum, frame) -> None:
    _STATE["signal"] = signum
    raise KeyboardInterrupt


def _interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM that `exc` stands for: exc itself if it is one; once either signal has arrived,
    any other exception too, as the library the handler's KeyboardInterrupt went through turned it into
    its own error (pybind11 reports one inside a module's initialization as ImportError "initialization
    failed": a sweep interrupted while scipy imported); else None."""
    import signal

    from beltdyn.errors import Terminated

    if isinstance(exc, KeyboardInterrupt):
        return exc
    if _STATE["signal"] is None:
        return None
    return Terminated() if _STATE["signal"] == signal.SIGTERM else KeyboardInterrupt()


def _run(body) -> None:
    """Run a command's body: a BeltdynError is one line and its exit code; Ctrl-C exit 130 and SIGTERM
    (handled like Ctrl-C: atomic writes discarded, a transient's samples and a sweep's journal kept)
    exit 143; anything else is an internal error, one line and exit 1 (the traceback with --debug)."""
    import signal

    _STATE["signal"] = None
    try:
        signal.signal(signal.SIGTERM, _on_sigterm)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # (not where the caller ignores it)
            signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread (e.g. called from a test harness)
        pass
    import rich.console  # noqa: F401 - loaded before the body, so the handlers below need no memory to import
    import rich.text  # noqa: F401

    from beltdyn import errors  # noqa: F401

    memory_error = None
    try:
        body()
    except typer.Exit:
        raise
    except MemoryError as exc:
        if _STATE["debug"]:
            import traceback

            try:
                traceback.print_exception(exc, file=sys.stderr)
            except MemoryError:
                pass
        memory_error = str(exc)  # leaving this block frees the frames, and the memory they hold
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - the top-level handler
        _fail(exc)
    if memory_error is not None:
        import gc

        gc.collect()
        _out_of_memory(memory_error)


def _failed_group(name: str, exc: BaseException):
    from beltdyn.results.io import GroupData

    return GroupData(name=name, coords={}, variables=(), status="failed", error=str(exc))


@app.command()
def geometry(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
             force: bool = ForceOpt) -> None:
    """Tangent points, spans, wrap angles, belt length and the L0 fit of the adjustable pulley."""

    def body() -> None:
        from beltdyn.results.export import geometry_group

        job = _Job(config, output, set_, force)
        layout = job.layout
        job.add(geometry_group(layout))
        job.write()
        _print_geometry(layout)
        _console().print(f"wrote [bold]/geometry[/] to {job.output}")

    _run(body)


def _refined_modal(job: "_Job", n_modes: int, rtol: float) -> None:
    import numpy as np
    from rich.table import Table

    from beltdyn.config import config_hash, resolved_toml
    from beltdyn.results.export import geometry_group, modal_group, static_group
    from beltdyn.study.sweep import refine_mesh

    replace = _rtol_target(job)  # before the refinement: may its result replace what the output holds?
    (cfg, model, st, md), ref = refine_mesh(job.cfg, n_modes=n_modes, rtol=rtol)
    # the results belong to the chosen mesh: record that configuration
    job.cfg, job.toml, job.sha = cfg, resolved_toml(cfg), config_hash(cfg)
    job.force = job.force or replace
    from beltdyn.results.io import check_target

    check_target(job.output, config_sha256=job.sha, force=job.force)
    job.add(geometry_group(job.layout))  # the L0 fit (the mesh does not change it); /static: the solved layout
    job.add(static_group(model, st, cfg.tension.target))
    group = modal_group(model, md, st.q)
    attrs = dict(group.attrs, rtol=rtol, chosen_elements_per_span=int(ref.elements[ref.chosen]),
                 mesh_converged=int(ref.converged), estimated_error=float(np.nanmax(ref.estimate[ref.chosen])))
    job.add(type(group)(name=group.name, coords=group.coords, variables=group.variables, attrs=attrs))
    job.write()
    con = _console()
    tbl = Table(title=f"Mesh refinement to rtol = {rtol:g}: estimated relative error per mode")
    tbl.add_column("el/span", justify="right")
    for lab in ref.labels:
        tbl.add_column(lab, justify="right")
    for i, n_el in enumerate(ref.elements):
        mark = " <- chosen" if i == ref.chosen else ""
        tbl.add_row(f"{n_el}{mark}", *[f"{ref.estimate[i, j]:.1e}" for j in range(len(ref.labels))])
    con.print(tbl)
    _print_modal(md)
    state = "meets" if ref.converged else "does NOT meet (mesh limit reached)"
    con.print(f"chosen mesh: {ref.elements[ref.chosen]} elements per span; it {state} rtol = {rtol:g} "
              f"(largest estimate {np.nanmax(ref.estimate[ref.chosen]):.2e}); wrote {job.output}")
    if not ref.converged:
        _rtol_not_met(ref, rtol, job.output)


REFINED_GROUPS = {"geometry", "static", "modal"}  # what `modal --rtol` writes, all of it


def _rtol_target(job: "_Job") -> bool:
    """Before the refinement: the output of `modal --rtol` is decided whatever mesh it will choose.

    The early check (`_Job`) refused a file of another configuration. A file of this configuration (or
    of an earlier `--rtol` run of it) holding only /geometry /static /modal is replaced by the run's
    (True: they are all written anew, for the mesh chosen); one holding more (a /transient, a /sweep)
    is refused now (exit 2), since the chosen mesh may not be theirs, unless --force. False: no file,
    or --force."""
    from beltdyn.results.io import group_names

    if job.force or not job.output.exists():
        return False
    others = sorted(set(group_names(job.output)) - REFINED_GROUPS)
    if not others:
        return True
    from beltdyn.errors import OutputError

    raise OutputError(f"{job.output}: holds /{', /'.join(others)} of this configuration; modal --rtol may choose "
                      f"another mesh, whose /static and /modal would not belong with them: use --force to start "
                      f"the file afresh or choose another output path")


def _rtol_not_met(ref, rtol: float, output) -> None:
    """`modal --rtol` reached the mesh limit without meeting the tolerance: a solver failure (exit 1)
    after the table and the file (its /modal has mesh_converged = 0) are written."""
    import numpy as np

    from beltdyn.errors import SolverError

    raise SolverError(f"the modes do NOT meet rtol = {rtol:g}: largest estimated relative error "
                      f"{np.nanmax(ref.estimate[ref.chosen]):.2e} at {ref.elements[ref.chosen]} elements per span, "
                      f"the finest mesh tried (the refinement limit); its results are in {output} "
                      "(/modal mesh_converged = 0)", analysis="modal", step="mesh refinement")


def _static_pipeline(job: "_Job", *, modal: bool, n_modes: int | None = None, compiled: bool = False):
    """geometry -> system -> static (-> modal) through the library pipeline; writes the groups reached,
    and a failed group for the stage that failed."""
    from beltdyn.errors import SolverError
    from beltdyn.results.export import geometry_group, modal_group, static_group
    from beltdyn.pipeline import analyse

    job.add(geometry_group(job.layout))
    try:
        run = analyse(job.cfg, modal=modal, n_modes=n_modes, layout=job.layout, compiled=compiled)
    except SolverError as exc:
        part = getattr(exc, "partial", None)
        if part is not None and part.static is not None:
            job.add(static_group(part.system, part.static, job.cfg.tension.target))
        job.add(_failed_group(exc.analysis if exc.analysis in ("static", "modal") else "static", exc))
        job.write()
        raise
    _add_results(job, run)
    job.write()
    return run


def _add_results(job: "_Job", run) -> None:
    """/static (with the automatic span choice, if made) and /modal (with the modes that spring spans
    leave out) of a finished run."""
    from beltdyn.results.export import ladder_attrs, ladder_variables, modal_group, static_group

    group = static_group(run.system, run.static, job.cfg.tension.target)
    if job.ladder is not None:
        group = type(group)(name=group.name, coords=group.coords,
                            variables=group.variables + ladder_variables(job.ladder),
                            attrs={**group.attrs, **ladder_attrs(job.ladder)})
    job.add(group)
    if run.modal is not None:
        job.add(modal_group(run.system, run.modal, run.static.q, _unrepresented(job, run)))


def _unrepresented(job: "_Job", run) -> tuple:
    """The modes the spring spans cannot represent, below --fmax (else below the highest mode computed);
    kept on the job for `_print_unrepresented`."""
    if run.system.springs is None:
        return ()
    from beltdyn.analysis.ladder import unrepresented_modes

    band = job.ladder.fmax if job.ladder is not None else float(run.modal.frequency.max(initial=0.0))
    job.unrepresented = (band, run.system.layout, unrepresented_modes(run.system, run.static, band))
    return job.unrepresented[2]


def _print_unrepresented(job: "_Job") -> None:
    band, lay, modes = getattr(job, "unrepresented", (0.0, None, ()))
    if modes:
        text = ", ".join(f"{f:.4g} Hz ({kind} {order}, span {lay.span_name(s)})" for s, kind, order, f in modes)
        _console().print(f"[bold yellow]note:[/] the spring spans leave out {len(modes)} mode(s) below {band:.4g} Hz "
                         f"(their own modes, not in the table above): {text}")


def _choose_spans(job: "_Job", fmax: Optional[float], rtol: Optional[float], *, command: str):
    """--fmax/--rtol: the cheapest model of each span for the band (`ladder.choose_models`); the job's
    configuration becomes the chosen one (its resolved TOML holds the [spans] table). Returns the
    chosen drive's Analysis (static and modal), or None without --fmax."""
    if fmax is None:
        if rtol is not None and command != "modal":
            from beltdyn.errors import ConfigError

            raise ConfigError("--rtol needs --fmax here (the band whose modes the span models must get within "
                              "RTOL)", file=job.cfg.source, key="--fmax")
        return None
    if rtol is None:
        from beltdyn.errors import ConfigError

        raise ConfigError("--fmax needs --rtol (the relative tolerance of the modes below FMAX)", file=job.cfg.source,
                          key="--rtol")
    if not fmax > 0 or not rtol > 0:
        from beltdyn.errors import ConfigError

        raise ConfigError(f"--fmax and --rtol must be > 0, got {fmax:g} and {rtol:g}", file=job.cfg.source,
                          key="--fmax" if not fmax > 0 else "--rtol")
    from beltdyn.config import config_hash, resolved_toml
    from beltdyn.study.fidelity import choose_models
    from beltdyn.results.io import check_target

    choice, run = choose_models(job.cfg, fmax=fmax, rtol=rtol)
    job.ladder = choice
    job.cfg, job.toml, job.sha = choice.config, resolved_toml(choice.config), config_hash(choice.config)
    check_target(job.output, config_sha256=job.sha, force=job.force)
    _print_ladder(choice)
    return run


def _print_ladder(choice) -> None:
    from rich.table import Table

    con = _console()
    tbl = Table(title=f"Span models for the modes below {choice.fmax:g} Hz within rtol = {choice.rtol:g} "
                      f"(cheapest first: spring, string, ANCF)")
    for col in ("span", "model", "elements", "DOFs", "estimated error", "note"):
        tbl.add_column(col, justify="left" if col in ("span", "model", "note") else "right")
    for c in choice.spans:
        tbl.add_row(c.name, c.model, "-" if c.model == "spring" else str(c.elements), str(c.dofs), f"{c.estimate:.1e}",
                    c.note)
    con.print(tbl)
    state = "meets" if choice.met else "does NOT meet"
    con.print(f"the choice {state} rtol = {choice.rtol:g} below {choice.fmax:g} Hz (largest estimate "
              f"{choice.estimate:.2e}, {choice.solves} drive solves); it is the \\[spans] table of the resolved "
              f"configuration in the results file")


def _ladder_not_met(job: "_Job") -> None:
    """The span choice could not meet rtol even with the richest rung: exit 1 after the results are written."""
    if job.ladder is None or job.ladder.met:
        return
    from beltdyn.errors import SolverError

    raise SolverError(f"the span models do NOT meet rtol = {job.ladder.rtol:g} below {job.ladder.fmax:g} Hz: largest "
                      f"estimated relative error {job.ladder.estimate:.2e} with the finest meshes tried; the results "
                      f"are in {job.output} (/static ladder_met = 0)", analysis="modal", step="span model choice")


@app.command()
def static(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
           force: bool = ForceOpt, fmax: Optional[float] = FmaxOpt,
           rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                                help="With --fmax: the relative tolerance of the span choice.")) -> None:
    """Nonlinear static equilibrium: span tensions, hub loads, solved pulley positions."""

    def body() -> None:
        job = _Job(config, output, set_, force)
        _choose_spans(job, fmax, rtol, command="static")
        _announce_cost(job.cfg)
        run = _static_pipeline(job, modal=False)
        _print_static(run.layout, run.system, run.static)
        _console().print(f"wrote [bold]/geometry /static[/] to {job.output}")
        _ladder_not_met(job)

    _run(body)


@app.command()
def modal(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
          force: bool = ForceOpt,
          modes: Optional[int] = typer.Option(None, "--modes", min=1, help="Number of elastic modes [default: modal.modes]."),
          rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                               help="Refine mesh.elements_per_span (doubling) until the modes' estimated relative error is below RTOL; the cheapest such mesh is used. With --fmax: the tolerance of the span choice."),
          fmax: Optional[float] = FmaxOpt) -> None:
    """Natural frequencies and classified mode shapes about the static equilibrium."""

    def body() -> None:
        job = _Job(config, output, set_, force)
        if rtol is not None and fmax is None:
            _refined_modal(job, modes or job.cfg.modal.modes, rtol)
            return
        chosen = _choose_spans(job, fmax, rtol, command="modal")
        if chosen is not None:  # the choice solved the chosen drive already
            from beltdyn.results.export import geometry_group

            job.add(geometry_group(job.layout))
            _add_results(job, chosen)
            job.write()
            run = chosen
        else:
            _announce_cost(job.cfg)
            run = _static_pipeline(job, modal=True, n_modes=modes)
        _print_static(run.layout, run.system, run.static)
        _print_modal(run.modal)
        _print_unrepresented(job)
        _console().print(f"wrote [bold]/geometry /static /modal[/] to {job.output}")
        _ladder_not_met(job)

    _run(body)


SPECTRUM_SERIES = ("span_tension", "hub_load", "bearing_force", "midspan_displacement", "pulley_speed", "driver_torque",
                   "arm_angle")


@app.command()
def transient(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
              force: bool = ForceOpt, force_large: bool = ForceLargeOpt,
              duration: Optional[float] = typer.Option(None, "--duration", min=0.0, help="Simulated time, s [default: transient.duration]."),
              step: Optional[float] = typer.Option(None, "--step", min=0.0, help="Time step, s, used as given [default: transient.step, or from transient.accuracy and fmax]."),
              fmax: Optional[float] = FmaxOpt,
              rtol: Optional[float] = typer.Option(None, "--rtol", min=0.0,
                                                   help="With --fmax: the relative tolerance of the span choice.")) -> None:
    """Nonlinear time response (generalized-alpha) with streamed histories and their spectra."""

    def body() -> None:
        sets = list(set_ or [])
        if duration is not None:
            sets.append(f"transient.duration={duration!r}")
        if step is not None:
            sets.append(f"transient.step={step!r}")
        job = _Job(config, output, sets, force)
        cfg = job.cfg
        if cfg.transient is None:
            from beltdyn.errors import ConfigError

            raise ConfigError("no [transient] table: add one (duration, step, excitations)", file=cfg.source,
                              key="transient")
        from beltdyn.analysis.timestep import resolve_step

        resolved, origin = resolve_step(cfg.transient, manual=step)
        if resolved.step != cfg.transient.step:  # the chosen step goes into the resolved configuration
            job = _Job(config, output, sets + [f"transient.step={resolved.step!r}"], force)  # (provenance)
        job.step_origin = origin
        _choose_spans(job, fmax, rtol, command="transient")
        _announce_cost(job.cfg, resolved)
        _check_output_volume(job, force_large)
        spec_opts = cfg.transient.spectrum
        run = _static_pipeline(job, modal=spec_opts.enabled)
        _run_transient(job, run, force_large=force_large)
        _ladder_not_met(job)

    _run(body)


@app.command()
def response(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
             force: bool = ForceOpt) -> None:
    """Steady forced response over driver speed and engine orders: amplitudes and phases of tensions,
    hub loads, pulley and arm angles, mid-span displacements (the drive linearized about its static
    equilibrium; one complex solve per frequency)."""

    def body() -> None:
        job = _Job(config, output, set_, force)
        cfg = job.cfg
        if cfg.response is None:
            from beltdyn.errors import ConfigError

            raise ConfigError("no [response] table: add one (speed range, orders, [[response.excitation]])",
                              file=cfg.source, key="response")
        run = _static_pipeline(job, modal=False)
        from beltdyn.errors import SolverError
        from beltdyn.results.export import response_group
        from beltdyn.pipeline import response_of

        try:
            res = response_of(cfg, run)
        except SolverError as exc:
            job.add(_failed_group("response", exc))
            job.write()
            raise
        job.add(response_group(run.system, res))
        job.write()
        _print_response(_console(), res)
        _console().print(f"wrote [bold]/geometry /static /response[/] to {job.output}")

    _run(body)


def _print_response(con, res) -> None:
    """Per order: the largest span-tension and hub-load amplitudes over the speeds, and where."""
    import numpy as np
    from rich.table import Table

    for w in res.warnings:
        con.print(f"[bold yellow]warning[/]: {w}")
    table = Table(title=f"steady response, {len(res.speed)} speeds {res.speed[0]:.6g}-{res.speed[-1]:.6g} rad/s "
                        f"(prescribed: {', '.join(res.prescribed)})")
    for col in ("order", "largest tension amplitude", "at speed", "frequency", "largest hub-load amplitude",
                "at speed"):
        table.add_column(col, justify="right")
    T = np.abs(res.outputs["span_tension"]).max(axis=(2, 3))
    H = np.linalg.norm(np.abs(res.outputs["hub_load"]), axis=-1).max(axis=2)
    for o, k in enumerate(res.orders):
        i, j = int(np.argmax(T[:, o])), int(np.argmax(H[:, o]))
        table.add_row(f"{k:g}", f"{T[i, o]:.4g} N", f"{res.speed[i]:.5g} rad/s", f"{res.frequency[i, o]:.5g} Hz",
                      f"{H[j, o]:.4g} N", f"{res.speed[j]:.5g} rad/s")
    con.print(table)


@app.command()
def plot(result: Path = typer.Argument(..., help="A beltdyn results file (HDF5)."),
         what: Optional[str] = typer.Argument(None, help="layout | modes | sweep | transient | response "
                                                         "[default: every figure the file holds]"),
         output: Optional[Path] = typer.Option(None, "-o", "--output",
                                               help="Figure file (.png, .svg, .pdf); without WHAT a prefix: "
                                                    "PREFIX_<what>.png [default: next to RESULT]"),
         modes: Optional[str] = typer.Option(None, "--modes", help="Modes to draw, e.g. 1-8 or 1,3,5 [default: 1-8]."),
         show: bool = typer.Option(False, "--show", help="Also open the figures in a window."),
         measured: Optional[Path] = typer.Option(None, "--measured", help="A measured-frequency CSV (beltdyn fit) "
                                                 "drawn over the sweep figure.")) -> None:
    """Figures of a results file: drive layout, mode shapes, frequency maps and Campbell diagrams,
    histories and spectra, forced response (needs the plot extra: pip install 'beltdyn[plot]')."""

    def body() -> None:
        from beltdyn.errors import ConfigError, OutputError

        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise ConfigError("matplotlib is not installed: pip install 'beltdyn[plot]'", file=str(result),
                              key="plot") from None
        from beltdyn import fit_plot as FP
        from beltdyn import plot as P

        if what is not None and what not in P.KINDS + FP.KINDS:
            raise ConfigError(f"unknown figure {what!r}; one of {', '.join(P.KINDS + FP.KINDS)}", file=str(result),
                              key="WHAT")
        try:
            chosen_modes = P.parse_modes(modes)
        except ValueError:
            raise ConfigError(f"--modes must be like 1-8 or 1,3,5, got {modes!r}", file=str(result),
                              key="--modes") from None
        P.set_interactive(show)
        res = P.read_results(result)
        kinds = (what,) if what else P.available(res) + FP.available(res)
        if not kinds:
            raise OutputError(f"{result}: holds no group a figure is drawn from (/geometry, /modal, /sweep, "
                              f"/transient or /response)")
        written = []
        for kind in kinds:
            fig = FP.figure(kind, res, modes=chosen_modes, measured=measured)
            if what and output is not None:
                path = output
            else:
                base = output if output is not None else result.with_suffix("")
                path = base.with_name(f"{base.name}_{kind}.png")
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
            fig.savefig(tmp)  # then renamed: an interrupted run leaves no half-written figure
            tmp.replace(path)
            written.append(str(path))
        if show:
            import matplotlib.pyplot as plt

            plt.show()
        _console().print("wrote " + ", ".join(written))

    _run(body)


def _announce_cost(cfg, transient=None) -> None:
    """Before any work: a run estimated to take long says so, with its DOFs and steps (`guards`)."""
    from beltdyn.analysis.guards import cost_note, estimate_cost

    note = cost_note(estimate_cost(cfg, transient))
    if note:
        _console().print(f"[bold]note[/]: {note}")


def _check_output_volume(job: "_Job", force_large: bool) -> None:
    """Before any work: histories above transient.max_output_mb need --force-large (exit 2)."""
    from beltdyn.model.system import DeferredSystem, build_system
    from beltdyn.analysis.transient import output_volume

    opts = job.cfg.transient
    # the DOF map and the pulleys' components answer it without a belt built (anything else would build)
    facts = DeferredSystem(job.cfg, job.layout, build=lambda lay: build_system(job.cfg, lay))
    n_samples, volume = output_volume(facts, opts)
    if volume > opts.max_output_mb * 1e6 and not force_large:
        from beltdyn.errors import ConfigError

        raise ConfigError(f"the histories would take {volume / 1e6:.4g} MB ({n_samples:,} samples every "
                          f"{opts.output_interval:g} s over {opts.duration:g} s), above transient.max_output_mb = "
                          f"{opts.max_output_mb:g} MB: raise transient.output_interval, record fewer series "
                          f"([transient.record]) or pass --force-large", file=str(job.cfg.source),
                          key="transient.output_interval")


COMPILE_SECONDS = 20  # numba's first compile of the transient kernels on a 2-core machine (18 s CPU measured)


def _warm_kernels(con) -> None:
    """Compile the transient kernels before any output file is opened when they are not in numba's
    cache yet (`jitcache.is_warm`), announced with a spinner (shown in a terminal only), with Ctrl-C
    and SIGTERM deferred until the compiler is done (a signal inside numba's compiler was lost, or
    left a half-written cache entry). Cached kernels are loaded as the run first calls them."""
    import signal

    from beltdyn import jitcache
    from beltdyn.analysis.transient import entry_kernels
    from beltdyn.pipeline import warm_up

    if jitcache.is_warm(*entry_kernels()):
        return  # in numba's cache: loaded as the run first calls them (~0.2 s)

    got: list = []
    olds = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            olds[sig] = signal.signal(sig, lambda signum, frame: got.append(signum))
        except ValueError:  # not the main thread
            pass
    try:
        with con.status(f"compiling the transient kernels, once, about {COMPILE_SECONDS} s (numba; later runs "
                        f"load them from its cache)"):
            warm_up()
    finally:
        for sig, handler in olds.items():
            signal.signal(sig, handler)
    if signal.SIGTERM in got:
        from beltdyn.errors import Terminated

        raise Terminated()
    if got:
        raise KeyboardInterrupt


def _run_transient(job: "_Job", run, *, force_large: bool = False) -> None:
    import numpy as np

    from beltdyn.results.io import GroupData, StreamWriter, Variable
    from beltdyn.analysis.transient import prepare, run_transient

    cfg = job.cfg
    opts = cfg.transient
    from beltdyn.pipeline import transient_start

    (model, res), mres = transient_start(run), run.modal
    if mres is not None and model.belt_speed != run.system.belt_speed:  # the peaks against the modes at the start speed
        from beltdyn.analysis.modal import solve_modes

        mres = solve_modes(model, res.q, n_modes=len(mres.frequency), solver=cfg.modal.solver)
    setup = prepare(model, res, opts)
    early = _step_warnings(opts, setup, mres)
    for w in early:  # before the work: a step that resolves nothing is said at once
        _console().print(f"[bold yellow]warning[/]: {w}")
    _warm_kernels(_console())
    shapes = {name: len(v) for name, v in setup.coords.items()}
    series = {s.name: (tuple(shapes[d] for d in s.dims), s.units, s.dims) for s in setup.series}
    keep = {s.name for s in setup.series if s.name in SPECTRUM_SERIES} if opts.spectrum.enabled else set()
    con = _console()
    from beltdyn.analysis.timestep import describe, frequency_error

    step_text, band, band_acc = describe(opts.step, accuracy=opts.accuracy, fmax=opts.fmax, rho_inf=opts.rho_inf)
    attrs = {"rho_inf": opts.rho_inf, "step_s": opts.step, "duration_s": opts.duration,
             "output_interval_s": opts.output_interval, "start": opts.start,
             "step_origin": getattr(job, "step_origin", "config"), "resolved_fmax_Hz": band,
             "resolved_accuracy": band_acc}
    if opts.fmax is not None:
        attrs["fmax_frequency_error"] = frequency_error(opts.fmax, opts.step, opts.rho_inf)
    with StreamWriter(job.output, "transient", series=series, coords=setup.coords, attrs=attrs,
                      config_toml=job.toml, config_sha256=job.sha, force=True) as writer:
        _notes(writer.notes)
        if "dof" in setup.coords:  # full state recorded: the unit of each DOF beside q and v
            from beltdyn.results.export import dof_unit_variable

            writer.add_variables((dof_unit_variable(model),))

        def sink(t, batch):
            writer.append(t, batch)

        progress, update = _progress_bar(con, opts.duration)
        with progress:
            summary = run_transient(model, res, opts, sink=sink, progress=update, setup=setup)
        ev = summary.slack_events
        writer.set_attrs(steps=summary.steps, refactorizations=summary.refactorizations,
                         newton_iterations=summary.newton_iterations,
                         energy_balance_error=summary.energy_error, energy_moved_J=summary.energy_moved,
                         step_halvings=summary.step_halvings, smallest_step_s=summary.min_step,
                         n_slack_events=int(len(ev)),
                         warnings=list(early) + [w for w in summary.warnings if w not in early])
        if np.isfinite(summary.worst_slip_margin[0]):
            writer.set_attrs(worst_slip_margin=summary.worst_slip_margin[0],
                             worst_slip_time_s=summary.worst_slip_margin[1],
                             worst_slip_pulley=summary.worst_slip_margin[2])
        spans = [model.layout.span_name(i) for i in range(model.layout.n)]
        if len(ev):
            writer.add_subgroup(GroupData(
                name="slack_events", coords={"event": np.arange(1, len(ev) + 1)},
                variables=(Variable(name="event_time", data=ev[:, 0], dims=("event",), units="s"),
                           Variable(name="event_span", data=[spans[int(i)] for i in ev[:, 1]], dims=("event",), units="1"),
                           Variable(name="slack", data=ev[:, 2].astype(np.int8), dims=("event",), units="1",
                                    description="1: the span went slack (compressed), 0: taut again"),
                           Variable(name="min_force", data=ev[:, 3], dims=("event",), units="N"))))
        peaks = []
        if keep:  # the spectrum window is read back from the file: nothing is kept while streaming
            t_all = writer.read("time")
            first = int(np.searchsorted(t_all, opts.spectrum.start - 1e-9 * opts.output_interval))
            if len(t_all) - first >= 8:
                kept = {name: writer.read(name, first) for name in keep}
                peaks = _spectra(writer, setup, t_all[first:], kept, mres, opts)
    con.print(f"time step ({attrs['step_origin']}): {step_text}")
    _print_transient(con, summary, spans, peaks, setup.excitation_frequency, shown=early)
    con.print(f"wrote [bold]/transient[/] ({summary.n_outputs} samples) to {job.output}")


def _progress_bar(con, duration: float):
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


def _spectra(writer, setup, t, kept, mres, opts):
    from beltdyn.results.io import GroupData, Variable
    from beltdyn.analysis.spectrum import amplitude_spectrum, find_peaks

    variables, peaks, freq = [], [], None
    modal_f = mres.frequency if mres is not None else None
    for s in setup.series:
        if s.name not in kept:
            continue
        values = kept[s.name]
        spec = amplitude_spectrum(t, values, start=opts.spectrum.start, window=opts.spectrum.window)
        freq = spec.frequency
        variables.append(Variable(name=s.name, data=spec.amplitude, dims=("frequency", *s.dims), units=s.units,
                                  description=f"single-sided amplitude spectrum ({spec.window} window)"))
        labels = _channel_labels(s, setup.coords)
        peaks.append((s.name, s.units, find_peaks(spec, labels=labels, n_peaks=opts.spectrum.peaks,
                                                  excitation_frequency=setup.excitation_frequency,
                                                  modal_frequencies=modal_f)))
    if freq is not None:
        writer.add_subgroup(GroupData(name="spectrum", coords={"frequency": freq}, coord_units={"frequency": "Hz"},
                                      variables=tuple(variables)))
    store_peaks(writer, peaks, setup.excitation_frequency)
    return peaks


def _shown_peaks(peaks):
    """The rows of the printed peak table: (series, units, peak), the 4 largest peaks of each series
    (round-off ripples below 1e-6 of its largest dropped)."""
    rows = []
    for name, units, plist in peaks:
        top = max((p.amplitude for p in plist), default=0.0)
        rows += [(name, units, p) for p in [p for p in plist if p.amplitude >= 1e-6 * top][:4]]
    return rows


def _peak_relation(p, f_exc) -> str:
    parts = []
    if p.harmonic:
        parts.append(f"harmonic {p.harmonic} of the excitation ({f_exc:g} Hz)" if f_exc else f"harmonic {p.harmonic}")
    if p.nearest_mode:
        parts.append(f"nearest mode {p.nearest_mode} at {p.mode_frequency:.3f} Hz ({p.mode_distance_pct:+.2f} %)")
    return "; ".join(parts) or "-"


def store_peaks(writer, peaks, f_exc=None) -> None:
    """/transient/peaks: the printed table of dominant spectral peaks, one row per peak (series,
    channel, frequency, amplitude in its series' units, harmonic, nearest mode, relation text).
    `peaks` as returned by `_spectra` (series name, units, [spectrum.Peak]); nothing for no peaks.
    Called by `_spectra`, so `_run_transient` needs no change."""
    import numpy as np

    from beltdyn.results.io import GroupData, Variable

    rows = _shown_peaks(peaks)
    if not rows:
        return
    nan = float("nan")
    writer.add_subgroup(GroupData(
        name="peaks", coords={"peak": np.arange(1, len(rows) + 1)},
        variables=(
            Variable(name="series", data=[n for n, _, _ in rows], dims=("peak",), units="1",
                     description="recorded quantity (its spectrum is in /transient/spectrum)"),
            Variable(name="channel", data=[p.channel for _, _, p in rows], dims=("peak",), units="1"),
            Variable(name="frequency", data=np.array([p.frequency for _, _, p in rows]), dims=("peak",), units="Hz"),
            Variable(name="amplitude", data=np.array([p.amplitude for _, _, p in rows]), dims=("peak",),
                     units="mixed (see amplitude_unit)", description="single-sided peak amplitude, in amplitude_unit"),
            Variable(name="amplitude_unit", data=[u for _, u, _ in rows], dims=("peak",), units="1"),
            Variable(name="harmonic", data=np.array([p.harmonic for _, _, p in rows], dtype=np.int64), dims=("peak",),
                     units="1", description="k if the peak is the k-th harmonic of the excitation, 0 if none"),
            Variable(name="nearest_mode", data=np.array([p.nearest_mode for _, _, p in rows], dtype=np.int64),
                     dims=("peak",), units="1", description="1-based number of the closest natural frequency, 0 if none"),
            Variable(name="mode_frequency", data=np.array([p.mode_frequency if p.nearest_mode else nan
                                                           for _, _, p in rows]), dims=("peak",), units="Hz"),
            Variable(name="mode_distance", data=np.array([p.mode_distance_pct if p.nearest_mode else nan
                                                          for _, _, p in rows]), dims=("peak",), units="%",
                     description="100 (f - f_mode) / f_mode"),
            Variable(name="relation", data=[_peak_relation(p, f_exc) for _, _, p in rows], dims=("peak",), units="1"),
        ),
        attrs={"excitation_frequency_Hz": float(f_exc) if f_exc else nan}))


def _channel_labels(series, coords) -> list[str]:
    import itertools

    if not series.dims:
        return [series.name]
    axes = [coords[d] for d in series.dims]
    return [f"{series.name}[{', '.join(map(str, combo))}]" for combo in itertools.product(*axes)]


def _step_warnings(opts, setup, mres) -> tuple[str, ...]:
    """The step against the excitation and the highest mode the run is meant to resolve:
    transient.fmax if given, else the highest of the modes computed for the spectra (modal.modes)."""
    from beltdyn.analysis.timestep import step_warnings

    f_mode, source = None, ""
    if opts.fmax is not None:
        f_mode, source = float(opts.fmax), "transient.fmax"
    elif mres is not None and len(mres.frequency):
        f_mode = float(mres.frequency.max())
        source = f"mode {int(mres.frequency.argmax()) + 1}, the highest of the {len(mres.frequency)} computed (modal.modes)"
    return step_warnings(opts.step, excitation_frequency=setup.excitation_frequency, mode_frequency=f_mode,
                         mode_source=source)


def _print_transient(con, summary, spans, peaks, f_exc, shown=()) -> None:
    from rich.table import Table

    con.print(f"transient {summary.status}: {summary.steps} steps to t = {summary.final_time:.6g} s "
              f"({summary.newton_iterations / max(summary.steps, 1):.2f} Newton iterations per step), "
              f"{summary.refactorizations} refactorizations, {summary.step_halvings} step halvings "
              f"(smallest step {summary.min_step:.3g} s); energy balance error {summary.energy_error:.2e} "
              f"of the energy moved")
    for w in summary.warnings:
        if w not in shown:  # (those shown before the run are not repeated)
            con.print(f"[bold yellow]warning[/]: {w}")
    ev = summary.slack_events
    for t, s, slack, fmin in ev[:8]:
        con.print(f"  span {spans[int(s)]} {'went slack' if slack else 'taut again'} at t = {t:.6g} s "
                  f"(min axial force {fmin:.4g} N)")
    if len(ev) > 8:
        n_slack = int(ev[:, 2].sum())
        con.print(f"  ... {len(ev)} slack/taut events in all ({n_slack} times a span went slack); "
                  f"all are in /transient/slack_events")
    if not peaks:
        return
    # the largest peaks of each recorded quantity (amplitudes in that quantity's units)
    tbl = Table(title="Dominant spectral peaks" + (f" (excitation {f_exc:g} Hz)" if f_exc else ""))
    for col in ("channel", "frequency (Hz)", "amplitude", "harmonic", "nearest mode (Hz)", "vs mode (%)"):
        tbl.add_column(col, justify="left" if col == "channel" else "right")
    for _, units, p in _shown_peaks(peaks):  # the same rows as /transient/peaks
        tbl.add_row(p.channel, f"{p.frequency:.3f}", f"{p.amplitude:.4g} {units}",
                    str(p.harmonic) if p.harmonic else "-",
                    f"{p.mode_frequency:.3f}" if p.nearest_mode else "-",
                    f"{p.mode_distance_pct:+.2f}" if p.nearest_mode else "-")
    con.print(tbl)


@app.command()
def sweep(config: Path = ConfigArg, output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt,
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
        from beltdyn.study.sweep import Journal, assemble, available_cores, make_spec

        job = _Job(config, output, set_, force)
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
        if cfg.sweep is not None and cfg.sweep.params:
            if params:
                from beltdyn.errors import ConfigError

                raise ConfigError("give the parameters either in [sweep.params] ("
                                  + ", ".join(k for k, _ in cfg.sweep.params) + ") or with --param ("
                                  + ", ".join(k for k, _ in params) + "), not both",
                                  file=cfg.source, key="--param")
            params = list(cfg.sweep.params)
        if cfg.sweep is not None:  # the table's analysis and zip are defaults for --analysis / --zip
            zip_flag = zip_flag or cfg.sweep.zip
            kind = kind or cfg.sweep.analysis
        spec = make_spec(cfg, params, analysis=kind or "modal", zip_=zip_flag, n_modes=modes)
        con = _console()
        if workers is not None and scheduler is None and workers > available_cores():
            con.print(f"note: --workers {workers} is more than the {available_cores()} available cores; "
                      f"using {available_cores()}")
        journal = Journal(job.output)
        with journal:  # exclusive: a second sweep on the same output is refused, not raced
            assembly = _sweep_cases(con, cfg, spec, journal, resume=resume, workers=workers, scheduler=scheduler,
                                    force=force)
            result = assemble(spec, journal, assembly)
            from beltdyn.results.export import sweep_group

            job.add(sweep_group(cfg, result))
            job.write()
            journal.remove()
        _print_sweep(con, result)
        _print_campbell(con, cfg, result)
        if result.failed.all():
            from beltdyn.errors import SolverError

            raise SolverError(f"all {spec.n_cases} cases failed (first: {result.errors[0]})", analysis="sweep")
        con.print(f"wrote [bold]/sweep[/] ({spec.n_cases} cases, {int(result.failed.sum())} failed) to {job.output}")

    _run(body)


def _sweep_cases(con, cfg, spec, journal, *, resume, workers, scheduler, force):
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
                             progress=lambda k, n: bar.update(task, completed=k), restart=force)
    except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - an interruption is told apart below
        stop = _interruption(exc)
        if stop is None:
            raise
        n_done = len(journal.done()) if journal.exists() else 0
        what = "terminated (SIGTERM)" if isinstance(stop, Terminated) else "interrupted"
        _console(stderr=True).print(f"sweep {what}: {n_done} of {spec.n_cases} cases are journaled in "
                                    f"{journal.dir}; continue with --resume")
        if stop is exc:
            raise
        raise stop from exc


def _print_sweep(con, result) -> None:
    import numpy as np
    from rich.table import Table

    from beltdyn.study.sweep import richardson

    spec = result.spec
    keys = [p.key for p in spec.params]
    n = spec.n_cases
    show = list(range(n)) if n <= 24 else sorted(set(np.linspace(0, n - 1, 24).round().astype(int)))
    tbl = Table(title=f"Sweep: {spec.analysis}, {n} cases" + (" (every case)" if n <= 24 else " (a selection)"))
    for k in keys:
        tbl.add_column(k, justify="right")
    n_show = 0
    if result.frequency is not None:
        n_show = min(6, result.frequency.shape[1])
        for j in range(n_show):
            tbl.add_column(f"{result.label[j]} (Hz)" if j < len(result.label) else f"mode {j + 1}", justify="right")
    elif "mean_tension" in result.extras:
        tbl.add_column("mean tension (N)", justify="right")
    tbl.add_column("wall (ms)", justify="right")
    for i in show:
        row = [f"{v:g}" if isinstance(v, (int, float)) else str(v) for v in result.values[i]]
        if result.failed[i]:
            row += ["failed"] + [""] * (n_show - 1 if n_show else 0)
        elif result.frequency is not None:
            row += [f"{result.frequency[i, j]:.3f}" for j in range(n_show)]
        elif "mean_tension" in result.extras:
            row.append(f"{result.extras['mean_tension'][i]:.3f}")
        row.append(f"{result.wall_time[i] * 1e3:.1f}")
        tbl.add_row(*row)
    con.print(tbl)
    if result.frequency is not None and keys == ["mesh.elements_per_span"] and n >= 2 and not result.failed.any():
        # distinct meshes, coarse to fine (a range may round to repeated or unordered counts)
        elements_all = np.array([v[0] for v in result.values], dtype=float)
        uniq, first_idx = np.unique(elements_all, return_index=True)
        if len(uniq) < 2:
            return
        sel = first_idx[np.argsort(uniq)]
        elements = elements_all[sel]
        f_inf, est, p = richardson(result.frequency[sel], elements)
        n = len(sel)
        conv = Table(title="Mesh convergence: Richardson-extrapolated error estimate per mode")
        conv.add_column("el/span", justify="right")
        for j in range(n_show):
            conv.add_column(result.label[j], justify="right")
        conv.add_column("wall (ms)", justify="right")
        for i in range(n):
            conv.add_row(str(int(elements[i])), *[f"{est[i, j]:.1e}" for j in range(n_show)],
                         f"{result.wall_time[sel[i]] * 1e3:.1f}")
        conv.add_row("f_inf (Hz)", *[f"{f_inf[j]:.4f}" for j in range(n_show)], "")
        conv.add_row("order p", *[f"{p[j]:.2f}" for j in range(n_show)], "")
        con.print(conv)


def _print_campbell(con, cfg, result) -> None:
    """A speed sweep's resonance table: the engine-order crossings of [running] orders and the critical
    speeds (`running.campbell`)."""
    from rich.table import Table

    from beltdyn.analysis.running import campbell, speed_axis

    if not speed_axis(result):
        return
    names = [p.name for p in cfg.pulleys]
    spans = [f"{names[i]}-{names[(i + 1) % len(names)]}" for i in range(len(names))]
    orders = cfg.running.orders if cfg.running is not None else ()
    crossings, unstable = campbell(result, orders, spans)
    if orders:
        t = Table(title=f"Campbell diagram: crossings of the modes with the engine orders {', '.join(f'{k:g}' for k in orders)}")
        for col in ("order", "driver speed (rad/s)", "(rpm)", "belt speed (m/s)", "frequency (Hz)", "mode"):
            t.add_column(col, justify="left" if col == "mode" else "right")
        for x in crossings:
            t.add_row(f"{x.order:g}", f"{x.driver_speed:.2f}", f"{x.driver_speed * 30 / 3.141592653589793:.0f}",
                      f"{x.belt_speed:.3f}", f"{x.frequency:.3f}", f"{x.mode + 1}: {x.label}")
        if not crossings:
            t.add_row("", "", "", "", "", "no crossing in the swept range")
        con.print(t)
    for x in unstable:
        con.print(f"[bold yellow]{x.kind}:[/] mode {x.mode + 1} ({x.label}) at the critical driver speed "
                  f"{x.driver_speed:.4g} rad/s (belt speed {x.belt_speed:.4g} m/s)")


@app.command()
def paper(outdir: Path = typer.Option(Path("results/paper"), "--outdir", help="Folder for the HDF5 files and tables.md."),
          configs: Path = typer.Option(Path("configs/paper"), "--configs", help="Folder of the paper configs."),
          force: bool = ForceOpt) -> None:
    """Reproduce the paper's Tables 1 and 2: ours beside the paper's values."""

    def body() -> None:
        from beltdyn.study.paper import CASES, compare, markdown_table

        rows = []
        for case in CASES:
            job = _Job(configs / f"{case.config}.toml", outdir / f"{case.config}.h5", [], force)
            rows += compare(case, _static_pipeline(job, modal=True).modal)
        _print_paper(rows)
        outdir.mkdir(parents=True, exist_ok=True)
        (outdir / "tables.md").write_text(markdown_table(rows), encoding="utf-8")
        worst = max(abs(r.diff_theory_pct) for r in rows)
        _console().print(f"24 modes, largest difference to the paper's theoretical values: {worst:.3f} %; "
                         f"wrote {outdir / 'tables.md'}")

    _run(body)


# ------------------------------------------------------------------------------------ printing
def _degrees_180(angle: float) -> float:
    """A direction in degrees in (-180, 180]."""
    import math

    d = math.degrees(angle) % 360.0
    return d - 360.0 if d > 180.0 else d


def _print_geometry(layout) -> None:
    import math

    from rich.table import Table

    con = _console()
    t = Table(title="Pulleys")
    for col in ("pulley", "x (m)", "y (m)", "radius (m)", "side", "wrap (deg)", "arc (m)"):
        t.add_column(col, justify="right" if col not in ("pulley", "side") else "left")
    for j, name in enumerate(layout.names):
        t.add_row(name, f"{layout.center[j, 0]:.7f}", f"{layout.center[j, 1]:.7f}", f"{layout.radius[j]:.5g}",
                  "inside" if layout.side_sign[j] > 0 else "backside", f"{math.degrees(layout.wrap_angle[j]):.4f}",
                  f"{layout.arc_length[j]:.7f}")
    con.print(t)
    s = Table(title="Spans")
    for col in ("span", "length (m)", "angle (deg)"):
        s.add_column(col, justify="right" if col != "span" else "left")
    for i in range(layout.n):
        s.add_row(layout.span_name(i), f"{layout.span_length[i]:.7f}", f"{_degrees_180(layout.span_angle[i]):.4f}")
    con.print(s)
    extra = ""
    if layout.adjust_index is not None:
        name = layout.names[layout.adjust_index]
        if layout.adjust_kind == "arm":
            extra = f"; the arm of pulley {name} turned {math.degrees(layout.adjust_offset):.4f} deg about its pivot"
        else:
            extra = f"; adjustable pulley {name} moved {layout.adjust_offset * 1e3:.4f} mm along its slide"
    con.print(f"belt length {layout.belt_length:.10f} m{extra}")


def _print_static(layout, model, res) -> None:
    import math

    import numpy as np
    from rich.table import Table

    con = _console()
    speed = f" of the belt running at {model.belt_speed:.4g} m/s" if model.belt_speed else ""
    t = Table(title=f"Static equilibrium{speed} ({res.iterations} Newton iterations, {model.n_dof} DOFs)")
    for col in ("span", "tension start (N)", "tension end (N)"):
        t.add_column(col, justify="right" if col != "span" else "left")
    for i in range(layout.n):
        t.add_row(layout.span_name(i), f"{res.span_tension[i, 0]:.4f}", f"{res.span_tension[i, 1]:.4f}")
    con.print(t)
    h = Table(title="Pulleys")
    slip = res.slip_margin is not None and not np.all(np.isnan(res.slip_margin))
    loads = res.applied_torque is not None and np.any(res.applied_torque)
    cols = ["pulley", "x (m)", "y (m)", "hub load x (N)", "hub load y (N)", "|hub load| (N)"]
    cols += ["torque (N m)"] if loads else []
    cols += ["tight (N)", "slack (N)", "mu required", "slip margin"] if slip else []
    for col in cols:
        h.add_column(col, justify="right" if col != "pulley" else "left")
    from beltdyn.model.slip import pulley_tensions

    t_in, t_out = pulley_tensions(res.span_tension)
    for j, name in enumerate(layout.names):
        row = [name, f"{res.pulley_center[j, 0]:.7f}", f"{res.pulley_center[j, 1]:.7f}", f"{res.hub_load[j, 0]:.3f}",
               f"{res.hub_load[j, 1]:.3f}", f"{float((res.hub_load[j] ** 2).sum()) ** 0.5:.3f}"]
        if loads:
            row.append(f"{res.applied_torque[j]:.4g}" if j != model.driver else f"{res.driver_torque:.4g} (driver)")
        if slip:
            row += [f"{max(t_in[j], t_out[j]):.3f}", f"{min(t_in[j], t_out[j]):.3f}",
                    f"{res.required_friction[j]:.4g}", "-" if np.isnan(res.slip_margin[j]) else f"{res.slip_margin[j]:.3g}"]
        h.add_row(*row)
    con.print(h)
    if res.arm_angle is not None and not np.all(np.isnan(res.arm_angle)):
        a = Table(title="Tensioner arms")
        for col in ("pulley", "arm angle (deg)", "spring torque (N m)", "spring free angle (deg)",
                    "pivot reaction x (N)", "pivot reaction y (N)"):
            a.add_column(col, justify="right" if col != "pulley" else "left")
        for j, name in enumerate(layout.names):
            if np.isnan(res.arm_angle[j]):
                continue
            a.add_row(name, f"{math.degrees(res.arm_angle[j]):.4f}", f"{res.arm_torque[j]:.4f}",
                      "-" if np.isnan(res.arm_free_angle[j]) else f"{math.degrees(res.arm_free_angle[j]):.4f}",
                      f"{res.pivot_reaction[j, 0]:.3f}", f"{res.pivot_reaction[j, 1]:.3f}")
        con.print(a)
    if layout.adjust_index is not None and layout.adjust_kind == "arm":
        moved = f"the arm of pulley {layout.names[layout.adjust_index]} turned {math.degrees(res.adjust_offset):.4f} deg"
    else:
        moved = f"adjustable pulley offset {res.adjust_offset * 1e3:.4f} mm"
    con.print(f"mean span tension {res.mean_tension:.6f} N; driver torque {res.driver_torque:.4g} N m; {moved}")
    from beltdyn.results.export import static_warnings

    for w in static_warnings(model, res):
        con.print(f"[bold yellow]warning:[/] {w}")


def _print_modal(mres) -> None:
    import numpy as np
    from rich.table import Table

    con = _console()
    speed = f" at belt speed {mres.belt_speed:.4g} m/s (gyroscopic)" if mres.belt_speed else ""
    t = Table(title=f"Modes{speed} ({mres.solver} solver; {mres.n_rigid} rigid-body mode(s) excluded)")
    tens = bool(mres.energy_share[:, 4].any()) if mres.energy_share.shape[1] > 4 else False
    unstable = mres.growth_rate is not None and bool(np.any(mres.growth_rate > 0))
    for col in ("mode", "frequency (Hz)") + (("growth (1/s)",) if unstable else ()) + \
            ("modal shape", "rot", "trans", "long", "transv") + (("tens",) if tens else ()):
        t.add_column(col, justify="left" if col == "modal shape" else "right")
    for k in range(len(mres.frequency)):
        sh = mres.energy_share[k][: 5 if tens else 4]
        growth = (f"{mres.growth_rate[k]:.4g}",) if unstable else ()
        t.add_row(str(k + 1), f"{mres.frequency[k]:.3f}", *growth, mres.label[k], *(f"{x:.2f}" for x in sh))
    con.print(t)
    if unstable:
        con.print(f"[bold yellow]warning:[/] the running belt is unstable at {mres.belt_speed:.4g} m/s: above its first "
                  f"critical speed {mres.critical_speed:.4g} m/s (about this equilibrium) a span diverges "
                  f"(frequency 0, growth rate > 0)")


def _print_paper(rows) -> None:
    from rich.table import Table

    con = _console()
    t = Table(title="Paper Tables 1 and 2: theoretical (paper), experimental (paper), beltdyn")
    for col in ("case", "mode", "modal shape", "paper theory (Hz)", "paper exp. (Hz)", "beltdyn (Hz)",
                "vs theory (%)", "vs exp. (%)"):
        t.add_column(col, justify="right" if "Hz" in col or "%" in col or col == "mode" else "left")
    for r in rows:
        t.add_row(r.case, str(r.mode), r.shape, f"{r.theory:.1f}", "-" if r.experiment is None else f"{r.experiment:.1f}",
                  f"{r.ours:.3f}", f"{r.diff_theory_pct:+.3f}",
                  "-" if r.diff_experiment_pct is None else f"{r.diff_experiment_pct:+.2f}")
    con.print(t)


GC_YOUNG = 200_000  # the console script's first-generation threshold of the garbage collector (`run`)


def run() -> None:
    """The `beltdyn` console script: the app, then a quick exit. The interpreter's teardown (freeing
    every module numba, scipy and h5py loaded) takes ~0.2 s of a short command; it is skipped once the
    command is over: output flushed, the atexit handlers run (results-file locks released, h5py's
    files closed), no other thread alive. The exit code is the app's.

    The cyclic garbage collector runs once per GC_YOUNG net new container objects instead of Python's
    700: a command's start-up (numpy, scipy, numba, h5py, rich and the model: ~10^6 long-lived objects)
    otherwise triggers ~250 collections that traverse them, ~90 ms of a short `beltdyn transient`
    (measured), while it makes almost no cyclic garbage; a long run still collects, every GC_YOUNG."""
    import gc

    gc.set_threshold(GC_YOUNG, *gc.get_threshold()[1:])
    code: int | str | None = 0
    try:
        app()
    except SystemExit as exc:
        code = exc.code
    import threading

    if threading.active_count() > 1:  # a pool or a scheduler's thread still winding down: the normal way
        sys.exit(code)
    if code is not None and not isinstance(code, int):  # sys.exit("message"): printed, exit 1
        print(code, file=sys.stderr)
        code = 1
    import atexit

    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed pipe: nothing more to say
        pass
    atexit._run_exitfuncs()
    os._exit(code or 0)


# ------------------------------------------------------------------------------------ fit (issue 28)
@app.command()
def fit(config: Path = ConfigArg, measured: Path = typer.Option(..., "--measured", help="CSV of measured frequencies "
                                                                "(frequency [, kind, order, span, weight, scatter, "
                                                                "reference, dotted load-case keys])."),
        param: List[str] = typer.Option(..., "--param", help="A parameter to identify: KEY or KEY=LOW:HIGH.",
                                        metavar="KEY[=LOW:HIGH]"),
        output: Optional[Path] = OutOpt, set_: Optional[List[str]] = SetOpt, force: bool = ForceOpt,
        write_config: Optional[Path] = typer.Option(None, "--write-config",
                                                    help="Write the fitted configuration (TOML) here.")) -> None:
    """Identify drive parameters from measured natural frequencies (bounded least squares on the
    relative frequency errors; sensitivities from the eigenvectors): fitted values, standard
    deviations, correlations, measured against computed before and after (/fit)."""

    def body() -> None:
        from rich.table import Table

        from beltdyn.config import resolved_toml
        from beltdyn.results.fit import fit_group
        from beltdyn.study.fit import fit as identify, fitted_config, parse_parameter
        from beltdyn.study.measured import read_measured

        job = _Job(config, output, set_, force)
        data = read_measured(measured)
        params = [parse_parameter(job.cfg, p) for p in param]
        res = identify(job.cfg, data, params)
        job.add(fit_group(res))
        job.write()
        con = _console()
        for w in res.warnings:
            con.print(f"[bold yellow]warning[/]: {_one_line(w)}")
        t = Table(title=f"identified parameters ({res.evaluations} analyses; {res.status})")
        for col in ("parameter", "initial", "fitted", "std. dev.", "rel. std. dev.", "method"):
            t.add_column(col, justify="left" if col in ("parameter", "method") else "right")
        for k, p0, p, sd, ok, how in zip(res.keys, res.initial, res.fitted, res.std, res.identifiable, res.method):
            t.add_row(k, f"{p0:.6g}", f"{p:.6g}" if ok else "not identifiable", f"{sd:.3g}" if ok else "-",
                      f"{sd / abs(p):.2%}" if ok and p else "-", how)
        con.print(t)
        ref = bool((res.reference == res.reference).any())
        t = Table(title=f"measured against computed ({measured})")
        for col in ("row", "case", "mode", "measured (Hz)") + (("reference (Hz)",) if ref else ()) + \
                ("before (Hz)", "error", "after (Hz)", "error"):
            t.add_column(col, justify="left" if col in ("case", "mode") else "right")
        for k in range(len(res.measured)):
            fm = res.measured[k]
            t.add_row(str(res.row_line[k]), res.cases[int(res.case[k])], res.mode_label[k], f"{fm:.5g}",
                      *((f"{res.reference[k]:.5g}" if res.reference[k] == res.reference[k] else "-",) if ref else ()),
                      f"{res.before[k]:.5g}", f"{(res.before[k] - fm) / fm:+.2%}", f"{res.after[k]:.5g}",
                      f"{(res.after[k] - fm) / fm:+.2%}")
        con.print(t)
        extra = ""
        if ref:
            have = res.reference == res.reference
            e = (res.reference[have] - res.measured[have]) / res.measured[have]
            r = float((e @ e / len(e)) ** 0.5)
            extra = f" (reference column: {r:.3%})"
        con.print(f"RMS relative error: before {res.rms_before:.3%}, after {res.rms_after:.3%}{extra}")
        if write_config is not None:
            write_config.parent.mkdir(parents=True, exist_ok=True)
            write_config.write_text(resolved_toml(fitted_config(job.cfg, res)), encoding="utf-8")
            con.print(f"wrote the fitted configuration to {write_config}")
        con.print(f"wrote [bold]/fit[/] to {job.output}")

    _run(body)


if __name__ == "__main__":  # pragma: no cover
    run()
