"""The Random Forest's 32 features: hand-checked values, wrap, layouts, resolution."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.models.features import FEATURE_NAMES, extract_features, frame_signals, taxel_coords
from sphri.testing.toy_windows import arm_geometry, blob_windows, grid_geometry
from sphri.types import TaxelGeometry

F = {name: i for i, name in enumerate(FEATURE_NAMES)}


def frames_from_cells(h: int, w: int, cells_per_frame: list[list[tuple[int, int]]]) -> np.ndarray:
    x = np.zeros((1, len(cells_per_frame), h * w), dtype=np.float32)
    for t, cells in enumerate(cells_per_frame):
        for r, c in cells:
            x[0, t, r * w + c] = 1.0
    return x


def test_feature_names_are_32_and_unique():
    assert len(FEATURE_NAMES) == 32
    assert len(set(FEATURE_NAMES)) == 32


def test_hand_computed_signals_and_features():
    h, w = 4, 6
    geom = grid_geometry(h, w)
    block = [(1, 1), (1, 2), (2, 1), (2, 2)]
    x = frames_from_cells(h, w, [[], block + [(3, 5)], [(1, 2), (1, 3), (2, 2), (2, 3)]])
    sig = frame_signals(x, taxel_coords(geom))
    cm2 = 1e-4
    np.testing.assert_allclose(sig["area"][0], [0, 5 * cm2, 4 * cm2])
    np.testing.assert_allclose(sig["cop_a"][0], [0, 0.023, 0.020])
    np.testing.assert_allclose(sig["cop_b"][0], [0, 0.027, 0.030])
    np.testing.assert_allclose(sig["spread_a"][0], [0, 0.56 * cm2, 0.25 * cm2], atol=1e-12)
    np.testing.assert_allclose(sig["spread_b"][0], [0, 2.16 * cm2, 0.25 * cm2], atol=1e-12)
    np.testing.assert_allclose(sig["bbox"][0], [0, 15 * cm2, 4 * cm2])
    np.testing.assert_allclose(sig["lcc"][0], [0, 4 * cm2, 4 * cm2])  # (3, 5) is not 8-connected to the block
    np.testing.assert_array_equal(sig["contact"][0], [False, True, True])

    f = extract_features(x, geom)[0]
    area = np.array([0, 5, 4]) * cm2
    assert f[F["area_mean_m2"]] == pytest.approx(area.mean())
    assert f[F["area_std_m2"]] == pytest.approx(area.std())
    assert f[F["area_range_m2"]] == pytest.approx(5 * cm2)
    assert f[F["darea_absmean_m2"]] == pytest.approx(3 * cm2)
    assert f[F["darea_range_m2"]] == pytest.approx(6 * cm2)
    assert f[F["darea_max_m2"]] == pytest.approx(5 * cm2)
    assert f[F["peak_count"]] == 1
    assert f[F["contact_fraction"]] == pytest.approx(2 / 3)
    assert f[F["cop_a_std_m"]] == pytest.approx(0.0015)
    assert f[F["cop_a_range_m"]] == pytest.approx(0.003)
    assert f[F["cop_b_range_m"]] == pytest.approx(0.003)
    assert f[F["speed_mean_m"]] == pytest.approx(np.hypot(0.003, 0.003))
    assert f[F["bbox_max_m2"]] == pytest.approx(15 * cm2)
    assert f[F["lcc_mean_m2"]] == pytest.approx(8 / 3 * cm2)
    # spreads summarise contact frames only
    assert f[F["spread_a_mean_m2"]] == pytest.approx((0.56 + 0.25) / 2 * cm2)
    assert f[F["spread_b_max_m2"]] == pytest.approx(2.16 * cm2)


def test_peak_count_counts_separate_bursts():
    h, w = 3, 3
    geom = grid_geometry(h, w)
    on = [(1, 1), (1, 2)]
    x = frames_from_cells(h, w, [on, on, [], [], on, [], on, on, []])
    assert extract_features(x, geom)[0, F["peak_count"]] == 3


def test_component_across_the_seam_is_merged():
    h, w = 4, 8
    geom = grid_geometry(h, w, wrap=True)
    seam = frames_from_cells(h, w, [[(1, 7), (1, 0), (2, 7), (2, 0)]])
    middle = frames_from_cells(h, w, [[(1, 3), (1, 4), (2, 3), (2, 4)]])
    sig = frame_signals(seam, taxel_coords(geom))
    cm2 = 1e-4
    assert sig["lcc"][0, 0] == pytest.approx(4 * cm2)  # one component, not two halves
    assert sig["bbox"][0, 0] == pytest.approx(4 * cm2)  # 2 x 2 cm, not 2 x 8 cm
    assert sig["spread_b"][0, 0] == pytest.approx(0.25 * cm2)
    assert sig["cop_b"][0, 0] == pytest.approx(0.0, abs=1e-12) or sig["cop_b"][0, 0] == pytest.approx(0.08)
    np.testing.assert_allclose(extract_features(seam, geom), extract_features(middle, geom), atol=1e-12)
    # without wrap the same taxels are two components at opposite edges
    flat = frame_signals(seam, taxel_coords(grid_geometry(h, w, wrap=False)))
    assert flat["lcc"][0, 0] == pytest.approx(2 * cm2)
    assert flat["bbox"][0, 0] == pytest.approx(16 * cm2)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), shift=st.integers(1, 18))
def test_features_do_not_change_when_the_skin_is_rotated(seed, shift):
    """Around a wrapping link, rotating every frame by whole columns changes nothing."""
    win = blob_windows(participants=1, repetitions=1, res=18, noise_p=0.0, seed=seed)
    h, w = win.geometry.grid_shape
    rolled = np.roll(win.x.reshape(-1, 50, h, w), shift, axis=3).reshape(win.x.shape)
    np.testing.assert_allclose(
        extract_features(rolled, win.geometry), extract_features(win.x, win.geometry), rtol=1e-9, atol=1e-12
    )


@pytest.mark.parametrize("wrap", [False, True])
def test_grid_and_neighbour_graph_paths_agree(wrap):
    """A square grid given without grid_shape (neighbour graph) gives the same features."""
    rng = np.random.default_rng(3)
    h, w = 6, 9
    x = (rng.random((20, 12, h * w)) < 0.25).astype(np.float32)
    grid = extract_features(x, grid_geometry(h, w, wrap=wrap))
    graph = extract_features(x, grid_geometry(h, w, wrap=wrap, grid=False))
    np.testing.assert_allclose(graph, grid, rtol=1e-9, atol=1e-12)


def test_layout_without_chart_uses_principal_axes():
    """A planar grid given only by 3-D positions matches the charted one (no wrap)."""
    rng = np.random.default_rng(4)
    h, w = 8, 5  # longer along u, so the first principal axis is u
    charted = grid_geometry(h, w)
    chartless = TaxelGeometry(
        grid_shape=(h, w), uv=None, position_m=charted.position_m, wrap_v=False, metres_per_u=0.0, metres_per_v=0.0
    )
    x = (rng.random((10, 6, h * w)) < 0.3).astype(np.float32)
    np.testing.assert_allclose(extract_features(x, chartless), extract_features(x, charted), rtol=1e-9, atol=1e-12)


def test_features_are_in_physical_units_across_resolutions():
    """The same touches at res 18 and res 36 give similar areas and spreads (counts would differ 4x)."""
    lo = blob_windows(participants=2, repetitions=2, res=18, noise_p=0.0, seed=5)
    hi = blob_windows(participants=2, repetitions=2, res=36, noise_p=0.0, seed=5)
    f_lo, f_hi = extract_features(lo.x, lo.geometry), extract_features(hi.x, hi.geometry)
    for name in ("area_max_m2", "lcc_max_m2", "bbox_max_m2", "spread_a_max_m2"):
        ratio = np.median(f_lo[:, F[name]] / f_hi[:, F[name]])
        assert 0.8 < ratio < 1.6, (name, ratio)
    assert np.median(np.abs(f_lo[:, F["cop_a_range_m"]] - f_hi[:, F["cop_a_range_m"]])) < 0.01


def test_single_taxel_and_scatter_layouts():
    one = blob_windows(participants=1, repetitions=2, res=1, seed=6)
    assert one.geometry.grid_shape == (1, 1)
    f = extract_features(one.x, one.geometry)
    assert f.shape == (16, 32) and np.all(np.isfinite(f))
    # one taxel: no spatial information beyond contact area
    assert np.all(f[:, F["cop_a_std_m"]] == 0) and np.all(f[:, F["spread_b_max_m2"]] == 0)
    scatter = blob_windows(participants=1, repetitions=2, res=10, layout="scatter", seed=6)
    coords = taxel_coords(scatter.geometry)
    assert coords.adjacency.grid_shape is None and coords.adjacency.pairs.shape[0] > scatter.geometry.n_taxels
    fs = extract_features(scatter.x, scatter.geometry)
    assert np.all(np.isfinite(fs)) and np.all(fs[:, F["lcc_max_m2"]] > 0)


def test_bad_inputs_are_named():
    geom = grid_geometry(3, 4)
    with pytest.raises(ValueError, match="12"):
        extract_features(np.zeros((2, 5, 10), np.float32), geom)
    with pytest.raises(ValueError, match="NaN"):
        extract_features(np.full((2, 5, 12), np.nan, np.float32), geom)
    with pytest.raises(ValueError, match="n_trials, L, N_taxels"):
        extract_features(np.zeros((5, 12), np.float32), geom)
    bad = TaxelGeometry(
        grid_shape=(5, 5), uv=geom.uv, position_m=geom.position_m, wrap_v=False, metres_per_u=0.03, metres_per_v=0.04
    )
    with pytest.raises(ValueError, match="grid_shape"):
        taxel_coords(bad)


def test_arm_geometry_matches_the_reference_grid():
    g = arm_geometry(18)
    assert g.grid_shape == (18, 19)
    c = taxel_coords(g)
    assert c.pitch_a_m == pytest.approx(0.241 / 18)
    assert c.pitch_b_m == pytest.approx(0.26 / 19)
    assert c.circumference_m == pytest.approx(0.26)
