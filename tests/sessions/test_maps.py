"""Whole-body maps a designer reads at a glance: no contact drawn apart from the colour scale, one scale shared by
every scenario's figure, views cropped to the robot."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest

from sphri.sessions import render
from sphri.sessions.body import body_surface


@pytest.fixture(scope="module")
def view(small):
    _, _, robot, ds = small
    body = body_surface(robot, ds.links, 20.0, 30.0, 0)
    return render.body_view(body, 3000), body


def test_no_contact_is_grey_and_the_least_contact_is_coloured(view):
    v, body = view
    d = np.zeros(body.samples.n)
    d[body.part == body.parts[0]] = 1.0
    c = render.contact_colours(v, d, vmax=float(d.max() * render.PERCENT_PER_CM2))
    vals = v.face_values(d)
    none = vals < render.NONE_SHARE * vals.max()
    assert none.any() and (~none).any()
    assert np.allclose(c[none], render.NO_CONTACT)
    low = render.contact_colours(v, d * 1e-2, vmax=float(d.max() * render.PERCENT_PER_CM2))
    some = vals >= 0.5 * vals.max()
    grey = np.array(render.NO_CONTACT)
    # a density of 1 % of the scale's top is coloured (the scale starts at a visible yellow), not grey
    assert (np.abs(low[some] - grey).max(axis=1) > 0.1).all()
    assert not np.allclose(low[some, 0], low[some, 2])


def test_each_scenarios_figure_uses_the_scale_it_is_given(view, tmp_path, monkeypatch):
    v, body = view
    seen = []
    monkeypatch.setattr(render, "_contact_bar", lambda fig, vmax, ax: seen.append(vmax))
    d = np.linspace(0.0, 1.0, body.samples.n)
    render.plot_views(v, {"S1": d}, tmp_path / "a.png", "S1", vmax=0.5)
    render.plot_views(v, {"S1": d}, tmp_path / "b.png", "S1")
    assert seen[0] == 0.5 and seen[1] == pytest.approx(render._vmax([d]))


def test_views_are_cropped_to_the_robot(view):
    v, _ = view
    for _name, az, el in render.VIEWS:
        fig, ax = plt.subplots()
        v.draw(ax, None, az, 1.0, elev_deg=el, colours=np.ones((len(v.faces), 4)))
        render._crop(ax, v, az, el)
        _, right, up = v._eye(az, el)
        x, y = v.display @ right, v.display @ up
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 <= x.min() and x1 >= x.max() and y0 <= y.min() and y1 >= y.max()
        assert (x1 - x0) <= 1.07 * max(np.ptp(x), np.ptp(y)) and (y1 - y0) <= 1.07 * max(np.ptp(x), np.ptp(y))
        plt.close(fig)


def test_gesture_histogram_sets_drawn_beside_coded_on_an_axis_that_fits(tmp_path, monkeypatch):
    import pandas as pd

    from sphri.types import GESTURES

    figs = []
    monkeypatch.setattr(render, "_finish", lambda fig, title, path, provenance: figs.append(fig) or path)
    hist = pd.DataFrame(
        [
            dict(scenario=s, gesture=g, n_episodes=10, expected=3.0 if g == "poke" else 1.0, expected_sd=0.5, count=4)
            for s in ("S1_attention", "S2_path_redirection")
            for g in GESTURES
        ]
    )
    coded = pd.DataFrame({"session": [0, 1, 2, 3], "scenario": ["S1_attention"] * 2 + ["S2_path_redirection"] * 2})
    truth = pd.DataFrame({"gesture": ["push", "push", "tap", "grab"]})
    drawn = render.drawn_shares(coded, truth)
    assert drawn.groupby("scenario")["share"].sum().tolist() == [1.0, 1.0]
    render.plot_gesture_histogram(hist, tmp_path / "g.png", "Gestures", drawn=drawn)
    ax = figs[-1].axes[0]
    assert ax.get_ylim()[1] == 1.0  # the drawn push share (1.0) is the highest bar; shares end at 1
    labels = [t.get_text() for t in figs[-1].legends[0].get_texts()]
    assert sorted(labels) == ["coded: argmax share", "coded: expected (sum of probabilities)", "drawn by the generator"]
    heights = sorted(round(p.get_height(), 3) for p in ax.patches)
    assert heights.count(1.0) == 1 and heights.count(0.3) == 1
    render.plot_gesture_histogram(hist[hist["scenario"] == "S1_attention"], tmp_path / "h.png", "Gestures")
    assert figs[-1].axes[0].get_ylim()[1] == pytest.approx(1.1 * 0.4)  # bars under 0.45: the axis ends near them
    plt.close("all")


def test_atlas_titles_give_the_reachable_area_the_ranking_counts(small, view, tmp_path, monkeypatch):
    _, _, robot, _ = small
    _, body = view
    figs = []
    said = []
    monkeypatch.setattr(
        render, "_finish", lambda fig, title, path, provenance: figs.append(fig) or said.append(title) or path
    )
    render.plot_atlas(body, np.zeros(body.samples.n), tmp_path / "a.png", "Atlas")
    reach = body.part_area_m2(reachable=True)
    titles = [ax.get_title() for ax in figs[-1].axes if ax.get_title()]
    assert len(titles) == len(body.parts)
    for p, title in zip(body.parts, titles):
        assert title.endswith(f"({reach[p] * 1e4:.0f} cm$^2$)"), (p, title)
    assert said[-1].endswith("cm$^2$: reachable area)")
    assert any(reach[p] < body.part_area_m2()[p] * 0.99 for p in body.parts)  # some area is out of reach
    plt.close("all")


def test_views_shade_smoothly_within_faces_and_keep_no_contact_grey(view):
    from matplotlib.collections import TriMesh

    v, body = view
    d = np.zeros(body.samples.n)
    d[body.part == body.parts[0]] = np.linspace(0.0, 1.0, int((body.part == body.parts[0]).sum()))
    vmax = float(d.max() * render.PERCENT_PER_CM2)
    flat = render.contact_colours(v, d, vmax)
    c = render.contact_colours(v, d, vmax, smooth=True)
    assert c.shape == (len(v.faces), 3, 4)
    none = np.all(np.isclose(flat, render.NO_CONTACT), axis=1)
    assert none.any() and (~none).any()
    assert np.allclose(c[none], render.NO_CONTACT)  # no contact: grey at every corner
    grey = np.abs(c[~none] - np.array(render.NO_CONTACT)).max(axis=2) < 1e-9
    assert not grey.any()  # contact: on the colour scale at every corner, never grey
    assert (np.ptp(c[~none], axis=1).max(axis=1) > 0.01).mean() > 0.2  # colour varies within faces
    fig, ax = plt.subplots()
    v.draw(ax, None, 0.0, vmax, colours=c)
    assert isinstance(ax.collections[0], TriMesh)
    plt.close(fig)


def test_chart_frame_gives_a_part_and_its_mirror_image_the_same_chart():
    rng = np.random.default_rng(0)
    # an arm on the robot's left: long axis tilted down and forward, off the midplane
    pts = rng.normal(size=(400, 3)) * [0.03, 0.03, 0.15] @ np.array([[1, 0, 0], [0, 1, 0.2], [0.3, 0, 1]])
    left = pts + [0.05, 0.25, 0.8]
    right = left * [1.0, -1.0, 1.0]
    (cl, al), (cr, ar) = render.chart_frame(left), render.chart_frame(right)
    assert np.allclose(ar, al * [1.0, -1.0, 1.0]) and np.allclose(cr, cl * [1.0, -1.0, 1.0])
    for a, b in zip(render.unroll(left, (cl, al)), render.unroll(right, (cr, ar))):
        assert np.allclose(a, b)
    assert al[0][2] > 0  # along: up
    ang, _ = render.unroll(cl + np.array([[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]]), (cl, al))
    assert ang[0] == pytest.approx(0.0, abs=1.0) and ang[1] == pytest.approx(90.0, abs=20.0)  # front, outer side
    ang, _ = render.unroll(cr + np.array([[0.0, -0.1, 0.0]]), (cr, ar))
    assert ang[0] == pytest.approx(90.0, abs=20.0)  # the right arm's outer side (-y) is +90 too
    # a round link (a ball) runs along the vertical, whatever its sampling
    ball = rng.normal(size=(500, 3))
    ball /= np.linalg.norm(ball, axis=1, keepdims=True)
    assert np.allclose(render.chart_frame(ball * 0.05 + [0, 0.2, 1.0])[1][0], [0, 0, 1])


def test_atlas_draws_left_and_right_parts_alike(view, small, tmp_path, monkeypatch):
    _, _, robot, _ = small
    _, body = view
    figs = []
    monkeypatch.setattr(render, "_finish", lambda fig, title, path, provenance: figs.append(fig) or path)
    render.plot_atlas(body, np.ones(body.samples.n), tmp_path / "a.png", "Atlas")
    axes = {p: ax for p, ax in zip(body.parts, [a for a in figs[-1].axes if a.get_title()])}
    pairs = [(p, p[:-2] + "_r") for p in body.parts if p.endswith("_l") and p[:-2] + "_r" in axes]
    assert len(pairs) >= 4
    world, area = body.samples.points_m, body.samples.area_m2
    for left, right in pairs:  # the links' charts: mirror images of each other
        (_, al), (_, ar) = (
            render.chart_frame(
                world[body.offset[li] : body.offset[li + 1]], area[body.offset[li] : body.offset[li + 1]]
            )
            for li in (int(body.link_of[body.part == p][0]) for p in (left, right))
        )
        assert np.abs(ar - al * [1.0, -1.0, 1.0]).max() < 0.1, (left, right)
    for left, right in pairs:
        a, b = (np.asarray(axes[p].collections[0].get_offsets()) for p in (left, right))
        # the same along-axis range (not mirrored: -10..-5 against 5..10)
        assert np.percentile(a[:, 1], [10, 90]) == pytest.approx(np.percentile(b[:, 1], [10, 90]), abs=2.5)
        assert axes[left].get_ylim() == pytest.approx(axes[right].get_ylim(), abs=2.0), (left, right)
        # around: the front at 0 deg and the outer side (away from the midplane) at +90 deg on both sides
        for p, off in ((left, a), (right, b)):
            pts = world[body.part == p]
            for coord, deg in ((np.abs(pts[:, 1]), 90.0), (pts[:, 0], 0.0)):
                top = coord >= np.percentile(coord, 75)
                mean = np.degrees(np.angle(np.exp(1j * np.radians(off[top, 0])).mean()))
                assert abs((mean - deg + 180) % 360 - 180) < 45, (p, deg, mean)
    plt.close("all")
