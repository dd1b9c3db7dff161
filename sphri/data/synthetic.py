"""``SyntheticData`` (``data=synthetic``, the default): calibrated synthetic gesture trials.

Each trial is a kinematic right hand (:mod:`sphri.data.handfk`) that rests
away from the link, approaches a touch point sampled on the link's real
surface (along the surface normal, tilted by the participant's approach
direction), performs the gesture (:mod:`sphri.data.gestures`) and returns to
rest, like the reference study's self-paced trials. Motions are min-jerk
interpolations between keyframes, evaluated for all frames of a trial at
once; forward kinematics runs once per (participant, region).

Timing. Frames are at ``frame_rate_hz`` (30 Hz by default: the rate that the
study's trial lengths are counted in, see
:mod:`sphri.data.reference_stats`). Hand tracking updates at about
``tracking_rate_hz`` with jittered intervals and is seen ``latency_ms`` late
(varying by ``latency_sd_ms``); each frame holds the latest tracking sample
(so some frames repeat the previous pose); about ``dropouts_per_trial``
losses per trial (3 to ``dropout_max_frames`` frames) freeze the hand, which
then jumps to where it is, and ``jumps_per_trial`` mis-tracked samples throw
it by ``jump_mm``. Tracking noise: ``jitter_mm`` (SD per axis) on the hand
position per sample, 0.4 degrees on its rotation, 1 degree on finger joints,
0.3 mm per joint.

Timing of a trial. Its whole length (rest to rest) is drawn first: the VR
study's median for the gesture and region
(:data:`sphri.data.reference_stats.VR_MEDIAN_TRIAL_FRAMES`) times the
participant's, the participant x gesture and a heavy-tailed trial factor
(:class:`sphri.data.people.Spread`, calibrated to the manifests' spread); a
few trials nobody ended get tens of seconds more. The contact phase
(:mod:`sphri.data.gestures`: CoST's durations with participant, participant
x gesture and trial factors, brushes and re-touches) and the approach and
retreat (``approach_s`` over the participant's speed) are placed in it, and
what is left is idle time, split at random before and after. Some trials are
mis-timed: started late (the hand already approaching) or ended early
(during the touch or the retreat).

Determinism. Participant ``k``'s style (hand size, handedness, speed,
durations, depths, habits, per-gesture effects) comes from the stream ``(seed, k, 0)`` and its trials in
a region from ``(seed, k, crc32(region))``: generating only the arm gives
exactly the arm trials of arm + torso, and 4 participants are the first 4 of
18.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING

import numpy as np

from sphri.data.format import make_trials_frame, participant_id, trial_id
from sphri.data.gestures import RELAXED, ContactPlan, Style, plan_contact
from sphri.data.people import Spread
from sphri.data.reference_stats import VR_FRAME_RATE_HZ, median_trial_frames
from sphri.data.schema import SyntheticDataSchema as _S  # the defaults, stated once
from sphri.types import GESTURES, GestureDataset, HandModel, Robot

if TYPE_CHECKING:  # imported where trials are generated: numba, trimesh and scipy stay out of a cached run
    from sphri.data.handfk import HandRig
    from sphri.data.linkgeom import LinkSurface

log = logging.getLogger(__name__)

#: Study size: participants and repetitions per gesture.
DEFAULT_PARTICIPANTS = 18
DEFAULT_REPETITIONS = 20

_S_GRID = np.linspace(0.0, 1.0, 2001)
_SMOOTH = _S_GRID**3 * (10.0 - 15.0 * _S_GRID + 6.0 * _S_GRID**2)


def smoothstep(s: np.ndarray) -> np.ndarray:
    """Min-jerk profile 10 s^3 - 15 s^4 + 6 s^5 on [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


def inverse_smoothstep(y: float) -> float:
    """The s in [0, 1] where :func:`smoothstep` reaches ``y``."""
    return float(np.interp(y, _SMOOTH, _S_GRID))


def interpolate(t: np.ndarray, knot_t: Sequence[float] | np.ndarray, knot_v: np.ndarray) -> np.ndarray:
    """(T, D) min-jerk interpolation of knots (K,) -> (K, D) at times ``t`` (T,); held outside the knots."""
    kt = np.asarray(knot_t, dtype=np.float64)
    kv = np.asarray(knot_v, dtype=np.float64).reshape(len(kt), -1)
    if len(kt) == 1:
        return np.broadcast_to(kv[0], (len(t), kv.shape[1])).copy()
    i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 2)
    dt = kt[i + 1] - kt[i]
    s = np.where(dt > 0, (t - kt[i]) / np.where(dt > 0, dt, 1.0), 1.0)
    w = smoothstep(s)[:, None]
    return kv[i] + (kv[i + 1] - kv[i]) * w


def height_knots(plan: ContactPlan) -> list[tuple[float, float]]:
    """(time s, effector height m) knots of the touches: crossing the surface exactly at each touch's start and end."""
    knots: list[tuple[float, float]] = []
    touches = plan.touches
    h = plan.hover_m
    for i, (a, b, d) in enumerate(touches):
        q = inverse_smoothstep(h / (h + d))
        r = plan.ramp_s
        if b - a < 2 * (1 - q) * r:
            r = (b - a) / (2 * (1 - q))
        if i > 0:
            r = min(r, (a - touches[i - 1][1]) / (2 * q))
        if i < len(touches) - 1:
            r = min(r, (touches[i + 1][0] - b) / (2 * q))
        knots += [(a - q * r, h), (a + (1 - q) * r, -d), (b - (1 - q) * r, -d), (b + q * r, h)]
    return knots


def region_stream(region: str) -> int:
    """Stable integer key of a region name for seeding (crc32)."""
    return zlib.crc32(region.encode("utf-8")) & 0x7FFFFFFF


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.sqrt(v @ v)


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``v`` (3,) rotated by ``angle`` radians about ``axis`` (Rodrigues)."""
    k = _unit(axis)
    c, s = np.cos(angle), np.sin(angle)
    return v * c + np.cross(k, v) * s + k * (k @ v) * (1.0 - c)


@dataclass
class _TrialMotion:
    """Per-frame hand parameters of one trial before forward kinematics."""

    fingers: np.ndarray  # (T, 5, 4) radians
    rot: np.ndarray  # (T, 3, 3) hand frame -> link frame
    target: np.ndarray  # (T, 3) where the effector point goes (metres, link frame)
    effector: int  # index into EFFECTORS
    pos_noise: np.ndarray  # (T, 3) metres
    joint_noise: np.ndarray  # (T, C, 3) metres
    contact: np.ndarray  # (T,) bool: the frame shows a time inside one of the plan's touches (the contact phase)


@dataclass
class _TouchSite:
    """Where one trial touches: its contact plan, the touch point ``p`` (3,) m with outward normal ``n`` and
    tangents ``t1``, ``t2`` (link frame), and the plan's (time s, effector height m) knots."""

    plan: ContactPlan
    p: np.ndarray
    n: np.ndarray
    t1: np.ndarray
    t2: np.ndarray
    hk: list[tuple[float, float]]


@dataclass
class _Timeline:
    """Phase times of one trial (seconds): first rest ends, hover reached, contact-plan time 0 (``shift``),
    leaving the surface, back away, end; the first frame's time and the number of frames."""

    rest1: float
    t_hover: float
    shift: float
    t_leave: float
    t_gone: float
    t_end: float
    t_start: float
    n_frames: int


@dataclass
class _Tracking:
    """Per frame: the time its pose shows (s, ``t``) and the tracking sample it holds (``held``), of ``n_samples``."""

    t: np.ndarray
    held: np.ndarray
    n_samples: int


def trial_records(
    records: list[dict], pid: str, region: str, gestures: Sequence[str], lengths: Sequence[int], start: int
) -> int:
    """Append one trials-table row per generated trial (ordinals 1..n, frames from ``start``); the next start."""
    for o, (g, n) in enumerate(zip(gestures, lengths), 1):
        records.append(
            dict(
                participant=pid,
                region=region,
                trial_ordinal=o,
                trial_id=trial_id(o, g),
                gesture=g,
                start=start,
                n_frames=int(n),
            )
        )
        start += int(n)
    return start


class SyntheticData:
    """Synthetic gesture trials (see the module docstring); ``load`` returns a :class:`GestureDataset`.

    ``participants``/``repetitions``: None = the study's 18 / 20.
    ``regions``: skin regions of the robot to touch. ``root`` must be None
    (it belongs to ``data=vr_gesture``). Other fields, their defaults and
    sources: :class:`sphri.data.schema.SyntheticDataSchema`.
    """

    VERSION = "3"

    def __init__(
        self,
        seed: int = _S.seed,
        participants: int | None = _S.participants,
        repetitions: int | None = _S.repetitions,
        regions: Sequence[str] = ("arm",),
        gestures: Sequence[str] = GESTURES,
        root: str | None = None,
        frame_rate_hz: float = _S.frame_rate_hz,
        tracking_rate_hz: float = _S.tracking_rate_hz,
        jitter_mm: float = _S.jitter_mm,
        latency_ms: float = _S.latency_ms,
        latency_sd_ms: float = _S.latency_sd_ms,
        dropouts_per_trial: float = _S.dropouts_per_trial,
        dropout_max_frames: int = _S.dropout_max_frames,
        jumps_per_trial: float = _S.jumps_per_trial,
        jump_mm: float = _S.jump_mm,
        **spread,
    ):
        self.seed = int(seed)
        self.participants = DEFAULT_PARTICIPANTS if participants is None else int(participants)
        self.repetitions = DEFAULT_REPETITIONS if repetitions is None else int(repetitions)
        self.regions = list(regions)
        self.gestures = list(gestures)
        unknown = [g for g in self.gestures if g not in GESTURES]
        if unknown:
            raise ValueError(f"data.gestures: unknown gesture(s) {unknown}; known: {list(GESTURES)}")
        if root is not None:
            raise ValueError(f"data.root={root!r} is only read by data=vr_gesture; data=synthetic generates its trials")
        known = {f.name for f in dataclass_fields(Spread)}
        extra = sorted(set(spread) - known)
        if extra:
            raise TypeError(f"data: unknown field(s) {extra} for data=synthetic")
        self.spread = Spread.from_kwargs(**spread)
        self.frame_rate_hz = float(frame_rate_hz)
        self.tracking_rate_hz = float(tracking_rate_hz)
        self.jitter_mm = float(jitter_mm)
        self.latency_ms = float(latency_ms)
        self.latency_sd_ms = float(latency_sd_ms)
        self.dropouts_per_trial = float(dropouts_per_trial)
        self.dropout_max_frames = int(dropout_max_frames)
        self.jumps_per_trial = float(jumps_per_trial)
        self.jump_mm = float(jump_mm)

    # ------------------------------------------------------------------ public
    def load(self, hand: HandModel, robot: Robot) -> GestureDataset:
        """Generate the trials (participant-major, regions in configured order, ordinals 1..n)."""
        from sphri.data.handfk import HandRig
        from sphri.data.linkgeom import LinkSurface

        rig = HandRig.from_hand(hand)
        surfaces = {r: LinkSurface(robot.link_for(r)) for r in self.regions}
        records: list[dict] = []
        chunks: list[np.ndarray] = []
        start = 0
        for k in range(1, self.participants + 1):
            style = Style.draw(np.random.default_rng([self.seed, k, 0]), self.spread, GESTURES)
            pid = participant_id(k)
            for region in self.regions:
                rng = np.random.default_rng([self.seed, k, region_stream(region)])
                gestures, poses, lengths, _ = self._participant_region_phases(rng, style, rig, surfaces[region], region)
                start = trial_records(records, pid, region, gestures, lengths, start)
                chunks.append(poses)
        poses = np.concatenate(chunks, axis=0) if chunks else np.zeros((0, hand.n_capsules, 7), np.float32)
        return GestureDataset(
            name="synthetic",
            synthetic=True,
            hand=hand,
            trials=make_trials_frame(records),
            poses=np.ascontiguousarray(poses, dtype=np.float32),
            frame_rate_hz=self.frame_rate_hz,
            repairs={},
        )

    # --------------------------------------------------------------- internals
    def _participant_region_phases(
        self, rng: np.random.Generator, style: Style, rig: HandRig, surf: LinkSurface, region: str
    ) -> tuple[list[str], np.ndarray, list[int], np.ndarray]:
        """The trials of one participant on one region: (gestures in order, poses (T, C, 7) float32 link frame,
        frames per trial) and, per frame (T,) bool, whether it lies in its trial's contact phase
        (the time it shows is inside one of the plan's touches: surface crossed on the way in, not yet on the way
        out; pauses between re-touches are outside)."""
        from sphri.data.handfk import EFFECTORS, effectors_from_bones

        sp = self.spread
        v, w = sp.variability, min(sp.variability, 1.0)
        # habitual touch site of this participant on this region, and its per-gesture shifts
        axial = 0.5 + v * sp.site_axial_sd * float(rng.standard_normal())
        axial_sd = 0.25 + w * (float(rng.uniform(0.08, 0.2)) - 0.25)
        angle = float(rng.uniform(0, 2 * np.pi))
        kappa = w * float(rng.uniform(0.5, sp.site_kappa_max))
        samplers = {}
        for g in self.gestures:
            samplers[g] = surf.sampler(
                surf.preference(
                    axial_frac=float(np.clip(axial + v * sp.site_interaction_sd * rng.standard_normal(), 0.1, 0.9)),
                    axial_sd=axial_sd,
                    angle=angle + v * sp.site_angle_interaction_sd * float(rng.standard_normal()),
                    angle_kappa=kappa,
                )
            )
        order = [g for g in self.gestures for _ in range(self.repetitions)]
        order = [order[i] for i in rng.permutation(len(order))]
        if not order:
            return [], np.zeros((0, rig.hand.n_capsules, 7), np.float32), [], np.zeros(0, dtype=bool)
        finger_r = float(rig.hand.radius_m[rig.chain_slot[2, 0]])
        plans, points = [], []
        for g in order:
            sampler = samplers[g]
            if g == "grab":
                i = sampler.draw(rng, margin_m=0.03)
                plan = plan_contact(g, rng, style, float(np.clip(surf.radius[i], 0.025, 0.2)), finger_r, sp)
            else:
                plan = plan_contact(g, rng, style, 0.05, finger_r, sp)
                margin = 0.015 + plan.slide_extent_m * abs(np.cos(plan.slide_angle))
                i = sampler.draw(rng, margin_m=min(margin, 0.45 * surf.length_m))
            plans.append(plan)
            points.append(i)
        # effector normal and forward of every trial's touching hand shape, in one batch
        kind = np.array([EFFECTORS.index(p.effector) for p in plans])
        _, nrm, fwd = effectors_from_bones(rig, *rig.bones(np.stack([p.fingers for p in plans]), style.scale))
        rows = np.arange(len(plans))
        m_l, f_l = nrm[rows, kind], fwd[rows, kind]
        motions = [self._trial(rng, style, rig, surf, region, plans[k], points[k], m_l[k], f_l[k]) for k in rows]
        fingers = np.concatenate([m.fingers for m in motions])
        rot = np.concatenate([m.rot for m in motions])
        target = np.concatenate([m.target for m in motions])
        kind = np.concatenate([np.full(len(m.fingers), m.effector) for m in motions])
        start, frame, length = rig.bones(fingers, style.scale)
        pts, _, _ = effectors_from_bones(rig, start, frame, length)
        e = pts[np.arange(len(kind)), kind]
        pos = target - np.einsum("tij,tj->ti", rot, e) + np.concatenate([m.pos_noise for m in motions])
        poses = rig.poses_from_bones(start, frame, length, rot, pos)
        poses[..., :3] += np.concatenate([m.joint_noise for m in motions])
        contact = np.concatenate([m.contact for m in motions])
        return order, poses.astype(np.float32), [len(m.fingers) for m in motions], contact

    def _trial(
        self,
        rng: np.random.Generator,
        style: Style,
        rig: HandRig,
        surf: LinkSurface,
        region: str,
        plan: ContactPlan,
        i: int,
        m_l: np.ndarray,
        f_l: np.ndarray,
    ) -> _TrialMotion:
        """The motion of one trial touching ``surf`` at its point ``i`` with ``plan``; ``m_l``/``f_l`` (3,): the
        touching effector's normal and forward in the hand frame."""
        from sphri.data.handfk import EFFECTORS

        p, n, t1, t2 = surf.frame_at(i)
        site = _TouchSite(plan, p, n, t1, t2, height_knots(plan))
        r_contact = _contact_rotation(site, m_l, f_l)
        tl = self._timeline(rng, style, region, site)
        tr = self._tracking(rng, tl)
        target = _target_track(rng, style, surf, site, tl, tr.t)
        fingers = _finger_track(rng, plan, tl, tr.t)
        rot, fingers, pos_noise, joint_noise = self._tracked(rng, tl, tr, r_contact, fingers, rig.hand.n_capsules)
        return _TrialMotion(
            fingers=fingers,
            rot=rot,
            target=target,
            effector=EFFECTORS.index(plan.effector),
            pos_noise=pos_noise,
            joint_noise=joint_noise,
            contact=contact_phase(plan, tl.shift, tr.t),
        )

    def _timeline(self, rng: np.random.Generator, style: Style, region: str, site: _TouchSite) -> _Timeline:
        """The phase times (s) and frame count of one trial: its whole length, approach and retreat, the idle
        time split before and after, and mis-timed boundaries."""
        plan, hk = site.plan, site.hk
        gesture = plan.gesture
        sp = self.spread
        c0, c1 = hk[0][0], hk[-1][0]
        # whole-trial length: the study's median for the gesture, times the participant's, the participant x
        # gesture and a heavy-tailed trial factor; now and then a trial nobody ended (tens of seconds)
        log_len = (
            np.log(median_trial_frames(region, gesture) / VR_FRAME_RATE_HZ)
            + style.length
            + style.length_g.get(gesture, 0.0)
            + sp.heavy(rng, sp.length_trial_sd_for(region, gesture))
        )
        total = float(np.exp(log_len))
        if rng.random() < sp.rate(sp.long_trial_rate):
            total += float(np.exp(rng.uniform(np.log(8.0), np.log(sp.long_trial_max_s))))
        total = min(total, sp.long_trial_max_s)
        speed = style.speed * style.speed_g.get(gesture, 1.0)
        approach = max(0.25, sp.approach_s / speed * sp.lognormal(rng, sp.speed_trial_sd))
        retreat = max(0.25, sp.approach_s / speed * sp.lognormal(rng, sp.speed_trial_sd))
        idle = max(0.2, total - (c1 - c0) - approach - retreat)
        rest1 = idle * float(rng.beta(2.0, 2.0))
        rest2 = idle - rest1
        t_hover = rest1 + approach
        shift = t_hover - c0
        t_leave = shift + c1
        t_gone = t_leave + retreat
        t_end = t_gone + rest2
        # mis-timed trial boundaries: started late (the hand already on its way), ended early (during the touch)
        t_start, t_stop = 0.0, t_end
        if rng.random() < sp.rate(sp.boundary_late_rate):
            t_start = float(rng.uniform(0.0, t_hover))
        if rng.random() < sp.rate(sp.boundary_early_rate):
            first_touch = shift + plan.touches[0][0]
            t_stop = float(rng.uniform(first_touch + 0.5 * (plan.touches[0][1] - plan.touches[0][0]), t_gone))
        n_frames = max(int(round((t_stop - t_start) * self.frame_rate_hz)), 2)
        return _Timeline(rest1, t_hover, shift, t_leave, t_gone, t_end, t_start, n_frames)

    def _tracking(self, rng: np.random.Generator, tl: _Timeline) -> _Tracking:
        """Which tracking sample each frame of the trial ``tl`` holds, and the time (s) it shows."""
        # tracking: jittered ~tracking_rate_hz samples held between frames, seen with a latency;
        # dropouts freeze the hand, jumps throw it a few centimetres for a sample or three
        t_start, n_frames = tl.t_start, tl.n_frames
        frame_t = t_start + np.arange(n_frames) / self.frame_rate_hz
        period = 1.0 / self.tracking_rate_hz
        n_samples = int(n_frames * self.tracking_rate_hz / self.frame_rate_hz * 1.6) + 8
        steps = period * np.clip(1.0 + 0.15 * rng.standard_normal(n_samples), 0.4, 2.0)
        sample_t = t_start + rng.uniform(0.0, period) + np.concatenate([[0.0], np.cumsum(steps[:-1])])
        held = np.clip(np.searchsorted(sample_t, frame_t, side="right") - 1, 0, None)
        for _ in range(rng.poisson(self.dropouts_per_trial)):
            a = int(rng.integers(0, n_frames))
            held[a : a + int(rng.integers(3, self.dropout_max_frames + 1))] = held[a]
        latency = (self.latency_ms + self.latency_sd_ms * rng.standard_normal(n_samples)) / 1000.0
        t = np.minimum(sample_t[held], frame_t) - latency[held]
        return _Tracking(t, held, n_samples)

    def _tracked(
        self,
        rng: np.random.Generator,
        tl: _Timeline,
        tr: _Tracking,
        r_contact: np.ndarray,
        fingers: np.ndarray,
        n_capsules: int,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(rotation (T, 3, 3), fingers (T, 5, 4) radians, position noise (T, 3) m, joint noise (T, C, 3) m) of
        the trial: the hand's wobble at rest around ``r_contact`` and the tracking noise, one draw per sample."""
        from sphri.data.handfk import rotvec_to_matrix

        t, held = tr.t, tr.held
        w_rest1 = rng.normal(0.0, 0.3, size=3)
        w_rest2 = rng.normal(0.0, 0.3, size=3)
        omega = interpolate(
            t, [tl.rest1, tl.t_hover, tl.t_leave, tl.t_gone], np.stack([w_rest1, np.zeros(3), np.zeros(3), w_rest2])
        )

        # tracking noise, one draw per tracking sample (held with it)
        ns = tr.n_samples
        omega = omega + np.radians(0.4) * rng.standard_normal((ns, 3))[held]
        fingers = fingers + np.radians(1.0) * rng.standard_normal((ns, 5, 4))[held]
        rot = r_contact[None] @ rotvec_to_matrix(omega)
        sample_noise = self.jitter_mm / 1000.0 * rng.standard_normal((ns, 3))
        for _ in range(rng.poisson(self.jumps_per_trial)):
            j = int(rng.integers(0, ns))
            sample_noise[j : j + int(rng.integers(1, 4))] += self.jump_mm / 1000.0 * rng.standard_normal(3)
        pos_noise = sample_noise[held]
        joint_noise = 0.0003 * rng.standard_normal((ns, n_capsules, 3))[held]
        return rot, fingers, pos_noise, joint_noise


def contact_phase(plan: ContactPlan, shift: float, t: np.ndarray) -> np.ndarray:
    """(T,) bool: the times ``t`` (s, trial time) inside one of ``plan``'s touches (plan time + ``shift``)."""
    inside = np.zeros(t.shape, dtype=bool)
    for a, b, _ in plan.touches:
        inside |= (t >= a + shift) & (t <= b + shift)
    return inside


def _contact_rotation(site: _TouchSite, m_l: np.ndarray, f_l: np.ndarray) -> np.ndarray:
    """(3, 3) hand frame -> link frame while touching: the effector's normal ``m_l`` against the (tilted)
    surface normal, its forward ``f_l`` along the plan's yaw."""
    plan, n, t1, t2 = site.plan, site.n, site.t1, site.t2
    tilt_axis = np.cos(plan.tilt_azimuth) * t1 + np.sin(plan.tilt_azimuth) * t2
    press = _rotate(-n, tilt_axis, plan.tilt)
    tau = np.cos(plan.yaw) * t1 + np.sin(plan.yaw) * t2
    tau = _unit(tau - (tau @ press) * press)
    world = np.stack([press, tau, np.cross(press, tau)], axis=1)
    local = np.stack([m_l, f_l, np.cross(m_l, f_l)], axis=1)
    return world @ local.T


def _target_track(
    rng: np.random.Generator, style: Style, surf: LinkSurface, site: _TouchSite, tl: _Timeline, t: np.ndarray
) -> np.ndarray:
    """(T, 3) where the effector goes at times ``t`` (s), metres in the link frame: from a drifting rest point
    to the touch (height and slide over the surface) and back."""
    plan, p, n, t1, t2, hk = site.plan, site.p, site.n, site.t1, site.t2, site.hk
    rest1, t_hover, shift, t_leave, t_gone = tl.rest1, tl.t_hover, tl.shift, tl.t_leave, tl.t_gone
    beta = interpolate(t, [rest1, t_hover, t_leave, t_gone], np.array([0.0, 1.0, 1.0, 0.0]))[:, 0]
    h = interpolate(t, [k + shift for k, _ in hk], np.array([v for _, v in hk]))[:, 0]
    angle = plan.slide_angle
    slide_dir = np.cos(angle) * t1 + np.sin(angle) * t2
    if plan.slide:
        s = interpolate(t, [k + shift for k, _ in plan.slide], np.array([v for _, v in plan.slide]))[:, 0]
        ext = plan.slide_extent_m + 0.01
        grid = np.linspace(-ext, ext, 17)
        s_h = np.interp(s, grid, surf.height_profile(p, n, slide_dir, grid))
    else:
        s = np.zeros(tl.n_frames)
        s_h = np.zeros(tl.n_frames)
    tilt_app = style.tilt + rng.normal(0.0, np.radians(8.0))
    az = style.tilt_azimuth + rng.normal(0.0, np.radians(25.0))
    d_app = _rotate(n, np.cos(az) * t1 + np.sin(az) * t2, tilt_app)
    rest = p + d_app * style.rest_m * float(rng.uniform(0.9, 1.1))
    drift = rng.normal(0.0, 0.015, size=(3, 3))
    rest_t = [0.0, rest1, t_gone, tl.t_end]
    rest_v = np.stack([rest, rest + drift[0], rest + drift[1], rest + drift[1] + drift[2]])
    rest_track = interpolate(t, rest_t, rest_v)
    touch = p + n * (h + s_h)[:, None] + slide_dir * s[:, None]
    return (1.0 - beta)[:, None] * rest_track + beta[:, None] * touch


def _finger_track(rng: np.random.Generator, plan: ContactPlan, tl: _Timeline, t: np.ndarray) -> np.ndarray:
    """(T, 5, 4) finger angles (radians) at times ``t`` (s): relaxed at rest, the plan's shape (and knots) in contact."""
    rest1, t_hover, shift = tl.rest1, tl.t_hover, tl.shift
    relaxed = RELAXED + rng.normal(0.0, 0.05, size=RELAXED.shape)
    f_t = [0.0, rest1, t_hover]
    f_v = [relaxed, relaxed, plan.fingers]
    for k, v in plan.finger_knots:
        f_t.append(k + shift)
        f_v.append(v)
    f_t += [tl.t_leave, tl.t_gone]
    f_v += [plan.fingers if not plan.finger_knots else plan.finger_knots[-1][1], relaxed]
    order = np.argsort(f_t, kind="stable")
    return interpolate(t, np.asarray(f_t)[order], np.stack(f_v)[order].reshape(len(f_t), -1)).reshape(-1, 5, 4)
