"""Config schemas of the ``model`` group (``conf/model/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import require, require_choice, require_range, runtime_setting, store


@dataclass
class RandomForestSchema:
    """``model=rf``: Random Forest on the 32 touch features."""

    _target_: str = "sphri.models.rf.RandomForest"
    n_estimators: int = 100
    """Number of trees."""
    max_depth: int | None = None
    """Maximum tree depth (None: grow until leaves are pure)."""
    min_samples_leaf: int = 1
    """Minimum trials in a leaf."""
    max_features: str = "sqrt"
    """Features tried per split: "sqrt", "log2" (of 32)."""
    class_weight: str | None = None
    """None, "balanced" or "balanced_subsample"."""
    n_jobs: int = runtime_setting(-1)
    """Threads for the forest (-1: all the cores the CV leaves it)."""
    seed: int = 0
    """Random state of the forest."""
    active_threshold: float = 0.5
    """Readings at or above this count as contact (binary skins: 1)."""

    def __post_init__(self) -> None:
        require_range("model.n_estimators", self.n_estimators, lo=1)
        if self.max_depth is not None:
            require_range("model.max_depth", self.max_depth, lo=1)
        require_range("model.min_samples_leaf", self.min_samples_leaf, lo=1)
        require_choice("model.max_features", self.max_features, ["sqrt", "log2"])
        require_choice("model.class_weight", self.class_weight, [None, "balanced", "balanced_subsample"])
        require(self.n_jobs == -1 or self.n_jobs >= 1, "model.n_jobs", self.n_jobs, "-1 (all cores) or >= 1")
        require_range("model.seed", self.seed, lo=0)
        require_range("model.active_threshold", self.active_threshold, lo=0.0, hi=1.0, lo_open=True)


@dataclass
class CnnGruSchema:
    """``model=cnn_gru``: per-frame CNN (or MLP), GRU, linear classifier."""

    _target_: str = "sphri.models.cnn_gru.CnnGru"
    max_epochs: int = 20
    """Upper bound on training epochs (early stopping usually ends sooner)."""
    batch_size: int = 32
    """Trials per optimisation step."""
    lr: float = 1e-3
    """AdamW learning rate."""
    weight_decay: float = 1e-2
    """AdamW weight decay."""
    patience: int = 4
    """Epochs without validation-loss improvement before stopping."""
    schedule: str = "constant"
    """Learning rate over training: "constant" (``lr`` throughout) or "onecycle" (warm-up to ``lr``, cosine to ~0 at ``max_epochs``)."""
    dedupe_frames: bool = False
    """Embed each distinct frame of a batch once (same predictions to float rounding; fewer convolutions)."""
    val_fraction: float = 0.15
    """Share of training participants held out for early stopping (0: none)."""
    min_val_participants: int = 3
    """Early stopping needs at least this many held-out participants: with fewer (a small study: 6
    participants leave 5 to train on, of which 15 % is one person) it would stop on one person's
    validation loss, which kept an almost untrained model (macro-F1 0.111, below chance, at 6
    participants x 10 repetitions, res 18; 0.324 training all 20 epochs: issue 31). Then the model
    trains all ``max_epochs`` epochs without a validation split and a warning says so. The paper's 18
    participants give 3 (17 x 0.15, rounded): unchanged. 1: split whatever the size."""
    hidden: int = 128
    """GRU hidden units."""
    channels: list[int] = field(default_factory=lambda: [16, 32, 64])
    """Output channels of the 3x3 convolutions (widths of the MLP on non-grid layouts)."""
    strides: list[int] = field(default_factory=lambda: [2, 2, 1])
    """Stride of each convolution (2 halves the grid; 1 x 1 stays 1 x 1)."""
    embed_size: int = 2
    """Side of the adaptive average pooling: frame embedding = channels[-1] x embed_size^2."""
    device: str = "auto"
    """"auto" (CUDA when torch sees a GPU, else the CPU; the device used is recorded in MLflow,
    ``run.device``), "cpu", "cuda" or "cuda:K"."""
    precision: str = "auto"
    """"float32", "bf16" (bfloat16 autocast, ~1.8x faster where native) or "auto" (bf16 where native)."""
    seed: int = 0
    """Seeds weights, batch order and the validation split."""
    threads: int = runtime_setting(0)
    """Torch CPU threads (0: as set by the caller, e.g. the CV's per-worker share)."""

    def __post_init__(self) -> None:
        require_range("model.max_epochs", self.max_epochs, lo=1)
        require_range("model.batch_size", self.batch_size, lo=1)
        require_range("model.lr", self.lr, lo=0.0, lo_open=True)
        require_range("model.weight_decay", self.weight_decay, lo=0.0)
        require_range("model.patience", self.patience, lo=1)
        require_choice("model.schedule", self.schedule, ["constant", "onecycle"])
        require_range("model.val_fraction", self.val_fraction, lo=0.0, hi=1.0, hi_open=True)
        require_range("model.min_val_participants", self.min_val_participants, lo=1)
        require_range("model.hidden", self.hidden, lo=1)
        require(
            len(self.channels) >= 1 and all(c >= 1 for c in self.channels),
            "model.channels",
            list(self.channels),
            "at least one positive width",
        )
        require(
            len(self.strides) == len(self.channels) and all(s >= 1 for s in self.strides),
            "model.strides",
            list(self.strides),
            f"one stride >= 1 per channel entry ({len(self.channels)})",
        )
        require_range("model.embed_size", self.embed_size, lo=1)
        require(
            self.device in ("auto", "cpu", "cuda") or self.device.startswith("cuda:"),
            "model.device",
            self.device,
            "auto, cpu, cuda or cuda:K",
        )
        require_choice("model.precision", self.precision, ["auto", "float32", "bf16"])
        require_range("model.seed", self.seed, lo=0)
        require_range("model.threads", self.threads, lo=0)


store(group="model", name="rf_schema", node=RandomForestSchema)
store(group="model", name="cnn_gru_schema", node=CnnGruSchema)
