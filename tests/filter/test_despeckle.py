"""Spatial skin filter ``filter=despeckle``: connected groups of on-taxels below a physical area are cleared."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sphri import pipeline
from sphri.adjacency import taxel_adjacency
from sphri.cache import StageCache
from sphri.config import ConfigError, compose
from sphri.filter.components import DespeckleFilter
from sphri.testing.toy_windows import arm_geometry, grid_geometry
from sphri.types import TaxelGeometry, WindowedFrames


def windows(x: np.ndarray, geom: TaxelGeometry) -> WindowedFrames:
    t = x.shape[0]
    return WindowedFrames(
        x=x.astype(np.float32),
        y=np.zeros(t, np.int64),
        groups=np.array(["a"] * t),
        geometry=geom,
        trial_row=np.arange(t, dtype=np.int64),
        n_dropped=0,
    )


def grid_frames(h: int, w: int, cells_per_frame: list[list[tuple[int, int]]]) -> np.ndarray:
    """(1, frames, h * w) binary window with the given (row, column) cells on."""
    x = np.zeros((1, len(cells_per_frame), h, w), np.float32)
    for t, cells in enumerate(cells_per_frame):
        for r, c in cells:
            x[0, t, r, c] = 1.0
    return x.reshape(1, len(cells_per_frame), h * w)


def brute_component_area(active: np.ndarray, geom: TaxelGeometry, diagonal: bool) -> np.ndarray:
    """Flood fill over the adjacency pairs, frame by frame: each active taxel's group area."""
    pairs = taxel_adjacency(geom, diagonal=diagonal).pairs
    nbr: dict[int, list[int]] = {}
    for i, j in pairs:
        nbr.setdefault(int(i), []).append(int(j))
        nbr.setdefault(int(j), []).append(int(i))
    out = np.zeros(active.shape)
    for f in range(active.shape[0]):
        seen: set[int] = set()
        for s in np.flatnonzero(active[f]):
            if s in seen:
                continue
            group, stack = [], [int(s)]
            seen.add(int(s))
            while stack:
                k = stack.pop()
                group.append(k)
                for q in nbr.get(k, []):
                    if active[f, q] and q not in seen:
                        seen.add(q)
                        stack.append(q)
            out[f, group] = geom.area_m2[group].sum()
    return out


# 10 x 10 grid of 1 cm taxels: 100 mm^2 each
PATCH = [(r, c) for r in range(3, 6) for c in range(4, 7)]  # 3 x 3 = 900 mm^2
SPECKLE = [(0, 0), (9, 9), (0, 9), (8, 1), (1, 5), (2, 5 - 3)]  # lone false taxels (none touches the patch)
PAIR = [(9, 4), (9, 5)]  # two adjacent false taxels: 200 mm^2


def test_a_real_patch_survives_and_isolated_false_taxels_are_cleared():
    geom = grid_geometry(10, 10, pitch_m=0.01, wrap=False)
    x = grid_frames(10, 10, [PATCH + SPECKLE + PAIR, SPECKLE, PATCH])
    out = DespeckleFilter(min_area_mm2=300).apply(windows(x, geom)).x
    np.testing.assert_array_equal(out, grid_frames(10, 10, [PATCH, [], PATCH]))
    # the threshold is inclusive: a group whose area equals it is kept (9 x 100 mm^2 summed in floating point)
    np.testing.assert_array_equal(DespeckleFilter(min_area_mm2=900).apply(windows(x, geom)).x, out)
    assert DespeckleFilter(min_area_mm2=901).apply(windows(x, geom)).x.sum() == 0
    # the pair is kept once the threshold is at or below its area
    kept = DespeckleFilter(min_area_mm2=200).apply(windows(x, geom)).x
    np.testing.assert_array_equal(kept, grid_frames(10, 10, [PATCH + PAIR, [], PATCH]))


def test_the_threshold_is_physical_area_not_a_taxel_count():
    """The same 4 cm^2 touch: kept on a 1 cm grid (4 taxels) and on a 0.5 cm grid (16 taxels); with 3 cm^2,
    a lone 1 cm taxel (1 cm^2) is cleared and so are 11 adjacent 0.5 cm taxels (2.75 cm^2)."""
    coarse = grid_geometry(10, 10, pitch_m=0.01)
    fine = grid_geometry(20, 20, pitch_m=0.005)
    xc = grid_frames(10, 10, [[(r, c) for r in (2, 3) for c in (2, 3)] + [(8, 8)]])
    xf = grid_frames(20, 20, [[(r, c) for r in range(4, 8) for c in range(4, 8)] + [(15, c) for c in range(11)]])
    oc = DespeckleFilter(min_area_mm2=300).apply(windows(xc, coarse)).x
    of = DespeckleFilter(min_area_mm2=300).apply(windows(xf, fine)).x
    assert oc.sum() == 4 and of.sum() == 16
    assert of[0].reshape(20, 20)[15].sum() == 0


def test_a_patch_straddling_the_seam_of_a_wrapped_grid_is_one_group():
    # rows 3-4, columns 9 and 0: 4 taxels, 400 mm^2, two halves of 200 mm^2 on either side of the seam
    seam = [(3, 9), (4, 9), (3, 0), (4, 0)]
    x = grid_frames(10, 10, [seam])
    wrapped, flat = grid_geometry(10, 10, pitch_m=0.01, wrap=True), grid_geometry(10, 10, pitch_m=0.01, wrap=False)
    np.testing.assert_array_equal(DespeckleFilter(min_area_mm2=300).apply(windows(x, wrapped)).x, x)
    assert DespeckleFilter(min_area_mm2=300).apply(windows(x, flat)).x.sum() == 0, "without wrap: two halves"
    # corner contact across the seam joins with 8-connectivity only
    diag = grid_frames(10, 10, [[(3, 9), (4, 0)]])
    np.testing.assert_array_equal(DespeckleFilter(min_area_mm2=150).apply(windows(diag, wrapped)).x, diag)
    assert DespeckleFilter(min_area_mm2=150, diagonal=False).apply(windows(diag, wrapped)).x.sum() == 0


@pytest.mark.parametrize("diagonal", [True, False])
def test_grid_path_matches_flood_fill_on_random_frames(diagonal: bool):
    """The vectorised label-and-join-the-seam path against a per-frame flood fill over the neighbour pairs."""
    rng = np.random.default_rng(3)
    geom = arm_geometry(9)  # 9 x 10 wrapped grid
    active = rng.random((40, geom.n_taxels)) < rng.uniform(0.05, 0.5, (40, 1))
    got = taxel_adjacency(geom, diagonal=diagonal).component_weight(active, geom.area_m2)
    np.testing.assert_allclose(got, brute_component_area(active, geom, diagonal), rtol=1e-12)


def test_a_scattered_layout_works_and_matches_flood_fill():
    geom = arm_geometry(14, layout="scatter", seed=2)  # jittered taxels, no grid, wrapping around the link
    assert geom.grid_shape is None
    a = geom.uv[:, 0] * 0.241
    b = geom.uv[:, 1] * 0.26
    d_b = np.abs(np.mod(b - 0.005 + 0.13, 0.26) - 0.13)  # a touch centred on the seam (b = 5 mm)
    patch = np.hypot(a - 0.12, d_b) < 0.035
    far = np.flatnonzero(np.hypot(a - 0.12, d_b) > 0.08)
    rng = np.random.default_rng(0)
    speckle = np.zeros_like(patch)
    for k in rng.permutation(far):  # lone taxels: none next to another on-taxel
        nbrs = taxel_adjacency(geom).table()[k]
        if not speckle[nbrs[nbrs >= 0]].any():
            speckle[k] = True
        if speckle.sum() == 8:
            break
    assert patch.sum() >= 10 and speckle.sum() == 8
    x = np.stack([patch | speckle, speckle])[None].astype(np.float32)
    area_one = geom.area_m2[0] * 1e6
    out = DespeckleFilter(min_area_mm2=2.5 * area_one).apply(windows(x, geom)).x
    np.testing.assert_array_equal(out[0, 0], patch.astype(np.float32))
    assert out[0, 1].sum() == 0
    active = np.random.default_rng(5).random((20, geom.n_taxels)) < 0.3
    got = taxel_adjacency(geom).component_weight(active, geom.area_m2)
    np.testing.assert_allclose(got, brute_component_area(active, geom, True), rtol=1e-12)


def test_zero_area_is_identity_and_a_tiny_area_changes_nothing():
    rng = np.random.default_rng(1)
    geom = arm_geometry(12)
    x = (rng.random((3, 7, geom.n_taxels)) < 0.2).astype(np.float32)
    w = windows(x, geom)
    assert DespeckleFilter(min_area_mm2=0).apply(w) is w
    out = DespeckleFilter(min_area_mm2=1e-3).apply(w)
    np.testing.assert_array_equal(out.x, x)
    assert out.x is not x and out.x.dtype == np.float32


def test_analogue_readings_below_threshold_are_left_and_input_untouched():
    geom = grid_geometry(6, 6, pitch_m=0.01)
    x = np.zeros((1, 1, 6, 6), np.float32)
    x[0, 0, 1:4, 1:4] = 0.8  # a 9-taxel touch
    x[0, 0, 5, 5] = 0.9  # a lone on-taxel
    x[0, 0, 0, 5] = 0.3  # below threshold: not on, left as it is
    x = x.reshape(1, 1, 36)
    before = x.copy()
    out = DespeckleFilter(min_area_mm2=250).apply(windows(x, geom)).x.reshape(6, 6)
    np.testing.assert_array_equal(x, before)
    assert out[5, 5] == 0 and out[0, 5] == pytest.approx(0.3) and np.all(out[1:4, 1:4] == pytest.approx(0.8))


def test_chunks_give_the_same_answer(monkeypatch):
    import sphri.filter.components as comp

    rng = np.random.default_rng(4)
    geom = arm_geometry(10)
    x = (rng.random((9, 6, geom.n_taxels)) < 0.25).astype(np.float32)
    whole = DespeckleFilter(min_area_mm2=700).apply(windows(x, geom)).x
    monkeypatch.setattr(comp, "_DESPECKLE_CHUNK", 2 * 6 * geom.n_taxels)  # two trials per pass
    np.testing.assert_array_equal(DespeckleFilter(min_area_mm2=700).apply(windows(x, geom)).x, whole)
    assert 0 < whole.sum() < x.sum()


def test_geometry_without_areas_is_named():
    geom = dataclasses.replace(grid_geometry(4, 4), area_m2=None)
    with pytest.raises(ValueError, match="geometry.area_m2 is None"):
        DespeckleFilter(min_area_mm2=10).apply(windows(np.ones((1, 2, 16)), geom))
    bad = dataclasses.replace(grid_geometry(4, 4), area_m2=np.full(15, 1e-4))
    with pytest.raises(ValueError, match=r"area_m2 has shape \(15,\)"):
        DespeckleFilter(min_area_mm2=10).apply(windows(np.ones((1, 2, 16)), bad))


@pytest.mark.parametrize(
    "override, key",
    [
        ("filter.min_area_mm2=-1", "filter.min_area_mm2"),
        ("filter.min_area_mm2=nan", "filter.min_area_mm2"),
        ("filter.min_area_mm2=2e6", "filter.min_area_mm2"),
        ("filter.active_threshold=0", "filter.active_threshold"),
        ("filter.active_threshold=1.5", "filter.active_threshold"),
    ],
)
def test_invalid_values_fail_at_composition_in_one_line(override: str, key: str):
    with pytest.raises(ConfigError, match=key) as err:
        compose(["filter=despeckle", override])
    assert "\n" not in str(err.value)


def test_config_composes_and_the_pipeline_windows_carry_taxel_areas(tmp_path: Path):
    cfg = compose(["filter=despeckle", "filter.min_area_mm2=150"])
    assert cfg.filter.min_area_mm2 == 150 and cfg.filter.diagonal is True
    assert compose(["filter=despeckle"]).filter.min_area_mm2 == 100.0
    exp = compose(["+experiment=despeckle_compare", "sensitivity=despeckle200"])
    assert exp.filter._target_.endswith("DespeckleFilter") and exp.filter.min_area_mm2 == 200
    assert exp.variant == "despeckle200" and exp.model._target_.endswith("RandomForest")
    assert compose(["+experiment=despeckle_compare", "sensitivity=reference"]).filter._target_.endswith("NoFilter")
    cfg = compose(
        ["+debug=fast", "tracking.enabled=false", f"cache.dir={tmp_path}", "layout.res=30", "filter=despeckle"]
    )
    p = pipeline.make_pipeline(cfg, StageCache(tmp_path))
    noisy, filtered, layout = p.get("noise"), p.get("filter"), p.get("layout")
    np.testing.assert_array_equal(filtered.geometry.area_m2, layout.area_m2)
    lone = filtered.x > noisy.x
    assert not lone.any(), "the filter only clears taxels"
    cleared = (noisy.x >= 0.5) & (filtered.x < 0.5)
    # at res 30 one taxel is about 0.7 cm^2 (< 1.5 cm^2): the 2 % noise's lone taxels are cleared
    assert cleared.sum() > 0.005 * noisy.x.size
