"""sphri.adjacency: the one definition of neighbouring taxels (grids, the v seam, scattered layouts)."""

import numpy as np
import pytest
from scipy import ndimage

from sphri.adjacency import grid_adjacency, point_adjacency, taxel_adjacency
from sphri.testing.toy_windows import grid_geometry
from sphri.types import TaxelGeometry


def pair_set(adj):
    return {tuple(p) for p in adj.pairs.tolist()}


def test_grid_neighbours_by_hand():
    # 3 x 4 grid, indices row-major: taxel 5 is row 1, column 1
    four = grid_adjacency((3, 4), wrap_v=False, diagonal=False)
    assert {j for i, j in pair_set(four) if i == 5} | {i for i, j in pair_set(four) if j == 5} == {1, 4, 6, 9}
    eight = grid_adjacency((3, 4), wrap_v=False, diagonal=True)
    nb5 = {j for i, j in pair_set(eight) if i == 5} | {i for i, j in pair_set(eight) if j == 5}
    assert nb5 == {0, 1, 2, 4, 6, 8, 9, 10}
    # corner 3 (row 0, column 3): no wrap -> 3 neighbours; wrap -> column 0 joins (0, 4; 4 and 7 diagonally)
    assert set(eight.table()[3]) - {-1} == {2, 6, 7}
    wrapped = grid_adjacency((3, 4), wrap_v=True, diagonal=True)
    assert set(wrapped.table()[3]) - {-1} == {2, 6, 7, 0, 4}
    assert len(pair_set(four)) == 3 * 3 + 2 * 4  # horizontal + vertical edges
    assert all(i < j for i, j in pair_set(wrapped))


@pytest.mark.parametrize("shape", [(1, 1), (1, 2), (2, 1), (3, 2), (4, 1)])
def test_tiny_grids_have_no_self_or_double_pairs(shape):
    for wrap in (False, True):
        for diagonal in (False, True):
            adj = grid_adjacency(shape, wrap, diagonal)
            p = adj.pairs
            assert np.all(p[:, 0] < p[:, 1]) and len(pair_set(adj)) == p.shape[0]
            assert adj.table().shape[0] == shape[0] * shape[1]


@pytest.mark.parametrize("diagonal", [False, True])
@pytest.mark.parametrize("wrap", [False, True])
def test_grid_components_agree_with_the_general_graph_and_with_ndimage(wrap, diagonal):
    rng = np.random.default_rng(0)
    h, w = 7, 9
    frames = (rng.random((200, h * w)) < 0.35).astype(np.float64) * rng.random((200, h * w))
    adj = grid_adjacency((h, w), wrap, diagonal)
    graph = type(adj)(adj.n_taxels, adj.pairs, None, False, False, 0.0)  # the general path on the same pairs
    np.testing.assert_allclose(adj.largest_component(frames), graph.largest_component(frames), rtol=1e-12)
    if not wrap:  # without the seam, ndimage alone is the reference
        struct = ndimage.generate_binary_structure(2, 2 if diagonal else 1)
        for f in frames[:20]:
            lab, n = ndimage.label(f.reshape(h, w) > 0, structure=struct)
            ref = max((f.reshape(h, w)[lab == k].sum() for k in range(1, n + 1)), default=0.0)
            assert adj.largest_component(f[None])[0] == pytest.approx(ref)


def test_a_touch_across_the_seam_is_one_group():
    h, w = 4, 10
    f = np.zeros((1, h * w))
    f[0, [1 * w + 0, 1 * w + 9, 2 * w + 9]] = 1  # columns 0 and 9 of rows 1-2
    assert taxel_adjacency(grid_geometry(h, w, wrap=True)).largest_component(f)[0] == 3
    assert taxel_adjacency(grid_geometry(h, w, wrap=False)).largest_component(f)[0] == 2


def test_scattered_layouts_use_the_radius_rule_and_wrap():
    # points on a circle of circumference 1 (b wraps): first and last are neighbours
    b = np.linspace(0, 1, 20, endpoint=False)
    pts = np.column_stack([np.zeros(20), b])
    ring = point_adjacency(pts, period=1.0)
    assert ring.spacing_m == pytest.approx(0.05)
    assert (0, 19) in pair_set(ring) and ring.pairs.shape[0] == 20
    line = point_adjacency(pts)
    assert (0, 19) not in pair_set(line) and line.pairs.shape[0] == 19
    # a grid given without grid_shape finds the grid's edge neighbours (diagonals are 1.41 > 1.5? no: inside)
    g = grid_geometry(5, 6, wrap=False, grid=False)
    adj = taxel_adjacency(g)
    assert adj.grid_shape is None
    assert pair_set(grid_adjacency((5, 6), False, True)) == pair_set(adj)


def test_bad_geometry_is_named():
    with pytest.raises(ValueError, match="grid_shape"):
        taxel_adjacency(TaxelGeometry((2, 3), None, np.zeros((5, 3)), False, 0.0, 0.0))
    with pytest.raises(ValueError, match="weights must be"):
        grid_adjacency((2, 2), False, True).largest_component(np.zeros((1, 5)))
