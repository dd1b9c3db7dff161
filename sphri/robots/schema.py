"""Config schemas of the ``robot`` group and their range checks.

Three kinds of robot, one schema each: ``parametric_schema`` (built-in
morphologies from dimensions: ``robot=reachy``, ``nao_child``,
``service_bot``), ``mesh_schema`` (mesh files: ``robot=mesh``,
``robot=reachy_vr``) and ``urdf_schema`` (``robot=urdf``), plus
``kinematic_schema`` (a whole robot from dimensions, ``robot=reachy_full``).

This module is the bottom of :mod:`sphri.robots`: the checks of every robot
config live here (the components call them too) and it imports no robot
implementation, so composing a config never loads a mesh library.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from omegaconf import MISSING

from sphri.config import (
    ComponentSchema,
    ConfigError,
    close_match,
    cross_check,
    require,
    require_choice,
    require_range,
    setting,
    store,
)
from sphri.inputs import input_path

#: Long-axis names of parametric links.
AXES: tuple[str, ...] = ("x", "y", "z")
#: Mesh units a robot may declare (``auto``: mm when a link is larger than 5 m).
UNITS: tuple[str, ...] = ("auto", "m", "cm", "mm")
#: Which URDF geometry to read.
GEOMETRIES: tuple[str, ...] = ("collision", "visual")
#: Robot descriptions shipped with sphri (``robot.builtin``): name -> URDF file.
BUILTIN: dict[str, Path] = {"reachy2": Path(__file__).with_name("data") / "reachy2" / "reachy2.urdf"}
#: Sides a body part may keep (the outward normal's sign along a link axis).
SIDES: tuple[str, ...] = ("+x", "-x", "+y", "-y", "+z", "-z")


def _opt(spec: Any, key: str, default: Any = None) -> Any:
    if isinstance(spec, Mapping) or hasattr(spec, "keys"):
        return spec[key] if key in spec else default
    return getattr(spec, key, default)


def check_parametric_link(spec: Any, key: str) -> None:
    """Range-check one parametric link (mapping or :class:`ParametricLinkSpec`); ``key`` e.g. ``robot.links.l_arm``."""
    size = list(_opt(spec, "size_m"))
    require(
        len(size) == 3 and all(s > 0 for s in size), f"{key}.size_m", size, "3 extents (x, y, z) in metres, all > 0"
    )
    centre = list(_opt(spec, "center_m"))
    require(len(centre) == 3, f"{key}.center_m", centre, "3 coordinates (x, y, z) in metres")
    require_choice(f"{key}.axis", _opt(spec, "axis"), AXES)
    require_range(f"{key}.exponent", float(_opt(spec, "exponent")), lo=1.0)
    n = int(_opt(spec, "n_around"))
    require(n >= 8 and n % 4 == 0, f"{key}.n_around", n, "a multiple of 4, >= 8 (vertices per cross-section ring)")
    prof = [list(row) for row in _opt(spec, "profile")]
    require(len(prof) >= 2, f"{key}.profile", prof, "at least 2 stations [t, scale_a, scale_b]")
    for i, row in enumerate(prof):
        require(len(row) == 3, f"{key}.profile[{i}]", row, "[t, scale_a, scale_b]: 3 numbers")
        require(
            0.0 < row[1] <= 1.0 and 0.0 < row[2] <= 1.0,
            f"{key}.profile[{i}]",
            row,
            "scales must lie in (0, 1] (fractions of size_m)",
        )
    ts = [row[0] for row in prof]
    require(
        ts[0] == 0.0 and ts[-1] == 1.0 and all(b > a for a, b in zip(ts, ts[1:])),
        f"{key}.profile",
        ts,
        "stations t must rise strictly from 0 to 1 (fractions of the length along axis)",
    )
    for col, label in ((1, "scale_a"), (2, "scale_b")):
        top = max(row[col] for row in prof)
        require(
            abs(top - 1.0) < 1e-9,
            f"{key}.profile",
            prof,
            f"the largest {label} must be 1 so that size_m is the link's true size (found {top:g})",
        )


def loft_spec(spec: Any, key: str) -> dict[str, Any]:
    """A link spec (mapping, DictConfig or ParametricLinkSpec) as a plain dict with defaults filled."""
    defaults: dict[str, Any] = {"center_m": [0.0, 0.0, 0.0], "axis": "z", "exponent": 2.0, "n_around": 32}
    mapping = isinstance(spec, Mapping) or hasattr(spec, "keys")
    out: dict[str, Any] = {}
    for k in ("size_m", "center_m", "axis", "profile", "exponent", "n_around"):
        has = (k in spec) if mapping else hasattr(spec, k)
        if not has and k not in defaults:
            raise ConfigError(f"{key}.{k} is missing (parametric links need size_m and profile)")
        out[k] = (spec[k] if mapping else getattr(spec, k)) if has else defaults[k]
    out["size_m"] = [float(x) for x in out["size_m"]]
    out["center_m"] = [float(x) for x in out["center_m"]]
    out["profile"] = [[float(x) for x in row] for row in out["profile"]]
    out["axis"] = str(out["axis"])
    out["exponent"] = float(out["exponent"])
    out["n_around"] = int(out["n_around"])
    return out


def _is_mapping(value: Any) -> bool:
    """A dict, an OmegaConf DictConfig or anything else with ``items()``."""
    return isinstance(value, Mapping) or hasattr(value, "items")


def _mapping_items(value: Any, key: str, expected: str) -> list[tuple[Any, Any]]:
    """The items of the optional mapping setting ``value`` (None: none), or :class:`ConfigError` naming ``key``."""
    if value is None:
        return []
    require(_is_mapping(value), key, value, expected)
    return list(value.items())


def check_str_map(value: Any, key: str, what: str) -> dict[str, str]:
    """``value`` as a plain ``{str: str}`` dict, or :class:`ConfigError` naming ``key``."""
    require(value is not None and _is_mapping(value), key, value, f"a mapping {what}, e.g. {key}={{arm: l_arm}}")
    out = dict(value.items())
    for k, v in out.items():
        require(isinstance(k, str) and isinstance(v, str) and v != "", f"{key}.{k}", v, "a non-empty string")
    return out


def unknown_links(key: str, bad: Any, known: Any, where: Path | str) -> ConfigError:
    """One line for link names ``bad`` that ``where`` (a URDF) does not have: each with its closest link name
    (``did you mean``), and how many links it has."""
    known = sorted(str(k) for k in known)
    named = "; ".join(f"{str(b)!r}{close_match(str(b), known)}" for b in bad)
    return ConfigError(
        f"{key}: {named} {'is not a link' if len(list(bad)) == 1 else 'are not links'} of {where} "
        f"({len(known)} links; `sphri robot check {where}` without parts lists them)"
    )


def check_link_names(
    known: Any,
    where: Path | str,
    links: Any = None,
    exclude: Any = None,
    merge: Any = None,
    parts: Any = None,
) -> None:
    """Every link a URDF robot's settings name (``links``, ``exclude``, ``merge``, each part's ``link``) is one of
    ``known``, the links of the URDF ``where``; else :func:`unknown_links` for the first setting that names others."""
    known = {str(k) for k in known}
    checks: list[tuple[str, list[str]]] = [
        ("robot.links", [str(x) for x in links or []]),
        ("robot.exclude", [str(x) for x in exclude or []]),
    ]
    for target, extra in _mapping_items(merge, "robot.merge", "a mapping link -> [descendant links]"):
        checks.append(
            (f"robot.merge.{target}", [str(target)] + [str(x) for x in ([extra] if isinstance(extra, str) else extra)])
        )
    if _is_mapping(parts):
        checks += [
            (f"robot.parts.{name}.link", [str(_opt(spec, "link"))]) for name, spec in parts.items() if _is_mapping(spec)
        ]
    for key, names in checks:
        bad = [n for n in dict.fromkeys(names) if n not in known]
        if bad:
            raise unknown_links(key, bad, known, where)


def check_regions(regions: Mapping[str, str], links: list[str], key: str = "robot.regions") -> None:
    """Every region must name one of ``links``; at least one region."""
    require(len(regions) > 0, key, dict(regions), "at least one skin region, e.g. {arm: <link name>}")
    for region, link in regions.items():
        require(link in links, f"{key}.{region}", link, f"must name one of the robot's links {sorted(links)}")


@dataclass
class RobotSchema(ComponentSchema, group="robot"):
    """Base of the robot group's schemas."""


@dataclass
class ParametricLinkSpec:
    """A link built by sphri: a loft of superellipse cross-sections along one axis.

    Cross-section axes (``a``, ``b``) are the two other axes in x, y, z
    order (axis z: a = x, b = y; axis y: a = x, b = z; axis x: a = y, b = z).
    """

    size_m: list[float] = MISSING
    """Bounding-box extents (x, y, z) in metres."""
    center_m: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    """Bounding-box centre in the link frame (metres)."""
    axis: str = "z"
    """Long axis of the loft: x, y or z."""
    profile: list[list[float]] = field(default_factory=lambda: [[0.0, 1.0, 1.0], [1.0, 1.0, 1.0]])
    """Stations ``[t, scale_a, scale_b]``: t in [0, 1] along the axis; scales of
    the cross-section's half-extents, fractions of ``size_m`` (largest = 1)."""
    exponent: float = 2.0
    """Superellipse exponent of the cross-section: 2 ellipse, larger -> rounded rectangle."""
    n_around: int = 32
    """Vertices per cross-section ring (multiple of 4)."""


@dataclass
class ParametricRobotSchema(RobotSchema):
    """A built-in morphology from dimensions (no files)."""

    _target_: str = "sphri.robots.parametric.ParametricRobot"
    name: str = MISSING
    """Robot name in logs and run tags."""
    links: dict[str, ParametricLinkSpec] = field(default_factory=dict)
    """Link name -> its loft (:class:`ParametricLinkSpec`), in the link's own frame."""
    regions: dict[str, str] = field(default_factory=dict)
    """Skin region -> link name, e.g. {arm: l_arm}."""

    def check(self) -> None:
        require(len(self.links) > 0, self.key("links"), {}, "at least one link")
        for name, spec in self.links.items():
            check_parametric_link(spec, f"robot.links.{name}")
        check_regions(self.regions, list(self.links))


@dataclass
class MeshRobotSchema(RobotSchema):
    """A robot from mesh files, one per link (obj, stl, ply, dae, ...)."""

    _target_: str = "sphri.robots.mesh.MeshRobot"
    name: str = "mesh"
    """Robot name in logs and run tags."""
    # ``Any`` rather than ``dict[str, str]``: Hydra cannot add keys to a typed
    # dict from the command line (``robot.links={arm: a.obj}``); values are
    # checked in ``__post_init__``.
    links: Any = input_path(None, kind="map", relative_to="root")
    """Link name -> mesh file (obj, stl, ply, dae, ...; relative paths are relative to ``root``)."""
    regions: Any = None
    """Skin region -> link name, e.g. {arm: l_arm}."""
    root: str | None = None
    """Folder that relative paths start from (None: the working directory)."""
    root_required: bool = False
    """Refuse to build when ``root`` is None (robots whose meshes come with a dataset)."""
    units: str = setting("auto", choices=UNITS)
    """Mesh units: auto (mm when the main connected part of a link is larger than 5 m), m, cm or mm."""

    def check(self) -> None:
        links = check_str_map(self.links, self.key("links"), "link name -> mesh file")
        require(len(links) > 0, self.key("links"), {}, "at least one link: {name: path}")
        check_regions(check_str_map(self.regions, self.key("regions"), "skin region -> link"), list(links))


@dataclass
class UrdfRobotSchema(RobotSchema):
    """A robot from a URDF file: chosen links as a plain robot, or with ``parts`` a whole kinematic robot."""

    INPUT_CHECK: ClassVar[str] = "sphri.robots.urdf:check_names"
    """Every link name of the config is a link of the URDF (:func:`sphri.inputs.check_contents`)."""

    _target_: str = "sphri.robots.urdf.UrdfRobot"
    name: str = "urdf"
    """Robot name in logs and run tags."""
    path: str | None = input_path(None, references="sphri.robots.urdf:mesh_files")
    """The URDF file; ``package://`` mesh URIs resolve relative to its folder (or ``mesh_root``)."""
    builtin: str | None = setting(None, choices=list(BUILTIN), optional=True)
    """A description that ships inside sphri instead of ``path``: reachy2 (robot=reachy2)."""
    links: Any = None
    """URDF links to load (each mesh in that link's own frame); with ``parts``: null loads every link that loads."""
    regions: Any = None
    """Skin region -> link name, e.g. {arm: l_upper_arm} (``Any``: see :class:`MeshRobotSchema`); with ``parts``:
    null, derived from them."""
    geometry: str = "collision"
    """Which geometry to read: collision or visual (missing mesh files fall back to collision primitives); with
    ``parts`` also auto (collision meshes, else visual
    meshes, else collision primitives, else visual primitives)."""
    joints: Any = None
    """Joint name -> angle (radians; metres for prismatic joints), others 0; used only by ``merge`` (plain robot)."""
    merge: Any = None
    """Link -> descendant links whose geometry joins it, placed at ``joints`` (plain) or the rest pose (``parts``)."""
    units: str = setting("auto", choices=UNITS)
    """Mesh units after the URDF's own scale: auto, m, cm or mm."""
    parts: Any = input_path(None)
    """Whole-body robot: body part -> {link, side, z_min, z_max, min_cos}, or a YAML file holding
    ``parts`` (and ``groups``, ``rest``, ``exclude``, ``merge``); see :mod:`sphri.robots.urdf_tree`."""
    groups: Any = None
    """Whole-body robot: group -> [body parts]."""
    rest: Any = None
    """Whole-body robot: joint name -> value of the rest pose (others 0)."""
    exclude: Any = None
    """Whole-body robot: links left out (named in the skipped-link report)."""
    mesh_root: str | None = input_path(None, kind="dir")
    """Folder that mesh URIs resolve against (null: the URDF's folder)."""

    def check(self) -> None:
        require(
            self.path not in (None, "") or self.builtin is not None,
            self.key("path"),
            self.path,
            "the URDF file (or robot.builtin=reachy2)",
        )
        if self.parts is not None:
            require_choice(self.key("geometry"), self.geometry, GEOMETRIES + ("auto",))
            require(
                self.regions is None,
                self.key("regions"),
                self.regions,
                "null for a whole-body robot (regions come from robot.parts)",
            )
            require(
                self.links is None or len(self.links) > 0,
                self.key("links"),
                self.links,
                "null (every link) or link names",
            )
            return
        require(
            self.links is not None and len(self.links) > 0,
            self.key("links"),
            self.links,
            "at least one URDF link name (or robot.parts for a whole-body robot)",
        )
        require(len(set(self.links)) == len(self.links), self.key("links"), list(self.links), "names must be unique")
        check_regions(check_str_map(self.regions, self.key("regions"), "skin region -> link"), list(self.links))
        require_choice(self.key("geometry"), self.geometry, GEOMETRIES)
        check_joints(self.joints)
        check_merge(self.merge, list(self.links))


def check_joints(joints: Any) -> dict[str, float]:
    """``robot.joints`` as ``{name: float}`` (None -> {})."""
    out = {}
    hint = "a mapping joint name -> value (radians), e.g. robot.joints={r_elbow: 1.57}"
    for k, v in _mapping_items(joints, "robot.joints", hint):
        require(
            isinstance(v, (int, float)) and not isinstance(v, bool),
            f"robot.joints.{k}",
            v,
            "a number (radians or metres)",
        )
        out[str(k)] = float(v)
    return out


def check_merge(merge: Any, links: list[str]) -> dict[str, list[str]]:
    """``robot.merge`` as ``{link: [descendant links]}`` (None -> {})."""
    out = {}
    hint = "a mapping link -> [descendant links], e.g. robot.merge={l_upper_arm: [l_forearm]}"
    for link, extra in _mapping_items(merge, "robot.merge", hint):
        require(link in links, f"robot.merge.{link}", link, f"must be one of robot.links {links}")
        extra = [extra] if isinstance(extra, str) else list(extra)
        require(link not in extra, f"robot.merge.{link}", extra, "must not list the link itself")
        out[str(link)] = [str(x) for x in extra]
    return out


store(group="robot", name="parametric_schema", node=ParametricRobotSchema)
store(group="robot", name="mesh_schema", node=MeshRobotSchema)
store(group="robot", name="urdf_schema", node=UrdfRobotSchema)


def check_tree_link(spec: Any, key: str) -> dict[str, Any]:
    """One tree link as a plain dict: parent, xyz, rpy, joints [(name, axis)], shape (loft spec)."""
    if spec is None:
        raise ConfigError(f"{key}: missing link spec")
    parent = _opt(spec, "parent")
    xyz = [float(x) for x in (_opt(spec, "xyz") or [0.0, 0.0, 0.0])]
    rpy = [float(x) for x in (_opt(spec, "rpy") or [0.0, 0.0, 0.0])]
    if len(xyz) != 3:
        raise ConfigError(f"{key}.xyz={xyz} is invalid: 3 coordinates (metres)")
    if len(rpy) != 3:
        raise ConfigError(f"{key}.rpy={rpy} is invalid: roll, pitch, yaw (radians)")
    joints = []
    for j in list(_opt(spec, "joints") or []):
        name, _, axis = str(j).partition(":")
        if not name or axis not in AXES:
            raise ConfigError(f"{key}.joints: {j!r} is invalid: expected 'name:axis' with axis x, y or z")
        joints.append((name, axis))
    shape = _opt(spec, "shape")
    if shape is None:
        raise ConfigError(f"{key}.shape is missing: a loft (size_m, center_m, axis, profile, ...)")
    shape = loft_spec(shape, f"{key}.shape")
    check_parametric_link(shape, f"{key}.shape")
    return {
        "parent": None if parent in (None, "") else str(parent),
        "xyz": xyz,
        "rpy": rpy,
        "joints": joints,
        "shape": shape,
    }


def tree_order(specs: Mapping[str, dict]) -> list[str]:
    """The links of checked tree links (:func:`check_tree_link`) parents first; exactly one root, every parent
    a link, no cycle, unique joint names."""
    names = list(specs)
    roots = [n for n in names if specs[n]["parent"] is None]
    if len(roots) != 1:
        raise ConfigError(f"robot.links: exactly one link must have no parent (the base), found {roots}")
    for n in names:
        p = specs[n]["parent"]
        if p is not None and p not in specs:
            raise ConfigError(f"robot.links.{n}.parent={p!r} is invalid: must name one of {names}")
    order: list[str] = []
    pending = list(names)
    while pending:
        ready = [n for n in pending if specs[n]["parent"] is None or specs[n]["parent"] in order]
        if not ready:
            raise ConfigError(f"robot.links: the parents of {pending} form a cycle")
        order += ready
        pending = [n for n in pending if n not in ready]
    seen: set[str] = set()
    for n in order:
        for j, _ in specs[n]["joints"]:
            if j in seen:
                raise ConfigError(f"robot.links.{n}.joints: joint {j!r} is used twice")
            seen.add(j)
    return order


def check_part_specs(parts: Any, links: Mapping[str, Any]) -> list[dict[str, Any]]:
    """``robot.parts`` as checked plain dicts (name, link, side, z_min, z_max, min_cos, mountable), in order; every part on
    one of ``links`` (:class:`sphri.robots.kinematic.BodyPart` holds them)."""
    if parts is None or not _is_mapping(parts) or len(parts) == 0:
        raise ConfigError(f"robot.parts={parts!r} is invalid: a mapping body part -> {{link: ..., side: ...}}")
    out = []
    for name, spec in parts.items():
        key = f"robot.parts.{name}"
        if not (isinstance(spec, Mapping) or hasattr(spec, "keys")):
            raise ConfigError(f"{key}={spec!r} is invalid: a mapping {{link: ..., side: ..., z_min: ..., z_max: ...}}")
        link = _opt(spec, "link")
        if link not in links:
            raise ConfigError(f"{key}.link={link!r} is invalid: must name one of the links {sorted(links)}")
        side = _opt(spec, "side")
        if side is not None and side not in SIDES:
            raise ConfigError(f"{key}.side={side!r} is invalid: allowed values: {list(SIDES)} or null")
        z_min, z_max = _opt(spec, "z_min"), _opt(spec, "z_max")
        if z_min is not None and z_max is not None and not float(z_min) < float(z_max):
            raise ConfigError(f"{key}: z_min={z_min} must be below z_max={z_max}")
        if str(name) in links and str(link) != str(name):
            raise ConfigError(f"{key}: a body part may share a name only with its own link")
        min_cos = float(_opt(spec, "min_cos", 0.0) or 0.0)
        if not 0.0 <= min_cos < 1.0 or (min_cos > 0 and side is None):
            raise ConfigError(f"{key}.min_cos={min_cos} is invalid: in [0, 1), and only with a side")
        mountable = _opt(spec, "mountable", True)
        if not isinstance(mountable, bool):
            raise ConfigError(f"{key}.mountable={mountable!r} is invalid: true or false")
        allowed = {"link", "side", "z_min", "z_max", "min_cos", "mountable"}
        unknown = sorted(set(spec.keys() if hasattr(spec, "keys") else []) - allowed)
        if unknown:
            raise ConfigError(f"{key}: unknown key(s) {unknown}; allowed: link, side, z_min, z_max, min_cos, mountable")
        out.append(
            {
                "name": str(name),
                "link": str(link),
                "side": None if side is None else str(side),
                "z_min": None if z_min is None else float(z_min),
                "z_max": None if z_max is None else float(z_max),
                "min_cos": min_cos,
                "mountable": mountable,
            }
        )
    return out


def check_groups(groups: Any, parts: list[str]) -> dict[str, list[str]]:
    """``robot.groups`` as ``{group: [body parts]}`` (None -> {}); every member one of ``parts``."""
    out = {}
    for g, members in _mapping_items(groups, "robot.groups", "a mapping group -> [body parts]"):
        members = [str(m) for m in ([members] if isinstance(members, str) else list(members))]
        bad = [m for m in members if m not in parts]
        if bad or not members:
            raise ConfigError(f"robot.groups.{g}={members} is invalid: unknown body part(s) {bad}; parts: {parts}")
        if str(g) in parts:
            raise ConfigError(f"robot.groups.{g}: a group must not share a body part's name")
        out[str(g)] = members
    return out


@dataclass(frozen=True)
class KinematicSpec:
    """A checked kinematic robot config (:func:`check_kinematic`): what :class:`sphri.robots.kinematic.KinematicRobot`
    builds from."""

    links: dict[str, dict[str, Any]]
    """Link name -> :func:`check_tree_link` dict."""
    order: list[str]
    """Links parents first (:func:`tree_order`)."""
    parts: list[dict[str, Any]]
    """:func:`check_part_specs` dicts."""
    groups: dict[str, list[str]]
    rest: dict[str, float]


def check_kinematic(links: Mapping[str, Any], parts: Any, groups: Any = None, rest: Any = None) -> KinematicSpec:
    """Every check of a kinematic robot's config (``robot=reachy_full``): links, body parts, groups, the tree
    and the rest pose's joints; :class:`ConfigError` naming the key."""
    specs = {str(k): check_tree_link(v, f"robot.links.{k}") for k, v in links.items()}
    part_specs = check_part_specs(parts, specs)
    group_map = check_groups(groups, [p["name"] for p in part_specs])
    rest_map = {str(k): float(v) for k, v in (rest or {}).items()}
    order = tree_order(specs)
    joint_names = [j for n in order for j, _ in specs[n]["joints"]]
    unknown = sorted(set(rest_map) - set(joint_names))
    if unknown:
        raise ConfigError(f"robot.rest: unknown joint(s) {unknown}; joints: {joint_names}")
    return KinematicSpec(specs, order, part_specs, group_map, rest_map)


@dataclass
class KinematicRobotSchema(RobotSchema):
    """A whole robot: a kinematic tree of parametric links with named body parts (no files)."""

    _target_: str = "sphri.robots.kinematic.KinematicRobot"
    name: str = MISSING
    """Robot name in logs and run tags."""
    links: Any = None
    """Link name -> {parent, xyz, rpy, joints: ["name:axis", ...], shape: a parametric loft}."""
    parts: Any = None
    """Body part -> {link, side (+x, -x, ...), z_min, z_max, mountable}: named pieces of the links' surfaces."""
    groups: Any = None
    """Group -> [body parts] (e.g. upper_torso: [torso_front_upper, torso_back_upper])."""
    rest: Any = None
    """Joint name -> angle (radians) of the rest pose; other joints 0."""

    def check(self) -> None:
        check_kinematic(self.links or {}, self.parts, self.groups, self.rest)


store(group="robot", name="kinematic_schema", node=KinematicRobotSchema)


@cross_check
def data_regions_on_robot(cfg) -> None:
    """Every region in ``data.regions`` must be one of the robot's ``robot.regions``."""
    regions = cfg.robot.get("regions")
    if not hasattr(regions, "keys"):
        return  # the robot's own check reports a missing region map
    wanted = cfg.data.get("regions") if "regions" in cfg.data else None
    if wanted is None:
        return  # data without skin regions (interaction sessions cover the whole robot)
    have = [str(k) for k in regions.keys()]
    for region in wanted:
        if region not in have:
            raise ConfigError(
                f"data.regions={list(cfg.data.regions)} is invalid: robot {cfg.robot.get('name', '')!r} has no region "
                f"{region!r}{close_match(str(region), have)}; its regions: {have}"
            )
