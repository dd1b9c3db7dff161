"""Taxel layouts: where a skin's taxels sit on a link (positions, normals, areas, (u, v)).

Components (``layout=...``, ``build(link, surface, res) -> Layout``):
``grid`` and ``hex`` (:mod:`sphri.layout.grid`), ``random`` and ``density``
(:mod:`sphri.layout.poisson`), ``file`` (:mod:`sphri.layout.file`).
:func:`sphri.layout.units.describe` states a layout's resolution in mm.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.layout",
    {
        "describe": "sphri.layout.units",
    },
)
