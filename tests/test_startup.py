"""Start-up (issue 10, item 5; issue 24): where numba's cache goes, whether it is warm (beltdyn's stamp,
told through public means only), and that `warm_up` (what `make` runs at install) compiles every signature
a transient uses, so a user's first run loads instead of compiling. Whether numba compiled or loaded a
kernel is read from its documented NUMBA_DEBUG_CACHE report ("data saved to" / "data loaded from").
Timings are in `make bench`, not here."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from beltdyn import jitcache

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "beltdyn"


def test_cache_goes_to_the_user_cache_when_the_package_folder_is_not_writable(tmp_path, monkeypatch):
    # an in-tree folder that cannot be made (a path below a regular file): the user cache folder
    # ($XDG_CACHE_HOME/beltdyn/numba); when that cannot be made either: the temporary folder's
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    key = jitcache.source_key()  # each folder keyed by the kernels' sources
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert jitcache.cache_dir(blocked / "__pycache__") == str(tmp_path / "cache" / "beltdyn" / "numba" / key)
    assert (tmp_path / "cache" / "beltdyn" / "numba" / key).is_dir()
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    got = jitcache.cache_dir(blocked / "__pycache__")
    assert got is not None and Path(got).parent.parent == Path(__import__("tempfile").gettempdir())
    assert Path(got).name == key
    writable = tmp_path / "writable" / "__pycache__"
    assert jitcache.cache_dir(writable) == str(writable / "numba" / key)  # the package's own folder first
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert jitcache.cache_dir(blocked / "__pycache__") is None  # the user's choice stands


def _read_only_namespace() -> list[str] | None:
    """`unshare` prefix that runs a command with the package folder mounted read-only, or None."""
    if shutil.which("unshare") is None:
        return None
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", f"mount --bind -o ro {PACKAGE} {PACKAGE} && "
                            f"! touch {PACKAGE}/__pycache__/.probe 2>/dev/null"], capture_output=True)
    return ["unshare", "-rm", "sh", "-c"] if probe.returncode == 0 else None


def test_read_only_installation_caches_in_the_user_folder(tmp_path):
    # The package folder mounted read-only (a mount namespace; skipped where there is none): importing
    # the kernels sets NUMBA_CACHE_DIR to $XDG_CACHE_HOME/beltdyn/numba, and numba's config follows.
    prefix = _read_only_namespace()
    if prefix is None:
        pytest.skip("no mount namespace here to make the package folder read-only")
    code = ("import os, beltdyn.analysis.integrator, numba.core.config as c; "
            "print(os.environ['NUMBA_CACHE_DIR']); print(c.CACHE_DIR)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    r = subprocess.run([*prefix, f"mount --bind -o ro {PACKAGE} {PACKAGE} && {sys.executable} -c \"{code}\""],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    want = str(tmp_path / "cache" / "beltdyn" / "numba" / jitcache.source_key())
    assert r.stdout.split() == [want, want]


def test_the_cache_folder_is_keyed_by_every_kernel_source(tmp_path):
    # numba invalidates a cached compile only when the function's own file changes, not when a kernel it
    # inlines from another file (the bar law) does: the cache folder is keyed by the sources of every module
    # that defines a kernel, which `KERNEL_SOURCES` lists (held here to the package's sources), and an edit
    # of any of them (the bar law's file included) is a new key.
    import re

    import importlib

    defining = {str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                if p.name != "jitcache.py" and re.search(r"^\s*@njit\(", p.read_text(), re.M)}
    compiled = set()  # the modules whose functions the kernel modules compile (njit(barlaw.axial_force) too)
    for name in defining:
        module = importlib.import_module("beltdyn." + name[:-3].replace("/", "."))
        compiled |= {str(Path(sys.modules[o.py_func.__module__].__file__).relative_to(PACKAGE))
                     for o in vars(module).values() if hasattr(o, "py_func")}
    assert sorted(defining | compiled) == sorted(jitcache.KERNEL_SOURCES)
    copy = tmp_path / "beltdyn"
    for name in jitcache.KERNEL_SOURCES:
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(PACKAGE / name, copy / name)
    assert jitcache.source_key(copy) == jitcache.source_key()
    keys = {jitcache.source_key()}
    for name in jitcache.KERNEL_SOURCES:
        original = (copy / name).read_text()
        (copy / name).write_text(original + "\n# edited\n")
        keys.add(jitcache.source_key(copy))
        (copy / name).write_text(original)
    assert len(keys) == 1 + len(jitcache.KERNEL_SOURCES)


def test_a_fresh_cache_is_cold():
    # a cache folder with nothing in it: is_warm says so without compiling anything
    import tempfile

    with tempfile.TemporaryDirectory() as empty:
        env = dict(os.environ, NUMBA_CACHE_DIR=empty)
        r = subprocess.run([sys.executable, "-c", "from beltdyn import jitcache; from beltdyn.analysis.transient import "
                            "entry_kernels; print(jitcache.is_warm(*entry_kernels()))"], capture_output=True, text=True,
                           env=env, timeout=120)
        assert r.returncode == 0 and r.stdout.strip() == "False", r.stderr


def test_warm_up_compiles_every_signature_a_transient_uses():
    # After warm_up (in the cache since `make`), transients of the bench (slide), the FEAD example
    # (arm with friction, many pulleys, running belt; with a spring span) and a backside idler with belt
    # damping add no signature to any
    # compiled kernel: a user's first run loads them, none is compiled on the way.
    from beltdyn.model import belt_kernel
    from beltdyn.analysis import integrator
    from beltdyn.model import spring_kernel
    from beltdyn.config import load_config
    from beltdyn.pipeline import analyse
    from beltdyn.analysis.transient import entry_kernels, run_transient
    from beltdyn.pipeline import warm_up

    warm_up()
    assert jitcache.is_warm(*entry_kernels())
    kernels = [o for m in (integrator, belt_kernel, spring_kernel) for o in vars(m).values()
               if hasattr(o, "signatures") and getattr(o, "__module__", "") == m.__name__]
    before = {k.__name__: len(k.signatures) for k in kernels}
    cases = [(ROOT / "configs/examples/bench_transient_small.toml", []),
             (ROOT / "configs/examples/fead_4cyl.toml", []),
             (ROOT / "configs/examples/three_pulley_tensioner.toml", ["transient.damping.belt_axial=1e-5"]),
             (ROOT / "configs/examples/fead_4cyl.toml", ['spans.ALT-TEN.model="spring"'])]
    for path, sets in cases:
        cfg = load_config(path, ["transient.duration=0.002", "transient.spectrum.enabled=false", *sets])
        run = analyse(cfg)
        run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)
    after = {k.__name__: len(k.signatures) for k in kernels}
    assert after == before


TRANSIENTS = [  # (example, overrides): every kind of drive the stepper knows
    ("bench_transient_small.toml", []),  # slide, band Cholesky
    ("fead_4cyl.toml", []),  # arm with friction, running belt: band LU without row exchanges
    ("three_pulley_tensioner.toml", ["transient.damping.belt_axial=1e-5"]),  # belt damping
    ("fead_4cyl.toml", ['spans.ALT-TEN.model="spring"']),  # a spring span
]
_RUN_ALL = ("from beltdyn.config import load_config; from beltdyn.pipeline import analyse; "
            "from beltdyn.analysis.transient import run_transient\n"
            "for name, sets in {cases!r}:\n"
            "    cfg = load_config({root!r} + '/configs/examples/' + name, ['transient.duration=0.002', "
            "'transient.spectrum.enabled=false', *sets]); run = analyse(cfg)\n"
            "    run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None)\n")


def _python(code: str, env: dict | None = None) -> list[str]:
    """The lines `code` prints, run by this Python in a fresh process (which must succeed)."""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout.splitlines()


def _cache_report(stdout: str) -> tuple[int, int]:
    """(kernels compiled and saved, kernels loaded) in numba's NUMBA_DEBUG_CACHE report."""
    lines = [ln for ln in stdout.splitlines() if ln.startswith("[cache]")]
    return sum("data saved to" in ln for ln in lines), sum("data loaded from" in ln for ln in lines)


def test_entry_kernels_are_the_kernels_transients_call_from_python():
    # In a fresh process with the cache warm, the compiled functions that transients of every kind of drive
    # dispatch (each loaded from the cache, none compiled: numba's own cache report; the kernels they call
    # run inside them and are never dispatched) are exactly `entry_kernels`, the list `is_warm` checks.
    from beltdyn.pipeline import warm_up

    warm_up()
    out = _python(_RUN_ALL.format(cases=TRANSIENTS, root=str(ROOT)) + textwrap.dedent("""
        from beltdyn.analysis import band_solve, integrator
        from beltdyn.model import belt_kernel
        from beltdyn.model import spring_kernel
        from beltdyn.analysis.transient import entry_kernels
        got = [o for m in (integrator, band_solve, belt_kernel, spring_kernel) for o in vars(m).values()
               if hasattr(o, "py_func") and o.py_func.__module__ == m.__name__ and o.signatures]
        print(sorted(k.__name__ for k in got))
        print(sorted(k.__name__ for k in entry_kernels()))
    """), env=dict(os.environ, NUMBA_DEBUG_CACHE="1"))
    dispatched, entries = [ln for ln in out if not ln.startswith("[cache]")]
    assert dispatched == entries
    saved, loaded = _cache_report("\n".join(out))
    assert saved == 0 and loaded >= 2


def _cli_env(cache: Path, **extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "COLUMNS")}
    env.update(NUMBA_CACHE_DIR=str(cache), NUMBA_DEBUG_CACHE="1", TTY_COMPATIBLE="1", **extra)  # rich: a terminal
    return env


@pytest.mark.slow  # three real compiles of the kernels (minutes of CPU each on numba 0.68): `make test-slow`
def test_a_cold_cache_announces_and_compiles_a_warm_one_does_not_an_edited_source_is_cold(tmp_path):
    # A copy of the package with an empty numba cache (NUMBA_CACHE_DIR): the first `beltdyn transient`
    # announces the compile and compiles (numba saves the kernels), the second neither announces nor
    # compiles (every kernel loaded). Then an edited kernel source (the stepper, or the spring kernel it
    # calls), another numba version or another cache folder reads cold; the unedited copy stays warm.
    src = tmp_path / "src"
    shutil.copytree(PACKAGE, src / "beltdyn", ignore=shutil.ignore_patterns("__pycache__"))
    cache = tmp_path / "cache"
    env = _cli_env(cache, PYTHONPATH=str(src))
    args = [sys.executable, "-c", "from beltdyn.cli import run; run()", "transient",
            str(ROOT / "configs/examples/bench_transient_small.toml"), "--duration", "0.002",
            "--set", "transient.spectrum.enabled=false", "-o", "t.h5", "--force"]
    announce = "compiling the transient kernels"
    cold = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=1800)
    assert cold.returncode == 0, cold.stderr
    assert announce in cold.stdout + cold.stderr and _cache_report(cold.stdout)[0] > 0
    assert list(cache.glob("beltdyn-kernels-*.stamp"))
    warm = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300)
    assert warm.returncode == 0, warm.stderr
    assert announce not in warm.stdout + warm.stderr
    saved, loaded = _cache_report(warm.stdout)
    assert saved == 0 and loaded > 0

    ask = ("from beltdyn import jitcache; from beltdyn.analysis.transient import entry_kernels; "
           "print(jitcache.is_warm(*entry_kernels()))")

    def warm_now(**extra) -> str:
        r = subprocess.run([sys.executable, "-c", ask], capture_output=True, text=True, timeout=120,
                           env={**env, "NUMBA_DEBUG_CACHE": "0", **extra})
        assert r.returncode == 0, r.stderr
        return r.stdout.strip()

    assert warm_now() == "True"
    assert warm_now(NUMBA_CACHE_DIR=str(tmp_path / "other")) == "False"
    numba_again = ("import numba; numba.__version__ = numba.__version__ + '.post1'; " + ask)
    r = subprocess.run([sys.executable, "-c", numba_again], capture_output=True, text=True, timeout=120, env=env)
    assert r.stdout.strip() == "False", r.stderr
    for name in ("analysis/integrator.py", "model/spring_kernel.py"):
        source = src / "beltdyn" / name
        text = source.read_text()
        source.write_text(text + "\n# edited\n")
        assert warm_now() == "False", name
        source.write_text(text)
        assert warm_now() == "True", name


def test_kernel_options_are_public_numba_options():
    # The kernels' njit options name only numba's public options (no leading underscore; issue 24), and
    # numba takes them: a function compiled with them runs.
    import numpy as np
    from numba import njit

    assert jitcache.kernel_options() == jitcache.KERNEL and jitcache.KERNEL["cache"] is True
    assert not [k for k in jitcache.KERNEL if k.startswith("_")]

    def add(a, b):
        a[0] += b[0]

    options = {k: v for k, v in jitcache.KERNEL.items() if k != "cache"}  # (not cached: no files)
    a = np.zeros(1)
    njit(**options)(add)(a, np.ones(1))
    assert a[0] == 1.0


@pytest.mark.parametrize("example, loaded", [
    ("bench_transient_small.toml", ["advance"]),  # band Cholesky (LAPACK): the stepper alone
    ("fead_4cyl.toml", ["advance", "band_lu_nopivot"]),  # the running belt's factor without row exchanges
])
def test_a_transient_enters_the_stepper_through_one_kernel(example, loaded):
    # In a fresh process a transient calls, of `integrator`'s compiled functions, only its entry point
    # `advance` (and the factorization it needs): every other kernel runs inside it, so one library is
    # loaded from numba's cache instead of one per kernel (each load parses its own copy of the
    # callees' code).
    code = ("from beltdyn.config import load_config; from beltdyn.pipeline import analyse; "
            "from beltdyn.analysis.transient import run_transient; from beltdyn.analysis import integrator as i; "
            f"cfg = load_config({str(ROOT / 'configs' / 'examples' / example)!r}, "
            "['transient.duration=0.002', 'transient.spectrum.enabled=false']); run = analyse(cfg); "
            "run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None); "
            "print(' '.join(sorted(k.__name__ for k in vars(i).values() if getattr(k, 'signatures', None))))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == loaded
