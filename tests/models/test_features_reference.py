"""The paper's 32 features are the reference (``model=rf``): their values must not drift.

``data/features_reference.json`` holds the features of fixed toy windows (a
wrapped grid and a scattered layout, with salt-and-pepper noise), recorded
before the spatial ``filter=despeckle`` was added. Any change to
:mod:`sphri.models.features` or :mod:`sphri.adjacency` that moves one of
them by more than floating-point rounding fails here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sphri.models.features import FEATURE_NAMES, extract_features
from sphri.testing.toy_windows import blob_windows

REFERENCE = json.loads((Path(__file__).parent / "data" / "features_reference.json").read_text())


def test_reference_names_are_the_32_features():
    assert tuple(REFERENCE["feature_names"]) == FEATURE_NAMES


@pytest.mark.parametrize("case", ["grid_res6", "scatter_res5"])
def test_features_of_fixed_windows_are_unchanged(case: str):
    ref = REFERENCE[case]
    w = blob_windows(**ref["blob_windows"])
    expected = np.array(ref["features"], dtype=np.float64)
    got = extract_features(w.x, w.geometry)
    assert got.shape == expected.shape == (16, 32)
    # the reference is not degenerate: every feature family varies over trials
    assert np.count_nonzero(expected.std(axis=0) > 0) >= 28
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
