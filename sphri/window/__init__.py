"""Windowing: per-trial windows aligned to contact onset (``window=onset``).

:class:`~sphri.window.onset.OnsetWindow` plans the frames of each window from
contacts (before encoding) and assembles the encoded frames into
:class:`~sphri.types.WindowedFrames`.
"""
