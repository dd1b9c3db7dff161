"""Every YAML of the surface, layout, encoder, noise, filter and window groups matches its schema and builds."""

from __future__ import annotations

from pathlib import Path

import pytest
from hydra.core.config_store import ConfigStore
from hydra.utils import instantiate
from omegaconf import OmegaConf

import sphri.encode.schema  # noqa: F401  (registers the schemas)
import sphri.filter.schema  # noqa: F401
import sphri.layout.schema  # noqa: F401
import sphri.noise.schema  # noqa: F401
import sphri.surface.schema  # noqa: F401
import sphri.window.schema  # noqa: F401
from sphri.config import CONF_DIR, ConfigError

GROUPS = ("surface", "layout", "encoder", "noise", "filter", "window")
YAMLS = sorted(p for g in GROUPS for p in (CONF_DIR / g).glob("*.yaml"))


def compose_one(path: Path, **overrides):
    raw = OmegaConf.load(path)
    defaults = list(raw.pop("defaults"))
    assert defaults[-1] == "_self_" and defaults[0] == f"/schema_{path.parent.name}_{path.stem}@_here_"
    schema = ConfigStore.instance().load(f"schema_{path.parent.name}_{path.stem}.yaml").node
    cfg = OmegaConf.merge(schema, raw, OmegaConf.create(overrides))
    cfg = OmegaConf.create({"seed": 0, "component": cfg}).component  # under a root: `seed: ${seed}` resolves
    OmegaConf.to_object(cfg)  # runs the schema's range checks
    return cfg


def test_every_group_has_configs():
    names = {(p.parent.name, p.stem) for p in YAMLS}
    for want in [
        ("surface", "cylinder"),
        ("surface", "box"),
        ("surface", "mesh"),
        ("layout", "grid"),
        ("layout", "hex"),
        ("layout", "random"),
        ("layout", "density"),
        ("layout", "file"),
        ("encoder", "ellipse"),
        ("encoder", "coverage"),
        ("encoder", "proximity"),
        ("noise", "salt_pepper"),
        ("noise", "gaussian"),
        ("noise", "dead_taxels"),
        ("noise", "crosstalk"),
        ("noise", "none"),
        ("filter", "none"),
        ("filter", "debounce"),
        ("filter", "median"),
        ("filter", "despeckle"),
        ("window", "onset"),
    ]:
        assert want in names


@pytest.mark.parametrize("path", YAMLS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_yaml_matches_schema_and_instantiates(path):
    cfg = compose_one(path)
    obj = instantiate(cfg)
    assert type(obj).__module__ + "." + type(obj).__name__ == cfg._target_
    assert isinstance(obj.VERSION, str) and obj.VERSION  # part of every cache key
    if path.parent.name == "layout":  # the chain's resolution: every layout is given it
        assert 1 <= cfg.res <= 1000
    if path.parent.name == "encoder":  # the resolution is the layout's, never an encoder's
        assert "res" not in cfg


@pytest.mark.parametrize(
    "path,key,value",
    [
        ("layout/grid.yaml", "res", 0),
        ("encoder/proximity.yaml", "intensity", "loud"),
        ("noise/salt_pepper.yaml", "p", 1.5),
        ("window/onset.yaml", "frames", 0),
        ("filter/debounce.yaml", "frames", 0),
        ("filter/median.yaml", "frames", 4),
        ("filter/despeckle.yaml", "min_area_mm2", -1.0),
        ("layout/grid.yaml", "aspect", -1.0),
        ("surface/cylinder.yaml", "axis", "w"),
    ],
)
def test_bad_values_name_the_key(path, key, value):
    with pytest.raises(ConfigError, match=rf"\.{key}="):
        compose_one(CONF_DIR / path, **{key: value})


def test_unknown_key_is_refused():
    with pytest.raises(Exception, match="resolution"):
        compose_one(CONF_DIR / "encoder/ellipse.yaml", resolution=3)
