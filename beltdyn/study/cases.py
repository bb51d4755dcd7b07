"""One sweep case: the base configuration with the case's overrides applied (`config.with_overrides`),
analysed by a top-level, picklable function (`run_case`, in chunks `run_chunk`), so the same code runs
in beltdyn's local worker processes and on Dask workers.
"""

from __future__ import annotations

import copy
import time
import tomllib
from typing import Any

import numpy as np

from beltdyn.model.reuse import Reuse


def load_case_modules(analysis: str) -> None:
    """Import what the cases of `analysis` and this process's assembly run, in the sweep's process before
    it forks its local workers (`pool.run_pool`), so that the workers share these modules instead of each
    importing them at its first case: the pipeline and the static analysis; for a modal sweep the modal
    analysis, the scipy.linalg it calls at its first solve and the scipy.optimize of the mode tracking
    (`tracking.match_modes`, which this process would import at its first tracked case anyway, while the
    workers run). Measured on the 61-speed Campbell sweep of the paper bench, 2 workers: the sweep's CPU
    time 3.25 -> 2.39 s (each worker imported scipy.linalg and the analyses, about 0.3 s of CPU)."""
    import beltdyn.analysis.static  # noqa: F401
    import beltdyn.pipeline  # noqa: F401

    if analysis == "modal":
        import scipy.linalg  # noqa: F401
        import scipy.optimize  # noqa: F401

        import beltdyn.analysis.modal  # noqa: F401


def run_case(base_toml: str, source: str, assignments: list[str], analysis: str, n_modes: int,
             tables: dict[str, bytes] | None = None) -> dict:
    """One case, self-contained (picklable arguments, plain-dict result) for any executor: the CSV
    tables travel with it (`config.table_bytes`), so a worker on another machine needs no files."""
    return case_of(tomllib.loads(base_toml), source, assignments, analysis, n_modes, tables)


def case_of(raw: dict, source: str, assignments: list[str], analysis: str, n_modes: int,
            tables: dict[str, bytes] | None = None, reuse: Reuse | None = None) -> dict:
    """`run_case` of the base configuration parsed (`raw`, the TOML's dict; the case's overrides are
    applied to it: pass a copy). reuse: the chunk's store of L0 fits, DOF maps and patterns
    (`pipeline.analyse`'s); None: the case makes its own."""
    from beltdyn.config import apply_override, config_from_dict
    from beltdyn.errors import BeltdynError

    t0 = time.perf_counter()
    out: dict[str, Any] = {"failed": 0, "error": ""}
    try:
        for a in assignments:
            apply_override(raw, a, file=source)
        cfg = config_from_dict(raw, file=source, tables=tables)
        if analysis == "transient" and cfg.transient is not None:
            from dataclasses import replace

            from beltdyn.analysis.timestep import resolve_step  # the step each case's accuracy (or step) asks for

            cfg = replace(cfg, transient=resolve_step(cfg.transient)[0])
        from beltdyn.pipeline import analyse

        run = analyse(cfg, modal=analysis == "modal", n_modes=n_modes + 4, reuse=reuse)
        model, st = run.system, run.static
        out["mean_tension"] = st.mean_tension
        out["span_tension"] = st.span_tension
        out["hub_load"] = st.hub_load
        out["pulley_center"] = st.pulley_center
        if model.arms is not None:  # the tensioner's working curve over the swept load
            out["arm_angle"] = st.arm_angle
            out["arm_torque"] = st.arm_torque
        if st.slip_margin is not None and not np.all(np.isnan(st.slip_margin)):
            out["slip_margin"] = st.slip_margin
        if model.belt_speed or cfg.running is not None:  # the running belt's speeds (a Campbell diagram)
            from beltdyn.model.geometry import driver_speed_of

            out["belt_speed"] = float(model.belt_speed)
            out["driver_speed"] = driver_speed_of(model.belt_speed, model.layout, model.driver)
        if analysis == "modal":
            md = run.modal
            out["frequency"] = md.frequency
            out["growth_rate"] = md.growth_rate if md.growth_rate is not None else np.zeros(len(md.frequency))
            out["shapes"] = md.shapes
            out["mshapes"] = np.asarray((model.mass_matrix(st.q) @ md.shapes.T).T)
            out["kind"] = np.array(md.kind)
            out["order"] = md.order
            out["span"] = md.span
            out["label"] = np.array(md.label)
        elif analysis == "transient":
            out.update(_transient_case(run))
    except BeltdynError as exc:
        out = {"failed": 1, "error": str(exc)}
    except Exception as exc:  # a defect in one case must not take the sweep down: record it
        out = {"failed": 1, "error": f"{type(exc).__name__}: {exc}"}
    out["wall_time"] = time.perf_counter() - t0
    return out


def _transient_case(run) -> dict:
    """Steady-state amplitudes (first harmonic of the excitation, and half peak-to-peak) of the
    span tensions, hub loads and bearing forces after transient.spectrum.start."""
    from beltdyn.analysis.spectrum import amplitude_spectrum, harmonic_content
    from beltdyn.analysis.transient import prepare, run_transient

    from beltdyn.pipeline import transient_start

    cfg = run.config
    system, static = transient_start(run)
    setup = prepare(system, static, cfg.transient)
    keep = ("span_tension", "hub_load", "bearing_force")
    got: dict[str, list] = {k: [] for k in keep if any(s.name == k for s in setup.series)}
    times: list = []

    def sink(t, batch):
        sel = t >= cfg.transient.spectrum.start
        times.append(t[sel])
        for k in got:
            got[k].append(batch[k][sel])

    summary = run_transient(system, static, cfg.transient, sink=sink, setup=setup)
    t = np.concatenate(times)
    out: dict[str, Any] = {"n_slack_events": len(summary.slack_events)}
    for k, parts in got.items():
        x = np.concatenate(parts)
        out[f"{k}_half_range"] = 0.5 * (x.max(axis=0) - x.min(axis=0))
        if setup.excitation_frequency and len(t) >= 8:
            spec = amplitude_spectrum(t, x, start=t[0])
            out[f"{k}_first_harmonic"] = harmonic_content(spec, setup.excitation_frequency, n_harmonics=1)[0]
    return out


def run_chunk(base_toml: str, source: str, tables: dict[str, bytes], items: list[tuple[int, list[str]]],
              analysis: str, n_modes: int) -> list[tuple[int, dict]]:
    """`run_case` of each (case index, overrides) of `items`, the base TOML parsed once for the chunk
    (each case applies its overrides to a copy: 0.05 ms against the 0.33 ms of a parse of the paper bench),
    and the L0 fit, DOF map and assembly patterns once for the cases of one drive (a `Reuse`, `pipeline.analyse`'s:
    a sweep of loads, tensions or speeds fits and numbers once a chunk)."""
    raw = tomllib.loads(base_toml)
    reuse = Reuse()
    return [(i, case_of(copy.deepcopy(raw), source, a, analysis, n_modes, tables, reuse)) for i, a in items]
