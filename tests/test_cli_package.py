"""The CLI as a package (issue 24): one module per command, beltdyn's own cleanup list before the quick
exit, `--unset KEY`, and the console's words in their number (issue 26)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from beltdyn import cleanup
from beltdyn.config import apply_override
from beltdyn.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "configs" / "smoke" / "two_pulley.toml"
TENSIONER = ROOT / "configs" / "examples" / "three_pulley_tensioner.toml"


def test_every_command_module_is_a_command():
    # adding a command is adding a module to beltdyn/cli/commands: the app has exactly those commands
    from beltdyn.cli.main import app, command_modules

    names = sorted(c.callback.__name__ for c in app.registered_commands)
    assert names == command_modules()
    assert {"geometry", "static", "modal", "transient", "response", "sweep", "plot", "paper"} <= set(names)


def test_python_dash_m_runs_the_cli():
    r = subprocess.run([sys.executable, "-m", "beltdyn.cli", "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("beltdyn "), r.stderr


def test_cleanup_runs_newest_first_once_each_and_all_despite_an_error():
    ran = []

    def boom():
        ran.append("boom")
        raise RuntimeError("x")

    cleanup.at_exit(lambda: ran.append("first"))
    cleanup.at_exit(boom)
    cleanup.at_exit(lambda: ran.append("last"))
    with pytest.raises(RuntimeError):
        cleanup.run_all()
    assert ran == ["last", "boom", "first"]
    cleanup.run_all()  # nothing left: each ran once
    assert ran == ["last", "boom", "first"]


def test_unset_removes_a_key_and_refuses_one_that_is_not_there():
    raw = {"tension": {"target": 400.0, "mode": "adjust"}, "pulleys": [{"name": "A", "radius": 0.04, "torque": 1.0}]}
    apply_override(raw, "tension.target=", file="d.toml")
    assert raw["tension"] == {"mode": "adjust"}
    apply_override(raw, "pulleys.A.torque=", file="d.toml")
    assert raw["pulleys"] == [{"name": "A", "radius": 0.04}]
    with pytest.raises(ConfigError, match=r"d.toml: --unset tension.target: no 'tension.target'"):
        apply_override(raw, "tension.target=", file="d.toml")
    with pytest.raises(ConfigError, match="--unset tensoin"):
        apply_override(raw, "tensoin.target=", file="d.toml")  # an unknown table, as --set says it


def test_unset_on_the_command_line_is_bad_input_in_under_a_second(tmp_path):
    from processes import BELTDYN

    start = time.monotonic()
    r = subprocess.run([*BELTDYN, "geometry", str(SMOKE), "--unset", "belt.colour", "-o", "g.h5"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=60)
    took = time.monotonic() - start
    assert r.returncode == 2 and "--unset belt.colour" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert took < 1.0 or pytest.skip(f"busy machine: {took:.2f} s")


def test_counts_are_said_in_their_number():
    from beltdyn.cli.console import plural

    assert plural(1, "Newton iteration") == "1 Newton iteration"
    assert plural(0, "Newton iteration") == "0 Newton iterations"
    assert plural(3, "step halving") == "3 step halvings"


def test_switching_to_spring_mode_needs_no_file_edit(tmp_path):
    # tension.mode = "spring" refuses a tension.target; --unset takes it out on the command line: the
    # configuration then gets as far as the next check (the arm's free angle), not the target's
    from processes import BELTDYN

    args = [*BELTDYN, "static", str(TENSIONER), "--set", "tension.mode=spring", "-o", "s.h5"]
    kept = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert kept.returncode == 2 and "remove tension.target" in kept.stderr, kept.stderr
    removed = subprocess.run([*args, "--unset", "tension.target"], cwd=tmp_path, capture_output=True, text=True,
                             timeout=60)
    assert removed.returncode == 2 and "tension.target" not in removed.stderr, removed.stderr
    assert "arm_free_angle" in removed.stderr


def test_the_kernel_compile_is_announced_with_its_time(tmp_path):
    # numba's first compile takes up to minutes on a busy machine: it is said before and its time after
    # (piped: on stderr; in a terminal a spinner with the elapsed time). The compile is stood in for by a
    # 1.2 s sleep, the kernels reported not cached.
    code = """
import time
import beltdyn.pipeline as p
import beltdyn.jitcache as j
p.warm_up = lambda: time.sleep(1.2)
j.is_warm = lambda *modules: False
import sys
from beltdyn.cli import app
sys.argv = ["beltdyn", "transient", %r, "--duration", "0.05", "--set", "transient.spectrum.enabled=false", "-o", "t.h5"]
app()
""" % str(ROOT / "configs" / "examples" / "bench_transient_small.toml")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "compiling the transient kernels" in r.stderr and "about 20 s" not in r.stderr + r.stdout
    assert "note: done in 1 s" in r.stderr
    assert "compiling" not in r.stdout  # stdout keeps the results
