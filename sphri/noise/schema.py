"""Config schemas of the noise group (``conf/noise/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, setting, store


@dataclass
class NoiseSchema(ComponentSchema, group="noise"):
    """Base of the noise group's schemas."""


@dataclass
class SaltPepperNoiseSchema(NoiseSchema):
    """Salt-and-pepper: independent per-taxel read errors; with probability p per taxel and frame a
    reading is replaced by 1 (salt) or 0 (pepper). An untouched skin of N taxels shows on average
    ``p * salt_vs_pepper * N`` false taxels per frame in replace mode (``p * N`` in flip mode)."""

    _target_: str = "sphri.noise.components.SaltPepperNoise"
    p: float = setting(0.02, lo=0.0, hi=1.0)
    """Probability that a taxel reading is corrupted, per taxel and per frame (paper: 0.02; applied to
    every slot of the model's window, padded slots included)."""
    mode: str = setting("replace", choices=("replace", "flip"))
    """replace: set to a random 0/1 (half the corruptions leave a reading as it was); flip: invert it."""
    salt_vs_pepper: float = setting(0.5, lo=0.0, hi=1.0)
    """replace mode: probability that a corrupted reading becomes 1."""


@dataclass
class GaussianNoiseSchema(NoiseSchema):
    """Analogue read noise: additive N(0, sigma^2) per taxel and frame, clipped to [0, 1] (float32 readings)."""

    _target_: str = "sphri.noise.components.GaussianNoise"
    sigma: float = setting(0.05, lo=0.0, hi=10.0)
    """Standard deviation of the added noise (reading units, 1 = full scale)."""


@dataclass
class DeadTaxelsNoiseSchema(NoiseSchema):
    """Broken taxels: a fixed fraction of the N taxels always reads ``value`` (same sensor in every trial);
    stuck-on taxels (value 1) are ``round(fraction * N)`` false taxels in every frame."""

    _target_: str = "sphri.noise.components.DeadTaxelsNoise"
    fraction: float = setting(0.05, lo=0.0, hi=1.0)
    """Fraction of the N taxels that are dead (round(fraction * N) of them, chosen by seed only)."""
    value: float = setting(0.0, lo=0.0, hi=1.0)
    """What a dead taxel reads (0 = silent, 1 = stuck on)."""


@dataclass
class CrosstalkNoiseSchema(NoiseSchema):
    """Crosstalk: neighbour coupling; ``alpha`` of each reading appears on each neighbouring taxel
    (float32). Nothing appears on an untouched skin (0 false taxels per frame at any N)."""

    _target_: str = "sphri.noise.components.CrosstalkNoise"
    alpha: float = setting(0.1, lo=0.0, hi=1.0)
    """Coupling coefficient: fraction (0-1) of a taxel's reading added to each neighbour (result clipped to [0, 1])."""


@dataclass
class ThresholdNoiseSchema(NoiseSchema):
    """A thresholded analogue skin (``encoder=coverage``): each taxel's signal is its covered area in mm^2
    (coverage fraction x taxel area), plus crosstalk from its neighbours, white read noise and a drifting
    baseline (AR(1) per taxel), read "on" when it exceeds ``threshold_mm2``. An untouched taxel reads on with
    probability ``P(N(0, sigma_mm2^2 + drift_sigma_mm2^2) > threshold_mm2)`` per frame, at every taxel size; a
    touched taxel with covered area a reads off with probability ``P(N(0, ...) < threshold_mm2 - a)``: small
    taxels, with a small covered area per contact, read off more often at the same noise."""

    _target_: str = "sphri.noise.components.ThresholdNoise"
    sigma_mm2: float = setting(2.0, lo=0.0, hi=1e6)
    """White read noise per taxel and frame, standard deviation in mm^2 of equivalent covered area
    (assumption: no measured value for a given skin; set it from the skin's datasheet or a bench test)."""
    threshold_mm2: float = setting(10.0, lo=0.0, hi=1e6)
    """Covered area (mm^2) at which a taxel reads on (assumption: 10 mm^2, about 6 % of the built-in hand's 1.7 cm^2 fingertip patch)."""
    crosstalk: float = setting(0.0, lo=0.0, hi=1.0)
    """Fraction (0-1) of each taxel's signal that appears on each neighbour (the neighbours of
    ``noise=crosstalk``), before the read noise (assumption; 0 = none)."""
    drift_sigma_mm2: float = setting(0.0, lo=0.0, hi=1e6)
    """Standard deviation (mm^2) of the baseline drift, a stationary AR(1) per taxel and trial (0 = none)."""
    drift_tau_ms: float = setting(500.0, lo=1e-3, hi=1e7)
    """Time constant of the baseline drift (ms): successive frames dt apart correlate by exp(-dt / tau)
    (assumption)."""


@dataclass
class NoNoiseSchema(NoiseSchema):
    """No noise: readings pass through unchanged."""

    _target_: str = "sphri.noise.components.NoNoise"


store(group="noise", name="salt_pepper_schema", node=SaltPepperNoiseSchema)
store(group="noise", name="gaussian_schema", node=GaussianNoiseSchema)
store(group="noise", name="dead_taxels_schema", node=DeadTaxelsNoiseSchema)
store(group="noise", name="crosstalk_schema", node=CrosstalkNoiseSchema)
store(group="noise", name="threshold_schema", node=ThresholdNoiseSchema)
store(group="noise", name="none_schema", node=NoNoiseSchema)
