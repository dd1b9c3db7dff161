"""Contact stage: exact capsule-vs-mesh contact and the paper's sphere approximation.

Public API:

- :func:`capsule_mesh_query` (arrays in, :class:`ContactQuery` out): exact
  segment-to-surface distance, inside flag, contact flag, closest point,
  triangle, barycentric coordinates, patch radius and depth per capsule.
- :class:`~sphri.contact.exact.ExactContact` and
  :class:`~sphri.contact.spheres.SphereContact`: the pipeline components
  (``contact=exact`` / ``contact=spheres``), ``compute(dataset, robot) -> Contacts``.
- :func:`prepare_mesh`: the cached per-link acceleration data.
- :mod:`sphri.contact.reference`: a brute-force numpy reference and the
  benchmark's capsule sets.
"""

from sphri.contact.mesh import INSIDE_MODES, MeshAccel, prepare_mesh
from sphri.contact.query import ContactQuery, capsule_mesh_query, sphere_mesh_query, winding_number

__all__ = [
    "INSIDE_MODES",
    "ContactQuery",
    "MeshAccel",
    "capsule_mesh_query",
    "prepare_mesh",
    "sphere_mesh_query",
    "winding_number",
]
