"""What a run will cost, known from the configuration before anything is built (issue 10).

The memory guard itself is `system.check_model_size` (a model that cannot fit is exit 2 naming
mesh.elements_per_span); this module adds the wall-time estimate the CLI announces before a long run.
The rates are this machine class's, from `make bench` (2 cores, single-threaded BLAS): static + modal
about 50 us per DOF (160 el/span, 1283 DOFs: 65 ms; 4000 el/span, 32 003 DOFs: 1.6 s), a transient
step about 5 us + 0.15 us per DOF (paper bench: 10 el/span 19 us, 40 el/span 38 us; the FEAD
example, 288 DOFs with an arm: 76 us). An estimate, good to a factor of about two: more Newton
iterations per step (a slackening span, large motion) cost more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from beltdyn.config import DriveConfig, TransientOptions

STATIC_S_PER_DOF = 50e-6  # s per DOF: geometry, static and modal analysis
STEP_S = 5e-6  # s: a transient step's fixed cost
STEP_S_PER_DOF = 0.15e-6  # s per DOF and transient step
ANNOUNCE_ABOVE_S = 30.0  # the CLI announces a run estimated to take longer than this


@dataclass(frozen=True, kw_only=True)
class CostEstimate:
    """n_dof (an upper bound: 3 per pulley), memory (bytes, `system.BYTES_PER_DOF`), wall times (s)."""

    n_dof: int
    memory: int
    static_s: float
    steps: int = 0  # transient steps (duration / step), 0 without a transient
    transient_s: float = 0.0

    @property
    def total_s(self) -> float:
        return self.static_s + self.transient_s


def estimate_cost(cfg: DriveConfig, transient: TransientOptions | None = None) -> CostEstimate:
    """The cost of the static (+ modal) analysis of `cfg`, and of the transient `transient` (its step
    resolved, `timestep.resolve_step`) if given."""
    from beltdyn.model.system import BYTES_PER_DOF, model_dofs

    n = model_dofs(cfg)
    est = CostEstimate(n_dof=n, memory=n * BYTES_PER_DOF, static_s=STATIC_S_PER_DOF * n)
    if transient is None or not transient.step:
        return est
    steps = int(math.ceil(transient.duration / transient.step - 1e-9))
    return CostEstimate(n_dof=n, memory=est.memory, static_s=est.static_s, steps=steps,
                        transient_s=steps * (STEP_S + STEP_S_PER_DOF * n))


def duration_text(seconds: float) -> str:
    """'40 s', '12 min', '3.5 h', '2.1 days'."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 172800:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


def cost_note(est: CostEstimate) -> str | None:
    """The sentence the CLI prints before a run estimated above ANNOUNCE_ABOVE_S, else None."""
    if est.total_s <= ANNOUNCE_ABOVE_S:
        return None
    parts = [f"about {duration_text(est.total_s)} of work ahead: {est.n_dof:,} DOFs (~{est.memory / 1e9:.2g} GB)"]
    if est.steps:
        parts.append(f"{est.steps:,} transient steps (~{duration_text(est.transient_s)})")
    return "; ".join(parts) + " — an estimate from the DOF count; Ctrl-C stops it (a transient keeps its samples)"
