"""Analyses beside the chain: where people touch a link, and whether groups differ.

- :mod:`sphri.surface.density`: surface samples (elements), contact
  footprints, geodesic / Euclidean kernel smoothing to a density in 1/m^2.
- :mod:`sphri.analysis.placement`: greedy coverage curve, the placement
  recommendation and its leave-one-participant-out check.
- :mod:`sphri.analysis.swd`: sliced Wasserstein distances (no POT needed).
- :mod:`sphri.analysis.stats`: paired sign-flip permutation test, Holm.
- :mod:`sphri.analysis.compare`: the split-half paired SWD design over
  participants for every pair of conditions.
- :mod:`sphri.analysis.coverage`: :class:`CoverageAnalysis` for one link and
  the files it writes; :mod:`sphri.analysis.render`: PNG / PLY output.
- ``sphri coverage`` (:mod:`sphri.coverage`) is the command line over this library.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.analysis",
    {
        "PairwiseComparison": "sphri.analysis.compare",
        "paired_swd_tests": "sphri.analysis.compare",
        "split_halves": "sphri.analysis.compare",
        "rotated_halves": "sphri.analysis.compare",
        "CoverageAnalysis": "sphri.analysis.coverage",
        "RegionCoverage": "sphri.analysis.coverage",
        "write_density_npz": "sphri.analysis.coverage",
        "write_region": "sphri.analysis.coverage",
        "SurfaceKernel": "sphri.surface.density",
        "SurfaceSamples": "sphri.surface.density",
        "sample_link": "sphri.surface.density",
        "touched_elements": "sphri.surface.density",
        "CoverageCurve": "sphri.analysis.placement",
        "coverage_curve": "sphri.analysis.placement",
        "heldout_capture": "sphri.analysis.placement",
        "SignFlipResult": "sphri.analysis.stats",
        "holm": "sphri.analysis.stats",
        "sign_flip_test": "sphri.analysis.stats",
        "SharedSupportSW": "sphri.analysis.swd",
        "sliced_wasserstein": "sphri.analysis.swd",
        "wasserstein_1d": "sphri.analysis.swd",
    },
)
