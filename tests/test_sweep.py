"""Sweeps: value specs, mode tracking across a crossing, process pool vs Dask, resume, --rtol."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.config import load_config, with_overrides
from beltdyn.errors import ConfigError
from beltdyn.pipeline import analyse
from beltdyn.study.refine import mode_keys
from beltdyn.study.sweep import Journal, assemble, make_spec, parse_values, refine_mesh, richardson, run_sweep
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"


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
    from beltdyn.study.sweep import Journal

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
    assert f"resuming: {kept} of 300 cases reused from {journal}" in resumed.stdout  # issue 26: says what it reuses
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
    ref_keys = mode_keys(rmd)
    chosen_keys = mode_keys(md)
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
    from beltdyn.study.sweep import Journal

    args = ["sweep", str(BENCH), "--param", "tension.target=150:300:6", "--workers", "1"]
    full = subprocess.run([*BELTDYN, *args, "-o", str(tmp_path / "full.h5")], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert full.returncode == 0, full.stderr
    # a journal of cases 0-3 written by the library, the last record torn
    from beltdyn.config import load_config
    from beltdyn.study.sweep import make_spec, run_case, spec_hash

    cfg = load_config(BENCH)
    spec = make_spec(cfg, [("tension.target", "150:300:6")], analysis="modal", zip_=False)
    out = tmp_path / "cut.h5"
    from beltdyn.config import resolved_toml
    from beltdyn.study.grid import _assign

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


# ----------------------------------------------------------------------- streamed assembly, journal format
def _reference_tracking(spec, cases):
    """The tracking as it was first written, on every case at once (a list of dicts, None for a failed
    case): each case from its parent, past failed ones, else from the latest tracked case."""
    from scipy.optimize import linear_sum_assignment

    from beltdyn.study.sweep import MAC_LOST

    n, k = spec.n_cases, spec.n_modes
    freq, mac = np.full((n, k), np.nan), np.full((n, k), np.nan)
    kind = np.full((n, k), "", dtype=object)
    order, span = np.zeros((n, k), dtype=np.int64), np.zeros((n, k), dtype=np.int64)
    pick = {}
    for i, c in enumerate(cases):
        if c is None:
            continue
        p = spec.parent(i)
        while p >= 0 and p not in pick:
            p = spec.parent(p)
        if p < 0 and pick:
            p = max(pick)
        m = len(c["frequency"])
        if p < 0:
            sel = np.r_[np.arange(min(m, k)), np.full(max(k - m, 0), -1)]
            macs = np.where(sel >= 0, 1.0, np.nan)
        else:
            cp, prev = cases[p], pick[p]
            alive = np.flatnonzero(prev >= 0)
            M = np.abs((cp["shapes"][prev[alive]] @ c["mshapes"].T) * (cp["mshapes"][prev[alive]] @ c["shapes"].T))
            rows, cols = linear_sum_assignment(-M)
            sel, macs = np.full(k, -1, dtype=np.int64), np.full(k, np.nan)
            for r, col in zip(rows, cols):
                if M[r, col] >= MAC_LOST:
                    sel[alive[r]], macs[alive[r]] = col, M[r, col]
        pick[i] = sel
        ok = sel >= 0
        freq[i, ok] = c["frequency"][sel[ok]]
        kind[i, ok], kind[i, ~ok] = c["kind"][sel[ok]], "lost"
        order[i, ok], span[i, ok] = c["order"][sel[ok]], c["span"][sel[ok]]
        mac[i, ok] = np.minimum(macs[ok], 1.0)
    return {"frequency": freq, "kind": kind, "order": order, "span": span, "mac": mac}


def _synthetic_case(rng, i, ndof=12, m=7, failed=False):
    if failed:
        return {"failed": 1, "error": f"case {i} failed", "wall_time": 0.001}
    shapes = np.linalg.qr(rng.normal(size=(ndof, ndof)))[0][:m] + 0.05 * rng.normal(size=(m, ndof))
    return {"failed": 0, "error": "", "mean_tension": float(i), "hub_load": rng.normal(size=(2, 2)),
            "frequency": np.sort(rng.uniform(10, 100, m)), "shapes": shapes,
            "mshapes": np.asfortranarray(1.3 * shapes), "kind": np.array(["transverse", "rotational"] * 3 + ["x"])[:m],
            "order": np.arange(m), "span": np.arange(m) % 2, "label": np.array([f"mode {j}" for j in range(m)]),
            "wall_time": 0.001}


@pytest.mark.parametrize("shape", [(40,), (5, 6), (3, 3, 4)], ids=["1d", "2d", "3d"])
@pytest.mark.parametrize("p_fail", [0.0, 0.3], ids=["ok", "failures"])
def test_streamed_assembly_equals_tracking_all_cases_at_once(tmp_path, monkeypatch, shape, p_fail):
    # Cases arriving in a shuffled order (a few waiting whole in memory, the others read back from the
    # journal when their turn comes), failed ones included: the same tracked modes, MACs and per-case
    # quantities as the tracking of all cases at once, exactly. In case order, the assembly holds the
    # shapes of at most one case per swept parameter between cases, however many cases there are.
    from beltdyn.study.sweep import Assembly, Param, SweepSpec

    monkeypatch.setattr(Assembly, "BUFFER", 3)
    rng = np.random.default_rng(len(shape) + int(10 * p_fail))
    spec = SweepSpec(params=tuple(Param(key=f"k{a}", values=tuple(range(s))) for a, s in enumerate(shape)),
                     analysis="modal", zip=False, n_modes=5)
    fails = rng.random(spec.n_cases) < p_fail
    cases = [_synthetic_case(rng, i, failed=f) for i, f in enumerate(fails)]
    ref = _reference_tracking(spec, [None if f else c for c, f in zip(cases, fails)])
    # shuffled arrival in batches, each journaled, offered and assembled as far as it goes
    with Journal(tmp_path / "syn.h5") as j:
        j.start(spec.to_json(), "0" * 64)
        a = Assembly(spec)
        order = rng.permutation(spec.n_cases)
        for batch in np.array_split(order, 7):
            for i in batch:
                j.write(int(i), cases[i], sync_dir=False)
                a.offer(int(i), cases[i])
            j.sync()
            a.advance(j)
        res = assemble(spec, j, a)
        again = assemble(spec, j)  # every case streamed from the journal
        in_order, held = Assembly(spec), 0
        for i, c in enumerate(cases):
            in_order.offer(i, c)
            in_order.advance(j)
            held = max(held, in_order.held)
    assert held <= len(shape), held
    for r in (res, again):
        for key, want in ref.items():
            np.testing.assert_array_equal(getattr(r, key), want, err_msg=key)
        np.testing.assert_array_equal(r.failed, fails.astype(np.int8))
        assert r.errors == [c["error"] for c in cases]
        if not fails.all():
            np.testing.assert_array_equal(r.extras["mean_tension"],
                                          [np.nan if f else float(i) for i, f in enumerate(fails)])


def test_journal_records_round_trip_and_old_records_are_read(tmp_path):
    # A record keeps each array's values, type, shape and memory order (a Fortran-ordered array comes back
    # Fortran-ordered, so that products with it round the same); object arrays are refused; a log of the
    # previous format (.npz payloads, BDC1) is still read.
    import struct
    import zlib

    case = {"f": np.asfortranarray(np.arange(12.0).reshape(3, 4)), "c": np.arange(6).reshape(2, 3), "s": "boom",
            "u": np.array(["a", "longer"]), "z": np.zeros((0, 5)), "x": 1.5, "b": np.array([True, False])}
    with Journal(tmp_path / "r.h5") as j:
        j.start({}, "0" * 64)
        j.write(7, case)
        with pytest.raises(TypeError, match="object"):
            j.write(8, {"o": np.array([None, 1], dtype=object)})
        assert j.done() == {7}
    back = Journal(tmp_path / "r.h5").read(7)
    assert list(back) == list(case)
    for k, v in case.items():
        v = np.asarray(v)
        assert back[k].dtype == v.dtype and back[k].shape == v.shape, k
        np.testing.assert_array_equal(back[k], v, err_msg=k)
    assert back["f"].flags.f_contiguous and back["c"].flags.c_contiguous
    assert all(a.ctypes.data % Journal.ALIGN == 0 for a in back.values() if a.size)
    # a record of the previous format appended by hand
    import io

    buf = io.BytesIO()
    np.savez(buf, failed=np.array(0), frequency=np.arange(3.0))
    payload = buf.getvalue()
    with open(tmp_path / "r.h5.sweep" / "cases.log", "ab") as fh:
        fh.write(struct.pack("<4sIQI", b"BDC1", 9, len(payload), zlib.crc32(payload)) + payload)
    with Journal(tmp_path / "r.h5") as j:
        assert j.done() == {7, 9}
        np.testing.assert_array_equal(j.read(9)["frequency"], np.arange(3.0))


GRID = [("pulleys[1].radius", "0.1016,0.7,0.1016"), ("tension.target", "150:450:4")]  # the middle row fails


@pytest.mark.parametrize("tear", ["header", "payload", "zeroed"])
def test_resume_after_a_torn_record_equals_an_uninterrupted_sweep(tmp_path, tear):
    # A 3 x 4 grid journaled up to case 7, whose record is torn: cut inside its header, cut inside its
    # arrays, or at full length but never written (zeros, as a crash can leave an appended block). The
    # resumed sweep recomputes case 7 on (only those), tracks the later cases from shapes read back from
    # the journal (case 8 from case 4, across the failed row) and gives the uninterrupted results, to 1e-12.
    cfg = load_config(BENCH)
    spec = make_spec(cfg, GRID, analysis="modal", zip_=False, n_modes=8)
    with Journal(tmp_path / "full.h5") as j:
        full = assemble(spec, j, run_sweep(cfg, spec, journal=j, workers=1))
    assert list(full.failed) == [0] * 4 + [1] * 4 + [0] * 4
    out = tmp_path / "cut.h5"
    with Journal(out) as j:
        run_sweep(cfg, spec, journal=j, workers=1)
        offsets = sorted(start for start, _, _ in j._scan().values())
    log = Path(str(out) + ".sweep") / "cases.log"
    head = Journal._HEAD.size
    start7 = offsets[7] - head  # records are in case order with one worker
    data = bytearray(log.read_bytes()[:offsets[8] - head])
    if tear == "header":
        data = data[:start7 + 10]
    elif tear == "payload":
        data = data[:offsets[7] + 100]
    else:
        data[start7 + head:] = bytes(len(data) - start7 - head)
    log.write_bytes(bytes(data))
    seen = []
    with Journal(out) as j:
        assert j.done() == set(range(7)) and log.stat().st_size == start7  # the torn record cut off on lock
        res = assemble(spec, j, run_sweep(cfg, spec, journal=j, resume=True, workers=1,
                                          progress=lambda k, n: seen.append(k)))
    assert seen[0] == 7 and seen[-1] == 12
    np.testing.assert_array_equal(res.failed, full.failed)
    np.testing.assert_allclose(res.frequency, full.frequency, rtol=1e-12)
    np.testing.assert_allclose(res.mac, full.mac, rtol=0, atol=1e-12)
    for key in ("kind", "order", "span", "label"):
        np.testing.assert_array_equal(getattr(res, key), getattr(full, key), err_msg=key)
    for key, arr in full.extras.items():
        np.testing.assert_allclose(res.extras[key], arr, rtol=1e-12, err_msg=key)


def test_sweep_file_equals_the_analysis_of_each_case(tmp_path):
    # The CLI's /sweep (two workers: cases arrive out of order and are assembled as they come) against a
    # reference built here: every case analysed on its own with beltdyn.pipeline.analyse, and all of them
    # tracked at once as the first implementation did. Equal to 1e-12: frequencies, MACs, kinds, orders,
    # spans, labels, the static quantities, and which cases failed (the middle row: overlapping pulleys).
    from beltdyn.config import with_overrides
    from beltdyn.errors import BeltdynError
    from beltdyn.study.grid import _assign

    n_modes = 8
    out = tmp_path / "grid.h5"
    r = subprocess.run([*BELTDYN, "sweep", str(BENCH), *sum((["--param", f"{k}={v}"] for k, v in GRID), []),
                        "--modes", str(n_modes), "--workers", "2", "-o", str(out)], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    base = load_config(BENCH)
    spec = make_spec(base, GRID, analysis="modal", zip_=False, n_modes=n_modes)
    cases, static = [], []
    for i in range(spec.n_cases):
        try:
            run = analyse(with_overrides(base, [_assign(p.key, v) for p, v in zip(spec.params, spec.case_values(i))]),
                          modal=True, n_modes=n_modes + 4)
        except BeltdynError:
            cases.append(None)
            static.append(None)
            continue
        md, st = run.modal, run.static
        cases.append({"frequency": md.frequency, "shapes": md.shapes, "kind": np.array(md.kind), "order": md.order,
                      "span": md.span, "label": np.array(md.label),
                      "mshapes": np.asarray((run.system.mass_matrix(st.q) @ md.shapes.T).T)})
        static.append({"mean_tension": st.mean_tension, "span_tension": st.span_tension, "hub_load": st.hub_load,
                       "pulley_center": st.pulley_center})
    ref = _reference_tracking(spec, cases)
    with h5py.File(out) as f:
        g = f["sweep"]
        got = {name: g[name][()] for name in g if isinstance(g[name], h5py.Dataset)}
    failed = np.array([c is None for c in cases], dtype=np.int8)
    assert failed.tolist() == [0] * 4 + [1] * 4 + [0] * 4
    np.testing.assert_array_equal(got["failed"], failed)
    np.testing.assert_allclose(got["frequency"], ref["frequency"], rtol=1e-12)
    np.testing.assert_allclose(got["mac"], ref["mac"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got["order"], ref["order"])
    np.testing.assert_array_equal(got["span"], ref["span"])
    assert [[x.decode() if isinstance(x, bytes) else str(x) for x in row] for row in got["kind"]] \
        == [[str(x) for x in row] for row in ref["kind"]]
    first = next(c for c in cases if c is not None)
    assert [x.decode() if isinstance(x, bytes) else str(x) for x in got["label"]] == list(first["label"][:n_modes])
    for key in static[0]:
        want = np.stack([np.full(np.shape(static[0][key]), np.nan) if s is None else s[key] for s in static])
        np.testing.assert_allclose(got[key], want, rtol=1e-12, err_msg=key)


def test_the_journal_is_fsynced_at_the_end_and_on_an_interrupt(tmp_path, monkeypatch):
    # Batches are fsync'ed at most every SYNC_EVERY seconds; whatever the interval, the log is fsync'ed
    # when the run ends, and when it is interrupted (Ctrl-C after the first batch: those cases are kept).
    import stat

    from beltdyn.study import sweep as sw

    synced = []
    real = os.fsync

    def spy(fd):
        if stat.S_ISREG(os.fstat(fd).st_mode):
            synced.append(os.path.basename(os.readlink(f"/proc/self/fd/{fd}")))
        real(fd)

    monkeypatch.setattr(os, "fsync", spy)
    monkeypatch.setattr(sw, "SYNC_EVERY", 1e9)
    cfg = load_config(BENCH)
    spec = make_spec(cfg, [("tension.target", "150:300:12")], analysis="static", zip_=False)
    with Journal(tmp_path / "a.h5") as j:
        res = assemble(spec, j, run_sweep(cfg, spec, journal=j, workers=1))
    assert not res.failed.any() and synced.count("cases.log") == 1 and synced[-1] == "cases.log"
    synced.clear()

    def stop(k, n):
        if k:
            raise KeyboardInterrupt

    with Journal(tmp_path / "b.h5") as j, pytest.raises(KeyboardInterrupt):
        run_sweep(cfg, spec, journal=j, workers=1, progress=stop)
    assert synced[-1] == "cases.log"
    kept = Journal(tmp_path / "b.h5").done()
    assert kept and len(kept) < 12


def _drive_with_tables(folder: Path, tables: dict[str, float]) -> Path:
    """Torque tables (a ramp to the given torque in 10 ms, N m) and the bench with a 20 ms transient
    whose torque on C reads the first of them; the configuration's path."""
    for name, torque in tables.items():
        (folder / name).write_text(f"# time (s), torque (N m)\n0.0, 0.0\n0.01, {torque}\n1.0, {torque}\n")
    path = folder / "drive.toml"
    path.write_text(BENCH.read_text() + '\n[transient]\nduration = 0.02\nstep = 1e-4\n'
                    '[transient.spectrum]\nenabled = false\n[[transient.torque]]\npulley = "C"\n'
                    f'table = "{next(iter(tables))}"\n')
    return path


def test_csv_tables_travel_with_the_case(tmp_path):
    # A remote worker has no files next to the configuration: the case carries the tables' bytes
    # (config.table_bytes), and the worker parses the configuration from them (same static result as
    # a local parse, to round-off); without them the case fails naming the table it could not read.
    from beltdyn.config import resolved_toml, table_bytes
    from beltdyn.study.sweep import run_case

    path = _drive_with_tables(tmp_path, {"torque.csv": 2.0})
    cfg = load_config(path)
    tables = table_bytes(cfg)
    assert set(tables) == {"torque.csv"}
    elsewhere = str(tmp_path / "remote" / "drive.toml")  # no such folder: as on another machine
    got = run_case(resolved_toml(cfg), elsewhere, ["tension.target=250.0"], "static", 4, tables)
    assert got["failed"] == 0, got["error"]
    local = analyse(load_config(path, ["tension.target=250.0"])).static
    np.testing.assert_allclose(got["span_tension"], local.span_tension, rtol=1e-12)
    lost = run_case(resolved_toml(cfg), elsewhere, ["tension.target=250.0"], "static", 4)
    assert lost["failed"] == 1 and "torque.csv" in lost["error"]


def test_swept_csv_tables_travel_and_are_pinned(tmp_path):
    # Sweeping the table file itself: each case names its own table and carries its sha256
    # (sweep.case_assignments), the bytes of every swept table travel with the cases
    # (sweep_tables): a worker without the files gets the same results as one reading them (1e-12),
    # the two tables give different runs, and changing a swept table changes the sweep's identity
    # (a journal of the old table is not resumed with the new one).
    from beltdyn.config import resolved_toml
    from beltdyn.study.sweep import case_assignments, run_case, spec_hash, sweep_tables

    path = _drive_with_tables(tmp_path, {"a.csv": 2.0, "b.csv": 4.0})
    cfg = load_config(path)
    spec = make_spec(cfg, [("transient.torque[0].table", '"a.csv","b.csv"')], analysis="transient", zip_=False)
    tables = sweep_tables(cfg, spec)
    assert set(tables) == {"a.csv", "b.csv"}
    elsewhere = str(tmp_path / "remote" / "drive.toml")
    got = []
    for i in range(spec.n_cases):
        a = case_assignments(spec, spec.case_values(i), tables)
        remote = run_case(resolved_toml(cfg), elsewhere, a, "transient", 4, tables)
        local = run_case(resolved_toml(cfg), str(path), a, "transient", 4)
        assert remote["failed"] == 0 and local["failed"] == 0, (remote["error"], local["error"])
        np.testing.assert_allclose(remote["span_tension_half_range"], local["span_tension_half_range"], rtol=1e-12)
        got.append(remote["span_tension_half_range"])
    assert not np.allclose(got[0], got[1])
    before = spec_hash(cfg, spec)
    _drive_with_tables(tmp_path, {"b.csv": 3.0})
    assert spec_hash(cfg, spec) != before


def test_modal_rtol_decides_on_its_output_before_the_refinement(tmp_path):
    # A file of this configuration holding only /geometry /static /modal is replaced by the refined
    # run (its mesh is the chosen one afterwards); a file holding a /transient of this configuration is
    # refused at once (exit 2, before any refinement: no refinement table), and left as it was.
    plain = [*BELTDYN, "modal", str(BENCH)]
    r = subprocess.run([*plain, "-o", "m.h5"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([*plain, "--rtol", "1e-4", "-o", "m.h5"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "m.h5") as f:
        chosen = int(f["modal"].attrs["chosen_elements_per_span"])
        assert chosen > 10 and f"elements_per_span = {chosen}" in f["provenance/config_toml"].asstr()[()]
    sets = ["--set", "transient.duration=0.01", "--set", "transient.spectrum.enabled=false"]
    r = subprocess.run([*BELTDYN, "transient", str(BENCH), *sets, "-o", "t.h5"], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    before = (tmp_path / "t.h5").read_bytes()
    r = subprocess.run([*plain, *sets, "--rtol", "1e-5", "-o", "t.h5"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and "holds /transient" in r.stderr and "--force" in r.stderr, r.stderr
    assert "Mesh refinement" not in r.stdout and "Traceback" not in r.stderr
    assert (tmp_path / "t.h5").read_bytes() == before


def test_a_chunk_fits_and_numbers_each_drive_once_and_its_cases_equal_single_runs(monkeypatch):
    # `run_chunk` keeps the L0 fits, DOF maps and assembly patterns of its cases by their inputs (a
    # `reuse.Reuse`): the cases of one geometry share one fit, a case of another geometry (the belt's length
    # swept) fits anew, all four (one mesh, one set of pulleys) share one DOF map and one pattern, and every
    # case's results equal the case run alone (`run_case`, which makes its own), to the bit.
    from beltdyn.config import resolved_toml
    from beltdyn.model import reuse
    from beltdyn.study.cases import run_chunk
    from beltdyn.study.sweep import run_case

    cfg = load_config(BENCH)
    base = resolved_toml(cfg)
    items = [(0, ["tension.target=150.0"]), (1, ["belt.length=1.80"]), (2, ["tension.target=300.0"]),
             (3, ["belt.length=1.80", "tension.target=250.0"])]
    alone = [run_case(base, cfg.source, a, "modal", 6) for _, a in items]
    made = {"fit": [], "dofs": [], "pattern": []}
    for kind, name in (("fit", "layout_from_config"), ("dofs", "number_dofs"), ("pattern", "make_pattern")):
        real = getattr(reuse, name)
        monkeypatch.setattr(reuse, name, lambda *a, _k=kind, _f=real, **kw: made[_k].append(a[0]) or _f(*a, **kw))
    chunk = run_chunk(base, cfg.source, {}, items, "modal", 6)
    assert [c.belt.length for c in made["fit"]] == [cfg.belt.length, 1.80]  # two geometries: two fits for four cases
    assert len(made["dofs"]) == 1 and len(made["pattern"]) == 1
    for (i, got), want in zip(chunk, alone):
        assert got["failed"] == 0 == want["failed"], got["error"]
        assert got.keys() == want.keys()
        for k in got:
            if k != "wall_time":
                np.testing.assert_array_equal(got[k], want[k], err_msg=f"case {i}: {k}")
