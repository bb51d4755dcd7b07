"""The package's shape (docs/architecture.md): its import graph has no circle, and the layers import
one way, top to bottom.

Every import statement of every module counts, at module level or inside a function, except those
under `if TYPE_CHECKING:` (annotations only, never run).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "beltdyn"

# The layers, bottom to top: a module may import its own layer and the ones below, never one above.
LAYERS = (
    ("beltdyn", "beltdyn.errors", "beltdyn.jitcache"),
    ("beltdyn.config",),
    ("beltdyn.model",),
    ("beltdyn.analysis",),
    ("beltdyn.results",),
    ("beltdyn.pipeline",),
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
