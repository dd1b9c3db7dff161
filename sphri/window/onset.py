"""``window=onset``: per-trial windows aligned to the first contact frame.

:meth:`OnsetWindow.plan` decides from contacts alone which global frames each
trial's window holds (so that only those frames are encoded):
slot ``k`` of trial ``t`` is frame ``start_t + onset_t + k`` while that stays
inside the trial, else padding (-1, read as zeros). Trials with no contact at
all are counted and logged; ``no_contact: drop`` removes them,
``keep`` gives them a window starting at the trial's frame 0 (all zero before
noise, since nothing touches the skin). :meth:`OnsetWindow.assemble` scatters
the encoded frames (in ``plan.selected_frames()`` order) into
``x (n_kept, L, N)`` float32.

Both estimate their arrays' size before allocating them and raise
:class:`WindowMemoryError` (one line with the estimate) when it exceeds
``window.max_memory_gib`` or, unset, a quarter of the memory available
(``MemAvailable``): the noise and filter stages each hold a copy of the windows.
"""

from __future__ import annotations

import logging

import numpy as np

from sphri.config import Configured
from sphri.limits import available_memory_bytes
from sphri.types import Contacts, Frames, GestureDataset, Layout, SurfaceMap, TaxelGeometry, WindowedFrames, WindowPlan
from sphri.window.schema import OnsetWindowSchema

log = logging.getLogger(__name__)

GIB = float(1 << 30)


class WindowMemoryError(ValueError):
    """The windows would not fit in memory; the message gives the estimate and the setting."""


def check_memory(
    what: str, shape: tuple[int, ...], itemsize: int, max_memory_gib: float | None, copies: int = 1
) -> None:
    """Refuse an allocation of ``copies`` arrays of ``shape`` x ``itemsize`` bytes above the limit
    (``window.max_memory_gib``, else a quarter of the available memory), before it is made."""
    need = float(np.prod(np.asarray(shape, dtype=np.float64))) * itemsize * copies
    if max_memory_gib is not None:
        limit, why = float(max_memory_gib) * GIB, f"window.max_memory_gib={max_memory_gib:g}"
    else:
        avail = available_memory_bytes()
        if avail is None:
            return
        limit, why = avail / 4.0, f"a quarter of the {avail / GIB:.3g} GiB of memory available"
    if need > limit:
        dims = " x ".join(str(int(d)) for d in shape)
        raise WindowMemoryError(
            f"window: {what} ({dims}{f', {copies} arrays' if copies > 1 else ''}, {itemsize} bytes each) would take "
            f"{need / GIB:.3g} GiB, more than {why} ({limit / GIB:.3g} GiB): lower window.frames (now {shape[1]}), "
            f"the resolution or data.participants, or raise window.max_memory_gib"
        )


def trial_onsets(contacts: Contacts, dataset: GestureDataset) -> np.ndarray:
    """(N_trials,) int64 first contact frame of each trial, 0-based within the trial (-1 if none)."""
    if contacts.n_frames != dataset.n_frames:
        raise ValueError(
            f"window: contacts.n_frames={contacts.n_frames} differs from the dataset's {dataset.n_frames} frames"
        )
    trials = dataset.trials
    starts = trials["start"].to_numpy(dtype=np.int64)
    counts = trials["n_frames"].to_numpy(dtype=np.int64)
    if np.any(counts < 0) or np.any(starts < 0) or np.any(starts + counts > dataset.n_frames):
        raise ValueError("window: dataset.trials has start/n_frames outside the dataset's frames")
    onset = np.full(len(trials), -1, dtype=np.int64)
    fr = np.asarray(contacts.frame, dtype=np.int64)
    if fr.size == 0 or len(trials) == 0:
        return onset
    # first contact row at or after each trial's start, kept when inside the trial
    pos = np.searchsorted(fr, starts, side="left")
    first = fr[np.minimum(pos, fr.size - 1)]
    inside = (pos < fr.size) & (first < starts + counts)
    onset[inside] = first[inside] - starts[inside]
    return onset


class OnsetWindow(Configured):
    """``window=onset``: align to contact onset, clip or pad to ``frames``."""

    VERSION = "1"

    SCHEMA = OnsetWindowSchema
    frames: int  # these three set from SCHEMA by Configured
    no_contact: str
    max_memory_gib: float | None

    def plan(self, contacts: Contacts, dataset: GestureDataset) -> WindowPlan:
        """Which global frames fill each trial's window (see module docstring)."""
        fr = np.asarray(contacts.frame)
        if fr.size > 1 and np.any(np.diff(fr) < 0):
            raise ValueError("window: contacts.frame must be sorted (rows sorted by frame, then capsule)")
        onset = trial_onsets(contacts, dataset)
        starts = dataset.trials["start"].to_numpy(dtype=np.int64)
        counts = dataset.trials["n_frames"].to_numpy(dtype=np.int64)
        none = onset < 0
        n_none = int(none.sum())
        if n_none:
            log.warning(
                "window: %d of %d trials have no contact at all (%s them, window.no_contact=%s)",
                n_none,
                len(onset),
                "dropped" if self.no_contact == "drop" else "kept as zero windows",
                self.no_contact,
            )
        kept = ~none if self.no_contact == "drop" else np.ones(len(onset), dtype=bool)
        # idx, rel and their comparison: three (trials, frames) arrays of int64 live at once
        check_memory("the window plan", (len(onset), int(self.frames)), 8, self.max_memory_gib, copies=3)
        first = np.where(none, 0, onset)
        k = np.arange(self.frames, dtype=np.int64)[None, :]
        rel = first[:, None] + k
        idx = np.where(rel < counts[:, None], starts[:, None] + rel, -1)
        idx[~kept] = -1
        return WindowPlan(frame_index=idx.astype(np.int64), onset=onset, kept=kept)

    def assemble(
        self, frames: Frames, plan: WindowPlan, dataset: GestureDataset, layout: Layout, surface: SurfaceMap
    ) -> WindowedFrames:
        """Windows ``x (n_kept, L, N)`` float32 from frames encoded in ``plan.selected_frames()`` order."""
        values = np.asarray(frames.values)
        sel = plan.frame_index[plan.kept]
        mask = sel >= 0
        n_sel = int(mask.sum())
        if values.ndim != 2 or values.shape[0] != n_sel:
            raise ValueError(
                f"window.assemble: frames.values has shape {values.shape}; expected ({n_sel}, N) "
                "rows in plan.selected_frames() order"
            )
        if values.shape[1] != layout.n_taxels:
            raise ValueError(
                f"window.assemble: frames have {values.shape[1]} taxels but the layout has {layout.n_taxels}"
            )
        if len(plan.kept) != len(dataset.trials):
            raise ValueError(f"window.assemble: plan covers {len(plan.kept)} trials, dataset has {len(dataset.trials)}")
        check_memory("the windows", (sel.shape[0], plan.length, values.shape[1]), 4, self.max_memory_gib)
        x = np.zeros((sel.shape[0], plan.length, values.shape[1]), dtype=np.float32)
        x[mask] = values
        rows = np.flatnonzero(plan.kept).astype(np.int64)
        return WindowedFrames(
            x=x,
            y=dataset.labels[rows],
            groups=dataset.groups[rows],
            geometry=TaxelGeometry.from_layout(layout, surface),
            trial_row=rows,
            n_dropped=int((~plan.kept).sum()),
            frame_rate_hz=float(dataset.frame_rate_hz),
        )
