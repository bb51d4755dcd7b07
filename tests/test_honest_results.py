"""The crash and small-defect list of the "Honest results" issue, each with the real command in a
subprocess: no traceback (internal errors and MemoryError are one line), sweep journal lock, sweep
workers dying with their parent, SIGTERM, --workers cap, --param vs [sweep.params], every sweep value
validated, read-only / foreign / corrupt output files, `modal --rtol` exit code and re-run, the stored
peak table, honest units, angles and table widths on the console, the SPDX license.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "configs" / "smoke" / "two_pulley.toml"
BENCH = ROOT / "configs" / "paper" / "bench_T200.toml"
TRANSIENT = ROOT / "configs" / "examples" / "bench_transient_small.toml"
_SCRIPT = Path(sys.executable).parent / "beltdyn"
BELTDYN = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "beltdyn.cli"]


def _env(**extra) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("FORCE_COLOR", "TTY_COMPATIBLE", "CLICOLOR_FORCE",
                                                            "COLUMNS")}
    env["NO_COLOR"] = "1"
    env.update(extra)
    return env


def run(*args, cwd, timeout=120, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*BELTDYN, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env=env or _env(), **kw)


def run_patched(patch: str, *args, cwd, debug=False) -> subprocess.CompletedProcess:
    """The real CLI app in a fresh interpreter, after `patch` (Python source) has broken a module."""
    argv = ["beltdyn", *(["--debug"] if debug else []), *map(str, args)]
    code = textwrap.dedent(patch) + f"\nimport sys\nfrom beltdyn.cli import app\nsys.argv = {argv!r}\napp()\n"
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=120,
                          env=_env())


# ----------------------------------------------------------------------------- 1. no traceback
BOOM = """
import beltdyn.geometry as g
def boom(*a, **k):
    raise RuntimeError("boom\\nsecond line")
g.layout_from_config = boom
"""


def test_internal_error_is_one_line_and_debug_shows_the_traceback(tmp_path):
    # An unexpected exception (a defect): exit 1, one stderr line "internal error: RuntimeError: boom..."
    # asking for a report and --debug, no traceback; with the global --debug the traceback comes first.
    r = run_patched(BOOM, "geometry", SMOKE, "-o", "x.h5", cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("internal error: RuntimeError: boom\\nsecond line; please file it")
    assert "--debug" in lines[0]
    assert not (tmp_path / "x.h5").exists()
    d = run_patched(BOOM, "geometry", SMOKE, "-o", "x.h5", cwd=tmp_path, debug=True)
    assert d.returncode == 1
    assert "Traceback (most recent call last)" in d.stderr and "RuntimeError: boom" in d.stderr
    assert d.stderr.strip().splitlines()[-1].startswith("internal error: RuntimeError")


def test_memory_error_is_one_line_suggesting_a_smaller_mesh(tmp_path):
    # A real MemoryError: the address space limited to 900 MiB and a mesh of a million elements per
    # span. Exit 1, one line saying "out of memory" and naming mesh.elements_per_span, no traceback.
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (900 << 20, 900 << 20))

    r = subprocess.run([*BELTDYN, "modal", str(SMOKE), "--set", "mesh.elements_per_span=1000000", "-o", "m.h5"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120, env=_env(), preexec_fn=limit)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: out of memory"), r.stderr
    assert "mesh.elements_per_span" in lines[0]
    assert not list(tmp_path.glob("*.tmp*"))


def test_help_lists_debug_and_exit_codes(tmp_path):
    r = run("--help", cwd=tmp_path)
    assert r.returncode == 0
    assert "--debug" in r.stdout and "143" in r.stdout
