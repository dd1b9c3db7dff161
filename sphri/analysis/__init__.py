"""Analyses beside the chain: where people touch a link, and whether groups differ.

- :mod:`sphri.analysis.density`: surface samples (elements), contact
  footprints, geodesic / Euclidean kernel smoothing to a density in 1/m^2.
- :mod:`sphri.analysis.placement`: greedy coverage curve, the placement
  recommendation and its leave-one-participant-out check.
- :mod:`sphri.analysis.swd`: sliced Wasserstein distances (no POT needed).
- :mod:`sphri.analysis.stats`: paired sign-flip permutation test, Holm.
- :mod:`sphri.analysis.compare`: the split-half paired SWD design over
  participants for every pair of conditions.
- :mod:`sphri.analysis.coverage`: :class:`CoverageAnalysis` for one link and
  the files it writes; :mod:`sphri.analysis.render`: PNG / PLY output.
- :mod:`sphri.analysis.cli`: ``python -m sphri.coverage``.
"""

from sphri.analysis.compare import PairwiseComparison, paired_swd_tests, split_halves
from sphri.analysis.coverage import CoverageAnalysis, RegionCoverage, write_density_npz, write_region
from sphri.analysis.density import SurfaceKernel, SurfaceSamples, sample_link, touched_elements
from sphri.analysis.placement import CoverageCurve, coverage_curve, heldout_capture
from sphri.analysis.stats import SignFlipResult, holm, sign_flip_test
from sphri.analysis.swd import SharedSupportSW, sliced_wasserstein, wasserstein_1d

__all__ = [
    "CoverageAnalysis",
    "CoverageCurve",
    "PairwiseComparison",
    "RegionCoverage",
    "SharedSupportSW",
    "SignFlipResult",
    "SurfaceKernel",
    "SurfaceSamples",
    "coverage_curve",
    "heldout_capture",
    "holm",
    "paired_swd_tests",
    "sample_link",
    "sign_flip_test",
    "sliced_wasserstein",
    "split_halves",
    "touched_elements",
    "wasserstein_1d",
    "write_density_npz",
    "write_region",
]
