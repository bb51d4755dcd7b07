"""The library-level pipeline: configuration -> system -> static -> modal (-> transient).

What the CLI, the sweeps, the benchmarks and the tests call; the analyses themselves take a
`System` and their options, never the configuration. A solver failure is re-raised with the
results that were reached attached (`exc.partial`, an `Analysis`), so a caller can still write them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from .config import DriveConfig
from .errors import SolverError
from .geometry import Layout, layout_from_config

if TYPE_CHECKING:
    from .modal import ModalResult
    from .static import StaticResult
    from .system import System


@dataclass(frozen=True, kw_only=True)
class Analysis:
    """What one run reached: the system, and the static / modal results asked for (None otherwise)."""

    config: DriveConfig
    layout: Layout
    system: "System | None" = None
    static: "StaticResult | None" = None
    modal: "ModalResult | None" = None


def analyse(cfg: DriveConfig, *, static: bool = True, modal: bool = False, n_modes: int | None = None,
            layout: Layout | None = None, compiled: bool = False) -> Analysis:
    """Geometry, system, and the static equilibrium and modes if asked for (modal implies static).

    compiled: belt forces by the compiled kernel, for a process that evaluates them many times (a
    sweep, a transient follows); the numpy reference otherwise, which spares numba's ~0.3 s start-up
    (the two agree to 1e-12, tests/test_belt_kernel.py)."""
    from .system import build_system

    layout = layout or layout_from_config(cfg)
    system = build_system(cfg, layout)
    if compiled:
        system = system.with_belt(compiled=True)
    out = Analysis(config=cfg, layout=layout, system=system)
    if not (static or modal):
        return out
    from .static import solve_static

    try:
        out = replace(out, static=solve_static(out.system, cfg.static))
        if modal:
            from .modal import solve_modes

            out = replace(out, modal=solve_modes(out.system, out.static.q, n_modes=n_modes or cfg.modal.modes,
                                                 solver=cfg.modal.solver))
    except SolverError as exc:
        exc.partial = out  # type: ignore[attr-defined]
        raise
    return out


def transient(run: Analysis, *, sink, progress=None, status=None):
    """The transient analysis from a static result (see `transient.run_transient`)."""
    from .transient import run_transient

    assert run.system is not None and run.static is not None and run.config.transient is not None
    return run_transient(run.system, run.static, run.config.transient, sink=sink, progress=progress, status=status)
