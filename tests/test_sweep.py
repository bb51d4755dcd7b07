"""Sweeps: value specs, mode tracking across a crossing, process pool vs Dask, resume, --rtol."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.config import load_config, with_overrides
from beltdyn.errors import ConfigError
from beltdyn.modal import solve_modes
from beltdyn.pipeline import analyse
from beltdyn.sweep import Journal, _keys, assemble, make_spec, parse_values, refine_mesh, richardson, run_sweep

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
_SCRIPT = Path(sys.executable).parent / "beltdyn"
BELTDYN = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "beltdyn.cli"]


@pytest.mark.parametrize("key,spec,expect", [
    ("belt.EI", "0.02,1,100", (0.02, 1, 100)),
    ("tension.target", "100:600:6", (100.0, 200.0, 300.0, 400.0, 500.0, 600.0)),
    ("belt.EI", "0.01:100:5:log", (0.01, 0.1, 1.0, 10.0, 100.0)),
    ("mesh.elements_per_span", "2:10:3", (2, 6, 10)),
    ("model.curvature", "linear,none", ("linear", "none")),
])
def test_value_specs(key, spec, expect):
    # list, linear range (inclusive, count), log range (1e-12 relative), integer keys, bare words
    got = parse_values(key, spec)
    if isinstance(expect[0], str):
        assert got == expect
    else:
        assert got == pytest.approx(expect, rel=1e-12)
        assert [type(v) for v in got] == [type(v) for v in expect] or key != "mesh.elements_per_span"


def test_bad_sweep_specs():
    cfg = load_config(BENCH)
    with pytest.raises(ConfigError, match="equal length"):
        make_spec(cfg, [("tension.target", "1,2"), ("belt.EI", "1,2,3")], analysis="modal", zip_=True)
    with pytest.raises(ConfigError, match="unknown key"):
        make_spec(cfg, [("tension.targt", "1,2")], analysis="modal", zip_=False)
    with pytest.raises(ConfigError, match="transient"):
        make_spec(cfg, [("tension.target", "1,2")], analysis="transient", zip_=False)


def sweep(tmp_path, params, *, zip_=False, workers=1, scheduler=None, n_modes=10, name="s"):
    cfg = load_config(BENCH)
    spec = make_spec(cfg, params, analysis="modal", zip_=zip_, n_modes=n_modes)
    journal = Journal(tmp_path / f"{name}.h5")
    run_sweep(cfg, spec, journal=journal, workers=workers, scheduler=scheduler)
    return assemble(spec, journal)


def test_tracking_across_the_rotational_crossing(tmp_path):
    # Between 200 and 400 N the 3rd transverse pair crosses the rotational mode (paper Table 1):
    # every tracked mode keeps its kind and order (and span) on both sides, and the tracked
    # "1st rotational" stays near 100.8 Hz while the transverse ones rise with sqrt(T).
    res = sweep(tmp_path, [("tension.target", "150:450:13")], n_modes=9)
    assert not res.failed.any()
    for j in range(res.frequency.shape[1]):
        assert set(res.kind[:, j]) == {res.kind[0, j]}, (j, res.kind[:, j])
        assert set(res.order[:, j]) == {res.order[0, j]}
        assert set(res.span[:, j]) == {res.span[0, j]}
    rot = [j for j in range(res.frequency.shape[1]) if res.kind[0, j] == "rotational"][0]
    third = [j for j in range(res.frequency.shape[1]) if res.kind[0, j] == "transverse" and res.order[0, j] == 3]
    assert np.ptp(res.frequency[:, rot]) < 0.5
    for j in third:  # crossed: below the rotational mode at 150 N, above at 450 N
        assert res.frequency[0, j] < res.frequency[0, rot] and res.frequency[-1, j] > res.frequency[-1, rot]
    assert np.nanmin(res.mac) > 0.5  # every match unambiguous (shapes near the crossings couple a little)


def test_grid_product_and_parents(tmp_path):
    # A 3 x 2 grid: C order with the last parameter fastest; each case equals a single run.
    res = sweep(tmp_path, [("tension.target", "200,300,400"), ("belt.EI", "0.02,1.0")], n_modes=4)
    assert res.spec.shape == (3, 2) and res.values[1] == (200, 1.0) and res.values[2] == (300, 0.02)
    cfg = with_overrides(load_config(BENCH), ["tension.target=400", "belt.EI=1.0"])
    md = analyse(cfg, modal=True, n_modes=4).modal
    np.testing.assert_allclose(np.sort(res.frequency[5]), md.frequency, rtol=1e-10)


def test_process_pool_equals_serial_and_dask(tmp_path):
    # The same sweep serially, in a 2-process pool and on a local Dask cluster: identical tracked
    # frequencies (bitwise, BLAS single-threaded everywhere).
    distributed = pytest.importorskip("distributed")
    params = [("tension.target", "150:350:6"), ("belt.EI", "0.02,10")]
    serial = sweep(tmp_path, params, workers=1, name="serial")
    pool = sweep(tmp_path, params, workers=2, name="pool")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        dask = sweep(tmp_path, params, scheduler=cl.scheduler_address, name="dask")
    np.testing.assert_array_equal(pool.frequency, serial.frequency)
    np.testing.assert_array_equal(dask.frequency, serial.frequency)
    assert (dask.kind == serial.kind).all() and (pool.kind == serial.kind).all()


def test_failed_case_is_recorded(tmp_path):
    # A case whose geometry is impossible (pulleys overlapping) is marked failed with its message; the
    # others complete.
    res = sweep(tmp_path, [("pulleys[1].radius", "0.1016,0.7")], n_modes=3)
    assert list(res.failed) == [0, 1]
    assert "overlap" in res.errors[1]
    assert np.all(np.isfinite(res.frequency[0])) and np.all(np.isnan(res.frequency[1]))


def h5_dump(path):
    out = {}
    with h5py.File(path) as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset) and not name.endswith("wall_time") and "provenance" not in name:
                out[name] = obj[()]
        f["sweep"].visititems(visit)
        out["attrs"] = dict(f["sweep"].attrs)
    return out


def _journaled(journal: Path) -> int:
    """Cases in a sweep journal's log (valid records only)."""
    from beltdyn.sweep import Journal

    j = Journal(journal.parent / journal.name[: -len(".sweep")])
    return len(j.done()) if (journal / "cases.log").exists() else 0


def test_interrupted_sweep_resumes_to_the_same_file(tmp_path):
    # Ctrl-C midway (serial worker so that it is midway), then --resume: no finished case recomputed
    # (the journal keeps its files) and the final /sweep equals an uninterrupted run's (wall times aside).
    args = ["sweep", str(BENCH), "--param", "tension.target=100:600:150", "--param", "belt.EI=0.02,5", "--workers", "1"]
    full = subprocess.run([*BELTDYN, *args, "-o", str(tmp_path / "full.h5")], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)
    assert full.returncode == 0, full.stderr
    out = tmp_path / "cut.h5"
    # SIGINT at its default in the CLI even when this runner was started with it ignored (a background
    # job of a non-interactive shell, nohup): else the Ctrl-C below is lost and the sweep runs to its end
    proc = subprocess.Popen([*BELTDYN, *args, "-o", str(out)], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    journal = Path(str(out) + ".sweep")
    deadline = time.time() + 120
    while time.time() < deadline and _journaled(journal) < 40 and proc.poll() is None:
        time.sleep(0.01)
    # Midway for sure on a loaded machine: the sweep is frozen (SIGSTOP) the moment the journal holds 40
    # cases, so that it cannot run on to its end (or into assembling the file) before the Ctrl-C lands;
    # the Ctrl-C is delivered when it continues.
    proc.send_signal(signal.SIGSTOP)
    proc.send_signal(signal.SIGINT)
    proc.send_signal(signal.SIGCONT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "--resume" in stderr
    kept = _journaled(journal)
    log = (journal / "cases.log").read_bytes()
    assert 40 <= kept < 300 and not out.exists()
    again = subprocess.run([*BELTDYN, *args, "-o", str(out)], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and "--resume" in again.stderr  # refuses to start over silently
    assert (journal / "cases.log").read_bytes() == log  # the refused run touched nothing
    resumed = subprocess.run([*BELTDYN, *args, "-o", str(out), "--resume"], cwd=tmp_path, capture_output=True,
                             text=True, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    assert not journal.exists()
    a, b = h5_dump(tmp_path / "full.h5"), h5_dump(out)
    assert a.keys() == b.keys()
    for k in a:
        if k == "attrs":
            assert a[k] == b[k]
        else:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_richardson_on_a_known_sequence():
    # f(h) = f_inf + c h^4: the extrapolation recovers f_inf to round-off, the order 4, and the
    # estimate of each mesh equals its true error times the safety factor 1.25.
    n = np.array([4.0, 8.0, 16.0, 32.0])
    f = (10.0 + 3.0 / n**4)[:, None]
    f_inf, est, p = richardson(f, n)
    assert f_inf[0] == pytest.approx(10.0, rel=1e-13)
    assert p[0] == pytest.approx(4.0, abs=1e-6)
    np.testing.assert_allclose(est[:, 0], 1.25 * 3.0 / n**4 / 10.0, rtol=1e-6)


@pytest.mark.parametrize("start,rtol,n_modes", [(2, 1e-4, 12), (3, 1e-3, 16), (10, 1e-6, 8)])
def test_rtol_refinement_meets_tolerance_and_bounds_error(start, rtol, n_modes):
    # --rtol on the paper bench: against a converged reference (320 el/span), every requested mode of
    # the chosen mesh is within rtol, and the reported estimate is >= the true error.
    cfg = load_config(BENCH, [f"mesh.elements_per_span={start}"])
    (c, model, st, md), ref = refine_mesh(cfg, n_modes=n_modes, rtol=rtol)
    assert ref.converged
    rc = with_overrides(cfg, ["mesh.elements_per_span=320"])
    rmd = analyse(rc, modal=True, n_modes=n_modes + 10).modal
    ref_keys = _keys(rmd)
    chosen_keys = _keys(md)
    for j, lab in enumerate(ref.labels):
        f = ref.frequency[ref.chosen, j]
        key = next(k for k, idx in zip(chosen_keys, range(len(chosen_keys))) if abs(md.frequency[idx] - f) == 0)
        f_true = rmd.frequency[ref_keys.index(key)]
        true_err = abs(f - f_true) / f_true
        assert true_err <= rtol, (lab, true_err)
        assert ref.estimate[ref.chosen, j] >= true_err * (1 - 1e-6) or true_err < 1e-9, (lab, true_err)


def test_transient_sweep_resonance_curve(tmp_path):
    # An excitation-frequency sweep through the same path (transient analysis per case): the first
    # harmonic of A's bearing force under a 1 N hub force on A peaks at the translational mode
    # (~178.5 Hz) among 120, 178 and 240 Hz, and its quasi-static value at 120 Hz is finite.
    cfg = load_config(ROOT / "configs/examples/bench_transient_small.toml",
                      ["transient.duration=0.5", "transient.spectrum.start=0.3", "transient.rotation[0].amplitude=0.0",
                       "transient.damping.rayleigh_mass=30.0"])
    from beltdyn.config import config_from_dict, config_to_dict

    raw = config_to_dict(cfg)
    raw["transient"]["rotation"] = []
    raw["transient"]["hub_force"] = [{"pulley": "A", "amplitude": [1.0, 0.0], "frequency": 120.0}]
    cfg = config_from_dict(raw, file=cfg.source)
    spec = make_spec(cfg, [("transient.hub_force[0].frequency", "120,178,240")], analysis="transient", zip_=False)
    journal = Journal(tmp_path / "tr.h5")
    run_sweep(cfg, spec, journal=journal, workers=2)
    res = assemble(spec, journal)
    amp = res.extras["bearing_force_first_harmonic"][:, 0, 0]
    assert not res.failed.any() and np.all(np.isfinite(amp))
    assert np.argmax(amp) == 1


def test_mac_is_insensitive_to_a_mass_scale(tmp_path):
    # Halving the belt's mass per length changes the mass matrix, not the mode shapes of the spans:
    # the normalized MAC stays ~1 (it would read 0.5 without the normalization).
    res = sweep(tmp_path, [("belt.mass_per_length", "0.2,0.1,0.05")], n_modes=6)
    assert np.nanmin(res.mac[1:, :4]) > 0.9


def test_modes_leaving_the_window_are_lost_not_mislabelled(tmp_path):
    # EI from 0.02 to 100 N m^2: high transverse modes climb past the computed window; they become
    # "lost" (NaN) from there on instead of being filled with another kind of mode.
    res = sweep(tmp_path, [("belt.EI", "0.02:100:9:log")], n_modes=12)
    for j in range(res.frequency.shape[1]):
        kinds = set(res.kind[:, j])
        assert kinds <= {res.kind[0, j], "lost"}, (j, kinds)
        lost = res.kind[:, j] == "lost"
        assert np.all(np.isnan(res.frequency[lost, j]))
        if lost.any():  # once lost, lost for good
            assert lost[np.argmax(lost):].all()


def test_failed_root_case_keeps_tracking_consistent(tmp_path):
    # A 2 x 2 grid whose first row fails (overlapping pulleys): the two good cases are tracked from one
    # another, so each column keeps one kind/order/span.
    res = sweep(tmp_path, [("pulleys[1].radius", "0.7,0.1016"), ("tension.target", "200,400")], n_modes=9)
    assert list(res.failed) == [1, 1, 0, 0]
    for j in range(res.frequency.shape[1]):
        assert res.kind[2, j] == res.kind[3, j] and res.order[2, j] == res.order[3, j], j


def test_unreachable_scheduler_is_a_usage_error(tmp_path):
    # A bad --scheduler address: exit 2 naming --scheduler, no traceback, nothing journaled.
    pytest.importorskip("distributed")
    r = subprocess.run([*BELTDYN, "sweep", str(BENCH), "--param", "tension.target=200,300", "--scheduler",
                        "notanaddress", "-o", str(tmp_path / "x.h5")], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    assert "--scheduler" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "x.h5.sweep").exists() and not (tmp_path / "x.h5").exists()


def test_a_torn_journal_record_is_cut_off_and_the_case_recomputed(tmp_path):
    # A crash in the middle of appending a case: the log ends in half a record. The next lock cuts it off
    # (the CRC and the length say where the valid log ends), that case counts as not done, --resume
    # recomputes it, and /sweep equals an uninterrupted run's (wall times aside), to the bit.
    from beltdyn.sweep import Journal

    args = ["sweep", str(BENCH), "--param", "tension.target=150:300:6", "--workers", "1"]
    full = subprocess.run([*BELTDYN, *args, "-o", str(tmp_path / "full.h5")], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert full.returncode == 0, full.stderr
    # a journal of cases 0-3 written by the library, the last record torn
    from beltdyn.config import load_config
    from beltdyn.sweep import make_spec, run_case, spec_hash

    cfg = load_config(BENCH)
    spec = make_spec(cfg, [("tension.target", "150:300:6")], analysis="modal", zip_=False)
    out = tmp_path / "cut.h5"
    from beltdyn.config import resolved_toml
    from beltdyn.sweep import _assign

    with Journal(out) as j:
        j.start(spec.to_json(), spec_hash(cfg, spec))
        for i in range(4):
            assign = [_assign(p.key, v) for p, v in zip(spec.params, spec.case_values(i))]
            j.write(i, run_case(resolved_toml(cfg), cfg.source, assign, "modal", spec.n_modes))
    log = Path(str(out) + ".sweep") / "cases.log"
    size = log.stat().st_size
    with open(log, "r+b") as fh:
        fh.truncate(size - 100)  # case 3's record cut short
    with Journal(out) as j:
        assert j.done() == {0, 1, 2}
    assert log.stat().st_size < size - 100  # the torn record was cut off on lock
    resumed = subprocess.run([*BELTDYN, *args, "-o", str(out), "--resume"], cwd=tmp_path, capture_output=True,
                             text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    a, b = h5_dump(tmp_path / "full.h5"), h5_dump(out)
    for k in a:
        if k != "attrs" and "wall_time" not in k:
            np.testing.assert_array_equal(a[k], b[k], err_msg=k)
