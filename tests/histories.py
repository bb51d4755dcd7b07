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
