"""``model=cnn_gru``: a per-frame CNN, a GRU over time and a linear classifier.

Each frame (H x W grid) goes through three 3x3 convolutions with ReLU
(channels 16, 32, 64 by default, strides 2, 2, 1 for speed; zero padding 1
along u, circular along v when v wraps, so every size from 1 x 1 works),
then adaptive average pooling to ``embed_size`` x ``embed_size``; the frame
embeddings of a window feed a single-layer GRU (128 hidden units) whose last
hidden state a linear layer maps to gesture logits. Layouts that are not
grids use a per-frame MLP over the N taxels instead of the CNN. All frames
of a batch go through the encoder at once, as (B * L, 1, H, W).

Training: AdamW, cross-entropy, early stopping on a validation split of the
training data (whole participants when ``groups`` are given), best epoch
restored. Inputs are standardised with the mean and standard deviation of
the training split only. Deterministic for a seed on a given CPU.

``precision="bf16"`` runs the network under bfloat16 autocast (less CPU per
step on CPUs with native bf16, AVX512-BF16 or AMX: 1.45x at res 18 on an AMX
Xeon, docs/BENCHMARKS.md; slow on CPUs without it). ``"auto"`` (default)
picks bf16 only where it is native *and* the network has no degenerate
stride-2 convolution (:func:`bf16_hazard`; its accuracy equivalent to float32's by the rule
of ``bench/bf16_parity.py`` on an AMD EPYC and an AMX Xeon), else float32. oneDNN 3.12 (torch 2.13.0's CPU build) computes wrong or NaN weight
gradients for a bf16 stride-2 convolution over an input 1 wide with zero
padding inside the convolution (AVX512-BF16 and AMX kernels), and, on AMX,
wrong or NaN outputs for stride 2 over an input 1 or 2 wide and 9 or more
long, whatever the padding; float32 and stride 1 are clean. So the padding
along v is always explicit (zeros, or circular when v wraps) and the
convolution pads along u only (no wrong weight gradient in 100 calls on an
AMX CPU), and a grid whose stride-2 convolutions see a side of at most 2
taxels trains in float32 under ``auto``: on an AMX CPU that rule covered
every one of the 22 grids (of 302 probed) the default network computed wrong
in bf16 (``bench/bf16_grid_sweep.py``; docs/BENCHMARKS.md).

Training stops on the first non-finite loss or gradient. Under ``auto`` with
bf16 chosen, the model is retrained from the start in float32 and the reason
is kept (``runtime_``, recorded on the MLflow run as ``run.precision_reason``);
with a precision the user chose it is a :class:`sphri.finite.NonFiniteError`
naming the epoch, the precision and the grid. ``predict_proba`` refuses
non-finite probabilities. ``runtime_`` records the device, the precision and
why after ``fit``, and the allocator setting the process trained with: ``fit``
sets glibc's allocator to keep freed memory (:mod:`sphri.models.allocator`;
the same numbers, about 1.2x less CPU per training step at res 18).
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from sphri.finite import NonFiniteError, require_finite
from sphri.models.allocator import keep_freed_memory
from sphri.models.features import check_windows
from sphri.types import TaxelGeometry


def adaptive_pool_matrix(h: int, w: int, size: int) -> torch.Tensor:
    """(h * w, size * size) float32 matrix doing ``adaptive_avg_pool2d(., size)`` as a product.

    Same bins as torch (start floor(i n / size), end ceil((i + 1) n / size));
    a matrix product is much faster than the pooling kernel's backward on CPU.
    """

    def axis(n: int) -> torch.Tensor:
        m = torch.zeros(n, size)
        for i in range(size):
            lo, hi = (i * n) // size, -((-(i + 1) * n) // size)
            m[lo:hi, i] = 1.0 / (hi - lo)
        return m

    return torch.einsum("ai,bj->abij", axis(h), axis(w)).reshape(h * w, size * size)


class CircularPadV(torch.autograd.Function):
    """Circular pad of 1 along the last axis (v): ``cat([x[..., -1:], x, x[..., :1]])``.

    The backward folds the two pad columns' gradients back onto the columns they copy (last and first)
    instead of scattering three slices into zero tensors and summing them: the same gradients as
    ``F.pad(x, (1, 1, 0, 0), mode="circular")`` (tests/models/test_cnn_gru_pad.py), less memory traffic.
    """

    @staticmethod
    def forward(ctx, x: torch.Tensor) -> torch.Tensor:
        return torch.cat([x[..., -1:], x, x[..., :1]], dim=-1)

    @staticmethod
    def backward(ctx, g: torch.Tensor) -> torch.Tensor:
        grad = g[..., 1:-1].clone()
        grad[..., :1] += g[..., -1:]  # this order (right pad, then left) sums a 1-wide v as autograd does
        grad[..., -1:] += g[..., :1]
        return grad


class GridEncoder(nn.Module):
    """(B, 1, H, W) frames -> (B, channels[-1] * embed_size^2) embeddings.

    3x3 convolutions with ReLU; padding 1 with zeros along H (u) inside the convolution, and along W (v)
    explicit before it: circular when ``wrap_v``, zeros otherwise (never inside the convolution: see the
    module doc), so any H, W >= 1 works.
    """

    pool: torch.Tensor  # buffer (H*W, embed_size^2), registered in __init__

    def __init__(
        self, grid_shape: tuple[int, int], channels: list[int], strides: list[int], wrap_v: bool, embed_size: int
    ):
        super().__init__()
        cin = 1
        h, w = grid_shape
        self.convs = nn.ModuleList()
        for c, s in zip(channels, strides):
            # zero padding along u inside the conv; along v explicit in forward (circular or zeros)
            self.convs.append(nn.Conv2d(cin, c, kernel_size=3, stride=s, padding=(1, 0)))
            h, w = (h - 1) // s + 1, (w - 1) // s + 1
            cin = c
        self.wrap_v = wrap_v
        self.embed_size = embed_size
        self.out_dim = cin * embed_size * embed_size
        self.register_buffer("pool", adaptive_pool_matrix(h, w, embed_size), persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for conv in self.convs:
            if self.wrap_v:  # circular pad of 1 along v (backward: the pad columns folded back)
                x = CircularPadV.apply(x)
            else:  # zeros along v outside the convolution (oneDNN's bf16 defect: module doc)
                x = F.pad(x, (1, 1))
            x = F.relu(conv(x))
        return (x.flatten(2) @ self.pool).flatten(1)


class MlpEncoder(nn.Module):
    """(B, N) frames of a non-grid layout -> (B, widths[-1]) embeddings."""

    def __init__(self, n_taxels: int, widths: list[int]):
        super().__init__()
        layers: list[nn.Module] = []
        cin = n_taxels
        for c in widths:
            layers += [nn.Linear(cin, c), nn.ReLU()]
            cin = c
        self.net = nn.Sequential(*layers)
        self.out_dim = cin

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class CnnGruNet(nn.Module):
    """Windows (B, L, N) -> logits (B, n_classes)."""

    x_mean: torch.Tensor  # buffers (scalars), registered in __init__, set by CnnGru.fit
    x_std: torch.Tensor

    def __init__(
        self,
        n_taxels: int,
        grid_shape: tuple[int, int] | None,
        wrap_v: bool,
        channels: list[int],
        strides: list[int],
        embed_size: int,
        hidden: int,
        n_classes: int,
    ):
        super().__init__()
        self.grid_shape = grid_shape
        if grid_shape is not None:
            self.encoder: nn.Module = GridEncoder(grid_shape, channels, strides, wrap_v, embed_size)
        else:
            self.encoder = MlpEncoder(n_taxels, channels)
        self.gru = nn.GRU(self.encoder.out_dim, hidden, num_layers=1, batch_first=True)
        self.head = nn.Linear(hidden, n_classes)
        self.register_buffer("x_mean", torch.zeros(()))
        self.register_buffer("x_std", torch.ones(()))

    def embed(self, frames: torch.Tensor) -> torch.Tensor:
        """(F, N) raw frames (any real dtype) -> (F, D) embeddings."""
        frames = (frames.float() - self.x_mean) / self.x_std
        if self.grid_shape is not None:
            frames = frames.reshape(frames.shape[0], 1, *self.grid_shape)
        return self.encoder(frames)

    def classify(self, emb: torch.Tensor) -> torch.Tensor:
        """(B, L, D) frame embeddings -> (B, n_classes) logits."""
        _, h = self.gru(emb)
        return self.head(h[-1])

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, length, n = x.shape
        return self.classify(self.embed(x.reshape(b * length, n)).reshape(b, length, -1))

    def forward_ids(self, table: torch.Tensor, ids: torch.Tensor) -> torch.Tensor:
        """Logits of windows given as frame ids (B, L) into a table of distinct frames (U, N).

        Each distinct frame of the batch goes through the encoder once; the
        same logits as ``forward(table[ids])`` up to float rounding.
        """
        b, length = ids.shape
        uniq, inv = torch.unique(ids, return_inverse=True)
        emb = self.embed(table[uniq])
        return self.classify(emb[inv.reshape(-1)].reshape(b, length, -1))


def unique_frames(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Windows (n, L, N) -> (table (U, N) of distinct frames, ids (n, L) int64 into it)."""
    n, length, taxels = x.shape
    flat = np.ascontiguousarray(x.reshape(n * length, taxels))
    rows = flat.view(np.dtype((np.void, flat.dtype.itemsize * taxels))).ravel()
    _, first, inv = np.unique(rows, return_index=True, return_inverse=True)
    return flat[first], inv.reshape(n, length).astype(np.int64)


def compact(x: np.ndarray) -> np.ndarray:
    """``x`` as uint8 when every value is an integer in 0..255 (binary skins), else unchanged."""
    if x.size and x.dtype != np.uint8:
        xu = x.astype(np.uint8)
        if np.array_equal(xu, x):
            return xu
    return x


@contextmanager
def _torch_state(threads: int, device: torch.device) -> Iterator[None]:
    """Set thread count and deterministic algorithms for a block; restore after."""
    prev_threads = torch.get_num_threads()
    prev_det = torch.are_deterministic_algorithms_enabled()
    prev_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    try:
        if threads > 0:
            torch.set_num_threads(threads)
        # on CUDA some kernels (adaptive pooling backward) have no
        # deterministic version: warn instead of failing there.
        torch.use_deterministic_algorithms(True, warn_only=device.type != "cpu")
        yield
    finally:
        torch.use_deterministic_algorithms(prev_det, warn_only=prev_warn)
        torch.set_num_threads(prev_threads)


def resolve_device(device: str) -> torch.device:
    """``"auto"`` (CUDA when available, else the CPU), ``"cpu"``, ``"cuda"`` or ``"cuda:K"`` -> torch.device;
    clear error when CUDA is asked for and absent."""
    if device == "auto":
        return torch.device("cuda") if torch.cuda.is_available() else torch.device("cpu")
    if device == "cpu":
        return torch.device("cpu")
    if device == "cuda" or device.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise RuntimeError(
                f"model.device={device!r} but CUDA is not available to this torch "
                f"({torch.__version__}); use model.device=cpu"
            )
        dev = torch.device(device)
        if dev.index is not None and dev.index >= torch.cuda.device_count():
            raise RuntimeError(f"model.device={device!r} but only {torch.cuda.device_count()} CUDA device(s) exist")
        return dev
    raise ValueError(f"model.device={device!r} is invalid: allowed values: auto, cpu, cuda, cuda:K")


log = logging.getLogger(__name__)

#: Allowed values of ``schedule``: constant lr, or one-cycle (warm-up to ``lr``, cosine down to ~0).
SCHEDULES: tuple[str, ...] = ("constant", "onecycle")

#: Warnings already given in this process (the folds of a job share one).
_WARNED: set[str] = set()

#: Allowed values of ``precision``.
PRECISIONS: tuple[str, ...] = ("auto", "float32", "bf16")


def native_bf16(device: torch.device) -> bool:
    """Whether ``device`` computes bfloat16 natively (CPU: AVX512-BF16 or AMX; CUDA: bf16 support)."""
    if device.type == "cuda":
        return bool(torch.cuda.is_bf16_supported())
    if device.type == "cpu":
        cpu = torch.cpu
        checks = [getattr(cpu, "_is_avx512_bf16_supported", None), getattr(cpu, "_is_amx_tile_supported", None)]
        return any(bool(f()) for f in checks if f is not None)
    return False


def conv_inputs(grid_shape: tuple[int, int], strides: list[int] | tuple[int, ...]) -> list[tuple[int, int, int]]:
    """(H, W, stride) of the input each convolution of a :class:`GridEncoder` sees, before padding."""
    h, w = grid_shape
    out = []
    for s in strides:
        out.append((h, w, int(s)))
        h, w = (h - 1) // int(s) + 1, (w - 1) // int(s) + 1
    return out


def bf16_hazard(grid_shape: tuple[int, int] | None, strides: list[int] | tuple[int, ...]) -> str | None:
    """Why bf16 is not known to be safe for this network on a CPU, or None.

    A stride-2 (or larger) convolution over an input with a side of at most 2 taxels is the shape
    class in which oneDNN's bf16 kernels were measured wrong (module doc). Non-grid layouts (the MLP)
    have no convolution."""
    if grid_shape is None:
        return None
    for i, (h, w, s) in enumerate(conv_inputs(grid_shape, strides), 1):
        if s >= 2 and min(h, w) <= 2:
            return f"convolution {i} has stride {s} over a {h} x {w} input (a side of at most 2 taxels)"
    return None


def choose_precision(
    precision: str,
    device: torch.device,
    grid_shape: tuple[int, int] | None = None,
    strides: list[int] | tuple[int, ...] = (),
) -> tuple[str, str]:
    """(precision, why) for a network of ``grid_shape`` and ``strides`` on ``device``.

    ``"auto"`` is bf16 only where :func:`native_bf16` and, on a CPU, no :func:`bf16_hazard`; an explicit
    ``"float32"`` or ``"bf16"`` is kept as the user's choice."""
    if precision != "auto":
        return precision, "chosen (model.precision)"
    if not native_bf16(device):
        return "float32", f"auto: {device.type} without native bf16"
    hazard = bf16_hazard(grid_shape, strides) if device.type == "cpu" else None
    if hazard is not None:
        return "float32", f"auto: {hazard}, where oneDNN's bf16 kernels are not known to be right"
    return "bf16", f"auto: native bf16 on {device.type}"


def resolve_precision(
    precision: str,
    device: torch.device,
    grid_shape: tuple[int, int] | None = None,
    strides: list[int] | tuple[int, ...] = (),
) -> str:
    """The precision of :func:`choose_precision` (without the reason)."""
    return choose_precision(precision, device, grid_shape, strides)[0]


def validation_split(
    y: np.ndarray, groups: np.ndarray | None, fraction: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Indices (train, val) of a held-out split of the training data.

    With ``groups``: whole groups (participants) go to validation, about
    ``fraction`` of them (at least one, never all). Without: a stratified
    random split (each class with >= 2 trials contributes). ``fraction`` 0
    gives an empty validation set.
    """
    n = y.shape[0]
    idx = np.arange(n)
    if fraction <= 0 or n < 2:
        return idx, idx[:0]
    rng = np.random.default_rng(seed)
    if groups is not None:
        groups = np.asarray(groups)
        if groups.shape != (n,):
            raise ValueError(f"groups must be (n_trials,) = ({n},), got shape {groups.shape}")
        uniq = np.unique(groups)
        if uniq.size >= 2:
            k = min(uniq.size - 1, max(1, int(round(fraction * uniq.size))))
            val_groups = rng.choice(uniq, size=k, replace=False)
            is_val = np.isin(groups, val_groups)
            return idx[~is_val], idx[is_val]
    is_val = np.zeros(n, dtype=bool)
    for c in np.unique(y):
        members = idx[y == c]
        if members.size < 2:
            continue
        k = min(members.size - 1, max(1, int(round(fraction * members.size))))
        is_val[rng.choice(members, size=k, replace=False)] = True
    return idx[~is_val], idx[is_val]


def _standardize(net: CnnGruNet, x: np.ndarray, tr: np.ndarray) -> None:
    """Set the network's input mean and standard deviation to those of the training windows ``x[tr]`` (an SD
    under 1e-6, or a single value, gives 1)."""
    x_tr_np = x[tr]
    mean = float(x_tr_np.mean(dtype=np.float64))
    std = float(x_tr_np.astype(np.float64).std(ddof=1)) if x_tr_np.size > 1 else 1.0
    del x_tr_np
    net.x_mean.fill_(mean)
    net.x_std.fill_(std if std > 1e-6 else 1.0)


@dataclass
class _TrainRun:
    """One training run: the network and its trainable parameters, optimizer, learning-rate schedule (or
    None), batch-order generator, device, precision, frame table (or None), training and validation inputs
    and labels, and whether there is a validation split."""

    net: CnnGruNet
    params: list[torch.Tensor]
    opt: torch.optim.AdamW
    sched: torch.optim.lr_scheduler.OneCycleLR | None
    gen: torch.Generator
    dev: torch.device
    precision: str
    table: torch.Tensor | None
    x_tr: torch.Tensor
    y_tr: torch.Tensor
    x_va: torch.Tensor
    y_va: torch.Tensor
    has_val: bool


class CnnGru(ClassifierMixin, BaseEstimator):
    """CNN-GRU gesture classifier on windows (n_trials, L, N_taxels).

    Hyperparameters: ``CnnGruSchema`` (``sphri show model=cnn_gru``). ``geometry`` gives the
    grid shape and wrap (None: a per-frame MLP over the N taxels).
    ``fit(x, y, groups=None)``: ``groups`` (participants of the training
    trials) make the early-stopping split group-wise. After ``fit``:
    ``classes_``, ``net_``, ``history_`` (per epoch: train loss, validation
    loss and accuracy), ``best_epoch_``.
    """

    NAME = "cnn_gru"
    VERSION = "4"

    def __init__(
        self,
        max_epochs: int = 20,
        batch_size: int = 32,
        lr: float = 1e-3,
        weight_decay: float = 1e-2,
        patience: int = 4,
        schedule: str = "constant",
        dedupe_frames: bool = False,
        val_fraction: float = 0.15,
        min_val_participants: int = 3,
        hidden: int = 128,
        channels: tuple[int, ...] | list[int] = (16, 32, 64),
        strides: tuple[int, ...] | list[int] = (2, 2, 1),
        embed_size: int = 2,
        device: str = "auto",
        precision: str = "auto",
        seed: int = 0,
        threads: int = 0,
        geometry: TaxelGeometry | None = None,
    ):
        self.max_epochs = max_epochs
        self.batch_size = batch_size
        self.lr = lr
        self.weight_decay = weight_decay
        self.patience = patience
        self.schedule = schedule
        self.dedupe_frames = dedupe_frames
        self.val_fraction = val_fraction
        self.min_val_participants = min_val_participants
        self.hidden = hidden
        self.channels = channels
        self.strides = strides
        self.embed_size = embed_size
        self.device = device
        self.precision = precision
        self.seed = seed
        self.threads = threads
        self.geometry = geometry

    # -- helpers -----------------------------------------------------------
    def _check_params(self) -> None:
        if len(self.channels) < 1 or any(int(c) < 1 for c in self.channels):
            raise ValueError(f"model.channels={list(self.channels)} is invalid: positive widths, at least one")
        if len(self.strides) != len(self.channels) or any(int(s) < 1 for s in self.strides):
            raise ValueError(
                f"model.strides={list(self.strides)} is invalid: one positive stride per channel entry "
                f"({len(self.channels)})"
            )
        for key in ("max_epochs", "batch_size", "hidden", "embed_size"):
            if int(getattr(self, key)) < 1:
                raise ValueError(f"model.{key}={getattr(self, key)!r} is invalid: must be >= 1")
        if self.schedule not in SCHEDULES:
            raise ValueError(f"model.schedule={self.schedule!r} is invalid: allowed values: {list(SCHEDULES)}")
        if self.precision not in PRECISIONS:
            raise ValueError(f"model.precision={self.precision!r} is invalid: allowed values: {list(PRECISIONS)}")
        if not 0.0 <= self.val_fraction < 1.0:
            raise ValueError(f"model.val_fraction={self.val_fraction!r} is invalid: must be in [0, 1)")

    def early_stopping_fraction(self, groups: np.ndarray | None) -> float:
        """``val_fraction``, or 0 (no validation split, all epochs) when the participants it would hold
        out number fewer than ``min_val_participants`` (warned: a split that small cannot steer training)."""
        if groups is None or self.val_fraction <= 0:
            return float(self.val_fraction)
        n = np.unique(np.asarray(groups)).size
        k = min(n - 1, max(1, int(round(self.val_fraction * n)))) if n >= 2 else 0
        if k < int(self.min_val_participants):
            message = (
                f"CNN-GRU: early stopping would hold out {k} of {n} training participants (fewer than "
                f"model.min_val_participants={int(self.min_val_participants)}): training all "
                f"{int(self.max_epochs)} epochs without a validation split"
            )
            if message not in _WARNED:  # once per process, not once per fold
                _WARNED.add(message)
                log.warning(message)
            return 0.0
        return float(self.val_fraction)

    def _layout(self, n_taxels: int) -> tuple[tuple[int, int] | None, bool]:
        g = self.geometry
        if g is None:
            return None, False
        if g.n_taxels != n_taxels:
            raise ValueError(f"x has {n_taxels} taxels per frame but the geometry has {g.n_taxels}")
        if g.grid_shape is None:
            return None, False
        h, w = int(g.grid_shape[0]), int(g.grid_shape[1])
        if h * w != n_taxels:
            raise ValueError(f"geometry.grid_shape={g.grid_shape} does not hold {n_taxels} taxels")
        return (h, w), bool(g.wrap_v)

    def _network(self, n_taxels: int, n_classes: int) -> CnnGruNet:
        """A fresh network of these hyperparameters (for ``fit``, and for ``load_state`` to load weights into)."""
        grid, wrap = self._layout(n_taxels)
        return CnnGruNet(
            n_taxels,
            grid,
            wrap,
            [int(c) for c in self.channels],
            [int(s) for s in self.strides],
            int(self.embed_size),
            int(self.hidden),
            n_classes,
        )

    def _autocast(self, dev: torch.device, precision: str | None = None) -> torch.autocast:
        """bf16 autocast of the network's forward when the precision (default: the fitted one) is bf16."""
        use = precision or getattr(self, "precision_", None) or self._choose(dev)[0]
        return torch.autocast(device_type=dev.type, dtype=torch.bfloat16, enabled=use == "bf16")

    def _choose(self, dev: torch.device) -> tuple[str, str]:
        """(precision, why) for this model's network on ``dev`` (:func:`choose_precision`)."""
        g = self.geometry
        grid = (int(g.grid_shape[0]), int(g.grid_shape[1])) if g is not None and g.grid_shape is not None else None
        return choose_precision(self.precision, dev, grid, [int(s) for s in self.strides])

    def _where(self, precision: str) -> str:
        """The network's shape and precision, for an error message."""
        g = self.geometry
        if g is None or g.grid_shape is None:
            return f"precision {precision}, MLP over the taxels"
        h, w = g.grid_shape
        return f"precision {precision}, grid {h} x {w}, {'v wraps' if g.wrap_v else 'no wrap'}"

    def _batches(self, n: int, gen: torch.Generator | None) -> list[torch.Tensor]:
        order = torch.randperm(n, generator=gen) if gen is not None else torch.arange(n)
        return list(torch.split(order, int(self.batch_size)))

    def _loss_acc(
        self,
        net: CnnGruNet,
        x: torch.Tensor,
        y: torch.Tensor,
        dev: torch.device,
        table: torch.Tensor | None = None,
        precision: str | None = None,
    ) -> tuple[float, float]:
        """Mean loss and accuracy; ``x`` windows, or frame ids (n, L) into ``table``."""
        net.eval()
        total, correct = 0.0, 0
        with torch.no_grad():
            for b in torch.split(torch.arange(x.shape[0]), 256):
                with self._autocast(dev, precision):
                    logits = self._logits(net, x[b], dev, table)
                yb = y[b].to(dev)
                total += float(F.cross_entropy(logits, yb, reduction="sum"))
                correct += int((logits.argmax(1) == yb).sum())
        return total / max(1, x.shape[0]), correct / max(1, x.shape[0])

    @staticmethod
    def _logits(net: CnnGruNet, xb: torch.Tensor, dev: torch.device, table: torch.Tensor | None) -> torch.Tensor:
        if table is None:
            return net(xb.to(dev)).float()
        return net.forward_ids(table, xb.to(dev)).float()

    def runtime(self) -> dict[str, str]:
        """The device and precision this model trains with on this machine (``device`` and ``precision``
        resolved from ``auto`` for its geometry) and why, recorded in MLflow as ``run.device``,
        ``run.precision`` and ``run.precision_reason``. After ``fit``, ``runtime_`` is what it trained with, and
        its process's allocator setting (``allocator``: :func:`sphri.models.allocator.keep_freed_memory`)."""
        dev = resolve_device(self.device)
        precision, why = self._choose(dev)
        return {"device": str(dev), "precision": precision, "precision_reason": why}

    # -- estimator API -----------------------------------------------------
    def fit(self, x: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> CnnGru:
        """Train on windows x (n, L, N) float32 and labels y (n,) int64.

        A non-finite loss or gradient stops training: under ``precision="auto"`` with bf16 chosen the
        model is retrained in float32 (``runtime_["precision_reason"]`` says so); otherwise
        :class:`~sphri.finite.NonFiniteError` names the epoch, the step, the precision and the grid."""
        self._check_params()
        x = check_windows(x)
        y = np.asarray(y)
        if y.ndim != 1 or y.shape[0] != x.shape[0]:
            raise ValueError(f"y must be (n_trials,) = ({x.shape[0]},), got shape {y.shape}")
        self._layout(x.shape[2])  # the geometry fits x (a ValueError naming both otherwise)
        dev = resolve_device(self.device)
        precision, why = self._choose(dev)
        allocator = keep_freed_memory()  # the same numbers, fewer page faults (sphri.models.allocator)
        self.classes_, y_idx = np.unique(y, return_inverse=True)
        tr, va = validation_split(y_idx, groups, self.early_stopping_fraction(groups), self.seed)
        try:
            net, history, best_epoch = self._train(x, y_idx, tr, va, dev, precision)
        except NonFiniteError as exc:
            if not (self.precision == "auto" and precision == "bf16"):
                raise
            log.warning("CNN-GRU: %s; retraining in float32", exc)
            why = f"auto: bf16 chosen, then {exc}; retrained in float32"
            precision = "float32"
            net, history, best_epoch = self._train(x, y_idx, tr, va, dev, precision)
        self.precision_ = precision
        self.runtime_ = {"device": str(dev), "precision": precision, "precision_reason": why, "allocator": allocator}
        self.net_ = net
        self.history_ = history
        self.best_epoch_ = best_epoch
        self.n_train_, self.n_val_ = int(tr.size), int(va.size)
        return self

    def _train(
        self,
        x: np.ndarray,
        y_idx: np.ndarray,
        tr: np.ndarray,
        va: np.ndarray,
        dev: torch.device,
        precision: str,
    ) -> tuple[CnnGruNet, list[dict[str, float]], int]:
        """(network at its best epoch, per-epoch history, best epoch) of one training run from the seed."""
        with _torch_state(int(self.threads), dev), torch.random.fork_rng(devices=[]):
            torch.manual_seed(self.seed)
            gen = torch.Generator().manual_seed(self.seed)
            net = self._network(x.shape[2], len(self.classes_))
            yt = torch.from_numpy(y_idx.astype(np.int64))
            _standardize(net, x, tr)
            net.to(dev)
            table, xt = self._inputs(x, dev)
            params = [p for p in net.parameters() if p.requires_grad]
            opt, sched = self._optimizer(params, tr.size)
            has_val = va.size > 0
            x_tr = xt[torch.from_numpy(tr)]
            x_va, y_va = xt[torch.from_numpy(va)], yt[torch.from_numpy(va)]
            y_tr = yt[torch.from_numpy(tr)]
            run = _TrainRun(net, params, opt, sched, gen, dev, precision, table, x_tr, y_tr, x_va, y_va, has_val)
            history, best_epoch = self._epochs(run)
        net.eval()
        return net, history, best_epoch

    def _inputs(self, x: np.ndarray, dev: torch.device) -> tuple[torch.Tensor | None, torch.Tensor]:
        """(frame table on ``dev`` or None, inputs): with ``dedupe_frames`` the distinct frames once (uint8
        while binary) and the windows as frame ids (n, L); else no table and the windows x (n, L, N)."""
        if self.dedupe_frames:
            table_np, ids = unique_frames(x)
            return torch.from_numpy(compact(table_np)).to(dev), torch.from_numpy(ids)
        return None, torch.from_numpy(np.ascontiguousarray(x))

    def _optimizer(
        self, params: list[torch.Tensor], n_train: int
    ) -> tuple[torch.optim.AdamW, torch.optim.lr_scheduler.OneCycleLR | None]:
        """(AdamW over ``params``, the one-cycle learning-rate schedule or None) for ``n_train`` training windows."""
        opt = torch.optim.AdamW(params, lr=self.lr, weight_decay=self.weight_decay)
        steps_per_epoch = math.ceil(n_train / int(self.batch_size))
        total_steps = steps_per_epoch * int(self.max_epochs)
        sched = None
        if self.schedule == "onecycle" and total_steps >= 3:
            # a warm-up of a quarter of the steps, at least 2 (torch divides by the warm-up's length
            # minus one); fewer than 3 steps in all leave nothing to schedule: constant lr
            sched = torch.optim.lr_scheduler.OneCycleLR(
                opt,
                max_lr=self.lr,
                total_steps=total_steps,
                pct_start=max(0.25, 2.0 / total_steps),
                anneal_strategy="cos",
                cycle_momentum=False,
            )
        return opt, sched

    def _epochs(self, run: _TrainRun) -> tuple[list[dict[str, float]], int]:
        """(per-epoch history, best epoch) of training ``run`` up to ``max_epochs``, stopping early after
        ``patience`` epochs without a better validation loss; the network is left at its best epoch."""
        best, best_state, best_epoch, stale = math.inf, None, 0, 0
        history = []
        for epoch in range(1, int(self.max_epochs) + 1):
            train_loss = self._epoch(run, epoch)
            val_loss, val_acc = self._validate(run, epoch)
            history.append({"epoch": epoch, "train_loss": train_loss, "val_loss": val_loss, "val_accuracy": val_acc})
            score = val_loss if run.has_val else train_loss
            if score < best - 1e-4:
                best, best_epoch, stale = score, epoch, 0
                best_state = copy.deepcopy(run.net.state_dict())
            else:
                stale += 1
                if run.has_val and stale >= int(self.patience):
                    break
        if best_state is not None:
            run.net.load_state_dict(best_state)
        return history, best_epoch

    def _epoch(self, run: _TrainRun, epoch: int) -> float:
        """One pass over the training windows in shuffled batches; the mean training loss. A non-finite loss or
        gradient raises :class:`~sphri.finite.NonFiniteError`."""
        net, dev, precision, params = run.net, run.dev, run.precision, run.params
        x_tr, y_tr = run.x_tr, run.y_tr
        net.train()
        run_loss = 0.0
        for step, b in enumerate(self._batches(x_tr.shape[0], run.gen), 1):
            yb = y_tr[b].to(dev)
            with self._autocast(dev, precision):
                logits = self._logits(net, x_tr[b], dev, run.table)
            loss = F.cross_entropy(logits, yb)
            run.opt.zero_grad(set_to_none=True)
            loss.backward()
            loss_value = loss.detach().item()
            grad_norm = float(torch.nn.utils.get_total_norm([p.grad for p in params if p.grad is not None]))
            if not (math.isfinite(loss_value) and math.isfinite(grad_norm)):
                raise NonFiniteError(
                    f"CNN-GRU training: non-finite {'loss' if not math.isfinite(loss_value) else 'gradient'} "
                    f"at epoch {epoch}, step {step} ({self._where(precision)})"
                )
            run.opt.step()
            if run.sched is not None:
                run.sched.step()
            run_loss += loss_value * b.numel()
        return run_loss / max(1, x_tr.shape[0])

    def _validate(self, run: _TrainRun, epoch: int) -> tuple[float, float]:
        """(validation loss, accuracy) after an epoch, NaN without a validation split; a non-finite loss raises
        :class:`~sphri.finite.NonFiniteError`."""
        if not run.has_val:
            return float("nan"), float("nan")
        val_loss, val_acc = self._loss_acc(run.net, run.x_va, run.y_va, run.dev, run.table, run.precision)
        if not math.isfinite(val_loss):
            raise NonFiniteError(
                f"CNN-GRU training: non-finite validation loss at epoch {epoch} ({self._where(run.precision)})"
            )
        return val_loss, val_acc

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """(n, n_classes) softmax probabilities, columns in ``classes_`` order; a
        :class:`~sphri.finite.NonFiniteError` rather than a NaN row (whose argmax would be class 0)."""
        check_is_fitted(self, "net_")
        x = check_windows(x)
        self._layout(x.shape[2])
        dev = next(self.net_.parameters()).device
        out = []
        with _torch_state(int(self.threads), dev), torch.no_grad():
            self.net_.eval()
            xt = torch.from_numpy(np.ascontiguousarray(x))
            for b in torch.split(torch.arange(xt.shape[0]), 256):
                with self._autocast(dev):
                    logits = self.net_(xt[b].to(dev)).float()
                out.append(torch.softmax(logits, dim=1).cpu().double().numpy())
        if not out:
            return np.zeros((0, len(self.classes_)))
        return require_finite(
            np.concatenate(out), f"CNN-GRU probabilities ({self._where(getattr(self, 'precision_', 'float32'))})"
        )

    def predict(self, x: np.ndarray) -> np.ndarray:
        """(n,) predicted labels (values of ``classes_``)."""
        return self.classes_[np.argmax(self.predict_proba(x), axis=1)]

    # -- model files (sphri.export.registry) -------------------------------
    def save_state(self) -> tuple[dict, dict[str, np.ndarray]]:
        """(hyperparameters and precision, arrays: classes and the network's state dict), no pickle."""
        from sphri.models.persist import params_of, torch_state_array

        check_is_fitted(self, "net_")
        head = {"params": params_of(self), "precision_": getattr(self, "precision_", "float32")}
        return head, {"classes": np.asarray(self.classes_), "state_dict": torch_state_array(self.net_)}

    @classmethod
    def load_state(cls, head: dict, arrays, geometry: TaxelGeometry) -> CnnGru:
        """The fitted model of :meth:`save_state`'s output (weights read with ``torch.load(weights_only=True)``)."""
        from sphri.models.persist import torch_state_load

        model = cls(**dict(head.get("params") or {}), geometry=geometry)
        classes = arrays["classes"]
        model.net_ = torch_state_load(arrays["state_dict"], model._network(geometry.n_taxels, len(classes))).eval()
        model.classes_ = classes
        model.precision_ = head.get("precision_", "float32")
        return model
