"""The time step's frequency error (beltdyn.analysis.timestep) against free vibrations integrated by the
production stepper, its series, its inversion, and `transient.accuracy` / `transient.fmax` in use."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from beltdyn.analysis.timestep import (frequency_error, resolve_step, resolved_band, series_coefficient, series_coefficients,
                              step_for_accuracy)
from beltdyn.analysis.transient import integrate_linear

ROOT = Path(__file__).resolve().parents[1]


def measured_error(Om: float, rho_inf: float, periods: int = 40) -> float:
    """Frequency error of x'' + x = 0 integrated with h = Omega through the production path: the
    discrete oscillation x_n obeys x_{n+1} - 2 r cos(W) x_n + r^2 x_{n-1} = 0 once the spurious root
    has died out; least squares on that recurrence gives W, the discrete phase advance per step."""
    n = int(periods * 2 * math.pi / Om) + 50
    _, q, _, _ = integrate_linear(np.eye(1), np.eye(1), None, np.ones(1), np.zeros(1), step=Om, n_steps=n,
                                  rho_inf=rho_inf, tol=1e-13)
    x = q[20:, 0]
    A = np.column_stack([x[1:-1], -x[:-2]])
    c1, c2 = np.linalg.lstsq(A, x[2:], rcond=None)[0]  # c1 = 2 r cos W, c2 = r^2
    W = math.acos(c1 / (2.0 * math.sqrt(c2)))
    return W / Om - 1.0


def _phase_advance(x: np.ndarray) -> float:
    """W of a sampled decaying oscillation x_{n+1} = 2 r cos(W) x_n - r^2 x_{n-1} (least squares)."""
    A = np.column_stack([x[1:-1], -x[:-2]])
    c1, c2 = np.linalg.lstsq(A, x[2:], rcond=None)[0]
    return math.acos(c1 / (2.0 * math.sqrt(c2)))


def bench_mode_errors(step: float, modes, rho_inf: float = 0.9, duration: float = 0.2):
    """Frequency errors of the paper bench's own modes (configs/examples/bench_transient_small.toml,
    T = 200 N, no excitation, no damping) through the production transient (`run_transient`, nonlinear
    belt, the drive's stepper): started from the static equilibrium with a small velocity along mode k
    (amplitude 1e-6 of the largest entry, linear regime), the modal coordinate phi_k^T M (q_n - q_s) at
    every step (output interval = step, no interpolation) gives the discrete phase advance W per step;
    the error is W / (2 pi f_k step) - 1 against the modal frequency f_k. Returns [(f_k, error)]."""
    import dataclasses

    from beltdyn.config import config_from_dict, config_to_dict, load_config
    from beltdyn.pipeline import analyse
    from beltdyn.analysis.transient import prepare, run_transient

    raw = config_to_dict(load_config(ROOT / "configs" / "examples" / "bench_transient_small.toml"))
    raw["transient"] = {"duration": duration, "step": step, "output_interval": step, "rho_inf": rho_inf,
                        "tolerance": 1e-10, "spectrum": {"enabled": False},
                        "record": {"full_state": True, "pulley_speeds": False, "span_tension": False,
                                   "hub_load": False, "bearing_force": False, "midspan_displacement": False,
                                   "energy": False}}
    cfg = config_from_dict(raw, file="bench_transient_small.toml")
    run = analyse(cfg, modal=True, n_modes=max(modes) + 1, compiled=True)
    system, st, md = run.system, run.static, run.modal
    M = system.mass_matrix(st.q)
    out = []
    for k in modes:
        f, phi = float(md.frequency[k]), md.shapes[k]
        setup = prepare(system, st, cfg.transient)
        setup = dataclasses.replace(setup, v0=setup.v0 + 1e-6 * 2 * math.pi * f * phi / np.abs(phi).max())
        got: list = []
        run_transient(system, st, cfg.transient, setup=setup, sink=lambda t, b: got.append(b["q"]))
        eta = (np.concatenate(got) - st.q) @ (M @ phi)
        out.append((f, _phase_advance(eta[5:]) / (2 * math.pi * f * step) - 1.0))
    return out


def test_formula_matches_the_bench_modes_in_the_production_transient():
    # The paper bench's modes at 92 Hz and 178 Hz (4th and 12th elastic modes), integrated by the full
    # nonlinear transient at dt = 4e-4 s (f dt = 0.037 and 0.071, rho_inf 0.9): the measured frequency
    # errors (-4.5e-3, -1.6e-2) equal the formula's within 1e-6 absolute (a wrong rho_inf in the formula, 1
    # instead of 0.9, would be off by 5.5e-5 and 2.0e-4).
    for f, got in bench_mode_errors(4e-4, [4, 11]):
        assert abs(got - frequency_error(f, 4e-4, 0.9)) < 1e-6, f
        assert abs(frequency_error(f, 4e-4, 1.0) - frequency_error(f, 4e-4, 0.9)) > 5e-5


@pytest.mark.parametrize("rho_inf", [0.5, 0.9, 1.0])
@pytest.mark.parametrize("Om", [0.05, 0.2, 0.6])
def test_formula_matches_the_integrated_oscillator(rho_inf, Om):
    # The exact error from the amplification matrix against the measured phase advance of the production
    # stepper (generalized-alpha with the stepper's own parameters): within 1e-6 absolute (the errors
    # are 2e-4 to 3e-2).
    got = measured_error(Om, rho_inf)
    assert abs(got - frequency_error(Om / (2 * math.pi), 1.0, rho_inf)) < 1e-6


def test_rho_one_is_the_trapezoidal_rule():
    # rho_inf = 1 (no numerical damping): generalized alpha is the trapezoidal rule, whose phase advance per
    # step is 2 atan(Omega/2) exactly: the eigenvalue form against that closed form, within 1e-13 absolute
    # (round-off of the 3x3 eigenvalues), up to Omega = 3 (f dt = 0.48).
    Om = np.linspace(0.01, 3.0, 300)
    exact = 2.0 * np.arctan(Om / 2.0) / Om - 1.0
    assert np.max(np.abs(frequency_error(Om / (2 * math.pi), 1.0, 1.0) - exact)) < 1e-13


def test_series_coefficients():
    # The series e = -c Omega^2 + d Omega^4 + O(Omega^6) (c, d derived symbolically, module docstring):
    # at rho_inf = 1 the trapezoidal rule's 1/12 and 1/80 (exact rationals, to 1e-15); for every rho_inf the
    # exact error minus the series, divided by Omega^6, is the same at Omega = 0.1 and 0.05 within 5 %
    # (a wrong c or d leaves an Omega^2 or Omega^4 residual, whose ratio would be 16 or 4 times larger:
    # measured ratios 1.00 to 1.03); c(0.5) = 1/8 and c(0) = 11/24 from the closed form, to 1e-15.
    assert series_coefficients(1.0) == pytest.approx((1 / 12, 1 / 80), abs=1e-15)
    assert series_coefficient(0.5) == pytest.approx(1 / 8, abs=1e-15)
    assert series_coefficient(0.0) == pytest.approx(11 / 24, abs=1e-15)
    for rho in (0.0, 0.3, 0.5, 0.8, 0.9, 1.0):
        c, d = series_coefficients(rho)

        def rest(Om):
            return (frequency_error(Om / (2 * math.pi), 1.0, rho) - (-c * Om ** 2 + d * Om ** 4)) / Om ** 6

        assert rest(0.05) == pytest.approx(rest(0.1), rel=0.05), rho
        # and the leading term alone: e / (-c Omega^2) - 1 = O(Omega^2), below 0.03 at Omega = 0.1
        e = frequency_error(0.1 / (2 * math.pi), 1.0, rho)
        assert abs(e / (-c * 0.01) - 1.0) < 0.03, rho
    assert (frequency_error(0.1 / (2 * math.pi), 1.0, 1.0) + 0.01 / 12 - 1e-4 / 80) / 1e-6 == \
        pytest.approx(-1 / 448, rel=0.01)  # the trapezoidal rule's next term


@pytest.mark.parametrize("rho_inf", np.linspace(0.0, 1.0, 11))
def test_the_error_grows_monotonically_with_omega(rho_inf):
    # step_for_accuracy brackets |e| = accuracy on the assumption that |e| grows with Omega: checked on a
    # grid of 4000 points up to f dt = 1 (|e| beyond 0.5, the largest accuracy the config takes),
    # finite (the pair stays complex) and strictly increasing.
    Om = np.linspace(1e-3, 2 * math.pi, 4000)
    e = frequency_error(Om / (2 * math.pi), 1.0, rho_inf)
    assert np.all(np.isfinite(e)) and np.all(e < 0.0)
    assert np.all(np.diff(np.abs(e)) > 0.0)
    assert abs(e[-1]) > 0.5


def test_vectorized_equals_scalar():
    # frequency_error on an array is the scalar result per entry (identical floats), shape kept.
    f = np.array([[10.0, 190.0], [300.0, 2000.0]])
    got = frequency_error(f, 1e-4, 0.9)
    assert got.shape == f.shape
    assert all(got[i] == frequency_error(float(f[i]), 1e-4, 0.9) for i in np.ndindex(f.shape))


def test_issue_numbers_at_the_default_step():
    # At dt = 1e-4 s and rho_inf = 0.9 the transient's peaks sat 0.12 % low at 190 Hz and 0.29 % low at
    # 300 Hz (measured on the bench): the formula gives -0.120 % and -0.298 %.
    e = frequency_error(np.array([190.0, 300.0]), 1e-4, 0.9)
    assert e[0] == pytest.approx(-1.20e-3, rel=1e-2) and e[1] == pytest.approx(-2.98e-3, rel=1e-2)


@pytest.mark.parametrize("rho_inf", [0.5, 0.9, 1.0])
@pytest.mark.parametrize("accuracy", [1e-4, 1e-3, 1e-2, 0.3, 0.49])
def test_step_for_accuracy_is_the_inverse(rho_inf, accuracy):
    # The step meets the accuracy exactly at fmax (|e| = accuracy to 1e-8 relative) and everywhere below
    # it (200 frequencies), and resolved_band gives fmax back (1e-9 relative); up to the largest accuracy
    # the config accepts (< 0.5).
    fmax = 300.0
    h = step_for_accuracy(fmax, accuracy, rho_inf)
    assert abs(frequency_error(fmax, h, rho_inf)) == pytest.approx(accuracy, rel=1e-8)
    f = np.linspace(1.0, fmax, 200)  # the error grows with the frequency: the whole band is within it
    assert np.all(np.abs(frequency_error(f, h, rho_inf)) <= accuracy * (1 + 1e-9))
    assert resolved_band(h, accuracy, rho_inf) == pytest.approx(fmax, rel=1e-9)


def _options(**kw):
    from beltdyn.config import load_config

    sets = [f"transient.{k}={v!r}" for k, v in kw.items()]
    return load_config(ROOT / "configs" / "examples" / "bench_transient_small.toml", sets).transient


def test_resolve_step_rules():
    # The step a transient runs with (timestep.resolve_step), against step_for_accuracy (identical floats):
    from beltdyn.config import config_from_dict, config_to_dict, load_config

    h = step_for_accuracy(300.0, 1e-3, 0.9)  # 5.78e-5 s
    # no accuracy: transient.step as given, origin config
    t, origin = resolve_step(_options(step=2e-4))
    assert (t.step, origin) == (2e-4, "config")
    # accuracy and fmax, step given longer (the example's 1e-4 s): the accuracy's step
    t, origin = resolve_step(_options(accuracy=1e-3, fmax=300.0))
    assert (t.step, origin) == (h, "accuracy")
    # accuracy and fmax, step given shorter: the step is an upper bound, kept
    t, origin = resolve_step(_options(accuracy=1e-3, fmax=300.0, step=2e-5))
    assert (t.step, origin) == (2e-5, "config")
    # --step wins over both
    t, origin = resolve_step(_options(accuracy=1e-3, fmax=300.0, step=2e-5), manual=3e-4)
    assert (t.step, origin) == (3e-4, "--step")
    # accuracy and fmax without a step: it stays unset in the configuration (not written to its TOML, so a
    # sweep over fmax chooses each case's step) until resolved, and can be longer than the 1e-4 s default
    raw = config_to_dict(load_config(ROOT / "configs" / "examples" / "bench_transient_small.toml"))
    del raw["transient"]["step"]
    raw["transient"].update(accuracy=1e-3, fmax=50.0)
    cfg = config_from_dict(raw)
    assert cfg.transient.step is None and "step" not in config_to_dict(cfg)["transient"]
    t, origin = resolve_step(cfg.transient)
    assert (t.step, origin) == (step_for_accuracy(50.0, 1e-3, 0.9), "accuracy") and t.step > 1e-4
    del raw["transient"]["accuracy"], raw["transient"]["fmax"]
    assert config_from_dict(raw).transient.step == 1e-4  # neither: the default
    # a step below min_step is refused
    from beltdyn.errors import ConfigError

    with pytest.raises(ConfigError, match="below transient.min_step"):
        resolve_step(_options(accuracy=1e-6, fmax=2000.0, min_step=1e-6))


def test_pipeline_transient_resolves_the_step():
    # pipeline.transient runs with the step resolve_step gives (accuracy 1e-3 up to 300 Hz without a step:
    # 5.78e-5 s, so 0.01 s takes ceil(0.01 / h) = 173 steps, exactly); run_transient itself refuses
    # options whose step was never resolved (ValueError naming resolve_step).
    from beltdyn.config import config_from_dict, config_to_dict, load_config
    from beltdyn.pipeline import analyse, transient
    from beltdyn.analysis.transient import run_transient

    raw = config_to_dict(load_config(ROOT / "configs" / "examples" / "bench_transient_small.toml"))
    del raw["transient"]["step"]
    raw["transient"].update(accuracy=1e-3, fmax=300.0, duration=0.01, spectrum={"enabled": False})
    cfg = config_from_dict(raw)
    run = analyse(cfg)
    summary = transient(run, sink=lambda t, b: None)
    assert summary.steps == math.ceil(0.01 / step_for_accuracy(300.0, 1e-3, 0.9)) == 173
    assert summary.step_halvings == 0 and summary.warnings == ()
    with pytest.raises(ValueError, match="resolve_step"):
        run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)


def _run(*args, tmp_path):
    import subprocess
    import sys

    exe = [str(Path(sys.executable).parent / "beltdyn")]
    return subprocess.run([*exe, *map(str, args)], cwd=tmp_path, capture_output=True, text=True, timeout=300)


def test_transient_takes_its_step_from_accuracy_and_fmax(tmp_path):
    # transient.accuracy = 1e-3 with fmax = 300 Hz: the step is the one of the formula (5.78e-5 s), the
    # resolved configuration records it, /transient says where it came from and what band it resolves.
    import h5py

    cfg = ROOT / "configs" / "examples" / "bench_transient_small.toml"
    sets = ["transient.spectrum.start=0.05", "transient.accuracy=1e-3", "transient.fmax=300"]
    r = _run("transient", cfg, "--duration", "0.1", *[x for s in sets for x in ("--set", s)], "-o", "a.h5",
             tmp_path=tmp_path)
    assert r.returncode == 0, r.stderr
    h = step_for_accuracy(300.0, 1e-3, 0.9)
    assert "time step (accuracy): step 5.781e-05 s: frequency error <= 0.001 up to 300 Hz" in r.stdout
    assert "-0.100% at fmax = 300 Hz" in r.stdout
    with h5py.File(tmp_path / "a.h5") as f:
        a = f["transient"].attrs
        assert a["step_origin"] == "accuracy" and a["step_s"] == pytest.approx(h, rel=1e-12)
        assert a["resolved_fmax_Hz"] == pytest.approx(300.0, rel=1e-9) and len(a["warnings"]) == 0
        assert a["resolved_accuracy"] == 1e-3 and a["fmax_frequency_error"] == pytest.approx(-1e-3, rel=1e-8)
        assert f"step = {h!r}" in f["provenance/config_toml"].asstr()[()]


def test_a_manual_step_that_misses_the_accuracy_is_marked(tmp_path):
    # --step overrides the accuracy; a step too long for it is marked in /transient warnings.
    import h5py

    cfg = ROOT / "configs" / "examples" / "bench_transient_small.toml"
    sets = ["transient.spectrum.start=0.05", "transient.accuracy=1e-3", "transient.fmax=300"]
    r = _run("transient", cfg, "--duration", "0.1", "--step", "1e-4", *[x for s in sets for x in ("--set", s)],
             "-o", "m.h5", tmp_path=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "m.h5") as f:
        a = f["transient"].attrs
        assert a["step_origin"] == "--step" and a["step_s"] == 1e-4
        assert any("misses transient.accuracy" in str(w) for w in a["warnings"])
        assert a["resolved_fmax_Hz"] == pytest.approx(resolved_band(1e-4, 1e-3, 0.9), rel=1e-9)


def test_an_explicit_shorter_step_bounds_the_accuracy_step(tmp_path):
    # transient.step = 4e-5 s given with accuracy 1e-3 up to 300 Hz (which asks for 5.78e-5 s): the
    # shorter configured step is kept (origin config, no warning), and the band it resolves at that
    # accuracy is resolved_band(4e-5) = 434 Hz, printed and stored (1e-9 relative).
    import h5py

    cfg = ROOT / "configs" / "examples" / "bench_transient_small.toml"
    sets = ["transient.spectrum.start=0.02", "transient.accuracy=1e-3", "transient.fmax=300", "transient.step=4e-5"]
    r = _run("transient", cfg, "--duration", "0.04", *[x for s in sets for x in ("--set", s)], "-o", "c.h5",
             tmp_path=tmp_path)
    assert r.returncode == 0, r.stderr
    band = resolved_band(4e-5, 1e-3, 0.9)
    assert f"time step (config): step 4e-05 s: frequency error <= 0.001 up to {band:.4g} Hz" in r.stdout
    with h5py.File(tmp_path / "c.h5") as f:
        a = f["transient"].attrs
        assert a["step_origin"] == "config" and a["step_s"] == 4e-5 and len(a["warnings"]) == 0
        assert a["resolved_fmax_Hz"] == pytest.approx(band, rel=1e-9) and 430.0 < band < 440.0
        assert a["fmax_frequency_error"] == pytest.approx(frequency_error(300.0, 4e-5, 0.9), rel=1e-12)
