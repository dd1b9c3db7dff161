"""Every component's effective defaults are its schema's (issue 30, "declared once"): the YAML merged onto
the schema changes only what the YAML writes, and the component's constructor takes exactly the schema's
settings with the schema's defaults (a ``Configured`` component takes them from its schema; any other
states them in its signature, where a drifted default fails here)."""

import dataclasses
import inspect

import pytest
import yaml
from hydra.core.config_store import ConfigStore
from hydra.utils import get_class
from omegaconf import OmegaConf

from sphri.config import CONF_DIR, Configured, compose, register_schemas

#: Constructor parameters that are not settings: what the chain hands a component besides its config.
NOT_SETTINGS = {"geometry"}


def components() -> list[tuple[str, str]]:
    """``(group, name)`` of every YAML of a stage group that opts into a schema."""
    register_schemas()
    out = []
    for path in sorted(CONF_DIR.glob("*/*.yaml")):
        defaults = (yaml.safe_load(path.read_text()) or {}).get("defaults", [])
        if any(isinstance(d, str) and d.startswith(f"/schema_{path.parent.name}_") for d in defaults):
            out.append((path.parent.name, path.stem))
    return out


def schema_of(group: str, name: str) -> type:
    defaults = yaml.safe_load((CONF_DIR / group / f"{name}.yaml").read_text())["defaults"]
    entry = next(d for d in defaults if isinstance(d, str) and d.startswith(f"/schema_{group}_"))
    return OmegaConf.get_type(ConfigStore.instance().repo[entry[1:].removesuffix("@_here_") + ".yaml"].node)


def schema_defaults(schema: type) -> dict:
    node = OmegaConf.structured(schema)
    return {k: OmegaConf.to_container(node, resolve=False)[k] for k in node.keys()}


def same(a, b) -> bool:
    """Equal as settings: a tuple default and the schema's list are the same value."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


COMPONENTS = components()


def test_every_stage_group_has_components_with_schemas():
    groups = {g for g, _ in COMPONENTS}
    assert {"encoder", "layout", "noise", "filter", "window", "model", "cv", "contact", "surface"} <= groups


@pytest.mark.parametrize("group,name", COMPONENTS, ids=[f"{g}/{n}" for g, n in COMPONENTS])
def test_component_defaults_are_the_schema_defaults(group: str, name: str):
    schema = schema_of(group, name)
    default = schema_defaults(schema)
    written = {k for k in (yaml.safe_load((CONF_DIR / group / f"{name}.yaml").read_text()) or {}) if k != "defaults"}
    cfg = compose([f"{group}={name}"], check=False)
    effective = OmegaConf.to_container(cfg[group], resolve=False)
    drift = {k: (effective.get(k), v) for k, v in default.items() if k not in written and effective.get(k) != v}
    assert not drift, f"{group}={name}: composed values differ from the schema without the YAML saying so: {drift}"
    assert OmegaConf.get_type(cfg[group]) is schema
    cls = get_class(default["_target_"])
    settings = {f.name for f in dataclasses.fields(schema)} - {"_target_"}
    if isinstance(cls, type) and issubclass(cls, Configured):
        assert issubclass(schema, cls.SCHEMA), f"{cls.__name__}.SCHEMA is {cls.SCHEMA.__name__}, the YAML's {schema}"
        return
    params = {
        p.name: p
        for p in list(inspect.signature(cls.__init__).parameters.values())[1:]
        if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL) and (p.name in settings or p.name not in NOT_SETTINGS)
    }
    takes_more = any(p.kind is p.VAR_KEYWORD for p in inspect.signature(cls.__init__).parameters.values())
    assert set(params) <= settings, f"{cls.__name__} takes {sorted(set(params) - settings)}, not settings of {schema}"
    missing = settings - set(params)
    assert takes_more or not missing, f"{cls.__name__} does not take {sorted(missing)} of {schema.__name__}"
    drifted = {
        k: (p.default, default[k])
        for k, p in params.items()
        if p.default is not inspect.Parameter.empty and not same(p.default, default[k]) and default[k] != "???"
    }
    assert not drifted, f"{cls.__name__}'s defaults (constructor, schema) drifted: {drifted}"


def test_a_drifted_constructor_default_is_caught(monkeypatch):
    """The check above fails on a component whose constructor default differs from its schema."""
    from sphri.models.rf import RandomForest

    sig = inspect.signature(RandomForest.__init__)
    params = [p.replace(default=7) if p.name == "n_estimators" else p for p in sig.parameters.values()]
    monkeypatch.setattr(RandomForest.__init__, "__signature__", sig.replace(parameters=params), raising=False)
    with pytest.raises(AssertionError, match="n_estimators"):
        test_component_defaults_are_the_schema_defaults("model", "rf")


def test_schemas_are_never_choices_and_hydra_is_not_patched():
    """Each group's options are its YAML files (the schemas are root-level ``schema_<group>_<name>``
    entries), as Hydra itself lists them: what completion and ``glob(...)`` sweeps see, with no patch
    of Hydra's loader."""
    from hydra import initialize_config_dir
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from hydra.core.global_hydra import GlobalHydra

    import sphri.__main__  # noqa: F401 - the app module, which used to patch the loader on import of main()

    original = ConfigLoaderImpl.get_group_options
    register_schemas()
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        loader = GlobalHydra.instance().config_loader()
        for group in sorted({g for g, _ in COMPONENTS}):
            assert loader.get_group_options(group) == sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))
    GlobalHydra.instance().clear()
    assert ConfigLoaderImpl.get_group_options is original and not hasattr(original, "_sphri_hides_schemas")
