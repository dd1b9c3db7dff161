"""The geometry floor: one link's mesh and everything derived from it, computed once and shared.

:func:`geometry_of` returns the :class:`~sphri.geometry.link.LinkGeometry` of a
:class:`~sphri.types.Link` (built on first use, kept while the link lives):
face normals and areas, area-weighted surface samples, principal axes,
the trimesh mesh, its proximity structures and ray intersectors, and the
surface elements of the coverage analysis
(:class:`~sphri.geometry.samples.SurfaceSamples`) with their search tree and
neighbour graphs. Surfaces, layouts, contact, the synthetic data and the
analyses read geometry from here; nothing recomputes it.

numpy only at import: trimesh, embreex and scipy are imported by the
methods that need them (a fully cached job never loads them).
"""

from sphri._lazy import lazy_exports

__getattr__, __all__ = lazy_exports(
    "sphri.geometry",
    {
        "LinkGeometry": "sphri.geometry.link",
        "geometry_of": "sphri.geometry.link",
        "geometry_of_arrays": "sphri.geometry.link",
        "check_link": "sphri.geometry.link",
        "closest_points": "sphri.geometry.link",
        "face_areas": "sphri.geometry.link",
        "face_normals": "sphri.geometry.link",
        "link_from_trimesh": "sphri.geometry.link",
        "principal_axes": "sphri.geometry.link",
        "project_along": "sphri.geometry.link",
        "sample_surface": "sphri.geometry.link",
        "to_trimesh": "sphri.geometry.link",
        "triangle_normals_areas": "sphri.geometry.link",
        "DEGENERATE_AREA_M2": "sphri.geometry.link",
        "SurfaceSamples": "sphri.geometry.samples",
        "sample_link": "sphri.geometry.samples",
        "neighbour_csr": "sphri.geometry.samples",
        "knn_graph": "sphri.geometry.samples",
    },
)
