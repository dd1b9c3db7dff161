"""Random (Poisson-disk), density and file layouts."""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

from sphri.config import ConfigError
from sphri.layout.common import LayoutFileError, grid_equivalent_count, nn_spacing
from sphri.layout.file import FileLayout, dedupe, read_icub_positions, transform_matrix
from sphri.layout.poisson import DensityLayout, RandomLayout
from sphri.layout.units import describe
from sphri.surface.box import BoxSurface
from sphri.surface.mesh import MeshSurface
from sphri.surface.meshutil import closest_points, face_areas, link_from_trimesh


def test_random_matches_grid_count_and_is_seeded(cyl_link, cyl_map):
    a = RandomLayout(seed=1).build(cyl_link, cyl_map, 18)
    b = RandomLayout(seed=1).build(cyl_link, cyl_map, 18)
    c = RandomLayout(seed=2).build(cyl_link, cyl_map, 18)
    assert a.n_taxels == grid_equivalent_count(cyl_link, cyl_map, 18) == 18 * round(18 * cyl_map.metres_per_v / 0.24)
    np.testing.assert_array_equal(a.position_m, b.position_m)
    assert not np.array_equal(a.position_m, c.position_m)
    assert a.grid_shape is None and a.uv.shape == (a.n_taxels, 2)
    _, dist, _ = closest_points(cyl_link, a.position_m)
    assert dist.max() < 1e-9
    # Poisson-disk: no clumps. Uniform random points would have min spacing near 0.
    nn = nn_spacing(a.position_m)
    assert nn.min() > 0.45 * np.median(nn)
    assert a.area_m2.sum() == pytest.approx(face_areas(cyl_link).sum())
    d = describe(a, cyl_map)
    assert d["pitch_u_mm"] == pytest.approx(np.mean(nn) * 1e3) == pytest.approx(d["nn_spacing_mm"])
    # same density as the grid: the equivalent square pitch is the grid's (~1 cm x 1.05 cm)
    assert d["equivalent_pitch_mm"] == pytest.approx(np.sqrt(face_areas(cyl_link).sum() / a.n_taxels) * 1e3, rel=1e-6)


def test_random_on_a_chartless_surface(cyl_link):
    sm = MeshSurface().fit(cyl_link)
    lay = RandomLayout().build(cyl_link, sm, 12)
    pitch = 0.24 / 12
    assert lay.n_taxels == round(face_areas(cyl_link).sum() / pitch**2)
    assert lay.uv is None


def test_density_layout_crowds_where_touched(cyl_link, cyl_map, tmp_path):
    pts = np.column_stack([np.zeros(200), np.zeros(200), np.linspace(-0.12, 0.12, 200)])
    pts[:, 0] = 0.04
    dens = np.where(pts[:, 2] > 0, 10.0, 1.0)
    path = tmp_path / "density.npz"
    np.savez(path, points_m=pts, density=dens)
    lay = DensityLayout(density_path=str(path), seed=0).build(cyl_link, cyl_map, 18)
    assert lay.n_taxels == grid_equivalent_count(cyl_link, cyl_map, 18)
    top = (lay.position_m[:, 2] > 0).sum()
    assert top > 2.5 * (lay.n_taxels - top)


def contacts_at(points: np.ndarray, normals: np.ndarray | None = None):
    """Contacts (one per point, one frame each) at surface points with outward ``normals`` (default +x)."""
    import dataclasses

    from sphri.contact.stage import empty_contacts

    k = points.shape[0]
    base = empty_contacts(k)
    return dataclasses.replace(
        base,
        frame=np.arange(k, dtype=np.int64),
        capsule=np.zeros(k, dtype=np.int16),
        distance_m=np.zeros(k),
        inside=np.zeros(k, dtype=bool),
        point_m=points,
        segment_point_m=points,
        triangle=np.zeros(k, dtype=np.int64),
        barycentric=np.full((k, 3), 1 / 3),
        normal=np.tile([1.0, 0.0, 0.0], (k, 1)) if normals is None else normals,
        patch_radius_m=np.full(k, 0.005),
        depth_m=np.full(k, 0.001),
    )


def test_density_from_contacts_crowds_where_touched(cyl_link, cyl_map):
    rng = np.random.default_rng(0)
    # contacts on the +x side of the upper half of the cylinder (radius 0.04 m, z in -0.12..0.12)
    z = rng.uniform(0.02, 0.11, 3000)
    ang = rng.uniform(-0.6, 0.6, 3000)
    pts = np.column_stack([0.04 * np.cos(ang), 0.04 * np.sin(ang), z])
    layout = DensityLayout(seed=0)
    assert layout.uses_contacts
    lay = layout.build(cyl_link, cyl_map, 18, contacts=contacts_at(pts, normals=pts * [25.0, 25.0, 0.0]))
    assert lay.n_taxels == grid_equivalent_count(cyl_link, cyl_map, 18)
    touched = (lay.position_m[:, 2] > 0.01) & (lay.position_m[:, 0] > 0.02)
    # the touched patch is about 1/6 of the area; it gets far more than 1/6 of the taxels
    assert touched.mean() > 0.5
    again = layout.build(cyl_link, cyl_map, 18, contacts=contacts_at(pts, normals=pts * [25.0, 25.0, 0.0]))
    np.testing.assert_array_equal(lay.position_m, again.position_m)


def test_density_layout_errors(cyl_link, cyl_map, tmp_path):
    with pytest.raises(ValueError, match="needs layout.density_path"):
        DensityLayout().build(cyl_link, cyl_map, 6)
    with pytest.raises(ValueError, match="no contact on link"):
        DensityLayout().build(cyl_link, cyl_map, 6, contacts=contacts_at(np.zeros((0, 3))))
    with pytest.raises(ConfigError, match="bandwidth_mm"):
        DensityLayout(bandwidth_mm=0.0)
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        DensityLayout(density_path=str(tmp_path / "nope.npz")).build(cyl_link, cyl_map, 6)
    bad = tmp_path / "bad.npz"
    np.savez(bad, points_m=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="'density'"):
        DensityLayout(density_path=str(bad)).build(cyl_link, cyl_map, 6)


ICUB_LIKE = """name    l_forearm
spatial_sampling     taxel
taxel2Repr ( 0 0 -1 )
[calibration]
0.0500  0.0000  0.0100  1.0  0.0  0.0
0.0500  0.0000  0.0100  1.0  0.0  0.0
0.0000  0.0000  0.0000  0.0  0.0  0.0
0.0500  0.0100  0.0200  1.0  0.0  0.0
0.0500  -0.0100  -0.0200  1.0  0.0  0.0
"""


def test_file_layout_reads_dedupes_and_places(tmp_path, caplog):
    path = tmp_path / "skin.txt"
    path.write_text(ICUB_LIKE)
    pos, nrm = read_icub_positions(path)
    assert pos.shape == (4, 3)  # the all-zero row is an absent taxel
    assert dedupe(pos, nrm, 1e-5)[0].shape == (3, 3)
    link = link_from_trimesh(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), "cube")  # faces at +-0.05
    # file frame -> link frame: shift by 1 cm along y and rotate 90 deg about z
    lay_id = FileLayout(path=str(path)).build(link, BoxSurface().fit(link), 999)
    assert lay_id.n_taxels == 3 and lay_id.kind == "file" and lay_id.grid_shape is None
    np.testing.assert_allclose(lay_id.position_m[:, 0], 0.05, atol=1e-12)
    with caplog.at_level(logging.INFO):
        lay = FileLayout(path=str(path), transform=[0, 0.01, 0, 0, 0, np.pi / 2]).build(
            link, MeshSurface().fit(link), 18
        )
    assert "ignores res=18" in caplog.text
    np.testing.assert_allclose(lay.position_m[:, 1], 0.05, atol=1e-9)  # x -> y, on the +y face
    np.testing.assert_allclose(lay.normal, np.tile([0, 1, 0], (3, 1)), atol=1e-9)
    assert lay.uv is None and (lay.area_m2 > 0).all()


def test_transform_and_read_errors(tmp_path):
    np.testing.assert_allclose(transform_matrix([]), np.eye(4))
    m = transform_matrix(list(np.arange(12.0)) + [0, 0, 0, 1])
    assert m[0, 3] == 3.0
    with pytest.raises(ValueError, match="last row"):
        transform_matrix([1.0] * 16)
    with pytest.raises(ConfigError, match="layout.transform"):
        FileLayout(path="x", transform=[1.0, 2.0])
    bad = tmp_path / "bad.txt"
    bad.write_text("[calibration]\n1 2 3\n")
    with pytest.raises(ValueError, match=r"bad.txt:2"):
        read_icub_positions(bad)
    with pytest.raises(ValueError, match="layout.path is empty"):
        FileLayout().build(None, None, 18)


#: The iCub skin files are in the forearm's kinematic (DH) frame, not the URDF link frame.
#: This xyz + rpy was found by a rigid (Kabsch) fit of the 24 skin triangles' taxel centroids
#: to the URDF's l_forearm_skin_N fixed joints (triangle centres): residual 1-6 mm.
ICUB_FOREARM_TO_URDF = [0.10454, -0.00061, 0.02622, 2.91163, -0.00037, 1.56165]


@pytest.mark.shared
def test_icub_forearm_on_its_link(shared_dir, caplog):
    """The iCub forearm skin (240 taxel rows, 148 unique positions) on the iCub forearm mesh."""
    path = shared_dir / "layouts/icub_skin/positions/left_forearm_V2.txt"
    pos, nrm = read_icub_positions(path)
    assert len(pos) == 240
    uniq, _ = dedupe(pos, nrm, 0.05e-3)
    assert len(uniq) == 148
    # link frame: the URDF places the STL (mm) at this visual origin in l_forearm
    mesh = trimesh.load(shared_dir / "robots/icub/meshes/sim_sea_2-5_l_forearm_prt-binary.stl")
    mesh.apply_scale(0.001)
    mesh.apply_translation([-0.29688696737542175, 0.0, -0.07955060152271212])
    link = link_from_trimesh(mesh, "l_forearm")
    sm = MeshSurface().fit(link)
    with caplog.at_level(logging.WARNING):
        lay = FileLayout(path=str(path), transform=ICUB_FOREARM_TO_URDF, max_offset_mm=10).build(link, sm, 18)
    assert "check layout.transform" not in caplog.text
    assert lay.n_taxels == 148
    m = transform_matrix(ICUB_FOREARM_TO_URDF)
    moved = np.linalg.norm(uniq @ m[:3, :3].T + m[:3, 3] - lay.position_m, axis=1)
    assert np.median(moved) < 3e-3  # the skin lies on the forearm shell
    # file normals point away from the link's centre
    out = lay.position_m - link.vertices.mean(axis=0)
    assert (np.einsum("ij,ij->i", lay.normal, out) > 0).mean() > 0.9
    d = describe(lay, sm)
    assert 4.0 < d["pitch_u_mm"] < 9.0  # SOURCE.txt: ~6.5 mm median spacing
    # without the transform the taxels miss the link and crowd onto its nearest part: the layout says so,
    # then refuses taxels that close
    with caplog.at_level(logging.WARNING), pytest.raises(LayoutFileError, match="layout.transform"):
        FileLayout(path=str(path)).build(link, sm, 18)
    assert "check layout.transform" in caplog.text


@pytest.mark.parametrize("name", ["text.txt", "binary.txt", "junk.npz", "strings.npz", "no_normal.npz", "shape.npz"])
def test_a_layout_file_that_does_not_read_is_a_layout_file_error_naming_it(tmp_path, name):
    """Every way a layout file can fail to read raises LayoutFileError (one line ``layout file error`` at the
    command line) naming the file; a binary .txt, a non-zip .npz and non-numeric arrays were tracebacks."""
    from sphri.errors import kind_of
    from sphri.layout.common import LayoutFileError
    from sphri.layout.file import read_layout_file

    path = tmp_path / name
    if name == "text.txt":
        path.write_text("x y z\n1 2 3\n")
    elif name == "binary.txt":
        path.write_bytes(bytes(range(128, 256)) * 3)
    elif name == "junk.npz":
        path.write_text("junk\n")
    elif name == "strings.npz":
        np.savez(path, position_m=np.array([["a", "b", "c"]]), normal=np.zeros((1, 3)))
    elif name == "no_normal.npz":
        np.savez(path, position_m=np.zeros((2, 3)))
    else:
        np.savez(path, position_m=np.zeros((2, 2)), normal=np.zeros((2, 2)))
    with pytest.raises(LayoutFileError, match=name) as info:
        read_layout_file(path)
    assert kind_of(info.value) == "layout file error"
