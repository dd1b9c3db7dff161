"""Config schema of the coverage analysis (``sphri coverage``).

Not a pipeline stage: the analysis reads the data and contact stages of a
composed sphri config; its own settings are given on the same command line
(``by=gesture bandwidth_mm=8``, or ``coverage.by=...``) and checked here,
naming the full key (``coverage.bandwidth_mm``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import ComponentSchema, require, setting, store
from sphri.figures import FORMATS as FIGURE_FORMATS
from sphri.figures import valid_formats

KERNELS = ("geodesic", "euclidean")
FOOTPRINTS = ("patch", "point")
ALTERNATIVES = ("greater", "two-sided")


@dataclass
class CoverageAnalysisSchema(ComponentSchema, group="coverage"):
    """Where on the link people touch, per group, and whether groups differ: the settings of
    :class:`~sphri.analysis.coverage.CoverageAnalysis`."""

    _target_: str = "sphri.analysis.coverage.CoverageAnalysis"
    by: str = "gesture"
    """Trial column whose values are the groups (gesture, participant, region, scenario, ...)."""
    pair_by: str = "participant"
    """Trial column of the paired units of the condition tests (the study's participants)."""
    bandwidth_mm: float = setting(10.0, lo=0.5, hi=500.0)
    """Standard deviation of the Gaussian smoothing kernel on the surface (mm)."""
    kernel: str = setting("geodesic", choices=KERNELS)
    """Distance of the kernel: geodesic (along the surface) or euclidean (straight, 3-D)."""
    footprint: str = setting("patch", choices=FOOTPRINTS)
    """A contact touches its patch (all elements within patch_radius_m) or only its closest point."""
    spacing_mm: float = setting(4.0, lo=0.5, hi=100.0)
    """Spacing of the surface samples (elements) that carry the density (mm)."""
    capture: float = setting(0.9, lo=0.0, hi=1.0, lo_open=True)
    """Share of contact frames the recommended placement must capture (0-1)."""
    n_projections: int = setting(128, lo=1, hi=100_000)
    """Random directions of the sliced Wasserstein distance."""
    swd_p: float = setting(1.0, lo=1.0, hi=10.0)
    """Order p of the sliced Wasserstein distance (1: mean transport distance, 2: SW2)."""
    alpha: float = setting(0.05, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    """Family-wise error rate of the Holm-corrected condition tests."""
    alternative: str = setting("greater", choices=ALTERNATIVES)
    """greater: conditions differ when between-condition SWD exceeds the split-half baseline."""
    exact_max: int = setting(12, lo=0, hi=20)
    """Enumerate all 2^n sign flips up to this many participants; Monte-Carlo beyond."""
    n_permutations: int = setting(9999, lo=99, hi=10_000_000)
    """Monte-Carlo sign flips when participants exceed exact_max."""
    seed: int = setting(0, lo=0)
    """Seeds the surface samples, projections and Monte-Carlo sign flips."""
    views: int = setting(4, lo=1, hi=8)
    """Views around the long axis in the PNG renders."""
    render: bool = True
    """Write the figures (in the formats of ``formats``) and PLY meshes (False: numbers and .npz only)."""
    heldout: bool = True
    """Also score each participant's frames with the placement chosen from the others."""

    def check(self) -> None:
        require(bool(str(self.by)), self.key("by"), self.by, "must name a trial column")
        require(bool(str(self.pair_by)), self.key("pair_by"), self.pair_by, "must name a trial column")
        require(
            self.spacing_mm <= self.bandwidth_mm,
            self.key("spacing_mm"),
            self.spacing_mm,
            f"must be <= coverage.bandwidth_mm={self.bandwidth_mm} (the kernel must span several samples)",
        )


@dataclass
class CoverageSchema(CoverageAnalysisSchema):
    """Where on the link people touch, per group, and whether groups differ (``sphri coverage``:
    the analysis's settings and the figures')."""

    marks: bool | None = None
    """The SYNTHETIC DATA banner on the figures: None = for synthetic data only, true = always, false = never."""
    formats: list[str] = field(default_factory=lambda: list(FIGURE_FORMATS))
    """Files per figure, any of png, pdf, svg (``formats=png`` for a quick look: the vector formats take
    most of a run's time, docs/BENCHMARKS.md)."""

    def check(self) -> None:
        super().check()
        require(
            valid_formats(self.formats),
            self.key("formats"),
            self.formats,
            f"must be one or more of {', '.join(FIGURE_FORMATS)}",
        )


store(group="coverage", name="coverage_schema", node=CoverageSchema)
