"""Fixtures of the report tests: one MLflow store per session, a two-model fake sweep."""

from __future__ import annotations

from pathlib import Path

import pytest
from fake_sweep import FakeSweep, make_sweep


@pytest.fixture(scope="session")
def store(tmp_path_factory) -> Path:
    """One MLflow output_dir shared by every fake sweep of the session."""
    return tmp_path_factory.mktemp("store")


@pytest.fixture(scope="session")
def two_model_sweep(store, tmp_path_factory) -> FakeSweep:
    """rf and cnn_gru over 8 resolutions, 8 participants, SYNTHETIC; cnn_gru fails at res 36."""
    return make_sweep(
        store,
        tmp_path_factory.mktemp("two_models"),
        [1, 2, 3, 4, 6, 9, 18, 36],
        models=["rf", "cnn_gru"],
        top={"rf": 0.85, "cnn_gru": 0.75},
        fail={("cnn_gru", 36)},
    )
