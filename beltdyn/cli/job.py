"""A command's job: its configuration, layout, output file and the groups it writes; the static
pipeline (geometry -> static -> modal) with the failed group of a stage that failed; the automatic
choice of span models and meshes (--fmax/--rtol); the checks made before any work."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

from beltdyn.cli.console import console, print_notes
from beltdyn.cli.tables import print_ladder, print_modal

class Job:
    """One command's pipeline state: config, layout, output path, hash."""

    def __init__(self, config: Path, output: Optional[Path], sets: Optional[List[str]], force: bool) -> None:
        from beltdyn.config import config_hash, load_config, resolved_toml
        from beltdyn.model.geometry import layout_from_config

        self.cfg = load_config(config, sets or [])
        print_belt_section(self.cfg.belt)
        self.layout = layout_from_config(self.cfg)  # geometric config errors come before the output check
        self.toml = resolved_toml(self.cfg)
        self.sha = config_hash(self.cfg)
        # the configuration as given: `modal --rtol` replaces cfg/toml/sha by the chosen mesh's and
        # its file records both, so that the same command is accepted on its own output again
        self.base_sha = self.sha
        self.force = force
        self.ladder = None  # the automatic choice of the span models (--fmax/--rtol), if made
        self.output = output if output is not None else Path("results") / f"{config.stem}.h5"
        from beltdyn.results.io import check_target, recover

        # what a killed earlier command left (its samples recovered, leftovers removed), whatever its
        # configuration: before the check, which may refuse a file of another configuration
        print_notes(recover(self.output))
        # early check (before any analysis); a file of a derived configuration (from this base) passes
        # here and is checked strictly, against the configuration actually written, by `write`
        check_target(self.output, config_sha256=self.sha, force=force, base_config_sha256=self.base_sha)
        from beltdyn.results.io import lock_output

        lock_output(self.output)  # held until this command ends: no other beltdyn command writes it meanwhile
        self.groups: list = []
        self.step_origin = "config"  # where a transient's step came from (`timestep.resolve_step`)
        self.unrepresented: tuple = (0.0, None, ())  # (band, layout, modes the spring spans leave out)

    def add(self, group) -> None:
        self.groups.append(group)

    def write(self) -> None:
        from beltdyn.results.io import write_groups

        print_notes(write_groups(self.output, self.groups, config_toml=self.toml, config_sha256=self.sha,
                            force=self.force, base_config_sha256=self.base_sha))

def print_belt_section(belt) -> None:
    """The belt values used when belt.section gave some: which came from the shipped table."""
    if belt.section is None:
        return
    units = {"EA": "N", "EI": "N m^2", "mass_per_length": "kg/m"}
    parts = [f"{name} {getattr(belt, name):.6g} {unit} ({'section' if name in belt.derived else 'given'})"
             for name, unit in units.items()]
    console().print(f"belt {belt.ribs}{belt.section}: " + ", ".join(parts))


def failed_group(name: str, exc: BaseException):
    from beltdyn.results.io import GroupData

    return GroupData(name=name, coords={}, variables=(), status="failed", error=str(exc))

def refined_modal(job: "Job", n_modes: int, rtol: float) -> None:
    import numpy as np
    from rich.table import Table

    from beltdyn.config import config_hash, resolved_toml
    from beltdyn.results.export import geometry_group, modal_group, static_group
    from beltdyn.study.sweep import refine_mesh

    replace = rtol_target(job)  # before the refinement: may its result replace what the output holds?
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
    con = console()
    tbl = Table(title=f"Mesh refinement to rtol = {rtol:g}: estimated relative error per mode")
    tbl.add_column("el/span", justify="right")
    for lab in ref.labels:
        tbl.add_column(lab, justify="right")
    for i, n_el in enumerate(ref.elements):
        mark = " <- chosen" if i == ref.chosen else ""
        tbl.add_row(f"{n_el}{mark}", *[f"{ref.estimate[i, j]:.1e}" for j in range(len(ref.labels))])
    con.print(tbl)
    print_modal(md)
    state = "meets" if ref.converged else "does NOT meet (mesh limit reached)"
    con.print(f"chosen mesh: {ref.elements[ref.chosen]} elements per span; it {state} rtol = {rtol:g} "
              f"(largest estimate {np.nanmax(ref.estimate[ref.chosen]):.2e}); wrote {job.output}")
    if not ref.converged:
        rtol_not_met(ref, rtol, job.output)


REFINED_GROUPS = {"geometry", "static", "modal"}  # what `modal --rtol` writes, all of it


def rtol_target(job: "Job") -> bool:
    """Before the refinement: the output of `modal --rtol` is decided whatever mesh it will choose.

    The early check (`Job`) refused a file of another configuration. A file of this configuration (or
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


def rtol_not_met(ref, rtol: float, output) -> None:
    """`modal --rtol` reached the mesh limit without meeting the tolerance: a solver failure (exit 1)
    after the table and the file (its /modal has mesh_converged = 0) are written."""
    import numpy as np

    from beltdyn.errors import SolverError

    raise SolverError(f"the modes do NOT meet rtol = {rtol:g}: largest estimated relative error "
                      f"{np.nanmax(ref.estimate[ref.chosen]):.2e} at {ref.elements[ref.chosen]} elements per span, "
                      f"the finest mesh tried (the refinement limit); its results are in {output} "
                      "(/modal mesh_converged = 0)", analysis="modal", step="mesh refinement")


def static_pipeline(job: "Job", *, modal: bool, n_modes: int | None = None, compiled: bool = False):
    """geometry -> system -> static (-> modal) through the library pipeline; writes the groups reached,
    and a failed group for the stage that failed."""
    from beltdyn.errors import SolverError
    from beltdyn.results.export import geometry_group, static_group
    from beltdyn.pipeline import analyse

    job.add(geometry_group(job.layout))
    try:
        run = analyse(job.cfg, modal=modal, n_modes=n_modes, layout=job.layout, compiled=compiled)
    except SolverError as exc:
        part = getattr(exc, "partial", None)
        if part is not None and part.static is not None:
            job.add(static_group(part.system, part.static, job.cfg.tension.target))
        job.add(failed_group(exc.analysis if exc.analysis in ("static", "modal") else "static", exc))
        job.write()
        raise
    add_results(job, run)
    job.write()
    return run


def add_results(job: "Job", run) -> None:
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
        job.add(modal_group(run.system, run.modal, run.static.q, unrepresented(job, run)))


def unrepresented(job: "Job", run) -> tuple:
    """The modes the spring spans cannot represent, below --fmax (else below the highest mode computed);
    kept on the job for `print_unrepresented`."""
    if run.system.springs is None:
        return ()
    from beltdyn.analysis.ladder import unrepresented_modes

    band = job.ladder.fmax if job.ladder is not None else float(run.modal.frequency.max(initial=0.0))
    job.unrepresented = (band, run.system.layout, unrepresented_modes(run.system, run.static, band))
    return job.unrepresented[2]


def choose_spans(job: "Job", fmax: Optional[float], rtol: Optional[float], *, command: str):
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
    print_ladder(choice)
    return run


def ladder_not_met(job: "Job") -> None:
    """The span choice could not meet rtol even with the richest rung: exit 1 after the results are written."""
    if job.ladder is None or job.ladder.met:
        return
    from beltdyn.errors import SolverError

    raise SolverError(f"the span models do NOT meet rtol = {job.ladder.rtol:g} below {job.ladder.fmax:g} Hz: largest "
                      f"estimated relative error {job.ladder.estimate:.2e} with the finest meshes tried; the results "
                      f"are in {job.output} (/static ladder_met = 0)", analysis="modal", step="span model choice")


def announce_cost(cfg, transient=None) -> None:
    """Before any work: a run estimated to take long says so, with its DOFs and steps (`guards`)."""
    from beltdyn.analysis.guards import cost_note, estimate_cost

    note = cost_note(estimate_cost(cfg, transient))
    if note:
        console().print(f"[bold]note[/]: {note}")


def check_output_volume(job: "Job", force_large: bool) -> None:
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

