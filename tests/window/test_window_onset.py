"""Onset windows: alignment, clip, pad, no-contact rule, assembly."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

from sphri.config import ConfigError
from sphri.testing.synthetic_contacts import make_contacts
from sphri.types import Frames, GestureDataset, HandModel, Layout, SurfaceMap
from sphri.window.onset import OnsetWindow, trial_onsets


def dataset(n_frames_per_trial, gestures=None):
    n = len(n_frames_per_trial)
    counts = np.asarray(n_frames_per_trial)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    gestures = gestures or ["hit", "pat", "poke", "push", "rub", "stroke", "tap", "grab"][:n]
    trials = pd.DataFrame(
        {
            "participant": [f"participant_{i % 2 + 1:02d}" for i in range(n)],
            "region": ["arm"] * n,
            "trial_ordinal": np.arange(1, n + 1),
            "trial_id": [f"{i + 1:04d}_{g}" for i, g in enumerate(gestures)],
            "gesture": gestures,
            "start": starts,
            "n_frames": counts,
        }
    )
    hand = HandModel(("wrist1",), ("palm",), np.array([0.01]), np.array([0.04]), np.array([0]), np.zeros((1, 3)))
    poses = np.zeros((int(counts.sum()), 1, 7), dtype=np.float32)
    return GestureDataset("toy", True, hand, trials, poses, 30.0)


def contacts_at(frames, n_frames):
    k = len(frames)
    return make_contacts(frames, np.zeros((k, 3)), np.tile([0, 0, 1.0], (k, 1)), np.full(k, 0.01), n_frames)


def toy_layout(n=4):
    lay = Layout(
        "grid", np.zeros((n, 3)), np.tile([0, 0, 1.0], (n, 1)), np.ones(n), np.zeros((n, 2)), (1, n), 0.01, 0.01
    )
    sm = SurfaceMap("cylinder", True, 0.24, 0.25, True, 0.0, {})
    return lay, sm


def test_alignment_clip_and_pad():
    # trial 0: 100 frames, contact from frame 10 (clipped to L); trial 1: 30 frames, contact from 25 (padded);
    # trial 2: 20 frames, no contact
    ds = dataset([100, 30, 20])
    c = contacts_at([10, 11, 60, 100 + 25, 100 + 29], ds.n_frames)
    plan = OnsetWindow(frames=50).plan(c, ds)
    np.testing.assert_array_equal(plan.onset, [10, 25, -1])
    np.testing.assert_array_equal(plan.kept, [True, True, False])
    np.testing.assert_array_equal(plan.frame_index[0], np.arange(10, 60))
    np.testing.assert_array_equal(plan.frame_index[1, :5], np.arange(125, 130))
    assert (plan.frame_index[1, 5:] == -1).all() and (plan.frame_index[2] == -1).all()
    sel = plan.selected_frames()
    assert len(sel) == 55 and sel[0] == 10 and sel[-1] == 129


def test_onset_is_per_trial():
    ds = dataset([10, 10, 10])
    # a contact in trial 0's last frame must not become trial 1's onset
    np.testing.assert_array_equal(trial_onsets(contacts_at([9, 25], ds.n_frames), ds), [9, -1, 5])


def test_assemble_places_frames_and_pads_with_zeros():
    ds = dataset([100, 30, 20])
    c = contacts_at([10, 125], ds.n_frames)
    win = OnsetWindow(frames=50)
    plan = win.plan(c, ds)
    sel = plan.selected_frames()
    lay, sm = toy_layout(4)
    values = np.repeat(sel[:, None].astype(np.float32), 4, axis=1)  # reading = its global frame
    w = win.assemble(Frames(values, (1, 4)), plan, ds, lay, sm)
    assert w.x.shape == (2, 50, 4) and w.x.dtype == np.float32
    np.testing.assert_array_equal(w.x[0, :, 0], np.arange(10, 60))
    np.testing.assert_array_equal(w.x[1, :5, 0], np.arange(125, 130))
    assert not w.x[1, 5:].any()
    np.testing.assert_array_equal(w.y, [0, 1])
    np.testing.assert_array_equal(w.groups, ["participant_01", "participant_02"])
    np.testing.assert_array_equal(w.trial_row, [0, 1])
    assert w.n_dropped == 1 and w.geometry.grid_shape == (1, 4) and w.geometry.wrap_v
    assert np.isfinite(w.x).all()


def test_no_contact_rules(caplog):
    ds = dataset([40, 40])
    c = contacts_at([45], ds.n_frames)
    with caplog.at_level(logging.WARNING):
        drop = OnsetWindow(frames=10).plan(c, ds)
    assert "1 of 2 trials have no contact" in caplog.text
    np.testing.assert_array_equal(drop.kept, [False, True])
    keep = OnsetWindow(frames=10, no_contact="keep").plan(c, ds)
    np.testing.assert_array_equal(keep.kept, [True, True])
    np.testing.assert_array_equal(keep.frame_index[0], np.arange(10))  # from the trial's frame 0
    np.testing.assert_array_equal(keep.frame_index[1], np.arange(45, 55))
    lay, sm = toy_layout(3)
    w = OnsetWindow(frames=10, no_contact="keep").assemble(
        Frames(np.zeros((20, 3), np.uint8), (1, 3)), keep, ds, lay, sm
    )
    assert w.x.shape == (2, 10, 3) and w.n_dropped == 0 and not w.x[0].any()


def test_single_frame_window_and_one_frame_trial():
    ds = dataset([1, 5])
    c = contacts_at([0, 3], ds.n_frames)
    plan = OnsetWindow(frames=1).plan(c, ds)
    np.testing.assert_array_equal(plan.frame_index, [[0], [3]])


def test_errors():
    ds = dataset([10, 10])
    c = contacts_at([1], ds.n_frames + 1)
    with pytest.raises(ValueError, match="contacts.n_frames"):
        OnsetWindow().plan(c, ds)
    c = contacts_at([1, 12], ds.n_frames)
    plan = OnsetWindow(frames=5).plan(c, ds)
    lay, sm = toy_layout(4)
    with pytest.raises(ValueError, match="selected_frames"):
        OnsetWindow(frames=5).assemble(Frames(np.zeros((3, 4), np.uint8), (1, 4)), plan, ds, lay, sm)
    with pytest.raises(ValueError, match="taxels"):
        OnsetWindow(frames=5).assemble(Frames(np.zeros((10, 3), np.uint8), (1, 3)), plan, ds, lay, sm)
    with pytest.raises(ConfigError, match="window.frames"):
        OnsetWindow(frames=0)
    with pytest.raises(ConfigError, match="window.no_contact"):
        OnsetWindow(no_contact="pad")
