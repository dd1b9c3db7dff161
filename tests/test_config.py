"""Every YAML under conf/ composes; wrong values fail at composition with the key named."""

from __future__ import annotations

from pathlib import Path

import pytest

from sphri.config import CONF_DIR, STAGE_GROUPS, ConfigError, compose, normalize_overrides, register_schemas

#: Components that need a value only a user can give; the test supplies one.
REQUIRED = {
    "robot/urdf": ["robot.path=/nonexistent/robot.urdf", "robot.links=[base_link]", "robot.regions={arm:base_link}"],
    "robot/mesh": ["robot.links={l_arm:/nonexistent/arm.obj}", "robot.regions={arm:l_arm}"],
    "robot/reachy_vr": ["data=vr_gesture", "data.root=/nonexistent/dataset"],
    "data/vr_gesture": ["data.root=/nonexistent/dataset"],
    "data/sessions": ["data.root=/nonexistent/sessions"],
    # irregular layouts and chartless surfaces need an encoder that works on any layout
    "layout/random": ["encoder=coverage"],
    "layout/density": ["encoder=coverage"],
    "layout/file": ["encoder=coverage", "layout.path=/nonexistent/taxels.npz"],
    "surface/mesh": ["encoder=coverage", "layout=random"],
}


def all_yaml() -> list[tuple[str, str]]:
    out = []
    for path in sorted(CONF_DIR.rglob("*.yaml")):
        rel = path.relative_to(CONF_DIR)
        if rel.parent == Path("."):
            continue
        out.append((str(rel.parent), rel.stem))
    return out


def overrides_for(group: str, name: str) -> list[str]:
    extra = REQUIRED.get(f"{group}/{name}", [])
    if group == "_debug_model":
        debug, model = name.split("_", 1)
        return [f"debug={debug}", f"model={model}"]
    return [f"{group}={name}", *extra]


def test_every_group_has_components():
    groups = {g for g, _ in all_yaml()}
    for group in (*STAGE_GROUPS, "debug", "experiment"):
        assert group in groups, f"conf/{group}/ has no YAML file"


@pytest.mark.parametrize("group,name", all_yaml(), ids=lambda x: str(x))
def test_every_yaml_composes_and_validates(group: str, name: str):
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir

    ov = overrides_for(group, name)
    if group.startswith("hydra/"):
        register_schemas()
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = hydra_compose("config", overrides=[f"{group}={name}"], return_hydra_config=True)
        assert cfg.hydra.launcher is not None
        return
    cfg = compose(ov)
    if group in STAGE_GROUPS:
        assert cfg[group]._target_.startswith("sphri.")


@pytest.mark.parametrize(
    "overrides,named",
    [
        (["layout=random"], "RandomLayout"),
        (["layout=density"], "DensityLayout"),
        (["surface=mesh", "layout=grid"], "MeshSurface"),
    ],
)
def test_grid_encoder_on_an_irregular_layout_fails_at_composition(overrides, named):
    with pytest.raises(ConfigError, match=rf"encoder=ellipse .* needs layout=grid\|hex .*{named}.*encoder=coverage"):
        compose(overrides)
    compose([*overrides, "encoder=coverage"])  # the suggested fix composes


def test_plus_and_plain_group_overrides_are_equivalent():
    assert normalize_overrides(["+robot=reachy", "layout.res=18", "+foo=1"]) == [
        "robot=reachy",
        "layout.res=18",
        "+foo=1",
    ]
    a = compose(["+robot=reachy", "layout.res=18"])
    b = compose(["robot=reachy", "layout.res=18"])
    assert a == b
    assert a.layout.res == 18


@pytest.mark.parametrize(
    "override,key",
    [
        ("layout.res=0", "layout.res"),
        ("layout.res=-3", "layout.res"),
        ("layout.res=abc", "layout.res"),
        ("noise.p=1.5", "noise.p"),
        ("window.frames=0", "window.frames"),
        ("encoder.no_such_key=1", "no_such_key"),
        ("robot=nonexistent", "robot"),
        ("data.regions=[arm,torso]", "data.regions"),
        ("seed=-1", "seed"),
        ("tracking.uri=nonsense", "tracking.uri"),
    ],
)
def test_wrong_values_fail_naming_the_key(override: str, key: str):
    from sphri.pipeline import chain_region

    with pytest.raises(ConfigError) as err:
        cfg = compose([override])
        chain_region(cfg)
    assert key in str(err.value), str(err.value)


def test_wrong_robot_lists_the_choices():
    with pytest.raises(ConfigError) as err:
        compose(["+robot=nonexistent"])
    msg = str(err.value)
    assert "nonexistent" in msg
