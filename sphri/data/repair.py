"""Vectorized repairs of tracked poses: hold the last valid pose within a trial."""

from __future__ import annotations

import numpy as np


def segment_bounds(starts: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-row (segment start, segment end) for ``n`` rows cut at sorted ``starts``."""
    st = np.union1d(np.asarray(starts, dtype=np.int64), [0])
    owner = np.searchsorted(st, np.arange(n), side="right") - 1
    ends = np.append(st[1:] - 1, n - 1)
    return st[owner], ends[owner]


def hold_last_valid(values: np.ndarray, bad: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Replace invalid entries by the last valid one of the same series and segment.

    ``values`` (R, C, K): R rows (frames), C series (capsules), K values each.
    ``bad`` (R, C) marks invalid entries. ``starts`` (sorted row indices, e.g.
    trial starts) cut the rows into independent segments: a value never
    crosses a segment boundary. Leading invalid entries take the first valid
    one after them. Returns ``(repaired copy, orphan)`` where ``orphan`` (R, C)
    marks entries whose segment has no valid value for that series at all
    (left unchanged).
    """
    values = np.asarray(values)
    bad = np.asarray(bad, dtype=bool)
    n = values.shape[0]
    out = values.copy()
    if n == 0 or not bad.any():
        return out, np.zeros_like(bad)
    ss, se = segment_bounds(starts, n)
    t = np.arange(n, dtype=np.int64)[:, None]
    ss = ss[:, None]
    se = se[:, None]
    valid = ~bad
    # last valid row at or before t; values below the segment start mean none
    prev = np.maximum.accumulate(np.where(valid, t, ss - 1), axis=0)
    # first valid row at or after t; values above the segment end mean none
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(valid, t, se + 1), axis=0), axis=0), axis=0)
    src = np.where(prev >= ss, prev, np.where(nxt <= se, nxt, -1))
    rows, cols = np.nonzero(bad)
    s = src[rows, cols]
    ok = s >= 0
    out[rows[ok], cols[ok]] = values[s[ok], cols[ok]]
    orphan = np.zeros_like(bad)
    orphan[rows[~ok], cols[~ok]] = True
    return out, orphan
