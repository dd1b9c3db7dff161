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
times :data:`DURATION_CALIBRATION`, with participant, participant x gesture
and trial factors whose total spread is CoST's SD
(:meth:`sphri.data.people.Spread.duration_trial_sd`). Penetration depth
(nothing stops a virtual hand) has the same three levels and a deep tail
(:func:`penetration_depth`). Which variant a participant uses (palm or fist,
palm or finger pads, ...) follows personal habits (:data:`HABITS`), and
:func:`add_brush_and_retouch` adds accidental contacts around the gesture.

| gesture | effector | touches | motion |
| --- | --- | --- | --- |
| poke | index fingertip (fist, index out) | 1 | press along the normal |
| tap | index (and middle) fingertip, fingers bent | 1-3 brief | lifts 1.5-2.5 cm between |
| pat | flat palm or finger pads | 2-4 brief | lifts 3-5 cm between |
| hit | palm or fist knuckles | 1 fast | strikes from 8-12 cm |
| push | flat palm or index fingertip | 1 held | slow press, deep |
| rub | palm or finger pads | 1 held | back and forth, 1.5-3 Hz |
| stroke | palm or finger pads | 1-3 | one way along the link, lift and return |
| grab | palm, fingers wrap, thumb opposes | 1 held | fingers close around the link |
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sphri.data.people import Spread
from sphri.data.reference_stats import COST_DURATION_MS

#: Multiplier on CoST's mean duration per gesture. The draws are mean-preserving, so 1.0 keeps CoST's mean in
#: expectation; one study of 18 participants lands within about +/-25 % of it (participant x gesture effects).
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

#: Median penetration of the effector below the surface per gesture (metres), before the participant,
#: participant x gesture and trial factors and the deep tail (:func:`penetration_depth`). Nothing stops a
#: virtual hand, so the depth sets the touch footprint. Calibrated (data version 3) so the simulated CoST
#: sensor (:mod:`sphri.data.cost_sensor`, ``sphri stats``) reads each gesture's contact-area
#: fraction within its band of CoST's Table 4 row (Jung et al. 2017; fraction of the 8 x 8 sensor). Numbers:
#: the full default study (18 participants, arm, seed 0), before and after:
#:
#: - hit 0.0035 (was 0.013; row hit .15): at 0.013 the sensor read 0.241, 1.61x CoST; now 0.148, 0.99x
#:   (data seeds 1 and 2: 1.23x, 1.00x; at 0.005 seed 1 read 1.42x, outside);
#: - pat 0.004 (was 0.008; row pat .15): 0.204, 1.36x; now 0.166, 1.10x;
#: - tap 0.026 (was 0.006; row tap .12): 0.061, 0.51x; now 0.100, 0.83x (seeds 1, 2: 0.86x, 0.73x);
#: - rub 0.006 (was 0.008; row rub .21): 0.265, 1.26x (the band's edge); now 0.246, 1.17x (seeds 1, 2: 1.22x, 1.02x);
#: - push 0.016 (row press .23), stroke 0.006 (row stroke .20): inside their bands as they were;
#: - grab 0.017 (row grab .59): reads 0.38 (0.64x, just outside) and at most 0.40 with any depth
#:   (0.017-0.03 m), finger closure (1.2-1.8x) or tighter wrap tried: the hand spans about 5 of the
#:   sensor's 8 rows along the arm (23-33 of 64 cells once closed). Left outside;
#: - poke 0.008 (row poke .08): reads about 0.04 at any depth or tilt tried (0.008-0.018 m, 0-50 degrees):
#:   the index fingertip (capsule radius 7.6 mm) covers at most 2 x 2 cells of 20 mm; CoST's 5 cells may
#:   come from pressure spreading in its textile sensor (not measured here), which the generator does not
#:   fake. Left outside.
DEPTH_M: dict[str, float] = {
    "poke": 0.008,
    "tap": 0.026,
    "pat": 0.004,
    "hit": 0.0035,
    "push": 0.016,
    "rub": 0.006,
    "stroke": 0.006,
    "grab": 0.017,
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


def _hand(thumb: list[float], *fingers: list[float]) -> np.ndarray:
    """(5, 4) finger angles from the thumb's row and the fingers' rows from the index on; the fingers not
    given (the ones that move together) repeat the last row given."""
    rows = [thumb, *fingers]
    return np.array(rows + [fingers[-1]] * (5 - len(rows)))


RELAXED = _hand(
    [0.0, 0.20, 0.20, 0.15],
    [0.0, 0.30, 0.35, 0.20],
    [0.0, 0.30, 0.35, 0.20],
    [0.0, 0.32, 0.38, 0.22],
    [0.0, 0.35, 0.40, 0.25],
)
FLAT = _hand([-0.15, 0.05, 0.05, 0.05], [0.0, 0.05, 0.05, 0.03])
POINT = _hand([0.0, 0.60, 0.50, 0.35], [0.0, 0.05, 0.08, 0.05], [0.0, 1.50, 1.60, 1.00])
TAP = _hand([0.0, 0.30, 0.50, 0.40], [0.0, 0.45, 0.55, 0.30], [0.0, 0.70, 1.40, 0.90])
TAP2 = TAP.copy()
TAP2[2] = TAP[1]  # two-finger tap: the middle finger as the index
FIST = _hand([0.0, 0.70, 0.60, 0.50], [0.0, 1.50, 1.70, 1.10])
_PADS = [0.0, 0.30, 0.15, 0.10]  # index to ring sliding on their pads
SLIDE_FINGERS = _hand([0.0, 0.30, 0.30, 0.20], _PADS, _PADS, _PADS, [0.0, 0.60, 0.60, 0.40])
GRAB_OPEN = _hand([0.0, 0.00, 0.10, 0.10], [0.0, 0.15, 0.20, 0.10])


#: Population rates of the per-participant habits (probability that a trial uses the variant).
#: Assumptions (no published rates for these variants); ``data.preference_concentration`` and
#: ``data.variability`` set how much participants differ around them.
HABITS: dict[str, float] = {
    "hit_fist": 0.3,  # hit with the fist's knuckles instead of the palm
    "slide_fingers": 0.3,  # rub / stroke with the finger pads instead of the palm
    "tap_two": 0.6,  # tap with index and middle fingers
    "rub_across": 0.25,  # rub around the link instead of along it
    "pat_fingers": 0.25,  # pat with the finger pads (closer to a tap)
    "push_tip": 0.15,  # push with the index fingertip (closer to a poke)
    "grab_side": 0.5,  # which way the fingers wrap in a grab
    "stroke_sign": 0.5,  # preferred stroke direction along the link
}


@dataclass
class Style:
    """How one participant touches (drawn once per participant, shared by all regions).

    Scalars are participant effects; ``*_g`` dicts are participant x gesture
    effects (multiplicative factors, median 1), so a participant's ordering
    of gestures by duration, depth, speed, ... differs from another's.
    """

    scale: float
    """Hand size factor (bone lengths): hand length over the hand model's."""
    speed: float
    """Approach/retreat speed factor (> 1: faster)."""
    length: float
    """Participant effect on the log trial length."""
    duration: float
    """Factor on contact durations."""
    depth: float
    """Factor on penetration depths."""
    tilt: float
    """Approach tilt from the surface normal (radians)."""
    tilt_azimuth: float
    """Direction of that tilt around the normal, from t1 (radians): the side the hand comes from."""
    yaw: float
    """Preferred hand yaw around the normal, from t1 (radians)."""
    spread: float
    """Extra finger abduction (radians)."""
    rest_m: float
    """Distance of the rest pose from the touch point (metres)."""
    left_handed: bool = False
    """Left-handed participant using the tracked right hand (mirrored approach side, slower)."""
    habits: dict[str, float] = field(default_factory=dict)
    """Probability of each variant in :data:`HABITS`."""
    counts: dict[str, np.ndarray] = field(default_factory=dict)
    """Per multi-touch gesture, probabilities of its touch counts."""
    length_g: dict[str, float] = field(default_factory=dict)
    """Participant x gesture effect on the log trial length."""
    speed_g: dict[str, float] = field(default_factory=dict)
    duration_g: dict[str, float] = field(default_factory=dict)
    depth_g: dict[str, float] = field(default_factory=dict)
    rate_g: dict[str, float] = field(default_factory=dict)
    """Factor on repetition rate (rub frequency, touches per second of tap, pat, stroke)."""
    extent_g: dict[str, float] = field(default_factory=dict)
    """Factor on slide extent (rub amplitude, stroke length)."""

    def habit(self, name: str) -> float:
        return self.habits.get(name, HABITS[name])

    @classmethod
    def draw(cls, rng: np.random.Generator, spread: Spread, gestures=tuple(DEPTH_M)) -> Style:
        v = spread.variability
        sp = spread

        def around(mean: float, lo: float, hi: float) -> float:
            return float(mean + min(v, 1.0) * (rng.uniform(lo, hi) - mean))

        left = bool(rng.random() < sp.left_handed_fraction * min(v, 1.0))
        scale = sp.hand_scale(rng)
        side = (-np.pi / 2 if left else np.pi / 2) + v * rng.normal(0.0, 0.6)
        speed = sp.lognormal(rng, sp.speed_participant_sd) * (sp.nondominant_speed if left else 1.0)
        style = cls(
            scale=scale,
            speed=speed,
            length=float(v * sp.length_participant_sd * rng.standard_normal()),
            duration=sp.lognormal(rng, sp.duration_participant_sd),
            depth=sp.lognormal(rng, sp.depth_participant_sd),
            tilt=around(np.radians(15.0), 0.0, np.radians(30.0)),
            tilt_azimuth=float(side),
            yaw=float(min(v, 1.0) * rng.uniform(-np.pi, np.pi)),
            spread=around(0.06, 0.0, 0.12),
            rest_m=around(0.285, 0.22, 0.35),
            left_handed=left,
        )
        style.habits = {k: sp.preference(rng, m) for k, m in HABITS.items()}
        for g in sorted(TOUCH_COUNTS):
            k = len(TOUCH_COUNTS[g][0])
            pop = np.full(k, 1.0 / k)
            style.counts[g] = pop + min(v, 1.0) * (rng.dirichlet(np.full(k, 2.0)) - pop)
        for g in gestures:
            style.length_g[g] = float(v * sp.length_interaction_sd * rng.standard_normal())
            style.speed_g[g] = sp.lognormal(rng, sp.speed_interaction_sd)
            style.duration_g[g] = sp.lognormal(rng, sp.duration_interaction_sd)
            style.depth_g[g] = sp.lognormal(rng, sp.depth_interaction_sd)
            style.rate_g[g] = sp.lognormal(rng, sp.rate_interaction_sd)
            style.extent_g[g] = sp.lognormal(rng, sp.extent_interaction_sd)
        return style


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


def contact_duration(rng: np.random.Generator, gesture: str, style: Style, spread: Spread) -> float:
    """A trial's contact duration (s): CoST's mean x calibration x participant x participant-gesture x trial factors.

    Mean-preserving: the log-normal factors' variances (``variability``
    times the participant, interaction and CoST-derived trial SDs) are
    taken off the median, so the expected duration stays CoST's mean.
    """
    v = spread.variability
    sd_t = spread.duration_trial_sd(gesture)
    var = v * v * (spread.duration_participant_sd**2 + spread.duration_interaction_sd**2 + sd_t**2)
    mean = COST_DURATION_MS[gesture][0] / 1000.0 * DURATION_CALIBRATION[gesture]
    factor = style.duration * style.duration_g.get(gesture, 1.0)
    return float(mean * factor * np.exp(v * sd_t * rng.standard_normal() - 0.5 * var))


def penetration_depth(rng: np.random.Generator, gesture: str, style: Style, spread: Spread) -> float:
    """How far the effector goes below the surface in one trial (metres).

    Nothing stops a virtual hand: the median per gesture (:data:`DEPTH_M`)
    times participant, participant-gesture and trial log-normal factors; with
    probability ``deep_rate`` the hand passes a further 1 cm to
    ``depth_max_m`` into the hull. Capped at ``depth_max_m``.
    """
    d = DEPTH_M[gesture] * style.depth * style.depth_g.get(gesture, 1.0) * spread.lognormal(rng, spread.depth_trial_sd)
    if rng.random() < spread.rate(spread.deep_rate):
        d += float(rng.uniform(0.01, spread.depth_max_m))
    return float(min(d, spread.depth_max_m))


def _touch_train(
    total: float, n: int, kappa: float, depth: float, rng: np.random.Generator
) -> list[tuple[float, float, float]]:
    c = total / (n + (n - 1) * (1.0 - kappa) / kappa)
    g = c * (1.0 - kappa) / kappa
    out, t = [], 0.0
    for _i in range(n):
        ci = c * float(rng.uniform(0.85, 1.15))
        out.append((t, t + ci, depth * float(rng.uniform(0.8, 1.2))))
        t += ci + g * float(rng.uniform(0.8, 1.2))
    return out


def add_brush_and_retouch(plan: ContactPlan, rng: np.random.Generator, spread: Spread) -> ContactPlan:
    """Accidental contacts around the gesture, in place.

    With probability ``brush_rate`` the hand grazes the surface (30-120 ms,
    1-4 mm deep) 0.15-0.5 s before the gesture; with probability
    ``retouch_rate`` it comes back 0.2-0.6 s after it for a 0.1-0.4 s touch
    at half the gesture's depth (an adjustment). Times are shifted so the
    first contact still starts at 0.
    """
    depth = max(d for _, _, d in plan.touches)
    if rng.random() < spread.rate(spread.brush_rate):
        gap, dur = float(rng.uniform(0.15, 0.5)), float(rng.uniform(0.03, 0.12))
        shift = gap + dur
        plan.touches = [(0.0, dur, float(rng.uniform(0.001, 0.004)))] + [
            (a + shift, b + shift, d) for a, b, d in plan.touches
        ]
        plan.slide = [(t + shift, x) for t, x in plan.slide]
        plan.finger_knots = [(t + shift, f) for t, f in plan.finger_knots]
    if rng.random() < spread.rate(spread.retouch_rate):
        end = plan.touches[-1][1]
        a = end + float(rng.uniform(0.2, 0.6))
        plan.touches = plan.touches + [(a, a + float(rng.uniform(0.1, 0.4)), 0.5 * depth)]
    return plan


def plan_contact(
    gesture: str,
    rng: np.random.Generator,
    style: Style,
    wrap_radius_m: float,
    finger_radius_m: float,
    spread: Spread | None = None,
) -> ContactPlan:
    """Draw the contact phase of one ``gesture`` trial for a participant's ``style``.

    ``wrap_radius_m``: radius of the link's cross-section at the touch point
    (how far the grab's fingers must curl); ``finger_radius_m``: the fingers'
    capsule radius; ``spread``: the variability assumptions (default: the
    calibrated :class:`Spread`).
    """
    spread = Spread() if spread is None else spread
    plan = _plan(gesture, rng, style, wrap_radius_m, finger_radius_m, spread)
    return add_brush_and_retouch(plan, rng, spread)


@dataclass
class _Draws:
    """What every gesture's contact plan starts from, drawn for one trial (in this order): the depth below
    the surface (m), hand yaw, tilt and tilt azimuth (radians), the fingers' spread (5, 4 radians), the
    contact duration (s), and the participant-gesture factors on ramp time (``slow``), repetition rate and
    slide extent. Its methods draw the rest from the same ``rng``."""

    gesture: str
    rng: np.random.Generator
    style: Style
    depth: float
    yaw: float
    tilt: float
    az: float
    spread: np.ndarray
    dur: float
    slow: float
    rate: float
    extent: float

    @classmethod
    def draw(cls, gesture: str, rng: np.random.Generator, style: Style, sp: Spread) -> _Draws:
        """The common draws of one ``gesture`` trial for ``style`` under ``sp``."""
        depth = penetration_depth(rng, gesture, style, sp)
        yaw = style.yaw + rng.normal(0.0, np.radians(20.0))
        tilt = float(rng.uniform(0.0, np.radians(10.0)))
        az = float(rng.uniform(0.0, 2 * np.pi))
        spread = np.zeros((5, 4))
        spread[1:, 0] = np.array([1.0, 0.0, -1.0, -2.0]) * (style.spread + rng.normal(0.0, 0.02)) * 0.5
        dur = contact_duration(rng, gesture, style, sp)
        slow = 1.0 / style.speed_g.get(gesture, 1.0)  # pressing speed: ramps take longer for a slow participant-gesture
        rate = style.rate_g.get(gesture, 1.0)
        extent = style.extent_g.get(gesture, 1.0)
        return cls(gesture, rng, style, depth, yaw, tilt, az, spread, dur, slow, rate, extent)

    @property
    def one(self) -> list[tuple[float, float, float]]:
        """A single touch: (0 s, the duration in s, the depth in m)."""
        return [(0.0, self.dur, self.depth)]

    def hover(self, lo: float, hi: float) -> float:
        """A hover height (m) drawn uniformly in [lo, hi)."""
        return float(self.rng.uniform(lo, hi))

    def multi(self, g: str) -> list[tuple[float, float, float]]:
        """A train of (start s, end s, depth m) touches of a repeated gesture ``g``."""
        choices, expected = TOUCH_COUNTS[g]
        n = int(self.rng.choice(choices, p=self.style.counts[g]))
        return _touch_train(self.dur * n / expected / self.rate, n, CONTACT_FRACTION[g], self.depth, self.rng)

    def plan(self, effector: str, fingers: np.ndarray, touches, hover_m: float, ramp_s: float, **kw) -> ContactPlan:
        """The :class:`ContactPlan` of these draws; ``ramp_s`` (s) is scaled by ``slow``, ``kw`` may override
        ``yaw`` and ``tilt`` (radians) and set the other fields."""
        # ``hover_m`` is drawn by the caller before the draws in ``kw`` (the random stream's order)
        kw = {"yaw": self.yaw, "tilt": self.tilt, **kw}
        return ContactPlan(
            self.gesture, effector, fingers, touches, hover_m, ramp_s * self.slow, tilt_azimuth=self.az, **kw
        )

    def pads_or_palm(self, habit: str) -> tuple[str, np.ndarray]:
        """(effector, (5, 4) finger angles in radians): finger pads with the probability of ``habit``, else the palm."""
        fingers = self.rng.random() < self.style.habit(habit)
        return ("fingers", SLIDE_FINGERS) if fingers else ("palm", FLAT + self.spread)


def _poke(d: _Draws) -> ContactPlan:
    """A poke: the index tip, one touch, tilted up to 25 degrees."""
    return d.plan(
        "index_tip",
        POINT + 0.5 * d.spread,
        d.one,
        d.hover(0.03, 0.05),
        0.15,
        tilt=float(d.rng.uniform(0.0, np.radians(25.0))),
    )


def _tap_or_pat(d: _Draws) -> ContactPlan:
    """A tap (index tip, or two fingers) or a pat (pads or palm): a train of touches, each jittered along the surface."""
    rng, style, spread = d.rng, d.style, d.spread
    if d.gesture == "tap":
        effector, shape = "index_tip", (TAP2 if rng.random() < style.habit("tap_two") else TAP) + 0.5 * spread
        heights, ramp, jitter = (0.015, 0.025), 0.08, 0.004
    else:
        (effector, shape), heights, ramp, jitter = d.pads_or_palm("pat_fingers"), (0.03, 0.05), 0.10, 0.006
    touches = d.multi(d.gesture)
    out = d.plan(effector, shape, touches, d.hover(*heights), ramp, slide_angle=float(rng.uniform(0, 2 * np.pi)))
    out.slide = [(a, float(rng.normal(0.0, jitter))) for a, _, _ in touches]
    return out


def _hit(d: _Draws) -> ContactPlan:
    """A hit: fist or palm, one fast touch."""
    fist = d.rng.random() < d.style.habit("hit_fist")
    effector, shape = ("fist", FIST) if fist else ("palm", FLAT + d.spread)
    return d.plan(effector, shape, d.one, d.hover(0.08, 0.12), 0.05)


def _push(d: _Draws) -> ContactPlan:
    """A push: index tip or palm, one slow touch."""
    tip = d.rng.random() < d.style.habit("push_tip")
    effector, shape = ("index_tip", POINT + 0.5 * d.spread) if tip else ("palm", FLAT + d.spread)
    return d.plan(effector, shape, d.one, d.hover(0.03, 0.05), 0.25)


def _rub(d: _Draws) -> ContactPlan:
    """A rub: pads or palm sliding back and forth (1.5-3 Hz, 1.5-3 cm) along or across the link."""
    rng, dur = d.rng, d.dur
    effector, shape = d.pads_or_palm("slide_fingers")
    across = rng.random() < d.style.habit("rub_across")
    angle = (np.pi / 2 if across else 0.0) + rng.normal(0.0, np.radians(20.0))
    amp = float(rng.uniform(0.015, 0.03)) * d.extent
    freq = float(rng.uniform(1.5, 3.0)) * d.rate
    out = d.plan(effector, shape, d.one, d.hover(0.02, 0.04), 0.15, slide_angle=float(angle))
    half = 0.5 / freq
    k = np.arange(1, max(int(dur / half), 1) + 1)
    out.slide = [(0.0, 0.0)] + [(float(t), float(amp * (1 if i % 2 else -1))) for i, t in zip(k, k * half) if t < dur]
    return out


def _stroke(d: _Draws) -> ContactPlan:
    """A stroke: pads or palm sliding 6-12 cm (times hand scale) one way, once or more."""
    rng = d.rng
    effector, shape = d.pads_or_palm("slide_fingers")
    touches = d.multi("stroke")
    length = float(rng.uniform(0.06, 0.12)) * d.style.scale * d.extent
    sign = 1.0 if rng.random() < d.style.habit("stroke_sign") else -1.0
    angle = (0.0 if sign > 0 else np.pi) + rng.normal(0.0, np.radians(10.0))
    out = d.plan(effector, shape, touches, d.hover(0.02, 0.04), 0.12, slide_angle=float(angle))
    for a, b, _ in touches:
        out.slide += [(a, -0.5 * length), (b, 0.5 * length)]
    return out


def _grab(d: _Draws, rho: float) -> ContactPlan:
    """A grab: the palm on the link, fingers closing around a cylinder of radius ``rho`` (m) and opening again."""
    rng, dur = d.rng, d.dur
    side = 1.0 if rng.random() < d.style.habit("grab_side") else -1.0
    closed = _grab_fingers(rho, d.style.scale) * float(rng.uniform(1.2, 1.4))
    out = d.plan(
        "palm",
        GRAB_OPEN,
        d.one,
        d.hover(0.03, 0.05),
        0.2,
        yaw=np.pi / 2 * side + rng.normal(0.0, np.radians(10.0)),
        grab=True,
    )
    close = min(0.25, 0.3 * dur)
    out.finger_knots = [
        (0.0, GRAB_OPEN),
        (close, closed),
        (max(dur - close, close), closed),
        (dur + 0.1, GRAB_OPEN),
    ]
    return out


#: The plan of each gesture but the grab (which also takes the link's radius).
_PLANS = {
    "poke": _poke,
    "tap": _tap_or_pat,
    "pat": _tap_or_pat,
    "hit": _hit,
    "push": _push,
    "rub": _rub,
    "stroke": _stroke,
}


def _plan(
    gesture: str, rng: np.random.Generator, style: Style, wrap_radius_m: float, finger_radius_m: float, sp: Spread
) -> ContactPlan:
    """The contact phase of one ``gesture`` trial before accidental touches (see :func:`plan_contact`)."""
    d = _Draws.draw(gesture, rng, style, sp)
    if gesture == "grab":
        return _grab(d, wrap_radius_m + finger_radius_m)
    if gesture in _PLANS:
        return _PLANS[gesture](d)
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
