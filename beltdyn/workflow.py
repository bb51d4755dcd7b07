"""The transient workflow: from an analysed drive (`pipeline.analyse`) to a /transient group streamed into
a results file, with its slack events, spectra and table of dominant peaks.

Two steps, so that a caller can speak in between (the CLI prints the step's warnings and compiles the
kernels with a spinner before the output is opened): `plan_transient` (the start state, the step's
warnings, the group's attributes) and `transient_to_file` (the run, streamed; its summaries written
when it ends). Nothing here prints: notes and progress go to the callbacks given.

Resume. While a transient runs, its resume journal `<output>.transient/` holds `spec.json` (the
configuration's SHA-256, written at the start) and `state.bin`, the stepper's last checkpoint
(`transient.TransientSnapshot` as one checksummed record, `snapshot_bytes`), replaced atomically
(a temporary file beside the output, renamed into the folder: `_replace_file`) every CHECKPOINT_SECONDS of wall time once the samples up to it are in the
group's stream journal, fsync'ed every DURABLE_SECONDS. A run that ends (complete or failed) removes the folder; an interrupted
one (Ctrl-C, SIGTERM, kill -9) leaves it, and `transient_to_file(resume=True)` continues from the
checkpoint: the group is written again with the samples up to the checkpoint, then the rest of the
run, one time axis, no sample twice.
"""

from __future__ import annotations

import itertools
import json
import os
import secrets
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from beltdyn.analysis.spectrum import amplitude_spectrum, find_peaks
from beltdyn.analysis.timestep import describe, frequency_error, step_warnings
from beltdyn.analysis.transient import TransientSnapshot, prepare, run_transient, snapshot_bytes, snapshot_from_bytes
from beltdyn.analysis.transient_setup import wrap_slip_notes
from beltdyn.errors import ConfigError, OutputError
from beltdyn.pipeline import Analysis, transient_start
from beltdyn.results.files import temp_name
from beltdyn.results.io import GroupData, StreamWriter, Variable, WriteFailure, fsync_dir, read_group, recover

ORDER_SERIES = ("span_tension", "hub_load", "arm_angle", "pulley_speed", "rotor_speed",
                "decoupler_torque")  # tracked by [transient.orders]
SPECTRUM_SERIES = ("span_tension", "hub_load", "bearing_force", "midspan_displacement", "pulley_speed", "driver_torque",
                   "arm_angle")


@dataclass(frozen=True, kw_only=True)
class TransientPlan:
    """What a transient run starts from: the system and static state (`pipeline.transient_start`), the
    modes its peaks are compared with (None without spectra), the recorder's setup
    (`transient.prepare`), the warnings about the step (said before the run), the step described in
    words and the /transient group's attributes."""

    system: Any
    static: Any
    modal: Any
    setup: Any
    warnings: tuple[str, ...]
    step_text: str
    attrs: Mapping[str, Any]


@dataclass(frozen=True, kw_only=True)
class TransientOutcome:
    """A finished run: its summary (`transient.TransientSummary`), the span names, the spectral peaks
    ((series, units, [spectrum.Peak]) per series; empty without spectra) and the excitation frequency."""

    summary: Any
    spans: tuple[str, ...]
    peaks: tuple
    excitation_frequency: float | None


def plan_transient(run: Analysis, *, step_origin: str = "config") -> TransientPlan:
    """The start state, setup, step warnings and group attributes of `run`'s transient
    (run.config.transient, its step resolved already)."""
    cfg = run.config
    opts = cfg.transient
    (model, res), mres = transient_start(run), run.modal
    if mres is not None and model.belt_speed != run.system.belt_speed:  # the peaks against the modes at the start speed
        from beltdyn.analysis.modal import solve_modes

        mres = solve_modes(model, res.q, n_modes=len(mres.frequency), solver=cfg.modal.solver)
    setup = prepare(model, res, opts)
    refuse_unresolving_step(cfg, opts, setup, mres, step_origin=step_origin)
    step_text, band, band_acc = describe(opts.step, accuracy=opts.accuracy, fmax=opts.fmax, rho_inf=opts.rho_inf)
    attrs = {"rho_inf": opts.rho_inf, "step_s": opts.step, "duration_s": opts.duration,
             "output_interval_s": opts.output_interval, "start": opts.start, "step_origin": step_origin,
             "resolved_fmax_Hz": band, "resolved_accuracy": band_acc}
    if opts.fmax is not None:
        attrs["fmax_frequency_error"] = frequency_error(opts.fmax, opts.step, opts.rho_inf)
    return TransientPlan(system=model, static=res, modal=mres, setup=setup,
                         warnings=step_warnings_of(opts, setup, mres) + wrap_slip_notes(model),
                         step_text=step_text, attrs=MappingProxyType(attrs))


CHECKPOINT_SECONDS = 1.0  # wall time between checkpoints of a running transient (its resume journal)
DURABLE_SECONDS = 5.0  # ... of which one this often is fsync'ed (~20 ms on a busy disk); the others are safe from
# a kill -9 (the page cache), and one torn by a power loss fails its checksum (resume refused, exit 2)
RESUME_STATE = "state.bin"
RESUME_SPEC = "spec.json"


def resume_folder(output: Path) -> Path:
    """The resume journal of the transient written to `output`: `<output>.transient/`."""
    return Path(str(output) + ".transient")


def _replace_file(folder: Path, name: str, data: bytes, *, durable: bool = True) -> None:
    """`folder/name` replaced by `data` atomically (temporary file, rename: a reader, or the next run
    after a kill -9, sees the old or the new file whole); durable: fsync'ed first and the folder after
    (also safe from a power loss). The temporary file lies beside the output the journal belongs to,
    named as a results file's temporary root (`results.files.temp_name`): one that a kill -9 leaves
    behind is removed, with the dead writer's other leftovers, by the next command on that output."""
    output = folder.with_name(folder.name.removesuffix(".transient"))
    tmp = temp_name(output, secrets.token_hex(6))
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, folder / name)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if durable:
        fsync_dir(folder)


def start_resume_journal(output: Path, config_sha256: str) -> Path:
    """A new resume journal for a run of the configuration `config_sha256` (an older one removed)."""
    folder = resume_folder(output)
    shutil.rmtree(folder, ignore_errors=True)
    try:
        folder.mkdir(parents=True)
        _replace_file(folder, RESUME_SPEC, json.dumps({"config_sha256": config_sha256, "group": "transient"}).encode())
    except OSError as exc:
        raise WriteFailure(f"{folder}: cannot start the transient's resume journal: {exc}") from exc
    return folder


def write_checkpoint(folder: Path, snap: TransientSnapshot, *, durable: bool = True) -> None:
    """The snapshot as the resume journal's state (replacing the previous one atomically; durable: on
    the disk too, see `_replace_file`)."""
    try:
        _replace_file(folder, RESUME_STATE, snapshot_bytes(snap), durable=durable)
    except OSError as exc:
        raise WriteFailure(f"{folder / RESUME_STATE}: cannot write the transient's checkpoint: {exc}") from exc


def read_checkpoint(output: Path, config_sha256: str, *, source: str = "") -> TransientSnapshot | None:
    """The last checkpoint of the interrupted transient of `output` (None: it was interrupted before
    its first). ConfigError (exit 2) when there is no resume journal, or when it belongs to another
    configuration (both hashes named); OutputError (exit 2) when its checkpoint fails its checksum,
    WriteFailure (exit 1) when it cannot be read."""
    folder = resume_folder(output)
    try:
        spec = json.loads((folder / RESUME_SPEC).read_text())
    except (OSError, ValueError):
        raise ConfigError(f"no interrupted transient to resume for {output} (no journal {folder}); "
                          "run without --resume", file=source, key="--resume") from None
    journaled = str(spec.get("config_sha256", ""))
    if journaled != config_sha256:
        raise ConfigError(f"the interrupted transient of {output} ran configuration sha256 {journaled}, "
                          f"this one is sha256 {config_sha256}: resume with the same configuration and options "
                          "(or run without --resume)", file=source, key="--resume")
    try:
        data = (folder / RESUME_STATE).read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise WriteFailure(f"{folder / RESUME_STATE}: cannot read the checkpoint: {exc}") from exc
    try:
        return snapshot_from_bytes(data)
    except ValueError as exc:
        raise OutputError(f"{folder / RESUME_STATE}: {exc}; run without --resume") from exc


def samples_before(output: Path, snap: TransientSnapshot, names: list[str]) -> tuple[np.ndarray, dict]:
    """The first snap.delivered samples of /transient in `output` (time (k,), {series: (k, ...)}), the
    part of the interrupted run that the checkpoint follows. OutputError when the file holds fewer."""
    group = read_group(output, "transient")
    t = np.asarray(group["coords"].get("time", np.zeros(0)), dtype=float)
    k = snap.delivered
    if len(t) < k or any(name not in group["variables"] for name in names):
        raise OutputError(f"{output}: /transient holds {len(t)} samples, its checkpoint at t = {snap.time:.6g} s "
                          f"follows {k}: run without --resume")
    return t[:k], {name: np.asarray(group["variables"][name])[:k] for name in names}


def transient_to_file(plan: TransientPlan, opts, *, output: Path, config_toml: str, config_sha256: str,
                      notes: Callable[[list[str]], None] = lambda notes: None,
                      progress: Callable[[float], None] | None = None, resume: bool = False,
                      source: str = "", checkpoint_seconds: float = CHECKPOINT_SECONDS) -> TransientOutcome:
    """Run the planned transient (options `opts`, the configuration's [transient]) streaming its histories
    into /transient of `output` (`results.io.StreamWriter`: running while it runs; complete, failed or
    interrupted at the end, the samples so far kept), then its summaries, slack events, spectra and
    peaks. notes: called with what the results layer did on its own (a recovered group) and with what
    a resume starts from; progress: called with the simulated time. resume: continue the interrupted
    run of `output` from its last checkpoint (`read_checkpoint`; source: the configuration file, for
    its messages); the outcome is that of the whole run. checkpoint_seconds: wall time between the
    checkpoints of its resume journal."""
    model, res, setup, early = plan.system, plan.static, plan.setup, plan.warnings
    shapes = {name: len(v) for name, v in setup.coords.items()}
    series = {s.name: (tuple(shapes[d] for d in s.dims), s.units, s.dims) for s in setup.series}
    keep = {s.name for s in setup.series if s.name in SPECTRUM_SERIES} if opts.spectrum.enabled else set()
    spans = tuple(model.layout.span_name(i) for i in range(model.layout.n))
    snap, before = None, None
    if resume:
        snap = read_checkpoint(output, config_sha256, source=source)
        notes(recover(output))  # a writer killed (kill -9): its samples into the file first
        if snap is None:
            notes([f"{output}: the interrupted transient made no checkpoint yet: it starts over"])
        else:
            before = samples_before(output, snap, list(series))
            notes([f"{output}: resuming the transient at t = {snap.time:.6g} s (step {snap.steps}, "
                   f"{snap.delivered} samples kept)"])
    folder = start_resume_journal(output, config_sha256) if snap is None else resume_folder(output)
    with StreamWriter(output, "transient", series=series, coords=setup.coords, attrs=dict(plan.attrs),
                      config_toml=config_toml, config_sha256=config_sha256, force=True) as writer:
        notes(writer.notes)
        if "dof" in setup.coords:  # full state recorded: the unit of each DOF beside q and v
            from beltdyn.results.export import dof_unit_variable

            writer.add_variables((dof_unit_variable(model),))
        if before is not None:
            writer.append(*before)

        durable_at = [-np.inf]

        def checkpoint(state: TransientSnapshot) -> None:
            writer.flush()  # the samples it follows are in the stream journal first
            now = time.monotonic()
            durable = now - durable_at[0] >= DURABLE_SECONDS
            write_checkpoint(folder, state, durable=durable)
            if durable:
                durable_at[0] = now

        try:
            summary = run_transient(model, res, opts, sink=writer.append, progress=progress, setup=setup,
                                    resume=snap, on_checkpoint=checkpoint, checkpoint_seconds=checkpoint_seconds)
        except Exception:  # a failed run is not resumed: it would fail again (the samples stay, marked failed)
            shutil.rmtree(folder, ignore_errors=True)
            raise
        ev = summary.slack_events
        writer.set_attrs(steps=summary.steps, refactorizations=summary.refactorizations,
                         newton_iterations=summary.newton_iterations,
                         energy_balance_error=summary.energy_error, energy_moved_J=summary.energy_moved,
                         step_halvings=summary.step_halvings, smallest_step_s=summary.min_step,
                         n_slack_events=int(len(ev)),
                         warnings=list(early) + [w for w in summary.warnings if w not in early])
        if opts.orders.orders:
            late = order_tracking_variables(writer, setup, opts, model.layout.names)
            if late:
                writer.set_attrs(warnings=list(early) + [w for w in summary.warnings if w not in early] + late)
        if np.isfinite(summary.worst_slip_margin[0]):
            writer.set_attrs(worst_slip_margin=summary.worst_slip_margin[0],
                             worst_slip_time_s=summary.worst_slip_margin[1],
                             worst_slip_pulley=summary.worst_slip_margin[2])
        if len(ev):
            writer.add_subgroup(slack_events_group(ev, spans))
        peaks = []
        if keep:  # the spectrum window is read back from the file: nothing is kept while streaming
            t_all = writer.read("time")
            first = int(np.searchsorted(t_all, opts.spectrum.start - 1e-9 * opts.output_interval))
            if len(t_all) - first >= 8:
                kept = {name: writer.read(name, first) for name in keep}
                peaks = spectra(writer, setup, t_all[first:], kept, plan.modal, opts)
    shutil.rmtree(folder, ignore_errors=True)  # complete: nothing to resume
    return TransientOutcome(summary=summary, spans=spans, peaks=tuple(peaks),
                            excitation_frequency=setup.excitation_frequency)


def order_tracking_variables(writer, setup, opts, pulley_names) -> list[str]:
    """/transient order_amplitude and order_phase (speed, order, channel) of the recorded ORDER_SERIES
    against the reference pulley's angle (`analysis.orders.order_tracking`, options [transient.orders]),
    added to `writer`; returns warnings (the run too short for one window: nothing added)."""
    # imported here, not at the top: scipy.interpolate (which it needs) costs ~0.3 s of every `beltdyn transient`'s
    # start-up on a quiet machine (python -X importtime, after scipy.linalg, scipy.sparse and h5py), and only a
    # run with [transient.orders] uses it
    from beltdyn.analysis.orders import order_tracking

    o = opts.orders
    ref = o.reference if o.reference is not None else opts.rotation[0].pulley
    j = list(pulley_names).index(ref)
    t = writer.read("time")
    chosen = [s for s in setup.series if s.name in ORDER_SERIES]
    labels = [lab for s in chosen for lab in channel_labels(s, setup.coords)]
    values = np.column_stack([writer.read(s.name).reshape(len(t), -1) for s in chosen])
    try:
        ot = order_tracking(t, writer.read("pulley_angle")[:, j], values, o.orders, revolutions=o.revolutions,
                            samples=o.samples)
    except ValueError as err:
        return [f"order tracking skipped: {err}"]
    units = [s.units for s in chosen for _ in channel_labels(s, setup.coords)]
    dims = ("speed", "order", "channel")
    writer.add_variables((
        Variable(name="order_amplitude", data=ot.amplitude, dims=dims, units="mixed (see order_unit)",
                 description=f"amplitude of each order of each channel per window of {o.revolutions} revolutions "
                             f"of {ref} (its mean speed)"),
        Variable(name="order_phase", data=ot.phase, dims=dims, units="rad",
                 description=f"phase of each order: amplitude cos(order theta + phase), theta the angle of {ref} "
                             f"from the first sample"),
        Variable(name="order_unit", data=units, dims=("channel",), units="1"),
        Variable(name="order_time", data=ot.time, dims=("speed",), units="s", description="middle of each window")),
        coords={"speed": ot.speed, "order": ot.orders, "channel": labels},
        coord_units={"speed": "rad/s", "order": "1", "channel": "1"})
    return []


def slack_events_group(ev: np.ndarray, spans: tuple[str, ...]) -> GroupData:
    """/transient/slack_events from the events (n, 4): time, span index, slack (1) or taut (0), min force."""
    return GroupData(
        name="slack_events", coords={"event": np.arange(1, len(ev) + 1)},
        variables=(Variable(name="event_time", data=ev[:, 0], dims=("event",), units="s"),
                   Variable(name="event_span", data=[spans[int(i)] for i in ev[:, 1]], dims=("event",), units="1"),
                   Variable(name="slack", data=ev[:, 2].astype(np.int8), dims=("event",), units="1",
                            description="1: the span went slack (compressed), 0: taut again"),
                   Variable(name="min_force", data=ev[:, 3], dims=("event",), units="N")))


def spectra(writer, setup, t, kept, mres, opts):
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
        labels = channel_labels(s, setup.coords)
        peaks.append((s.name, s.units, find_peaks(spec, labels=labels, n_peaks=opts.spectrum.peaks,
                                                  excitation_frequency=setup.excitation_frequency,
                                                  modal_frequencies=modal_f)))
    if freq is not None:
        writer.add_subgroup(GroupData(name="spectrum", coords={"frequency": freq}, coord_units={"frequency": "Hz"},
                                      variables=tuple(variables)))
    store_peaks(writer, peaks, setup.excitation_frequency)
    return peaks


def shown_peaks(peaks):
    """The rows of the printed peak table: (series, units, peak), the 4 largest peaks of each series
    (round-off ripples below 1e-6 of its largest dropped)."""
    rows = []
    for name, units, plist in peaks:
        top = max((p.amplitude for p in plist), default=0.0)
        rows += [(name, units, p) for p in [p for p in plist if p.amplitude >= 1e-6 * top][:4]]
    return rows


def peak_relation(p, f_exc) -> str:
    parts = []
    if p.harmonic:
        parts.append(f"harmonic {p.harmonic} of the excitation ({f_exc:g} Hz)" if f_exc else f"harmonic {p.harmonic}")
    if p.nearest_mode:
        parts.append(f"nearest mode {p.nearest_mode} at {p.mode_frequency:.3f} Hz ({p.mode_distance_pct:+.2f} %)")
    return "; ".join(parts) or "-"


def store_peaks(writer, peaks, f_exc=None) -> None:
    """/transient/peaks: the printed table of dominant spectral peaks, one row per peak (series,
    channel, frequency, amplitude in its series' units, harmonic, nearest mode, relation text).
    `peaks` as returned by `spectra` (series name, units, [spectrum.Peak]); nothing for no peaks.
    Called by `spectra`, so `run_transient_command` needs no change."""
    rows = shown_peaks(peaks)
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
            Variable(name="relation", data=[peak_relation(p, f_exc) for _, _, p in rows], dims=("peak",), units="1"),
        ),
        attrs={"excitation_frequency_Hz": float(f_exc) if f_exc else nan}))


def channel_labels(series, coords) -> list[str]:
    if not series.dims:
        return [series.name]
    axes = [coords[d] for d in series.dims]
    return [f"{series.name}[{', '.join(map(str, combo))}]" for combo in itertools.product(*axes)]


def refuse_unresolving_step(cfg, opts, setup, mres, *, step_origin: str) -> None:
    """A step that resolves nothing of the run (`timestep.unresolved_motion`) is refused before the
    transient starts: ConfigError naming --step or transient.step (exit 2)."""
    from beltdyn.analysis.timestep import unresolved_motion
    from beltdyn.errors import ConfigError

    lowest = float(mres.frequency.min()) if mres is not None and len(mres.frequency) else None
    why = unresolved_motion(opts.step, duration=opts.duration, rho_inf=opts.rho_inf,
                            excitation_frequency=setup.excitation_frequency, lowest_frequency=lowest,
                            fmax=opts.fmax, accuracy=opts.accuracy)
    if why is not None:
        key = {"--step": "--step", "accuracy": "transient.accuracy"}.get(step_origin, "transient.step")
        raise ConfigError(why, file=cfg.source, key=key)


def step_warnings_of(opts, setup, mres) -> tuple[str, ...]:
    """The step against the excitation and the highest mode the run is meant to resolve:
    transient.fmax if given, else the highest of the modes computed for the spectra (modal.modes)."""
    f_mode, source = None, ""
    if opts.fmax is not None:
        f_mode, source = float(opts.fmax), "transient.fmax"
    elif mres is not None and len(mres.frequency):
        f_mode = float(mres.frequency.max())
        source = f"mode {int(mres.frequency.argmax()) + 1}, the highest of the {len(mres.frequency)} computed (modal.modes)"
    return step_warnings(opts.step, excitation_frequency=setup.excitation_frequency, mode_frequency=f_mode,
                         mode_source=source)


