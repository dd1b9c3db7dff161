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

from sphri.contact.stage import ContactStage


class SphereContact(ContactStage):
    """k-sphere approximation of every capsule against the link of its trial's region.

    ``compute(dataset, robot) -> Contacts`` (``inside`` is always False).
    Config: ``python -m sphri.cli show contact=spheres``.
    """

    VERSION = "1"

    def __init__(self, k: int = 5, margin_m: float = 0.0, chunk_frames: int = 20000) -> None:
        if int(k) < 1:
            raise ValueError(f"contact.k={k!r} is invalid: must be >= 1 spheres per capsule")
        if not margin_m >= 0:
            raise ValueError(f"contact.margin_m={margin_m!r} is invalid: must be >= 0 (metres)")
        if int(chunk_frames) < 1:
            raise ValueError(f"contact.chunk_frames={chunk_frames!r} is invalid: must be >= 1")
        self.k = int(k)
        self.spheres = int(k)
        self.margin_m = float(margin_m)
        self.inside = "none"
        self.chunk_frames = int(chunk_frames)
