"""The iteration matrix of the stepper with slipping wraps (issue 25 speed): its factor by the run's
`IterationPlan` against the reference assembly, and the Newton correction's low-rank regime update
(`friction_kernel.regime_correction`) against a factor of the new regime."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.pipeline import analyse

ROOT = Path(__file__).resolve().parents[1]
FEAD = ROOT / "configs" / "examples" / "fead_4cyl.toml"


def wrap_stepper(sets: list[str]):
    """The FEAD's stepper structures with its seven slipping wraps (the crank's hub held: its prescribed
    rotation), at a state near the static one (every factor without row exchanges there)."""
    from beltdyn.analysis.transient import prepare, stepper_arms, stepper_system
    from beltdyn.analysis.transient_wraps import stepper_arms as wrap_arms, stepper_setup, stepper_wraps, wrap_slip

    cfg = load_config(FEAD, ["transient.spectrum.enabled=false"])
    cfg = load_config(FEAD, ["transient.spectrum.enabled=false", *[s.format(n) for s in sets for n in cfg.span_names]])
    run = analyse(cfg)
    setup = prepare(run.system, run.static, cfg.transient)
    system = stepper_system(run.system, cfg.transient)
    slip = wrap_slip(system, cfg.transient, static=run.static, setup=setup)  # (as the run builds it)
    parts = stepper_setup(slip, system, setup)
    wraps = stepper_wraps(slip, system, setup)
    arms = wrap_arms(slip, stepper_arms(system))
    rng = np.random.default_rng(3)
    q = parts["q0"] + 1e-6 * rng.standard_normal(len(parts["q0"]))
    arms.anchor[:] = q[arms.dof] - 2e-4  # the arm's bristle set
    return cfg, system, setup, slip, parts, wraps, arms, q


SLIDING = np.array([1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0])  # the crank (held hub), ALT and PS sliding


@pytest.mark.parametrize("sets", [[], ['spans.{}.model="spring"']], ids=["ancf", "all-spring (dense)"])
def test_the_plan_factors_the_wraps_iteration_matrix(sets):
    # Against the reference assembly (band_factor of the scipy sum, held DOFs, the bristles and the moved
    # inertia of each wrap): the plan's factor solves S x = b to the same x within 1e-10 relative, with every
    # wrap sticking and with three sliding; the plan's own path (no row exchanges: kind 2, the running belt's LU).
    from beltdyn.analysis.integrator import factor_solve
    from beltdyn.analysis.transient_factor import wrap_factorizer

    cfg, system, setup, slip, parts, wraps, arms, q = wrap_stepper(sets)
    kw = dict(perm=parts["perm"], bandwidth=parts["bandwidth"], hold=parts["constraints"].dof)
    fast = wrap_factorizer(system, setup, cfg.transient.rho_inf, arms, slip, wraps, **kw)
    ref = wrap_factorizer(system, setup, cfg.transient.rho_inf, arms, slip, wraps, **kw, plan=False)
    assert fast.plan is not None and ref.plan is None
    b = np.random.default_rng(5).standard_normal(len(parts["perm"]))
    x, y, work = np.empty_like(b), np.empty_like(b), np.empty_like(b)
    for sliding in (np.zeros(slip.n), SLIDING):
        wraps.sliding[:] = sliding
        got = fast(q, 1e-4, None, 0.3)
        assert got.kind == 2
        factor_solve(got, b, x, work)
        factor_solve(ref(q, 1e-4, None, 0.3), b, y, work)
        assert np.array_equal(wraps.factored, sliding)
        assert np.abs(x - y).max() <= 1e-10 * np.abs(y).max()


@pytest.mark.parametrize("before, after", [(np.zeros(7), SLIDING), (SLIDING, np.zeros(7)),
                                           (SLIDING, 1.0 - SLIDING)], ids=["stick-to-slide", "slide-to-stick", "both"])
def test_the_regime_update_of_a_solve_is_the_solve_of_the_new_regimes_factor(before, after):
    # A factor of one regime, its Newton correction updated to another (the Woodbury identity, one to seven
    # wraps changed, the crank's held hub among them) against the correction of a factor of that regime at
    # the same state: equal within 1e-12 relative (round-off; measured 3e-15, against 3e-4 to 1e-3 between the
    # two regimes' solves); the prescribed DOFs' entries stay 0.
    from beltdyn.analysis import friction_kernel
    from beltdyn.analysis import integrator as itg
    from beltdyn.analysis.transient_factor import wrap_factorizer

    cfg, system, setup, slip, parts, wraps, arms, q = wrap_stepper([])
    factor = wrap_factorizer(system, setup, cfg.transient.rho_inf, arms, slip, wraps, perm=parts["perm"],
                             bandwidth=parts["bandwidth"], hold=parts["constraints"].dof)
    n = len(parts["perm"])
    held = np.zeros(n, dtype=np.int64)
    held[parts["constraints"].dof] = 1
    R = np.random.default_rng(11).standard_normal(n)
    R[held == 1] = 0.0  # (the stepper's residual: 0 on the held rows)
    wraps.sliding[:] = before
    old = factor(q, 1e-4, None, 0.3)
    wraps.sliding[:] = after
    new = factor(q, 1e-4, None, 0.3)
    wraps.factored[:] = before  # the stepper's state: the old factor, the last evaluation in the new regime
    wraps.updated[:] = 0.0
    dx, want, work = np.empty(n), np.empty(n), np.empty(n)
    itg.factor_solve(old, R, dx, work)
    itg.factor_solve(new, R, want, work)
    on = np.r_[slip.wrap, slip.hub]  # the regimes differ in the solve where they act (measured 4 %; over the
    # whole solve 4e-6, the belt's entries dominating, since the wrap angles carry the belt on their wraps)
    assert np.abs(dx - want)[on].max() > 1e-3 * np.abs(want[on]).max()
    _, af, _, _ = itg.alpha_parameters(cfg.transient.rho_inf)
    friction_kernel.regime_correction.py_func(wraps, old, held, 1.0 - af, dx, work)
    assert np.abs(dx - want).max() <= 1e-12 * np.abs(want).max()
    assert np.all(dx[held == 1] == 0.0)
    changed = before != after
    assert np.array_equal(wraps.updated, changed.astype(float))  # one solve per changed wrap and factor


@pytest.mark.parametrize("sets", [[], ['spans.{}.model="spring"']], ids=["ancf", "all-spring (dense)"])
def test_the_plan_factors_the_rigid_wraps_iteration_matrix_without_row_exchanges(sets):
    # The same against the reference on the FEAD with rigid wraps (the system's own factorizer), at a state
    # where the plan's LU without row exchanges exists (kind 2: its own path, not the reference's fallback;
    # tests/test_transient.py's state, 1e-4 m of noise on every coordinate, needs row exchanges on the FEAD).
    from beltdyn.analysis.integrator import factor_solve
    from beltdyn.analysis.transient import factorizer, prepare, stepper_arms, stepper_system

    cfg = load_config(FEAD, ["transient.spectrum.enabled=false", 'belt.wraps="rigid"'])
    cfg = load_config(FEAD, ["transient.spectrum.enabled=false", 'belt.wraps="rigid"',
                             *[s.format(n) for s in sets for n in cfg.span_names]])
    run = analyse(cfg)
    setup = prepare(run.system, run.static, cfg.transient)
    system = stepper_system(run.system, cfg.transient)
    arms = stepper_arms(system)
    rng = np.random.default_rng(7)
    q = setup.q0[: system.n_dof] + 1e-6 * rng.standard_normal(system.n_dof)
    arms.anchor[:] = q[arms.dof] - 2e-4
    fast = factorizer(system, setup, cfg.transient.rho_inf, arms)
    ref = factorizer(system, setup, cfg.transient.rho_inf, arms, plan=False)
    assert fast.plan is not None and fast.plan.dense == bool(sets)
    b = rng.standard_normal(system.n_dof)
    x, y, work = np.empty_like(b), np.empty_like(b), np.empty_like(b)
    got = fast(q, 1e-4, None, 0.3)
    assert got.kind == 2
    factor_solve(got, b, x, work)
    factor_solve(ref(q, 1e-4, None, 0.3), b, y, work)
    assert np.abs(x - y).max() <= 1e-10 * np.abs(y).max()
