"""conf/cv/*.yaml compose and instantiate; bad values name their key."""

from __future__ import annotations

import pytest
from hydra.utils import instantiate

from sphri.config import ConfigError, compose
from sphri.evaluate.cv import LeaveOneSubjectOut, WithinSubjectKFold
from sphri.evaluate.schema import KFoldSchema, LosoSchema


@pytest.mark.parametrize("name,cls", [("loso", LeaveOneSubjectOut), ("kfold", WithinSubjectKFold)])
def test_cv_yaml_instantiates(name, cls):
    cv = instantiate(compose([f"cv={name}", "cv.workers=2", "cv.max_folds=3"]).cv)
    assert isinstance(cv, cls) and cv.SCHEME == name and cls.VERSION == "1"
    assert cv.workers == 2 and cv.max_folds == 3


def test_bad_value_fails_at_composition():
    with pytest.raises(ConfigError, match="cv.workers"):
        compose(["cv.workers=0"])


@pytest.mark.parametrize(
    "schema,kwargs,key",
    [
        (LosoSchema, {"workers": 0}, "cv.workers"),
        (LosoSchema, {"max_folds": 0}, "cv.max_folds"),
        (LosoSchema, {"threads_per_worker": 0}, "cv.threads_per_worker"),
        (KFoldSchema, {"k": 1}, "cv.k"),
    ],
)
def test_cv_schema_ranges(schema, kwargs, key):
    with pytest.raises(ConfigError, match=key):
        schema(**kwargs)
