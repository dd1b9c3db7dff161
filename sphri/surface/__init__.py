"""Surface parameterizations: a link's surface as a 2-D chart (u, v) in [0, 1]^2.

Components (``surface=...``): :class:`~sphri.surface.cylinder.CylinderSurface`
(the paper's), :class:`~sphri.surface.box.BoxSurface` (flat-ish links) and
:class:`~sphri.surface.mesh.MeshSurface` (no chart). Mapping functions live in
:mod:`sphri.surface.charts`.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.surface",
    {
        "from_uv": "sphri.surface.charts",
        "jacobian": "sphri.surface.charts",
        "primitive_distance": "sphri.surface.charts",
        "to_uv": "sphri.surface.charts",
    },
)
