"""The import structure: dependencies point one way (no cycle between packages or between files, no import
against the layer order of docs/ARCHITECTURE.md), test oracles stay out of the pipeline."""

from __future__ import annotations

import ast
import functools
import re
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sphri"


def _unit(path: Path) -> str:
    """The package (``sphri/<name>/``) or top-level module (``sphri/<name>.py``) a file belongs to."""
    return path.relative_to(PACKAGE).parts[0].removesuffix(".py")


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


@functools.cache
def _parsed(package: Path = PACKAGE) -> dict[Path, ast.Module]:
    """Every file of the package, parsed once per test session."""
    return {p: ast.parse(p.read_text(), str(p)) for p in sorted(package.rglob("*.py"))}


def dependency_graph() -> dict[str, set[str]]:
    """unit -> units of sphri it imports at run time (itself excluded).

    ``from sphri import make_pipeline`` (the published API, lazy exports of ``sphri/__init__.py``) is an
    import of the unit that defines the name (``pipeline``), not of ``sphri`` itself: the package imports
    none of its exports, so the foundation's ``sphri`` row never stands for the chain or the stages."""
    graph: dict[str, set[str]] = defaultdict(set)
    units = {_unit(p) for p in PACKAGE.rglob("*.py")}
    published = _lazy_exports(_parsed()[PACKAGE / "__init__.py"])
    for path in PACKAGE.rglob("*.py"):
        src = _unit(path)
        for module in _runtime_imports(_parsed()[path]):
            parts = module.split(".")
            if len(parts) == 2 and parts[0] == "sphri" and parts[1] in published:
                parts = published[parts[1]].split(".")
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
    detail = "; ".join(
        " <-> ".join(c) + " (" + ", ".join(f"{a}->{b}" for a in c for b in sorted(graph[a] & set(c))) + ")"
        for c in found
    )
    assert not found, f"import cycles between sphri packages: {detail}"


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_test_oracles_stay_out_of_the_pipeline():
    users = sorted(src for src, deps in dependency_graph().items() if "testing" in deps and src != "testing")
    assert not users, f"sphri.testing (oracles, toy data) is imported by {users}"


# --- file level: every module of sphri, its imports, the layers of docs/ARCHITECTURE.md -----------------------------

ROOT = PACKAGE.parent
ARCHITECTURE = ROOT / "docs" / "ARCHITECTURE.md"


def module_name(path: Path, root: Path = ROOT) -> str:
    """``sphri/robots/schema.py`` -> ``sphri.robots.schema``; a package's ``__init__.py`` -> the package."""
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _lazy_exports(tree: ast.AST) -> dict[str, str]:
    """``name -> module`` of a package's ``lazy_exports(package, {...})`` (``sphri._lazy``)."""
    out = {}
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Call)
            and getattr(node.func, "id", "") == "lazy_exports"
            and len(node.args) == 2
            and isinstance(node.args[1], ast.Dict)
        ):
            out.update({k.value: v.value for k, v in zip(node.args[1].keys, node.args[1].values)})
    return out


def _file_imports(tree: ast.AST, module: str, is_package: bool):
    """``(imported module path, names, line)`` of every import in ``tree``: at module level, in a class or a
    function, under ``if __name__ == "__main__"``; only ``if TYPE_CHECKING`` blocks (typing only) are left out."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, [], node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the file's package upwards
                pkg = module.split(".") if is_package else module.split(".")[:-1]
                pkg = pkg[: len(pkg) - node.level + 1]
                base = ".".join(pkg + ([base] if base else []))
            yield base, [a.name for a in node.names], node.lineno


@functools.cache
def module_graph(package: Path = PACKAGE) -> dict[str, dict[str, str]]:
    """module -> {module of sphri it imports -> ``file:line`` of the first such import}, at file granularity
    (computed once; copy it before changing it).

    ``from sphri.robots import schema`` is an edge to ``sphri.robots.schema``; ``from sphri.contact import
    capsule_mesh_query`` goes through the package's lazy exports to the module that defines the name, and so does
    ``from sphri import make_pipeline`` (the published API: an edge to ``sphri.pipeline``, never to the
    foundation's ``sphri``, whose ``__init__`` imports none of its exports); any other name imported from a
    package is an edge to the package (its ``__init__``)."""
    root = package.parent
    files = {module_name(p, root): p for p in _parsed(package)}
    trees = {module_name(p, root): tree for p, tree in _parsed(package).items()}
    lazy = {m: _lazy_exports(t) for m, t in trees.items() if files[m].name == "__init__.py"}
    graph: dict[str, dict[str, str]] = {m: {} for m in files}
    for src, tree in trees.items():
        for base, names, line in _file_imports(tree, src, files[src].name == "__init__.py"):
            if base != "sphri" and not base.startswith("sphri."):
                continue
            targets = set()
            if base in files:
                for name in names:
                    if f"{base}.{name}" in files:
                        targets.add(f"{base}.{name}")
                    else:
                        targets.add(lazy.get(base, {}).get(name, base))
                if not names:  # import sphri.x
                    targets.add(base)
            else:  # "import sphri.x.y.Name"-like paths: the longest prefix that is a file
                parts = base.split(".")
                while parts and ".".join(parts) not in files:
                    parts.pop()
                targets.add(".".join(parts))
            for dst in sorted(targets - {src}):
                graph[src].setdefault(dst, f"{files[src].relative_to(root).as_posix()}:{line}")
    return graph


def find_cycle(graph: Mapping[str, Iterable[str]], members: Sequence[str]) -> list[str]:
    """One closed path ``[a, b, ..., a]`` through a strongly connected component ``members``."""
    inside = set(members)
    start = members[0]
    path, seen = [start], {start: 0}
    while True:  # walk inside the component until a node repeats: that stretch is a cycle
        step = sorted(w for w in graph.get(path[-1], ()) if w in inside)[0]
        if step in seen:
            return path[seen[step] :] + [step]
        seen[step] = len(path)
        path.append(step)


def check_no_file_cycles(graph: Mapping[str, Mapping[str, str]]) -> None:
    """AssertionError naming every import cycle between files: its members and one closed path with file:line."""
    found = cycles({k: set(v) for k, v in graph.items()})
    lines = []
    for comp in found:
        loop = find_cycle(graph, comp)
        where = ", ".join(f"{a} -> {b} ({graph[a][b]})" for a, b in zip(loop, loop[1:]))
        lines.append(
            f"{' -> '.join(loop)} [{where}]" + (f"; all of {comp} are tied" if len(comp) > len(loop) - 1 else "")
        )
    assert not found, (
        "import cycles between files of sphri (move the shared piece to the lower module):\n  " + "\n  ".join(lines)
    )


def _layer_tables(text: str | None = None) -> dict[str, list[list[str]]]:
    """``{first header cell: [row cells]}`` of every table under ``## Layers`` of docs/ARCHITECTURE.md."""
    text = ARCHITECTURE.read_text() if text is None else text
    assert "\n## Layers\n" in text, "docs/ARCHITECTURE.md has no '## Layers' section (the layer table)"
    section = text.split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    tables: dict[str, list[list[str]]] = {}
    rows: list[list[str]] | None = None
    for line in section.splitlines():
        if not line.lstrip().startswith("|"):
            rows = None  # a table ends at its first line that is not a row
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if rows is None:
            rows = tables.setdefault(cells[0], [])
        elif not set(cells[0]) <= set("-: "):
            rows.append(cells)
    return tables


def layer_table(text: str | None = None) -> list[tuple[str, list[str]]]:
    """``[(layer, [module or package names])]``, highest layer first, from the table under ``## Layers`` of
    docs/ARCHITECTURE.md whose first column is ``layer`` (the one place the layer order is written)."""
    out = []
    for cells in _layer_tables(text).get("layer", []):
        assert len(cells) >= 2, f"docs/ARCHITECTURE.md, layer table: row {cells} has no modules column"
        names = re.findall(r"`(sphri(?:\.[A-Za-z_][A-Za-z0-9_]*)*)`", cells[1])
        assert names, f"docs/ARCHITECTURE.md, layer table: row {cells[0]!r} names no module (`sphri.x`)"
        out.append((cells[0].strip("*"), names))
    assert out, "docs/ARCHITECTURE.md: no layer table under '## Layers'"
    return out


def layer_bans(text: str | None = None) -> list[tuple[str, list[str]]]:
    """``[(module or package, [layers it may not import])]`` from the table under ``## Layers`` whose first
    column is ``module`` (the rules beside the order)."""
    layers = {name for name, _ in layer_table(text)}
    out = []
    for cells in _layer_tables(text).get("module", []):
        module = re.fullmatch(r"`(sphri(?:\.[A-Za-z_][A-Za-z0-9_]*)*)`", cells[0])
        banned = [w.strip() for w in cells[1].split(",")] if len(cells) > 1 else []
        assert module and banned, f"docs/ARCHITECTURE.md, layer rules: row {cells} needs `sphri.x` | layers"
        unknown = sorted(set(banned) - layers)
        assert not unknown, f"docs/ARCHITECTURE.md, layer rules: row {cells[0]} names no layer {unknown}"
        out.append((module.group(1), banned))
    return out


def _covers(name: str, module: str) -> bool:
    """A table entry names a module, or a package and every module below it; ``sphri`` alone is its ``__init__``."""
    return module == name or (name != "sphri" and module.startswith(name + "."))


def layer_of(module: str, table: Sequence[tuple[str, list[str]]]) -> tuple[int, str, str] | None:
    """``(rank, layer, entry)`` of ``module`` (rank 0 = lowest) by the longest table entry covering it; None when
    no entry does."""
    best = None
    for rank, (layer, names) in enumerate(reversed(table)):
        for name in names:
            if _covers(name, module) and (best is None or len(name) > len(best[2])):
                best = (rank, layer, name)
    return best


def check_layers(graph: Mapping[str, Mapping[str, str]], table: Sequence[tuple[str, list[str]]]) -> None:
    """AssertionError naming every module without a layer and every import of a higher layer."""
    lost = sorted(m for m in graph if layer_of(m, table) is None)
    assert not lost, f"modules with no layer in docs/ARCHITECTURE.md's layer table (add them to a row): {lost}"
    bad = []
    for src, deps in sorted(graph.items()):
        low = layer_of(src, table)
        for dst, where in sorted(deps.items()):
            high = layer_of(dst, table)
            if high is not None and high[0] > low[0]:
                bad.append(f"{src} (layer {low[1]}) imports {dst} (layer {high[1]}) at {where}")
    assert not bad, (
        "imports against the layer order of docs/ARCHITECTURE.md (a layer imports only itself and "
        "the layers below it):\n  " + "\n  ".join(bad)
    )


def test_no_import_cycles_between_files():
    check_no_file_cycles(module_graph())


def test_file_cycle_check_names_the_loop():
    graph = {
        "sphri.a": {"sphri.b": "sphri/a.py:3"},
        "sphri.b": {"sphri.c": "sphri/b.py:7"},
        "sphri.c": {"sphri.a": "sphri/c.py:9"},
        "sphri.d": {"sphri.a": "sphri/d.py:1"},
    }
    with pytest.raises(AssertionError, match=r"sphri\.a -> sphri\.b -> sphri\.c -> sphri\.a .*sphri/c\.py:9"):
        check_no_file_cycles(graph)
    check_no_file_cycles({"sphri.a": {"sphri.b": "sphri/a.py:3"}, "sphri.b": {}})


def test_module_graph_counts_every_kind_of_import(tmp_path):
    """Module level, in a function, in a ``__main__`` block, relative, through a package's lazy exports: each is an
    edge to the file it loads; a typing-only import is not."""
    pkg = tmp_path / "sphri"
    (pkg / "pkg").mkdir(parents=True)
    (pkg / "__init__.py").write_text(
        "from sphri._lazy import lazy_exports\n__getattr__, __all__ = lazy_exports('sphri', {'X': 'sphri.low'})\n"
    )
    (pkg / "low.py").write_text("X = 1\n")
    (pkg / "cmd.py").write_text("from sphri import X\ndef main():\n    return X\n")
    (pkg / "pkg" / "__init__.py").write_text(
        "from sphri._lazy import lazy_exports\n__getattr__, __all__ = lazy_exports('sphri.pkg', {'Thing': 'sphri.pkg.impl'})\n"
    )
    (pkg / "pkg" / "impl.py").write_text("from .. import low\nfrom . import other\nThing = low.X\n")
    (pkg / "pkg" / "other.py").write_text("")
    (pkg / "_lazy.py").write_text("")
    (pkg / "high.py").write_text(
        "from typing import TYPE_CHECKING\nimport numpy\nif TYPE_CHECKING:\n    from sphri import cmd\n"
        "def f():\n    from sphri.pkg import Thing\n    return Thing\n"
        "if __name__ == '__main__':\n    from sphri.cmd import main\n    main()\n"
    )
    graph = module_graph(pkg)
    assert graph["sphri.high"] == {"sphri.pkg.impl": "sphri/high.py:6", "sphri.cmd": "sphri/high.py:9"}
    assert graph["sphri.pkg.impl"] == {"sphri.low": "sphri/pkg/impl.py:1", "sphri.pkg.other": "sphri/pkg/impl.py:2"}
    assert graph["sphri.pkg"] == {"sphri._lazy": "sphri/pkg/__init__.py:1"}
    # the published API: an edge to the module that defines the name; the package itself imports only _lazy
    assert graph["sphri.cmd"] == {"sphri.low": "sphri/cmd.py:1"}
    assert graph["sphri"] == {"sphri._lazy": "sphri/__init__.py:1"}


def test_the_two_loops_of_issue_30_stay_broken():
    graph = module_graph()
    # the robot schema is the bottom of sphri.robots: it imports no robot implementation, not even in a function
    assert not [m for m in graph["sphri.robots.schema"] if m.startswith("sphri.robots.")]
    # the `sphri cache` verb is sphri/cache/command.py; the cache itself imports no command
    assert "sphri.cache" in graph["sphri.cache.command"] and "sphri.cache.command" not in graph["sphri.cache"]


def check_bans(
    graph: Mapping[str, Mapping[str, str]],
    table: Sequence[tuple[str, list[str]]],
    bans: Sequence[tuple[str, list[str]]],
) -> None:
    """AssertionError naming every import of a module of a layer its rule in the layer rules table bans."""
    bad = []
    for name, banned in bans:
        for src, deps in sorted(graph.items()):
            if not _covers(name, src):
                continue
            for dst, where in sorted(deps.items()):
                high = layer_of(dst, table)
                if high is not None and high[1] in banned:
                    bad.append(f"{src} imports {dst} (layer {high[1]}) at {where}: {name} imports no {high[1]} module")
    assert not bad, "imports the layer rules of docs/ARCHITECTURE.md ban:\n  " + "\n  ".join(bad)


def test_imports_follow_the_layers():
    check_layers(module_graph(), layer_table())


def test_imports_follow_the_layer_rules():
    check_bans(module_graph(), layer_table(), layer_bans())


def test_the_layer_rules_of_the_core_are_written_and_hold():
    """No stage imports the command layer, tracking imports nothing of the runner (the chain, the commands),
    hardware imports no stage module: each is a rule of the table, and a planted import of each is named."""
    table, bans = layer_table(), dict(layer_bans())
    rank = {layer: r for r, (layer, _) in enumerate(reversed(table))}
    assert rank["commands"] > rank["stages"] and rank["commands"] > rank["geometry"]
    assert rank["chain"] > rank["tracking"] and {"chain", "commands"} <= set(bans["sphri.tracking"])
    assert "stages" in bans["sphri.hardware"]
    graph = module_graph()
    assert layer_of("sphri.args", table)[1] == "foundation" and layer_of("sphri.command", table)[1] == "commands"
    for src, dst, rule in [
        ("sphri.data.stats", "sphri.command", check_layers),
        ("sphri.robots.reachy2_derivative", "sphri.command", check_layers),
        ("sphri.tracking.parent", "sphri.pipeline", check_layers),
        ("sphri.tracking.mlflow_tracker", "sphri.__main__", check_layers),
        ("sphri.hardware.source", "sphri.encode.common", None),
    ]:
        bad = {m: dict(deps) for m, deps in graph.items()}
        bad[src][dst] = f"{src.replace('.', '/')}.py:1"
        with pytest.raises(AssertionError, match=re.escape(f"{src} ") + r".*imports " + re.escape(dst)):
            if rule is None:
                check_bans(bad, table, list(bans.items()))
            else:
                rule(bad, table)


def test_skin_frames_live_with_the_types():
    import sphri.encode
    import sphri.types

    assert sphri.types.SkinFrames.__module__ == "sphri.types"
    assert not hasattr(sphri.encode, "SkinFrames")  # no second name for it (issue 53)


def test_layer_rules_table_rejects_an_unknown_layer():
    text = ARCHITECTURE.read_text().replace("| `sphri.hardware` | stages |", "| `sphri.hardware` | stagez |")
    with pytest.raises(AssertionError, match=r"names no layer \['stagez'\]"):
        layer_bans(text)


def test_layer_check_names_both_modules_of_a_violation():
    table = layer_table()
    graph = {m: dict(deps) for m, deps in module_graph().items()}
    graph["sphri.types"]["sphri.pipeline"] = "sphri/types.py:1"  # the bottom importing the chain
    with pytest.raises(
        AssertionError,
        match=r"sphri\.types \(layer foundation\) imports sphri\.pipeline \(layer chain\) "
        r"at sphri/types\.py:1",
    ):
        check_layers(graph, table)
    graph = {m: dict(deps) for m, deps in module_graph().items()}
    graph["sphri.brand_new"] = {}
    with pytest.raises(AssertionError, match=r"no layer .*sphri\.brand_new"):
        check_layers(graph, table)


def test_layer_table_names_only_modules_that_exist():
    modules = set(module_graph())
    table = layer_table()
    stale = [n for _, names in table for n in names if not any(_covers(n, m) for m in modules)]
    assert not stale, f"docs/ARCHITECTURE.md's layer table names modules that do not exist: {stale}"
    twice = sorted({n for _, names in table for n in names if sum(n in ns for _, ns in table) > 1})
    assert not twice, f"docs/ARCHITECTURE.md's layer table names these in two rows: {twice}"


def test_the_geometry_floor_sits_below_the_surfaces_and_the_stages():
    """issue 30 point 5: sphri.geometry is its own row under the bodies and surfaces; it imports only the
    foundation, and importing a surface or a stage from it is a violation the layer check names."""
    table = layer_table()
    floor, bodies = layer_of("sphri.geometry.link", table), layer_of("sphri.surface.density", table)
    assert floor is not None and bodies is not None and floor[1] == "geometry floor" and floor[0] < bodies[0]
    graph = module_graph()
    assert {m for m in graph if m.startswith("sphri.geometry")} >= {"sphri.geometry.link", "sphri.geometry.samples"}
    above = [
        (m, d) for m in graph if m.startswith("sphri.geometry") for d in graph[m] if layer_of(d, table)[0] > floor[0]
    ]
    assert not above, above
    bad = {m: dict(deps) for m, deps in graph.items()}
    bad["sphri.geometry.samples"]["sphri.surface.density"] = "sphri/geometry/samples.py:1"
    with pytest.raises(
        AssertionError, match=r"sphri\.geometry\.samples \(layer geometry floor\) imports sphri\.surface"
    ):
        check_layers(bad, table)


def test_the_suites_heavy_first_order_names_real_test_modules():
    """tests/conftest.py runs its HEAVY_FIRST modules first; a renamed module would silently drop out."""
    from tests.conftest import HEAVY_FIRST

    missing = [m for m in HEAVY_FIRST if not (PACKAGE.parent / m).is_file()]
    assert not missing and len(set(HEAVY_FIRST)) == len(HEAVY_FIRST), missing
