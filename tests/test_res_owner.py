"""``encoder.res`` has one owner (issue 30, point 2): the encoder group's base schema declares it and its
check, the chain reads it through ``sphri.encode.schema.grid_res``, no encoder is given it, and what
earlier sweeps recorded (the ``encoder.res`` param, the config hash) still matches."""

import re
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from sphri.config import ConfigError, build, compose, result_config
from sphri.encode.schema import DEFAULT_RES, check_res, grid_res
from sphri.integrity import stable_hash

SPHRI = Path(__file__).resolve().parents[1] / "sphri"


def test_only_the_owner_reads_cfg_encoder_res():
    readers = [
        f"{p.relative_to(SPHRI.parent)}:{i}"
        for p in sorted(SPHRI.rglob("*.py"))
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if re.search(r"cfg\.encoder\.res\b", line)
    ]
    assert readers and all(r.startswith("sphri/encode/schema.py:") for r in readers), readers


@pytest.mark.parametrize("encoder", ["ellipse", "coverage", "proximity"])
def test_every_encoder_gets_res_from_the_owner_and_is_not_given_it(encoder):
    cfg = compose([f"encoder={encoder}", "encoder.res=7", "layout=grid" if encoder == "ellipse" else "layout=random"])
    assert grid_res(cfg) == 7 and cfg.encoder.res == 7
    component = build(cfg.encoder)
    assert not hasattr(component, "res") and "res=" not in repr(component)


def test_the_one_check_names_encoder_res_and_who_read_it():
    with pytest.raises(ConfigError, match=r"^encoder\.res=0 is invalid: must be an integer in \[1, 1000\]$"):
        compose(["encoder.res=0"])
    with pytest.raises(
        ConfigError, match=r"encoder\.res=2\.5 is invalid: must be an integer.*\(read by layout\.grid\)"
    ):
        check_res(2.5, "layout.grid")
    assert check_res(18.0) == 18


def test_a_plugin_encoder_without_a_schema_gets_the_default_resolution():
    cfg = compose([])
    OmegaConf.set_struct(cfg, False)
    cfg.encoder = OmegaConf.create({"_target_": "labext.skin.NearestTaxelEncoder"})
    assert grid_res(cfg) == DEFAULT_RES


#: What main 7fe8a41 (before encoder.res had its owner) made of these configs: the stable hash of the
#: encoder's and the layout's result config, which the config hash of a job (MLflow's ``sphri.config_hash``,
#: how a resumed sweep finds its finished runs) is made of, and the ``encoder.res`` param the report reads.
BEFORE = {
    "encoder.res=4": ("8a8e7bcbef6909747ff7", "9b4a56fd39f2ca209be0"),
    "": ("ac278eca12b2fa579b4c", "9b4a56fd39f2ca209be0"),
}


@pytest.mark.parametrize("override", sorted(BEFORE))
def test_earlier_sweeps_still_resume(override):
    cfg = compose([override] if override else [])
    encoder, layout = BEFORE[override]
    assert stable_hash(result_config(cfg.encoder)) == encoder
    assert stable_hash(result_config(cfg.layout)) == layout


def test_an_old_run_record_is_found_by_its_param_and_hash(tmp_path):
    """A FINISHED job recorded as earlier sweeps recorded it (param ``encoder.res``, tag
    ``sphri.config_hash``) is found by the resume lookup of today's config, and its param read back."""
    from sphri.pipeline import config_hash
    from sphri.tracking.mlflow_tracker import MlflowTracker, flatten_params

    cfg = compose(["+debug=fast", "encoder.res=4"])
    params = flatten_params(cfg)
    assert params["encoder.res"] == "4"
    tracker = MlflowTracker(experiment="resume-test")
    client = tracker.client(str(tmp_path))
    run = client.create_run(tracker.experiment_id(str(tmp_path)))
    client.log_param(run.info.run_id, "encoder.res", "4")
    client.set_tag(run.info.run_id, "sphri.config_hash", config_hash(cfg))
    client.set_tag(run.info.run_id, "sphri.kind", "job")
    client.set_terminated(run.info.run_id, "FINISHED")
    assert tracker.find_finished(str(tmp_path), config_hash(cfg)) == run.info.run_id
    assert tracker.find_finished(str(tmp_path), config_hash(compose(["+debug=fast", "encoder.res=5"]))) is None
    assert client.get_run(run.info.run_id).data.params["encoder.res"] == "4"
