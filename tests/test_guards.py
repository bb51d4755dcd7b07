"""Guards before work and warnings for results outside their model's validity (issue 10, item 4).

References: the rule itself (a step longer than a tenth of the period of the excitation or of the
highest mode the run resolves), the recorded span tensions and slack events of the same run (the
warnings must name what the file holds), the model's own DOF count (the estimate's upper bound).
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from beltdyn.config import load_config
from beltdyn.analysis.guards import cost_note, estimate_cost
from beltdyn.model.system import build_system, model_dofs
from beltdyn.analysis.timestep import step_warnings
from processes import BELTDYN  # tests/processes.py

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "configs" / "examples" / "bench_transient_small.toml"
LARGE = ROOT / "configs" / "examples" / "bench_transient_large.toml"


def run(*args, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300)


def warnings_of(path: Path) -> list[str]:
    with h5py.File(path, "r") as f:
        return [w.decode() if isinstance(w, bytes) else str(w) for w in f["transient"].attrs["warnings"]]


@pytest.mark.parametrize("f", [45.0, 224.997, 1000.0])
def test_step_rule_is_a_tenth_of_the_period(f):
    # exactly a tenth of the period passes; 0.1 % longer is flagged, for the excitation and the mode alike
    assert step_warnings(0.1 / f, excitation_frequency=f, mode_frequency=f) == ()
    (exc,) = step_warnings(1.001 * 0.1 / f, excitation_frequency=f)
    assert "excitation period" in exc
    (mode,) = step_warnings(1.001 * 0.1 / f, mode_frequency=f, mode_source="transient.fmax")
    assert "highest mode" in mode and "transient.fmax" in mode and f"{f:.6g} Hz" in mode


def test_a_step_that_resolves_no_mode_is_warned_before_the_run(tmp_path):
    # --step 5e-4 s on the bench: within a tenth of the 45 Hz excitation's period (2.2e-3 s) but beyond
    # a tenth of the period of its 16th mode (225 Hz, 4.4e-4 s): said before the run starts, kept in the
    # file. (It was 2e-3 s; that step's energy balance error, ~7 %, now fails the run: issue 26.)
    r = run("transient", SMALL, "--step", "5e-4", "--duration", "0.1", "--set", "transient.spectrum.start=0.05",
            "--set", "transient.output_interval=2e-3", "-o", "s.h5", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert out.index("highest mode the run is meant to resolve") < out.index("transient complete")
    assert out.count("highest mode the run is meant to resolve") == 1  # not repeated after the run
    w = warnings_of(tmp_path / "s.h5")
    assert any("mode 16" in x and "224.8" in x for x in w), w  # (creep wraps; 224.9 Hz with rigid wraps)
    assert not any("excitation period" in x for x in w), w


@pytest.mark.parametrize("amplitude, kind", [(0.025, "came close to slack"), (0.03, "went slack")])
def test_transient_names_spans_near_or_past_slack(tmp_path, amplitude, kind):
    # The bench under a large rotation of C (45 Hz): at 0.025 rad both spans' tension dips below 10 %
    # of the static 200 N without going slack, at 0.03 rad they go slack. The warning quotes the
    # smallest recorded end tension (4 digits) or the number of slack events in /transient/slack_events.
    r = run("transient", LARGE, "--duration", "0.3", "--set", "transient.spectrum.enabled=false",
            "--set", f"transient.rotation[0].amplitude={amplitude}", "-o", "t.h5", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    w = [x for x in warnings_of(tmp_path / "t.h5") if kind in x]
    assert {x.split()[1] for x in w} == {"A-C", "C-A"}, w
    with h5py.File(tmp_path / "t.h5", "r") as f:
        T = f["transient/span_tension"][()]  # (time, span, end)
        spans = [s.decode() if isinstance(s, bytes) else str(s) for s in f["transient/span"][()]]
        ev = f["transient/slack_events"] if "slack_events" in f["transient"] else None
        ev_span = [] if ev is None else [s.decode() if isinstance(s, bytes) else str(s) for s in ev["event_span"][()]]
        ev_slack = [] if ev is None else ev["slack"][()].tolist()
    for x in w:
        name = x.split()[1]
        if kind == "came close to slack":
            low = float(re.search(r"slack: (\S+) N", x).group(1))
            assert low == pytest.approx(T[:, spans.index(name)].min(), rel=1e-3)
            assert 0.0 < low < 20.0
        else:
            count = int(re.search(r"went slack (\d+) time", x).group(1))
            assert count == sum(1 for s, k in zip(ev_span, ev_slack) if s == name and k == 1)
    assert kind in r.stdout


def test_dof_estimate_bounds_the_model():
    # the estimate counts 3 DOFs per pulley; a fixed or sliding pulley has fewer: an upper bound
    # within 3 per pulley of the built model
    for path in sorted((ROOT / "configs").glob("*/*.toml")):
        cfg = load_config(path)
        n = build_system(cfg).n_dof
        assert n <= model_dofs(cfg) <= n + 3 * len(cfg.pulleys), path


def test_a_long_run_is_announced_before_any_work(tmp_path):
    # 2000 s at 1e-5 s: 2e8 steps, hours of work: announced with its step count before anything runs
    # (here the output-volume guard then refuses the histories, exit 2, before any analysis)
    cfg = load_config(SMALL)
    from beltdyn.analysis.timestep import resolve_step

    opts, _ = resolve_step(cfg.transient, manual=1e-5)
    est = estimate_cost(cfg, opts)
    assert est.steps == int(round(cfg.transient.duration / 1e-5)) and est.n_dof == model_dofs(cfg)
    r = run("transient", SMALL, "--duration", "2000", "--step", "1e-5", "--set", "transient.output_interval=1e-5",
            "-o", "l.h5", cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert "note" in r.stdout and "200,000,000 transient steps" in r.stdout
    assert not (tmp_path / "l.h5").exists()
    assert cost_note(estimate_cost(cfg)) is None  # the example's static + modal: no note


def test_the_memory_guard_names_the_mesh_key(tmp_path):
    # an impossible mesh: exit 2 naming mesh.elements_per_span with the estimate, nothing written
    r = run("static", ROOT / "configs" / "paper" / "bench_T200.toml", "--set", "mesh.elements_per_span=1000000000",
            "-o", "m.h5", cwd=tmp_path)
    assert r.returncode == 2 and "mesh.elements_per_span" in r.stderr and "GB" in r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "m.h5").exists()
    assert np.isfinite(estimate_cost(load_config(ROOT / "configs" / "paper" / "bench_T200.toml")).total_s)
