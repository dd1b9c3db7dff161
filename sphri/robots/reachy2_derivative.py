"""Regenerate sphri's packaged Reachy 2 (``sphri/robots/data/reachy2/``) from Pollen Robotics' description.

    sphri derive-reachy2 src=../shared/robots/reachy2 [faces=4000] [out=DIR]

Reads ``reachy2.urdf`` and ``obj_meshes/`` of the source folder (Apache-2.0,
pollen-robotics/reachy2_mujoco; see its SOURCE.md) and writes:

- ``reachy2.urdf``: a reduced URDF: every link and joint (names, origins,
  axes, types, mimic), and for each link only the geometry sphri's loader
  uses (``geometry: auto``: collision meshes, else visual meshes, else
  collision primitives, else visual primitives); no comments, inertials,
  limits, materials, ``<gazebo>``, ``<transmission>``, ``<ros2_control>``;
- ``meshes/*.ply``: those meshes as binary PLY, each decimated to at most
  ``faces`` faces (meshes already within the budget are converted only);
- ``derivative.json`` and ``SOURCE.md``: per mesh the faces before/after and
  the surface error of the decimated mesh (max and mean distance in mm, both
  ways, between 20,000 area-weighted samples and the other surface);
- ``LICENSE``: the source's Apache-2.0 text.

Decimation is vertex clustering written here (:func:`cluster_decimate`):
trimesh's quadric decimation needs the ``fast_simplification`` package, which
is not a sphri dependency; clustering needs only numpy, is deterministic, and
its error is measured and reported. The cell size is bisected to the largest
face count within the budget.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import cast

import numpy as np
import trimesh

from sphri.args import arg

#: Default face budget per mesh.
FACE_BUDGET = 4000
#: Samples per surface for the reported error.
ERROR_SAMPLES = 20000
OUT = Path(__file__).with_name("data") / "reachy2"


def cluster_decimate(vertices: np.ndarray, faces: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering on a grid of ``cell`` metres: each occupied cell's vertices merge at their mean."""
    v = np.asarray(vertices, dtype=np.float64)
    key = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    n = int(inv.max()) + 1
    counts = np.bincount(inv, minlength=n).astype(np.float64)
    pos = np.stack([np.bincount(inv, weights=v[:, k], minlength=n) for k in range(3)], axis=1) / counts[:, None]
    f = inv[np.asarray(faces)]
    ok = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[ok]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    used = np.unique(f)
    remap = np.full(n, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return pos[used], remap[f]


def decimate_to(mesh: trimesh.Trimesh, budget: int) -> trimesh.Trimesh:
    """The clustering with the most faces within ``budget`` (bisection on the cell size)."""
    if len(mesh.faces) <= budget:
        return mesh.copy()
    lo, hi = 1e-5, float(mesh.extents.max())
    best: tuple[np.ndarray, np.ndarray] | None = None
    for _ in range(40):
        mid = np.sqrt(lo * hi)
        v, f = cluster_decimate(mesh.vertices, mesh.faces, mid)
        if len(f) <= budget:
            best, hi = (v, f), mid
        else:
            lo = mid
        if hi / lo < 1.01:
            break
    if best is None:
        raise ValueError(
            f"cannot decimate the mesh to {budget} faces: no cell size up to its extent clusters it that far"
        )
    v, f = best
    return trimesh.Trimesh(v, f, process=False)


def surface_error_mm(a: trimesh.Trimesh, b: trimesh.Trimesh, seed: int = 0) -> dict[str, float]:
    """Max and mean distance (mm) from samples of ``a`` to ``b`` and back (the larger of the two ways)."""
    out = {}
    for name, (p, q) in {"a_to_b": (a, b), "b_to_a": (b, a)}.items():
        pts = trimesh.sample.sample_surface(p, ERROR_SAMPLES, seed=seed)[0]
        _, d, _ = trimesh.proximity.closest_point(q, pts)
        out[name] = (float(d.max()) * 1e3, float(d.mean()) * 1e3)
    return {"max_mm": max(out["a_to_b"][0], out["b_to_a"][0]), "mean_mm": max(out["a_to_b"][1], out["b_to_a"][1])}


def _strip(el: ET.Element, keep: set[str]) -> None:
    for child in list(el):
        if child.tag not in keep:
            el.remove(child)


def derive(src: Path, out: Path = OUT, budget: int = FACE_BUDGET) -> dict:
    """Write the derivative (see the module docstring); returns the manifest."""
    from sphri.robots.urdf_tree import _XACRO, GEOMETRY_ORDER, MeshResolver, mesh_uri

    src = Path(src)
    urdf = src / "reachy2.urdf"
    root = ET.parse(urdf).getroot()
    resolver = MeshResolver(src)
    (out / "meshes").mkdir(parents=True, exist_ok=True)
    for old in (out / "meshes").glob("*.ply"):
        old.unlink()
    new = ET.Element("robot", {"name": root.get("name", "reachy2")})
    meshes: dict[str, dict] = {}
    for link in root.findall("link"):
        name = link.get("name", "")
        if _XACRO.search(name):
            continue
        el = ET.SubElement(new, "link", {"name": name})
        for which, kind in GEOMETRY_ORDER["auto"]:
            chosen = []
            for g in link.findall(which):
                geo = g.find("geometry")
                if geo is None or len(geo) == 0 or (geo[0].tag == "mesh") != (kind == "mesh"):
                    continue
                if kind == "mesh":
                    found = resolver.resolve(mesh_uri(geo[0].get("filename", "")))[0]
                    if found is None:
                        continue
                    key = found.stem
                    if key not in meshes:
                        meshes[key] = {"source": found.name}
                    geo[0].set("filename", f"meshes/{key}.ply")
                chosen.append(g)
            if chosen:
                for g in chosen:
                    _strip(g, {"origin", "geometry"})
                    el.append(g)
                break
    for joint in root.findall("joint"):
        _strip(joint, {"origin", "parent", "child", "axis", "mimic"})
        new.append(joint)
    for key, info in meshes.items():
        # trimesh annotates load as returning a Geometry; force="mesh" gives a Trimesh
        m = cast(trimesh.Trimesh, trimesh.load(str(src / "obj_meshes" / info["source"]), process=False, force="mesh"))
        d = decimate_to(m, budget)
        d.export(str(out / "meshes" / f"{key}.ply"), file_type="ply", encoding="binary")
        info.update(
            faces_source=int(len(m.faces)),
            faces=int(len(d.faces)),
            area_cm2_source=round(float(m.area) * 1e4, 1),
            area_cm2=round(float(d.area) * 1e4, 1),
        )
        info.update(
            {k: round(v, 3) for k, v in surface_error_mm(m, d).items()}
            if len(d.faces) < len(m.faces)
            else {"max_mm": 0.0, "mean_mm": 0.0}
        )
    ET.indent(new)
    text = (
        '<?xml version="1.0"?>\n<!-- Derived from Pollen Robotics\' Reachy 2 description (Apache-2.0; see SOURCE.md '
        "and LICENSE beside this file) by sphri.robots.reachy2_derivative. -->\n"
        + ET.tostring(new, encoding="unicode")
        + "\n"
    )
    (out / "reachy2.urdf").write_text(text)
    shutil.copyfile(src / "LICENSE", out / "LICENSE")
    manifest = {"source": str(urdf.name), "face_budget": budget, "error_samples": ERROR_SAMPLES, "meshes": meshes}
    (out / "derivative.json").write_text(json.dumps(manifest, indent=1) + "\n")
    (out / "SOURCE.md").write_text(source_md(manifest, src))
    return manifest


def source_md(manifest: dict, src: Path) -> str:
    import re

    origin = (src / "SOURCE.md").read_text() if (src / "SOURCE.md").is_file() else ""
    found = re.search(r"\b[0-9a-f]{40}\b", origin)
    when = re.search(r"\(\d{4}-\d{2}-\d{2}\)", origin[found.end() : found.end() + 20]) if found else None
    commit = f"commit {found.group(0)}{' ' + when.group(0) if when else ''}" if found else ""
    rows = "\n".join(
        f"| {k}.ply | {v['source']} | {v['faces_source']} | {v['faces']} | {v['area_cm2_source']} | {v['area_cm2']} | "
        f"{v['max_mm']:.2f} | {v['mean_mm']:.3f} |"
        for k, v in sorted(manifest["meshes"].items())
    )
    return f"""# Reachy 2 (Pollen Robotics): a compact derivative shipped with sphri

Derived from Pollen Robotics' Reachy 2 description: the public repository
pollen-robotics/reachy2_mujoco, folder `reachy2_mujoco/description/`
({commit or "commit: see the source folder SOURCE.md"}).
Copyright Pollen Robotics, licensed under the Apache License 2.0 (`LICENSE`
beside this file). Modified by sphri: the URDF is reduced (comments,
inertials, limits, materials, gazebo / transmission / ros2_control elements
removed; per link only the geometry sphri loads: collision meshes, else visual
meshes, else primitives) and the meshes are converted to binary PLY and
decimated by vertex clustering to at most {manifest["face_budget"]} faces each.

Regenerate (needs the full description, e.g. ../shared/robots/reachy2):

    sphri derive-reachy2 src=../shared/robots/reachy2 faces={manifest["face_budget"]}

Surface error of each shipped mesh against its source, from
{manifest["error_samples"]} area-weighted samples on each surface to the other
(the larger of the two directions), in mm:

| file | source | faces (source) | faces | area cm^2 (source) | area cm^2 | max error mm | mean error mm |
|---|---|---|---|---|---|---|---|
{rows}
"""


def _positive(n: int) -> str | None:
    return None if n > 0 else "must be > 0"


@dataclasses.dataclass
class DeriveArgs:
    src: Path = arg(metavar="DIR", help="folder holding reachy2.urdf, obj_meshes/ and LICENSE")
    faces: int = arg(FACE_BUDGET, check=_positive, help="face budget per mesh")
    out: Path = arg(OUT, help="output folder (default: the packaged one)")


def command(args: DeriveArgs) -> int:
    """Regenerate sphri's packaged Reachy 2 (reduced URDF, decimated PLY meshes, their measured surface error,
    licence) from Pollen Robotics' description."""
    m = derive(args.src, args.out, args.faces)
    for k, v in sorted(m["meshes"].items()):
        print(
            f"{k}: {v['faces_source']} -> {v['faces']} faces, error max {v['max_mm']:.2f} mm, mean {v['mean_mm']:.3f} mm"
        )
    return 0
