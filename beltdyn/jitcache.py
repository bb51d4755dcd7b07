"""Where numba caches the compiled kernels, and whether they are cached already (issues 10 and 24).

numba caches each ``@njit(**KERNEL)`` function (cache=True) and invalidates a cached compile when the
function's own source file changes, not when a kernel it calls (and inlines) from another file does:
an edited bar law (`model/barlaw.py`) would leave the stepper's cached compile of the old law in use.
So beltdyn keys the cache folder by the sources of every module that defines a kernel
(`KERNEL_SOURCES`, `source_key`): `configure` sets NUMBA_CACHE_DIR (numba's public setting), before
numba compiles anything, to ``<base>/<source key>``, the base being the package's own
``beltdyn/__pycache__/numba`` when writable, else ``$XDG_CACHE_HOME/beltdyn/numba``
(``~/.cache/beltdyn/numba``: a read-only installation, a container image), else a folder in the
temporary directory. An edited kernel source is a new folder, hence a fresh compile; `mark_warm` removes
the package's folders of other keys (in the package's own cache only: a user cache may serve other
installations). A user's NUMBA_CACHE_DIR is left as it is (then keeping it fresh is the user's
business). Call it before ``import numba`` (`belt_kernel` and `integrator` do); numba reads the
variable when it is first imported, so a numba imported earlier gets its ``config.CACHE_DIR`` set too.

`is_warm` tells whether the kernels a run calls from Python (its entry points, `transient.entry_kernels`)
were compiled into the cache for their current sources, so the CLI can say "compiling ..., once" only
when it compiles. numba's cache files are its own business (their layout is no public API), so beltdyn
keeps its own record: `mark_warm`, called by `pipeline.warm_up` once the kernels are compiled and cached,
writes a stamp file into the cache folder (`stamp_folder`) whose name holds `kernel_key`, a hash of
the kernels' module sources (with the modules whose kernels they call and this module, which holds
their options), of the numba, llvmlite and Python versions and of the machine. An edited source,
another numba or another Python is a new key, hence cold until the next `warm_up`. A cache emptied
by hand with the stamp left in place reads warm: the run then compiles unannounced (correct results,
a slower first run); a cache filled by a run outside `warm_up` reads cold: the CLI then runs `warm_up`,
which loads the kernels from numba's cache and writes the stamp.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shutil
import sys
import tempfile
import types
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
_CHOSEN: list[str | None] = []  # configure's answer, once per process
# The njit options of beltdyn's kernels (`@njit(**KERNEL)`): cached (numba's public options only; the
# kernels compile with numba's defaults otherwise, its runtime included).
KERNEL: dict = {"cache": True}


def kernel_options() -> dict:
    """The njit options of beltdyn's kernels (a copy of `KERNEL`), for the modules that define kernels."""
    return dict(KERNEL)


def _writable(folder: Path) -> bool:
    """True if files can be created in `folder` (made if missing), tried as numba tries it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def user_cache_dir() -> Path:
    """$XDG_CACHE_HOME/beltdyn/numba, or ~/.cache/beltdyn/numba."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "beltdyn" / "numba"


# Every module that defines a kernel (`@njit(**KERNEL)`), relative to the package (a test holds the list
# to the package's sources): their text keys the cache folder (`source_key`).
KERNEL_SOURCES = ("model/barlaw.py", "model/belt_kernel.py", "model/spring_kernel.py", "analysis/integrator.py",
                  "analysis/forcing_laws.py", "analysis/friction_kernel.py", "analysis/band_solve.py")


def source_key(package: Path = PACKAGE) -> str:
    """A hash of the sources of every module that defines a kernel (`KERNEL_SOURCES`; hexadecimal, 16 digits)."""
    h = hashlib.sha256()
    for name in KERNEL_SOURCES:
        h.update(name.encode() + b"\0" + (package / name).read_bytes() + b"\0")
    return h.hexdigest()[:16]


def cache_dir(in_tree: Path = PACKAGE / "__pycache__") -> str | None:
    """The folder to set as NUMBA_CACHE_DIR (``<base>/<source_key>``, the base `in_tree`/numba when
    writable, else the user cache folder, else the temporary folder's), or None for a user's
    NUMBA_CACHE_DIR (or nowhere to write)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    key = source_key()
    uid = os.getuid() if hasattr(os, "getuid") else 0
    for base in (in_tree / "numba", user_cache_dir(), Path(tempfile.gettempdir()) / f"beltdyn-numba-{uid}"):
        if _writable(base / key):
            return str(base / key)
    return None  # nowhere to write: numba compiles in memory each time (its caching then warns)


def configure() -> str | None:
    """Set NUMBA_CACHE_DIR if the package folder cannot hold the cache (see the module docstring);
    returns the folder set, or None. Cheap after the first call."""
    if not _CHOSEN:
        folder = cache_dir()
        if folder is not None:
            os.environ["NUMBA_CACHE_DIR"] = folder
            config = sys.modules.get("numba.core.config")
            if config is not None:  # numba already imported: it read the environment before
                config.CACHE_DIR = folder
        _CHOSEN.append(folder)
    return _CHOSEN[0]


def stamp_folder() -> Path:
    """The folder of numba's cache as configured: NUMBA_CACHE_DIR when set (by the user or `configure`),
    else the package's own ``__pycache__`` (nowhere writable: numba compiles in memory)."""
    configure()
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    return Path(chosen) if chosen else PACKAGE / "__pycache__"


def _source_files(kernels) -> list[Path]:
    """The source files whose text the compiled `kernels` depend on: each kernel's module, the modules of
    the kernels (and the beltdyn modules) those modules name at their top level, and this module."""
    files = {Path(__file__).resolve()}
    for kernel in kernels:
        module = sys.modules[kernel.py_func.__module__]
        for obj in (module, *vars(module).values()):
            if hasattr(obj, "py_func"):  # a compiled function: its module's source
                obj = sys.modules.get(obj.py_func.__module__)
            if isinstance(obj, types.ModuleType) and obj.__name__.split(".")[0] == "beltdyn" and getattr(
                    obj, "__file__", None):
                files.add(Path(obj.__file__).resolve())
    return sorted(files)


def kernel_key(*kernels) -> str:
    """A hash of what a cached compile of `kernels` depends on: their sources (`_source_files`), the numba,
    llvmlite and Python versions and the machine (hexadecimal, 24 digits)."""
    import llvmlite
    import numba

    h = hashlib.sha256()
    for part in (numba.__version__, llvmlite.__version__, sys.version, platform.machine(), repr(KERNEL)):
        h.update(part.encode() + b"\0")
    for path in _source_files(kernels):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:24]


def stamp_path(*kernels) -> Path:
    """The stamp file `mark_warm` writes for `kernels` (in `stamp_folder`)."""
    return stamp_folder() / f"beltdyn-kernels-{kernel_key(*kernels)}.stamp"


def is_warm(*kernels) -> bool:
    """True if `mark_warm` recorded `kernels` as compiled into the cache for their current sources, numba
    and Python (module docstring)."""
    return stamp_path(*kernels).is_file()


def mark_warm(*kernels) -> bool:
    """Record that `kernels` are compiled into numba's cache (call after compiling them, as `warm_up`
    does). Returns False when the cache folder cannot be written (numba then compiles in memory each
    run, and `is_warm` rightly stays False)."""
    path = stamp_path(*kernels)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as fh:
            fh.write("numba cache of beltdyn's kernels, written by beltdyn.pipeline.warm_up\n")
        os.replace(fh.name, path)
    except OSError:
        return False
    own = PACKAGE / "__pycache__" / "numba"
    if path.parent.parent == own:  # the package's own cache: the compiles of its earlier sources go
        for other in own.iterdir():
            if other.is_dir() and other != path.parent:
                shutil.rmtree(other, ignore_errors=True)
    return True
