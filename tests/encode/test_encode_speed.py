"""Full-size encoding speed (144,000 frames): res 18 under 5 s, res 50 under 15 s on 2 cores."""

from __future__ import annotations

import time

import numpy as np
import pytest

from sphri.encode.ellipse import EllipseEncoder
from sphri.testing.synthetic_contacts import synthetic_contacts
from sphri.layout.grid import GridLayout


FRAMES = 2880 * 50


@pytest.fixture(scope="module")
def full_contacts(cyl_link):
    return synthetic_contacts(cyl_link, FRAMES, contact_fraction=0.7, seed=0)


@pytest.mark.slow
@pytest.mark.parametrize("res,budget_s", [(18, 5.0), (50, 15.0)])
def test_full_size_encoding_time(cyl_link, cyl_map, full_contacts, res, budget_s):
    frames = FRAMES
    contacts = full_contacts
    layout = GridLayout().build(cyl_link, cyl_map, res)
    enc = EllipseEncoder(res=res)
    fi = np.arange(frames, dtype=np.int64)
    enc.encode(contacts, cyl_link, cyl_map, layout, fi[:1000])  # compile
    t0 = time.perf_counter()
    out = enc.encode(contacts, cyl_link, cyl_map, layout, fi)
    elapsed = time.perf_counter() - t0
    assert out.values.shape == (frames, layout.n_taxels) and out.values.any()
    assert elapsed < budget_s, f"res {res}: {elapsed:.2f} s"
