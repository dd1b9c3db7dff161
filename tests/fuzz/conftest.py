"""Fixtures of the fuzz campaign (the machinery is in ``fuzz_support``)."""

from __future__ import annotations

import pytest
from fuzz_support import Tally


@pytest.fixture(scope="module")
def tally(request):
    """The counts of the module's target, named after it (``test_fuzz_data.py``: ``data``), written at its end."""
    t = Tally(request.module.__name__.rsplit(".", 1)[-1].removeprefix("test_fuzz_"))
    yield t
    t.write()
