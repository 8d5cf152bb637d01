"""The package's import graph: no cycles, no import against the layers of
``tapm_opt._layers.LAYERS``, no private name imported from another package.

Every module under ``tapm_opt/`` is parsed with ``ast`` (nothing is imported), and every import
counts: at module level, inside functions (a lazy import is still a dependency) and under
``if TYPE_CHECKING:`` (a type is a dependency too). Relative imports are resolved to module
names; ``from package import name`` is an edge to the submodule when ``name`` is one, else to the
package's ``__init__``. A package's ``__init__`` importing its own submodules is an ordinary edge
down; it makes a cycle only when a submodule imports the ``__init__`` back (``from . import X``
with X defined there), which is then reported like any other.
"""

from __future__ import annotations

import ast
import pathlib
from dataclasses import dataclass

from tapm_opt._layers import LAYERS, layer_of, may_import

ROOT = pathlib.Path(__file__).resolve().parents[1] / "tapm_opt"

# Edges that break a rule only because of code in modules owned elsewhere, each with the edit that
# removes it. The test fails when an entry is no longer needed, so the lists only shrink.
#: (importer, imported) -> why the upward import is still there. An allowed edge is also left out
#: of the cycle search (it closes a cycle with the import it points back along).
ALLOWED_UPWARD: dict[tuple[str, str], str] = {
}
#: (importer, defining module, name) -> why the private name is still imported.
ALLOWED_PRIVATE: dict[tuple[str, str, str], str] = {
}


@dataclass(frozen=True)
class Edge:
    src: str      # importing module
    dst: str      # imported module (a package name: its __init__)
    line: int
    names: tuple[str, ...] = ()   # names taken from dst by ``from dst import ...``

    def __str__(self) -> str:
        what = f" ({', '.join(self.names)})" if self.names else ""
        return f"{self.src}:{self.line} -> {self.dst}{what}"


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for p in sorted(ROOT.rglob("*.py")):
        if "__pycache__" in p.parts:
            continue
        parts = list(p.relative_to(ROOT.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = p
    return out


MODULES = _modules()


def _is_package(module: str) -> bool:
    return MODULES[module].name == "__init__.py"


def _package_of(module: str) -> str:
    """The package a module's relative imports and private names belong to."""
    return module if _is_package(module) else module.rpartition(".")[0]


def _resolve_from(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = _package_of(module).split(".")
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _parse(module: str) -> ast.Module:
    path = MODULES[module]
    return ast.parse(path.read_text(encoding="utf-8"), str(path))


def _edges_and_aliases(module: str) -> tuple[list[Edge], list[tuple[str, str, str, int]]]:
    """The module's import edges into tapm_opt, and its private attribute uses on imported
    modules: ``(defining module, name, alias, line)`` for ``alias._x`` with ``alias`` bound to a
    tapm_opt module by an import."""
    tree = _parse(module)
    edges: list[Edge] = []
    aliases: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == "tapm_opt" or a.name.startswith("tapm_opt."):
                    edges.append(Edge(module, a.name, node.lineno))
                    if a.asname:
                        aliases[a.asname] = a.name
        elif isinstance(node, ast.ImportFrom):
            target = _resolve_from(module, node)
            if not (target == "tapm_opt" or target.startswith("tapm_opt.")):
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in MODULES:
                    edges.append(Edge(module, sub, node.lineno))
                    aliases[a.asname or a.name] = sub
                else:
                    edges.append(Edge(module, target, node.lineno, (a.name,)))
    private_attrs = []
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases
                and _private(node.attr)):
            private_attrs.append((aliases[node.value.id], node.attr, node.value.id, node.lineno))
    return edges, private_attrs


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


GRAPH = {m: _edges_and_aliases(m) for m in MODULES}
EDGES = [e for m in MODULES for e in GRAPH[m][0]]


def _strongly_connected(nodes: list[str], succ: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for root in nodes:
        if root in index:
            continue
        work = [(root, iter(sorted(succ.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(succ.get(w, ())))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    out.append(sorted(comp))
    return out


def _upward_edges() -> list[Edge]:
    bad = []
    for e in EDGES:
        a, b = layer_of(e.src), layer_of(e.dst)
        if a is not None and b is not None and not may_import(a, b):
            bad.append(e)
    return bad


def _private_imports() -> list[tuple[str, str, str, str]]:
    """``(importer, defining module, name, where)`` of every private name (or private module)
    used outside the package it belongs to."""
    out = []

    def outside(importer: str, scope: str) -> bool:
        return not (importer == scope or importer.startswith(scope + "."))

    for m in MODULES:
        edges, attrs = GRAPH[m]
        for e in edges:
            for name in e.names:
                if _private(name) and outside(m, _package_of(e.dst)):
                    out.append((m, e.dst, name, f"{m}:{e.line} from {e.dst} import {name}"))
            last = e.dst.rpartition(".")[2]
            if _private(last) and outside(m, e.dst.rpartition(".")[0]):
                out.append((m, e.dst, "", f"{m}:{e.line} imports the private module {e.dst}"))
        for dst, name, alias, line in attrs:
            if outside(m, _package_of(dst)):
                out.append((m, dst, name, f"{m}:{line} uses {alias}.{name} ({dst})"))
    return out


# --- the rules ----------------------------------------------------------------------------------

def test_every_module_has_a_layer():
    names = [name for name, _, _ in LAYERS]
    assert len(set(names)) == len(names), f"duplicate layer names in LAYERS: {names}"
    for _, _, deps in LAYERS:
        assert set(deps) <= set(names), f"LAYERS builds on unknown layers {sorted(set(deps) - set(names))}"
    missing = sorted(m for m in MODULES if layer_of(m) is None
                     or (_is_package(m) and m != "tapm_opt" and layer_of(m) == "base"))
    assert not missing, ("modules in no layer of tapm_opt._layers.LAYERS (add them to the layer they "
                         f"belong to): {missing}")


def test_no_import_cycles():
    succ: dict[str, set[str]] = {}
    by_pair: dict[tuple[str, str], list[Edge]] = {}
    for e in EDGES:
        if e.src != e.dst and (e.src, e.dst) not in ALLOWED_UPWARD:
            succ.setdefault(e.src, set()).add(e.dst)
            by_pair.setdefault((e.src, e.dst), []).append(e)
    cycles = [c for c in _strongly_connected(sorted(MODULES), succ) if len(c) > 1]
    lines = []
    for comp in cycles:
        members = set(comp)
        lines.append(f"cycle among {comp}:")
        for (a, b), es in sorted(by_pair.items()):
            if a in members and b in members:
                lines += [f"    {e}" for e in es]
    assert not cycles, "import cycles (each module must import only modules that do not import it back):\n" + \
        "\n".join(lines)


def test_no_upward_imports():
    bad = [e for e in _upward_edges() if (e.src, e.dst) not in ALLOWED_UPWARD]
    msg = "\n".join(f"    {e}    [{layer_of(e.src)} may not import {layer_of(e.dst)}]" for e in bad)
    assert not bad, ("imports against the layers of tapm_opt._layers.LAYERS (move the shared code down a "
                     "layer, or compute it above and pass it in):\n" + msg)


def test_no_private_names_across_packages():
    bad = [where for m, dst, name, where in _private_imports() if (m, dst, name) not in ALLOWED_PRIVATE]
    assert not bad, ("private names used outside their package (give them a public name in a module both "
                     "may import):\n" + "\n".join(f"    {w}" for w in bad))


def test_the_allow_lists_hold_only_edges_that_still_exist():
    upward = {(e.src, e.dst) for e in _upward_edges()}
    private = {(m, dst, name) for m, dst, name, _ in _private_imports()}
    stale = [k for k in ALLOWED_UPWARD if k not in upward] + [k for k in ALLOWED_PRIVATE if k not in private]
    assert not stale, f"allow-list entries no longer needed (delete them): {stale}"


# --- the checker itself -----------------------------------------------------------------------

def test_the_graph_reads_relative_lazy_and_type_checking_imports():
    """The parser sees what the rules rely on (guards against a checker that finds nothing)."""
    assert len(MODULES) > 100 and len(EDGES) > 500
    pairs = {(e.src, e.dst) for e in EDGES}
    # ``from .. import _backend as bk`` in a subpackage: the submodule, resolved two levels up
    assert ("tapm_opt.models.vessel", "tapm_opt._backend") in pairs
    # a lazy import inside a function
    lazy = [e for e in EDGES if e.src == "tapm_opt.models.mooring" and e.dst == "tapm_opt.models.characteristics"]
    assert lazy and lazy[0].line > 200
    # ``from tapm_opt import __version__``: an edge to the package's __init__
    assert any(e.dst == "tapm_opt" and "__version__" in e.names for e in EDGES)


def test_the_cycle_finder_and_the_layers_on_small_cases():
    comps = _strongly_connected(["a", "b", "c", "d"], {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}})
    assert sorted(map(tuple, comps)) == [("a", "b", "c"), ("d",)]
    assert layer_of("tapm_opt") == "package" and layer_of("tapm_opt.cli._common") == "cli"
    assert layer_of("tapm_opt.errors") == "base" and layer_of("tapm_opt.nowhere.x") is None
    assert may_import("design", "models") and may_import("control", "estimation")
    assert not may_import("control", "design") and not may_import("estimation", "control")
    assert not may_import("control", "plant") and not may_import("plant", "estimation")
