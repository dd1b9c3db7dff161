"""Contact statistics of any gesture dataset, side by side with published references.

``sphri stats [overrides]`` composes the config (e.g.
``data=vr_gesture data.root=DIR``, ``data.participants=4``), loads the
dataset, runs the configured contact stage and prints, per region and
gesture:

- trial length: median length of the whole trial (rest to rest) in frames
  at the references' 30 Hz, against the VR study's manifests;
- contact duration: first to last frame with any capsule in contact with the
  link, inclusive, divided by the frame rate (ms), mean over trials with
  contact, against CoST;
- contact area: per frame, the link surface area inside the union of the
  contact patches (disks of ``Contacts.patch_radius_m`` around
  ``Contacts.point_m``, measured on area-weighted surface samples), averaged
  over up to :data:`AREA_FRAMES` evenly spaced contact frames of the trial,
  then over trials (cm^2, and as a fraction of CoST's 160 x 160 mm sensor);
  only its ordering across gestures is comparable to CoST's;
- how many trials have no contact at all.

Then it compares distributions, not only centres, and flags every row whose
ratio to the reference falls outside its band (``ok`` / ``OUTSIDE``,
:data:`sphri.data.lengths.BANDS`):

- trial length (:mod:`sphri.data.lengths`): per gesture the 5/25/50/75/95 %
  quantiles and the SD of log length; over participants the variance of
  their mean log length, the participant x gesture variance, the median SD
  within participant and gesture, the range of per-participant medians and
  the longest trial. Reference: the VR manifests under ``reference=DIR``, or
  under ``data.root`` (``data=vr_gesture``), or ``../shared/vr-gesture-dataset``
  next to the repository when present; otherwise the copy of their numbers in
  :data:`sphri.data.reference_stats.VR_LENGTH_SPREAD`;
- contact duration: per gesture mean and SD over trials against CoST's mean
  and SD;
- the simulated CoST sensor (:mod:`sphri.data.cost_sensor`: an 8 x 8 grid of
  20 mm pitch, 160 x 160 mm, binary, where the trial touches): per gesture the
  mean and SD over trials of the contact-area fraction (cells on / 64, mean
  over the sensor's contact frames) and of the contact duration, against
  CoST's Table 4 (:func:`spatial_comparison`). This is the like-for-like
  spatial check (the raw patch area above is not: a poke turns on at least
  one 400 mm^2 cell, 0.016 of the sensor). CoST publishes no centre-of-pressure
  travel, so none is compared.

``sphri stats [overrides]`` is the same command. Extra arguments (:class:`StatsArgs`): ``json=PATH`` writes the per-gesture table as JSON (a list
of rows) and the comparison beside it (``PATH`` with ``_spread`` before the
suffix, the spatial rows included); ``reference=DIR`` names the manifests to
compare with; ``cost_threshold=X`` sets the simulated sensor's cell threshold
(fraction of a cell covered, default
:data:`sphri.data.cost_sensor.CELL_THRESHOLD`).

Participants that differ show in classification too: the Random Forest's
leave-one-subject-out accuracy should sit below within-subject k-fold (same
data and skin), as in recorded touch corpora. Measure both with
``python -m sphri [overrides]`` and ``python -m sphri cv=kfold [overrides]``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from sphri.args import arg
from sphri.data.cost_sensor import CELL_THRESHOLD, describe_sensor, sensor_trials
from sphri.data.lengths import (
    COMPARISON_COLUMNS,
    COST_BAND_LEVEL,
    compare,
    cost_band,
    flag_row,
    format_comparison,
    length_spread,
    length_table,
    manifest_lengths,
)
from sphri.data.linkgeom import LinkSurface
from sphri.data.reference_stats import (
    COST_AREA_FRACTION,
    COST_CELLS,
    COST_DURATION_MS,
    COST_PARTICIPANTS,
    COST_SENSOR_AREA_M2,
    COST_SOURCE,
    DURATION_TOLERANCE,
    TRIAL_LENGTH_TOLERANCE,
    VR_FRAME_RATE_HZ,
    VR_LENGTH_SPREAD,
    median_trial_frames,
)
from sphri.types import GESTURES, Contacts, GestureDataset, Robot

log = logging.getLogger(__name__)

#: Contact frames per trial over which the contact area is averaged.
AREA_FRAMES = 8


def trial_statistics(dataset: GestureDataset, contacts: Contacts, robot: Robot) -> pd.DataFrame:
    """One row per trial: participant, region, gesture, n_frames, trial_s (seconds), contact (bool),
    first/last contact frame (within the trial, -1 if none), duration_s,
    area_m2 (mean union patch area over sampled contact frames, NaN if none)
    and n_capsules (distinct capsules that ever touch)."""
    trials = dataset.trials
    owner = dataset.frame_trial_index()
    n_trials = len(trials)
    start = trials["start"].to_numpy(np.int64)
    cf = contacts.frame.astype(np.int64)
    ct = owner[cf] if cf.size else np.zeros(0, np.int64)
    first = np.full(n_trials, -1, np.int64)
    last = np.full(n_trials, -1, np.int64)
    if cf.size:
        # contacts are sorted by frame, so the first/last row per trial gives first/last frame
        uniq, idx_first = np.unique(ct, return_index=True)
        idx_last = len(ct) - 1 - np.unique(ct[::-1], return_index=True)[1]
        first[uniq] = cf[idx_first] - start[uniq]
        last[uniq] = cf[idx_last] - start[uniq]
    has = first >= 0
    duration = np.where(has, (last - first + 1) / dataset.frame_rate_hz, 0.0)
    ncap = np.zeros(n_trials, np.int64)
    if cf.size:
        pairs = np.unique(ct * 10000 + contacts.capsule.astype(np.int64))
        np.add.at(ncap, pairs // 10000, 1)
    area = _trial_areas(dataset, contacts, robot, ct)
    return pd.DataFrame(
        {
            "participant": trials["participant"].to_numpy(),
            "region": trials["region"].to_numpy(),
            "gesture": trials["gesture"].to_numpy(),
            "n_frames": trials["n_frames"].to_numpy(np.int64),
            "trial_s": trials["n_frames"].to_numpy(np.int64) / dataset.frame_rate_hz,
            "contact": has,
            "first_contact": first,
            "last_contact": last,
            "duration_s": duration,
            "area_m2": area,
            "n_capsules": ncap,
        }
    )


def _trial_areas(dataset: GestureDataset, contacts: Contacts, robot: Robot, ct: np.ndarray) -> np.ndarray:
    trials = dataset.trials
    area = np.full(len(trials), np.nan)
    if contacts.n_contacts == 0:
        return area
    cf = contacts.frame.astype(np.int64)
    # pick up to AREA_FRAMES evenly spaced contact frames per trial
    frames, fi = np.unique(cf, return_index=True)
    ftrial = ct[fi]
    keep = np.zeros(len(frames), bool)
    bounds = np.flatnonzero(np.r_[True, np.diff(ftrial) != 0, True])
    seg_a, seg_len = bounds[:-1], np.diff(bounds)
    steps = np.linspace(0.0, 1.0, AREA_FRAMES)
    keep[(seg_a[:, None] + np.round(steps[None, :] * (seg_len[:, None] - 1)).astype(np.int64)).ravel()] = True
    sel_frames = frames[keep]
    rows = np.isin(cf, sel_frames)
    regions = trials["region"].to_numpy()
    owner = dataset.frame_trial_index()
    for region in np.unique(regions):
        surf = LinkSurface(robot.link_for(str(region)), n_samples=6000)
        per_sample = surf.area_m2 / 6000.0
        tree = surf.tree
        r_rows = rows & (regions[ct] == region)
        idx = np.flatnonzero(r_rows)
        if idx.size == 0:
            continue
        radius = np.maximum(contacts.patch_radius_m[idx], 0.0)
        hits = tree.query_ball_point(contacts.point_m[idx], radius, return_sorted=False)
        counts = np.fromiter((len(h) for h in hits), np.int64, len(hits))
        samples = np.concatenate([np.asarray(h, np.int64) for h in hits]) if counts.sum() else np.zeros(0, np.int64)
        fr = np.repeat(cf[idx], counts)
        n_s = len(surf.points)
        key = _unique(fr * n_s + samples)
        uf, n_in = _unique_counts(key // n_s)
        frames_r = np.unique(cf[idx])
        frame_area = np.zeros(len(frames_r))
        frame_area[np.searchsorted(frames_r, uf)] = n_in * per_sample
        t_of = owner[frames_r]
        sums = np.bincount(t_of, weights=frame_area, minlength=len(trials))
        cnt = np.bincount(t_of, minlength=len(trials))
        got = cnt > 0
        area[got] = sums[got] / cnt[got]
    return area


def _unique(x: np.ndarray) -> np.ndarray:
    """Sorted unique values of an int array (sort-based; faster than np.unique's hash for large arrays)."""
    x = np.sort(x)
    return x[np.r_[True, x[1:] != x[:-1]]] if x.size else x


def _unique_counts(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unique values, counts) of an already sorted int array."""
    if x.size == 0:
        return x, np.zeros(0, np.int64)
    edges = np.flatnonzero(np.r_[True, x[1:] != x[:-1], True])
    return x[edges[:-1]], np.diff(edges)


def gesture_summary(stats: pd.DataFrame) -> pd.DataFrame:
    """Per (region, gesture): measured statistics and their references (see the module docstring)."""
    rows = []
    for (region, gesture), g in stats.groupby(["region", "gesture"], sort=False):
        touched = g[g["contact"]]
        ref_len = median_trial_frames(str(region), str(gesture))
        rows.append(
            {
                "region": region,
                "gesture": gesture,
                "trials": len(g),
                "no_contact": int((~g["contact"]).sum()),
                "median_frames": float(g["trial_s"].median() * VR_FRAME_RATE_HZ),
                "ref_median_frames": ref_len,
                "duration_ms": float(touched["duration_s"].mean() * 1000.0) if len(touched) else float("nan"),
                "ref_duration_ms": COST_DURATION_MS[gesture][0],
                "area_cm2": float(touched["area_m2"].mean() * 1e4) if len(touched) else float("nan"),
                "area_fraction": float(touched["area_m2"].mean() / COST_SENSOR_AREA_M2)
                if len(touched)
                else float("nan"),
                "ref_area_fraction": COST_AREA_FRACTION[gesture][0],
                "capsules": float(touched["n_capsules"].mean()) if len(touched) else float("nan"),
            }
        )
    return _by_region_gesture(pd.DataFrame(rows))


def _by_region_gesture(table: pd.DataFrame) -> pd.DataFrame:
    """``table`` sorted by region, then gesture in :data:`sphri.types.GESTURES` order (a stable sort), index reset."""
    order = {g: i for i, g in enumerate(GESTURES)}
    if len(table):
        table = table.sort_values(["region", "gesture"], key=lambda s: s.map(order) if s.name == "gesture" else s)
    return table.reset_index(drop=True)


def calibration_checks(summary: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """(check, passed, detail) for the generator's calibration targets, per region.

    Mean contact duration within +/- :data:`DURATION_TOLERANCE` of CoST per
    gesture; median trial length within +/- :data:`TRIAL_LENGTH_TOLERANCE` of
    the VR manifests; contact area largest for grab and smallest for poke
    (when both are present).
    """
    out = []
    for region, s in summary.groupby("region", sort=False):
        for _, r in s.iterrows():
            rel = r["duration_ms"] / r["ref_duration_ms"] - 1.0
            out.append(
                (
                    f"{region}/{r['gesture']} duration",
                    bool(abs(rel) <= DURATION_TOLERANCE),
                    f"{r['duration_ms']:.0f} ms vs CoST {r['ref_duration_ms']:.0f} ms ({rel:+.0%})",
                )
            )
            rel = r["median_frames"] / r["ref_median_frames"] - 1.0
            out.append(
                (
                    f"{region}/{r['gesture']} trial length",
                    bool(abs(rel) <= TRIAL_LENGTH_TOLERANCE),
                    f"median {r['median_frames']:.1f} vs VR {r['ref_median_frames']:.1f} frames ({rel:+.0%})",
                )
            )
        areas = s.set_index("gesture")["area_cm2"]
        if "grab" in areas and "poke" in areas and len(areas) > 1:
            out.append(
                (
                    f"{region} area: grab largest",
                    bool(areas.idxmax() == "grab"),
                    f"largest {areas.idxmax()} ({areas.max():.1f} cm2)",
                )
            )
            out.append(
                (
                    f"{region} area: poke smallest",
                    bool(areas.idxmin() == "poke"),
                    f"smallest {areas.idxmin()} ({areas.min():.1f} cm2)",
                )
            )
    return out


def format_summary(summary: pd.DataFrame, dataset_name: str = "", frame_rate_hz: float = 0.0) -> str:
    """A fixed-width text table of :func:`gesture_summary` with the references beside each value."""
    head = (
        f"{'region':7s} {'gesture':7s} {'trials':>6s} {'none':>5s} | {'len med':>7s} {'VR':>6s} | "
        f"{'dur ms':>7s} {'CoST':>6s} | {'area cm2':>8s} {'frac':>5s} {'CoST':>5s} | {'caps':>4s}"
    )
    lines = []
    if dataset_name:
        lines.append(f"dataset: {dataset_name} ({frame_rate_hz:g} Hz frames)")
    lines += [head, "-" * len(head)]
    for _, r in summary.iterrows():
        lines.append(
            f"{r['region']:7s} {r['gesture']:7s} {r['trials']:6d} {r['no_contact']:5d} | "
            f"{r['median_frames']:7.1f} {r['ref_median_frames']:6.1f} | {r['duration_ms']:7.0f} {r['ref_duration_ms']:6.0f} | "
            f"{r['area_cm2']:8.1f} {r['area_fraction']:5.2f} {r['ref_area_fraction']:5.2f} | {r['capsules']:4.1f}"
        )
    lines.append(
        "references: trial length = VR gesture dataset manifests (median, ~30 Hz frames); "
        f"duration and area = {COST_SOURCE}; see sphri/data/reference_stats.py"
    )
    return "\n".join(lines)


def duration_comparison(stats: pd.DataFrame) -> pd.DataFrame:
    """Per (region, gesture): mean and SD of contact duration (ms, trials with contact) against CoST's, flagged
    like :func:`sphri.data.lengths.compare`."""
    rows = []
    touched = stats[stats["contact"]]
    for (region, gesture), g in touched.groupby(["region", "gesture"], sort=False):
        d = g["duration_s"].to_numpy() * 1000.0
        mean, sd = COST_DURATION_MS[str(gesture)]
        for name, value, ref, what in (
            ("duration mean ms", float(d.mean()), mean, "mean"),
            ("duration sd ms", float(d.std(ddof=1)) if len(d) > 1 else float("nan"), sd, "sd"),
        ):
            row = flag_row(name, str(gesture), value, ref, what, cost_band(what, mean, sd))
            row["region"] = region
            rows.append(row)
    return _by_region_gesture(pd.DataFrame(rows, columns=COMPARISON_COLUMNS))


#: How the CoST rows' bands are made, printed under the tables.
COST_BAND_TEXT = (
    f"CoST bands: the {COST_BAND_LEVEL:.0%} sampling interval of CoST's own number as a ratio, from its reported mean, "
    f"SD and participant count n = {COST_PARTICIPANTS} ({COST_SOURCE}): mean 1 +/- t * (SD / mean) / sqrt(n), SD the "
    "chi-square interval (sphri.data.lengths.cost_band); CoST's sampling error only, not the simulation's"
)


#: Statistics of :func:`spatial_comparison`, in print order: (name, sensor column, mean or sd).
SPATIAL_STATISTICS = (
    ("CoST sensor area mean", "area_fraction", "mean"),
    ("CoST sensor area sd", "area_fraction", "sd"),
    ("CoST sensor dur mean ms", "duration_s", "mean"),
    ("CoST sensor dur sd ms", "duration_s", "sd"),
)


def spatial_comparison(sensor: pd.DataFrame) -> pd.DataFrame:
    """Per (region, gesture) of a :func:`sphri.data.cost_sensor.sensor_trials` table: mean and SD over the trials
    the sensor saw of the contact-area fraction and of the contact duration (ms), against CoST's Table 4, each
    flagged in its band (:func:`sphri.data.lengths.cost_band`: the sampling interval of CoST's number from its
    reported mean, SD and 31 participants). Columns :data:`sphri.data.lengths.COMPARISON_COLUMNS`; rows grouped by statistic, gestures
    in :data:`sphri.types.GESTURES` order."""
    rows = []
    seen = sensor[sensor["sensor_contact"]]
    order = {g: i for i, g in enumerate(GESTURES)}
    groups = sorted(seen.groupby(["region", "gesture"], sort=False), key=lambda kv: (kv[0][0], order.get(kv[0][1], 99)))
    for name, column, what in SPATIAL_STATISTICS:
        for (region, gesture), g in groups:
            x = g[column].to_numpy(np.float64) * (1000.0 if column == "duration_s" else 1.0)
            ref = (COST_AREA_FRACTION if column == "area_fraction" else COST_DURATION_MS)[str(gesture)]
            value = float(x.mean()) if what == "mean" else (float(x.std(ddof=1)) if len(x) > 1 else float("nan"))
            row = flag_row(name, str(gesture), value, ref[0] if what == "mean" else ref[1], what, cost_band(what, *ref))
            row["region"] = region
            rows.append(row)
    return pd.DataFrame(rows, columns=COMPARISON_COLUMNS)


def outside_area_lines(table: pd.DataFrame) -> list[str]:
    """One plain line per region naming the gestures whose CoST-sensor area mean is outside its band, with
    ratio and band (a :func:`spatial_comparison` table); none when every gesture is inside."""
    area = table[(table["statistic"] == SPATIAL_STATISTICS[0][0]) & (table["flag"] != "ok")]
    return [
        f"{region}: contact area outside its CoST band: "
        + ", ".join(f"{r['gesture']} {r['ratio']:.2f}x (band {r['band']})" for _, r in rows.iterrows())
        for region, rows in area.groupby("region", sort=False)
    ]


def spatial_checks(table: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """(check, passed, detail) per region: how many gestures' CoST-sensor area fraction lies in its band
    (the generator's spatial calibration target: at least 6 of 8)."""
    out = []
    area = table[table["statistic"] == SPATIAL_STATISTICS[0][0]]
    for region, a in area.groupby("region", sort=False):
        n_in = int((a["flag"] == "ok").sum())
        out.append(
            (
                f"{region} CoST sensor area",
                n_in >= min(6, len(a)),
                f"{n_in}/{len(a)} gestures in band; outside: {', '.join(a.loc[a['flag'] != 'ok', 'gesture']) or '-'}",
            )
        )
    return out


def reference_spread(reference: str | None, regions: Sequence[str]) -> tuple[dict, str]:
    """(length spread of the reference, where it came from): see the module docstring for the order."""
    candidates = [reference] if reference else []
    if not reference:
        candidates.append(str(Path(__file__).resolve().parents[2].parent / "shared" / "vr-gesture-dataset"))
    for c in candidates:
        path = Path(c)
        if path.is_dir() and any((path / r).is_dir() for r in regions):
            have = [r for r in regions if (path / r).is_dir()]
            return length_spread(manifest_lengths(path, have)), f"manifests under {path}"
        if reference:
            raise FileNotFoundError(f"reference={reference}: no {list(regions)} folders with manifests there")
    return VR_LENGTH_SPREAD, "VR manifests (numbers stored in sphri.data.reference_stats.VR_LENGTH_SPREAD)"


def dataset_statistics(
    overrides: Sequence[str] = (), cost_threshold: float = CELL_THRESHOLD
) -> tuple[GestureDataset, pd.DataFrame, pd.DataFrame, pd.DataFrame, list[str]]:
    """Compose the config, build hand, robot, dataset and contacts; return (dataset, trial stats, summary,
    simulated CoST sensor per trial, one line per region describing that sensor)."""
    from hydra.utils import instantiate

    from sphri.config import compose

    cfg = compose(list(overrides))
    hand = instantiate(cfg.hand).build()
    robot = instantiate(cfg.robot).build()
    dataset = instantiate(cfg.data).load(hand=hand, robot=robot)
    contacts = instantiate(cfg.contact).compute(dataset, robot)
    stats = trial_statistics(dataset, contacts, robot)
    surface = instantiate(cfg.surface)
    sensor = sensor_trials(dataset, contacts, robot, surface, cost_threshold)
    lines = [
        describe_sensor(robot, r, surface, cost_threshold) for r in sorted(set(dataset.trials["region"].astype(str)))
    ]
    return dataset, stats, gesture_summary(stats), sensor, lines


def _threshold(value: float) -> str | None:
    return None if 0.0 < value <= 1.0 else "must be in (0, 1]"


@dataclasses.dataclass
class StatsArgs:
    overrides: list[str] = arg([], rest=True, help="config overrides, e.g. data=vr_gesture data.root=DIR")
    json: str | None = arg(None, help="write the per-gesture table here as JSON, the comparison beside it (_spread)")
    reference: str | None = arg(None, help="a folder of VR manifests per region to compare trial lengths with")
    cost_threshold: float = arg(
        CELL_THRESHOLD, check=_threshold, help="the simulated CoST sensor's cell threshold (fraction of a cell)"
    )


def command(args: StatsArgs) -> int:
    """Compose the config, load the dataset, run the contact stage and print per region and gesture the trial
    lengths, contact durations and areas against the VR manifests and CoST, each row flagged ok or OUTSIDE."""
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    dataset, stats, summary, sensor, sensor_lines = dataset_statistics(args.overrides, args.cost_threshold)
    label = f"{dataset.name} ({'generated by sphri' if dataset.synthetic else 'recorded'})"
    print(format_summary(summary, label, dataset.frame_rate_hz))
    if dataset.repairs:
        print(f"repairs on load: {dataset.repairs}")
    spatial = spatial_comparison(sensor)
    if dataset.synthetic:
        checks = calibration_checks(summary) + spatial_checks(spatial)
        failed = [c for c in checks if not c[1]]
        print(f"calibration: {len(checks) - len(failed)}/{len(checks)} checks pass")
        for name, _, detail in failed:
            print(f"  FAIL {name}: {detail}")
    ref, source = reference_spread(args.reference, sorted(set(dataset.trials["region"])))
    lengths = length_spread(length_table(dataset.trials, dataset.frame_rate_hz))
    table = pd.concat([compare(lengths, ref), duration_comparison(stats)], ignore_index=True)
    print()
    print(format_comparison(table, f"distributions against {source} and {COST_SOURCE}:"))
    print()
    print("\n".join(sensor_lines))
    print(
        format_comparison(
            spatial,
            f"the simulated CoST sensor ({COST_CELLS} x {COST_CELLS}, 160 x 160 mm) against "
            f"{COST_SOURCE}: contact-area fraction (cells on / 64) and "
            "contact duration; trials the sensor saw:",
        )
    )
    print(COST_BAND_TEXT)
    for line in outside_area_lines(spatial):
        print(line)
    table = pd.concat([table, spatial], ignore_index=True)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(summary.to_dict(orient="records"), indent=2) + "\n")
        spread = {"reference": source, "rows": table.to_dict(orient="records")}
        path.with_name(f"{path.stem}_spread{path.suffix}").write_text(json.dumps(spread, indent=2) + "\n")
    return 0
