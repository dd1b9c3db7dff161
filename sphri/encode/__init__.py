"""Encoders: contacts -> skin readings (M, N) per frame, on any layout.

Components (``encoder=...``, ``encode(contacts, link, surface, layout,
frame_index) -> Frames``): ``ellipse`` (the paper's chart raster,
:mod:`sphri.encode.ellipse`), ``coverage`` (:mod:`sphri.encode.coverage`) and
``proximity`` (:mod:`sphri.encode.proximity`). Outputs are
:class:`~sphri.types.SkinFrames` (Frames + taxel geometry).
"""
