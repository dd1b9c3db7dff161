"""Distributions of trial length: quantiles, within- and between-participant spread, per gesture.

Trial length is the whole self-paced trial (rest to rest) in frames at the
VR study's 30 Hz (:data:`sphri.data.reference_stats.VR_FRAME_RATE_HZ`).
Trials shorter than :data:`MIN_FRAMES` frames are left out (the recorded
data has a few broken 1-frame trials; the loader drops them too).

The spread is decomposed on the log scale, as for any repeated-measures
data: ``r = log(frames) - mean log(frames) of the gesture``;

- ``sd_log``: SD of log length within a gesture (all participants);
- ``between_var``: variance over participants of their mean ``r``
  (how much slower or faster people are, gesture removed);
- ``interaction_var``: variance of the participant x gesture means of ``r``
  after removing each participant's mean (people differ per gesture);
- ``within_sd``: median over (participant, gesture) of the SD of log length
  (a person repeating a gesture);
- ``participant_median_min`` / ``_max``: range of per-participant median length;
- ``max_frames``: the longest trial.

:func:`compare` puts a dataset's numbers beside a reference (the real
manifests, or the copy in :data:`sphri.data.reference_stats.VR_LENGTH_SPREAD`)
and flags each row whose ratio falls outside its band (:data:`BANDS`; the bands
of the CoST statistics are sampling intervals of CoST's own numbers, :func:`cost_band`,
cited as :data:`sphri.data.reference_stats.COST_SOURCE`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from sphri.data.reference_stats import COST_PARTICIPANTS, REGION_STATISTICS, VR_FRAME_RATE_HZ
from sphri.types import GESTURES

#: Trials shorter than this (frames) are left out of the statistics.
MIN_FRAMES = 10

#: Quantiles of trial length reported per gesture.
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)

#: Accepted ratio (dataset / reference) per statistic: (lo, hi). Between-participant
#: variances over 18 participants have a sampling SE of about 35 %, hence the wider band.
BANDS: dict[str, tuple[float, float]] = {
    "sd_log": (0.7, 1.4),
    "quantile": (0.7, 1.4),
    "between_var": (0.5, 2.0),
    "interaction_var": (0.33, 3.0),
    "within_sd": (0.7, 1.4),
    "participant_median_min": (0.7, 1.4),
    "participant_median_max": (0.7, 1.4),
    "max_frames": (0.33, 3.0),
}

#: Confidence level of the CoST sampling bands (:func:`cost_band`).
COST_BAND_LEVEL = 0.95


def cost_band(what: str, mean: float, sd: float, n: int = COST_PARTICIPANTS) -> tuple[float, float]:
    """Accepted ratio (dataset / CoST) for a CoST Table 4 statistic: the sampling interval of CoST's own number,
    from its reported mean, SD and sample size (source: :data:`sphri.data.reference_stats.COST_SOURCE`).

    ``what="mean"``: ``1 +/- t(0.975, n-1) * (sd / mean) / sqrt(n)`` (the t interval of a mean, as a ratio);
    ``what="sd"``: ``sqrt((n-1) / chi2(0.975, n-1))`` .. ``sqrt((n-1) / chi2(0.025, n-1))`` (the chi-square
    interval of an SD). ``n`` is the 31 participants, not CoST's 558 captures per gesture: one person's
    captures are not independent, so the participant count is the sample size the interval can claim (with
    558 independent captures every band would be about 4 times narrower). The interval covers CoST's sampling
    error only; the simulated data's own sampling error and any real difference between CoST's mannequin arm
    and a robot's skin are not in it.
    """
    from scipy.stats import chi2, t

    if n < 2 or not (np.isfinite(mean) and np.isfinite(sd)) or mean <= 0 or sd < 0:
        raise ValueError(f"cost_band: needs n >= 2, a positive mean and an SD >= 0, got {n}, {mean}, {sd}")
    a = 1.0 - COST_BAND_LEVEL
    if what == "mean":
        half = float(t.ppf(1.0 - a / 2, n - 1)) * (sd / mean) / np.sqrt(n)
        return max(1.0 - half, 0.0), 1.0 + half
    if what == "sd":
        return (
            float(np.sqrt((n - 1) / chi2.ppf(1.0 - a / 2, n - 1))),
            float(np.sqrt((n - 1) / chi2.ppf(a / 2, n - 1))),
        )
    raise ValueError(f"cost_band: what={what!r} must be 'mean' or 'sd'")


def length_table(trials: pd.DataFrame, frame_rate_hz: float) -> pd.DataFrame:
    """``trials`` (participant, region, gesture, n_frames) -> one row per trial with ``frames`` at 30 Hz and ``log``."""
    frames = trials["n_frames"].to_numpy(np.float64) * VR_FRAME_RATE_HZ / float(frame_rate_hz)
    out = pd.DataFrame(
        {
            "participant": trials["participant"].to_numpy(),
            "region": trials["region"].to_numpy(),
            "gesture": trials["gesture"].to_numpy(),
            "frames": frames,
        }
    )
    out = out[out["frames"] >= MIN_FRAMES].reset_index(drop=True)
    out["log"] = np.log(out["frames"])
    return out


def length_spread(lengths: pd.DataFrame) -> dict[str, dict]:
    """Per region: ``{"gestures": {g: {n, sd_log, q05..q95}}, "between_var", "interaction_var", "within_sd",
    "participant_median_min", "participant_median_max", "max_frames", "participants"}`` of a :func:`length_table`."""
    out: dict[str, dict] = {}
    for region, t in lengths.groupby("region", sort=False):
        t = t.copy()
        t["r"] = t["log"] - t.groupby("gesture")["log"].transform("mean")
        gestures = {}
        for g in [g for g in GESTURES if g in set(t["gesture"])]:
            x = t.loc[t["gesture"] == g, "frames"].to_numpy()
            row = {"n": int(len(x)), "sd_log": float(np.std(np.log(x), ddof=1)) if len(x) > 1 else float("nan")}
            row.update({f"q{int(round(q * 100)):02d}": float(v) for q, v in zip(QUANTILES, np.quantile(x, QUANTILES))})
            gestures[g] = row
        per_p = t.groupby("participant")["r"].mean()
        pg = t.groupby(["participant", "gesture"])["r"].mean()
        inter = pg - per_p.reindex(pg.index.get_level_values(0)).to_numpy()
        within = t.groupby(["participant", "gesture"])["log"].std(ddof=1).dropna()
        med = t.groupby("participant")["frames"].median()
        out[str(region)] = {
            "gestures": gestures,
            "participants": int(len(per_p)),
            "between_var": float(per_p.var(ddof=1)) if len(per_p) > 1 else float("nan"),
            "interaction_var": float(np.var(inter.to_numpy())) if len(inter) else float("nan"),
            "within_sd": float(within.median()) if len(within) else float("nan"),
            "participant_median_min": float(med.min()),
            "participant_median_max": float(med.max()),
            "max_frames": float(t["frames"].max()),
        }
    return out


def manifest_lengths(root: str | Path, regions: Sequence[str] = ("arm",)) -> pd.DataFrame:
    """A :func:`length_table` of every trial in the manifests under ``root`` (no pose file is read)."""
    from sphri.data.format import manifest_path, read_manifest
    from sphri.data.vr_gesture import find_participants

    root = Path(root)
    rows = []
    for region in regions:
        for pid in find_participants(root, [region]):
            path = manifest_path(root, region, pid)
            if not path.is_file():
                continue  # a participant without this region (participant 17 has no torso)
            m = read_manifest(path)
            rate = float(m.get("frame_rate_hz", VR_FRAME_RATE_HZ))
            for t in m["trials"]:
                rows.append(
                    {
                        "participant": pid,
                        "region": region,
                        "gesture": t["gesture_label"],
                        "n_frames": int(t["frame_count"]) * VR_FRAME_RATE_HZ / rate,
                    }
                )
    if not rows:
        raise FileNotFoundError(f"{root}: no manifests for regions {list(regions)}")
    return length_table(pd.DataFrame(rows), VR_FRAME_RATE_HZ)


#: Columns of a comparison table.
COMPARISON_COLUMNS = ["region", "statistic", "gesture", "value", "reference", "ratio", "band", "flag"]


def flag_row(
    statistic: str, gesture: str, value: float, ref: float, band: str, bounds: tuple[float, float] | None = None
) -> dict:
    """One comparison row: ``value / ref`` flagged ``ok`` inside ``bounds`` (else :data:`BANDS` ``[band]``)."""
    lo, hi = bounds if bounds is not None else BANDS[band]
    ratio = value / ref if ref else float("nan")
    ok = bool(np.isfinite(ratio) and lo <= ratio <= hi)
    return {
        "statistic": statistic,
        "gesture": gesture,
        "value": value,
        "reference": ref,
        "ratio": ratio,
        "band": f"{lo:.2f}-{hi:.2f}x",
        "flag": "ok" if ok else "OUTSIDE",
    }


def compare(measured: dict[str, dict], reference: dict[str, dict]) -> pd.DataFrame:
    """One row per (region, statistic, gesture) present in both: value, reference, ratio, band, flag (``ok``/``OUTSIDE``)."""
    rows = []
    for region, m in measured.items():
        ref = reference.get(region)
        if ref is None:
            continue
        for g, mg in m["gestures"].items():
            rg = ref["gestures"].get(g)
            if rg is None:
                continue
            rows.append(flag_row("sd_log", g, mg["sd_log"], rg["sd_log"], "sd_log"))
            for q in QUANTILES:
                k = f"q{int(round(q * 100)):02d}"
                rows.append(flag_row(f"length {k}", g, mg[k], rg[k], "quantile"))
        for k in REGION_STATISTICS:
            if k == "participants":  # a count, not compared
                continue
            rows.append(flag_row(k, "all", m[k], ref[k], k))
        for r in rows:
            r.setdefault("region", region)
    return pd.DataFrame(rows, columns=COMPARISON_COLUMNS)


def format_comparison(table: pd.DataFrame, title: str) -> str:
    """A fixed-width text table of :func:`compare` (or any table with the same columns)."""
    head = f"{'region':6s} {'statistic':24s} {'gesture':7s} {'value':>9s} {'ref':>9s} {'ratio':>6s} {'band':>10s}  flag"
    lines = [title, head, "-" * len(head)]
    for _, r in table.iterrows():
        lines.append(
            f"{r['region']:6s} {r['statistic']:24s} {r['gesture']:7s} {r['value']:9.3f} {r['reference']:9.3f} "
            f"{r['ratio']:6.2f} {r['band']:>10s}  {r['flag']}"
        )
    n_out = int((table["flag"] != "ok").sum()) if len(table) else 0
    lines.append(f"{len(table) - n_out}/{len(table)} rows inside their band; {n_out} OUTSIDE")
    return "\n".join(lines)
