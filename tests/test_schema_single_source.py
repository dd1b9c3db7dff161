"""Defaults and docs live once, in the schemas: component YAMLs hold the choice and what differs."""

import dataclasses
import importlib
import linecache
import sys

import pytest
import yaml
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from sphri.command import main as cli_main
from sphri.config import CONF_DIR, SCHEMA_MODULES, field_docs

#: ``(group, option, key)`` a YAML may write although it equals the schema's default, with the reason.
#: Every other key equal to its default is reported: sources, units and citations live in the schema
#: fields' docstrings, so a YAML holds the choice and what differs (robot and hand definitions and the
#: synthetic study's assumptions included).
REPEAT_ALLOWED: dict[tuple[str, str, str], str] = {}


def opts_in(group: str, path) -> bool:
    defaults = (yaml.safe_load(path.read_text()) or {}).get("defaults", [])
    return any(isinstance(d, str) and d.startswith(f"/schema_{group}_") for d in defaults)


def schema_of(group: str, path) -> type:
    for m in SCHEMA_MODULES:
        importlib.import_module(m)
    d = yaml.safe_load(path.read_text())
    entry = next(x for x in d["defaults"] if isinstance(x, str) and x.startswith(f"/schema_{group}_"))
    return OmegaConf.get_type(ConfigStore.instance().repo[entry[1:].removesuffix("@_here_") + ".yaml"].node)


def repeated_defaults(group: str, path, allowed=REPEAT_ALLOWED) -> list[str]:
    """Keys of the YAML ``path`` that equal its schema's default and are not in ``allowed``."""
    default = OmegaConf.to_container(OmegaConf.structured(schema_of(group, path)))
    values = yaml.safe_load(path.read_text())
    return [
        k
        for k, v in values.items()
        if k not in ("defaults", "_target_")
        and k in default
        and default[k] == v
        and (group, path.stem, k) not in allowed
    ]


#: Every YAML of every group that opts into a schema (each stage group, data, robot, hand).
FILES = [(p.parent.name, p) for p in sorted(CONF_DIR.glob("*/*.yaml")) if opts_in(p.parent.name, p)]


def test_every_group_with_schemas_is_checked():
    assert {"data", "robot", "hand", "encoder", "cv", "model"} <= {g for g, _ in FILES}


@pytest.mark.parametrize("group,path", FILES, ids=[f"{g}/{p.stem}" for g, p in FILES])
def test_component_yaml_holds_only_what_differs_and_the_schema_documents_every_field(group, path):
    schema = schema_of(group, path)
    same = repeated_defaults(group, path)
    assert not same, (
        f"{path.name}: {same} repeat the schema's defaults (delete them, or list them in REPEAT_ALLOWED with a reason)"
    )
    docs = field_docs(schema)
    undocumented = [f.name for f in dataclasses.fields(schema) if f.name != "_target_" and not docs.get(f.name)]
    assert not undocumented, f"{schema.__name__}: fields without a docstring: {undocumented}"


def test_a_repeated_default_is_reported_unless_allowed(tmp_path):
    """A data YAML writing one value equal to its schema's default (a float written as in the schema) and
    one that differs: only the repeat is reported, and an allowance with a reason silences it."""
    path = tmp_path / "data" / "synthetic.yaml"
    path.parent.mkdir()
    path.write_text("defaults:\n  - /schema_data_synthetic@_here_\n  - _self_\njitter_mm: 3.0\nlatency_ms: 60.0\n")
    assert repeated_defaults("data", path) == ["jitter_mm"]
    assert repeated_defaults("data", path, {("data", "synthetic", "jitter_mm"): "a reason"}) == []
    assert all(reason.strip() for reason in REPEAT_ALLOWED.values()), "every allowance states its reason"
    stale = [
        key
        for key in REPEAT_ALLOWED
        if key[2] not in (yaml.safe_load((CONF_DIR / key[0] / f"{key[1]}.yaml").read_text()) or {})
    ]
    assert not stale, f"REPEAT_ALLOWED lists keys the YAMLs no longer write: {stale}"


def test_field_docs_include_inherited_fields():
    from sphri.evaluate.schema import KFoldSchema
    from sphri.layout.schema import HexLayoutSchema

    assert "parallel processes" in field_docs(KFoldSchema)["workers"] and "folds" in field_docs(KFoldSchema)["k"]
    assert set(field_docs(HexLayoutSchema)) >= {"aspect", "seed"}


def test_field_docs_of_a_class_defined_anew_are_read_anew(tmp_path, monkeypatch, request):
    """field_docs reads each class's source once per process; a module reloaded after its file changed
    defines new classes, and their docstrings (not the first class's) are what it gives."""
    source = tmp_path / "docs_anew_mod.py"

    def write(doc: str) -> None:
        source.write_text(
            f'from dataclasses import dataclass\n\n@dataclass\nclass S:\n    x: int = 1\n    """{doc}"""\n'
        )

    monkeypatch.syspath_prepend(str(tmp_path))
    write("first meaning")
    mod = importlib.import_module("docs_anew_mod")
    request.addfinalizer(lambda: sys.modules.pop("docs_anew_mod", None))  # passed or not
    assert field_docs(mod.S) == {"x": "first meaning"}
    write("second meaning")
    linecache.checkcache(str(source))
    mod = importlib.reload(mod)
    assert field_docs(mod.S) == {"x": "second meaning"}


def test_cli_show_prints_values_defaults_and_meaning(capsys):
    assert cli_main(["show", "noise=crosstalk", "noise.alpha=0.3"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("noise: CrosstalkNoise")
    assert "0.3" in out and "[changed; default 0.1]" in out and "neighbour" in out
    assert cli_main(["show", "--group", "nosuch"]) == 2


def test_every_schema_class_is_named_schema():
    """A config group's schemas are ``*Schema`` dataclasses, as the style of the package names them."""
    from sphri.config import Schema

    found = {}
    for m in SCHEMA_MODULES:
        mod = importlib.import_module(m)
        for name, obj in vars(mod).items():
            if isinstance(obj, type) and issubclass(obj, Schema) and obj.__module__ == m and obj.__name__ == name:
                found[f"{m}.{name}"] = obj
    assert "sphri.tracking.schema.MlflowTrackingSchema" in found
    odd = sorted(k for k in found if not k.endswith("Schema"))
    assert not odd, f"schema classes not named *Schema: {odd}"
