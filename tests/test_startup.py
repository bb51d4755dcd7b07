"""Start-up (issue 10, item 5): where numba's cache goes, whether it is warm, and that `warm_up` (what
`make` runs at install) compiles every signature a transient uses, so a user's first run loads
instead of compiling. Timings are in `make bench`, not here."""

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
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    assert jitcache.cache_dir(blocked / "__pycache__") == str(tmp_path / "cache" / "beltdyn" / "numba")
    assert (tmp_path / "cache" / "beltdyn" / "numba").is_dir()
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    got = jitcache.cache_dir(blocked / "__pycache__")
    assert got is not None and Path(got).parent == Path(__import__("tempfile").gettempdir())
    assert jitcache.cache_dir(tmp_path / "writable" / "__pycache__") is None  # numba's own in-tree cache
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
    want = str(tmp_path / "cache" / "beltdyn" / "numba")
    assert r.stdout.split() == [want, want]


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


def test_entry_kernels_are_the_kernels_transients_call_from_python():
    # In a fresh process with the cache warm, the compiled functions that transients of every kind of drive
    # dispatch (a cache hit each; the kernels they call run inside them and are never dispatched) are
    # exactly `entry_kernels`, the list `is_warm` checks.
    from beltdyn.pipeline import warm_up

    warm_up()
    dispatched, entries, all_hits = _python(_RUN_ALL.format(cases=TRANSIENTS, root=str(ROOT)) + textwrap.dedent("""
        from beltdyn import jitcache
        from beltdyn.analysis import integrator
        from beltdyn.model import belt_kernel
        from beltdyn.model import spring_kernel
        from beltdyn.analysis.transient import entry_kernels
        got = [k for m in (integrator, belt_kernel, spring_kernel) for k in jitcache._kernels(m) if k.signatures]
        print(sorted(k.__name__ for k in got))
        print(sorted(k.__name__ for k in entry_kernels()))
        print(all(k.stats.cache_hits and not k.stats.cache_misses for k in got))
    """))
    assert dispatched == entries and all_hits == "True"


def test_a_stale_helper_kernel_does_not_make_the_cache_cold(tmp_path):
    # A copy of the warm cache (NUMBA_CACHE_DIR) in which the index files of kernels that only run inside
    # the entry points (integrator.run_steps, belt_kernel.gather) are stale (written for another source, as
    # numba sees an index after an edit) or missing: `is_warm` says warm, and a transient indeed compiles
    # nothing (every dispatched kernel a cache hit). Checking every kernel of the modules, as before, said
    # cold: every run announced "compiling the transient kernels" and ran warm_up for nothing. A stale
    # `advance` or a missing `band_lu_nopivot` is cold.
    from beltdyn.pipeline import warm_up

    warm_up()
    code = textwrap.dedent(f"""
        import pickle, shutil
        from pathlib import Path
        from beltdyn import jitcache
        from beltdyn.analysis import integrator
        from beltdyn.model import belt_kernel
        from beltdyn.model import spring_kernel
        from beltdyn.analysis.transient import entry_kernels
        modules = (integrator, belt_kernel, spring_kernel)
        for m in modules:  # each module's kernels into the folder numba keeps for its source folder
            cache = Path(next(iter(jitcache._kernels(m)))._cache._cache_path)
            cache.mkdir(parents=True, exist_ok=True)
            for f in (Path(m.__file__).parent / "__pycache__").glob(Path(m.__file__).stem + ".*.nb[ic]"):
                shutil.copy(f, cache)

        def index(k):
            return Path(k._cache._cache_file._index_path)

        def stale(k):
            with open(index(k), "rb") as fh:
                version = pickle.load(fh)
            with open(index(k), "wb") as fh:
                pickle.dump(version, fh)
                fh.write(pickle.dumps(((0.0, 0), {{}})))

        def every_kernel():  # the old check
            return all(k._cache._cache_file._load_index() for m in modules for k in jitcache._kernels(m))

        print(jitcache.is_warm(*entry_kernels()), every_kernel())
        stale(integrator.run_steps)
        index(belt_kernel.gather).unlink()
        print(jitcache.is_warm(*entry_kernels()), every_kernel())
    """) + _RUN_ALL.format(cases=TRANSIENTS[:2], root=str(ROOT)) + textwrap.dedent("""
        got = [k for m in modules for k in jitcache._kernels(m) if k.signatures]
        print(all(k.stats.cache_hits and not k.stats.cache_misses for k in got))
        index(integrator.band_lu_nopivot).unlink()
        print(jitcache.is_warm(*entry_kernels()))
        stale(integrator.advance)
        print(jitcache.is_warm(integrator.advance))
    """)
    got = _python(code, env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba")))
    assert got == ["True True", "True False", "True", "False", "False"]


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


def test_cache_hits_skip_the_full_context_refresh():
    # A transient (FEAD: arms, running belt) in a fresh process with the kernels in the cache loads them
    # the lean way (jitcache.lean_loads): numba's lowering of things the kernels never use (typed dicts,
    # random generators, polynomials), which its full context refresh imports, stays unimported; the
    # results are those of the other tests (same kernels, same code).
    from beltdyn.pipeline import warm_up

    # Nor does it import numba's array modules (the kernels allocate nothing, so no function environment
    # names them) or start numba's runtime (NRT: kernels compiled with jitcache.KERNEL never call it).
    warm_up()  # (the cache warm, as after `make`)
    unused = ["numba.typed.typeddict", "numba.np.random.generator_methods", "numba.np.polynomial.polynomial_functions",
              "numba.np.arrayobj", "numba.np.arraymath"]
    code = ("import sys; from beltdyn.config import load_config; from beltdyn.pipeline import analyse; "
            "from beltdyn.analysis.transient import run_transient; from numba.core.runtime import rtsys; "
            f"cfg = load_config({str(ROOT / 'configs' / 'examples' / 'fead_4cyl.toml')!r}, "
            "['transient.duration=0.002', 'transient.spectrum.enabled=false']); run = analyse(cfg); "
            "s = run_transient(run.system, run.static, cfg.transient, sink=lambda t, b: None); "
            f"print(s.status, [m for m in {unused!r} if m in sys.modules], rtsys._init)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "complete [] False"


def test_runtime_use_is_told_from_the_object_code():
    # jitcache._uses_runtime reads a cached overload's object code: a function that allocates calls numba's
    # runtime (its object code names NRT_ symbols), one compiled with jitcache.KERNEL's options does not.
    import numpy as np
    from numba import njit

    def zeros(n):
        return np.zeros(n)

    def add(a, b):
        a[0] += b[0]

    options = {k: v for k, v in jitcache.KERNEL.items() if k != "cache"}  # (not cached: no files)
    allocating, plain = njit(zeros), njit(**options)(add)
    allocating(3)
    plain(np.zeros(1), np.ones(1))
    for f, uses in ((allocating, True), (plain, False)):
        lib = f.overloads[f.signatures[0]].library
        obj = lib._codegen._tm.emit_object(lib._final_module)  # its machine code, as the cache holds it
        assert jitcache._uses_runtime(((lib.name, "object", (obj, b"")),)) is uses
    assert jitcache._uses_runtime(((lib.name, "bitcode", b""),)) is True  # no object code: assume it does


def test_command_line_values_are_read_without_pydantic():
    # typer coerces every value through a pydantic adapter (~70 ms to import and build); beltdyn's
    # plain parameters are read by `cliparams` instead: parsing `beltdyn transient` with every kind of
    # value (path argument and option, list of --set, floats with a bound, flags) imports no pydantic.
    code = ("import sys; from beltdyn import cli; got = {}; "
            "cli._run = lambda body: got.update(body.__code__.co_freevars and "
            "{n: c.cell_contents for n, c in zip(body.__code__.co_freevars, body.__closure__)}); "
            "sys.argv = ['beltdyn', 'transient', 'x.toml', '--set', 'a=1', '--set', 'b=2', '--duration', '0.5', "
            "'--step', '1e-4', '-o', 'o.h5', '--force']; "
            "exec('try:\\n cli.app()\\nexcept SystemExit:\\n pass'); "
            "print('pydantic' in sys.modules, got['config'], got['output'], got['set_'], got['duration'], got['step'], "
            "got['force'], got['fmax'])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["False", "x.toml", "o.h5", "['a=1',", "'b=2']", "0.5", "0.0001", "True", "None"]


@pytest.mark.parametrize("annotation, minimum, text", [
    (float, 0.0, "1e-4"), (float, 0.0, "2"), (float, 0.0, ".5"), (float, 0.0, "abc"), (float, 0.0, "-1"),
    (float, 0.0, "1e999"), (float, 0.0, "nan"), (float, 0.0, " 2"), (float, 0.0, "1_0"), (float, None, "-3.5"),
    (int, 1, "4"), (int, 1, "0"), (int, 1, "2.0"), (int, 1, "x"), (str, None, "a=b"), (Path, None, "out.h5"),
])
def test_command_line_values_read_as_typer_reads_them(annotation, minimum, text):
    # The same value or the same refusal (typer's message) as typer's own pydantic coercion, for
    # well-formed and malformed numbers, bounds, strings and paths.
    import typer
    from typer._click.exceptions import BadParameter
    from typer._coercion import build_runtime_param, resolve_type_descriptor
    from typer.core import TyperOption

    from beltdyn import cli  # noqa: F401 - installs cliparams

    info = typer.models.OptionInfo(min=minimum)
    desc = resolve_type_descriptor(annotation, info)
    opt = TyperOption(param_decls=["--x"], type_descriptor=desc)

    def outcome(runtime):
        try:
            return ("ok", runtime.coerce(text, param=opt, ctx=None))
        except BadParameter as exc:
            return ("refused", exc.format_message())

    assert type(opt.get_runtime_param()).__name__ == "Plain"  # beltdyn's coercion is the one in use
    assert outcome(opt.get_runtime_param()) == outcome(build_runtime_param(desc))


def test_kernel_options_drop_a_private_option_the_installed_numba_does_not_know(monkeypatch):
    # `_nrt` (no runtime in the kernels) is a private numba option that numba checks only at a kernel's
    # first compile; a numba without it must get the kernels' options without it (they then compile with
    # the runtime) rather than refuse every kernel. Reference: numba's own option table.
    from numba.core.cpu import CPUTargetOptions

    from beltdyn import jitcache

    assert jitcache.kernel_options() == jitcache.KERNEL  # this numba knows it
    monkeypatch.setattr(CPUTargetOptions, "_nrt", None)  # (inherited: shadowed, as if gone)
    assert jitcache.kernel_options() == {k: v for k, v in jitcache.KERNEL.items() if k != "_nrt"}
