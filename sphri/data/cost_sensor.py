"""CoST's sensor simulated with sphri's own components: contact area and duration as CoST measured them.

CoST (Jung et al. 2017, :mod:`sphri.data.reference_stats`) recorded touch
with an 8 x 8 pressure grid of 160 x 160 mm (20 mm pitch) wrapped around a
mannequin forearm, and reports per gesture the contact area as a fraction of
the 64 cells and the contact duration. A raw patch area (cm^2) is not
comparable with that: on a 20 mm grid a fingertip poke turns on at least one
cell of 400 mm^2, 1/64 = 0.016 of the sensor. So the comparison simulates
the sensor:

1. ``surface`` (the run's, ``surface=cylinder`` by default) is fitted to the
   region's link and a ``layout=grid`` is built on it with the row count
   that gives CoST's pitch along the link (``round(length / 20 mm)``; the
   Reachy arm: 12 rows of 20.1 mm, 11 columns of 20.3 mm around);
2. every frame of the region with a contact row is encoded by the chart
   raster of ``encoder=ellipse`` / ``encoder=coverage``, binary: a cell is on
   when contact patches cover at least :data:`CELL_THRESHOLD` of it or it
   holds a patch centre (a pressure cell reports a load anywhere on it; the
   threshold only drops patches that graze its edge);
3. the sensor lies where the trial touches (CoST's participants touched the
   sensor itself): of all 8 x 8 windows of the grid (wrapping around the
   link), the one with the most on cells summed over the trial's frames;
4. per trial: sensor contact frames are those with at least one of the 64
   cells on; ``area_fraction`` is the mean over them of (cells on) / 64;
   ``duration_s`` is first to last sensor contact frame, inclusive, over the
   frame rate (CoST: first to last contact, repetitions included).

:func:`sensor_trials` returns one row per trial;
:func:`sphri.data.stats.spatial_comparison` compares the per-gesture means and
SDs with CoST's Table 4, flagged per row like the temporal statistics.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sphri.data.reference_stats import COST_CELLS, COST_PITCH_M
from sphri.encode.ellipse import encode_grid
from sphri.layout.common import long_axis_length_m
from sphri.layout.grid import build_grid
from sphri.types import Contacts, GestureDataset, Robot, SurfaceMap

#: A cell is on when at least this fraction of it is covered by contact patches (or it holds a patch centre):
#: 1 % of a 20 mm cell is 4 mm^2. A pressure cell responds to a load anywhere on it, so any real overlap
#: counts [assumption: CoST's Table 4 does not state its area threshold].
CELL_THRESHOLD = 0.01

#: Sub-rows per cell of the chart raster (as ``encoder.subsamples``).
SUBSAMPLES = 8

#: Columns of :func:`sensor_trials`.
SENSOR_COLUMNS = [
    "participant",
    "region",
    "gesture",
    "sensor_contact",
    "sensor_frames",
    "area_fraction",
    "duration_s",
    "window_row",
    "window_col",
]


def sensor_grid(link, surface: SurfaceMap):
    """The grid layout of CoST's pitch on ``link`` (rows along it) through ``surface``'s chart.

    Raises ValueError when the chart cannot hold CoST's 8 x 8 cells.
    """
    rows = max(1, int(round(long_axis_length_m(surface) / COST_PITCH_M)))
    layout = build_grid(link, surface, rows)
    if layout.grid_shape is None:
        raise RuntimeError(f"link {link.name!r}: build_grid returned a layout without a grid shape")
    h, w = layout.grid_shape
    if h < COST_CELLS or w < COST_CELLS:
        raise ValueError(
            f"link {link.name!r}: a {COST_PITCH_M * 1e3:g} mm grid has {h} x {w} cells, fewer than "
            f"CoST's {COST_CELLS} x {COST_CELLS}"
        )
    return layout


def best_window(on_sum: np.ndarray, wrap_v: bool, size: int = COST_CELLS) -> tuple[int, int]:
    """(row, col) of the ``size`` x ``size`` window with the largest sum of ``on_sum (H, W)``; columns wrap
    when ``wrap_v``. Ties go to the lowest (row, col)."""
    h, w = on_sum.shape
    cols = np.arange(w) if wrap_v else np.arange(w - size + 1)
    ext = np.concatenate([on_sum, on_sum[:, : size - 1]], axis=1) if wrap_v else on_sum
    c = np.zeros((h + 1, ext.shape[1] + 1))
    c[1:, 1:] = ext.cumsum(0).cumsum(1)
    r = np.arange(h - size + 1)
    s = (
        c[r[:, None] + size, cols[None, :] + size]
        - c[r[:, None], cols[None, :] + size]
        - c[r[:, None] + size, cols[None, :]]
        + c[r[:, None], cols[None, :]]
    )
    i, j = np.unravel_index(int(np.argmax(s)), s.shape)
    return int(r[i]), int(cols[j])


def sensor_trials(
    dataset: GestureDataset, contacts: Contacts, robot: Robot, surface_component, threshold: float = CELL_THRESHOLD
) -> pd.DataFrame:
    """One row per trial (:data:`SENSOR_COLUMNS`) of the simulated CoST sensor (see the module docstring).

    ``surface_component``: an object with ``fit(link) -> SurfaceMap`` (the
    run's ``surface``). Trials whose sensor sees nothing have
    ``sensor_contact`` False, ``area_fraction`` NaN and ``duration_s`` 0.
    """
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"cost_threshold={threshold} is invalid: must be in (0, 1]")
    trials = dataset.trials
    n = len(trials)
    owner = dataset.frame_trial_index()
    start = trials["start"].to_numpy(np.int64)
    regions = trials["region"].astype(str).to_numpy()
    out = {
        "sensor_contact": np.zeros(n, bool),
        "sensor_frames": np.zeros(n, np.int64),
        "area_fraction": np.full(n, np.nan),
        "duration_s": np.zeros(n),
        "window_row": np.full(n, -1, np.int64),
        "window_col": np.full(n, -1, np.int64),
    }
    cf = np.asarray(contacts.frame, np.int64)
    for region in sorted(set(regions)):
        frames = np.unique(cf)
        frames = frames[regions[owner[frames]] == region] if frames.size else frames
        if frames.size == 0:
            continue
        link = robot.link_for(region)
        surface = surface_component.fit(link)
        layout = sensor_grid(link, surface)
        h, w = layout.grid_shape
        on = (
            encode_grid(contacts, surface, layout, frames, True, threshold, SUBSAMPLES, "CoST sensor")
            .values.reshape(-1, h, w)
            .astype(bool)
        )
        t_of = owner[frames]
        bounds = np.flatnonzero(np.r_[True, np.diff(t_of) != 0, True])
        for a, b in zip(bounds[:-1], bounds[1:]):
            t = int(t_of[a])
            o = on[a:b]
            i, j = best_window(o.sum(0), surface.wrap_v)
            cells = o[:, i : i + COST_CELLS][:, :, (j + np.arange(COST_CELLS)) % w].reshape(b - a, -1).sum(1)
            hit = cells > 0
            out["window_row"][t], out["window_col"][t] = i, j
            if not hit.any():
                continue
            f = frames[a:b][hit] - start[t]
            out["sensor_contact"][t] = True
            out["sensor_frames"][t] = int(hit.sum())
            out["area_fraction"][t] = float(cells[hit].mean() / COST_CELLS**2)
            out["duration_s"][t] = float(f[-1] - f[0] + 1) / dataset.frame_rate_hz
    df = pd.DataFrame(
        {
            "participant": trials["participant"].to_numpy(),
            "region": regions,
            "gesture": trials["gesture"].to_numpy(),
            **out,
        }
    )
    return df[SENSOR_COLUMNS]


def describe_sensor(robot: Robot, region: str, surface_component, threshold: float = CELL_THRESHOLD) -> str:
    """One line: the simulated sensor's grid on ``region`` (cells, pitch in mm)."""
    link = robot.link_for(region)
    surface = surface_component.fit(link)
    layout = sensor_grid(link, surface)
    h, w = layout.grid_shape
    return (
        f"simulated CoST sensor on {region} ({link.name}): {COST_CELLS} x {COST_CELLS} window of a {h} x {w} grid, "
        f"pitch {layout.pitch_u_m * 1e3:.1f} mm along x {layout.pitch_v_m * 1e3:.1f} mm around, binary "
        f"(cell on at >= {threshold:.0%} covered or holding a patch centre), placed where each trial touches"
    )
