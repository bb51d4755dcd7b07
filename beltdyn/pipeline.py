"""The library-level pipeline: configuration -> system -> static -> modal (-> transient).

What the CLI, the sweeps, the benchmarks and the tests call; the analyses themselves take a
`System` and their options, never the configuration. A solver failure is re-raised with the
results that were reached attached (`exc.partial`, an `Analysis`), so a caller can still write them.

Solved geometry. The static analysis runs on the layout at the solved pulley positions
(`static.solve_static_on_solved_geometry`): the system is first laid out on the L0 fit
(`geometry.layout_from_config`), and whenever the static solve moves a pulley (the adjustable
pulley's tension travel, a bearing's deflection) the belt path is laid anew at the solved centres,
with tangent points, spans and wraps recomputed and the spans' reference lengths keeping the belt's
undeformed length L0, the system rebuilt and solved again until the pulleys stay where they are laid.
So the spans meet every pulley on its tangent, and a free pulley's two span tensions balance. The
modal and transient analyses run on that final system. `Analysis.layout` and `Analysis.system` are
the final (solved) ones; `Analysis.fit_layout` is the L0 fit, which is what `/geometry` shows (the
answer to "where must the adjustable pulley sit for the belt of length L0 to fit"); `/static`
holds the solved pulley centres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from beltdyn.config import DriveConfig
from beltdyn.errors import SolverError
from beltdyn.model.geometry import Layout, layout_from_config
from beltdyn.model.reuse import Reuse

if TYPE_CHECKING:
    from beltdyn.analysis.response import ResponseResult
    from beltdyn.analysis.modal import ModalResult
    from beltdyn.analysis.static import StaticResult
    from beltdyn.model.system import DriveFacts, System


@dataclass(frozen=True, kw_only=True)
class Analysis:
    """What one run reached: the system, and the static / modal results asked for (None otherwise)."""

    config: DriveConfig
    layout: Layout  # the final layout: at the solved pulley positions once the static analysis ran
    system: "System | None" = None  # the final system (laid out on `layout`)
    static: "StaticResult | None" = None
    modal: "ModalResult | None" = None
    fit_layout: Layout | None = None  # the L0 fit (what /geometry shows)
    static_passes: int = 0  # layouts the static analysis solved on (1: no pulley moved)


def analyse(cfg: DriveConfig, *, static: bool = True, modal: bool = False, n_modes: int | None = None,
            layout: Layout | None = None, compiled: bool = False, belt_speed: float | None = None,
            facts: "DriveFacts | None" = None, reuse: Reuse | None = None) -> Analysis:
    """Geometry, system, and the static equilibrium (on the solved geometry) and modes if asked for
    (modal implies static). `layout`: the L0 fit, if already computed. belt_speed (m/s): the running
    belt's speed instead of [running]'s (`running.belt_speed_of`); the static equilibrium is then the
    running one and the modes the gyroscopic ones. facts: the configuration's `DriveFacts` on `layout`
    (`drive_facts`), if at hand: the analyses of one configuration at several belt speeds share them
    (`response_of`). reuse: the store of a caller that analyses many configurations of few drives (a
    sweep's chunk, the fit to measurements, the mesh refinement, the speeds of a response: `reuse.Reuse`):
    the analysis takes its L0 fit, DOF map and assembly patterns from there, or adds the ones it makes.

    compiled: belt forces by the compiled kernel, for a process that evaluates them many times (a
    sweep, a transient follows); the numpy reference otherwise, which spares numba's ~0.3 s start-up
    (the two agree to 1e-12, tests/test_belt_kernel.py)."""
    from beltdyn.analysis.static import solve_static_on_solved_geometry
    from beltdyn.model.system import DeferredSystem, build_system, check_model_size, drive_facts

    def build(lay: Layout, stretch=None, spring_free=None) -> "System":
        system = build_system(cfg, lay, prestrain_stretch=stretch, spring_free=spring_free, belt_speed=belt_speed,
                              facts=facts, reuse=reuse)
        return system.with_belt(compiled=True) if compiled else system

    if facts is None:
        check_model_size(cfg)  # before the L0 fit: an impossible mesh is refused at once
        if layout is None:
            layout = layout_from_config(cfg) if reuse is None else reuse.fit(cfg)
        facts = drive_facts(cfg, layout, reuse=reuse)  # what every build of this analysis takes from the configuration alone
    elif layout is not facts.layout:
        raise ValueError("analyse: the facts given are of another layout than `layout`")
    if not (static or modal):
        return Analysis(config=cfg, layout=layout, system=build(layout), fit_layout=layout)
    initial = DeferredSystem(cfg, layout, build, facts=facts, belt_speed=belt_speed)  # built only if the static analysis solves on the L0 fit
    solved = None

    def reached(modes=None) -> Analysis:  # what the run reached (the partial results of a failure)
        if solved is None:
            return Analysis(config=cfg, layout=layout, system=None, fit_layout=layout)
        return Analysis(config=cfg, layout=solved.system.layout, system=solved.system, static=solved.static,
                        modal=modes, fit_layout=layout, static_passes=solved.passes)

    try:
        solved = solve_static_on_solved_geometry(initial, build, cfg.static)
        if not modal:
            return reached()
        from beltdyn.analysis.modal import solve_modes

        return reached(solve_modes(solved.system, solved.static.q, n_modes=n_modes or cfg.modal.modes,
                                   solver=cfg.modal.solver, tangent=solved.tangent))
    except SolverError as exc:
        exc.partial = reached()  # type: ignore[attr-defined]
        raise


def initial_belt_speed(system: "System", opts) -> float:
    """The belt speed (m/s) a transient starts at: its prescribed rotation's nominal speed at t = 0
    over the pulley's belt-travel factor u_rot (with a speed ramp its start_speed: 0 from rest, the idle
    speed of a run-up from idle),
    or without a prescribed speed the system's constant belt speed ([running]); 0 without the transport
    terms (transient.transport = false)."""
    if not opts.transport:
        return 0.0
    for r in opts.rotation:
        if r.speed != 0.0:
            speed = r.start_speed if r.ramp_time > 0.0 else r.speed
            if speed == 0.0:
                return 0.0
            from beltdyn.analysis.transient import belt_travel

            return float(speed / belt_travel(system)[system.rot_dof[system.pulley_index(r.pulley)]])
    return float(system.belt_speed)


def transient_start(run: Analysis):
    """(system, static result) the transient starts from. transient.start = "static": the solved
    drive (laid out at the solved positions) at the belt speed the run starts with
    (`initial_belt_speed`: the running equilibrium, solved again if [running] asked for another speed).
    "rest": the stress-free reference, so the drive on the L0 fit (q = 0 there is stress-free; the
    re-laid system's q = 0 carries the tension) with its own static solution for the spring preloads."""
    cfg = run.config
    speed = initial_belt_speed(run.system, cfg.transient) if cfg.transient is not None else run.system.belt_speed
    if cfg.transient is not None and cfg.transient.start == "rest" and run.fit_layout is not None \
            and run.fit_layout is not run.layout:
        from beltdyn.analysis.static import solve_static
        from beltdyn.model.system import build_system

        system = build_system(cfg, run.fit_layout, belt_speed=speed)
        return system, solve_static(system, cfg.static)
    if speed != run.system.belt_speed:
        again = analyse(cfg, layout=run.fit_layout, belt_speed=speed)
        return again.system, again.static
    return run.system, run.static


def transient(run: Analysis, *, sink, progress=None, status=None):
    """The transient analysis from a static result (see `transient.run_transient`), with the step
    resolved from the configuration (`timestep.resolve_step`: transient.accuracy and fmax, or step)."""
    from beltdyn.analysis.timestep import resolve_step
    from beltdyn.analysis.transient import run_transient

    assert run.system is not None and run.static is not None and run.config.transient is not None
    opts, _ = resolve_step(run.config.transient)
    system, static = transient_start(run)
    return run_transient(system, static, opts, sink=sink, progress=progress, status=status)


def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel a transient runs, with the signatures it
    runs them with: a few steps of a small drive (slide, backside arm with friction, belt and Rayleigh
    damping, a prescribed rotation and a load, gravity) through `run_transient` (the band Cholesky
    and band LU factors share one signature: both column-major). `make` calls it at install; the CLI
    before a transient's output is opened."""
    from beltdyn import jitcache
    from beltdyn.analysis.transient import WARM_DRIVE, entry_kernels, run_transient
    from beltdyn.config import config_from_dict

    cfg = config_from_dict(WARM_DRIVE, file="<warm-up drive>")
    run = analyse(cfg, compiled=True)
    run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)
    jitcache.mark_warm(*entry_kernels())  # beltdyn's record that the cache holds them (`jitcache.is_warm`)


def response_of(cfg: DriveConfig, run: Analysis) -> "ResponseResult":
    """The response of an analysed drive (`pipeline.analyse`) to cfg.response: with response.transport
    (default) linearized at each speed about the running equilibrium at the belt speed
    speed x R_driver (one static solve per speed, warm from the L0 fit), else once about `run`."""
    from beltdyn.analysis.response import running_response, solve_response
    from beltdyn.model.geometry import travel_sense
    from beltdyn.model.system import drive_facts

    opts = cfg.response
    assert opts is not None
    d = opts.damping

    def damped(system: "System") -> "System":
        return system.with_belt_damping(d.belt_axial, d.belt_bending) if (d.belt_axial or d.belt_bending) else system

    if not opts.transport:
        return solve_response(damped(run.system), run.static, opts)

    lay = run.fit_layout if run.fit_layout is not None else run.layout
    driver = cfg.driver_index
    per_metre = float(lay.radius[driver]) * travel_sense(lay, driver)
    reuse = Reuse()  # the same drive at every speed: one assembly pattern
    facts = drive_facts(cfg, lay, reuse=reuse)  # the same configuration and L0 fit at every speed: its facts made once

    def drive_at(omega: float):
        at = analyse(cfg, belt_speed=omega * per_metre, layout=lay, facts=facts, reuse=reuse)
        return damped(at.system), at.static
    return running_response(drive_at, opts)
