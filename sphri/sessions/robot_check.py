"""``sphri robot check``: what sphri makes of a robot description, before any study runs on it.

::

    sphri robot check PATH/robot.urdf                        # each link with a surface is a part
    sphri robot check PATH/robot.urdf parts=PATH/parts.yaml  # your body parts (docs/ROBOTS.md)
    sphri robot check reachy2                                # a robot config of sphri's (conf/robot/reachy2.yaml)

The robot is built as the scenario study builds it
(:class:`sphri.robots.urdf_tree.UrdfWholeBody`): every link that loads, at
the rest pose. It prints each body part with its link and area (cm^2, the
surface sampled in ``spacing_mm`` elements), the surface no part holds, the
groups, and every skipped link with its reason (a frame without geometry, a
mesh file not found, excluded, merged); it writes a picture of the parts on
the robot (front, left, back, right, top; one colour per part) as a PNG. A
missing or malformed file, or a parts file naming links the URDF does not
have, is one line, exit 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from sphri.args import arg, settings_main
from sphri.config import CONF_DIR, ConfigError, check_output_file, component_node, plain


def _spacing(value: float) -> str | None:
    return None if 1.0 <= value <= 50.0 else "must be in [1, 50] mm"


@dataclass
class RobotCheckSettings:
    """``sphri robot check``: a URDF robot's body parts, their areas, its skipped links and a picture of the parts."""

    urdf: str = arg(
        positional=True,
        metavar="URDF",
        help="the URDF file, or the name of a robot config that reads one (reachy2: conf/robot/reachy2.yaml)",
    )
    parts: str | None = arg(
        None,
        help="the parts YAML: parts, groups, rest, exclude, merge (docs/ROBOTS.md); default: a robot config's own, "
        "else each link with a surface is a part",
    )
    mesh_root: str | None = arg(None, help="the folder mesh URIs resolve against (default: the URDF's folder)")
    geometry: Literal["auto", "collision", "visual"] = arg(
        "auto", help="collision meshes, else visual meshes, else primitives (auto); or one kind only"
    )
    units: Literal["auto", "m", "mm"] = arg("m", help="mesh units after the URDF's own scale")
    spacing_mm: float = arg(8.0, check=_spacing, help="element size of the area sampling (mm)")
    out: str = arg("robot_parts.png", help="the picture of the parts on the robot (PNG)")


def urdf_configs() -> list[str]:
    """The robot configs of ``conf/robot`` that read a URDF of their own (``builtin`` or ``path``)."""
    out = []
    for f in sorted((CONF_DIR / "robot").glob("*.yaml")):
        text = f.read_text()
        if "schema_robot_urdf" in text and ("\nbuiltin:" in text or "\npath:" in text):
            out.append(f.stem)
    return out


def robot_settings(s: RobotCheckSettings) -> dict[str, Any]:
    """The :class:`~sphri.robots.urdf_tree.UrdfWholeBody` arguments for the check: from the URDF file and the
    command's settings, or from the robot config named ``s.urdf``."""
    path = Path(s.urdf).expanduser()
    out: dict[str, Any] = {"name": path.stem, "path": path, "parts": None}
    config = CONF_DIR / "robot" / f"{s.urdf}.yaml"
    if not path.exists() and not config.is_file():
        names = ", ".join(urdf_configs()) or "none"
        raise ConfigError(f"{s.urdf}: no such file (give a URDF file, or a robot config that reads one: {names})")
    if not path.exists():
        node = plain(component_node("robot", s.urdf))
        if not str(node.get("_target_", "")).endswith("UrdfRobot"):
            raise ConfigError(f"robot config {s.urdf!r} ({config}) does not read a URDF; give a URDF file")
        from sphri.robots.schema import BUILTIN

        urdf = node.get("path") or BUILTIN.get(str(node.get("builtin")))
        if not urdf:
            raise ConfigError(f"robot config {s.urdf!r} ({config}) names no URDF (robot.path); give a URDF file")
        out.update({k: node.get(k) for k in ("parts", "groups", "rest", "exclude", "merge", "mesh_root")})
        out.update(name=str(node.get("name", s.urdf)), path=Path(str(urdf)), geometry=node.get("geometry", "auto"))
        out["units"] = node.get("units", "m")
    if s.parts is not None:
        out.update(parts=s.parts, groups=None, rest=None, exclude=None, merge=None)
    if s.mesh_root is not None:
        out["mesh_root"] = s.mesh_root
    out.setdefault("geometry", s.geometry)
    out.setdefault("units", s.units)
    return out


def check_robot(s: RobotCheckSettings) -> tuple[str, Path]:
    """Build the robot, write the picture; (the text to print, the picture's path)."""
    from sphri import figures
    from sphri.analysis.render import LinkView
    from sphri.robots.urdf_tree import UrdfWholeBody
    from sphri.sessions.body import rest_surface
    from sphri.sessions.render import plot_parts

    check_output_file(s.out, key="out")
    kw = robot_settings(s)
    robot = UrdfWholeBody(**kw).build()
    if robot.tree is None:
        raise RuntimeError(f"robot {robot.name}: the URDF model built without a joint tree")
    links = tuple(robot.tree.links)
    surface = rest_surface(robot, links, s.spacing_mm)
    area = surface.samples.area_m2 * 1e4
    areas = {p: float(area[surface.part == p].sum()) for p in surface.parts}
    own = {p.name: p.link for p in robot.parts}
    lines = [
        f"robot {robot.name}: {kw['path']} ({len(links) + len(robot.skipped)} links: {len(links)} with a surface, "
        f"{len(robot.skipped)} skipped)",
        f"body parts (area at the rest pose, {s.spacing_mm:g} mm elements; {area.sum():,.0f} cm^2 in all):",
    ]
    width = max(len(p) for p in areas)
    for p, a in areas.items():
        where = f"link {own[p]}" if p in own else "its link's surface outside every part"
        lines.append(f"  {p:<{width}}  {a:>9,.0f} cm^2  {where}")
    for part in robot.parts:
        if part.name not in areas:
            lines.append(f"  {part.name:<{width}}  {0:>9,.0f} cm^2  link {part.link}: no element of the link is in it")
    for g, members in robot.groups.items():
        total = sum(areas.get(m, 0.0) for m in members)
        lines.append(f"group {g}: {', '.join(members)} ({total:,.0f} cm^2)")
    if robot.skipped:
        by_reason: dict[str, list[str]] = {}
        for name, why in robot.skipped:
            by_reason.setdefault(why, []).append(name)
        lines.append(f"skipped links ({len(robot.skipped)}):")
        lines += [f"  {why} ({len(names)}): {', '.join(names)}" for why, names in by_reason.items()]
    view = LinkView(surface.mesh, surface.samples, target_faces=20000)
    with figures.only_formats(("png",)):
        picture = plot_parts(view, view.face_labels(surface.part), areas, s.out, f"{robot.name}: body parts")
    lines.append(f"picture: {picture}")
    return "\n".join(lines), picture


#: The command and its settings (``sphri robot --help``).
COMMANDS = {"check": (RobotCheckSettings, False)}


@settings_main("sphri robot", COMMANDS)
def main(_cmd: str, settings: RobotCheckSettings, _overrides: list[str]) -> int:
    """``sphri robot check URDF [parts=FILE] ...``."""
    from sphri.robots.validate import MeshError

    try:
        text, _ = check_robot(settings)
    except (MeshError, FileNotFoundError, IsADirectoryError) as exc:  # a bad input file: one line, exit 2
        raise ConfigError(str(exc)) from None
    print(text)
    return 0
