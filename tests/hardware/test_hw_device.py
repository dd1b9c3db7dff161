"""Tests on real hardware: skipped unless SPHRI_SKIN_PORT / SPHRI_GLOVE_PORT name a device.

SPHRI_SKIN_PORT=/dev/ttyACM0 pytest -m hardware tests/hardware
SPHRI_GLOVE_PORT=/dev/rfcomm0 pytest -m hardware tests/hardware
"""

from __future__ import annotations

import numpy as np
import pytest

from sphri.hardware.glove import GloveDriver
from sphri.hardware.skin import SkinReader
from sphri.hardware.transport import Link

pytestmark = pytest.mark.hardware


def test_real_skin_streams_valid_frames(skin_port):
    with SkinReader(skin_port, reconnect=False) as reader:
        frames = [rf.frame for rf in reader.frames(max_frames=100, duration_s=10.0)]
    assert len(frames) == 100, f"only {len(frames)} frames in 10 s; decoder: {reader.stats.line()}"
    n = {f.n_taxels for f in frames}
    assert len(n) == 1
    values = np.stack([f.values for f in frames])
    assert values.min() >= 0 and values.max() <= 1
    # a healthy link: no more than 1 % of the frames broken
    assert reader.stats.errors <= 1, reader.stats.line()


def test_real_glove_acknowledges(glove_port):
    with Link(glove_port, 115200) as link:
        driver = GloveDriver(link, glove_id=1, acks=True, ack_timeout_s=0.5)
        driver.send((0, 80, 0, 0, 0, 0), (0, 50, 0, 0, 0, 0))
        driver.send((0,) * 6, (0,) * 6)
        report = driver.finish()
    assert report.acked == 2, report.lines()
