"""Contacts -> glove actuator commands (pure, vectorized over frames).

Each hand capsule belongs to a hand part (``HandModel.fingers``: thumb,
index, middle, ring, pinky or palm); the glove has one vibration actuator
per part (:data:`~sphri.hardware.glove_protocol.ACTUATORS`). A part is in
contact in a frame when any of its capsules has a contact row; its depth is
the largest penetration depth among them.
"""

from __future__ import annotations

import numpy as np

from sphri.config import require, require_choice, require_range
from sphri.hardware.glove_protocol import ACTUATORS, N_ACTUATORS
from sphri.types import Contacts, HandModel


def capsule_actuator(hand: HandModel) -> np.ndarray:
    """(C,) int64 actuator index (into ``ACTUATORS``) of each capsule of ``hand``."""
    lookup = {name: i for i, name in enumerate(ACTUATORS)}
    bad = sorted({f for f in hand.fingers if f not in lookup})
    if bad:
        raise ValueError(f"hand model has capsules on parts {bad}; the glove has actuators for {list(ACTUATORS)}")
    return np.array([lookup[f] for f in hand.fingers], dtype=np.int64)


def part_depths(contacts: Contacts, hand: HandModel, start: int, n_frames: int) -> np.ndarray:
    """(n_frames, 6) float64 max penetration depth (metres) per actuator; 0 = no contact.

    Covers global frames ``start .. start + n_frames - 1`` (one trial).
    """
    if start < 0 or n_frames < 0 or start + n_frames > contacts.n_frames:
        raise ValueError(f"frames {start}..{start + n_frames} outside the contacts' 0..{contacts.n_frames}")
    fr = np.asarray(contacts.frame)
    lo, hi = np.searchsorted(fr, [start, start + n_frames], side="left")
    cap = np.asarray(contacts.capsule[lo:hi], dtype=np.int64)
    act = capsule_actuator(hand)
    if cap.size and (cap.min() < 0 or cap.max() >= act.size):
        raise ValueError(f"contact capsule indices {cap.min()}..{cap.max()} outside the hand's {act.size} capsules")
    depth = np.asarray(contacts.depth_m[lo:hi], dtype=np.float64)
    out = np.zeros((n_frames, N_ACTUATORS), dtype=np.float64)
    # a contact row has depth > 0; the tiny floor keeps "in contact" even for depth == 0 rows
    np.maximum.at(out, (fr[lo:hi] - start, act[cap]), np.maximum(depth, 1e-12))
    return out


class ActuatorMap:
    """How contact becomes vibration.

    ``intensity``: ``depth`` scales linearly from ``intensity_min`` (just
    touching) to ``intensity_max`` at ``depth_full_m`` metres of penetration
    and beyond; ``constant`` always uses ``intensity_max``.
    ``trigger``: ``contact`` keeps an actuator pulsing (``pulse_ms`` ms,
    refreshed every frame) while its part is in contact; ``onset`` pulses
    once when the part's contact begins.
    """

    def __init__(
        self,
        pulse_ms: int = 60,
        intensity: str = "depth",
        intensity_min: int = 80,
        intensity_max: int = 255,
        depth_full_m: float = 0.01,
        trigger: str = "contact",
    ) -> None:
        require_range("pulse_ms", pulse_ms, lo=1, hi=65535)
        require_choice("intensity", intensity, ("depth", "constant"))
        require_range("intensity_min", intensity_min, lo=1, hi=255)
        require_range("intensity_max", intensity_max, lo=1, hi=255)
        require(
            intensity_min <= intensity_max, "intensity_min", intensity_min, f"must be <= intensity_max={intensity_max}"
        )
        require_range("depth_full_m", depth_full_m, lo=0.0, hi=0.5, lo_open=True)
        require_choice("trigger", trigger, ("contact", "onset"))
        self.pulse_ms = int(pulse_ms)
        self.intensity = intensity
        self.intensity_min = int(intensity_min)
        self.intensity_max = int(intensity_max)
        self.depth_full_m = float(depth_full_m)
        self.trigger = trigger

    def level(self, depth: np.ndarray) -> np.ndarray:
        """(F, 6) float64 intensity in [intensity_min, intensity_max] for depths (F, 6) metres (0 where depth is 0)."""
        depth = np.asarray(depth, dtype=np.float64)
        if self.intensity == "constant":
            level = np.full(depth.shape, float(self.intensity_max))
        else:
            s = np.clip(depth / self.depth_full_m, 0.0, 1.0)
            level = self.intensity_min + s * (self.intensity_max - self.intensity_min)
        return np.where(depth > 0, level, 0.0)

    def desired(self, depth: np.ndarray, frame_rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """What each actuator should be doing at each frame.

        ``depth`` (F, 6) metres per actuator (:func:`part_depths`), frames at
        ``frame_rate_hz``. Returns ``(intensity (F, 6) uint8, remaining_ms
        (F, 6) float64)``: the level and how much longer the pulse runs from
        that frame (0 = off). ``contact``: on with ``pulse_ms`` ahead while
        touching, off at release. ``onset``: a pulse of ``pulse_ms`` starts
        at each contact onset and runs out by itself.
        """
        depth = np.asarray(depth, dtype=np.float64)
        if depth.ndim != 2 or depth.shape[1] != N_ACTUATORS:
            raise ValueError(f"depth must be (F, {N_ACTUATORS}), got {depth.shape}")
        if not frame_rate_hz > 0:
            raise ValueError(f"frame_rate_hz={frame_rate_hz} must be > 0")
        level = np.rint(self.level(depth)).astype(np.uint8)
        touching = depth > 0
        if self.trigger == "contact":
            return level, np.where(touching, float(self.pulse_ms), 0.0)
        n = depth.shape[0]
        t_ms = np.arange(n, dtype=np.float64) * (1000.0 / frame_rate_hz)
        prev = np.vstack([np.zeros((1, N_ACTUATORS), dtype=bool), touching[:-1]])
        onset = touching & ~prev
        out_level = np.zeros_like(level)
        remaining = np.zeros(depth.shape, dtype=np.float64)
        for a in range(N_ACTUATORS):
            starts = np.flatnonzero(onset[:, a])
            if starts.size == 0:
                continue
            # index of the latest onset at or before each frame
            last = np.searchsorted(starts, np.arange(n), side="right") - 1
            has = last >= 0
            k = starts[np.maximum(last, 0)]
            rem = np.where(has, self.pulse_ms - (t_ms - t_ms[k]), 0.0)
            on = has & (rem > 0)
            remaining[:, a] = np.where(on, rem, 0.0)
            out_level[:, a] = np.where(on, level[k, a], 0)
        return out_level, remaining
