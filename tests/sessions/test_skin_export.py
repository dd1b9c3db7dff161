"""The patch export: every exported patch one connected piece on a mountable part, small pieces dropped."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import trimesh
from scipy import sparse

from sphri.robots.urdf_tree import UrdfWholeBody
from sphri.sessions.body import body_surface
from sphri.sessions.skin import connected_pieces, export_patches, make_patches

URDF = """<robot name="shells">
  <link name="base"><collision><origin xyz="0 0 0.5"/><geometry><box size="0.3 0.3 0.3"/></geometry></collision></link>
  <link name="pair"><collision><geometry><mesh filename="pair.stl"/></geometry></collision></link>
  <link name="ball"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="lid"><collision><geometry><box size="0.1 0.1 0.02"/></geometry></collision></link>
  <joint name="l" type="fixed"><parent link="base"/><child link="lid"/><origin xyz="0 0 0.66"/></joint>
  <joint name="p" type="fixed"><parent link="base"/><child link="pair"/><origin xyz="0.5 0 0.5"/></joint>
  <joint name="b" type="revolute"><parent link="base"/><child link="ball"/><origin xyz="0 0.3 0.5"/>
    <axis xyz="0 1 0"/></joint>
</robot>
"""


def box(extents, at) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=extents, transform=trimesh.transformations.translation_matrix(at))


def test_touching_shells_are_one_piece_and_apart_ones_are_not():
    a = box([0.1, 0.1, 0.1], [0, 0, 0])
    b = box([0.06, 0.06, 0.06], [0.08, 0, 0])  # its face at x = 0.05 lies on a's face: touching, no shared vertex
    c = box([0.04, 0.04, 0.04], [0.3, 0, 0])
    soup = trimesh.util.concatenate([a, b])
    assert len(connected_pieces(soup.vertices, soup.faces)) == 1
    # a triangle soup (no vertex shared between faces) is still one piece
    tri = a.vertices[a.faces].reshape(-1, 3)
    assert len(connected_pieces(tri, np.arange(len(tri)).reshape(-1, 3))) == 1
    three = trimesh.util.concatenate([a, b, c])
    pieces = connected_pieces(three.vertices, three.faces)
    assert len(pieces) == 2 and len(pieces[0]) == len(a.faces) + len(b.faces)  # largest first


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    root = tmp_path_factory.mktemp("shells")
    # one link, three shells: two 8 cm cubes 4 cm apart and a 1 cm cube off to the side
    pair = trimesh.util.concatenate(
        [box([0.08] * 3, [0, -0.06, 0]), box([0.08] * 3, [0, 0.06, 0]), box([0.01] * 3, [0, 0, 0.12])]
    )
    pair.export(root / "pair.stl")
    (root / "shells.urdf").write_text(URDF)
    parts = {"pair": {"link": "pair"}, "ball": {"link": "ball", "mountable": False}, "base": {"link": "base"}}
    robot = UrdfWholeBody(root / "shells.urdf", parts, merge={"base": ["lid"]}).build()
    body = body_surface(robot, robot.tree.links, spacing_mm=8.0, bandwidth_mm=15.0, floor_height_m=0.0)
    mountable = body.part != "ball"
    # a patch as large as the whole part: the pair link's patch spans both cubes and the small one
    patches = make_patches(body, patch_cm2=1000.0, mountable=mountable)
    k = len(patches.table)
    order = np.arange(k)
    m = sparse.csr_matrix(np.ones((4, k)))
    out = root / "export"
    export_patches(body, robot, patches, order, m, np.r_[4, np.zeros(k - 1, int)], 10.0, out, min_piece_cm2=20.0)
    return body, patches, out


def test_every_exported_patch_is_one_connected_piece_on_a_mountable_part(export):
    body, patches, out = export
    man = pd.read_csv(out / "manifest.csv")
    assert "ball" not in set(man["part"]) and "ball" not in set(patches.table["part"])
    for r in man.itertuples():
        mesh = trimesh.load(out / r.file, process=False)
        assert len(connected_pieces(mesh.vertices, mesh.faces)) == 1, r.file
        assert r.area_cm2 >= 20.0
    pair = man[man["part"] == "pair"]
    assert len(pair) == 2 and sorted(pair["piece"].str.rsplit("_", n=1).str[1]) == ["1", "2"]
    assert pair["patch"].nunique() == 1
    meta = json.loads((out / "manifest.json").read_text())
    # the 1 cm cube (6 cm^2) is dropped and counted; the contact share counts once per patch
    assert meta["dropped_pieces"] == 1 and meta["dropped_area_cm2"] == pytest.approx(6.0, rel=0.05)
    assert meta["captured"] == pytest.approx(1.0)


def test_taxels_lie_on_their_patch_at_the_pitch_with_outline_pose_and_merged_links(export):
    from scipy.spatial import cKDTree

    body, patches, out = export
    meta = json.loads((out / "manifest.json").read_text())
    assert meta["pitch_mm"] == 10.0 and meta["taxels_placed"] > 0
    for r in meta["patches"]:
        mesh = trimesh.load(out / r["file"], process=False)
        t = pd.read_csv(out / r["taxel_file"])
        pts, nrm = t[["x_m", "y_m", "z_m"]].to_numpy(), t[["nx", "ny", "nz"]].to_numpy()
        assert len(pts) == r["taxels_placed"] > 0
        # on the patch's surface (< 0.5 mm), no two closer than the pitch, and as many as the pitch allows
        _, dist, face = trimesh.proximity.closest_point(mesh, pts)
        assert dist.max() < 0.5e-3, r["piece"]
        if len(pts) > 1:
            assert cKDTree(pts).query(pts, k=2)[0][:, 1].min() >= 10e-3 * (1 - 1e-6)
        assert 0.5 * r["area_cm2"] <= len(pts) <= 1.2 * r["area_cm2"] + 1  # about one per cm^2 at 10 mm
        # unit normals, those of the faces they lie on, pointing out of the link's solid (its centre for a cube)
        assert np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-6)
        assert (np.einsum("ij,ij->i", nrm, mesh.face_normals[face]) > 0.99).mean() > 0.95
        closed = mesh.copy()
        closed.merge_vertices()
        # a closed piece (a whole cube) has no outline; an open one its boundary loops, on the piece's edges
        assert (len(r["outline_m"]) == 0) == closed.is_watertight, r["piece"]
        for loop in r["outline_m"]:
            assert len(loop) >= 3 and trimesh.proximity.closest_point(mesh, np.asarray(loop))[1].max() < 1e-6
        assert np.asarray(r["link_pose_rest"]).shape == (4, 4)
        assert r["merged_links"] == (["lid"] if r["link"] == "base" else [])
    assert any(r["outline_m"] for r in meta["patches"])
    base = next(r for r in meta["patches"] if r["link"] == "base")
    np.testing.assert_allclose(np.asarray(base["link_pose_rest"])[:3, 3], [0, 0, 0], atol=1e-9)
    pair = next(r for r in meta["patches"] if r["link"] == "pair")
    np.testing.assert_allclose(np.asarray(pair["link_pose_rest"])[:3, 3], [0.5, 0, 0.5], atol=1e-9)
