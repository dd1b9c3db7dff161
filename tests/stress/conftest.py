"""Stress suite settings and fixtures.

Hypothesis profiles: ``ci`` (the default, 25 examples per property, so
``make test`` stays fast) and ``deep`` (500 examples), loaded when
``SPHRI_DEEP_TESTS=1`` (``make test-all``). Tests here take their example
counts from the profile; they never set ``max_examples`` themselves.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings
from stress_fixtures import LINK_NAMES, degenerate_for, make_link, robot_of

from sphri.contact.exact import ExactContact

DEEP = bool(os.environ.get("SPHRI_DEEP_TESTS"))

settings.register_profile(
    "ci", max_examples=25, deadline=None, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "deep", max_examples=500, deadline=None, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile("deep" if DEEP else "ci")


@pytest.fixture(scope="session")
def links():
    """The degenerate links by name (:data:`stress_fixtures.LINK_NAMES`)."""
    return {name: make_link(name) for name in LINK_NAMES}


@pytest.fixture(scope="session")
def degenerate(links):
    """Per link name: (dataset, robot, contacts) of :func:`stress_fixtures.degenerate_dataset`."""
    out = {}
    for name, link in links.items():
        ds = degenerate_for(name)
        robot = robot_of(link)
        out[name] = (ds, robot, ExactContact().compute(ds, robot))
    return out
