"""Sweep items of issue 26, through the real CLI: a --param overrides the file's [sweep.params] key by key
(and says so), a resumed sweep says how many cases it reuses (in tests/test_sweep.py's resume test), and
a static sweep's console table shows the working curve (arm angle and torque) and the slip margins
that /sweep holds."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

from beltdyn.study.sweep import merge_params

ROOT = Path(__file__).resolve().parents[1]
BELTDYN = [str(Path(sys.executable).parent / "beltdyn")]
CAMPBELL = ROOT / "configs" / "examples" / "bench_campbell.toml"
ARM = ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"


def _run(*args, cwd) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE", "COLUMNS")}
    env["NO_COLOR"] = "1"
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=600, env=env)


def test_merge_params_overrides_key_by_key():
    # The file's keys keep their place (a key given on the command line takes its spec there); new keys
    # follow in command line order; the overridden keys are returned. Reference: the lists written out.
    table = (("running.driver_speed", "0:600:61"), ("belt.EI", "0.02,1"))
    given = [("tension.target", "150,250"), ("running.driver_speed", "0:600:5")]
    merged, overridden = merge_params(table, given)
    assert merged == [("running.driver_speed", "0:600:5"), ("belt.EI", "0.02,1"), ("tension.target", "150,250")]
    assert overridden == ("running.driver_speed",)
    assert merge_params(table, []) == (list(table), ())


def test_the_readmes_campbell_command_overrides_the_files_range(tmp_path):
    # The README's command on the Campbell example (its [sweep.params] sweeps running.driver_speed over
    # 0:600:61) with a --param of the same key: exit 0 (it was exit 2), the note on the console, and
    # /sweep holds the command line's 5 speeds, not the file's 61.
    r = _run("sweep", CAMPBELL, "--param", "running.driver_speed=0:600:5", "--modes", "4", "--workers", "1",
             "-o", "c.h5", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"note: --param running.driver_speed overrides [sweep.params] running.driver_speed of {CAMPBELL}" in r.stdout
    with h5py.File(tmp_path / "c.h5") as f:
        swept = [k for k in f["sweep"] if k.startswith("param_")]
        assert len(swept) == 1
        np.testing.assert_array_equal(f["sweep"][swept[0]][()], [0.0, 150.0, 300.0, 450.0, 600.0])


def _table_rows(stdout: str) -> list[list[str]]:
    """The body rows of the first rich table on the console (cells stripped)."""
    rows = [ln for ln in stdout.splitlines() if ln.startswith("│")]
    return [[c.strip() for c in ln.strip("│").split("│")] for ln in rows]


def _header(stdout: str) -> list[str]:
    line = next(ln for ln in stdout.splitlines() if ln.startswith("┃"))
    return [c.strip() for c in line.strip("┃").split("┃")]


def test_a_static_sweep_shows_the_working_curve_and_the_slip_margins(tmp_path):
    # A static sweep over an accessory torque (tensioner in spring mode, friction given on every pulley):
    # the console table shows, per case, the arm's angle (deg) and torque and the least slip margin with
    # its pulley, equal to /sweep's arm_angle, arm_torque and slip_margin of the same case (the file).
    sets = ["static.torque=[{pulley='C', value=0.0}]", "pulleys[2].arm_free_angle=3.19", "tension={mode='spring'}",
            "mesh.elements_per_span=6", "pulleys[0].friction=0.3", "pulleys[1].friction=0.3", "pulleys[2].friction=0.3"]
    r = _run("sweep", ARM, "--param", "static.torque[0].value=0:-30:4", "--analysis", "static",
             *[x for s in sets for x in ("--set", s)], "-o", "s.h5", "--workers", "1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    head = _header(r.stdout)
    assert head == ["static.torque[0].value", "mean tension (N)", "T arm angle (deg)", "T arm torque (N m)",
                    "least slip margin", "at pulley", "wall (ms)"], head
    rows = _table_rows(r.stdout)
    assert len(rows) == 4
    names = ["A", "C", "T"]  # the example's pulleys, in its order
    with h5py.File(tmp_path / "s.h5") as f:
        angle, torque = f["sweep/arm_angle"][:, 2], f["sweep/arm_torque"][:, 2]
        margin = f["sweep/slip_margin"][()]
        tension = f["sweep/mean_tension"][()]
    for i, row in enumerate(rows):
        assert float(row[1]) == float(f"{tension[i]:.3f}")
        assert float(row[2]) == float(f"{np.degrees(angle[i]):.3f}")
        assert float(row[3]) == float(f"{torque[i]:.4g}")
        least = np.nanmin(margin[i])  # inf where no pulley transmits torque (its two tensions agree)
        assert float(row[4]) == float(f"{least:.3f}")
        assert row[5] == (names[int(np.nanargmin(margin[i]))] if np.isfinite(least) else "")
    assert len({row[2] for row in rows}) == 4  # the arm turns with the load: a working curve, not one value
