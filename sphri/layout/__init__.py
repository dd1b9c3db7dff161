"""Taxel layouts: where a skin's taxels sit on a link (positions, normals, areas, (u, v)).

Components (``layout=...``, ``build(link, surface, res) -> Layout``):
``grid`` and ``hex`` (:mod:`sphri.layout.grid`), ``random`` and ``density``
(:mod:`sphri.layout.poisson`), ``file`` (:mod:`sphri.layout.file`).
:func:`sphri.layout.units.describe` states a layout's resolution in mm.
"""

from sphri.layout.units import describe

__all__ = ["describe"]
