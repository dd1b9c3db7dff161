"""The eight synthetic gestures: how the hand is shaped and how it touches.

A gesture's contact phase is a :class:`ContactPlan` in the local frame of the
touch point (outward normal ``n``, ``t1`` along the link, ``t2 = n x t1``):
which part of the hand touches (an effector of :mod:`sphri.data.handfk`),
the finger angles, the touches (intervals in seconds during which the
effector is below the surface, and how deep, metres), and tangential slides
(metres along a direction in the tangent plane). Times are relative to the
first contact. :mod:`sphri.data.synthetic` places the plan on the link and
adds the approach from rest and the retreat.

Contact durations (first to last contact, repetitions included) are drawn
around CoST's mean for the gesture (:mod:`sphri.data.reference_stats`)
times :data:`DURATION_CALIBRATION`, which absorbs what the contact stage
adds (other capsules touching before and after the effector).

| gesture | effector | touches | motion |
| --- | --- | --- | --- |
| poke | index fingertip (fist, index out) | 1 | press along the normal |
| tap | index (and middle) fingertip, fingers bent | 1-3 brief | lifts 1.5-2.5 cm between |
| pat | flat palm | 2-4 brief | lifts 3-5 cm between |
| hit | palm or fist knuckles | 1 fast, deep | strikes from 8-12 cm |
| push | flat palm | 1 held | slow press, deep |
| rub | palm or finger pads | 1 held | back and forth, 1.5-3 Hz |
| stroke | palm or finger pads | 1-3 | one way along the link, lift and return |
| grab | palm, fingers wrap, thumb opposes | 1 held | fingers close around the link |
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sphri.data.reference_stats import COST_DURATION_MS

#: Multiplier on CoST's mean duration per gesture (calibrated with ``python -m sphri.data.stats``).
DURATION_CALIBRATION: dict[str, float] = {
    "grab": 1.0,
    "hit": 1.0,
    "pat": 1.0,
    "poke": 1.0,
    "push": 1.0,
    "rub": 1.0,
    "stroke": 1.0,
    "tap": 1.0,
}

#: Typical effector depth below the surface per gesture (metres), before per-participant and per-trial factors.
DEPTH_M: dict[str, float] = {
    "poke": 0.008, "tap": 0.006, "pat": 0.008, "hit": 0.013,
    "push": 0.016, "rub": 0.008, "stroke": 0.006, "grab": 0.017,
}

#: Number of touches: (choices, expected count over participants).
TOUCH_COUNTS: dict[str, tuple[tuple[int, ...], float]] = {
    "tap": ((1, 2, 3), 2.0),
    "pat": ((2, 3, 4), 3.0),
    "stroke": ((1, 2, 3), 2.0),
}

#: Fraction of each touch cycle spent in contact for multi-touch gestures.
CONTACT_FRACTION = {"tap": 0.35, "pat": 0.4, "stroke": 0.65}

# Finger shapes: rows thumb, index, middle, ring, pinky; columns abduction, 3 flexions (radians).
RELAXED = np.array([[0.0, 0.20, 0.20, 0.15], [0.0, 0.30, 0.35, 0.20], [0.0, 0.30, 0.35, 0.20],
                    [0.0, 0.32, 0.38, 0.22], [0.0, 0.35, 0.40, 0.25]])
FLAT = np.array([[-0.15, 0.05, 0.05, 0.05], [0.0, 0.05, 0.05, 0.03], [0.0, 0.05, 0.05, 0.03],
                 [0.0, 0.05, 0.05, 0.03], [0.0, 0.05, 0.05, 0.03]])
POINT = np.array([[0.0, 0.60, 0.50, 0.35], [0.0, 0.05, 0.08, 0.05], [0.0, 1.50, 1.60, 1.00],
                  [0.0, 1.50, 1.60, 1.00], [0.0, 1.50, 1.60, 1.00]])
TAP = np.array([[0.0, 0.30, 0.50, 0.40], [0.0, 0.45, 0.55, 0.30], [0.0, 0.70, 1.40, 0.90],
                [0.0, 0.70, 1.40, 0.90], [0.0, 0.70, 1.40, 0.90]])
TAP2 = TAP.copy()
TAP2[2] = [0.0, 0.45, 0.55, 0.30]
FIST = np.array([[0.0, 0.70, 0.60, 0.50], [0.0, 1.50, 1.70, 1.10], [0.0, 1.50, 1.70, 1.10],
                 [0.0, 1.50, 1.70, 1.10], [0.0, 1.50, 1.70, 1.10]])
SLIDE_FINGERS = np.array([[0.0, 0.30, 0.30, 0.20], [0.0, 0.30, 0.15, 0.10], [0.0, 0.30, 0.15, 0.10],
                    [0.0, 0.30, 0.15, 0.10], [0.0, 0.60, 0.60, 0.40]])
GRAB_OPEN = np.array([[0.0, 0.00, 0.10, 0.10], [0.0, 0.15, 0.20, 0.10], [0.0, 0.15, 0.20, 0.10],
                      [0.0, 0.15, 0.20, 0.10], [0.0, 0.15, 0.20, 0.10]])


@dataclass
class Style:
    """How one participant touches (drawn once per participant, shared by all regions)."""

    scale: float
    """Hand size factor (bone lengths), about 1 +/- 10 %."""
    speed: float
    """Approach/retreat speed factor (> 1: faster)."""
    pause: float
    """Factor on the rest phases before and after the touch."""
    duration: float
    """Factor on contact durations."""
    depth: float
    """Factor on contact depths."""
    tilt: float
    """Approach tilt from the surface normal (radians)."""
    tilt_azimuth: float
    """Direction of that tilt around the normal, from t1 (radians)."""
    yaw: float
    """Preferred hand yaw around the normal, from t1 (radians)."""
    grab_side: float
    """+1 or -1: which way the fingers wrap in a grab."""
    spread: float
    """Extra finger abduction (radians)."""
    rest_m: float
    """Distance of the rest pose from the touch point (metres)."""
    hit_fist: float
    """Probability that a hit uses the fist."""
    slide_fingers: float
    """Probability that a rub or stroke uses the finger pads."""
    tap_two: float
    """Probability that a tap uses two fingers."""
    rub_across: float
    """Probability that a rub goes around the link rather than along it."""
    stroke_sign: float
    """+1 or -1: preferred stroke direction along the link."""
    counts: dict[str, np.ndarray] = field(default_factory=dict)
    """Per multi-touch gesture, probabilities of its touch counts."""

    @classmethod
    def draw(cls, rng: np.random.Generator, scale_sd: float) -> "Style":
        def logn(sd: float) -> float:
            return float(np.exp(rng.normal(0.0, sd) - 0.5 * sd * sd))

        return cls(
            scale=float(np.clip(1.0 + rng.normal(0.0, scale_sd), 0.9, 1.1)),
            speed=logn(0.15),
            pause=logn(0.25),
            duration=logn(0.2),
            depth=logn(0.25),
            tilt=float(rng.uniform(0.0, np.radians(30.0))),
            tilt_azimuth=float(rng.uniform(0.0, 2 * np.pi)),
            yaw=float(rng.uniform(0.0, 2 * np.pi)),
            grab_side=float(rng.choice([-1.0, 1.0])),
            spread=float(rng.uniform(0.0, 0.12)),
            rest_m=float(rng.uniform(0.22, 0.35)),
            hit_fist=float(rng.uniform(0.0, 0.6)),
            slide_fingers=float(rng.uniform(0.0, 0.6)),
            tap_two=float(rng.uniform(0.3, 0.9)),
            rub_across=float(rng.uniform(0.0, 0.5)),
            stroke_sign=float(rng.choice([-1.0, 1.0])),
            counts={g: rng.dirichlet(np.full(len(TOUCH_COUNTS[g][0]), 2.0)) for g in sorted(TOUCH_COUNTS)},
        )


@dataclass
class ContactPlan:
    """The contact phase of one trial, in the touch point's local frame (see the module docstring)."""

    gesture: str
    effector: str
    fingers: np.ndarray
    """(5, 4) finger angles while touching (radians)."""
    touches: list[tuple[float, float, float]]
    """(start s, end s, depth m) of each contact interval, start of the first = 0."""
    hover_m: float
    """Height of the effector above the surface before, between and after touches (metres)."""
    ramp_s: float
    """Nominal time to go from hover to full depth (seconds)."""
    yaw: float
    """Hand yaw around the normal, from t1 (radians)."""
    tilt: float
    """Tilt of the pressing direction away from -n (radians)."""
    tilt_azimuth: float
    slide_angle: float = 0.0
    """Slide direction in the tangent plane, from t1 (radians)."""
    slide: list[tuple[float, float]] = field(default_factory=list)
    """(time s, offset m) knots of the tangential slide."""
    finger_knots: list[tuple[float, np.ndarray]] = field(default_factory=list)
    """Extra (time s, (5, 4) angles) knots during contact (the grab's closing fingers)."""
    grab: bool = False

    @property
    def slide_extent_m(self) -> float:
        return max((abs(s) for _, s in self.slide), default=0.0)


def _lognormal(rng: np.random.Generator, mean: float, sd: float) -> float:
    return float(mean * np.exp(rng.normal(0.0, sd) - 0.5 * sd * sd))


def contact_duration(rng: np.random.Generator, gesture: str, style: Style, sd: float = 0.4) -> float:
    """A trial's contact duration (s): CoST's mean x calibration x participant x trial factors (mean-preserving)."""
    mean = COST_DURATION_MS[gesture][0] / 1000.0 * DURATION_CALIBRATION[gesture] * style.duration
    return _lognormal(rng, mean, sd)


def _touch_train(total: float, n: int, kappa: float, depth: float, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    c = total / (n + (n - 1) * (1.0 - kappa) / kappa)
    g = c * (1.0 - kappa) / kappa
    out, t = [], 0.0
    for i in range(n):
        ci = c * float(rng.uniform(0.85, 1.15))
        out.append((t, t + ci, depth * float(rng.uniform(0.8, 1.2))))
        t += ci + g * float(rng.uniform(0.8, 1.2))
    return out


def plan_contact(gesture: str, rng: np.random.Generator, style: Style, wrap_radius_m: float, finger_radius_m: float) -> ContactPlan:
    """Draw the contact phase of one ``gesture`` trial for a participant's ``style``.

    ``wrap_radius_m``: radius of the link's cross-section at the touch point
    (how far the grab's fingers must curl); ``finger_radius_m``: the fingers'
    capsule radius.
    """
    depth = _lognormal(rng, DEPTH_M[gesture] * style.depth, 0.3)
    yaw = style.yaw + rng.normal(0.0, np.radians(20.0))
    tilt = float(rng.uniform(0.0, np.radians(10.0)))
    az = float(rng.uniform(0.0, 2 * np.pi))
    spread = np.zeros((5, 4))
    spread[1:, 0] = np.array([1.0, 0.0, -1.0, -2.0]) * (style.spread + rng.normal(0.0, 0.02)) * 0.5
    dur = contact_duration(rng, gesture, style)

    def multi(g: str) -> list[tuple[float, float, float]]:
        choices, expected = TOUCH_COUNTS[g]
        n = int(rng.choice(choices, p=style.counts[g]))
        return _touch_train(dur * n / expected, n, CONTACT_FRACTION[g], depth, rng)

    if gesture == "poke":
        return ContactPlan(gesture, "index_tip", POINT + 0.5 * spread, [(0.0, dur, depth)], hover_m=float(rng.uniform(0.03, 0.05)),
                           ramp_s=0.15, yaw=yaw, tilt=float(rng.uniform(0.0, np.radians(25.0))), tilt_azimuth=az)
    if gesture == "tap":
        shape = TAP2 if rng.random() < style.tap_two else TAP
        touches = multi("tap")
        plan = ContactPlan(gesture, "index_tip", shape + 0.5 * spread, touches, hover_m=float(rng.uniform(0.015, 0.025)),
                           ramp_s=0.08, yaw=yaw, tilt=tilt, tilt_azimuth=az, slide_angle=float(rng.uniform(0, 2 * np.pi)))
        plan.slide = [(a, float(rng.normal(0.0, 0.004))) for a, _, _ in touches]
        return plan
    if gesture == "pat":
        touches = multi("pat")
        plan = ContactPlan(gesture, "palm", FLAT + spread, touches, hover_m=float(rng.uniform(0.03, 0.05)),
                           ramp_s=0.10, yaw=yaw, tilt=tilt, tilt_azimuth=az, slide_angle=float(rng.uniform(0, 2 * np.pi)))
        plan.slide = [(a, float(rng.normal(0.0, 0.006))) for a, _, _ in touches]
        return plan
    if gesture == "hit":
        fist = rng.random() < style.hit_fist
        return ContactPlan(gesture, "fist" if fist else "palm", FIST if fist else FLAT + spread, [(0.0, dur, depth)],
                           hover_m=float(rng.uniform(0.08, 0.12)), ramp_s=0.05, yaw=yaw, tilt=tilt, tilt_azimuth=az)
    if gesture == "push":
        return ContactPlan(gesture, "palm", FLAT + spread, [(0.0, dur, depth)], hover_m=float(rng.uniform(0.03, 0.05)),
                           ramp_s=0.25, yaw=yaw, tilt=tilt, tilt_azimuth=az)
    if gesture == "rub":
        fingers = rng.random() < style.slide_fingers
        across = rng.random() < style.rub_across
        angle = (np.pi / 2 if across else 0.0) + rng.normal(0.0, np.radians(20.0))
        amp = float(rng.uniform(0.015, 0.03))
        freq = float(rng.uniform(1.5, 3.0))
        plan = ContactPlan(gesture, "fingers" if fingers else "palm", SLIDE_FINGERS if fingers else FLAT + spread,
                           [(0.0, dur, depth)], hover_m=float(rng.uniform(0.02, 0.04)), ramp_s=0.15, yaw=yaw,
                           tilt=tilt, tilt_azimuth=az, slide_angle=float(angle))
        half = 0.5 / freq
        k = np.arange(1, max(int(dur / half), 1) + 1)
        plan.slide = [(0.0, 0.0)] + [(float(t), float(amp * (1 if i % 2 else -1))) for i, t in zip(k, k * half) if t < dur]
        return plan
    if gesture == "stroke":
        fingers = rng.random() < style.slide_fingers
        touches = multi("stroke")
        length = float(rng.uniform(0.06, 0.12)) * style.scale
        angle = (0.0 if style.stroke_sign > 0 else np.pi) + rng.normal(0.0, np.radians(10.0))
        plan = ContactPlan(gesture, "fingers" if fingers else "palm", SLIDE_FINGERS if fingers else FLAT + spread, touches,
                           hover_m=float(rng.uniform(0.02, 0.04)), ramp_s=0.12, yaw=yaw, tilt=tilt, tilt_azimuth=az,
                           slide_angle=float(angle))
        for a, b, _ in touches:
            plan.slide += [(a, -0.5 * length), (b, 0.5 * length)]
        return plan
    if gesture == "grab":
        closed = _grab_fingers(wrap_radius_m + finger_radius_m, style.scale) * float(rng.uniform(1.2, 1.4))
        plan = ContactPlan(gesture, "palm", GRAB_OPEN, [(0.0, dur, depth)], hover_m=float(rng.uniform(0.03, 0.05)),
                           ramp_s=0.2, yaw=np.pi / 2 * style.grab_side + rng.normal(0.0, np.radians(10.0)), tilt=tilt,
                           tilt_azimuth=az, grab=True)
        close = min(0.25, 0.3 * dur)
        plan.finger_knots = [(0.0, GRAB_OPEN), (close, closed), (max(dur - close, close), closed), (dur + 0.1, GRAB_OPEN)]
        return plan
    raise ValueError(f"unknown gesture {gesture!r}")


def _grab_fingers(rho: float, scale: float) -> np.ndarray:
    """(5, 4) finger angles that wrap the fingers around a cylinder of radius ``rho`` (metres).

    Each phalanx becomes a chord of the circle: flexion at a joint is the
    mean of the angles its two bones subtend; the knuckles sit about 3.5 cm
    beyond the palm's touch point. Flexions never fall below (0.45, 0.5, 0.3)
    radians, so the fingers close on flat links too.
    """
    bones = np.array([0.038, 0.024, 0.015]) * scale
    beta = 2.0 * np.arcsin(np.clip(bones / (2.0 * rho), 0.0, 0.99))
    knuckle = 0.8 * 0.035 * scale / rho
    flex = np.array([knuckle + beta[0] / 2, (beta[0] + beta[1]) / 2, (beta[1] + beta[2]) / 2])
    # on flat links (the torso) the fingers still close: fingertips press into the surface
    flex = np.maximum(flex, [0.45, 0.5, 0.3])
    out = np.zeros((5, 4))
    out[1:, 1:] = np.minimum(flex, 1.5)
    out[0] = [0.2, 0.6, 0.5, 0.4]
    return out
