"""Contact stage: exact capsule-vs-mesh contact and the paper's sphere approximation.

Public API:

- :func:`capsule_mesh_query` (arrays in, :class:`ContactQuery` out): exact
  segment-to-surface distance, inside flag, contact flag, closest point,
  triangle, barycentric coordinates, patch radius and depth per capsule.
- :class:`~sphri.contact.exact.ExactContact` and
  :class:`~sphri.contact.spheres.SphereContact`: the pipeline components
  (``contact=exact`` / ``contact=spheres``), ``compute(dataset, robot) -> Contacts``.
- :func:`prepare_mesh`: the cached per-link acceleration data.
- (tests) :mod:`sphri.testing.contact_reference`: a brute-force numpy reference and the
  benchmark's capsule sets.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.contact",
    {
        "INSIDE_MODES": "sphri.contact.mesh",
        "MeshAccel": "sphri.contact.mesh",
        "prepare_mesh": "sphri.contact.mesh",
        "ContactQuery": "sphri.contact.query",
        "capsule_mesh_query": "sphri.contact.query",
        "sphere_mesh_query": "sphri.contact.query",
        "winding_number": "sphri.contact.query",
    },
)
