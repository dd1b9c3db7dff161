"""Surface parameterizations: a link's surface as a 2-D chart (u, v) in [0, 1]^2.

Components (``surface=...``): :class:`~sphri.surface.cylinder.CylinderSurface`
(the paper's), :class:`~sphri.surface.box.BoxSurface` (flat-ish links) and
:class:`~sphri.surface.mesh.MeshSurface` (no chart). Mapping functions live in
:mod:`sphri.surface.charts`.
"""

from sphri.surface.charts import from_uv, jacobian, primitive_distance, to_uv

__all__ = ["to_uv", "jacobian", "from_uv", "primitive_distance"]
