"""Invariances through the stages (not the bare kernel: tests/contact covers that).

- A rigid motion of robot and hand together changes no contact
  (``ExactContact.compute`` on a moved dataset and a moved robot).
- Scaling everything by s scales distances, depths, patch radii and points by s.
- Quaternions are read up to scale: any non-zero norm gives the same contacts.
- 1000 m from the origin the chain (contact, cylinder, grid, encoder) gives
  the same skin readings, up to the float32 rounding of the poses there.
- Rotating the cylinder's angular origin by k cells rolls the encoder's
  output by k columns and changes nothing else.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation
from stress_fixtures import (
    FAR_OFFSET_M,
    compare_contacts,
    near_surface_dataset,
    reachy_arm,
    robot_of,
    transform_dataset,
    transform_link,
)

from sphri.contact.exact import ExactContact
from sphri.encode.coverage import CoverageEncoder
from sphri.encode.ellipse import EllipseEncoder
from sphri.layout.grid import GridLayout, HexLayout
from sphri.surface.charts import to_uv
from sphri.surface.cylinder import CylinderSurface
from sphri.testing.synthetic_contacts import make_contacts, synthetic_contacts
from sphri.window.onset import OnsetWindow

seeds = st.integers(min_value=0, max_value=2**31 - 1)
#: float32 poses: rounding of a coordinate of magnitude x is about 6e-8 x.
F32 = float(np.finfo(np.float32).eps)


def _contacts(ds, link, inside="auto"):
    return ExactContact(inside=inside).compute(ds, robot_of(link))


@given(seed=seeds, reach=st.sampled_from([0.0, 0.05, 1.0, 3.0]))
def test_rigid_motion_of_robot_and_hand_changes_no_contact(seed, reach):
    rng = np.random.default_rng(seed)
    arm = reachy_arm()
    rot = Rotation.random(random_state=seed)
    shift = rng.uniform(-reach, reach, 3)
    ds = near_surface_dataset(arm, 12, seed)
    before = _contacts(ds, arm)
    after = _contacts(transform_dataset(ds, rot, shift), transform_link(arm, rot, shift))
    tol = 4 * F32 * (1.0 + np.abs(shift).max())
    problems = compare_contacts(before, after, rot, shift, 1.0, tol, ds.hand.radius_m)
    assert not problems, problems
    assert after.n_contacts > 0


@given(seed=seeds, scale=st.floats(0.05, 20.0), inside=st.sampled_from(["hull", "winding"]))
def test_scaling_everything_scales_distances(seed, scale, inside):
    """With a fixed definition of the solid. (``inside=auto`` picks hull or winding with an absolute
    5 mm convexity tolerance, so the Reachy arm, 0.4 mm from convex, switches to winding above ~10x.)"""
    arm = reachy_arm()
    ident = Rotation.identity()
    ds = near_surface_dataset(arm, 12, seed)
    before = _contacts(ds, arm, inside)
    big = transform_dataset(ds, ident, np.zeros(3), scale)
    after = _contacts(big, transform_link(arm, ident, np.zeros(3), scale), inside)
    tol = 4 * F32 * scale
    problems = compare_contacts(before, after, ident, np.zeros(3), scale, tol, big.hand.radius_m)
    assert not problems, problems


@given(seed=seeds, log_norm=st.floats(-7.5, 7.0))
def test_quaternions_count_up_to_scale(seed, log_norm):
    """Any quaternion norm from 3e-8 to 1e7 (float32 storage) gives the contacts of the unit one."""
    arm = reachy_arm()
    ds = near_surface_dataset(arm, 10, seed)
    before = _contacts(ds, arm)
    scaled = transform_dataset(ds, Rotation.identity(), np.zeros(3))
    q = ds.poses[..., 3:].astype(np.float64) * 10.0**log_norm
    scaled.poses[..., 3:] = q.astype(np.float32)
    after = _contacts(scaled, arm)
    problems = compare_contacts(before, after, Rotation.identity(), np.zeros(3), 1.0, 8 * F32, ds.hand.radius_m)
    assert not problems, problems


def test_chain_far_from_the_origin_reads_the_same_skin():
    """Robot and hand 1000 m away: contacts, cylinder, grid and readings as at the origin."""
    arm = reachy_arm()
    ds = near_surface_dataset(arm, 40, 3, spheres=True)
    near_c = _contacts(ds, arm)
    ident = Rotation.identity()
    far_link = transform_link(arm, ident, FAR_OFFSET_M)
    far_ds = transform_dataset(ds, ident, FAR_OFFSET_M)
    far_c = _contacts(far_ds, far_link)
    tol = 4 * F32 * 1732.0  # float32 rounding of coordinates of magnitude 1000 m (~0.4 mm)
    problems = compare_contacts(near_c, far_c, ident, FAR_OFFSET_M, 1.0, tol, ds.hand.radius_m)
    assert not problems, problems

    near_s, far_s = CylinderSurface().fit(arm), CylinderSurface().fit(far_link)
    np.testing.assert_allclose(far_s.params["origin"] - FAR_OFFSET_M, near_s.params["origin"], atol=1e-9)
    np.testing.assert_allclose(far_s.params["axis"], near_s.params["axis"], atol=1e-9)
    assert abs(far_s.params["radius"] - near_s.params["radius"]) < 1e-9
    assert abs(far_s.fit_residual_m - near_s.fit_residual_m) < 1e-9
    near_l, far_l = GridLayout().build(arm, near_s, 18), GridLayout().build(far_link, far_s, 18)
    np.testing.assert_allclose(far_l.position_m - FAR_OFFSET_M, near_l.position_m, atol=1e-8)
    np.testing.assert_allclose(far_l.area_m2, near_l.area_m2, rtol=1e-9)

    plan = OnsetWindow(frames=50).plan(near_c, ds)
    fi = plan.selected_frames()
    # frames whose contacts are well defined on both sides: no sphere within tol of tangency
    shaky = np.zeros(ds.n_frames, dtype=bool)
    for c in (near_c, far_c):
        shaky[c.frame[(c.distance_m < tol) | (c.depth_m < tol)]] = True
    steady = ~shaky[fi]
    assert steady.sum() > 0.7 * len(fi)
    a = CoverageEncoder().encode(near_c, arm, near_s, near_l, fi).values[steady]
    b = CoverageEncoder().encode(far_c, far_link, far_s, far_l, fi).values[steady]
    # sub-millimetre shifts of 13 mm taxels: small coverage changes, no new or lost patches
    assert np.abs(a - b).max() < 0.05 and np.abs(a - b).mean() < 1e-3
    ba = EllipseEncoder().encode(near_c, arm, near_s, near_l, fi).values[steady]
    bb = EllipseEncoder().encode(far_c, far_link, far_s, far_l, fi).values[steady]
    assert (ba != bb).mean() < 1e-3


def _seam_patches(surface, seed: int, n_frames: int):
    """Patches on the cylinder itself, a third of them across the seam, some on the end caps."""
    rng = np.random.default_rng(seed)
    pr = surface.params
    k = 3 * n_frames
    frame = np.repeat(np.arange(n_frames), 3)
    u = rng.uniform(-0.1, 1.1, k)  # beyond [0, 1]: on the end caps' planes
    v = np.where(np.arange(k) % 3 == 0, rng.choice([0.0, 1.0 - 1e-12, 1e-12], k), rng.uniform(0, 1, k))
    t = pr["u_min"] + np.clip(u, 0, 1) * (pr["u_max"] - pr["u_min"])
    ang = 2 * np.pi * v
    radial = np.cos(ang)[:, None] * pr["ref"] + np.sin(ang)[:, None] * pr["binormal"]
    cap = (u < 0) | (u > 1)
    rho = np.where(cap, rng.uniform(0, 1, k) * pr["radius"], pr["radius"])
    point = pr["origin"] + t[:, None] * pr["axis"] + rho[:, None] * radial
    normal = np.where(cap[:, None], np.sign(u - 0.5)[:, None] * pr["axis"], radial)
    patch = rng.choice([0.0, 1e-5, 0.004, 0.015, 0.05], k)
    return make_contacts(frame, point, normal, patch, n_frames)


@cache
def _surface():
    return CylinderSurface().fit(reachy_arm())


@cache
def _base(res: int, hexgrid: bool):
    return _surface(), (HexLayout if hexgrid else GridLayout)().build(reachy_arm(), _surface(), res)


def _rotate_origin(surface, angle: float):
    """The chart with its angular origin (``ref``) turned by ``angle`` radians about the axis."""
    pr = dict(surface.params)
    pr["ref"] = Rotation.from_rotvec(angle * pr["axis"]).apply(pr["ref"])
    pr["binormal"] = np.cross(pr["axis"], pr["ref"])
    return replace(surface, params=pr)


def test_the_seam_setting_turns_the_angular_origin():
    """``surface.seam`` moves only the chart's zero angle: same axis, radius and extent."""
    base = _surface()
    seam = Rotation.from_rotvec(0.7 * base.params["axis"]).apply(base.params["ref"])
    turned = CylinderSurface(seam=seam.tolist()).fit(reachy_arm())
    expected = _rotate_origin(base, 0.7)
    for key in ("origin", "axis", "ref", "binormal"):
        np.testing.assert_allclose(turned.params[key], expected.params[key], atol=1e-12)
    for key in ("radius", "u_min", "u_max"):
        assert turned.params[key] == pytest.approx(base.params[key], abs=1e-12)


@cache
def _real_contacts(seed: int, n_frames: int):
    return synthetic_contacts(reachy_arm(), n_frames, contact_fraction=1.0, seed=seed)


@given(seed=seeds, res=st.integers(1, 40), shift=st.integers(0, 10_000), hexgrid=st.booleans())
def test_rotating_the_angular_origin_rolls_the_readings(seed, res, shift, hexgrid):
    arm = reachy_arm()
    base, lay = _base(res, hexgrid)
    layout_cls = HexLayout if hexgrid else GridLayout
    h, w = lay.grid_shape
    k = shift % w
    rotated = _rotate_origin(base, 2 * np.pi * k / w)
    lay_r = layout_cls().build(arm, rotated, res)
    assert lay_r.grid_shape == lay.grid_shape
    np.testing.assert_array_equal(lay_r.uv, lay.uv)

    n_frames = 12
    contacts = _seam_patches(base, seed, n_frames)
    real = _real_contacts(seed % 4, n_frames)
    fi = np.arange(n_frames)
    for c in (contacts, real):
        uv = to_uv(base, c.point_m)
        # a patch centre exactly on a column boundary may fall on either side after rotation
        assume(np.abs(uv[:, 1] * w - np.round(uv[:, 1] * w)).min() > 1e-9 or c is contacts)
        a = EllipseEncoder(binary=False).encode(c, arm, base, lay, fi).values.reshape(n_frames, h, w)
        b = EllipseEncoder(binary=False).encode(c, arm, rotated, lay_r, fi).values.reshape(n_frames, h, w)
        np.testing.assert_allclose(b, np.roll(a, -k, axis=2), atol=1e-6)
        ab = EllipseEncoder().encode(c, arm, base, lay, fi).values.reshape(n_frames, h, w)
        bb = EllipseEncoder().encode(c, arm, rotated, lay_r, fi).values.reshape(n_frames, h, w)
        differ = bb != np.roll(ab, -k, axis=2)
        # binary readings may only differ where a cell sits exactly on the threshold or holds a
        # patch centre that lies on a cell boundary
        borderline = np.abs(np.roll(a, -k, axis=2) - 0.5) < 1e-6
        assert not (differ & ~borderline).any() or c is contacts and differ.sum() <= 3 * n_frames
