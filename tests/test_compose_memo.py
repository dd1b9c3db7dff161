"""``sphri.config.compose`` composes each set of structural overrides once per process and sets plain
values on a copy (``_ComposeMemo``): the configs and the one-line errors must be Hydra's own, and an
edited config file or a node stored again must be seen."""

from __future__ import annotations

import subprocess
import sys

import pytest
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf, open_dict

from sphri.config import ConfigError, _explain, compose, compose_with_hydra, normalize_overrides, validate

SAME = [
    [],
    ["+debug=fast"],
    ["+debug=fast", "layout.res=7", "seed=3"],
    ["model=cnn_gru", "model.channels=[8,8]", "layout.res=6"],
    ["+debug=fast", "data.participants=5"],  # a value the debug preset sets: the override wins, as in Hydra
    ["data.participants=5", "+debug=fast"],  # ... in either order
    ["encoder=coverage", "layout.res=2"],
    ["output_dir=/tmp/a b", "tracking.enabled=false"],
    ["seed=${oc.env:HOME}"],  # an interpolation stays one
    ["experiment=requirement_sensitivity_quick", "sensitivity=noise0", "model.n_estimators=9"],
]


@pytest.mark.parametrize("overrides", SAME, ids=lambda o: " ".join(o) or "defaults")
def test_a_memo_composition_is_hydras(overrides):
    ours = compose(overrides, check=False)
    again = compose(overrides, check=False)  # from the memo
    hydras = compose_with_hydra("config", normalize_overrides(overrides))
    for cfg in (ours, again):
        assert OmegaConf.to_yaml(cfg) == OmegaConf.to_yaml(hydras)
        assert OmegaConf.is_struct(cfg) and OmegaConf.is_struct(hydras)


BAD = [
    ["layout.res=abc"],
    ["+debug=fast", "layout.res=1.5"],
    ["model.lr=0.1"],
    ["nokey=1"],
    ["encoder.rez=4"],
    ["seed=true"],
    ["data.participants=[1,2]"],
    ["model.n_estimators=null"],
    ["data={a:1}"],
    ["+seed2=1"],
    ["+debug=fast", "~data.participants"],
]


@pytest.mark.parametrize("overrides", BAD, ids=" ".join)
def test_a_refused_value_says_what_hydra_says(overrides):
    compose(["+debug=fast"])  # a memo entry for the same structure
    with pytest.raises(ConfigError) as ours:
        compose(overrides)
    try:
        validate(compose_with_hydra("config", normalize_overrides(overrides)))
    except ConfigError as exc:
        hydras = str(exc)
    except Exception as exc:  # noqa: BLE001 - Hydra's types, said as sphri says them
        hydras = _explain(exc)
    else:
        pytest.fail(f"Hydra composed {overrides}")
    assert str(ours.value) == hydras


def test_each_call_gets_its_own_config():
    first = compose(["+debug=fast", "seed=4"])
    with open_dict(first):
        first.data.participants = 99
        first.extra = 1
    second = compose(["+debug=fast", "seed=4"])
    assert second.data.participants == 3 and "extra" not in second


def test_an_edited_config_file_is_read_again(tmp_path):
    (tmp_path / "encoder").mkdir()
    mine = tmp_path / "encoder" / "mine.yaml"
    mine.write_text("defaults:\n  - /schema_encoder_ellipse@_here_\n  - _self_\nsubsamples: 3\n")
    search = f"hydra.searchpath=[file://{tmp_path}]"
    assert compose([search, "encoder=mine", "layout.res=5"]).encoder.subsamples == 3
    mine.write_text("defaults:\n  - /schema_encoder_ellipse@_here_\n  - _self_\nsubsamples: 4\n")
    assert compose([search, "encoder=mine", "layout.res=5"]).encoder.subsamples == 4


def test_a_node_stored_again_is_seen():
    store = ConfigStore.instance()
    store.store(name="memo_probe", node={"seed": 11})
    try:
        assert compose([], config_name="memo_probe", check=False).seed == 11
        store.store(name="memo_probe", node={"seed": 12})
        assert compose([], config_name="memo_probe", check=False).seed == 12
    finally:
        store.repo.pop("memo_probe.yaml", None)


def test_a_new_process_composes_a_structure_once():
    """Hydra stores its own nodes in the ConfigStore at a process's first composition: the memo's key is
    taken after it, so the second configuration of the same structure is not composed again."""
    code = (
        "import sphri.config as c\n"
        "calls = []\n"
        "hydra = c.compose_with_hydra\n"
        "c.compose_with_hydra = lambda *a: calls.append(a) or hydra(*a)\n"
        "assert c.compose(['+debug=fast', 'seed=1']).seed == 1\n"
        "assert c.compose(['+debug=fast', 'seed=2']).seed == 2\n"
        "print(len(calls))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["1"]


def test_the_memo_keeps_its_size_dropping_the_least_recently_used():
    from sphri.config import _ComposeMemo, register_schemas

    register_schemas()
    memo = _ComposeMemo(size=2)
    for overrides in (["encoder=coverage"], ["model=cnn_gru"], ["encoder=coverage"], ["noise=none"]):
        memo.compose("config", overrides)
    kept = [key[1] for key in memo.bases]
    assert kept == [("encoder=coverage",), ("noise=none",)], kept  # model=cnn_gru: least recently used
