"""The pipeline's data for the hardware commands: trials, contacts, encoded frames.

The hardware commands take the same overrides as ``python -m sphri`` and
read the cached stages through :func:`sphri.pipeline.make_pipeline`, so a
replayed trial or a simulated skin stream is exactly what the classifier
sees in simulation (same encoder, layout and noise).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sphri.types import GESTURES, TaxelGeometry


def open_pipeline(overrides: Sequence[str]):
    """Compose the config from ``overrides`` and wire the (lazy, cached) pipeline."""
    from sphri.config import compose
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


def encode_trials(pipeline, rows: Sequence[int], gap_s: float = 0.5) -> EncodedTrials:
    """Encode (and add the configured noise to) every frame of the trials ``rows``.

    ``gap_s`` seconds of untouched frames (zeros through the same noise
    model) are made for each trial, to stream before it. Noise is a pure
    function of (seed, trial, slot): frames from the trial's onset on get
    the slot they have in the model's window, so a stream carries exactly
    the noisy frames the offline model saw (padded slots streamed as the
    trial's tail); frames before the onset get their own draws.
    """
    from sphri.pipeline import build, chain_region, trial_keys

    cfg = pipeline.cfg
    dataset = pipeline.get("data")
    contacts = pipeline.get("contact")
    surface = pipeline.get("surface")
    layout = pipeline.get("layout")
    link = pipeline.get("robot").link_for(chain_region(cfg))
    encoder = build(cfg.encoder)
    noise = build(cfg.noise)
    seed = int(cfg.seed)
    keys = trial_keys(dataset)
    rate = float(dataset.frame_rate_hz)
    n_gap = int(round(gap_s * rate))
    length = int(cfg.window.frames)
    values, gaps, tails, onsets, binary = [], [], [], [], True
    contact_frames = np.asarray(contacts.frame)
    for row in rows:
        t = dataset.trials.iloc[int(row)]
        start, n = int(t["start"]), int(t["n_frames"])
        first = int(np.searchsorted(contact_frames, start))
        touched = first < contact_frames.size and contact_frames[first] < start + n
        onset = int(contact_frames[first]) - start if touched else 0
        onsets.append(onset if touched else -1)
        index = np.arange(start, start + n, dtype=np.int64)
        frames = encoder.encode(contacts, link, surface, layout, index)
        slot = np.arange(n, dtype=np.int64) - onset  # the frame's slot in the model's window
        key = np.where(slot < 0, keys[row] ^ 0x3C3C3C3C, keys[row]).astype(np.int64)
        frames = noise.apply(frames, np.abs(slot), key, seed)
        v = np.asarray(frames.values)
        binary &= v.dtype == np.uint8 or bool(np.isin(v, (0, 1)).all())
        values.append(v.astype(np.float32))

        def untouched(slots: np.ndarray, trial_key: int) -> np.ndarray:
            # called at once, in this iteration: the loop's frames and v are the ones meant
            blank = dataclasses.replace(frames, values=np.zeros((len(slots), v.shape[1]), dtype=v.dtype))  # noqa: B023
            out = noise.apply(blank, slots, np.full(len(slots), trial_key, dtype=np.int64), seed)
            return np.asarray(out.values).astype(np.float32)

        gaps.append(untouched(np.arange(n_gap, dtype=np.int64), keys[row] ^ 0x5A5A5A5A))
        tails.append(untouched(np.arange(n - onset, max(length, n - onset), dtype=np.int64), keys[row]))
    labels = dataset.labels[np.asarray(rows, dtype=np.int64)] if len(rows) else np.zeros(0, np.int64)
    return EncodedTrials(
        values=values,
        gap=gaps,
        tail=tails,
        rows=np.asarray(rows, dtype=np.int64),
        labels=np.asarray(labels, dtype=np.int64),
        onsets=np.asarray(onsets, dtype=np.int64),
        participants=[str(dataset.trials.iloc[int(r)]["participant"]) for r in rows],
        frame_rate_hz=rate,
        geometry=TaxelGeometry.from_layout(layout, surface),
        binary=bool(binary),
    )


def pick_rows(trials, count: int, participant: str | None, seed: int) -> np.ndarray:
    """Rows to stream: ``count`` trials (-1 = all) of ``participant`` (or of anyone), shuffled by ``seed``."""
    from sphri.config import ConfigError

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


def gesture_name(label: int) -> str:
    return GESTURES[int(label)] if 0 <= int(label) < len(GESTURES) else f"class {int(label)}"
