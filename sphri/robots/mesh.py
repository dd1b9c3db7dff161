"""``MeshRobot``: a robot from mesh files, one per link (``robot=mesh``, ``robot=reachy_vr``).

Each file is read with trimesh (obj, stl, ply, off, dae, glb, ...), taken to
be in the link's own frame, and validated by
:func:`sphri.robots.validate.load_mesh_file`.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

from sphri.config import ConfigError, require_choice
from sphri.robots.schema import UNITS, check_regions, check_str_map
from sphri.robots.validate import load_mesh_file
from sphri.types import Robot

log = logging.getLogger(__name__)


class MeshRobot:
    """A robot whose links are mesh files.

    ``links``: link name -> file (relative paths start at ``root``, or the
    working directory when ``root`` is None); ``regions``: skin region ->
    link name; ``root_required``: refuse a null ``root`` (``robot=reachy_vr``
    takes ``root`` from ``data.root``); ``units``: auto, m, cm or mm.
    """

    VERSION = "1"

    def __init__(
        self,
        links: Mapping[str, str] | None,
        regions: Mapping[str, str] | None,
        name: str = "mesh",
        root: str | None = None,
        root_required: bool = False,
        units: str = "auto",
    ):
        self.name = str(name)
        self.links = check_str_map(links, "robot.links", "link name -> mesh file")
        self.regions = check_str_map(regions, "robot.regions", "skin region -> link")
        self.root = None if root is None else str(root)
        self.root_required = bool(root_required)
        self.units = str(units)
        if not self.links:
            raise ConfigError("robot.links={} is invalid: at least one link: {name: path}")
        check_regions(self.regions, list(self.links))
        require_choice("robot.units", self.units, UNITS)

    def paths(self) -> dict[str, Path]:
        """Link name -> resolved mesh path."""
        if self.root is None and self.root_required:
            raise ConfigError(
                f"robot={self.name} reads its meshes from data.root; set data=vr_gesture data.root=PATH "
                f"(or robot.root=PATH, the folder holding {sorted(set(self.links.values()))})"
            )
        base = Path(self.root).expanduser() if self.root is not None else None
        if base is not None and not base.is_dir():
            raise FileNotFoundError(f"robot.root: folder not found: {base} (robot={self.name})")
        out = {}
        for link, p in self.links.items():
            path = Path(p).expanduser()
            out[link] = path if path.is_absolute() or base is None else base / path
        return out

    def build(self) -> Robot:
        """The :class:`Robot`; missing files raise ``FileNotFoundError`` naming the path."""
        links = {
            name: load_mesh_file(path, name, units=self.units, key=f"robot.links.{name}")
            for name, path in self.paths().items()
        }
        for link in links.values():
            log.info(
                "robot %s: link %s: %d vertices, %d faces, watertight=%s",
                self.name,
                link.name,
                len(link.vertices),
                len(link.faces),
                link.watertight,
            )
        return Robot(name=self.name, links=links, regions=dict(self.regions))
