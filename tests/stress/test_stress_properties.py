"""Properties of the geometric steps after contact (hypothesis; counts from the stress profile).

Charts at any point (on the axis, on the end caps' rims, 1000 m away),
single patches of any size and tilt anywhere on the chart (the seam and the
poles included), noise of every kind on any readings, onset windows of any
trial lengths (empty ones included) against a direct per-trial reference,
and the Random Forest's features on any windows at any resolution.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pandas as pd
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from stress_fixtures import make_link

from sphri.encode.coverage import CoverageEncoder
from sphri.encode.ellipse import EllipseEncoder
from sphri.encode.proximity import ProximityEncoder
from sphri.layout.grid import GridLayout, HexLayout
from sphri.models.features import extract_features
from sphri.noise.components import CrosstalkNoise, DeadTaxelsNoise, GaussianNoise, NoNoise, SaltPepperNoise
from sphri.surface.box import BoxSurface
from sphri.surface.charts import from_uv, jacobian, to_uv
from sphri.surface.cylinder import CylinderSurface
from sphri.testing.synthetic_contacts import make_contacts
from sphri.types import GESTURES, Frames, GestureDataset, HandModel, TaxelGeometry
from sphri.window.onset import OnsetWindow

seeds = st.integers(min_value=0, max_value=2**31 - 1)
chart_links = st.sampled_from(["arm", "sphere", "disc", "slivers", "far"])
chart_kinds = st.sampled_from(["cylinder", "box"])


@cache
def _surface(link: str, kind: str):
    return (CylinderSurface() if kind == "cylinder" else BoxSurface()).fit(make_link(link))


@cache
def _grid(link: str, kind: str, res: int, hexgrid: bool):
    return (HexLayout if hexgrid else GridLayout)().build(make_link(link), _surface(link, kind), res)


def _special_points(surface, rng, k):
    """Points that stress a chart: on the axis, on the primitive, far outside, at the centre."""
    pr = surface.params
    centre = pr.get("origin", pr.get("centre"))
    scale = float(np.ptp(make_link("arm").vertices, axis=0).max())
    out = [
        centre[None],  # the axis / box centre: every angle at once
        centre + rng.normal(size=(k, 3)) * scale,  # anywhere around
        centre + rng.normal(size=(k, 3)) * 1000.0,  # very far away
    ]
    if surface.kind == "cylinder":
        t = rng.choice([pr["u_min"], pr["u_max"], 0.0], size=k)
        out.append(centre + t[:, None] * pr["axis"])  # on the axis, on the caps' centres
    uv = rng.uniform(0, 1, (k, 2))
    uv[: k // 2, 1] = rng.choice([0.0, 1.0 - 1e-16, 0.5], k // 2)
    out.append(from_uv(surface, uv))
    return np.concatenate(out)


@given(link=chart_links, kind=chart_kinds, seed=seeds)
def test_charts_are_finite_everywhere(link, kind, seed):
    surface = _surface(link, kind)
    pts = _special_points(surface, np.random.default_rng(seed), 20)
    uv = to_uv(surface, pts)
    assert np.all(np.isfinite(uv)) and uv.min() >= 0.0 and uv.max() <= 1.0
    assert np.all(uv[:, 1] < 1.0)  # v in [0, 1)
    assert np.all(np.isfinite(jacobian(surface, pts)))
    back, normal, valid = from_uv(surface, uv, return_normal=True, return_valid=True)
    assert np.all(np.isfinite(back)) and np.allclose(np.linalg.norm(normal[valid], axis=1), 1.0)


@st.composite
def patches(draw):
    """Single patches on a chart: centre anywhere (seam, poles), any radius and tilt."""
    link = draw(chart_links)
    kind = draw(chart_kinds)
    u = draw(st.one_of(st.sampled_from([0.0, 1.0, 0.5]), st.floats(0, 1)))
    v = draw(st.one_of(st.sampled_from([0.0, 1.0 - 1e-16, 1e-16]), st.floats(0, 1, exclude_max=True)))
    radius = draw(st.one_of(st.sampled_from([0.0, 1e-9, 0.5]), st.floats(0, 0.08)))
    tilt = draw(st.floats(0.0, np.pi / 2))  # pi/2: the patch's disc seen edge-on in the chart
    spin = draw(st.floats(0.0, 2 * np.pi))
    return link, kind, u, v, radius, tilt, spin


@given(p=patches(), res=st.integers(1, 60), hexgrid=st.booleans())
def test_any_single_patch_encodes_to_valid_readings(p, res, hexgrid):
    link_name, kind, u, v, radius, tilt, spin = p
    surface = _surface(link_name, kind)
    lay = _grid(link_name, kind, res, hexgrid)
    point, normal = from_uv(surface, np.array([[u, v]]), return_normal=True)
    e1 = np.cross(normal[0], [1.0, 0, 0])
    if np.linalg.norm(e1) < 0.1:
        e1 = np.cross(normal[0], [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal[0], e1)
    tilted = np.cos(tilt) * normal[0] + np.sin(tilt) * (np.cos(spin) * e1 + np.sin(spin) * e2)
    contacts = make_contacts([0], point, tilted[None], [radius], 1)
    link = make_link(link_name)
    fi = np.array([0])
    binary = EllipseEncoder().encode(contacts, link, surface, lay, fi).values
    assert binary.dtype == np.uint8 and binary.sum() >= 1  # the centre's taxel is always on
    frac = EllipseEncoder(binary=False).encode(contacts, link, surface, lay, fi).values
    assert np.all(np.isfinite(frac)) and frac.min() >= 0 and frac.max() <= 1
    assert np.all(binary[frac >= 0.5 + 1e-6] == 1)  # covered cells are on
    cov = CoverageEncoder().encode(contacts, link, surface, lay, fi).values
    np.testing.assert_allclose(cov, frac, atol=1e-6)
    prox = ProximityEncoder(intensity="depth").encode(contacts, link, surface, lay, fi).values
    assert np.all(np.isfinite(prox)) and prox.min() >= 0 and prox.max() <= 1


@given(
    values=st.one_of(
        arrays(np.uint8, st.tuples(st.integers(0, 30), st.integers(1, 40)), elements=st.integers(0, 1)),
        arrays(np.float32, st.tuples(st.integers(0, 30), st.integers(1, 40)), elements=st.floats(0, 1, width=32)),
    ),
    grid=st.booleans(),
    seed=st.integers(0, 2**40),
)
def test_every_noise_kind_keeps_readings_in_range(values, grid, seed):
    m, n = values.shape
    rng = np.random.default_rng(seed % 2**32)
    fi = rng.integers(0, 2**40, m)
    tk = rng.integers(-(2**62), 2**62, m)
    geometry = TaxelGeometry(None, None, rng.normal(size=(n, 3)), False, 0.0, 0.0)
    if grid:
        frames = Frames(values=values, grid_shape=(1, n))
    else:
        from sphri.types import SkinFrames

        frames = SkinFrames(values=values, grid_shape=None, geometry=geometry)
    for noise in (
        SaltPepperNoise(p=0.3),
        SaltPepperNoise(mode="flip"),
        GaussianNoise(sigma=1.0),
        DeadTaxelsNoise(fraction=1.0, value=1.0),
        CrosstalkNoise(alpha=1.0),
        NoNoise(),
    ):
        out = noise.apply(frames, fi, tk, seed).values
        assert out.shape == values.shape
        assert out.dtype in (values.dtype, np.float32)
        if out.size:
            assert np.all(np.isfinite(out)) and out.min() >= 0 and out.max() <= 1
        np.testing.assert_array_equal(noise.apply(frames, fi, tk, seed).values, out)  # deterministic


def _toy_dataset(lengths):
    lengths = np.asarray(lengths, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    n = len(lengths)
    trials = pd.DataFrame(
        {
            "participant": [f"participant_{i % 3 + 1:02d}" for i in range(n)],
            "region": ["arm"] * n,
            "trial_ordinal": np.arange(1, n + 1),
            "trial_id": [f"{i + 1:04d}_x" for i in range(n)],
            "gesture": [GESTURES[i % 8] for i in range(n)],
            "start": starts,
            "n_frames": lengths,
        }
    )
    hand = HandModel(("a",), ("palm",), np.array([0.01]), np.array([0.02]), np.array([0]), np.zeros((1, 3)))
    return GestureDataset("toy", True, hand, trials, np.zeros((int(lengths.sum()), 1, 7), np.float32), 30.0)


@given(
    lengths=st.lists(st.integers(0, 40), min_size=1, max_size=12),
    density=st.floats(0, 1),
    window=st.integers(1, 30),
    keep=st.booleans(),
    seed=seeds,
)
def test_onset_windows_match_a_per_trial_reference(lengths, density, window, keep, seed):
    rng = np.random.default_rng(seed)
    ds = _toy_dataset(lengths)
    f = ds.n_frames
    hit = np.flatnonzero(rng.random(f) < density)
    contacts = make_contacts(
        hit, np.zeros((hit.size, 3)), np.tile([0, 0, 1.0], (hit.size, 1)), np.full(hit.size, 0.01), f
    )
    comp = OnsetWindow(frames=window, no_contact="keep" if keep else "drop")
    plan = comp.plan(contacts, ds)
    values = rng.random((len(plan.selected_frames()), 3)).astype(np.float32)
    # reference: one trial at a time
    expect_rows = []
    for t, (s, n) in enumerate(zip(ds.trials["start"], ds.trials["n_frames"])):
        own = hit[(hit >= s) & (hit < s + n)]
        onset = int(own[0] - s) if own.size else -1
        assert plan.onset[t] == onset
        assert plan.kept[t] == (onset >= 0 or keep)
        first = max(onset, 0)
        slots = [s + first + k if first + k < n else -1 for k in range(window)]
        if plan.kept[t]:
            np.testing.assert_array_equal(plan.frame_index[t], slots)
            expect_rows.append(slots)
        else:
            assert (plan.frame_index[t] == -1).all()
    sel = plan.selected_frames()
    assert (np.diff(sel) > 0).all() if sel.size > 1 else True  # ascending, no duplicates
    lay = type("L", (), {"n_taxels": 3, "grid_shape": None, "uv": None, "position_m": np.zeros((3, 3))})()
    from sphri.types import Layout, SurfaceMap

    lay = Layout("toy", np.eye(3), np.eye(3), np.ones(3), None, None, 0.01, 0.01)
    sm = SurfaceMap("mesh", False, 0.0, 0.0, False, 0.0, {})
    w = comp.assemble(Frames(values, None), plan, ds, lay, sm)
    assert w.x.shape == (int(plan.kept.sum()), window, 3) and w.x.dtype == np.float32
    flat = np.asarray(expect_rows, dtype=np.int64).reshape(-1, window)
    lookup = {int(fr): i for i, fr in enumerate(sel)}
    for i, slots in enumerate(flat):
        for k, fr in enumerate(slots):
            expected = values[lookup[int(fr)]] if fr >= 0 else np.zeros(3, np.float32)
            np.testing.assert_array_equal(w.x[i, k], expected)
    assert list(w.trial_row) == list(np.flatnonzero(plan.kept))


@given(
    res=st.integers(1, 80),
    hexgrid=st.booleans(),
    kind=st.sampled_from(["zeros", "ones", "random", "single", "fraction"]),
    seed=seeds,
    length=st.integers(1, 12),
)
def test_features_are_finite_for_any_windows(res, hexgrid, kind, seed, length):
    lay = _grid("arm", "cylinder", res, hexgrid)
    geom = TaxelGeometry.from_layout(lay, _surface("arm", "cylinder"))
    rng = np.random.default_rng(seed)
    n = lay.n_taxels
    x = {
        "zeros": np.zeros((3, length, n)),
        "ones": np.ones((3, length, n)),
        "random": (rng.random((3, length, n)) < 0.2).astype(float),
        "single": np.eye(n)[rng.integers(0, n, (3, length))],
        "fraction": rng.random((3, length, n)),
    }[kind].astype(np.float32)
    feats = extract_features(x, geom)
    assert feats.shape == (3, 32) and np.all(np.isfinite(feats))
