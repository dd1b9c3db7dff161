"""The published API (``sphri.__all__``) and the fence between the core and the apps (docs/ARCHITECTURE.md,
"Core and apps").

The *core* is the layers chain, tracking, stages, geometry, geometry floor and foundation of the layer table;
the *apps* are the layers commands and beside the chain, grouped as :data:`APPS`. An app imports from the
core only names of the published API: ``from sphri import make_pipeline``, or the same name from the module
that defines it (``from sphri.pipeline import make_pipeline``: the same object, the spelling code written
before the API keeps). Two exceptions, both written here:

- :data:`TOOLKIT`: foundation modules that serve the apps rather than the chain (argument parsing, one-line
  errors, the figure style, HTML templates, progress bars, file modes, the memory limit, lazy exports); any of
  their names may be imported.
- :data:`ALLOWANCE`: per app, the core internals it still imports, measured when the API was published. A new
  import of a core internal fails the test (one line: file, app, module and name); an allowance no app uses any
  more fails too, so the table only shrinks.

The layer and cycle checks of tests/test_architecture.py read ``from sphri import X`` as an import of the
module that defines ``X`` (the package's lazy exports), so an app importing ``sphri.make_pipeline`` is an app
importing the chain, never the foundation's ``sphri`` importing it; the core itself never imports the
published names through ``sphri`` (:func:`test_the_core_never_imports_through_the_published_api`).
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import subprocess
import sys
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

import pytest

from tests.test_architecture import (
    ARCHITECTURE,
    PACKAGE,
    ROOT,
    _covers,
    _file_imports,
    _lazy_exports,
    _parsed,
    dependency_graph,
    layer_of,
    layer_table,
    module_graph,
    module_name,
)

API_DOC = ROOT / "docs" / "reference" / "api.md"

#: Layers of the core (the published API's side of the fence).
CORE_LAYERS = ("chain", "tracking", "stages", "geometry", "geometry floor", "foundation")

#: The apps on the core, each by the layer-table entries it is made of (layers commands and beside the chain).
APPS: dict[str, tuple[str, ...]] = {
    "commands": (
        "sphri.__main__",
        "sphri.command",
        "sphri.cli",
        "sphri.completion",
        "sphri.coverage",
        "sphri.cache.command",
        "sphri.docs_gen",
    ),
    "report": ("sphri.report",),
    "scenario study": ("sphri.sessions", "sphri.analysis"),
    "hardware": ("sphri.hardware",),
    "export": ("sphri.export",),
    "recordings": ("sphri.recordings",),
}

#: Foundation modules the apps share that are not the chain: any name of theirs may be imported.
TOOLKIT = (
    "sphri.args",
    "sphri.errors",
    "sphri.figures",
    "sphri.templating",
    "sphri.progress",
    "sphri.fsutil",
    "sphri.limits",
    "sphri._lazy",
)

#: A whole module imported (``import sphri.pipeline``, ``from sphri import pipeline``).
MODULE = "(module)"

#: app -> {core module: "names it still imports from it, not published"}: the fence's exceptions. Remove an
#: entry when its last import goes (the test fails while it stays); never add one: publish the name in
#: ``sphri/__init__.py`` (a promise: documented, kept) or keep the app off the internal.
ALLOWANCE: dict[str, dict[str, str]] = {
    "commands": {
        "sphri.cache": "SUFFIX",
        "sphri.config": (
            "DEFAULT_GROUPS RANGE_META RENAMED_KEYS RUNTIME_META RootConfig check_choices check_inputs "
            "component_node field_docs normalize_overrides register_schemas resolved_setting"
        ),
        "sphri.contact.query": "winding_number",
        "sphri.pipeline": "(module) chain_region",
        "sphri.stages": "PARAM_GROUPS STAGE_GROUPS",
        "sphri.tracking.mlflow_tracker": "summary_text ui_hint",
        "sphri.tracking.parent": "progress_line read_parent stop_if_killed write_status",
    },
    "report": {
        "sphri.config": "result_neutral runtime_keys",
        "sphri.noise.components": "threshold_false_on_rate",
        "sphri.noise.schema": "ThresholdNoiseSchema",
        "sphri.tracking.artifacts": "draw_confusion",
        "sphri.tracking.mlflow_tracker": "PARENT_FILE",
    },
    "scenario study": {
        "sphri.config": "component_node cross_check load_schema plain result_config",
        "sphri.contact.exact": "ExactContact",
        "sphri.contact.mesh": "prepare_mesh",
        "sphri.contact.query": "SearchRecord capsule_mesh_query",
        "sphri.data.duplicates": "DUPLICATE_POLICIES describe find_duplicates fingerprint",
        "sphri.data.format": "POSE_SUFFIXES make_trials_frame participant_id pose_columns",
        "sphri.data.gestures": "Style",
        "sphri.data.handfk": "HandRig matrix_to_quat",
        "sphri.data.lengths": "BANDS",
        "sphri.data.linkgeom": "LinkSurface",
        "sphri.data.people": "Spread",
        "sphri.data.recording_schema": "(module)",
        "sphri.data.reference_stats": "COST_DURATION_MS VR_FRAME_RATE_HZ VR_MEDIAN_TRIAL_FRAMES",
        "sphri.data.schema": "DataSchema",
        "sphri.data.synthesize": "SynthesizeArgs write_dataset",
        "sphri.data.synthetic": "SyntheticData",
        "sphri.geometry.samples": "SurfaceSamples sample_link",
        "sphri.hand.kinematics": "capsule_segments quat_to_matrix",
        "sphri.integrity": "stable_hash",
        "sphri.pipeline": "COMPUTE StageCompute",
        "sphri.robots.kinematic": "JointTree WholeBodyRobot",
        "sphri.robots.schema": "BUILTIN",
        "sphri.robots.urdf_tree": "UrdfWholeBody",
        "sphri.surface.charts": "from_uv to_uv",
        "sphri.surface.density": "SurfaceKernel SurfaceSamples sample_link touched_elements",
    },
    "hardware": {
        "sphri.adjacency": "Adjacency taxel_adjacency",
        "sphri.pipeline": "trial_keys",
    },
    "export": {
        "sphri.adjacency": "metric_coords",
        "sphri.integrity": "DIGEST_SIZE FROM_ENV NO_KEY keyed_digest keyed_ok load_key plain_digest",
    },
    "recordings": {
        "sphri.data.duplicates": "describe find_duplicates fingerprint",
        "sphri.data.format": (
            "GENERATOR_KEY PARTICIPANT_RE manifest_path parquet_path participant_id write_hand_definition"
        ),
        "sphri.data.recording_schema": (
            "CAPSULE_LOG Column GAP_FACTOR HANDS LOG_KINDS OPENXR_CAPSULES OPENXR_JOINTS OPENXR_LOG OVR_BONES "
            "OVR_CAPSULE_LOG documented_capsules"
        ),
        "sphri.data.schema": "POSITION_UNITS",
        "sphri.data.synthesize": "SynthesizeArgs command write_dataset",
        "sphri.data.vr_gesture": (
            "HAND_SCALE_RANGE VRGestureData check_position_scale column_problems hand_model_size_m"
        ),
        "sphri.data.writer": "append_trial",
        "sphri.hand.capsules": "HandCapsules finger_of",
        "sphri.hand.kinematics": "capsule_segments quat_to_matrix",
    },
}


def published() -> dict[str, str]:
    """``name -> module that defines it`` of the published API (the dict literal of ``sphri/__init__.py``)."""
    return _lazy_exports(_parsed()[PACKAGE / "__init__.py"])


def app_of(module: str) -> str | None:
    """The app a module belongs to (the longest :data:`APPS` entry covering it), or None for the core."""
    best: tuple[int, str] | None = None
    for app, entries in APPS.items():
        for entry in entries:
            if _covers(entry, module) and (best is None or len(entry) > best[0]):
                best = (len(entry), app)
    return None if best is None else best[1]


def _is_core(module: str, table) -> bool:
    layer = layer_of(module, table)
    return layer is not None and layer[1] in CORE_LAYERS and not any(_covers(t, module) for t in TOOLKIT)


def app_imports(package: Path = PACKAGE) -> Iterator[tuple[str, str, str, str]]:
    """``(app, core module, name, file:line)`` of every import of a core name by an app that is not a published
    name (:data:`MODULE` for a whole module); typing-only imports are left out, as in the layer check."""
    root, table, api = package.parent, layer_table(), published()
    trees = {module_name(p, root): (p, tree) for p, tree in _parsed(package).items()}
    for src, (path, tree) in sorted(trees.items()):
        app = app_of(src)
        if app is None:
            continue
        for base, names, line in _file_imports(tree, src, path.name == "__init__.py"):
            if base != "sphri" and not base.startswith("sphri."):
                continue
            where = f"{path.relative_to(root).as_posix()}:{line}"
            for name in names or [MODULE]:
                module = f"{base}.{name}" if f"{base}.{name}" in trees else base
                name = MODULE if module != base else name
                if module == "sphri" and (name in api or name in (MODULE, "__version__")):
                    continue  # the published API itself
                if api.get(name) == module:
                    continue  # a published name, from the module that defines it
                if _is_core(module, table):
                    yield app, module, name, where


def check_fence(imports: Iterable[tuple[str, str, str, str]], allowance: Mapping[str, Mapping[str, str]]) -> None:
    """AssertionError naming, one line each, every app import of a core internal the allowance does not list,
    and every allowance no import uses any more."""
    allowed = {
        (app, mod, name) for app, mods in allowance.items() for mod, names in mods.items() for name in names.split()
    }
    used: set[tuple[str, str, str]] = set()
    new = []
    for app, module, name, where in imports:
        used.add((app, module, name))
        if (app, module, name) not in allowed:
            shown = module if name == MODULE else f"{module}.{name}"
            new.append(f"{where}: {app} imports {shown}, a core internal (use or publish sphri's API)")
    stale = [
        f"ALLOWANCE[{app!r}][{mod!r}] lists {name}, which {app} no longer imports: remove it"
        for app, mod, name in sorted(allowed - used)
    ]
    assert not new and not stale, "the fence between core and apps (tests/test_api.py):\n  " + "\n  ".join(
        sorted(set(new)) + stale
    )


# --- the published API ----------------------------------------------------------------------------------------------


def _declared_in_type_checking() -> dict[str, str]:
    """``name -> module`` of the ``if TYPE_CHECKING`` re-exports of ``sphri/__init__.py`` (for type checkers)."""
    out = {}
    for node in ast.walk(_parsed()[PACKAGE / "__init__.py"]):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for stmt in node.body:
                assert isinstance(stmt, ast.ImportFrom) and stmt.module, ast.unparse(stmt)
                out.update({a.asname or a.name: stmt.module for a in stmt.names})
    return out


def _has_doc_comment(module: str, name: str) -> bool:
    """A module-level constant is documented by a ``#:`` comment above its assignment or a string under it."""
    path = Path(sys.modules[module].__file__ or "")
    tree, lines = _parsed()[path], path.read_text().splitlines()
    body = tree.body
    for i, node in enumerate(body):
        targets = [node.target] if isinstance(node, ast.AnnAssign) else getattr(node, "targets", [])
        if any(isinstance(t, ast.Name) and t.id == name for t in targets):
            above = lines[node.lineno - 2].strip() if node.lineno > 1 else ""
            after = body[i + 1] if i + 1 < len(body) else None
            under = isinstance(after, ast.Expr) and isinstance(getattr(after, "value", None), ast.Constant)
            return above.startswith("#:") or under
    return False


def test_every_published_name_resolves_to_its_module_and_is_documented():
    import sphri

    api = published()
    assert sphri.__all__ == list(api) and len(set(api)) == len(api)
    assert _declared_in_type_checking() == api, "sphri/__init__.py: the TYPE_CHECKING re-exports differ from __all__"
    undocumented = []
    for name, module in api.items():
        obj = getattr(sphri, name)
        assert obj is getattr(sys.modules[module], name), name
        if inspect.isclass(obj) or inspect.isfunction(obj):
            doc = (obj.__dict__.get("__doc__") if inspect.isclass(obj) else obj.__doc__) or ""
            auto = dataclasses.is_dataclass(obj) and doc.startswith(f"{obj.__name__}(")  # dataclass's own
            if not doc.strip() or auto:
                undocumented.append(f"{module}.{name}")
        elif not _has_doc_comment(module, name):
            undocumented.append(f"{module}.{name} (a '#:' comment above it)")
    assert not undocumented, f"published names without a docstring: {undocumented}"
    with pytest.raises(AttributeError, match="no attribute 'not_published'"):
        sphri.not_published  # noqa: B018


def test_published_names_hide_no_module_and_stay_in_the_core():
    """A published name never shadows a module of sphri (``from sphri import figures`` stays the module),
    and each is defined in a core module, so publishing it draws no app into the core."""
    modules = {p.stem for p in PACKAGE.iterdir() if p.suffix == ".py" or (p / "__init__.py").is_file()}
    table = layer_table()
    for name, module in published().items():
        assert name not in modules, f"sphri.{name} is a module and a published name"
        assert _is_core(module, table), f"sphri.{name} is defined in {module}, not in the core"


def test_the_published_errors_are_the_cores_expected_errors():
    """The errors of the API are exactly the rows of sphri.errors.EXPECTED whose class lives in the core."""
    import sphri
    from sphri.errors import EXPECTED

    table = layer_table()
    core = {name for module, name, _ in EXPECTED if module != "builtins" and _is_core(module, table)}
    errors = {
        n for n in sphri.__all__ if inspect.isclass(getattr(sphri, n)) and issubclass(getattr(sphri, n), Exception)
    }
    assert errors == core, (
        f"published but not expected: {sorted(errors - core)}; expected, not published: {sorted(core - errors)}"
    )


def test_import_sphri_imports_nothing_but_the_standard_library():
    """``import sphri`` (every console script and ``python -m sphri`` start with it) imports no module of
    sphri beyond :mod:`sphri._lazy` and no library outside the standard library, numpy included; the first
    use of a name imports its module."""
    probe = (
        "import sys; import sphri; names = sphri.__all__\n"
        "print(sorted(m for m in sys.modules if m.startswith('sphri')))\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} - set(sys.stdlib_module_names) - {'sphri', '__main__'}"
        " - {m for m in sys.modules if m.startswith(('_distutils_hack', '__editable__'))}))\n"
        "sphri.GESTURES; print('sphri.types' in sys.modules, 'sphri.pipeline' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split("\n")[:3] == ["['sphri', 'sphri._lazy']", "[]", "True False"], out.stdout


def test_the_api_reference_lists_every_published_name():
    """docs/reference/api.md opens with one table row per published name (``[`name`][module.name]``, rendered
    by mkdocstrings below it): no name missing, none that is not published."""
    import re

    text = API_DOC.read_text()
    section = text.split("\n## The published API\n", 1)[1].split("\n## ", 1)[0]
    listed = re.findall(r"^\| \[`(\w+)`\]\[([\w.]+)\] \|", section, flags=re.M)
    api = published()
    assert [n for n, _ in listed] == list(api), "docs/reference/api.md's table and sphri.__all__ differ (order too)"
    wrong = [(n, ref) for n, ref in listed if ref != f"{api[n]}.{n}"]
    assert not wrong, f"docs/reference/api.md links these to another object: {wrong}"


# --- the fence ------------------------------------------------------------------------------------------------------


def test_every_app_module_belongs_to_one_app_and_every_core_module_to_none():
    table = layer_table()
    for module in module_graph():
        layer = layer_of(module, table)
        assert layer is not None
        if layer[1] in ("commands", "beside the chain"):
            assert app_of(module) is not None, f"{module} (layer {layer[1]}) is in no app of tests/test_api.py APPS"
        else:
            assert app_of(module) is None or layer[1] == "oracles", f"{module} (layer {layer[1]}) is in an app"
    for module in TOOLKIT:
        assert layer_of(module, table)[1] == "foundation", module


def test_apps_import_from_the_core_only_the_published_api():
    check_fence(app_imports(), ALLOWANCE)


def test_the_fence_names_a_new_internal_import_and_a_stale_allowance():
    imports = list(app_imports())
    planted = [*imports, ("hardware", "sphri.pipeline", "COMPUTE", "sphri/hardware/source.py:1")]
    with pytest.raises(AssertionError, match=r"sphri/hardware/source\.py:1: hardware imports sphri\.pipeline\.COMPUTE"):
        check_fence(planted, ALLOWANCE)
    stale = {app: dict(mods) for app, mods in ALLOWANCE.items()}
    stale["report"]["sphri.pipeline"] = "trial_keys"
    with pytest.raises(AssertionError, match=r"ALLOWANCE\['report'\]\['sphri.pipeline'\] lists trial_keys"):
        check_fence(imports, stale)


def test_a_published_name_passes_the_fence_in_either_spelling(tmp_path):
    """``from sphri import make_pipeline`` and ``from sphri.pipeline import make_pipeline`` are the API;
    ``from sphri.pipeline import trial_keys`` and ``import sphri.pipeline`` are not."""
    pkg = tmp_path / "sphri"
    (pkg / "hardware").mkdir(parents=True)
    (pkg / "__init__.py").write_text((PACKAGE / "__init__.py").read_text())
    for name in ("pipeline.py", "_lazy.py", "hardware/__init__.py"):
        (pkg / name).write_text("")
    (pkg / "hardware" / "x.py").write_text(
        "from sphri import make_pipeline, __version__\nfrom sphri.pipeline import open_cache\n"
        "from sphri.pipeline import trial_keys\nimport sphri.pipeline\nfrom sphri import _lazy\n"
    )
    found = [(app, mod, name, where) for app, mod, name, where in app_imports(pkg) if where.startswith("sphri/hard")]
    assert found == [
        ("hardware", "sphri.pipeline", "trial_keys", "sphri/hardware/x.py:3"),
        ("hardware", "sphri.pipeline", MODULE, "sphri/hardware/x.py:4"),
    ]


def test_the_core_never_imports_through_the_published_api():
    """Inside the core a published name is imported from the module that defines it: ``from sphri import X``
    in a core module would make the foundation's package the way between two core modules (a cycle risk)."""
    api, table = published(), layer_table()
    bad = [
        f"{src} imports sphri.{name} at {where}"
        for path, tree in _parsed().items()
        if (src := module_name(path)) != "sphri" and _is_core(src, table) or src in TOOLKIT
        for base, names, line in _file_imports(tree, src, path.name == "__init__.py")
        if base == "sphri"
        for name in names
        if name in api and (where := f"{path.relative_to(ROOT).as_posix()}:{line}")
    ]
    assert not bad, "core modules importing through sphri's API (import from the defining module):\n  " + "\n  ".join(
        bad
    )


def test_an_app_importing_the_api_depends_on_the_defining_package():
    """The unit-level cycle check reads ``from sphri import build`` (sphri/export/train.py) as export -> config."""
    assert "config" in dependency_graph()["export"]


def test_the_architecture_names_the_core_the_apps_and_the_toolkit():
    text = ARCHITECTURE.read_text()
    assert "\n## Core and apps\n" in text, "docs/ARCHITECTURE.md has no '## Core and apps' section"
    section = text.split("\n## Core and apps\n", 1)[1].split("\n## ", 1)[0]
    missing = [m for m in (*TOOLKIT, *CORE_LAYERS, *APPS) if m not in section]
    assert not missing, f"docs/ARCHITECTURE.md, 'Core and apps', does not name {missing}"


@pytest.mark.parametrize("page", [API_DOC, ROOT / "README.md"], ids=["api.md", "README"])
def test_the_api_example_runs_as_written(page, tmp_path, monkeypatch):
    """The first Python block of docs/reference/api.md and of the README, run as a reader would (in an empty
    folder: its cache and outputs go under it), gives the filter stage's windows: the published names are
    enough to drive the chain."""
    block = page.read_text().split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    scope: dict = {}
    exec(compile(block, str(page), "exec"), scope)
    windows = scope["windows"]
    assert type(windows).__name__ == "WindowedFrames" and windows.x.shape[0] == len(windows.y) > 0
    assert list((tmp_path / "outputs" / "cache" / "plan").glob("*.entry"))  # persisted stages, in the reader's folder
