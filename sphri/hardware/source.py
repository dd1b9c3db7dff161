"""The pipeline's data for the hardware commands: trials, contacts, encoded frames.

The hardware commands take the same overrides as ``python -m sphri`` and
read the cached stages through :func:`sphri.pipeline.make_pipeline`, so a
replayed trial or a simulated skin stream is exactly what the classifier
sees in simulation: the frames of a trial's window are taken from the
chain's own ``noise`` stage (the window plan restricted to the streamed
trials handed in as the ``plan`` input, :meth:`sphri.pipeline.Pipeline.given`),
so offline and streamed readings are equal by construction. Only the frames
no window holds (before the contact onset, past the window, the gaps between
trials) get draws of their own, from keys no window uses (:func:`outside_keys`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sphri.config import ConfigError, compose
from sphri.types import SkinFrames, TaxelGeometry


def open_pipeline(overrides: Sequence[str]):
    """Compose the config from ``overrides`` and wire the (lazy, cached) pipeline."""
    from sphri.pipeline import make_pipeline, open_cache

    cfg = compose(list(overrides))
    return make_pipeline(cfg, open_cache(cfg))


@dataclass
class EncodedTrials:
    """Skin readings of whole trials, as a simulated skin would stream them."""

    values: list[np.ndarray]
    """Per trial (n_frames_i, N) float32 in [0, 1] (encoder output with noise)."""
    gap: list[np.ndarray]
    """Per trial (n_gap, N) untouched frames (noise only) to stream before it."""
    tail: list[np.ndarray]
    """Per trial (n_pad, N) untouched frames to stream right after it: the padded slots of its
    window (``n_pad = window.frames - (n_frames - onset)`` when positive), with the noise the model saw there."""
    rows: np.ndarray
    """(T,) int64 row of each trial in ``GestureDataset.trials``."""
    labels: np.ndarray
    """(T,) int64 gesture index into :data:`sphri.types.GESTURES`."""
    onsets: np.ndarray
    """(T,) int64 first contact frame within each trial (-1 without contact)."""
    participants: list[str]
    frame_rate_hz: float
    geometry: TaxelGeometry
    binary: bool
    """True when the encoder's output is 0/1 (streamed as BITS by default)."""

    @property
    def n_taxels(self) -> int:
        return self.geometry.n_taxels


#: Mixed into a trial's key for the frames before its contact onset, and for the untouched gap
#: streamed before it: streams only, no window holds these frames.
PRE_ONSET_KEY = 0x3C3C3C3C
GAP_KEY = 0x5A5A5A5A


def outside_keys(trial_key: int, slot: np.ndarray) -> np.ndarray:
    """Noise keys of frames outside the model's window at ``slot`` (frame - onset; negative before it).

    Slots from the window's length on carry the trial's own key (the window never reaches them);
    slots before the onset a key of their own, drawn at ``|slot|``."""
    return np.where(slot < 0, trial_key ^ PRE_ONSET_KEY, trial_key).astype(np.int64)


def encode_trials(pipeline, rows: Sequence[int] | np.ndarray, gap_s: float = 0.5) -> EncodedTrials:
    """Encode (and add the configured noise to) every frame of the trials ``rows``.

    The frames inside a trial's window are the chain's ``noise`` stage for these trials (the plan
    restricted to ``rows`` is handed to the same pipeline; noise is a pure function of (seed, trial,
    slot), so they equal the full offline run's), its padded slots streamed as the trial's tail.
    Frames outside the window are encoded by the pipeline's encoder and drawn from
    :func:`outside_keys`; ``gap_s`` seconds of untouched frames (zeros through the same noise model)
    are made for each trial, to stream before it.
    """
    from sphri.pipeline import trial_keys

    dataset = pipeline.get("data")
    contacts = pipeline.get("contact")
    plan = pipeline.get("plan")
    rows = np.asarray(rows, dtype=np.int64)
    mine = plan.kept & np.isin(np.arange(len(plan.kept)), rows)
    windows = pipeline.given({"plan": dataclasses.replace(plan, kept=mine)}).get("noise")
    window_of = {int(r): w for w, r in enumerate(windows.trial_row)}
    encoder, noise = pipeline.components["encoder"], pipeline.components["noise"]
    link, surface, layout = pipeline.link(), pipeline.get("surface"), pipeline.get("layout")
    seed = pipeline.seed
    keys = trial_keys(dataset)
    rate = float(dataset.frame_rate_hz)
    n_gap = int(round(gap_s * rate))
    length = plan.length
    n_taxels = int(windows.x.shape[2])
    values, gaps, tails, onsets = [], [], [], []
    contact_frames = np.asarray(contacts.frame)

    def drawn(index: np.ndarray, slot: np.ndarray, key: np.ndarray) -> np.ndarray:
        """Frames ``index`` (-1: untouched) encoded, then noise at ``slot`` with ``key``."""
        blank = index < 0
        v = np.zeros((len(index), n_taxels), dtype=np.float32)
        if not blank.all():
            v[~blank] = np.asarray(encoder.encode(contacts, link, surface, layout, index[~blank]).values)
        frames = SkinFrames(values=v, grid_shape=layout.grid_shape, geometry=windows.geometry)
        return np.asarray(noise.apply(frames, slot, key, seed).values, dtype=np.float32)

    for row in rows.tolist():
        t = dataset.trials.iloc[row]
        start, n = int(t["start"]), int(t["n_frames"])
        first = int(np.searchsorted(contact_frames, start))
        touched = first < contact_frames.size and contact_frames[first] < start + n
        onset = int(contact_frames[first]) - start if touched else 0
        onsets.append(onset if touched else -1)
        v = np.zeros((n, n_taxels), dtype=np.float32)
        inside = np.zeros(n, dtype=bool)
        w = window_of.get(row)
        if w is not None:  # the window's frames, as the chain made them
            slots = plan.frame_index[row]
            held = slots >= 0
            v[slots[held] - start] = windows.x[w, held]
            inside[slots[held] - start] = True
            tails.append(np.asarray(windows.x[w, ~held], dtype=np.float32))
        else:  # no window (dropped without contact): the slots a window would have padded
            pad = np.arange(n - onset, max(length, n - onset), dtype=np.int64)
            tails.append(drawn(np.full(len(pad), -1, np.int64), pad, np.full(len(pad), keys[row], np.int64)))
        out = np.flatnonzero(~inside)
        if out.size:
            slot = out - onset
            v[out] = drawn(start + out, np.abs(slot), outside_keys(int(keys[row]), slot))
        values.append(v)
        gap_slots = np.arange(n_gap, dtype=np.int64)
        gaps.append(drawn(np.full(n_gap, -1, np.int64), gap_slots, np.full(n_gap, keys[row] ^ GAP_KEY, np.int64)))
    labels = dataset.labels[rows] if len(rows) else np.zeros(0, np.int64)
    binary = all(bool(np.isin(v, (0, 1)).all()) for v in values)
    return EncodedTrials(
        values=values,
        gap=gaps,
        tail=tails,
        rows=rows,
        labels=np.asarray(labels, dtype=np.int64),
        onsets=np.asarray(onsets, dtype=np.int64),
        participants=[str(dataset.trials.iloc[int(r)]["participant"]) for r in rows],
        frame_rate_hz=rate,
        geometry=TaxelGeometry.from_layout(layout, surface),
        binary=bool(binary),
    )


def pick_rows(trials, count: int, participant: str | None, seed: int) -> np.ndarray:
    """Rows to stream: ``count`` trials (-1 = all) of ``participant`` (or of anyone), shuffled by ``seed``."""
    rows = np.arange(len(trials))
    if participant is not None:
        rows = np.flatnonzero(trials["participant"].to_numpy() == participant)
        if rows.size == 0:
            raise ConfigError(
                f"participant={participant!r} is invalid: not in the dataset "
                f"({', '.join(sorted(set(trials['participant']))[:10])} ...)"
            )
    rows = np.random.default_rng(seed).permutation(rows)
    return rows if count < 0 else rows[:count]
