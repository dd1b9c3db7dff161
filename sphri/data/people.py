"""How the synthetic participants differ from each other and from trial to trial.

Every spread of the generator is a field of :class:`Spread` (one field per
``data.*`` key of ``data=synthetic``; each field's docstring names its
source, legend in :class:`sphri.data.schema.SyntheticDataSchema`), multiplied by the summary knob ``data.variability``: 1.0 is
calibrated to real people, 0 makes every participant draw from the same
population (no between-participant effects, no per-participant preferences,
no calibrated per-trial spread; only the gestures' own mechanical randomness
is left, e.g. where on the link a touch lands).

Random effects are log-normal factors on three levels, the usual
decomposition of repeated-measures data: participant (``*_participant_sd``),
participant x gesture (``*_interaction_sd``: a participant's style changes
which gestures resemble each other, e.g. slow taps that look like pokes) and
trial (``*_trial_sd``). Categorical habits (fist or palm for a hit, finger
pads or palm for a pat, ...) are per-participant probabilities drawn from a
Beta around the population's rate with concentration
``preference_concentration``; ``variability`` pulls them towards the
population rate.

Hand-written: the draws are a few lines of numpy each; no library models
nested random effects for simulation.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from sphri.data.reference_stats import COST_DURATION_MS, VR_LENGTH_SPREAD

#: Range of each kind of field: (lo, hi) inclusive.
_RANGES = {
    "variability": (0.0, 5.0),
    "_sd": (0.0, 3.0),
    "_rate": (0.0, 1.0),
    "_fraction": (0.0, 1.0),
    "hand_length_sd_mm": (0.0, 50.0),
    "_mm": (100.0, 300.0),
    "length_tail_df": (2.05, 1000.0),
    "long_trial_max_s": (8.0, 3600.0),
    "approach_s": (0.05, 10.0),
    "depth_max_m": (0.001, 0.2),
    "preference_concentration": (0.01, 1000.0),
    "site_kappa_max": (0.5, 50.0),
    "nondominant_speed": (0.1, 2.0),
}


@dataclass
class Spread:
    """The generator's variability assumptions, each field's source in its docstring ([VR], [CoST],
    [assumption], ...: the legend is :class:`sphri.data.schema.SyntheticDataSchema`'s).

    Also the base of the ``data=synthetic`` schema, so every field is a
    ``data.*`` key.
    """

    variability: float = 1.0
    """Multiplies EVERY spread below (participant, participant x gesture, trial, habit preferences, event
    rates): 1 = calibrated to real people, 0 = interchangeable participants (all draw from one population)
    with no calibrated trial spread; >1 exaggerates. Tracking noise is not scaled."""
    # trial length: log(frames) = log(VR median of the gesture) + participant + participant x gesture + trial
    length_participant_sd: float = 0.31
    """SD of a participant's effect on log trial length; gives a measured variance of participants' mean log
    length of 0.056-0.103 over seeds 0-2 [VR: 0.079; the fixed approach/retreat dilute it]."""
    length_interaction_sd: float = 0.10
    """SD of the participant x gesture effect on log length [VR: interaction variance 0.013, minus sampling noise]."""
    length_trial_sd: float = 0.10
    """Least SD of the trial effect; per gesture it is what is left of the VR study's SD of log length after the
    two effects above (:meth:`length_trial_sd_for`) [VR: SD of log length within a gesture 0.33-0.48]."""
    length_tail_df: float = 3.0
    """Student-t degrees of freedom of the trial effect (heavy tails) [VR: 99th percentile 403 frames]."""
    long_trial_rate: float = 0.004
    """Share of trials nobody ended in time (8 s to ``long_trial_max_s`` extra idle) [VR: 0.5 % of arm trials
    > 500 frames]."""
    long_trial_max_s: float = 70.0
    """Longest trial (s); longer draws are cut here [VR: longest arm trial 2,071 frames, 69 s]."""
    # approach and retreat
    approach_s: float = 0.7
    """Median duration of the approach and of the retreat (s) [assumption; the rest of the trial is idle]."""
    speed_participant_sd: float = 0.2
    """Log-SD of a participant's speed [assumption]."""
    speed_interaction_sd: float = 0.3
    """Log-SD of a participant x gesture speed (approach and pressing in) [assumption]."""
    speed_trial_sd: float = 0.2
    """Log-SD of a trial's approach and retreat times [assumption]."""
    # contact phase: mean duration = CoST's; trial log-SD chosen so the total spread matches CoST's SD
    duration_participant_sd: float = 0.35
    """Log-SD of a participant's contact-duration factor [assumption; CoST gives the total SD only]."""
    duration_interaction_sd: float = 0.55
    """Log-SD of a participant x gesture duration factor [assumption]; the trial SD fills up to CoST's SD."""
    depth_participant_sd: float = 0.5
    """Log-SD of how deep a participant's virtual hand goes into the hull [assumption: nothing stops it]."""
    depth_interaction_sd: float = 0.5
    """Log-SD of a participant x gesture depth factor [assumption]."""
    depth_trial_sd: float = 0.25
    """Log-SD of a trial's depth [assumption]."""
    deep_rate: float = 0.08
    """Share of trials where the hand passes 1 cm to ``depth_max_m`` further in [assumption]."""
    depth_max_m: float = 0.045
    """Deepest penetration (m), about the arm hull's half-width [VR: hull 7.2 x 9.3 cm]."""
    rate_interaction_sd: float = 0.35
    """Log-SD of a participant x gesture repetition rate (rub frequency, taps/pats/strokes per s) [assumption]."""
    extent_interaction_sd: float = 0.4
    """Log-SD of a participant x gesture slide extent (rub amplitude, stroke length) [assumption]."""
    preference_concentration: float = 0.5
    """Beta concentration of personal habits around the population rates (fist or palm hit, finger or palm
    pat/rub/stroke, fingertip push, ...; :data:`sphri.data.gestures.HABITS`) [assumption]."""
    # where people touch: a habitual site per participant and region, shifted per gesture
    site_axial_sd: float = 0.15
    """SD of a participant's habitual site along the link (fraction of its length) [assumption]."""
    site_interaction_sd: float = 0.15
    """SD of the per-gesture shift of that site along the link (fraction) [assumption]."""
    site_angle_interaction_sd: float = 0.8
    """SD of the per-gesture shift around the link (radians) [assumption]."""
    site_kappa_max: float = 3.0
    """Largest von Mises concentration of a participant's site around the link [assumption]."""
    # hands and handedness
    hand_length_male_mm: float = 189.0
    """Mean adult hand length, men (mm) [Pheasant & Haslegrave, Bodyspace, 3rd ed. 2006, British adults]."""
    hand_length_female_mm: float = 174.0
    """Mean adult hand length, women (mm) [same source]."""
    hand_length_sd_mm: float = 9.5
    """SD of hand length within each sex (mm) [same source: 10 and 9 mm]."""
    female_fraction: float = 0.5
    """Share of women among participants [assumption]."""
    hand_model_length_mm: float = 181.5
    """Hand length of the capsule hand model at scale 1 (mm) [assumption: the population mean]."""
    left_handed_fraction: float = 0.106
    """Share of left-handers, who touch with the tracked right hand from the other side [Papadatou-Pastou et al.
    2020, Psychol. Bull. 146:481-524: 10.6 %]."""
    nondominant_speed: float = 0.9
    """Speed factor of the non-dominant hand [assumption]."""
    # events inside a trial
    brush_rate: float = 0.06
    """Share of trials with an accidental graze 0.15-0.5 s before the gesture [assumption]."""
    retouch_rate: float = 0.06
    """Share of trials with a second short touch after the gesture [assumption]."""
    boundary_early_rate: float = 0.02
    """Share of trials ended too early (cut during the touch or the retreat) [assumption]."""
    boundary_late_rate: float = 0.02
    """Share of trials started late (the hand already approaching) [assumption]."""

    def validate(self, prefix: str = "data") -> None:
        """Range-check every field; raise :class:`sphri.config.ConfigError` naming ``prefix.field``."""
        from sphri.config import require_range

        for f in fields(Spread):
            lo, hi = next(r for k, r in _RANGES.items() if f.name == k or (k.startswith("_") and f.name.endswith(k)))
            require_range(f"{prefix}.{f.name}", getattr(self, f.name), lo=lo, hi=hi)

    @classmethod
    def from_kwargs(cls, **kw) -> Spread:
        """A Spread from the data config's fields (others ignored)."""
        names = {f.name for f in fields(cls)}
        return cls(**{k: float(v) for k, v in kw.items() if k in names})

    def lognormal(self, rng: np.random.Generator, sd: float) -> float:
        """A median-1 log-normal factor with log-SD ``variability * sd``."""
        return float(np.exp(self.variability * sd * rng.standard_normal()))

    def rate(self, rate: float) -> float:
        """An event probability scaled by ``variability`` (clipped to [0, 1])."""
        return float(min(1.0, self.variability * rate))

    def preference(self, rng: np.random.Generator, mean: float) -> float:
        """A participant's probability of a habit whose population rate is ``mean``."""
        c = self.preference_concentration
        q = float(rng.beta(mean * c, (1.0 - mean) * c))
        return float(np.clip(mean + min(self.variability, 1.0) * (q - mean), 0.0, 1.0))

    def heavy(self, rng: np.random.Generator, sd: float) -> float:
        """A trial-level term with SD ``variability * sd`` and Student-t tails (``length_tail_df`` > 2)."""
        df = self.length_tail_df
        return float(self.variability * sd * rng.standard_t(df) / np.sqrt(df / (df - 2.0)))

    def length_trial_sd_for(self, region: str, gesture: str) -> float:
        """Trial-level SD of log length such that the within-gesture total matches the VR manifests.

        The VR study's SD of log length for the gesture (region's table, the
        arm's for other regions), minus the participant and interaction
        variances; never below ``length_trial_sd``.
        """
        table = VR_LENGTH_SPREAD.get(region, VR_LENGTH_SPREAD["arm"])["gestures"]
        sd = table[gesture]["sd_log"] if gesture in table else 0.0
        rest = sd**2 - self.length_participant_sd**2 - self.length_interaction_sd**2
        return float(np.sqrt(max(rest, self.length_trial_sd**2)))

    def duration_trial_sd(self, gesture: str) -> float:
        """Trial-level log-SD of a gesture's contact duration such that the total matches CoST's SD.

        CoST reports mean (SD) per gesture over participants and trials; a
        log-normal with that coefficient of variation has log-variance
        ``ln(1 + CV^2)``; the participant and interaction variances are taken
        out of it (at least 0.15 is left for the trial).
        """
        mean, sd = COST_DURATION_MS[gesture]
        total = np.log1p((sd / mean) ** 2)
        rest = total - self.duration_participant_sd**2 - self.duration_interaction_sd**2
        return float(np.sqrt(max(rest, 0.15**2)))

    def hand_scale(self, rng: np.random.Generator) -> float:
        """A participant's hand size factor: hand length from a male/female mixture over the model's length."""
        female = rng.random() < self.female_fraction
        mean = self.hand_length_female_mm if female else self.hand_length_male_mm
        pop = self.female_fraction * self.hand_length_female_mm + (1 - self.female_fraction) * self.hand_length_male_mm
        length = pop + self.variability * (mean + self.hand_length_sd_mm * rng.standard_normal() - pop)
        return float(np.clip(length / self.hand_model_length_mm, 0.75, 1.25))
