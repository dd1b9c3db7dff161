"""A whole robot from a real-world URDF: its kinematic tree, every link that loads, body parts from YAML.

``robot=urdf robot.path=FILE robot.parts=PARTS.yaml`` (and ``robot=reachy2``,
the packaged Reachy 2) build a :class:`~sphri.robots.kinematic.WholeBodyRobot`
through :class:`UrdfWholeBody`:

1. :func:`parse_urdf` reads the file with the standard library's XML parser,
   strictly: a truncated or malformed file is refused with one line naming it
   and the line/column (no "recovery mode" that would silently drop the end of
   the robot). Comments, ``<gazebo>``, ``<transmission>``, ``<ros2_control>``
   and other non-URDF elements are ignored. Links with an unexpanded xacro name
   (``${name}_dummy_link3``) and repeated link names are skipped, named.
2. Each link's surface comes from the first of these that loads
   (``geometry: auto``): its collision meshes, its visual meshes, its
   collision primitives (box, cylinder, sphere), its visual primitives
   (``collision`` / ``visual`` restrict to one kind). Mesh URIs
   (``package://pkg/...``, ``file://$(find pkg)/...``, relative paths) resolve
   against ``mesh_root`` (default: the URDF's folder) with
   :class:`MeshResolver` (tails of the path, then the file
   name anywhere below the root); a mesh path that leaves that folder is
   refused, named.
3. Links without any loadable geometry (dummy, camera and tip frames; meshes
   of absent ROS packages) are *skipped*; so are ``exclude``-d links and links
   not connected to the root. A ``merge``-d link's geometry joins an ancestor
   link at the rest pose. The kinematic tree keeps only surface links: the
   joints between two of them (fixed transforms, revolute / continuous joints
   about any axis, prismatic joints, ``mimic`` joints) become
   :class:`~sphri.robots.kinematic.JointStep` chains, so the skipped frames
   still place the links correctly.
4. :attr:`WholeBodyRobot.skipped` lists every skipped link with the reason
   (``(link, reason)``); the log gives the counts.

Body parts and groups are the same YAML as ``robot=reachy_full``'s
(:func:`sphri.robots.kinematic.check_parts`): ``parts`` may be given inline
or as a YAML file holding ``parts``, ``groups`` and optionally ``rest``,
``exclude`` and ``merge``.
"""

from __future__ import annotations

import logging
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, cast

import numpy as np
import trimesh
import yaml

from sphri.config import ConfigError, require_choice
from sphri.robots.kinematic import (
    JointStep,
    JointTree,
    WholeBodyRobot,
    check_parts,
    joint_motion,
    mimic_value,
    part_regions,
    rpy_matrix,
)
from sphri.robots.schema import check_groups, check_link_names
from sphri.robots.validate import MeshError, make_link, read_mesh
from sphri.types import Link

log = logging.getLogger(__name__)

#: Geometry preference orders (see the module docstring).
GEOMETRY_ORDER = {
    "auto": (("collision", "mesh"), ("visual", "mesh"), ("collision", "primitive"), ("visual", "primitive")),
    "collision": (("collision", "mesh"), ("collision", "primitive")),
    "visual": (("visual", "mesh"), ("visual", "primitive")),
}
MOVABLE = ("revolute", "continuous", "prismatic")
JOINT_TYPES = MOVABLE + ("fixed", "floating", "planar")
_XACRO = re.compile(r"\$\{|\$\(")
_FIND = re.compile(r"^(?:file://)?\$\(find ([^)]+)\)/?")


class RobotFileError(MeshError):
    """A robot description (URDF or parts YAML) cannot be read; the message names the file."""


@dataclass
class Geometry:
    kind: str  # mesh | box | cylinder | sphere
    origin: np.ndarray
    filename: str = ""
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    size: tuple[float, ...] = ()


@dataclass
class UrdfLink:
    name: str
    collision: list[Geometry] = field(default_factory=list)
    visual: list[Geometry] = field(default_factory=list)


@dataclass
class UrdfJoint:
    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)
    mimic: tuple[str, float, float] | None = None


@dataclass
class UrdfModel:
    """A parsed URDF: links, the joint leading to each child link, the root, and what was skipped."""

    path: Path
    name: str
    links: dict[str, UrdfLink]
    joint_of: dict[str, UrdfJoint]
    """Child link -> the joint whose child it is."""
    root: str
    skipped: list[tuple[str, str]]
    notes: list[str]

    def path_from(self, ancestor: str, link: str) -> list[UrdfJoint]:
        """Joints from ``ancestor`` down to ``link`` (top first); ValueError when ``ancestor`` is not above it."""
        out = []
        cur = link
        while cur != ancestor:
            j = self.joint_of.get(cur)
            if j is None:
                raise ValueError(f"{ancestor!r} is not an ancestor of {link!r}")
            out.append(j)
            cur = j.parent
        return out[::-1]


def _floats(text: str | None, n: int, where: str, path: Path, default: Sequence[float]) -> tuple[float, ...]:
    if text is None:
        return tuple(float(x) for x in default)
    try:
        vals = tuple(float(x) for x in text.split())
    except ValueError:
        raise RobotFileError(f"{path}: {where}={text!r} is not {n} numbers") from None
    if len(vals) == 1 and n == 3 and where.endswith("scale"):
        vals = vals * 3
    if len(vals) != n or not all(np.isfinite(vals)):
        raise RobotFileError(f"{path}: {where}={text!r} is not {n} finite numbers")
    return vals


def _floats3(text: str | None, where: str, path: Path, default: Sequence[float]) -> tuple[float, float, float]:
    """:func:`_floats` of three numbers (it checks the count), typed as a triple."""
    x, y, z = _floats(text, 3, where, path, default)
    return x, y, z


def _origin(el: ET.Element | None, where: str, path: Path) -> np.ndarray:
    m = np.eye(4)
    if el is None:
        return m
    xyz = _floats(el.get("xyz"), 3, f"{where} origin xyz", path, (0, 0, 0))
    rpy = _floats(el.get("rpy"), 3, f"{where} origin rpy", path, (0, 0, 0))
    m[:3, :3] = rpy_matrix(rpy)
    m[:3, 3] = xyz
    return m


def _geometries(link: ET.Element, tag: str, name: str, path: Path) -> list[Geometry]:
    out = []
    for el in link.findall(tag):
        g = el.find("geometry")
        if g is None or len(g) == 0:
            continue
        shape = g[0]
        where = f"link {name!r} {tag}"
        origin = _origin(el.find("origin"), where, path)
        if shape.tag == "mesh":
            out.append(
                Geometry(
                    "mesh",
                    origin,
                    filename=str(shape.get("filename", "")),
                    scale=_floats3(shape.get("scale"), f"{where} mesh scale", path, (1, 1, 1)),
                )
            )
        elif shape.tag == "box":
            out.append(
                Geometry("box", origin, size=_floats(shape.get("size"), 3, f"{where} box size", path, (0, 0, 0)))
            )
        elif shape.tag == "cylinder":
            r = _floats(shape.get("radius"), 1, f"{where} cylinder radius", path, (0,))
            h = _floats(shape.get("length"), 1, f"{where} cylinder length", path, (0,))
            out.append(Geometry("cylinder", origin, size=(r[0], h[0])))
        elif shape.tag == "sphere":
            out.append(
                Geometry("sphere", origin, size=_floats(shape.get("radius"), 1, f"{where} sphere radius", path, (0,)))
            )
    return out


def parse_urdf(path: str | Path) -> UrdfModel:
    """Read a URDF strictly (see the module docstring); :class:`RobotFileError` names the file on any defect."""
    path = Path(path).expanduser()
    root = _robot_element(path)
    skipped: list[tuple[str, str]] = []
    notes: list[str] = []
    links = _read_links(root, path, skipped, notes)
    joint_of: dict[str, UrdfJoint] = {}
    for el in root.findall("joint"):
        joint = _read_joint(el, path, links, joint_of, notes)
        if joint is not None:
            joint_of[joint.child] = joint
    _refuse_cycles(path, links, joint_of)
    root_link = _root_link(links, joint_of, skipped)
    return UrdfModel(path, str(root.get("name", path.stem)), links, joint_of, root_link, skipped, notes)


def _robot_element(path: Path) -> ET.Element:
    """The ``<robot>`` element of the URDF file at ``path``; FileNotFoundError or :class:`RobotFileError`."""
    if not path.is_file():
        raise FileNotFoundError(f"robot.path: URDF file not found: {path}")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise RobotFileError(f"{path}: not a well-formed URDF (XML error {exc}; truncated or corrupt?)") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise RobotFileError(f"{path}: not a readable URDF ({exc})") from None
    if root.tag != "robot":
        raise RobotFileError(f"{path}: the root element is <{root.tag}>, a URDF's is <robot>")
    return root


def _read_links(root: ET.Element, path: Path, skipped: list[tuple[str, str]], notes: list[str]) -> dict[str, UrdfLink]:
    """The ``<link>`` elements of ``root`` by name; unnamed, xacro-named and repeated ones are skipped
    (appended to ``notes`` or ``skipped``). Refuses a file without links."""
    links: dict[str, UrdfLink] = {}
    for el in root.findall("link"):
        name = str(el.get("name", ""))
        if not name:
            notes.append("a <link> without a name was ignored")
            continue
        if _XACRO.search(name):
            skipped.append((name, "unexpanded xacro name"))
            continue
        if name in links:
            skipped.append((name, "repeated link name (the first one is kept)"))
            continue
        links[name] = UrdfLink(name, _geometries(el, "collision", name, path), _geometries(el, "visual", name, path))
    if not links:
        raise RobotFileError(f"{path}: no <link> elements")
    return links


def _read_joint(
    el: ET.Element, path: Path, links: Mapping[str, UrdfLink], joint_of: Mapping[str, UrdfJoint], notes: list[str]
) -> UrdfJoint | None:
    """The ``<joint>`` element ``el`` (floating, planar and zero-axis joints held fixed), or None when it is
    ignored (a link not loaded, a child that already has a parent joint in ``joint_of``): said in ``notes``."""
    name = str(el.get("name", ""))
    kind = str(el.get("type", ""))
    p, c = el.find("parent"), el.find("child")
    parent = p.get("link") if p is not None else None
    child = c.get("link") if c is not None else None
    if kind not in JOINT_TYPES:
        raise RobotFileError(f"{path}: joint {name!r} has type={kind!r}; URDF types: {list(JOINT_TYPES)}")
    if parent is None or child is None or parent not in links or child not in links:  # None: no such element
        bad = parent if parent not in links else child
        notes.append(f"joint {name!r} ignored: link {bad!r} is not a loaded link")
        return None
    if child in joint_of:
        notes.append(f"joint {name!r} ignored: link {child!r} already has a parent joint {joint_of[child].name!r}")
        return None
    ax = el.find("axis")
    axis = _floats3(ax.get("xyz") if ax is not None else None, f"joint {name!r} axis", path, (1, 0, 0))
    if kind in MOVABLE and not np.linalg.norm(axis) > 0:
        notes.append(f"joint {name!r}: zero axis, held fixed")
        kind = "fixed"
    if kind in ("floating", "planar"):
        notes.append(f"joint {name!r}: {kind} joint held fixed at its origin")
        kind = "fixed"
    mim = el.find("mimic")
    mimic = None
    if mim is not None and kind in MOVABLE:
        mult = _floats(mim.get("multiplier"), 1, f"joint {name!r} mimic multiplier", path, (1,))[0]
        off = _floats(mim.get("offset"), 1, f"joint {name!r} mimic offset", path, (0,))[0]
        mimic = (str(mim.get("joint", "")), mult, off)
    origin = _origin(el.find("origin"), f"joint {name!r}", path)
    return UrdfJoint(name, kind, parent, child, origin, axis, mimic)


def _refuse_cycles(path: Path, links: Mapping[str, UrdfLink], joint_of: Mapping[str, UrdfJoint]) -> None:
    """Raise :class:`RobotFileError` when the joints form a cycle (every link of it would have a parent):
    walks up from each link."""
    for start in links:
        seen, cur = set(), start
        while cur in joint_of:
            if cur in seen:
                raise RobotFileError(f"{path}: the joints form a cycle through link {cur!r}")
            seen.add(cur)
            cur = joint_of[cur].parent


def _root_link(links: Mapping[str, UrdfLink], joint_of: Mapping[str, UrdfJoint], skipped: list[tuple[str, str]]) -> str:
    """The root: the parentless link with the largest subtree; the links under other parentless links are
    appended to ``skipped``."""
    roots = [n for n in links if n not in joint_of]

    def size(r: str) -> int:
        return sum(1 for n in links if _root_of(n, joint_of) == r)

    root_link = max(roots, key=size)
    for r in roots:
        if r != root_link:
            for n in links:
                if _root_of(n, joint_of) == r:
                    skipped.append((n, f"not connected to the root link {root_link!r}"))
    return root_link


def _root_of(link: str, joint_of: Mapping[str, UrdfJoint]) -> str:
    while link in joint_of:
        link = joint_of[link].parent
    return link


#: Segments around a cylinder primitive; subdivisions of a sphere primitive.
CYLINDER_SECTIONS = 32
SPHERE_SUBDIVISIONS = 2


class MeshResolver:
    """Finds the files behind a URDF's mesh URIs (``package://pkg/dir/file``, ``file://``, relative) inside
    the robot's folder ``urdf_dir`` (the URDF's folder, or ``robot.mesh_root``): every tail of the URI's path
    under that folder, then the file name anywhere below it (case-insensitively, e.g. ``.STL`` vs ``.stl``);
    the note names such a match. Nothing outside the folder is ever used: a URI with ``..``, an absolute
    path or a link that leads out of it is a :class:`RobotFileError` naming the URI, the folder and
    ``source`` (the URDF)."""

    def __init__(self, urdf_dir: Path, source: Path | str | None = None):
        self.dir = urdf_dir
        self.source = source

    @cached_property
    def _root(self) -> Path:
        return Path(self.dir).resolve()

    def _inside(self, p: Path) -> bool:
        real = p.resolve()
        return real == self._root or self._root in real.parents

    def _refuse(self, uri: str, where: str) -> RobotFileError:
        src = f"{self.source}: " if self.source is not None else ""
        return RobotFileError(
            f"{src}mesh {uri!r} {where}, outside the robot's folder {self.dir}; meshes must lie inside it "
            "(or inside robot.mesh_root)"
        )

    @cached_property
    def _by_name(self) -> dict[str, list[Path]]:
        index: dict[str, list[Path]] = {}
        for p in sorted(self.dir.rglob("*")):
            if p.is_file() and self._inside(p):
                index.setdefault(p.name.lower(), []).append(p)
        return index

    def resolve(self, uri: str) -> tuple[Path | None, list[Path], str]:
        """``(path or None, candidates tried, note)``; the note is empty for a direct hit."""
        rel = uri
        for prefix in ("package://", "file://", "model://"):
            if rel.startswith(prefix):
                rel = rel[len(prefix) :]
                break
        direct = Path(rel)
        if ".." in direct.parts:
            raise self._refuse(uri, "climbs out with '..'")
        if direct.is_absolute() and direct.is_file() and self._inside(direct):
            return direct, [direct], ""
        parts = direct.parts[1:] if direct.is_absolute() else direct.parts
        tried = []
        for k in range(len(parts)):
            cand = self.dir / Path(*parts[k:])
            tried.append(cand)
            if cand.is_file():
                if not self._inside(cand):
                    raise self._refuse(uri, f"resolves through a link to {cand.resolve()}")
                return cand, tried, "" if k == 0 else f"{uri} -> {cand}"
        if parts:
            hits = self._by_name.get(parts[-1].lower(), [])
            if hits:
                # prefer the hit sharing the longest path tail with the URI
                def shared(p: Path) -> int:
                    a, b = [s.lower() for s in reversed(p.parts)], [s.lower() for s in reversed(parts)]
                    n = 0
                    while n < min(len(a), len(b)) and a[n] == b[n]:
                        n += 1
                    return n

                best = max(hits, key=shared)
                return best, tried, f"{uri} -> {best} (matched by file name)"
        if direct.is_absolute() and direct.is_file() and not self._inside(direct):
            raise self._refuse(uri, f"names {direct}")
        return None, tried, ""


def mesh_uri(filename: str) -> str:
    """``file://$(find pkg)/x`` -> ``package://pkg/x``; other URIs unchanged."""
    return _FIND.sub(lambda m: f"package://{m.group(1)}/", filename)


def _primitive(g: Geometry) -> trimesh.Trimesh | None:
    if g.kind == "box":
        return trimesh.creation.box(extents=g.size) if all(s > 0 for s in g.size) else None
    if g.kind == "cylinder":
        r, h = g.size
        return trimesh.creation.cylinder(radius=r, height=h, sections=CYLINDER_SECTIONS) if r > 0 and h > 0 else None
    if g.kind == "sphere":
        return trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=g.size[0]) if g.size[0] > 0 else None
    return None


_REPAIRED: dict[tuple, Any] = {}


def _repaired_file(path: Path, scale: Sequence[float], units: str):
    """The mesh file as a validated :class:`~sphri.types.Link` in its own frame, once per process and file version.

    Orientation repair of an open mesh (``make_link``) takes about a second per
    4,000 faces; the same file serves several links (Reachy 2's four joint balls,
    two antennas), and a study builds the robot more than once.
    """
    st = path.stat()
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns, tuple(float(x) for x in scale), units)
    if key not in _REPAIRED:
        m = read_mesh(path)
        v = np.asarray(m.vertices, dtype=np.float64) * np.asarray(scale, dtype=np.float64)
        f = np.asarray(m.faces)
        if np.prod(scale) < 0:
            f = f[:, ::-1]
        if len(_REPAIRED) > 64:
            _REPAIRED.clear()
        _REPAIRED[key] = make_link(path.stem, v, f, units=units, source=str(path))
    return _REPAIRED[key]


def link_geometry(
    link: UrdfLink, resolver, order, units: str = "auto"
) -> tuple[trimesh.Trimesh | None, str, list[str]]:
    """``(mesh in the link frame or None, what it is made of, notes)`` by the preference ``order``."""
    notes: list[str] = []
    problems: list[str] = []
    for which, kind in order:
        elements = [g for g in getattr(link, which) if (g.kind == "mesh") == (kind == "mesh")]
        if not elements:
            continue
        parts = []
        for g in elements:
            if kind == "mesh":
                uri = mesh_uri(g.filename)
                if _XACRO.search(uri):
                    problems.append(f"{which} mesh {g.filename!r} has an unexpanded xacro expression")
                    continue
                found, _, how = resolver.resolve(uri)
                if found is None:
                    problems.append(f"{which} mesh {g.filename!r} not found under {resolver.dir}")
                    continue
                if how:
                    notes.append(f"resolved {how}")
                try:
                    rep = _repaired_file(found, g.scale, units)
                except MeshError as exc:
                    problems.append(f"{which} mesh {found} unusable ({exc})")
                    continue
                m = trimesh.Trimesh(rep.vertices, rep.faces, process=False)
                if np.linalg.det(g.origin[:3, :3]) > 0:
                    m.metadata["sphri_link"] = rep  # already validated; a rigid motion keeps its orientation
            else:
                prim = _primitive(g)
                if prim is None:
                    problems.append(f"zero-size {which} {g.kind}")
                    continue
                m = prim
            m.apply_transform(g.origin)
            parts.append(m)
        if parts:
            notes += [f"not used: {p}" for p in problems]
            # trimesh annotates concatenate as returning a Geometry; meshes concatenate to a Trimesh
            mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(parts)) if len(parts) > 1 else parts[0]
            if len(parts) == 1 and "sphri_link" in parts[0].metadata:
                mesh.metadata["sphri_link"] = parts[0].metadata["sphri_link"]
            return mesh, f"{which} {kind}{'es' if kind == 'mesh' and len(parts) > 1 else ''} ({len(parts)})", notes
    if problems:
        return None, "", ["; ".join(problems)]
    return None, "", ["a frame without geometry (dummy, camera or tip frame)"]


def load_parts_spec(parts: Any) -> dict[str, Any]:
    """``robot.parts`` (a mapping of parts, or a YAML file with parts / groups / rest / exclude / merge) as a dict."""
    if isinstance(parts, (str, Path)):
        p = Path(parts).expanduser()
        if not p.is_file():
            raise FileNotFoundError(f"robot.parts: body-part file not found: {p}")
        try:
            table = yaml.safe_load(p.read_text())
        except yaml.YAMLError as exc:
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RobotFileError(f"{p}: not valid YAML ({first})") from None
        if not isinstance(table, dict) or not isinstance(table.get("parts"), dict):
            raise RobotFileError(f"{p}: needs a mapping 'parts' (body part -> {{link: ..., side: ...}})")
        unknown = sorted(set(table) - {"parts", "groups", "rest", "exclude", "merge"})
        if unknown:
            raise RobotFileError(f"{p}: unknown key(s) {unknown}; allowed: parts, groups, rest, exclude, merge")
        return table
    return {"parts": parts}


@dataclass
class _Surfaces:
    """The links of a robot being built: each kept link's mesh (link frame, metres) and notes, and the
    skipped links with the reason."""

    geom: dict[str, trimesh.Trimesh] = field(default_factory=dict)
    notes: dict[str, list[str]] = field(default_factory=dict)
    skipped: list[tuple[str, str]] = field(default_factory=list)


def _validated_link(model: UrdfModel, n: str, built: _Surfaces) -> Link:
    """Link ``n``'s mesh as a validated :class:`Link` (metres): a single mesh file moved rigidly keeps its
    validation (no second repair); any other mesh goes through ``make_link``."""
    mesh = built.geom[n]
    rep = mesh.metadata.get("sphri_link")
    if rep is not None:
        return Link(
            name=n,
            vertices=np.asarray(mesh.vertices, dtype=np.float64),
            faces=np.asarray(mesh.faces, dtype=np.int64),
            watertight=rep.watertight,
            notes=tuple(built.notes[n]) + tuple(rep.notes),
        )
    return make_link(n, mesh.vertices, mesh.faces, units="m", source=f"{model.path.name} {n}", notes=built.notes[n])


class UrdfWholeBody:
    """A whole robot from a URDF (see the module docstring); ``build()`` -> :class:`WholeBodyRobot`.
    ``parts=None``: each link with a surface is a body part of its own (``sphri robot check`` without a parts file)."""

    VERSION = "1"

    def __init__(
        self,
        path: str | Path,
        parts: Any,
        name: str = "urdf",
        groups: Any = None,
        rest: Any = None,
        exclude: Sequence[str] | None = None,
        merge: Mapping[str, Sequence[str]] | None = None,
        links: Sequence[str] | None = None,
        mesh_root: str | Path | None = None,
        geometry: str = "auto",
        units: str = "m",
    ):
        self.path = Path(path).expanduser()
        self.name = str(name)
        spec = load_parts_spec(parts)
        self.parts_spec = spec["parts"]
        self.groups_spec = groups if groups is not None else spec.get("groups")
        self.rest = {str(k): float(v) for k, v in dict(rest if rest is not None else spec.get("rest") or {}).items()}
        self.exclude = [str(x) for x in (exclude if exclude is not None else spec.get("exclude") or [])]
        m = merge if merge is not None else spec.get("merge") or {}
        self.merge = {str(k): [str(x) for x in ([v] if isinstance(v, str) else list(v))] for k, v in dict(m).items()}
        self.links = None if links is None else [str(x) for x in links]
        self.mesh_root = None if mesh_root in (None, "") else Path(str(mesh_root)).expanduser()
        require_choice("robot.geometry", geometry, list(GEOMETRY_ORDER))
        self.geometry = str(geometry)
        self.units = str(units)

    def build(self) -> WholeBodyRobot:
        """The robot: its links with a surface (metres), regions, joint tree, parts and groups, and every
        skipped link with the reason; :class:`ConfigError` or :class:`RobotFileError` naming the setting or file."""
        model = parse_urdf(self.path)
        root_dir = self.mesh_root if self.mesh_root is not None else model.path.parent
        if not root_dir.is_dir():
            raise FileNotFoundError(f"robot.mesh_root: folder not found: {root_dir} (meshes of {model.path})")
        merged_into = self._check_names(model)
        built = self._surfaces(model, MeshResolver(root_dir, model.path), merged_into)
        if model.root not in built.geom:
            raise ConfigError(
                f"{model.path}: the root link {model.root!r} has no loadable geometry; the whole-body tree "
                "needs its root (the base) to have a surface"
            )
        actuated = [j.name for j in model.joint_of.values() if j.kind in MOVABLE and j.mimic is None]
        self._merge_at_rest(model, merged_into, built)
        surface = [n for n in model.links if n in built.geom]  # file order; sorted topologically below
        bad_rest = sorted(set(self.rest) - set(actuated))
        if bad_rest:
            raise ConfigError(f"robot.rest: {bad_rest} are not movable joints of {model.path}; they are: {actuated}")
        tree = self._tree(model, surface)
        self._check_part_links(model, built)
        spec = self.parts_spec if self.parts_spec is not None else {n: {"link": n} for n in tree.links}
        part_list = check_parts(spec, {n: None for n in tree.links})
        groups = check_groups(self.groups_spec, [p.name for p in part_list])
        links = {n: _validated_link(model, n, built) for n in tree.links}
        self._log_built(model, links, built.skipped)
        return WholeBodyRobot(
            name=self.name,
            links=links,
            regions=part_regions(links, part_list, groups),
            tree=tree,
            parts=tuple(part_list),
            groups={k: tuple(v) for k, v in groups.items()},
            rest=dict(self.rest),
            skipped=tuple(built.skipped),
        )

    def _check_names(self, model: UrdfModel) -> dict[str, str]:
        """Check the link names the settings give against ``model``; returns merged link -> the link it joins
        (each below its target, else :class:`ConfigError`)."""
        check_link_names(model.links, model.path, self.links, self.exclude, self.merge, self.parts_spec)
        merged_into = {c: t for t, cs in self.merge.items() for c in cs}
        for child, target in merged_into.items():
            try:
                model.path_from(target, child)
            except ValueError:
                raise ConfigError(f"robot.merge.{target}: {child!r} is not below {target!r} in {model.path}") from None
        return merged_into

    def _surfaces(self, model: UrdfModel, resolver: MeshResolver, merged_into: Mapping[str, str]) -> _Surfaces:
        """The mesh (link frame, metres; files found by ``resolver``) and notes of every connected link that is
        kept and has geometry; the others in ``skipped`` with the reason (after the model's own skipped links)."""
        built = _Surfaces(skipped=list(model.skipped))
        gone = {n for n, r in built.skipped if r.startswith("not connected")}  # (a repeated name's first link stays)
        for n in (n for n in model.links if n not in gone):
            if n in self.exclude:
                built.skipped.append((n, "excluded (robot.exclude)"))
                continue
            if self.links is not None and n not in self.links and n not in merged_into and n != model.root:
                built.skipped.append((n, "not in robot.links"))
                continue
            mesh, what, nn = link_geometry(model.links[n], resolver, GEOMETRY_ORDER[self.geometry], self.units)
            if mesh is None:
                built.skipped.append((n, nn[0] if nn else "no geometry"))
                continue
            built.geom[n] = mesh
            built.notes[n] = [f"geometry: {what}"] + nn
        return built

    def _merge_at_rest(self, model: UrdfModel, merged_into: Mapping[str, str], built: _Surfaces) -> None:
        """Move each merged link's mesh (``merged_into``: link -> target) into its target's, placed at the rest
        pose; the merged link is then skipped, named."""
        mimic = {j.name: j.mimic for j in model.joint_of.values() if j.mimic is not None}
        geom = built.geom
        for child, target in merged_into.items():
            if child not in geom:
                continue
            if target not in geom:
                raise ConfigError(f"robot.merge.{target}: {target!r} has no loadable geometry to merge into")
            tf = np.eye(4)
            for j in model.path_from(target, child):
                q = np.array([mimic_value(j.name, mimic, lambda n: self.rest.get(n, 0.0))])
                tf = tf @ j.origin @ joint_motion(j.kind, j.axis, q)[0]
            mesh = geom.pop(child).copy()
            mesh.apply_transform(tf)
            # trimesh annotates concatenate as returning a Geometry; meshes concatenate to a Trimesh
            geom[target] = cast(trimesh.Trimesh, trimesh.util.concatenate([geom[target], mesh]))
            geom[target].metadata.pop("sphri_link", None)
            built.notes[target].append(f"merged link {child!r} at the rest pose")
            built.skipped.append((child, f"merged into {target!r} at the rest pose (robot.merge)"))

    def _check_part_links(self, model: UrdfModel, built: _Surfaces) -> None:
        """Refuse (:class:`ConfigError`) a body part on a link that was skipped, saying why it was."""
        why = dict(built.skipped)
        for name, spec in self.parts_spec.items() if hasattr(self.parts_spec, "items") else ():
            link = spec.get("link") if hasattr(spec, "get") else None
            if link in why and link not in built.geom:
                raise ConfigError(f"robot.parts.{name}.link={link!r} has no surface in {model.path}: {why[link]}")

    def _log_built(self, model: UrdfModel, links: Mapping[str, Link], skipped: Sequence[tuple[str, str]]) -> None:
        """Log how many links have a surface, the skipped ones counted by reason, and the model's notes."""
        reasons: dict[str, int] = {}
        for _, r in skipped:
            key = r.split(" (")[0].split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
        log.info(
            "robot %s: %d links with a surface from %s; skipped %d links: %s",
            self.name,
            len(links),
            model.path,
            len(skipped),
            ", ".join(f"{k} ({v})" for k, v in sorted(reasons.items(), key=lambda kv: -kv[1])),
        )
        for note in model.notes:
            log.info("robot %s: %s", self.name, note)

    @staticmethod
    def _tree(model: UrdfModel, surface: list[str]) -> JointTree:
        """The :class:`JointTree` over the ``surface`` links, skipped frames folded into the joint chains."""
        keep = set(surface)

        def anchor(n: str) -> str | None:
            cur = n
            while cur in model.joint_of:
                cur = model.joint_of[cur].parent
                if cur in keep:
                    return cur
            return None

        parent = {n: anchor(n) for n in surface}
        order: list[str] = []
        pending = list(surface)
        while pending:
            ready = [n for n in pending if parent[n] is None or parent[n] in order]
            order += ready
            pending = [n for n in pending if n not in ready]
        origins = np.tile(np.eye(4), (len(order), 1, 1))
        steps: list[tuple[JointStep, ...]] = []
        for i, n in enumerate(order):
            above = parent[n]
            if above is None:
                steps.append(())
                continue
            origin = np.eye(4)
            chain: list[JointStep] = []
            cur: UrdfJoint | None = None
            after = np.eye(4)
            for j in model.path_from(above, n):
                if cur is None:
                    origin = origin @ j.origin
                else:
                    after = after @ j.origin
                if j.kind in MOVABLE:
                    if cur is not None:
                        chain.append(_step(cur, after))
                    cur, after = j, np.eye(4)
            if cur is not None:
                chain.append(_step(cur, after))
            origins[i] = origin
            steps.append(tuple(chain))
        return JointTree(
            links=tuple(order),
            parent=tuple(-1 if (up := parent[n]) is None else order.index(up) for n in order),
            origin=origins,
            joints=tuple(() for _ in order),
            steps=tuple(steps),
        )


def _step(j: UrdfJoint, after: np.ndarray) -> JointStep:
    kind = "prismatic" if j.kind == "prismatic" else "revolute"
    x, y, z = j.axis
    return JointStep(j.name, kind, (float(x), float(y), float(z)), after, j.mimic)
