"""The package's shape (docs/architecture.md): its import graph has no circle, and the layers import
one way, top to bottom.

Every import statement of every module counts, at module level or inside a function, except those
under `if TYPE_CHECKING:` (annotations only, never run).

No private API of a dependency: no module imports a name or module whose dotted path has a private part
(`_x`, not a dunder) from another package, or reads an attribute `_x` of an imported third-party module
(`atexit._run_exitfuncs`, `numba._x`).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "beltdyn"

# The layers, bottom to top: a module may import its own layer and the ones below, never one above.
LAYERS = (
    ("beltdyn", "beltdyn.errors", "beltdyn.jitcache", "beltdyn.cleanup"),
    ("beltdyn.config",),
    ("beltdyn.model",),
    ("beltdyn.analysis",),
    ("beltdyn.results",),
    ("beltdyn.pipeline", "beltdyn.workflow"),
    ("beltdyn.study",),
)


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports_of(path: Path, name: str) -> list[tuple[str, int]]:
    """(imported module or name's dotted path, line) of every import in the module at `path`."""
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            node.body = []
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out += [(f"{mod}.{a.name}", node.lineno) for a in node.names]
    return out


def internal_graph() -> dict[str, set[str]]:
    """module -> the beltdyn modules it imports (a `from package import module` counts as the module)."""
    mods = modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for m, path in mods.items():
        for target, _ in imports_of(path, m):
            while target and target not in mods:
                target = target.rpartition(".")[0]
            if target and target != m and target.startswith("beltdyn"):
                graph[m].add(target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def layer_of(module: str) -> int | None:
    best = None
    for k, prefixes in enumerate(LAYERS):
        for p in prefixes:
            if module == p or (p != "beltdyn" and module.startswith(p + ".")):
                best = k
    return best


def test_cycle_finder_finds_a_circle():
    # the check itself can fail: a -> b -> c -> a is a circle, d -> a is not part of it
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_the_package_import_graph_has_no_circle():
    assert cycles(internal_graph()) == []


def test_layers_import_downward_only():
    upward = []
    for m, targets in internal_graph().items():
        lm = layer_of(m)
        if lm is None:
            continue  # the top: the CLI, figures, report
        for t in targets:
            lt = layer_of(t)
            if lt is None or lt > lm:
                upward.append(f"{m} -> {t}")
    assert upward == []


@pytest.mark.parametrize("module", ["beltdyn.model.system", "beltdyn.analysis.static", "beltdyn.results.io"])
def test_every_layer_module_is_placed(module):
    assert layer_of(module) is not None


# underscored names their library documents as public: os._exit ("the standard way to exit in a child
# process after a fork", Python's os documentation)
DOCUMENTED_PUBLIC = frozenset({"os._exit"})


ATTRIBUTE_BUILTINS = ("getattr", "setattr", "hasattr", "delattr")


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_uses(source: str, package: str = "beltdyn") -> list[str]:
    """What `source` (a module of `package`) uses of another package's private API: "line: dotted path"
    for every import (any statement, at module level or in a function) whose dotted path has a private
    part, and for every attribute `_x` read from a name bound to an imported third-party module (or
    from a dotted chain of such modules, `numba.core._x`). Relative imports and `package` itself are its own."""
    tree = ast.parse(source)
    found = []
    modules: dict[str, str] = {}  # local name -> the third-party module it is bound to
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == package:
                    continue
                if any(_private(p) for p in a.name.split(".")):
                    found.append(f"{node.lineno}: import {a.name}")
                modules[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            if node.level or (node.module or "").split(".")[0] == package:
                continue
            for a in node.names:
                path = f"{node.module}.{a.name}"
                if any(_private(p) for p in path.split(".")):
                    found.append(f"{node.lineno}: from {node.module} import {a.name}")
                else:
                    modules[a.asname or a.name] = path  # (a module or a name: its private attributes count too)
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ATTRIBUTE_BUILTINS \
                and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) \
                and isinstance(node.args[1].value, str) and _private(node.args[1].value):
            found.append(f"{node.lineno}: {ast.unparse(node)}")  # a private attribute by name, of anything
        if isinstance(node, ast.Attribute) and _private(node.attr):
            base = node.value
            while isinstance(base, ast.Attribute):
                base = base.value
            if isinstance(base, ast.Name) and base.id in modules and ast.unparse(node) not in DOCUMENTED_PUBLIC:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return sorted(set(found), key=lambda s: int(s.split(":")[0]))


def test_private_api_checker_finds_each_kind():
    # the check itself can fail: each kind of private use in a snippet is found, public uses are not
    snippet = """
import atexit
import numba
import numba.core._internal
from typer._coercion import build_runtime_param
from numba.core import _nrt_python as nrt
from beltdyn.results import files
from beltdyn._private import fine
from . import _local

def f(executor):
    from typer import _click
    atexit._run_exitfuncs()
    numba.core._x = 1
    files._release(1, 2)
    executor._processes
    numba.__version__
    atexit.register(f)
    os._exit(0)
    getattr(executor, "_processes", None)
    getattr(executor, "__name__")
"""
    assert private_uses(snippet) == [
        "4: import numba.core._internal", "5: from typer._coercion import build_runtime_param",
        "6: from numba.core import _nrt_python", "12: from typer import _click", "13: atexit._run_exitfuncs",
        "14: numba.core._x", "20: getattr(executor, '_processes', None)"]
    assert private_uses("import os\nos._exit(1)\n") == []  # documented public
    assert private_uses("import os\nos.path.join('a')\nfrom typer import Typer\n") == []


def test_no_module_uses_a_private_api_of_a_dependency():
    found = {m: uses for m, path in modules().items() if (uses := private_uses(path.read_text()))}
    assert found == {}
