"""Config schemas of the ``model`` group (``conf/model/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import ComponentSchema, require, setting, store


@dataclass
class ModelSchema(ComponentSchema, group="model"):
    """Base of the model group's schemas."""


@dataclass
class RandomForestSchema(ModelSchema):
    """``model=rf``: Random Forest on the 32 touch features."""

    _target_: str = "sphri.models.rf.RandomForest"
    n_estimators: int = setting(100, lo=1)
    """Number of trees."""
    max_depth: int | None = setting(None, lo=1, optional=True)
    """Maximum tree depth (None: grow until leaves are pure)."""
    min_samples_leaf: int = setting(1, lo=1)
    """Minimum trials in a leaf."""
    max_features: str = setting("sqrt", choices=["sqrt", "log2"])
    """Features tried per split: "sqrt", "log2" (of 32)."""
    class_weight: str | None = setting(None, choices=[None, "balanced", "balanced_subsample"])
    """None, "balanced" or "balanced_subsample"."""
    n_jobs: int = setting(-1, runtime=True)
    """Threads for the forest (-1: all the cores the CV leaves it)."""
    seed: int = setting(0, lo=0)
    """Random state of the forest."""
    active_threshold: float = setting(0.5, lo=0.0, hi=1.0, lo_open=True)
    """Readings at or above this count as contact (binary skins: 1)."""

    def check(self) -> None:
        require(self.n_jobs == -1 or self.n_jobs >= 1, self.key("n_jobs"), self.n_jobs, "-1 (all cores) or >= 1")


@dataclass
class CnnGruSchema(ModelSchema):
    """``model=cnn_gru``: per-frame CNN (or MLP), GRU, linear classifier."""

    _target_: str = "sphri.models.cnn_gru.CnnGru"
    max_epochs: int = setting(20, lo=1)
    """Upper bound on training epochs (early stopping usually ends sooner)."""
    batch_size: int = setting(32, lo=1)
    """Trials per optimisation step."""
    lr: float = setting(1e-3, lo=0.0, lo_open=True)
    """AdamW learning rate."""
    weight_decay: float = setting(1e-2, lo=0.0)
    """AdamW weight decay."""
    patience: int = setting(4, lo=1)
    """Epochs without validation-loss improvement before stopping."""
    schedule: str = setting("constant", choices=["constant", "onecycle"])
    """Learning rate over training: "constant" (``lr`` throughout) or "onecycle" (warm-up to ``lr``, cosine to ~0 at ``max_epochs``)."""
    dedupe_frames: bool = False
    """Embed each distinct frame of a batch once (same predictions to float rounding; fewer convolutions)."""
    val_fraction: float = setting(0.15, lo=0.0, hi=1.0, hi_open=True)
    """Share of training participants held out for early stopping (0: none)."""
    min_val_participants: int = setting(3, lo=1)
    """Early stopping needs at least this many held-out participants: with fewer (a small study: 6
    participants leave 5 to train on, of which 15 % is one person) it would stop on one person's
    validation loss, which kept an almost untrained model (macro-F1 0.111, below chance, at 6
    participants x 10 repetitions, res 18; 0.324 training all 20 epochs). Then the model
    trains all ``max_epochs`` epochs without a validation split and a warning says so. The paper's 18
    participants give 3 (17 x 0.15, rounded): unchanged. 1: split whatever the size."""
    hidden: int = setting(128, lo=1)
    """GRU hidden units."""
    channels: list[int] = field(default_factory=lambda: [16, 32, 64])
    """Output channels of the 3x3 convolutions (widths of the MLP on non-grid layouts)."""
    strides: list[int] = field(default_factory=lambda: [2, 2, 1])
    """Stride of each convolution (2 halves the grid; 1 x 1 stays 1 x 1)."""
    embed_size: int = setting(2, lo=1)
    """Side of the adaptive average pooling: frame embedding = channels[-1] x embed_size^2."""
    device: str = "auto"
    """"auto" (CUDA when torch sees a GPU, else the CPU; the device used is recorded in MLflow,
    ``run.device``), "cpu", "cuda" or "cuda:K"."""
    precision: str = setting("auto", choices=["auto", "float32", "bf16"])
    """"float32", "bf16" (bfloat16 autocast, faster where the CPU has native bf16: ``bench/bf16_parity.py``) or "auto": bf16 where native and
    no stride-2 convolution sees a side of at most 2 taxels (oneDNN's bf16 kernels are wrong there), else
    float32; a non-finite loss under auto's bf16 retrains in float32. The choice and why are recorded on
    the MLflow run (``run.precision``, ``run.precision_reason``)."""
    seed: int = setting(0, lo=0)
    """Seeds weights, batch order and the validation split."""
    threads: int = setting(0, runtime=True, lo=0)
    """Torch CPU threads (0: as set by the caller, e.g. the CV's per-worker share)."""

    def check(self) -> None:
        require(
            len(self.channels) >= 1 and all(c >= 1 for c in self.channels),
            self.key("channels"),
            list(self.channels),
            "at least one positive width",
        )
        require(
            len(self.strides) == len(self.channels) and all(s >= 1 for s in self.strides),
            self.key("strides"),
            list(self.strides),
            f"one stride >= 1 per channel entry ({len(self.channels)})",
        )
        require(
            self.device in ("auto", "cpu", "cuda") or self.device.startswith("cuda:"),
            self.key("device"),
            self.device,
            "auto, cpu, cuda or cuda:K",
        )


store(group="model", name="rf_schema", node=RandomForestSchema)
store(group="model", name="cnn_gru_schema", node=CnnGruSchema)
