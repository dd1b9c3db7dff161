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

from sphri.contact.schema import INSIDE_CHOICES
from sphri.contact.stage import ContactStage


class ExactContact(ContactStage):
    """Exact contact of every capsule with the link of its trial's region.

    ``compute(dataset, robot) -> Contacts``. Config: ``ExactContactSchema`` (``python -m sphri.cli show contact=exact``).
    """

    VERSION = "1"

    def __init__(self, margin_m: float = 0.0, inside: str = "auto", chunk_frames: int = 20000) -> None:
        if not margin_m >= 0:
            raise ValueError(f"contact.margin_m={margin_m!r} is invalid: must be >= 0 (metres)")
        if inside not in INSIDE_CHOICES:
            raise ValueError(f"contact.inside={inside!r} is invalid: allowed values: {list(INSIDE_CHOICES)}")
        if int(chunk_frames) < 1:
            raise ValueError(f"contact.chunk_frames={chunk_frames!r} is invalid: must be >= 1")
        self.margin_m = float(margin_m)
        self.inside = inside
        self.chunk_frames = int(chunk_frames)
        self.spheres = 0
