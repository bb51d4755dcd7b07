"""`beltdyn transient --resume` (issue 26, item 5): a transient interrupted by SIGTERM or kill -9 at
several moments (before its first checkpoint, after the first, after a later one) continues from its
last checkpoint (`<output>.transient/`) to the result of the uninterrupted run of the same command:
every history equal to 1e-9 of the series' largest magnitude (compared against that uninterrupted
run, computed here by the same CLI), one time axis with no sample twice, status `complete`, the
resume journal gone. A resume of another configuration, or with nothing to resume, is refused
(exit 2, naming both hashes). Real processes throughout (`tests/processes.py`).
"""

from __future__ import annotations

import functools
import signal
import time
from pathlib import Path

import numpy as np
import pytest

import processes  # tests/processes.py
from processes import BELTDYN, wait_for

from beltdyn.analysis.transient import TransientSnapshot, snapshot_bytes, snapshot_from_bytes
from beltdyn.results.io import read_group

ROOT = Path(__file__).resolve().parents[1]
TRANSIENT = ROOT / "configs" / "examples" / "bench_transient_small.toml"
# long enough for a few checkpoints (--checkpoint-every apart) on a fast machine as on a busy one, short
# enough for the default suite; the spectrum (from 1 s) on the samples of both parts
ARGS = ["--duration", "1.2", "--step", "2e-5"]  # 60000 steps: 1.5-6 s of stepping
OFTEN = ["--checkpoint-every", "0.1"]  # checkpoints 0.1 s apart, not the default 1 s (none in the configuration's hash)
RTOL = 1e-9


_env = processes.plain_env


run = functools.partial(processes.run, timeout=900)


def histories(path: Path) -> tuple[dict, np.ndarray, dict[str, np.ndarray]]:
    g = read_group(path, "transient")
    series = {k: np.asarray(v) for k, v in g["variables"].items() if g["dims"][k][:1] == ("time",)}
    return g["attrs"], np.asarray(g["coords"]["time"]), series


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The uninterrupted run of the same command."""
    folder = tmp_path_factory.mktemp("reference")
    out = folder / "ref.h5"
    r = run("transient", TRANSIENT, "-o", out, *ARGS, cwd=folder)
    assert r.returncode == 0, r.stderr
    assert not Path(str(out) + ".transient").exists()  # a complete run leaves no resume journal
    return histories(out)


def checkpoints_seen(proc, state: Path, count: int, timeout: float = 300.0) -> bool:
    """Wait until the checkpoint file has been (re)written `count` times (distinct modification times)
    while `proc` runs."""
    seen: set[int] = set()

    def more() -> bool:
        try:
            seen.add(state.stat().st_mtime_ns)
        except FileNotFoundError:
            pass
        return len(seen) >= count or proc.poll() is not None

    return bool(wait_for(more, timeout=timeout, step=0.01)) and len(seen) >= count


def interrupt(out: Path, cwd: Path, sig: int, checkpoints: int) -> None:
    """Start the transient into `out` and send `sig` once `checkpoints` checkpoints were written (0:
    as soon as it streams samples, before its first checkpoint)."""
    often = OFTEN if checkpoints else []  # before any: the default 1 s leaves the time to interrupt first
    proc = processes.popen([*BELTDYN, "transient", str(TRANSIENT), "-o", str(out), *ARGS, *often], cwd=cwd,
                           env=_env())
    state = Path(str(out) + ".transient") / "state.bin"
    try:
        if checkpoints:
            assert checkpoints_seen(proc, state, checkpoints), "not as many checkpoints written"
        else:
            assert wait_for(lambda: (Path(str(out) + ".transient") / "spec.json").exists(), timeout=300)
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before the interrupt: make ARGS longer"
    finally:
        proc.send_signal(sig)
        _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == (143 if sig == signal.SIGTERM else -signal.SIGKILL), stderr
    assert (Path(str(out) + ".transient") / "spec.json").exists()
    if checkpoints == 0:
        assert not state.exists(), "a checkpoint came before the interrupt (the case wants none)"


def assert_same_run(out: Path, reference) -> None:
    attrs, t, series = histories(out)
    ref_attrs, ref_t, ref_series = reference
    assert attrs["status"] == "complete"
    assert np.all(np.diff(t) > 0), "the time axis repeats or goes back"
    np.testing.assert_array_equal(t, ref_t)  # one continuous axis, the uninterrupted run's samples
    assert set(series) == set(ref_series)
    for name, ref in ref_series.items():
        scale = float(np.max(np.abs(ref[np.isfinite(ref)]), initial=0.0))  # (finite values: a margin may be inf)
        np.testing.assert_allclose(series[name], ref, rtol=RTOL, atol=RTOL * scale, err_msg=name)
    assert attrs["steps"] == ref_attrs["steps"]
    assert attrs["n_slack_events"] == ref_attrs["n_slack_events"]
    np.testing.assert_allclose(attrs["energy_balance_error"], ref_attrs["energy_balance_error"], rtol=1e-6)
    assert not Path(str(out) + ".transient").exists()


@pytest.mark.parametrize("sig, checkpoints", [(signal.SIGTERM, 1), (signal.SIGKILL, 2), (signal.SIGKILL, 0)],
                         ids=["sigterm-after-1st-checkpoint", "kill9-after-2nd-checkpoint", "kill9-before-any"])
def test_resume_equals_the_uninterrupted_run(tmp_path, reference, sig, checkpoints):
    out = tmp_path / "r.h5"
    interrupt(out, tmp_path, sig, checkpoints)
    r = run("transient", TRANSIENT, "-o", out, *ARGS, "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    said = "resuming the transient at t =" if checkpoints else "made no checkpoint yet: it starts over"
    assert said in r.stderr + r.stdout
    assert_same_run(out, reference)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["sigterm", "kill9"])
def test_resume_after_a_later_checkpoint_and_twice(tmp_path, reference, sig):
    # interrupted after its 3rd checkpoint, resumed, the resumed run interrupted again, resumed again
    out = tmp_path / "r.h5"
    interrupt(out, tmp_path, sig, 3)
    proc = processes.popen([*BELTDYN, "transient", str(TRANSIENT), "-o", str(out), *ARGS, *OFTEN, "--resume"],
                           cwd=tmp_path,
                           env=_env())
    state = Path(str(out) + ".transient") / "state.bin"
    before = state.stat().st_mtime_ns
    try:
        assert wait_for(lambda: state.stat().st_mtime_ns != before or proc.poll() is not None, timeout=300)
        assert proc.poll() is None
    finally:
        proc.send_signal(sig)
        proc.communicate(timeout=120)
    r = run("transient", TRANSIENT, "-o", out, *ARGS, "--resume", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert_same_run(out, reference)


def test_resume_of_another_configuration_or_of_nothing_is_refused(tmp_path):
    out = tmp_path / "r.h5"
    r = run("transient", TRANSIENT, "-o", out, *ARGS, "--resume", cwd=tmp_path)  # nothing interrupted
    assert r.returncode == 2 and "no interrupted transient to resume" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    interrupt(out, tmp_path, signal.SIGKILL, 0)
    r = run("transient", TRANSIENT, "-o", out, "--duration", "1.3", "--resume", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "ran configuration sha256" in r.stderr and "this one is sha256" in r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert "Traceback" not in r.stderr and len(errors) == 1 and "--resume: the interrupted" in errors[0], r.stderr
    assert (Path(str(out) + ".transient") / "spec.json").exists()  # the journal is kept for the right resume


def _snapshot() -> TransientSnapshot:
    rng = np.random.default_rng(7)
    n = 5
    return TransientSnapshot(
        q=rng.normal(size=n), v=rng.normal(size=n), a=rng.normal(size=n), f0=rng.normal(size=n),
        fd0=rng.normal(size=n), F0=rng.normal(size=n), R0=rng.normal(size=1), scal=rng.normal(size=16),
        anchor=rng.normal(size=1), slack=np.zeros(3), events=rng.normal(size=(2, 4)), factor_q=rng.normal(size=n),
        factor_v=rng.normal(size=n), factor_h=1e-4, factor_t=0.25, fresh=False, calm=1, delivered=42, steps=400,
        refactorizations=3, halvings=1, min_step=5e-5, refresh=12.5, tension_low=np.array([1.0, np.inf, 3.0]),
        tension_low_time=np.array([0.1, np.nan, 0.2]), tension_high=(900.0, 0.3), worst_slip=(np.inf, np.nan, ""),
        stop_hit=(0.2, "TEN", 0.7))


def test_snapshot_record_round_trips_bit_for_bit_and_refuses_damage():
    # the record against the snapshot it was made from (every field, arrays bit for bit)
    snap = _snapshot()
    back = snapshot_from_bytes(snapshot_bytes(snap))
    for name in ("q", "v", "a", "f0", "fd0", "F0", "R0", "scal", "anchor", "slack", "events", "factor_q", "factor_v",
                 "tension_low", "tension_low_time"):
        np.testing.assert_array_equal(getattr(back, name), getattr(snap, name), err_msg=name)
        assert not getattr(back, name).flags.writeable
    for name in ("factor_h", "factor_t", "fresh", "calm", "delivered", "steps", "refactorizations", "halvings",
                 "min_step", "refresh", "tension_high", "stop_hit"):
        assert getattr(back, name) == getattr(snap, name), name
    assert back.worst_slip[0] == np.inf and np.isnan(back.worst_slip[1]) and back.worst_slip[2] == ""
    data = bytearray(snapshot_bytes(snap))
    data[100] ^= 1
    with pytest.raises(ValueError, match="checksum"):
        snapshot_from_bytes(bytes(data))
    with pytest.raises(ValueError):
        snapshot_from_bytes(snapshot_bytes(snap)[:-8])


def test_run_transient_resumed_at_each_checkpoint_continues_the_same_run():
    # the library's restart hook against the uninterrupted run in the same process: from each
    # checkpoint (taken before every stepper call) through its checksummed record, the samples after it,
    # the step count, the energy balance and the slip/tension extrema are the uninterrupted run's
    from beltdyn.analysis.timestep import resolve_step
    from beltdyn.analysis.transient import run_transient
    from beltdyn.config import load_config
    from beltdyn.pipeline import analyse, transient_start

    cfg = load_config(TRANSIENT, ["transient.duration=0.3", "transient.spectrum.enabled=false"])
    drive = analyse(cfg)
    opts, _ = resolve_step(cfg.transient)

    def run(**kw):
        system, static = transient_start(drive)
        got: list = []
        summary = run_transient(system, static, opts, sink=lambda t, b: got.append((t, b)), **kw)
        return summary, np.concatenate([g[0] for g in got]), {k: np.concatenate([g[1][k] for g in got])
                                                              for k in got[0][1]}

    snaps: list = []
    whole, t_ref, ref = run(on_checkpoint=snaps.append, checkpoint_seconds=0.0)
    assert len(snaps) >= 2 and snaps[-1].delivered > 0
    for snap in snaps[1:]:
        part, t, got = run(resume=snapshot_from_bytes(snapshot_bytes(snap)))
        k = snap.delivered
        np.testing.assert_array_equal(t, t_ref[k:])
        for name, r in ref.items():
            scale = float(np.max(np.abs(r[np.isfinite(r)]), initial=0.0))  # (finite values: a margin may be inf)
            np.testing.assert_allclose(got[name], r[k:], rtol=RTOL, atol=RTOL * scale, err_msg=name)
        assert part.steps == whole.steps and part.n_outputs == whole.n_outputs
        assert part.energy_error == pytest.approx(whole.energy_error, rel=1e-6)
        assert part.worst_slip_margin[2] == whole.worst_slip_margin[2]
        assert len(part.slack_events) == len(whole.slack_events)
