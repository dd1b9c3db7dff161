"""Fixtures of the coverage tests (helpers live in coverage_fixtures.py)."""

from __future__ import annotations

import pytest
from coverage_fixtures import Study, make_study


@pytest.fixture(scope="session")
def study() -> Study:
    return make_study()
