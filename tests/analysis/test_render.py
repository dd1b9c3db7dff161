"""Colour varies smoothly within the faces of a coarse mesh (Gouraud shading between vertex values), and a face
without density keeps the zero colour."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from sphri.analysis import render
from sphri.surface.density import sample_link
from sphri.types import Link


@pytest.fixture(scope="module")
def square():
    """A 10 cm square of two triangles facing +x, density on the first triangle only."""
    v = np.array([[0.0, -0.05, -0.05], [0.0, 0.05, -0.05], [0.0, 0.05, 0.05], [0.0, -0.05, 0.05]])
    link = Link("square", v, np.array([[0, 1, 2], [0, 2, 3]]), watertight=False)
    samples = sample_link(link, spacing_mm=4.0, seed=0)
    view = render.LinkView(link, samples, target_faces=1)  # no subdivision: the two faces as they are
    assert len(view.faces) == 2
    density = (samples.face == 0).astype(float)
    return view, density


def test_vertices_take_the_area_weighted_mean_of_their_faces(square):
    view, _ = square
    vals = view.spread_to_vertices(np.array([2.0, 0.0]))
    assert vals == pytest.approx([1.0, 2.0, 1.0, 0.0])  # 0 and 2 on both faces (equal areas), 1 on the first only


def test_colour_varies_across_the_shared_edge_and_the_zero_face_keeps_the_zero_colour(square):
    view, density = square
    face = view.face_values(density)
    assert face[0] > 0 and face[1] == 0
    vmax = float(face[0] * render.PERCENT_PER_CM2)
    corners = view.density_colours(density, vmax)
    zero = np.array(plt.get_cmap(render.CMAP)(0.0))
    assert not np.allclose(corners[0, 0], corners[0, 1])  # the painted face is not one flat colour
    assert np.allclose(corners[1], zero)  # the face without density: the zero colour at every corner

    # drawn: pixels along the line from the painted face's far corner to the other face's, across the shared edge
    normal = view.rotation @ np.array([1.0, 0.0, 0.0])
    azim, elev = np.degrees(np.arctan2(normal[1], normal[0])), np.degrees(np.arcsin(normal[2]))
    fig, ax = plt.subplots(figsize=(3, 3), dpi=100)
    view.draw(ax, density, azim, vmax, elev_deg=elev)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    _, right, up = view._eye(azim, elev)
    px = ax.transData.transform(np.stack([view.display @ right, view.display @ up], axis=1))
    a, b = px[1], px[3]  # far corners of face 0 and face 1; the shared edge (0-2) crosses the middle
    t = np.linspace(0.1, 0.9, 81)
    pts = a + t[:, None] * (b - a)
    h = img.shape[0]
    line = np.array([img[int(round(h - y)), int(round(x))] for x, y in pts])
    painted, other = line[t < 0.45], line[t > 0.55]
    assert len({tuple(c) for c in painted}) > 10  # a gradient inside the painted face, not one colour
    assert np.abs(np.diff(painted.sum(axis=1))).max() < 40  # and a smooth one
    assert np.abs(other - np.round(zero[:3] * 255)).max() <= 2  # the face without density: the zero colour
    plt.close(fig)


def test_flat_colours_per_face_are_still_drawn_flat(square):
    view, _ = square
    fig, ax = plt.subplots()
    view.draw(ax, None, 0.0, 1.0, colours=np.array([[1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0]]))
    from matplotlib.collections import PolyCollection

    assert isinstance(ax.collections[0], PolyCollection)
    plt.close(fig)


def test_coarse_faces_are_split_even_among_many_small_ones():
    # one 1 m triangle beside 400 tiny ones (a torso among detailed joints): already more faces than the target
    tiny = np.array([[0.0, 0.0, 0.0], [0.001, 0.0, 0.0], [0.0, 0.001, 0.0]])
    v = np.concatenate(
        [[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]] + [tiny + [0.0, 0.0, 0.01 * i] for i in range(400)]
    )
    f = np.arange(len(v)).reshape(-1, 3)
    v2, f2 = render._subdivide(v, f, area=0.5, target_faces=200)
    edges = np.linalg.norm(v2[f2][:, [1, 2, 0]] - v2[f2], axis=2).max(axis=1)
    limit = np.sqrt(4.0 * 0.5 / (np.sqrt(3.0) * 200)) * 1.2
    assert len(f2) > len(f) and edges.max() <= limit + 1e-12
