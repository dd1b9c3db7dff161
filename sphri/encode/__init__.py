"""Encoders: contacts -> skin readings (M, N) per frame, on any layout.

Components (``encoder=...``, ``encode(contacts, link, surface, layout,
frame_index) -> Frames``): ``ellipse`` (the paper's chart raster,
:mod:`sphri.encode.ellipse`), ``coverage`` (:mod:`sphri.encode.coverage`) and
``proximity`` (:mod:`sphri.encode.proximity`). Outputs are
:class:`~sphri.types.SkinFrames` (Frames + taxel geometry; ``sphri.encode.SkinFrames`` names it
for one release).
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.encode",
    {
        "SkinFrames": "sphri.types",
    },
)
