"""The histories of a transient run in process, collected from its sink (the test files' one collector)."""

from __future__ import annotations

import numpy as np


def run_histories(system, static, options, *, time_key: str = "time") -> tuple[dict[str, np.ndarray], object]:
    """({series: (n_samples, ...)} with the sample times under `time_key`, the run's summary) of
    `analysis.transient.run_transient(system, static, options)`."""
    from beltdyn.analysis.transient import run_transient

    got: dict[str, list] = {}

    def sink(t, batch):
        got.setdefault(time_key, []).append(t)
        for name, value in batch.items():
            got.setdefault(name, []).append(value)

    summary = run_transient(system, static, options, sink=sink)
    return {name: np.concatenate(v) for name, v in got.items()}, summary


def arm_under_hub_force(cfg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, phi, M) after 1 s of the tensioner drive `cfg` (configs/examples/three_pulley_tensioner.toml
    with a 1 Hz vertical hub force of 30 N on pulley T ramped in over 0.25 s): the arm angle and the applied
    moment about the pivot (c - pivot) x (0, F_y). The run must complete with its energy balance within 1e-3."""
    from beltdyn.analysis.transient import run_transient
    from beltdyn.pipeline import analyse

    run = analyse(cfg)
    got = []
    summary = run_transient(run.system, run.static, cfg.transient,
                            sink=lambda t, b: got.append((t, b["arm_angle"][:, 0])))
    assert summary.status == "complete" and summary.energy_error < 1e-3
    t = np.concatenate([g[0] for g in got])
    phi = np.concatenate([g[1] for g in got])
    l = cfg.pulleys[2].arm_length
    M = l * np.cos(phi) * np.minimum(t / 0.25, 1.0) * 30.0 * np.sin(2 * np.pi * t)
    sel = t >= 1.0
    return t[sel], phi[sel], M[sel]
