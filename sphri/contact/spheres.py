"""``contact=spheres``: the paper's approximation (the component).

Each capsule becomes ``k`` spheres of its radius, centred evenly along its
segment (the midpoint for k = 1, both ends included for k > 1). A capsule is
in contact when some sphere centre is closer to the link's surface than the
radius (``margin_m`` added); the reported distance, closest points and patch
come from the nearest sphere. There is no inside test: as in the paper, a
hand pushed into the link with every sphere centre farther than its radius
from the surface is missed. Use it to compare error and speed with
``contact=exact`` (``bench/bench_contact.py``).
"""

from __future__ import annotations

from sphri.config import Configured
from sphri.contact.schema import SphereContactSchema
from sphri.contact.stage import ContactStage


class SphereContact(Configured, ContactStage):
    """k-sphere approximation of every capsule against the link of its trial's region.

    ``compute(dataset, robot) -> Contacts`` (``inside`` is always False).
    Config: ``sphri show contact=spheres``.
    """

    VERSION = "1"

    SCHEMA = SphereContactSchema
    k: int  # set from SCHEMA by Configured

    def configured(self) -> None:
        self.spheres = int(self.k)
        self.inside = "none"  # spheres have no inside test
