"""Where numba caches the compiled kernels, and whether they are cached already (issue 10, item 5).

numba caches each ``@njit(**KERNEL)`` function (cache=True) next to its source (``beltdyn/__pycache__``). In a
read-only installation (a system site-packages, a container image) numba falls back to its own user
cache folder, and fails at import when that is not writable either. `configure` decides before
numba compiles anything: the package folder when writable, else ``$XDG_CACHE_HOME/beltdyn/numba``
(``~/.cache/beltdyn/numba``), else a folder in the temporary directory, set as NUMBA_CACHE_DIR. A
user's NUMBA_CACHE_DIR is left as it is. Call it before ``import numba`` (`belt_kernel` and
`integrator` do); numba reads the variable when it is first imported, so a numba imported earlier
gets its ``config.CACHE_DIR`` set too.

`is_warm` tells whether the kernels a run calls from Python (its entry points, `transient.entry_kernels`)
are in the cache for this source, so the CLI can say "compiling ..., once" only when it compiles. Only
those: a kernel called inside another is compiled into its caller's library, so a cache hit of the
caller never loads (nor compiles) it, and its own cache entry, stale or missing, does not matter.

`lean_loads` makes loading a kernel from the cache initialize only what cached machine code needs.
Before its first load numba refreshes its whole target context, importing and registering every
lowering it knows (strings, lists, sets, dicts, random generators, polynomials, jitclasses, ...):
~120 ms of a short `beltdyn transient`, spent on a code generator that a cache hit does not run. A
cached library needs the modules its environments name, which unpickling imports itself, and numba's
runtime (NRT, `rtsys.initialize`, which compiles the runtime's functions: ~20 ms) when its machine code
calls it: the object code then names NRT_/nrt_ symbols (undefined ones), a kernel compiled with
`KERNEL` (no runtime) names none and loads without it. A compile still refreshes in full (numba's
compiler does so before every compile), and a load that fails the lean way is retried numba's way.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
_CHOSEN: list[str | None] = []  # configure's answer, once per process
# The njit options of beltdyn's kernels (`@njit(**KERNEL)`): cached, and without numba's runtime (NRT): the
# kernels allocate nothing (their callers hand in the scratch), so their code keeps no reference counts
# of the arrays and views it handles (a transient step ~11 % faster); a kernel that allocated would not
# compile.
KERNEL = {"cache": True, "_nrt": False}


def kernel_options() -> dict:
    """`KERNEL` as the installed numba takes it (for the modules that define kernels; they import numba
    anyway). `_nrt` is a private option, checked at the first compile, not at decoration: a numba that
    no longer knows it would refuse every kernel on first use, so without it the kernels compile with
    the runtime (the same results, ~11 % slower steps)."""
    try:
        from numba.core.cpu import CPUTargetOptions

        known = isinstance(getattr(CPUTargetOptions, "_nrt", None), CPUTargetOptions.Mapping)
    except (ImportError, AttributeError):
        known = False
    return dict(KERNEL) if known else {k: v for k, v in KERNEL.items() if k != "_nrt"}


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


def cache_dir(in_tree: Path = PACKAGE / "__pycache__") -> str | None:
    """The folder to set as NUMBA_CACHE_DIR, or None when numba's own choice is right (a user's
    NUMBA_CACHE_DIR, or the writable `in_tree` folder next to the sources)."""
    if os.environ.get("NUMBA_CACHE_DIR") or _writable(in_tree):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    for folder in (user_cache_dir(), Path(tempfile.gettempdir()) / f"beltdyn-numba-{uid}"):
        if _writable(folder):
            return str(folder)
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


def _kernels(module):
    """The cached numba functions of `module` that are compiled on their own (not inlined)."""
    for obj in vars(module).values():
        if (hasattr(obj, "py_func") and getattr(obj, "_cache", None) is not None
                and getattr(obj, "__module__", "") == module.__name__
                and obj.targetoptions.get("inline") != "always"):  # (an inlined one lives in its callers)
            yield obj


def is_warm(*kernels) -> bool | None:
    """True if each of the cached numba functions `kernels` has an entry in the cache for its current
    source (numba's index file, stamped with the source's hash), False if one has none, None if this
    cannot be told (numba's internals differ)."""
    try:
        return all(k._cache._cache_file._load_index() for k in kernels)
    except Exception:  # noqa: BLE001 - private numba API: unknown is not an error
        return None


def _uses_runtime(data) -> bool:
    """Whether a cached overload's machine code calls numba's runtime (NRT): its object code names an NRT_
    or nrt_ symbol (every runtime symbol is so named; an undefined one is named in the object's string
    table). True when this cannot be told."""
    try:
        _name, kind, (object_code, _bitcode) = data[0]  # CompileResult._reduce: the library's serialization
        return kind != "object" or b"NRT_" in object_code or b"nrt_" in object_code
    except Exception:  # noqa: BLE001 - private numba API: assume it does
        return True


def _lean_load_overload(cache, sig, target_context):
    """numba's `Cache.load_overload` with the runtime initialized (when the machine code calls it)
    instead of the whole target context refreshed (see the module docstring); numba's own on any
    failure."""
    try:
        with cache._guard_against_spurious_io_errors():
            if not cache._enabled:
                return None
            data = cache._cache_file.load(cache._index_key(sig, target_context.codegen()))  # (as _load_overload)
            if data is None:
                return None
            if _uses_runtime(data):
                from numba.core.runtime import rtsys

                rtsys.initialize(target_context)
            return cache._impl.rebuild(target_context, data)
    except Exception:  # noqa: BLE001 - private numba API: numba's own way then
        return type(cache).load_overload(cache, sig, target_context)


def lean_loads(module) -> None:
    """Load `module`'s cached kernels the lean way (module docstring). Call at the end of the module,
    once its kernels exist; nothing changes where numba's internals differ."""
    import types

    for k in _kernels(module):
        cache = k._cache
        if all(hasattr(cache, a) for a in ("_guard_against_spurious_io_errors", "_cache_file", "_index_key", "_impl",
                                           "_enabled")):
            cache.load_overload = types.MethodType(_lean_load_overload, cache)
