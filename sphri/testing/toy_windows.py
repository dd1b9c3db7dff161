"""Synthetic gesture windows for testing and benchmarking models.

:func:`blob_windows` draws :class:`~sphri.types.WindowedFrames` directly:
elliptical contact patches moving over a cylindrical arm skin (24.1 cm long,
26 cm around, like the reference study's arm), one window per trial aligned
to contact onset, then salt-and-pepper noise. It is not a physical
simulation of hands (that is the pipeline's job); it only gives the models
realistic structure to learn: gesture-dependent patch size, duration,
repetition and motion (loosely after CoST, Jung et al. 2017), and
participant-dependent size, tempo and touch location, so that
leave-one-subject-out is harder than within-subject validation.
"""

from __future__ import annotations

import numpy as np

from sphri.types import GESTURES, TaxelGeometry, WindowedFrames

#: Arm skin size: length along the link and circumference (metres).
ARM_LENGTH_M = 0.241
ARM_CIRCUMFERENCE_M = 0.26

#: Per gesture: (touches lo, hi), touch duration (frames), gap between
#: touches (frames), patch semi-axes along/around the link (metres), motion
#: ("none", "stroke": one direction, "rub": back and forth), speed (m/frame).
_GESTURE_SPECS: dict[str, dict] = {
    "hit": dict(touches=(1, 1), dur=5, gap=0, r=(0.028, 0.028), motion="none", speed=0.0),
    "pat": dict(touches=(2, 4), dur=5, gap=6, r=(0.032, 0.032), motion="none", speed=0.0),
    "poke": dict(touches=(1, 1), dur=14, gap=0, r=(0.009, 0.009), motion="none", speed=0.0),
    "push": dict(touches=(1, 1), dur=32, gap=0, r=(0.035, 0.035), motion="none", speed=0.0),
    "rub": dict(touches=(1, 1), dur=44, gap=0, r=(0.025, 0.022), motion="rub", speed=0.007),
    "stroke": dict(touches=(1, 2), dur=22, gap=6, r=(0.022, 0.018), motion="stroke", speed=0.005),
    "tap": dict(touches=(2, 3), dur=3, gap=6, r=(0.010, 0.010), motion="none", speed=0.0),
    "grab": dict(touches=(1, 1), dur=34, gap=0, r=(0.040, 0.10), motion="none", speed=0.0),
}


def arm_geometry(res: int, layout: str = "grid", seed: int = 0) -> TaxelGeometry:
    """Taxels on the synthetic arm: ``res`` along the link, about as many per length around it.

    ``layout="grid"``: an (H, W) grid with H = res, W = round(res x 26 / 24.1)
    (res 18 -> 18 x 19), cell centres in uv. ``layout="scatter"``: the same
    number of taxels jittered off the grid, with ``grid_shape=None``.
    """
    if res < 1:
        raise ValueError(f"res={res} is invalid: must be >= 1")
    h = res
    w = max(1, int(round(res * ARM_CIRCUMFERENCE_M / ARM_LENGTH_M)))
    u = (np.arange(h) + 0.5) / h
    v = (np.arange(w) + 0.5) / w
    uu, vv = np.meshgrid(u, v, indexing="ij")
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    if layout == "scatter":
        rng = np.random.default_rng(seed)
        uv = uv + rng.uniform(-0.3, 0.3, size=uv.shape) / np.array([h, w])
        uv[:, 0] = np.clip(uv[:, 0], 0.0, 1.0)
        uv[:, 1] = np.mod(uv[:, 1], 1.0)
    elif layout != "grid":
        raise ValueError(f"layout={layout!r} is invalid: allowed values: ['grid', 'scatter']")
    radius = ARM_CIRCUMFERENCE_M / (2.0 * np.pi)
    ang = 2.0 * np.pi * uv[:, 1]
    pos = np.column_stack([radius * np.cos(ang), radius * np.sin(ang), uv[:, 0] * ARM_LENGTH_M])
    return TaxelGeometry(
        grid_shape=(h, w) if layout == "grid" else None,
        uv=uv,
        position_m=pos,
        wrap_v=True,
        metres_per_u=ARM_LENGTH_M,
        metres_per_v=ARM_CIRCUMFERENCE_M,
        area_m2=np.full(h * w, ARM_LENGTH_M * ARM_CIRCUMFERENCE_M / (h * w)),
    )


def _trial_track(spec: dict, rng: np.random.Generator, length: int, size: float, tempo: float, home: np.ndarray):
    """Per-frame patch of one trial: (L,) on, centre a/b (m), semi-axes a/b (m)."""
    on = np.zeros(length, dtype=bool)
    ca = np.zeros(length)
    cb = np.zeros(length)
    n_touch = int(rng.integers(spec["touches"][0], spec["touches"][1] + 1))
    scale = size * rng.normal(1.0, 0.12)
    ra = max(0.004, spec["r"][0] * scale)
    rb = max(0.004, spec["r"][1] * scale)
    t = 0
    for _ in range(n_touch):
        dur = max(1, int(round(spec["dur"] * tempo * rng.normal(1.0, 0.2))))
        centre = home + rng.normal(0.0, 0.015, size=2)
        lo, hi = t, min(length, t + dur)
        if lo >= length:
            break
        k = np.arange(hi - lo, dtype=np.float64)
        on[lo:hi] = True
        if spec["motion"] == "none":
            ca[lo:hi], cb[lo:hi] = centre[0], centre[1]
        else:
            ang = rng.normal(0.0, 0.35) + (np.pi / 2 if rng.random() < 0.3 else 0.0)
            direction = np.array([np.cos(ang), np.sin(ang)])
            speed = spec["speed"] / tempo * rng.normal(1.0, 0.15)
            if spec["motion"] == "stroke":
                path = (k - k.mean()) * speed
            else:  # rub: back and forth, period ~ 14 frames
                period = 14.0 * tempo * rng.normal(1.0, 0.1)
                path = np.sin(2.0 * np.pi * k / period) * speed * period / (2.0 * np.pi)
            ca[lo:hi] = centre[0] + path * direction[0]
            cb[lo:hi] = centre[1] + path * direction[1]
        t = hi + max(1, int(round(spec["gap"] * tempo * rng.normal(1.0, 0.25))))
    ra_t = np.full(length, ra)
    if spec["motion"] == "none" and spec["dur"] > 20:  # pressing in: the patch grows
        ramp = np.clip(np.arange(length) / 6.0, 0.4, 1.0)
        ra_t = ra * ramp
    return on, ca, cb, ra_t, np.full(length, rb) * (ra_t / ra)


def blob_windows(
    participants: int = 6,
    repetitions: int = 5,
    res: int = 18,
    length: int = 50,
    noise_p: float = 0.02,
    layout: str = "grid",
    seed: int = 0,
) -> WindowedFrames:
    """Windows of ``participants`` x 8 gestures x ``repetitions`` synthetic trials.

    x is (n, length, N) float32 binary; a taxel reads 1 when the patch overlaps
    its cell (half a pitch around its centre; at res 1 any contact); then each
    reading flips with probability ``noise_p``. Trials are ordered by
    participant, repetition, gesture. Deterministic in ``seed``.
    """
    if participants < 1 or repetitions < 1 or length < 1:
        raise ValueError(f"participants={participants}, repetitions={repetitions}, length={length}: all must be >= 1")
    if not 0.0 <= noise_p <= 1.0:
        raise ValueError(f"noise_p={noise_p} is invalid: must be in [0, 1]")
    geom = arm_geometry(res, layout, seed)
    rng = np.random.default_rng(seed)
    n = participants * repetitions * len(GESTURES)
    on = np.zeros((n, length), dtype=bool)
    ca, cb, ra, rb = (np.zeros((n, length)) for _ in range(4))
    y = np.zeros(n, dtype=np.int64)
    groups = np.empty(n, dtype=object)
    i = 0
    for p in range(participants):
        size = rng.uniform(0.8, 1.25)
        tempo = rng.uniform(0.75, 1.3)
        home = np.array([rng.uniform(0.3, 0.7) * ARM_LENGTH_M, rng.uniform(0.0, ARM_CIRCUMFERENCE_M)])
        for _ in range(repetitions):
            for g, name in enumerate(GESTURES):
                on[i], ca[i], cb[i], ra[i], rb[i] = _trial_track(_GESTURE_SPECS[name], rng, length, size, tempo, home)
                y[i] = g
                groups[i] = f"participant_{p + 1:02d}"
                i += 1
    ca = np.clip(ca, 0.0, ARM_LENGTH_M)
    if geom.uv is None:
        raise AssertionError("arm_geometry gave a layout without uv")  # it always sets uv
    a_t = geom.uv[:, 0] * ARM_LENGTH_M
    b_t = geom.uv[:, 1] * ARM_CIRCUMFERENCE_M
    if geom.grid_shape is not None:
        half_a = 0.5 * ARM_LENGTH_M / geom.grid_shape[0]
        half_b = 0.5 * ARM_CIRCUMFERENCE_M / geom.grid_shape[1]
    else:
        half_a = 0.5 * ARM_LENGTH_M / res
        half_b = 0.5 * ARM_LENGTH_M / res
    n_tax = a_t.shape[0]
    x = np.empty((n, length, n_tax), dtype=np.float32)
    step = max(1, (1 << 22) // (length * n_tax))
    for s in range(0, n, step):
        sl = slice(s, s + step)
        da = np.maximum(np.abs(a_t - ca[sl, :, None]) - half_a, 0.0)
        db = np.abs(
            np.mod(b_t - cb[sl, :, None] + 0.5 * ARM_CIRCUMFERENCE_M, ARM_CIRCUMFERENCE_M) - 0.5 * ARM_CIRCUMFERENCE_M
        )
        db = np.maximum(db - half_b, 0.0)
        inside = (da / ra[sl, :, None]) ** 2 + (db / rb[sl, :, None]) ** 2 <= 1.0
        x[sl] = inside & on[sl, :, None]
    if noise_p > 0:
        flip = rng.random(x.shape, dtype=np.float32) < noise_p
        x[flip] = 1.0 - x[flip]
    return WindowedFrames(
        x=x,
        y=y,
        groups=groups.astype(str),
        geometry=geom,
        trial_row=np.arange(n, dtype=np.int64),
        n_dropped=0,
    )


def grid_geometry(h: int, w: int, pitch_m: float = 0.01, wrap: bool = False, grid: bool = True) -> TaxelGeometry:
    """An h x w grid of square cells of ``pitch_m`` on a chart (planar positions)."""
    u = (np.arange(h) + 0.5) / h
    v = (np.arange(w) + 0.5) / w
    uu, vv = np.meshgrid(u, v, indexing="ij")
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    pos = np.column_stack([uv[:, 0] * h * pitch_m, uv[:, 1] * w * pitch_m, np.zeros(h * w)])
    return TaxelGeometry(
        grid_shape=(h, w) if grid else None,
        uv=uv,
        position_m=pos,
        wrap_v=wrap,
        metres_per_u=h * pitch_m,
        metres_per_v=w * pitch_m,
        area_m2=np.full(h * w, pitch_m * pitch_m),
    )
