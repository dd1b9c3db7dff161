"""``contact=exact``: exact capsule-vs-link contact (the component).

Each capsule is its segment plus radius. Contact means the segment comes
closer to the link's surface than the radius (``margin_m`` added), or its
closest point lies inside the link's solid (``inside``: the convex hull for
convex links such as the study's open Unity hulls, else the generalized
winding number; see :mod:`sphri.contact.mesh`). Penetration was allowed in
the study, so a hand inside the link is in contact, with
``depth = radius + distance``.

Per contact row: distance to the surface, closest surface point, its
triangle and barycentric coordinates, the triangle's outward normal, the
closest segment point, and the patch radius: the circle where the sphere of
the capsule's radius centred at the segment point meets the triangle's
plane, ``sqrt(r^2 - d_plane^2)`` (the full radius when the sphere lies wholly
inside the solid). Culling and exactness: :mod:`sphri.contact.query`,
:mod:`sphri.contact.stage`.
"""

from __future__ import annotations

from sphri.config import Configured
from sphri.contact.schema import ExactContactSchema
from sphri.contact.stage import ContactStage


class ExactContact(Configured, ContactStage):
    """Exact contact of every capsule with the link of its trial's region.

    ``compute(dataset, robot) -> Contacts``. Config: ``ExactContactSchema`` (``sphri show contact=exact``).
    """

    VERSION = "1"

    SCHEMA = ExactContactSchema

    def configured(self) -> None:
        self.spheres = 0  # exact capsules
