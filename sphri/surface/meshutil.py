"""Mesh helpers of a :class:`~sphri.types.Link`: kept as the old import path of :mod:`sphri.geometry.link`.

Validation, face normals and areas, area-weighted surface sampling,
principal axes, projection along a direction and closest points all live on
the geometry floor (:func:`sphri.geometry.geometry_of`, computed once per
link); this module re-exports them for code written against it.
"""

from __future__ import annotations

from sphri.geometry.link import (
    DEGENERATE_AREA_M2,
    check_link,
    closest_points,
    face_areas,
    face_normals,
    link_from_trimesh,
    principal_axes,
    project_along,
    sample_surface,
    to_trimesh,
    triangle_normals_areas,
)

__all__ = [
    "DEGENERATE_AREA_M2",
    "check_link",
    "closest_points",
    "face_areas",
    "face_normals",
    "link_from_trimesh",
    "principal_axes",
    "project_along",
    "sample_surface",
    "to_trimesh",
    "triangle_normals_areas",
]
