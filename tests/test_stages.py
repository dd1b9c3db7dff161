"""The stage table (sphri.stages) drives the runner: keys from its inputs, no read outside them."""

import pytest
import yaml

from sphri.cache import StageCache
from sphri.config import CONF_DIR, SCHEMA_MODULES, STAGE_GROUPS, STAGE_METHODS, compose
from sphri.pipeline import Pipeline, make_pipeline
from sphri.stages import COMPONENTS, CONTRACTS, PERSISTED, STAGES, stage_inputs, upstream

STUDY = {"sessions", "body_contact"}  # the scenario study's rows


def test_config_defaults_list_every_group_of_the_table():
    defaults = yaml.safe_load((CONF_DIR / "config.yaml").read_text())["defaults"]
    groups = [next(iter(d)) for d in defaults if isinstance(d, dict) and next(iter(d)) in STAGE_GROUPS]
    assert groups == [g for g in STAGE_GROUPS if g in groups] and set(groups) == set(STAGE_GROUPS)
    assert set(STAGE_METHODS) == set(STAGE_GROUPS)
    assert all(c.schema_module in SCHEMA_MODULES for c in COMPONENTS)


def test_the_pipeline_has_the_tables_stages_with_keys_from_their_inputs(tmp_path):
    cfg = compose(["+debug=fast"])
    p = make_pipeline(cfg, StageCache(root=tmp_path, enabled=False))
    assert p.nodes == {}, "nothing is wired before it is asked for"
    p.key("evaluate")
    # a gesture job wires the chain, in table order, and never the study's rows
    assert list(p.nodes) == [s.name for s in STAGES if s.name not in STUDY]
    assert {n for n, node in p.nodes.items() if node.persist} == set(PERSISTED) - STUDY == set(CONTRACTS)
    # what each stage may read is exactly its table closure
    comps = p.components
    for s in STAGES:
        if s.name in p.nodes:
            assert p.nodes[s.name].reads == upstream(s.name, comps), s.name
    # changing a stage's config changes it and everything downstream, nothing upstream
    q = make_pipeline(compose(["+debug=fast", "window.frames=40"]), StageCache(root=tmp_path, enabled=False))
    changed = {n for n in p.nodes if p.nodes[n].key != q.key(n)}
    assert changed == {"plan", "encode", "noise", "filter", "evaluate"}


def test_the_study_wires_only_its_rows_of_the_one_table(tmp_path):
    """The scenario study's sessions and whole-body contacts are rows of STAGES, with their compute in the one
    registry (declared by the module the row names): its pipeline keys and builds nothing of the gesture chain."""
    from sphri.pipeline import COMPUTE

    cfg = compose(["+experiment=scenario_study", "+debug=fast"])
    p = make_pipeline(cfg, StageCache(root=tmp_path, enabled=False))
    p.key("body_contact")
    assert list(p.nodes) == ["hand", "robot", "sessions", "body_contact"]
    assert sorted(p.components) == ["contact", "data", "hand", "robot"]
    assert STUDY <= set(COMPUTE) and all(
        s.compute_module == "sphri.sessions.labelling" for s in STAGES if s.name in STUDY
    )
    assert p.nodes["body_contact"].reads == {"sessions", "robot", "hand"} == upstream("body_contact", p.components)


def test_optional_inputs_follow_the_components_capabilities():
    data = next(s for s in STAGES if s.name == "data")
    layout = next(s for s in STAGES if s.name == "layout")

    class Recorded:
        USES_ROBOT = False

    class ByDensity:
        uses_contacts = True

    assert stage_inputs(data, object()) == ("hand", "robot")
    assert stage_inputs(data, Recorded()) == ("hand",)
    assert stage_inputs(layout, object()) == ("surface", "robot")
    assert stage_inputs(layout, ByDensity()) == ("surface", "robot", "contact")


def test_a_stage_that_reads_outside_its_inputs_is_refused(tmp_path):
    p = Pipeline(cfg=None, cache=StageCache(root=tmp_path, enabled=False))
    p.add("hand", {}, lambda: "hand")
    p.add("robot", {}, lambda: p.get("hand"))  # robot's row has no inputs: its key ignores the hand
    with pytest.raises(RuntimeError, match="'robot' read stage 'hand'"):
        p.get("robot")
    p.add("data", {}, lambda: (p.get("hand"), p.get("robot")))
    p.nodes["robot"].compute = lambda: "robot"
    assert p.get("data") == ("hand", "robot")
    with pytest.raises(RuntimeError, match="declared before its inputs"):
        Pipeline(cfg=None, cache=StageCache(root=tmp_path, enabled=False)).add("contact", {}, lambda: None)
