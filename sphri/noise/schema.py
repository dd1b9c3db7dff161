"""Config schemas of the noise group (``conf/noise/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require_choice, require_range, store


@dataclass
class SaltPepperNoiseSchema:
    """Salt-and-pepper: independent per-taxel read errors; with probability p per taxel and frame a
    reading is replaced by 1 (salt) or 0 (pepper). An untouched skin of N taxels shows on average
    ``p * salt_vs_pepper * N`` false taxels per frame in replace mode (``p * N`` in flip mode)."""

    _target_: str = "sphri.noise.components.SaltPepperNoise"
    p: float = 0.02
    """Probability that a taxel reading is corrupted, per taxel and per frame (paper: 0.02; applied to
    every slot of the model's window, padded slots included)."""
    mode: str = "replace"
    """replace: set to a random 0/1 (half the corruptions leave a reading as it was); flip: invert it."""
    salt_vs_pepper: float = 0.5
    """replace mode: probability that a corrupted reading becomes 1."""

    def __post_init__(self) -> None:
        require_range("noise.p", self.p, lo=0.0, hi=1.0)
        require_choice("noise.mode", self.mode, ("replace", "flip"))
        require_range("noise.salt_vs_pepper", self.salt_vs_pepper, lo=0.0, hi=1.0)


@dataclass
class GaussianNoiseSchema:
    """Analogue read noise: additive N(0, sigma^2) per taxel and frame, clipped to [0, 1] (float32 readings)."""

    _target_: str = "sphri.noise.components.GaussianNoise"
    sigma: float = 0.05
    """Standard deviation of the added noise (reading units, 1 = full scale)."""

    def __post_init__(self) -> None:
        require_range("noise.sigma", self.sigma, lo=0.0, hi=10.0)


@dataclass
class DeadTaxelsNoiseSchema:
    """Broken taxels: a fixed fraction of the N taxels always reads ``value`` (same sensor in every trial);
    stuck-on taxels (value 1) are ``round(fraction * N)`` false taxels in every frame."""

    _target_: str = "sphri.noise.components.DeadTaxelsNoise"
    fraction: float = 0.05
    """Fraction of the N taxels that are dead (round(fraction * N) of them, chosen by seed only)."""
    value: float = 0.0
    """What a dead taxel reads (0 = silent, 1 = stuck on)."""

    def __post_init__(self) -> None:
        require_range("noise.fraction", self.fraction, lo=0.0, hi=1.0)
        require_range("noise.value", self.value, lo=0.0, hi=1.0)


@dataclass
class CrosstalkNoiseSchema:
    """Crosstalk: neighbour coupling; ``alpha`` of each reading appears on each neighbouring taxel
    (float32). Nothing appears on an untouched skin (0 false taxels per frame at any N)."""

    _target_: str = "sphri.noise.components.CrosstalkNoise"
    alpha: float = 0.1
    """Coupling coefficient: fraction (0-1) of a taxel's reading added to each neighbour (result clipped to [0, 1])."""

    def __post_init__(self) -> None:
        require_range("noise.alpha", self.alpha, lo=0.0, hi=1.0)


@dataclass
class NoNoiseSchema:
    """No noise: readings pass through unchanged."""

    _target_: str = "sphri.noise.components.NoNoise"


store(group="noise", name="salt_pepper_schema", node=SaltPepperNoiseSchema)
store(group="noise", name="gaussian_schema", node=GaussianNoiseSchema)
store(group="noise", name="dead_taxels_schema", node=DeadTaxelsNoiseSchema)
store(group="noise", name="crosstalk_schema", node=CrosstalkNoiseSchema)
store(group="noise", name="none_schema", node=NoNoiseSchema)
