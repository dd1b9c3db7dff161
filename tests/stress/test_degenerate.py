"""Degenerate inputs through the chain: bad quaternions, odd links, extreme resolutions, empty trials.

Each case goes through the real stage components, from the contact stage
to the Random Forest's features (or to the clear error that the case calls
for).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st
from stress_fixtures import CONFIGS, degenerate_for, nonfinite_fields, reachy_arm, robot_of

from sphri.contact.exact import ExactContact
from sphri.encode.coverage import CoverageEncoder
from sphri.encode.ellipse import EllipseEncoder
from sphri.encode.proximity import ProximityEncoder
from sphri.evaluate.cv import LeaveOneSubjectOut
from sphri.hand.kinematics import repair_quaternions
from sphri.layout.grid import GridLayout, HexLayout
from sphri.layout.poisson import RandomLayout
from sphri.models.features import extract_features
from sphri.models.rf import RandomForest
from sphri.noise.components import CrosstalkNoise, NoNoise, SaltPepperNoise
from sphri.pipeline import trial_keys
from sphri.surface.box import BoxSurface
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.meshutil import link_from_trimesh
from sphri.types import Link
from sphri.window.onset import OnsetWindow


def _quiet(caplog):
    caplog.set_level(logging.ERROR)


# --------------------------------------------------------------------------- quaternions


@given(
    frame=st.integers(0, 60),
    capsule=st.integers(0, 2),
    kind=st.sampled_from(["nan", "inf", "zero", "tiny"]),
)
def test_bad_quaternions_are_named_by_the_contact_stage_and_repair_gives_finite_contacts(frame, capsule, kind):
    arm = reachy_arm()
    ds = degenerate_for("arm")
    frame = frame % ds.n_frames
    poses = ds.poses.copy()
    poses[frame, capsule, 3:] = {"nan": np.nan, "inf": np.inf, "zero": 0.0, "tiny": 1e-9}[kind]
    bad = replace(ds, poses=poses)
    with pytest.raises(ValueError) as err:
        ExactContact().compute(bad, robot_of(arm))
    msg = str(err.value)
    assert ds.name in msg and "global frames" in msg and f"({frame}, {capsule})" in msg
    fixed_q, replaced = repair_quaternions(poses[..., 3:], ds.trials["start"].to_numpy())
    assert replaced.sum() == 1 and replaced[frame, capsule]
    assert np.allclose(np.linalg.norm(fixed_q, axis=-1), 1.0)
    poses[..., 3:] = fixed_q
    contacts = ExactContact().compute(replace(ds, poses=poses), robot_of(arm))
    assert not nonfinite_fields(contacts)


def test_nan_positions_are_named_not_propagated():
    arm = reachy_arm()
    ds = degenerate_for("arm")
    poses = ds.poses.copy()
    poses[7, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"NaN/inf positions.*\(frame 7, capsule 1\)"):
        ExactContact().compute(replace(ds, poses=poses), robot_of(arm))


# --------------------------------------------------------------------------- odd links


@pytest.mark.parametrize("height_m", [0.01, 0.004, 0.002])
def test_cylinder_of_a_very_short_link_keeps_its_axis(height_m, caplog):
    """A disc of radius 5 cm and a few mm thickness: the axis is its normal, the radius 5 cm."""
    _quiet(caplog)
    disc = link_from_trimesh(trimesh.creation.cylinder(radius=0.05, height=height_m, sections=64), "disc")
    sm = CylinderSurface().fit(disc)
    assert abs(sm.params["axis"][2]) > 0.999
    assert sm.params["radius"] == pytest.approx(0.05, rel=0.02)
    assert sm.fit_residual_m < 2e-4
    assert not nonfinite_fields(sm)


@pytest.mark.filterwarnings(
    "ignore:invalid value encountered in divide:RuntimeWarning"
)  # trimesh: a plate has no volume
def test_cylinder_and_box_of_a_sphere_and_of_a_flat_plate_are_finite(caplog):
    _quiet(caplog)
    ball = link_from_trimesh(trimesh.creation.icosphere(subdivisions=3, radius=0.05), "ball")
    plate = Link(
        "plate",
        np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0.2, 0], [0, 0.2, 0.0]]),
        np.array([[0, 1, 2], [0, 2, 3]]),
        watertight=False,
    )
    for link in (ball, plate):
        for surface in (CylinderSurface().fit(link), BoxSurface().fit(link)):
            assert not nonfinite_fields(surface), (link.name, surface.kind)
            assert surface.metres_per_u > 0 and surface.metres_per_v > 0
            lay = GridLayout().build(link, surface, 5)
            assert not nonfinite_fields(lay) and lay.area_m2.sum() > 0
    sm = CylinderSurface().fit(ball)
    assert 0.04 < sm.params["radius"] < 0.055
    assert any("nearly spherical" in n for n in sm.params["notes"])
    flat = BoxSurface().fit(plate)
    assert flat.params["extents"][2] > 0  # a flat link still gets a (1 nm) thickness


# --------------------------------------------------------------------------- resolutions 1 and 200


@pytest.mark.parametrize("res", [1, 200])
def test_resolution_1_and_200_through_the_chain(res, degenerate, caplog):
    _quiet(caplog)
    ds, robot, contacts = degenerate["arm"]
    link = robot.link_for("arm")
    surface = CylinderSurface().fit(link)
    window = OnsetWindow(frames=6)
    plan = window.plan(contacts, ds)
    fi = plan.selected_frames()
    tk = trial_keys(ds)[ds.frame_trial_index()[fi]]
    grid = GridLayout().build(link, surface, res)
    for lay in (grid, HexLayout().build(link, surface, res)):
        h, w = lay.grid_shape
        assert lay.n_taxels == h * w
        assert lay.pitch_u_m == pytest.approx(surface.metres_per_u / h)
        if lay.kind == "grid":
            assert h == res
        else:  # the hex lattice keeps the grid's taxel count (within a row or column's rounding)
            assert abs(lay.n_taxels - grid.n_taxels) <= max(h, w, 0.02 * grid.n_taxels)
        for enc in (EllipseEncoder(), CoverageEncoder(), ProximityEncoder()):
            frames = enc.encode(contacts, link, surface, lay, fi)
            assert frames.values.shape == (len(fi), lay.n_taxels)
            for noise in (SaltPepperNoise(), CrosstalkNoise()):
                out = noise.apply(frames, fi, tk, 0).values
                assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
            windows = window.assemble(frames, plan, ds, lay, surface)
            assert windows.x.shape == (int(plan.kept.sum()), 6, lay.n_taxels)
            feats = extract_features(windows.x, windows.geometry)
            assert np.all(np.isfinite(feats)), type(enc).__name__
    # res 1: a single ring of taxels around the arm; the ellipse lights its centre cell at least
    if res == 1:
        lit = EllipseEncoder().encode(contacts, link, surface, GridLayout().build(link, surface, 1), fi).values
        has_contact = np.isin(fi, contacts.frame)
        assert (lit[has_contact].sum(axis=1) >= 1).all() and not lit[~has_contact].any()


@pytest.mark.slow
def test_random_layout_at_resolution_200(degenerate, caplog):
    _quiet(caplog)
    ds, robot, contacts = degenerate["arm"]
    link = robot.link_for("arm")
    surface = CylinderSurface().fit(link)
    lay = RandomLayout().build(link, surface, 200)
    assert lay.n_taxels == GridLayout().build(link, surface, 200).n_taxels
    fi = OnsetWindow(frames=6).plan(contacts, ds).selected_frames()
    for enc in (CoverageEncoder(), ProximityEncoder()):
        v = enc.encode(contacts, link, surface, lay, fi).values
        assert np.all(np.isfinite(v)) and v.max() <= 1 and v.any()


# --------------------------------------------------------------------------- empty and contact-less trials


def _no_contact_dataset():
    """The degenerate dataset cut to its no-contact and empty trials (all frames far from the arm)."""
    arm = reachy_arm()
    ds = degenerate_for("arm")
    keep = [i for i in range(len(ds.trials)) if CONFIGS[i % len(CONFIGS)] in ("no_contact", "empty")]
    trials = ds.trials.iloc[keep].reset_index(drop=True)
    rows = np.concatenate([np.arange(s, s + n) for s, n in zip(trials["start"], trials["n_frames"])])
    starts = np.concatenate([[0], np.cumsum(trials["n_frames"].to_numpy())[:-1]])
    trials["start"] = starts.astype(np.int64)
    return replace(ds, trials=trials, poses=ds.poses[rows]), arm


def test_trials_without_contact_drop_cleanly_and_cv_says_why(caplog):
    _quiet(caplog)
    ds, arm = _no_contact_dataset()
    assert (ds.trials["n_frames"] == 0).any()
    contacts = ExactContact().compute(ds, robot_of(arm))
    assert contacts.n_contacts == 0 and contacts.n_frames == ds.n_frames
    surface = CylinderSurface().fit(arm)
    lay = GridLayout().build(arm, surface, 18)
    window = OnsetWindow(frames=50)
    plan = window.plan(contacts, ds)
    assert not plan.kept.any() and (plan.onset == -1).all()
    fi = plan.selected_frames()
    assert fi.shape == (0,)
    frames = EllipseEncoder().encode(contacts, arm, surface, lay, fi)
    assert frames.values.shape == (0, lay.n_taxels)
    noisy = SaltPepperNoise().apply(frames, fi, np.zeros(0, dtype=np.int64), 0)
    windows = window.assemble(noisy, plan, ds, lay, surface)
    assert windows.x.shape == (0, 50, lay.n_taxels) and windows.n_dropped == len(ds.trials)
    with pytest.raises(ValueError, match="no trials"):
        LeaveOneSubjectOut(progress=False).run(lambda: RandomForest(geometry=windows.geometry), windows)


def test_trials_without_contact_kept_as_zero_windows(caplog):
    _quiet(caplog)
    ds, arm = _no_contact_dataset()
    contacts = ExactContact().compute(ds, robot_of(arm))
    surface = CylinderSurface().fit(arm)
    lay = GridLayout().build(arm, surface, 6)
    window = OnsetWindow(frames=10, no_contact="keep")
    plan = window.plan(contacts, ds)
    assert plan.kept.all()
    fi = plan.selected_frames()
    tk = trial_keys(ds)[ds.frame_trial_index()[fi]]
    frames = CoverageEncoder().encode(contacts, arm, surface, lay, fi)
    assert frames.values.shape == (len(fi), lay.n_taxels) and not frames.values.any()
    windows = window.assemble(NoNoise().apply(frames, fi, tk, 0), plan, ds, lay, surface)
    assert windows.x.shape[0] == len(ds.trials) and not windows.x.any()
    feats = extract_features(windows.x, windows.geometry)
    assert np.all(feats == 0)
    noisy = window.assemble(SaltPepperNoise(p=0.5).apply(frames, fi, tk, 0), plan, ds, lay, surface)
    assert np.all(np.isfinite(extract_features(noisy.x, noisy.geometry)))


# --------------------------------------------------------------------------- float32 contacts


def test_float32_contact_arrays_encode_like_float64(degenerate):
    ds, robot, contacts = degenerate["arm"]
    link = robot.link_for("arm")
    surface = CylinderSurface().fit(link)
    lay = GridLayout().build(link, surface, 18)
    fi = OnsetWindow(frames=6).plan(contacts, ds).selected_frames()
    c32 = replace(
        contacts,
        **{
            k: getattr(contacts, k).astype(np.float32)
            for k in ("distance_m", "point_m", "segment_point_m", "normal", "patch_radius_m", "depth_m")
        },
    )
    for enc in (EllipseEncoder(binary=False), ProximityEncoder(intensity="depth")):
        a = enc.encode(contacts, link, surface, lay, fi).values
        b = enc.encode(c32, link, surface, lay, fi).values
        assert np.all(np.isfinite(b))
        assert np.abs(a - b).max() < 0.05 and np.abs(a - b).mean() < 1e-3
