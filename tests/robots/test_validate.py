"""Mesh validation: each defect kind on small hand-made meshes."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

from sphri.config import ConfigError
from sphri.robots.validate import (
    MeshError,
    edge_defects,
    is_closed,
    load_mesh_file,
    make_link,
    signed_volume,
)
from sphri.surface.meshutil import triangle_normals_areas as face_normals


def _box(extents=(0.1, 0.2, 0.3)):
    b = trimesh.creation.box(extents=extents)
    return np.asarray(b.vertices, dtype=np.float64), np.asarray(b.faces, dtype=np.int64)


def _outward_fraction(v, f):
    n, _ = face_normals(v, f)
    return float((np.einsum("ij,ij->i", n, v[f].mean(axis=1) - v.mean(axis=0)) > 0).mean())


def test_clean_box_untouched():
    v, f = _box()
    link = make_link("box", v, f)
    assert link.watertight and link.notes == ()
    np.testing.assert_array_equal(link.faces, f)
    assert signed_volume(link.vertices, link.faces) == pytest.approx(0.006)


def test_inverted_closed_mesh_fixed(caplog):
    v, f = _box()
    with caplog.at_level(logging.INFO, logger="sphri.robots.validate"):
        link = make_link("box", v, f[:, ::-1])
    assert signed_volume(link.vertices, link.faces) == pytest.approx(0.006)
    assert any("re-oriented 12 faces" in n for n in link.notes)
    assert "re-oriented 12 faces" in caplog.text


def test_partly_flipped_closed_mesh_fixed():
    v, f = _box()
    f = f.copy()
    f[[1, 4, 7]] = f[[1, 4, 7]][:, ::-1]
    link = make_link("box", v, f)
    assert _outward_fraction(link.vertices, link.faces) == 1.0
    assert any("re-oriented 3 faces" in n for n in link.notes)


def test_degenerate_faces_removed():
    v, f = _box()
    v = np.vstack([v, [[0.05, 0.0, 0.0], [0.05, 0.05, 0.0], [0.05, 0.1, 0.0]]])  # 3 collinear points
    n = len(v)
    bad = np.array([[0, 0, 1], [n - 3, n - 2, n - 1]])
    link = make_link("box", v, np.vstack([f, bad]))
    assert len(link.faces) == 12 and link.watertight
    assert any("removed 2 degenerate faces" in x for x in link.notes)
    assert any("removed 3 unreferenced vertices" in x for x in link.notes)


def test_duplicate_faces_removed():
    v, f = _box()
    link = make_link("box", v, np.vstack([f, f[:2], f[3:4, ::-1]]))
    assert len(link.faces) == 12 and link.watertight
    assert any("removed 3 duplicate faces" in x for x in link.notes)


def test_duplicate_vertices_merged():
    v, f = _box()
    soup_v = v[f].reshape(-1, 3)  # every face with its own vertices (like the Unity export)
    soup_f = np.arange(len(soup_v)).reshape(-1, 3)
    link = make_link("box", soup_v, soup_f)
    assert len(link.vertices) == 8 and link.watertight
    assert any("merged 28 duplicate vertices" in x for x in link.notes)


def test_open_boundary_kept():
    v, f = _box()
    link = make_link("box", v, f[2:])
    assert not link.watertight and len(link.faces) == 10
    assert edge_defects(link.faces) == (4, 0)
    assert any("not closed: 4 of 17 edges (23.5%) are boundary edges (holes)" in x for x in link.notes)


def test_open_convex_hull_faces_turned_away():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces).copy()
    f = f[10:]  # open it
    flip = np.arange(0, len(f), 7)
    f[flip] = f[flip][:, ::-1]
    link = make_link("hull", v, f)
    assert not link.watertight
    assert _outward_fraction(link.vertices, link.faces) == 1.0
    assert any(f"turned {len(flip)} inward faces" in x for x in link.notes)


def test_open_nonconvex_inverted_surface():
    # an L-shaped prism (not convex), its top cap removed, wound inside out
    poly = trimesh.path.polygons.Polygon([(0, 0), (0.2, 0), (0.2, 0.05), (0.05, 0.05), (0.05, 0.2), (0, 0.2)])
    prism = trimesh.creation.extrude_polygon(poly, height=0.1)
    v, f = np.asarray(prism.vertices), np.asarray(prism.faces)
    top = np.isclose(v[f][:, :, 2], 0.1).all(axis=1)
    open_f = f[~top]
    good = make_link("L", v, open_f)
    assert not any("re-oriented" in x for x in good.notes)
    bad = make_link("L", v, open_f[:, ::-1])
    assert any(f"re-oriented {len(open_f)} faces" in x for x in bad.notes)
    np.testing.assert_array_equal(np.sort(bad.faces, axis=1), np.sort(good.faces, axis=1))
    n_good, _ = face_normals(good.vertices, good.faces)
    n_bad, _ = face_normals(bad.vertices, bad.faces)
    np.testing.assert_allclose(n_good, n_bad)


def test_units_auto_mm(caplog):
    v, f = _box((60.0, 80.0, 240.0))  # a 24 cm arm written in millimetres
    with caplog.at_level(logging.WARNING, logger="sphri.robots.validate"):
        link = make_link("arm", v, f, units="auto")
    np.testing.assert_allclose(np.ptp(link.vertices, axis=0), [0.06, 0.08, 0.24])
    assert "millimetres" in caplog.text


def test_units_explicit():
    v, f = _box((60.0, 80.0, 240.0))
    link = make_link("arm", v, f, units="mm")
    np.testing.assert_allclose(np.ptp(link.vertices, axis=0), [0.06, 0.08, 0.24])
    assert any("units=mm" in x for x in link.notes)
    link = make_link("arm", v, f, units="m")  # kept as declared
    np.testing.assert_allclose(np.ptp(link.vertices, axis=0), [60.0, 80.0, 240.0])
    small = make_link("arm", *_box((0.06, 0.08, 0.24)), units="auto")
    assert not any("scaled" in x for x in small.notes)
    with pytest.raises(ConfigError, match="robot.units"):
        make_link("arm", v, f, units="inch")


@pytest.mark.parametrize(
    "vertices, faces, match",
    [
        (np.zeros((4, 2)), np.array([[0, 1, 2]]), r"vertices must have shape \(V, 3\)"),
        (np.eye(3), np.array([[0, 1]]), r"faces must be triangles"),
        (np.eye(3), np.array([[0, 1, 3]]), r"face indices must lie in \[0, 3\)"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]), r"1 vertices are NaN/inf"),
        (np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]]), r"no faces left"),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), r"all vertices coincide"),
    ],
)
def test_bad_input_errors(vertices, faces, match):
    with pytest.raises(MeshError, match=f"link 'x' \\(src.obj\\): {match}"):
        make_link("x", vertices, faces, source="src.obj")


def test_load_mesh_file_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match=f"robot.links.arm: mesh file not found: {tmp_path}/a.obj"):
        load_mesh_file(tmp_path / "a.obj", "arm", key="robot.links.arm")
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\n")
    with pytest.raises(MeshError, match="empty.obj"):
        load_mesh_file(empty, "arm")


def test_helpers():
    v, f = _box()
    assert is_closed(f) and not is_closed(f[1:])
    assert edge_defects(np.vstack([f, f[:1]])) == (0, 3)
