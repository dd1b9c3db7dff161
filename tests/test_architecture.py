"""The import structure: dependencies point one way, test oracles stay out of the pipeline."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sphri"


def _unit(path: Path) -> str:
    """The package (``sphri/<name>/``) or top-level module (``sphri/<name>.py``) a file belongs to."""
    rel = path.relative_to(PACKAGE)
    return rel.parts[0].removesuffix(".py")


def _runtime_imports(tree: ast.AST):
    """Modules imported by ``tree``, at module level or inside functions, but not under ``if TYPE_CHECKING``
    or ``if __name__ == "__main__"``."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        test = ast.unparse(node.test) if isinstance(node, ast.If) else ""
        if "TYPE_CHECKING" in test or "__name__ == '__main__'" in test:  # typing only; a module's command-line wiring
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield node.module
            yield from (f"{node.module}.{a.name}" for a in node.names)


def dependency_graph() -> dict[str, set[str]]:
    """unit -> units of sphri it imports at run time (itself excluded)."""
    graph: dict[str, set[str]] = defaultdict(set)
    units = {_unit(p) for p in PACKAGE.rglob("*.py")}
    for path in PACKAGE.rglob("*.py"):
        src = _unit(path)
        for module in _runtime_imports(ast.parse(path.read_text(), str(path))):
            parts = module.split(".")
            if parts[0] == "sphri" and len(parts) > 1 and parts[1] in units and parts[1] != src:
                graph[src].add(parts[1])
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one unit (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles_between_packages():
    graph = dependency_graph()
    found = cycles(graph)
    detail = "; ".join(" <-> ".join(c) + " (" + ", ".join(f"{a}->{b}" for a in c for b in sorted(graph[a] & set(c))) + ")"
                       for c in found)
    assert not found, f"import cycles between sphri packages: {detail}"


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_test_oracles_stay_out_of_the_pipeline():
    users = sorted(src for src, deps in dependency_graph().items() if "testing" in deps and src != "testing")
    assert not users, f"sphri.testing (oracles, toy data) is imported by {users}"
