"""Config schema of the coverage analysis (``python -m sphri.coverage``).

Not a pipeline stage: the analysis reads the data and contact stages of a
composed sphri config; its own settings are given on the same command line
(``by=gesture bandwidth_mm=8``, or ``coverage.by=...``) and checked here,
naming the full key (``coverage.bandwidth_mm``).
"""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require, require_choice, require_range, store

KERNELS = ("geodesic", "euclidean")
FOOTPRINTS = ("patch", "point")
ALTERNATIVES = ("greater", "two-sided")


@dataclass
class CoverageSchema:
    """Where on the link people touch, per group, and whether groups differ."""

    _target_: str = "sphri.analysis.coverage.CoverageAnalysis"
    by: str = "gesture"
    """Trial column whose values are the groups (gesture, participant, region, scenario, ...)."""
    pair_by: str = "participant"
    """Trial column of the paired units of the condition tests (the study's participants)."""
    bandwidth_mm: float = 10.0
    """Standard deviation of the Gaussian smoothing kernel on the surface (mm)."""
    kernel: str = "geodesic"
    """Distance of the kernel: geodesic (along the surface) or euclidean (straight, 3-D)."""
    footprint: str = "patch"
    """A contact touches its patch (all elements within patch_radius_m) or only its closest point."""
    spacing_mm: float = 4.0
    """Spacing of the surface samples (elements) that carry the density (mm)."""
    capture: float = 0.9
    """Share of contact frames the recommended placement must capture (0-1)."""
    n_projections: int = 128
    """Random directions of the sliced Wasserstein distance."""
    swd_p: float = 1.0
    """Order p of the sliced Wasserstein distance (1: mean transport distance, 2: SW2)."""
    alpha: float = 0.05
    """Family-wise error rate of the Holm-corrected condition tests."""
    alternative: str = "greater"
    """greater: conditions differ when between-condition SWD exceeds the split-half baseline."""
    exact_max: int = 12
    """Enumerate all 2^n sign flips up to this many participants; Monte-Carlo beyond."""
    n_permutations: int = 9999
    """Monte-Carlo sign flips when participants exceed exact_max."""
    seed: int = 0
    """Seeds the surface samples, projections and Monte-Carlo sign flips."""
    views: int = 4
    """Views around the long axis in the PNG renders."""
    render: bool = True
    """Write the figures (PNG, PDF, SVG) and PLY meshes (False: numbers and .npz only)."""
    marks: bool | None = None
    """The SYNTHETIC DATA banner on the figures: None = for synthetic data only, true = always, false = never."""
    heldout: bool = True
    """Also score each participant's frames with the placement chosen from the others."""

    def __post_init__(self) -> None:
        require(bool(str(self.by)), "coverage.by", self.by, "must name a trial column")
        require(bool(str(self.pair_by)), "coverage.pair_by", self.pair_by, "must name a trial column")
        require_range("coverage.bandwidth_mm", self.bandwidth_mm, lo=0.5, hi=500.0)
        require_choice("coverage.kernel", self.kernel, KERNELS)
        require_choice("coverage.footprint", self.footprint, FOOTPRINTS)
        require_range("coverage.spacing_mm", self.spacing_mm, lo=0.5, hi=100.0)
        require(
            self.spacing_mm <= self.bandwidth_mm,
            "coverage.spacing_mm",
            self.spacing_mm,
            f"must be <= coverage.bandwidth_mm={self.bandwidth_mm} (the kernel must span several samples)",
        )
        require_range("coverage.capture", self.capture, lo=0.0, hi=1.0, lo_open=True)
        require_range("coverage.n_projections", self.n_projections, lo=1, hi=100_000)
        require_range("coverage.swd_p", self.swd_p, lo=1.0, hi=10.0)
        require_range("coverage.alpha", self.alpha, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
        require_choice("coverage.alternative", self.alternative, ALTERNATIVES)
        require_range("coverage.exact_max", self.exact_max, lo=0, hi=20)
        require_range("coverage.n_permutations", self.n_permutations, lo=99, hi=10_000_000)
        require_range("coverage.seed", self.seed, lo=0)
        require_range("coverage.views", self.views, lo=1, hi=8)


store(group="coverage", name="coverage_schema", node=CoverageSchema)
