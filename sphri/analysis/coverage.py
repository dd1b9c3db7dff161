"""Coverage analysis of one skin region: maps, placement and condition tests.

:class:`CoverageAnalysis` (settings: :class:`~sphri.analysis.schema.CoverageAnalysisSchema`)
turns a dataset's contacts on one link into

- a contact density per group of trials (``by``: any trial column) and
  overall (``"all"``), on surface samples (:mod:`sphri.surface.density`);
- the greedy coverage curve and the placement recommendation per group, with
  a leave-one-participant-out check (:mod:`sphri.analysis.placement`);
- paired sliced-Wasserstein tests between every pair of groups across
  participants, Holm-corrected (:mod:`sphri.analysis.compare`).

:func:`write_region` writes the files (PNG, PLY, .npz for ``layout=density``,
CSV, JSON); :mod:`sphri.coverage` is the command line.
"""

from __future__ import annotations

import json
import logging
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from sphri.analysis.compare import PairwiseComparison, n_rotations, paired_swd_tests, rotated_halves
from sphri.analysis.placement import (
    CoverageCurve,
    coverage_curve,
    describe_regions,
    heldout_capture,
    recommendation,
)
from sphri.analysis.schema import CoverageAnalysisSchema
from sphri.analysis.swd import SharedSupportSW
from sphri.config import Configured
from sphri.surface.density import SurfaceKernel, SurfaceSamples, sample_link, touched_elements
from sphri.types import GESTURES, Contacts, GestureDataset, Link, SurfaceMap

if TYPE_CHECKING:
    from sphri.figures import Provenance

log = logging.getLogger(__name__)

ALL = "all"


@dataclass
class RegionCoverage:
    """Everything the analysis found on one link."""

    region: str
    link: str
    by: str
    groups: list[str]
    """Group values in display order (without ``"all"``)."""
    samples: SurfaceSamples
    uv: np.ndarray | None
    """(P, 2) chart coordinates of the samples, None without a chart."""
    surface_kind: str
    counts: dict[str, np.ndarray]
    """Group (and ``"all"``) -> (P,) contact frames touching each element."""
    densities: dict[str, np.ndarray]
    """Group (and ``"all"``) -> (P,) density in 1/m^2 (integrates to 1)."""
    curves: dict[str, CoverageCurve]
    regions: dict[str, list[dict]]
    """Group -> connected parts of the recommended placement (see describe_regions)."""
    sentences: dict[str, str]
    heldout: pd.DataFrame
    """group, unit, area_share, captured, n_frames (leave-one-participant-out)."""
    comparison: PairwiseComparison | None
    notes: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-ready numbers of the region."""
        out: dict[str, Any] = {
            "region": self.region,
            "link": self.link,
            "by": self.by,
            "n_elements": self.samples.n,
            "area_cm2": self.samples.total_area_m2 * 1e4,
            "element_spacing_mm": self.samples.spacing_m * 1e3,
            "notes": self.notes,
            "seconds": self.seconds,
            "groups": {},
        }
        for g, c in self.curves.items():
            entry = {
                "n_contact_frames": c.n_frames,
                "capture": c.capture,
                "area_share_at_capture": c.area_at_capture,
                "recommendation": self.sentences[g],
                "regions": self.regions[g],
            }
            h = self.heldout[self.heldout["group"] == g] if len(self.heldout) else self.heldout
            if len(h):
                entry["heldout_captured_mean"] = float(h["captured"].mean())
                entry["heldout_captured_min"] = float(h["captured"].min())
                entry["heldout_area_share_mean"] = float(h["area_share"].mean())
            out["groups"][g] = entry
        if self.comparison is not None:
            t = self.comparison.table
            out["comparison"] = {
                "n_pairs": int(len(t)),
                "n_significant": int(t["significant"].sum()),
                "alpha": self.comparison.alpha,
                "swd_p": self.comparison.swd_p,
                "n_projections": self.comparison.n_projections,
                "exact": bool(t["exact"].all()) if len(t) else True,
                "n_permutations": sorted({int(x) for x in t["n_permutations"]}),
            }
        return out


def group_order(values: pd.Series, by: str) -> list[str]:
    """Group values in display order: the study's gesture order for gestures, sorted otherwise."""
    present = [str(v) for v in pd.unique(values.astype(str))]
    if by == "gesture":
        return [g for g in GESTURES if g in present] + sorted(set(present) - set(GESTURES))
    return sorted(present)


@dataclass
class _Pairs:
    """The analysed (frame, element) pairs and what each belongs to."""

    frames: np.ndarray
    """(K,) int64 global frame of each pair."""
    elements: np.ndarray
    """(K,) int64 surface element of each pair."""
    trial_of: np.ndarray
    """(K,) trial index of each pair."""
    labels: np.ndarray
    """(N,) each trial's ``by`` value (str)."""
    units: np.ndarray
    """(N,) each trial's ``pair_by`` value (str)."""
    groups: list[str]
    """``by`` values of the analysed trials in display order."""
    code: dict[str, int]
    """Group -> its index in ``groups``."""
    group: np.ndarray
    """(K,) index into ``groups`` of each pair (-1: none)."""
    unit: np.ndarray
    """(K,) index into ``unit_names`` of each pair."""
    unit_names: np.ndarray


@dataclass
class _Curves:
    """Per group (and ``"all"``): coverage curve, placement regions, sentence; the held-out table."""

    curves: dict[str, CoverageCurve]
    regions: dict[str, list[dict]]
    sentences: dict[str, str]
    heldout: pd.DataFrame


def _region_trials(dataset: GestureDataset, region: str | None) -> np.ndarray:
    """(N,) bool: the trials of ``region`` (all when None or without a ``region`` column); raises ValueError
    when the region has none."""
    trials = dataset.trials
    in_region = np.ones(len(trials), dtype=bool)
    if region is not None and "region" in trials.columns:
        in_region = (trials["region"] == region).to_numpy()
        if not in_region.any():
            raise ValueError(
                f"dataset {dataset.name!r} has no trials in region {region!r}; "
                f"regions: {sorted(pd.unique(trials['region']))}"
            )
    return in_region


def _densities(
    kernel: SurfaceKernel, samples: SurfaceSamples, pairs: _Pairs
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Per group and ``"all"``: (P,) contact frames touching each of the P ``samples``, and their density smoothed
    by ``kernel`` (1/m^2)."""
    n = samples.n
    counts = {ALL: np.bincount(pairs.elements, minlength=n).astype(float)}
    for i, g in enumerate(pairs.groups):
        counts[g] = np.bincount(pairs.elements[pairs.group == i], minlength=n).astype(float)
    names = [ALL] + pairs.groups
    dens_mat = kernel.smooth(np.stack([counts[k] for k in names]))
    return counts, {k: dens_mat[i] for i, k in enumerate(names)}


def _chart(surface: SurfaceMap | None, samples: SurfaceSamples) -> tuple[np.ndarray | None, str]:
    """((P, 2) chart coordinates of the samples, or None without a chart; the surface kind, ``mesh`` without one)."""
    kind = surface.kind if surface is not None else "mesh"
    if surface is not None and surface.has_uv:
        from sphri.surface.charts import to_uv

        return to_uv(surface, samples.points_m), kind
    return None, kind


class CoverageAnalysis(Configured):
    """Contact maps, placement and condition tests on one link (see module)."""

    VERSION = "1"

    SCHEMA = CoverageAnalysisSchema
    by: str  # these set from SCHEMA by Configured
    pair_by: str
    bandwidth_mm: float
    kernel: str
    footprint: str
    spacing_mm: float
    capture: float
    n_projections: int
    swd_p: float
    alpha: float
    alternative: str
    exact_max: int
    n_permutations: int
    seed: int
    views: int
    render: bool
    heldout: bool

    # ------------------------------------------------------------------ analysis
    def analyze(
        self,
        dataset: GestureDataset,
        contacts: Contacts | None,
        link: Link,
        surface: SurfaceMap | None,
        region: str | None = None,
        samples: SurfaceSamples | None = None,
        kernel: SurfaceKernel | None = None,
        touched: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> RegionCoverage:
        """Maps, curves and tests for the trials of ``region`` (all trials when None) on ``link``.

        ``samples``/``kernel`` replace the link's own (e.g. a whole robot's
        samples with a kernel that smooths within each link) and ``touched``
        the (frame, element) pairs computed from ``contacts`` (which may then be None).
        """
        t0 = time.perf_counter()
        self._check_inputs(dataset, contacts)
        in_region = _region_trials(dataset, region)
        samples = samples if samples is not None else sample_link(link, self.spacing_mm, self.seed)
        kernel = kernel if kernel is not None else SurfaceKernel(samples, self.bandwidth_mm, self.kernel)
        t1 = time.perf_counter()
        pairs = self._touched_pairs(dataset, contacts, samples, touched, in_region)
        t2 = time.perf_counter()
        counts, densities = _densities(kernel, samples, pairs)
        uv, kind = _chart(surface, samples)
        notes: list[str] = []
        maps = self._curves(link, samples, kernel, densities, uv, kind, pairs, notes)
        t3 = time.perf_counter()
        comparison = self._tests(kernel, dataset.trials, in_region, pairs, notes)
        t4 = time.perf_counter()
        return RegionCoverage(
            region=region or ALL,
            link=link.name,
            by=self.by,
            groups=pairs.groups,
            samples=samples,
            uv=uv,
            surface_kind=kind,
            counts=counts,
            densities=densities,
            curves=maps.curves,
            regions=maps.regions,
            sentences=maps.sentences,
            heldout=maps.heldout,
            comparison=comparison,
            notes=notes,
            seconds={"surface": t1 - t0, "contacts": t2 - t1, "maps_and_curves": t3 - t2, "tests": t4 - t3},
        )

    def _check_inputs(self, dataset: GestureDataset, contacts: Contacts | None) -> None:
        """Raise ValueError when ``by``/``pair_by`` is no trial column or ``contacts`` is of another dataset."""
        trials = dataset.trials
        for col, key in ((self.by, "coverage.by"), (self.pair_by, "coverage.pair_by")):
            if col not in trials.columns:
                raise ValueError(
                    f"{key}={col!r} is not a column of dataset {dataset.name!r}'s trials; "
                    f"columns: {list(trials.columns)}"
                )
        if contacts is not None and contacts.n_frames != dataset.n_frames:
            raise ValueError(
                f"contacts cover {contacts.n_frames} frames but dataset {dataset.name!r} has "
                f"{dataset.n_frames}: they come from different datasets"
            )

    def _touched_pairs(
        self,
        dataset: GestureDataset,
        contacts: Contacts | None,
        samples: SurfaceSamples,
        touched: tuple[np.ndarray, np.ndarray] | None,
        in_region: np.ndarray,
    ) -> _Pairs:
        """The (frame, element) pairs of the trials ``in_region``: ``touched`` as given, else the elements
        ``contacts`` touch (``footprint``); with each pair's trial, group and ``pair_by`` unit."""
        trials = dataset.trials
        frame_trial = dataset.frame_trial_index()
        if touched is None:
            if contacts is None:
                raise ValueError("coverage: analyze needs contacts, or the touched (frame, element) pairs")
            sel = in_region[frame_trial[contacts.frame]]
            frames, elements = touched_elements(
                samples,
                contacts.frame[sel],
                contacts.point_m[sel],
                contacts.normal[sel],
                contacts.patch_radius_m[sel],
                self.footprint,
            )
        else:
            frames, elements = (np.asarray(x, dtype=np.int64) for x in touched)
            keep = in_region[frame_trial[frames]]
            frames, elements = frames[keep], elements[keep]
        trial_of = frame_trial[frames]
        labels = trials[self.by].astype(str).to_numpy()
        units = trials[self.pair_by].astype(str).to_numpy()
        groups = group_order(trials.loc[in_region, self.by], self.by)
        code = {g: i for i, g in enumerate(groups)}
        unit_codes, unit_names = pd.factorize(units)
        return _Pairs(
            frames=frames,
            elements=elements,
            trial_of=trial_of,
            labels=labels,
            units=units,
            groups=groups,
            code=code,
            group=np.array([code.get(v, -1) for v in labels], dtype=np.int64)[trial_of],
            unit=unit_codes[trial_of],
            unit_names=np.asarray(unit_names),
        )

    def _curves(
        self,
        link: Link,
        samples: SurfaceSamples,
        kernel: SurfaceKernel,
        densities: dict[str, np.ndarray],
        uv: np.ndarray | None,
        kind: str,
        pairs: _Pairs,
        notes: list[str],
    ) -> _Curves:
        """Per group (and ``"all"``): the greedy coverage curve at ``capture``, its regions and sentence, and
        (``heldout``) the leave-one-unit-out capture; a group without contact frames adds a note."""
        out = _Curves({}, {}, {}, pd.DataFrame(columns=["group", "unit", "area_share", "captured", "n_frames"]))
        held = []
        for n in [ALL] + pairs.groups:
            m = slice(None) if n == ALL else pairs.group == pairs.code[n]
            frames, elements, unit = pairs.frames[m], pairs.elements[m], pairs.unit[m]
            curve = coverage_curve(densities[n], samples.area_m2, frames, elements, self.capture, group=n)
            out.curves[n] = curve
            out.regions[n] = describe_regions(samples, curve.mask, uv, weight=densities[n] * samples.area_m2)
            out.sentences[n] = recommendation(curve, out.regions[n], kind, link.name)
            if self.heldout and curve.n_frames and np.count_nonzero(np.bincount(unit)) >= 2:
                h = heldout_capture(kernel, frames, elements, unit, self.capture)
                h["unit"] = pairs.unit_names[h["unit"].to_numpy(dtype=np.int64)]
                h.insert(0, "group", n)
                held.append(h)
            if curve.n_frames == 0:
                notes.append(f"group {n!r} has no contact frames on {link.name}")
        if held:
            out.heldout = pd.concat(held, ignore_index=True)
        return out

    def _tests(
        self, kernel: SurfaceKernel, trials: pd.DataFrame, in_region: np.ndarray, pairs: _Pairs, notes: list[str]
    ) -> PairwiseComparison | None:
        """The paired SWD tests between the groups (:meth:`_compare`), or None (with a note) when ``by`` is
        ``pair_by`` or there are fewer than two groups; a note when too few units can reach ``alpha``."""
        if self.pair_by == self.by:
            notes.append(f"no condition tests: coverage.by and coverage.pair_by are both {self.by!r}")
            return None
        if len(pairs.groups) < 2:
            notes.append(f"no condition tests: only {len(pairs.groups)} value(s) of {self.by!r}")
            return None
        comparison = self._compare(kernel, trials, in_region, pairs)
        n_max = int(comparison.table["n_participants"].max())
        if n_max <= self.exact_max and 2.0**-n_max > self.alpha:
            notes.append(
                f"with {n_max} {self.pair_by} value(s) the exact sign-flip test cannot reach "
                f"p <= {self.alpha:g} (smallest p = 2^-{n_max} = {2.0**-n_max:.3g})"
            )
        return comparison

    def _compare(
        self, kernel: SurfaceKernel, trials: pd.DataFrame, in_region: np.ndarray, pairs: _Pairs
    ) -> PairwiseComparison:
        """Split-half paired SWD tests between every pair of groups (see :mod:`sphri.analysis.compare`)."""
        s = kernel.samples
        elements, trial_of, labels, units = pairs.elements, pairs.trial_of, pairs.labels, pairs.units
        n_trials = len(trials)
        # per-trial element counts, only for trials with contact
        has = np.zeros(n_trials, dtype=bool)
        has[trial_of] = True
        ordinal = trials["trial_ordinal"].to_numpy() if "trial_ordinal" in trials.columns else np.arange(n_trials)
        order = np.argsort(trial_of, kind="stable")
        starts = np.searchsorted(trial_of[order], np.arange(n_trials + 1))

        def trial_counts(tr: np.ndarray) -> np.ndarray:
            el = np.concatenate([elements[order[starts[t] : starts[t + 1]]] for t in tr])
            return np.bincount(el, minlength=s.n).astype(float)

        member_lists: dict[tuple[str, str], list[np.integer]] = {}
        for t in np.flatnonzero(in_region & has):
            member_lists.setdefault((units[t], labels[t]), []).append(t)
        members = {k: np.asarray(v) for k, v in member_lists.items()}
        cache: dict[tuple[str, str, int, int], np.ndarray] = {}

        def half_masses(unit: str, cond: str, k: int, r: int) -> np.ndarray:
            key = (unit, cond, k, r)
            if key not in cache:
                tr = members[(unit, cond)]
                h0, h1 = rotated_halves(ordinal[tr], k, r)
                rho = kernel.smooth(np.stack([trial_counts(tr[h0]), trial_counts(tr[h1])]))
                cache[key] = rho * s.area_m2
            return cache[key]

        def halves(unit: str, a: str, b: str) -> list[tuple[np.ndarray, np.ndarray]] | None:
            """Every trial enters: one split per rotation of the trial order when 2 k leaves trials out."""
            if (unit, a) not in members or (unit, b) not in members:
                return None
            na, nb = members[(unit, a)].size, members[(unit, b)].size
            k = min(na, nb) // 2
            if k < 1:
                return None
            ra, rb = n_rotations(na, k), n_rotations(nb, k)
            return [(half_masses(unit, a, k, j % ra), half_masses(unit, b, k, j % rb)) for j in range(max(ra, rb))]

        participants = sorted({u for u, _ in members})
        sw = SharedSupportSW(s.points_m, self.n_projections, self.swd_p, self.seed)
        return paired_swd_tests(
            sw,
            participants,
            pairs.groups,
            halves,
            alpha=self.alpha,
            alternative=self.alternative,
            exact_max=self.exact_max,
            n_permutations=self.n_permutations,
            seed=self.seed,
        )


# ----------------------------------------------------------------------------- files


def safe_name(value: str, empty: str = "group") -> str:
    """A group value usable in file names (``empty`` when nothing of it is)."""
    return re.sub(r"[^\w.-]+", "_", str(value)).strip("_") or empty


def write_density_npz(result: RegionCoverage, group: str, path: str | Path) -> Path:
    """``points_m (P,3)``, ``density (P,)`` (1/m^2), ``mask (P,)`` (the placement),
    ``area_m2 (P,)``, ``normal (P,3)`` and ``uv (P,2)`` where charted: the
    format ``layout=density`` reads (``layout.density_path``)."""
    s = result.samples
    arrays = {
        "points_m": s.points_m,
        "density": result.densities[group],
        "mask": result.curves[group].mask,
        "area_m2": s.area_m2,
        "normal": s.normal,
        "counts": result.counts[group],
    }
    if result.uv is not None:
        arrays["uv"] = result.uv
    path = Path(path)
    # the stub's allow_pickle: bool keyword takes the **arrays (whose names are fixed above)
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]
    return path


def write_region(
    result: RegionCoverage,
    out_dir: str | Path,
    link: Link,
    surface: SurfaceMap | None,
    render: bool = True,
    views: int = 4,
    provenance: Provenance | None = None,
) -> list[Path]:
    """Write a region's files under ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = _write_tables(result, out)
    if render:
        t0 = time.perf_counter()
        paths += _render_region(result, out, link, surface, views, provenance)
        result.seconds["render"] = time.perf_counter() - t0
    (out / "summary.json").write_text(json.dumps(result.summary(), indent=2, default=_json_default))
    paths.append(out / "summary.json")
    return paths


def _write_tables(result: RegionCoverage, out: Path) -> list[Path]:
    """A region's data files in ``out``: ``density_<group>.npz`` per group (and ``"all"``), the coverage curves,
    the held-out table, the recommendation sentences and the SWD tables; returns their paths."""
    names = [ALL] + result.groups
    paths: list[Path] = []
    for n in names:
        paths.append(write_density_npz(result, n, out / f"density_{safe_name(n)}.npz"))
    curve_rows = pd.concat([result.curves[n].resampled() for n in names], ignore_index=True)
    curve_rows.to_csv(out / "coverage_curve.csv", index=False, float_format="%.6g")
    paths.append(out / "coverage_curve.csv")
    if len(result.heldout):
        result.heldout.to_csv(out / "heldout.csv", index=False, float_format="%.6g")
        paths.append(out / "heldout.csv")
    text = "\n".join(result.sentences[n] for n in names) + "\n"
    (out / "recommendation.txt").write_text(text)
    paths.append(out / "recommendation.txt")
    if result.comparison is not None:
        paths += result.comparison.write_csv(out)
    return paths


def _render_region(
    result: RegionCoverage,
    out: Path,
    link: Link,
    surface: SurfaceMap | None,
    views: int,
    provenance: Provenance | None,
) -> list[Path]:
    """A region's figures in ``out``: per group a map (PNG and PLY, a chart PNG where the surface has one),
    the overview, the coverage curves and the SWD heatmap; returns their paths."""
    from sphri.analysis import render as rd
    from sphri.figures import human

    names = [ALL] + result.groups
    paths: list[Path] = []
    view = rd.LinkView(link, result.samples)
    title = f"{result.region} ({result.link})"
    grid = rd.uv_grid(surface, result.samples) if surface is not None and surface.has_uv else None
    for n in names:
        dens = result.densities[n]
        label = f"{title}: {result.by} = {human(n)}" if n != ALL else f"{title}: all trials"
        paths.append(view.render(dens, out / f"map_{safe_name(n)}.png", label, views=views, provenance=provenance))
        paths.append(view.write_ply(dens, out / f"map_{safe_name(n)}.ply"))
        if grid is not None and surface is not None:  # grid is built only from a surface
            paths.append(
                rd.render_uv(
                    surface, result.samples, dens, out / f"uv_{safe_name(n)}.png", label, grid, provenance=provenance
                )
            )
    small = rd.LinkView(link, result.samples, target_faces=4000)
    paths.append(
        rd.plot_overview(
            small,
            {n: result.densities[n] for n in names},
            out / "overview.png",
            f"{title}: contact density by {result.by}",
            views=views,
            surface=surface,
            samples=result.samples,
            grid=grid,
            provenance=provenance,
        )
    )
    paths.append(
        rd.plot_coverage_curves(
            [result.curves[n] for n in names],
            out / "coverage_curve.png",
            f"{title}: greedy skin placement",
            provenance=provenance,
        )
    )
    if result.comparison is not None:
        paths.append(
            rd.plot_swd_heatmap(
                result.comparison,
                out / "swd_heatmap.png",
                f"{title}: touch distributions by {result.by}",
                provenance=provenance,
            )
        )
    return paths


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)
