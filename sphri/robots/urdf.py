"""``UrdfRobot``: robot links read from a URDF with yourdfpy (``robot=urdf``).

Each requested link becomes one mesh in that link's own frame: the link's
``collision`` (or ``visual``) elements, each placed by its ``<origin>``, mesh
files scaled by their ``scale``. Mesh URIs (``package://pkg/dir/file``,
``file://``, relative) resolve inside the robot's folder (the URDF's folder,
or ``mesh_root``): every tail of the URI's path is tried under that folder,
then the file name is looked up anywhere below it (case-insensitively, e.g.
``.STL`` vs ``.stl``); a note records such matches. A mesh path that leaves
the folder (``..``, an absolute path, a link) is refused, named. A link whose mesh file cannot be
found falls back to its collision primitives (box, cylinder, sphere) with a
warning (without primitives: the elements found, with a warning; none: an
error naming the files tried). Joint values (``joints``) matter only for ``merge``, which adds
descendant links' geometry to a link, placed at that joint configuration;
without ``merge`` every link stays in its own frame and joints are unused.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import trimesh

from sphri.config import ConfigError, require_choice
from sphri.robots.schema import (
    BUILTIN,
    GEOMETRIES,
    UNITS,
    check_joints,
    check_link_names,
    check_merge,
    check_regions,
    check_str_map,
    unknown_links,
)
from sphri.robots.urdf_tree import (
    CYLINDER_SECTIONS,
    SPHERE_SUBDIVISIONS,
    MeshResolver,
    UrdfWholeBody,
    load_parts_spec,
    parse_urdf,
)
from sphri.robots.validate import MeshError, make_link, read_mesh
from sphri.types import Robot

log = logging.getLogger(__name__)


def mesh_files(urdf_path: Path) -> list[Path]:
    """The mesh files a URDF names that resolve to a file (its cache fingerprint covers them).

    Every ``<mesh filename=...>`` (collision and visual), resolved like the
    loader does (:class:`MeshResolver`); unresolvable names are left to the
    loader's own error or fallback.
    """
    import xml.etree.ElementTree as ET

    resolver = MeshResolver(Path(urdf_path).parent, urdf_path)
    out = []
    for el in ET.parse(urdf_path).getroot().iter("mesh"):
        name = el.get("filename")
        found = resolver.resolve(name)[0] if name else None
        if found is not None and found not in out:
            out.append(found)
    return out


def check_names(settings: Mapping[str, Any]) -> None:
    """The links a ``robot=urdf`` config names (``links``, ``exclude``, ``merge``, the parts' ``link``) are links
    of its URDF: ``sphri validate`` and every job check them before any stage runs, one line with the closest
    link name (:func:`sphri.robots.schema.check_link_names`). Reads the URDF strictly and the parts file."""
    builtin = settings.get("builtin")
    path = settings.get("path") or (BUILTIN[builtin] if builtin in BUILTIN else None)
    if path in (None, ""):
        return
    model = parse_urdf(path)
    spec = load_parts_spec(settings["parts"]) if settings.get("parts") is not None else {}

    def given(key: str) -> Any:
        return settings.get(key) if settings.get(key) is not None else spec.get(key)

    check_link_names(
        model.links, model.path, settings.get("links"), given("exclude"), given("merge"), spec.get("parts")
    )


def primitive_mesh(geometry: Any) -> trimesh.Trimesh | None:
    """Trimesh of a URDF box/cylinder/sphere geometry (metres), None for a mesh or a zero-size primitive."""
    if geometry.box is not None:
        size = np.asarray(geometry.box.size, dtype=np.float64)
        return trimesh.creation.box(extents=size) if np.all(size > 0) else None
    if geometry.cylinder is not None:
        r, h = float(geometry.cylinder.radius), float(geometry.cylinder.length)
        return trimesh.creation.cylinder(radius=r, height=h, sections=CYLINDER_SECTIONS) if r > 0 and h > 0 else None
    if geometry.sphere is not None:
        r = float(geometry.sphere.radius)
        return trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=r) if r > 0 else None
    return None


def _kind(geometry: Any) -> str:
    for k in ("mesh", "box", "cylinder", "sphere"):
        if getattr(geometry, k, None) is not None:
            return k
    return "empty"


def _builtin_digest() -> str:
    """Short hash of the descriptions shipped with sphri (a regenerated derivative changes the robot's cache keys)."""
    import hashlib

    h = hashlib.blake2b(digest_size=6)
    data = Path(__file__).with_name("data")
    for p in sorted(data.rglob("*")) if data.is_dir() else []:
        if p.is_file():
            h.update(str(p.relative_to(data)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


class UrdfRobot:
    """Links of a URDF as a :class:`Robot` (``robot=urdf``), or with ``parts`` a whole kinematic robot.

    ``path``: the URDF; ``links``: link names to load; ``regions``: skin
    region -> link; ``geometry``: ``collision`` or ``visual``; ``joints``:
    joint name -> value (radians / metres, others 0), used by ``merge``
    (link -> descendant links added to it); ``units``: auto, m, cm or mm (after
    the URDF's own mesh scale).
    """

    VERSION = "2-" + _builtin_digest()

    def __init__(
        self,
        path: str | None = None,
        links: Sequence[str] | None = None,
        regions: Mapping[str, str] | None = None,
        name: str = "urdf",
        geometry: str = "collision",
        joints: Mapping[str, float] | None = None,
        merge: Mapping[str, Sequence[str]] | None = None,
        units: str = "auto",
        builtin: str | None = None,
        parts: Any = None,
        groups: Any = None,
        rest: Any = None,
        exclude: Sequence[str] | None = None,
        mesh_root: str | None = None,
    ):
        if builtin is not None:
            require_choice("robot.builtin", builtin, list(BUILTIN))
            if path in (None, ""):
                path = str(BUILTIN[builtin])
        if path in (None, ""):
            raise ConfigError("robot.path is missing: the URDF file (or robot.builtin=reachy2)")
        self.path = str(path)
        self.name = str(name)
        self.whole_body = None
        if parts is not None:
            # a whole kinematic robot (sphri.robots.urdf_tree): every link that loads, parts from YAML
            if regions is not None:
                raise ConfigError("robot.regions must be null for a whole-body robot: regions come from robot.parts")
            self.whole_body = UrdfWholeBody(
                self.path,
                parts,
                name=self.name,
                groups=groups,
                rest=rest,
                exclude=exclude,
                merge=merge,
                links=links,
                mesh_root=mesh_root,
                geometry=str(geometry),
                units=str(units),
            )
            return
        self.mesh_root = None if mesh_root in (None, "") else Path(str(mesh_root)).expanduser()
        if links is None:
            raise ConfigError("robot.links is missing: URDF link names to load (or robot.parts for a whole-body robot)")
        self.links = [str(x) for x in links]
        self.regions = check_str_map(regions, "robot.regions", "skin region -> link")
        self.geometry = str(geometry)
        self.joints = check_joints(joints)
        self.merge = check_merge(merge, self.links)
        self.units = str(units)
        if not self.links:
            raise ConfigError("robot.links=[] is invalid: at least one URDF link name")
        if len(set(self.links)) != len(self.links):
            raise ConfigError(f"robot.links={self.links} is invalid: names must be unique")
        check_regions(self.regions, self.links)
        require_choice("robot.geometry", self.geometry, GEOMETRIES)
        require_choice("robot.units", self.units, UNITS)

    def _load(self):
        import yourdfpy

        path = Path(self.path).expanduser()
        if not path.is_file():
            raise FileNotFoundError(f"robot.path: URDF file not found: {path}")
        # yourdfpy parses in lxml's recovery mode: a truncated file would load as a silently shorter robot
        parse_urdf(path)
        try:
            urdf = yourdfpy.URDF.load(
                str(path),
                build_scene_graph=bool(self.merge),
                load_meshes=False,
                build_collision_scene_graph=False,
                load_collision_meshes=False,
            )
        except Exception as exc:
            raise ValueError(f"robot.path: cannot parse URDF {path}: {exc}") from exc
        return path, urdf

    def build(self) -> Robot:
        """The :class:`Robot`; unknown links or joints raise ``ConfigError`` listing what the URDF has.

        With ``parts``: a :class:`~sphri.robots.kinematic.WholeBodyRobot` (:mod:`sphri.robots.urdf_tree`).
        """
        if self.whole_body is not None:
            return self.whole_body.build()
        path, urdf = self._load()
        known = set(urdf.link_map)
        wanted = set(self.links) | {c for extra in self.merge.values() for c in extra}
        unknown = sorted(wanted - known)
        if unknown:
            raise unknown_links("robot.links", unknown, known, path)
        if self.joints:
            actuated = set(urdf.actuated_joint_names)
            bad = sorted(set(self.joints) - actuated)
            if bad:
                raise ConfigError(f"robot.joints: {bad} are not movable joints of {path}; they are: {sorted(actuated)}")
            if not self.merge:
                log.info("robot %s: joints are unused without robot.merge (each link is in its own frame)", self.name)
            else:
                urdf.update_cfg({k: v for k, v in self.joints.items()})
        root_dir = self.mesh_root if self.mesh_root is not None else path.parent
        if not root_dir.is_dir():
            raise FileNotFoundError(f"robot.mesh_root: folder not found: {root_dir} (meshes of {path})")
        resolver = MeshResolver(root_dir, path)
        links = {}
        for name in self.links:
            notes: list[str] = []
            parts = self._link_parts(urdf, name, resolver, notes)
            for child in self.merge.get(name, []):
                try:
                    tf = urdf.get_transform(frame_to=child, frame_from=name)
                except Exception as exc:
                    raise ConfigError(f"robot.merge.{name}: cannot place {child!r} in {name!r}'s frame: {exc}") from exc
                child_parts = self._link_parts(urdf, child, resolver, notes)
                for p in child_parts:
                    p.apply_transform(tf)
                parts += child_parts
                notes.append(f"merged link {child!r} (placed at robot.joints, others 0)")
            if not parts:
                raise MeshError(
                    f"link {name!r} of {path} has no usable {self.geometry} geometry (nor collision primitives)"
                )
            # trimesh annotates concatenate as returning a Geometry; meshes concatenate to a Trimesh
            mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(parts)) if len(parts) > 1 else parts[0]
            if len(parts) > 1:
                notes.append(f"{len(parts)} geometry elements concatenated (they may overlap)")
            links[name] = make_link(
                name,
                mesh.vertices,
                mesh.faces,
                units=self.units,
                source=f"{path.name} {self.geometry}",
                notes=notes,
                plausible=True,
            )
        return Robot(name=self.name, links=links, regions=dict(self.regions))

    def _link_parts(self, urdf: Any, name: str, resolver: MeshResolver, notes: list[str]) -> list[trimesh.Trimesh]:
        """The link's geometry elements as meshes in the link frame (metres)."""
        link = urdf.link_map[name]
        elements = link.collisions if self.geometry == "collision" else link.visuals
        parts: list[trimesh.Trimesh] = []
        missing: list[str] = []
        for el in elements:
            g = el.geometry
            if g is None or _kind(g) == "empty":
                continue
            if g.mesh is not None:
                found, tried, how = resolver.resolve(g.mesh.filename)
                if found is None:
                    missing.append(f"{g.mesh.filename} (tried {tried[0]} and {len(tried) - 1} more)")
                    continue
                if how:
                    notes.append(f"resolved {how}")
                m = read_mesh(found, f"link {name!r}: ")
                if g.mesh.scale is not None:
                    scale = np.broadcast_to(np.asarray(g.mesh.scale, dtype=np.float64), (3,))
                    m.apply_transform(np.diag(np.append(scale, 1.0)))
            else:
                prim = primitive_mesh(g)
                if prim is None:
                    notes.append(f"skipped a zero-size {_kind(g)} primitive")
                    continue
                m = prim
            if el.origin is not None:
                m.apply_transform(np.asarray(el.origin, dtype=np.float64))
            parts.append(m)
        if missing:
            fallback = []
            for el in link.collisions:
                if el.geometry is not None and el.geometry.mesh is None:
                    fb = primitive_mesh(el.geometry)
                    if fb is not None:
                        if el.origin is not None:
                            fb.apply_transform(np.asarray(el.origin, dtype=np.float64))
                        fallback.append(fb)
            if not fallback and parts:
                msg = (
                    f"{self.geometry} mesh file(s) missing ({'; '.join(missing)}) and no collision primitives: "
                    f"using the {len(parts)} element(s) found"
                )
                log.warning("robot %s: link %s: %s", self.name, name, msg)
                notes.append(msg)
                return parts
            if not fallback:
                raise FileNotFoundError(
                    f"link {name!r}: {self.geometry} mesh file(s) not found: {'; '.join(missing)}; "
                    f"and the link has no collision primitives to fall back to"
                )
            msg = (
                f"{self.geometry} mesh file(s) missing ({'; '.join(missing)}): "
                f"using the link's {len(fallback)} collision primitive(s) instead"
            )
            log.warning("robot %s: link %s: %s", self.name, name, msg)
            notes.append(msg)
            parts = fallback
        return parts
