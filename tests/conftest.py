"""Shared fixtures: ../shared (skipped when absent), temporary output dirs."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("SPHRI_SHARED", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder with the real study's assets; skips the test when absent."""
    if not (SHARED / "vr-gesture-dataset").is_dir():
        pytest.skip(f"../shared not present at {SHARED}")
    return SHARED
