"""conf/model/*.yaml compose, instantiate to estimators, and bad values name their key."""

from __future__ import annotations

import dataclasses

import pytest
from hydra.utils import instantiate

from sphri.config import ConfigError, compose
from sphri.models.cnn_gru import CnnGru
from sphri.models.rf import RandomForest
from sphri.models.schema import CnnGruSchema, RandomForestSchema
from sphri.testing.toy_windows import arm_geometry


@pytest.mark.parametrize("name,cls", [("rf", RandomForest), ("cnn_gru", CnnGru)])
def test_model_yaml_instantiates_with_geometry(name, cls):
    cfg = compose([f"model={name}", "seed=7"])
    geom = arm_geometry(3)
    est = instantiate(cfg.model, _partial_=True, _convert_="all")(geometry=geom)
    assert isinstance(est, cls)
    assert est.seed == 7  # the model follows the run's seed
    assert est.geometry is geom
    assert cls.VERSION == {"rf": "1", "cnn_gru": "4"}[name] and cls.NAME == name
    # the YAML holds every schema field, and the estimator takes exactly those
    schema = RandomForestSchema if name == "rf" else CnnGruSchema
    fields = {f.name for f in dataclasses.fields(schema)} - {"_target_"}
    assert set(cfg.model) - {"_target_"} == fields
    assert set(est.get_params()) == fields | {"geometry"}


def test_bad_values_fail_at_composition():
    with pytest.raises(ConfigError, match="model.n_estimators"):
        compose(["model=rf", "model.n_estimators=0"])
    with pytest.raises(ConfigError, match="model.strides"):
        compose(["model=cnn_gru", "model.strides=[1,1]"])


@pytest.mark.parametrize(
    "schema,kwargs,key",
    [
        (RandomForestSchema, {"n_estimators": 0}, "model.n_estimators"),
        (RandomForestSchema, {"max_depth": 0}, "model.max_depth"),
        (RandomForestSchema, {"max_features": "all"}, "model.max_features"),
        (RandomForestSchema, {"class_weight": "heavy"}, "model.class_weight"),
        (RandomForestSchema, {"n_jobs": 0}, "model.n_jobs"),
        (RandomForestSchema, {"active_threshold": 0.0}, "model.active_threshold"),
        (CnnGruSchema, {"lr": 0.0}, "model.lr"),
        (CnnGruSchema, {"val_fraction": 1.0}, "model.val_fraction"),
        (CnnGruSchema, {"strides": [1, 1]}, "model.strides"),
        (CnnGruSchema, {"channels": []}, "model.channels"),
        (CnnGruSchema, {"device": "tpu"}, "model.device"),
        (CnnGruSchema, {"precision": "fp8"}, "model.precision"),
        (CnnGruSchema, {"hidden": 0}, "model.hidden"),
        (CnnGruSchema, {"patience": 0}, "model.patience"),
    ],
)
def test_schema_ranges(schema, kwargs, key):
    with pytest.raises(ConfigError, match=key):
        schema(**kwargs)
