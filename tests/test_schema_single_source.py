"""Defaults and docs live once, in the schemas: component YAMLs hold the choice and what differs."""

import dataclasses
import importlib

import pytest
import yaml
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from sphri.cli import main as cli_main
from sphri.config import CONF_DIR, SCHEMA_MODULES, field_docs

#: Groups whose YAML files are the choice plus what differs from the schema. data, robot and hand
#: files stay full tables on purpose: the synthetic study's assumptions with their sources, robot
#: and hand definitions.
TRIMMED = ("contact", "cv", "encoder", "filter", "layout", "noise", "surface", "window", "tracking", "model")


def schema_of(group: str, path) -> type:
    for m in SCHEMA_MODULES:
        importlib.import_module(m)
    d = yaml.safe_load(path.read_text())
    entry = next(x for x in d["defaults"] if isinstance(x, str) and x.startswith(f"/schema_{group}_"))
    return OmegaConf.get_type(ConfigStore.instance().repo[entry[1:].removesuffix("@_here_") + ".yaml"].node)


FILES = [(g, p) for g in TRIMMED for p in sorted((CONF_DIR / g).glob("*.yaml"))]


@pytest.mark.parametrize("group,path", FILES, ids=[f"{g}/{p.stem}" for g, p in FILES])
def test_component_yaml_holds_only_what_differs_and_the_schema_documents_every_field(group, path):
    schema = schema_of(group, path)
    default = OmegaConf.to_container(OmegaConf.structured(schema))
    values = yaml.safe_load(path.read_text())
    same = [k for k, v in values.items() if k not in ("defaults", "_target_") and k in default and default[k] == v]
    assert not same, f"{path.name}: {same} repeat the schema's defaults"
    docs = field_docs(schema)
    undocumented = [f.name for f in dataclasses.fields(schema) if f.name != "_target_" and not docs.get(f.name)]
    assert not undocumented, f"{schema.__name__}: fields without a docstring: {undocumented}"


def test_field_docs_include_inherited_fields():
    from sphri.evaluate.schema import KFoldSchema
    from sphri.layout.schema import HexLayoutSchema

    assert "parallel processes" in field_docs(KFoldSchema)["workers"] and "folds" in field_docs(KFoldSchema)["k"]
    assert set(field_docs(HexLayoutSchema)) >= {"aspect", "seed"}


def test_cli_show_prints_values_defaults_and_meaning(capsys):
    assert cli_main(["show", "noise=crosstalk", "noise.alpha=0.3"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("noise: CrosstalkNoise")
    assert "0.3" in out and "[changed; default 0.1]" in out and "neighbour" in out
    assert cli_main(["show", "--group", "nosuch"]) == 2
