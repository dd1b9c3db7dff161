"""model=cnn_gru: any grid size under each precision, circular padding, determinism, training-only splits,
and never a silent NaN (training and probabilities)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from sklearn.base import clone

from sphri.finite import NonFiniteError
from sphri.models.cnn_gru import (
    CnnGru,
    GridEncoder,
    bf16_hazard,
    choose_precision,
    native_bf16,
    resolve_precision,
    validation_split,
)
from sphri.testing.bf16 import WRONG, bf16_error
from sphri.testing.toy_windows import blob_windows
from sphri.types import TaxelGeometry

TINY = dict(max_epochs=2, batch_size=8, hidden=8, channels=[4, 4, 4], threads=1)

#: The precisions a CPU may train with: float32 everywhere, bf16 where the CPU computes it natively.
PRECISIONS = [
    "float32",
    pytest.param(
        "bf16",
        marks=pytest.mark.skipif(
            not native_bf16(torch.device("cpu")),
            reason="bf16 runs need a CPU with native bf16 (AVX512-BF16 or AMX); this CPU has neither",
        ),
    ),
]


def geometry(shape: tuple[int, int] | None, n: int, wrap: bool) -> TaxelGeometry:
    rng = np.random.default_rng(0)
    return TaxelGeometry(
        grid_shape=shape,
        uv=rng.random((n, 2)),
        position_m=rng.random((n, 3)),
        wrap_v=wrap,
        metres_per_u=0.24,
        metres_per_v=0.26,
    )


def toy_xy(n_taxels: int, n: int = 24, length: int = 6, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = (rng.random((n, length, n_taxels)) < 0.3).astype(np.float32)
    y = np.arange(n) % 4
    return x, y


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("shape", [(1, 1), (1, 5), (3, 1), (2, 2), (7, 8), (18, 1), None])
@pytest.mark.parametrize("wrap", [False, True])
def test_any_grid_size_and_non_grid(shape, wrap, precision):
    """Every grid trains to finite probabilities. Under bf16, a grid whose stride-2 convolutions see a
    side of at most 2 taxels (oneDNN's bf16 defect class) is asked for with ``auto``, which must pick
    float32 there; the others run in bf16 as asked."""
    n_tax = 6 if shape is None else shape[0] * shape[1]
    x, y = toy_xy(n_tax)
    hazard = bf16_hazard(shape, [2, 2, 1])
    ask = "auto" if precision == "bf16" and hazard is not None else precision
    m = CnnGru(geometry=geometry(shape, n_tax, wrap), precision=ask, **TINY).fit(x, y)
    assert m.precision_ == ("float32" if hazard is not None else precision)
    p = m.predict_proba(x)
    assert p.shape == (24, 4) and np.all(np.isfinite(p))
    np.testing.assert_allclose(p.sum(axis=1), 1.0, rtol=1e-5)
    np.testing.assert_array_equal(m.classes_, np.arange(4))
    assert len(m.history_) >= 1 and m.best_epoch_ >= 1
    assert all(np.isfinite(h["train_loss"]) for h in m.history_)


def test_zero_padding_along_v_is_explicit_and_equals_the_convolutions_own():
    """Without wrap the v padding is zeros outside the convolution (oneDNN's bf16 kernels are wrong with
    it inside): the same embeddings as a convolution padding (1, 1) itself."""
    torch.manual_seed(3)
    enc = GridEncoder((5, 1), [3, 4, 5], [2, 2, 1], wrap_v=False, embed_size=1)
    assert all(conv.padding == (1, 0) for conv in enc.convs)
    frames = torch.rand(4, 1, 5, 1)
    feats = frames
    for conv in enc.convs:
        feats = torch.relu(F.conv2d(feats, conv.weight, conv.bias, stride=conv.stride, padding=(1, 1)))
    torch.testing.assert_close(enc(frames), feats.mean(dim=(2, 3)), rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize(
    "shape,hazard",
    [
        ((1, 1), True),
        ((18, 1), True),
        ((3, 4), True),
        ((4, 4), True),
        ((5, 5), False),
        ((18, 19), False),
        (None, False),
    ],
)
def test_auto_avoids_bf16_where_a_stride_2_convolution_sees_a_side_of_two(shape, hazard):
    assert (bf16_hazard(shape, [2, 2, 1]) is not None) == hazard
    assert bf16_hazard(shape, [1, 1, 1]) is None  # stride 1 was measured clean
    cpu = torch.device("cpu")
    precision, why = choose_precision("auto", cpu, shape, [2, 2, 1])
    if not native_bf16(cpu):
        assert (precision, why) == ("float32", "auto: cpu without native bf16")
    else:
        assert precision == ("float32" if hazard else "bf16")
        assert ("at most 2 taxels" in why) == hazard
    assert choose_precision("bf16", cpu, shape, [2, 2, 1]) == ("bf16", "chosen (model.precision)")


def bf16_calls_wrong(shape: tuple[int, int], wrap: bool, calls: int) -> int:
    """How many of ``calls`` forward and backward passes of the default encoder on ``shape`` give bf16
    embeddings or weight gradients that are non-finite or off float32 by more than a quarter of
    (1 + float32's largest entry) (:func:`sphri.testing.bf16.bf16_error`)."""
    torch.manual_seed(0)
    enc = GridEncoder(shape, [16, 32, 64], [2, 2, 1], wrap, 2)
    return sum(bf16_error(enc, torch.randn(64, 1, *shape)) > WRONG for _ in range(calls))


@pytest.mark.skipif(not native_bf16(torch.device("cpu")), reason="bf16 runs need a CPU with native bf16")
@pytest.mark.parametrize("wrap", [False, True])
def test_every_grid_this_cpu_computes_wrong_in_bf16_is_one_auto_avoids(wrap):
    """On this CPU's oneDNN, the grids at the edge of the defect class (a stride-2 convolution over a side
    of 1 or 2 taxels, 9 or more long: wrong on AMX CPUs in most calls, NaN in many) either compute right
    in bf16 or are grids ``auto`` trains in float32. Fails where the rule misses a shape this CPU gets
    wrong; the rule's measured coverage (302 shapes) is in docs/BENCHMARKS.md."""
    shapes = [(9, 1), (18, 1), (18, 2), (2, 18), (9, 3), (18, 3), (3, 18), (18, 17)]
    missed = [s for s in shapes if bf16_calls_wrong(s, wrap, 4) and bf16_hazard(s, [2, 2, 1]) is None]
    assert missed == []


def nan_under(condition):
    """A forward hook that turns the encoder's output into NaN while ``condition()`` holds."""

    def hook(module, inputs, output):
        return output * float("nan") if condition() else output

    return hook


def poison(model: CnnGru, install) -> CnnGru:
    """``model`` whose every new network gets ``install(net)`` (a hook) before training."""
    real = model._network

    def network(*a):
        net = real(*a)
        install(net)
        return net

    model._network = network
    return model


def test_a_non_finite_loss_stops_training_with_one_line():
    x, y = toy_xy(12)
    m = CnnGru(geometry=geometry((3, 4), 12, True), precision="float32", **TINY)
    poison(m, lambda net: net.encoder.register_forward_hook(nan_under(lambda: True)))
    with pytest.raises(NonFiniteError) as err:
        m.fit(x, y)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg == "CNN-GRU training: non-finite loss at epoch 1, step 1 (precision float32, grid 3 x 4, v wraps)"
    assert not hasattr(m, "net_")  # nothing fitted is left behind to predict with


def test_a_non_finite_gradient_with_a_finite_loss_stops_training():
    """The defect's own shape: the loss is finite, a weight gradient is not."""
    x, y = toy_xy(6)
    m = CnnGru(geometry=geometry((3, 2), 6, False), precision="float32", **TINY)
    poison(m, lambda net: net.encoder.convs[0].weight.register_hook(lambda g: g * float("nan")))
    with pytest.raises(NonFiniteError, match=r"non-finite gradient at epoch 1, step 1 \(precision float32, grid 3 x 2"):
        m.fit(x, y)


def test_auto_bf16_that_goes_non_finite_retrains_in_float32_and_says_so(monkeypatch):
    from sphri.models import cnn_gru

    monkeypatch.setattr(cnn_gru, "native_bf16", lambda device: True)  # any CPU: autocast runs without it
    x, y = toy_xy(36)
    g = geometry((6, 6), 36, True)
    m = CnnGru(geometry=g, **TINY)
    assert m.runtime()["precision"] == "bf16"

    def install(net):
        net.encoder.register_forward_hook(nan_under(lambda: torch.is_autocast_enabled("cpu")))

    poison(m, install).fit(x, y)
    assert m.precision_ == "float32"
    assert m.runtime_["precision"] == "float32"
    reason = m.runtime_["precision_reason"]
    assert reason.startswith("auto: bf16 chosen, then CNN-GRU training: non-finite loss at epoch 1")
    assert reason.endswith("retrained in float32")
    assert np.all(np.isfinite(m.predict_proba(x)))
    explicit = poison(CnnGru(geometry=g, precision="bf16", **TINY), install)
    with pytest.raises(NonFiniteError, match="precision bf16, grid 6 x 6"):  # the user's own choice: no fallback
        explicit.fit(x, y)


def test_non_finite_probabilities_are_refused_not_argmaxed():
    x, y = toy_xy(12)
    m = CnnGru(geometry=geometry((3, 4), 12, True), precision="float32", **TINY).fit(x, y)
    with torch.no_grad():
        m.net_.head.bias[1] = float("nan")
    with pytest.raises(NonFiniteError, match=r"CNN-GRU probabilities \(precision float32, grid 3 x 4, v wraps\)"):
        m.predict_proba(x)
    with pytest.raises(NonFiniteError):
        m.predict(x)  # argmax over a NaN row would have said class 0


def test_no_geometry_uses_the_mlp():
    x, y = toy_xy(5)
    m = CnnGru(**TINY).fit(x, y)
    assert m.predict(x).shape == (24,)


def test_circular_padding_wraps_around_v():
    """With stride 1 and global pooling, rolling frames around v leaves embeddings unchanged."""
    torch.manual_seed(0)
    frames = (torch.rand(5, 1, 4, 7) < 0.3).float()
    rolled = torch.roll(frames, shifts=3, dims=3)
    wrap = GridEncoder((4, 7), [4, 8, 8], [1, 1, 1], wrap_v=True, embed_size=1)
    torch.testing.assert_close(wrap(rolled), wrap(frames), rtol=1e-5, atol=1e-6)
    flat = GridEncoder((4, 7), [4, 8, 8], [1, 1, 1], wrap_v=False, embed_size=1)
    flat.load_state_dict(wrap.state_dict())
    assert not torch.allclose(flat(rolled), flat(frames), atol=1e-4)


@pytest.mark.parametrize(
    "shape,strides", [((1, 1), [2, 2, 1]), ((18, 19), [2, 2, 1]), ((5, 3), [1, 2, 3]), ((4, 7), [1, 1, 1])]
)
@pytest.mark.parametrize("size", [1, 2, 3])
def test_pooling_matrix_equals_adaptive_average_pooling(shape, strides, size):
    torch.manual_seed(1)
    enc = GridEncoder(shape, [3, 4, 5], strides, wrap_v=True, embed_size=size)
    frames = torch.rand(6, 1, *shape)
    feats = frames
    for conv in enc.convs:
        feats = torch.relu(conv(torch.cat([feats[..., -1:], feats, feats[..., :1]], dim=-1)))
    expected = F.adaptive_avg_pool2d(feats, size).flatten(1)
    torch.testing.assert_close(enc(frames), expected, rtol=1e-5, atol=1e-6)


def test_deterministic_for_a_seed():
    x, y = toy_xy(12, seed=1)
    g = geometry((3, 4), 12, True)
    a = CnnGru(geometry=g, seed=5, **TINY).fit(x, y)
    b = clone(a).fit(x, y)
    np.testing.assert_array_equal(a.predict_proba(x), b.predict_proba(x))
    c = clone(a).set_params(seed=6).fit(x, y)
    assert not np.array_equal(a.predict_proba(x), c.predict_proba(x))


@pytest.mark.parametrize("precision", ["float32", "bf16", "auto"])
def test_each_precision_runs_and_is_deterministic(precision):
    x, y = toy_xy(30, seed=1)
    g = geometry((5, 6), 30, True)
    a = CnnGru(geometry=g, precision=precision, **TINY).fit(x, y)
    expected = resolve_precision(precision, torch.device("cpu"), (5, 6), [2, 2, 1])
    assert a.precision_ == expected == a.runtime_["precision"]
    assert expected == (
        "bf16" if precision == "bf16" or (precision == "auto" and native_bf16(torch.device("cpu"))) else "float32"
    )
    b = clone(a).fit(x, y)
    p = a.predict_proba(x)
    assert p.dtype == np.float64 and np.all(np.isfinite(p))
    np.testing.assert_array_equal(p, b.predict_proba(x))


def test_validation_split_holds_out_whole_training_participants():
    y = np.tile(np.arange(4), 30)
    groups = np.repeat([f"p{i}" for i in range(6)], 20)
    tr, va = validation_split(y, groups, 0.3, seed=0)
    assert not set(groups[tr]) & set(groups[va])
    assert len(set(groups[va])) == 2 and set(groups[tr])  # round(0.3 * 6), never all
    assert sorted(np.concatenate([tr, va])) == list(range(120))
    tr2, va2 = validation_split(y, None, 0.25, seed=0)  # stratified
    assert np.all(np.bincount(y[va2]) == 8)
    tr3, va3 = validation_split(y, groups[:1].repeat(120), 0.3, seed=0)  # one group: stratified
    assert va3.size > 0
    assert validation_split(y, groups, 0.0, seed=0)[1].size == 0


def test_input_scaling_is_fit_on_the_training_split_only():
    rng = np.random.default_rng(2)
    groups = np.repeat(["a", "b", "c", "d"], 10)
    x = rng.random((40, 5, 6)).astype(np.float32) + np.repeat([0.0, 1.0, 3.0, 7.0], 10)[:, None, None]
    y = np.arange(40) % 4
    m = CnnGru(geometry=geometry((2, 3), 6, False), val_fraction=0.25, min_val_participants=1, seed=1, **TINY).fit(
        x, y, groups=groups
    )
    tr, va = validation_split(np.unique(y, return_inverse=True)[1], groups, 0.25, seed=1)
    assert m.n_val_ == va.size == 10
    assert float(m.net_.x_mean) == pytest.approx(float(x[tr].mean()), rel=1e-5)
    assert float(m.net_.x_mean) != pytest.approx(float(x.mean()), rel=1e-2)


@pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA present: the error path cannot be exercised")
def test_cuda_requested_without_cuda_fails_clearly():
    x, y = toy_xy(4)
    with pytest.raises(RuntimeError, match="model.device='cuda'.*not available"):
        CnnGru(device="cuda", **TINY).fit(x, y)


def test_device_auto_is_cuda_when_available_else_cpu(monkeypatch):
    """model.device=auto (the default, issue 31) trains where runtime() says: CUDA if torch sees it."""
    from sphri.models import cnn_gru

    assert CnnGru().device == "auto"
    want = "cuda" if torch.cuda.is_available() else "cpu"
    assert cnn_gru.resolve_device("auto").type == want
    assert CnnGru().runtime() == {
        "device": str(cnn_gru.resolve_device("auto")),
        **dict(zip(("precision", "precision_reason"), choose_precision("auto", torch.device(want)))),
    }
    x, y = toy_xy(4)
    m = CnnGru(geometry=geometry((2, 2), 4, False), **TINY).fit(x, y)
    assert next(m.net_.parameters()).device.type == want
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # a machine without a GPU
    assert cnn_gru.resolve_device("auto") == torch.device("cpu")
    assert CnnGru(precision="float32").runtime() == {
        "device": "cpu",
        "precision": "float32",
        "precision_reason": "chosen (model.precision)",
    }


def test_bad_parameters_are_named():
    x, y = toy_xy(4)
    with pytest.raises(ValueError, match="model.strides"):
        CnnGru(channels=[4, 4], strides=[1], geometry=geometry((2, 2), 4, False)).fit(x, y)
    with pytest.raises(ValueError, match="taxels"):
        CnnGru(geometry=geometry((2, 3), 6, False), **TINY).fit(x, y)
    with pytest.raises(ValueError, match="model.device"):
        CnnGru(device="tpu", **TINY).fit(x, y)
    with pytest.raises(ValueError, match="model.precision"):
        CnnGru(precision="fp8", **TINY).fit(x, y)


def test_cnn_gru_learns_synthetic_gestures():
    """Fits synthetic arm touches (3 participants, res 6) far above chance (12.5 %)."""
    win = blob_windows(participants=3, repetitions=4, res=6, seed=21)
    m = CnnGru(geometry=win.geometry, max_epochs=15, batch_size=8, hidden=64, val_fraction=0.0, threads=1, seed=0)
    m.fit(win.x, win.y)
    losses = [h["train_loss"] for h in m.history_]
    assert losses[-1] < 0.6 * losses[0], losses
    assert float(np.mean(m.predict(win.x) == win.y)) > 0.5


@pytest.mark.slow
def test_cnn_gru_generalises_to_new_participants_and_resolution_matters():
    """LOSO (3 folds) at res 12 well above chance; res 1 clearly lower."""
    import functools

    from sphri.evaluate.cv import LeaveOneSubjectOut

    acc = {}
    for res in (1, 12):
        win = blob_windows(participants=6, repetitions=8, res=res, seed=22)
        make = functools.partial(CnnGru, geometry=win.geometry, max_epochs=30, patience=6, seed=0)
        result = LeaveOneSubjectOut(max_folds=3).run(make, win, seed=0)
        acc[res] = result.summary()["accuracy_mean"]
    assert acc[12] > 0.5, acc
    assert acc[1] < acc[12] - 0.1, acc


def test_unique_frames_round_trip_and_compact():
    from sphri.models.cnn_gru import compact, unique_frames

    x, _ = toy_xy(6, n=30, length=8, seed=3)
    x[:5] = 0.0  # many identical (empty) frames
    table, ids = unique_frames(x)
    assert ids.shape == x.shape[:2] and table.shape[0] < x.shape[0] * x.shape[1]
    np.testing.assert_array_equal(table[ids], x)
    assert compact(x).dtype == np.uint8 and np.array_equal(compact(x), x)
    assert compact(x * 0.5).dtype == np.float32  # not integers: unchanged


@pytest.mark.parametrize("shape,n_tax", [((3, 4), 12), (None, 6)])
def test_unique_frame_embedding_equals_embedding_every_frame(shape, n_tax):
    """forward_ids (each distinct frame embedded once) == forward on every frame, in float32."""
    from sphri.models.cnn_gru import CnnGruNet, compact, unique_frames

    x, _ = toy_xy(n_tax, n=10, length=7, seed=4)
    x[:4] = 0.0
    torch.manual_seed(0)
    net = CnnGruNet(n_tax, shape, True, [4, 4, 4], [2, 2, 1], 2, 8, 4).eval()
    table, ids = unique_frames(x)
    with torch.no_grad():
        ref = net(torch.from_numpy(x))
        got = net.forward_ids(torch.from_numpy(compact(table)), torch.from_numpy(ids))
    torch.testing.assert_close(got, ref, rtol=1e-5, atol=1e-6)


def test_dedupe_training_matches_plain_training():
    """fit with dedupe_frames: same training run as without, to float rounding (float32)."""
    x, y = toy_xy(12, n=24, seed=2)
    x[::3] = 0.0
    g = geometry((3, 4), 12, True)
    kw = dict(TINY, precision="float32", seed=3)
    a = CnnGru(geometry=g, **kw).fit(x, y)
    b = CnnGru(geometry=g, dedupe_frames=True, **kw).fit(x, y)
    np.testing.assert_allclose(b.predict_proba(x), a.predict_proba(x), rtol=1e-4, atol=1e-5)


def test_onecycle_schedule_runs_and_is_deterministic():
    x, y = toy_xy(12, seed=1)
    g = geometry((3, 4), 12, True)
    a = CnnGru(geometry=g, schedule="onecycle", dedupe_frames=True, **TINY).fit(x, y)
    b = clone(a).fit(x, y)
    np.testing.assert_array_equal(a.predict_proba(x), b.predict_proba(x))
    with pytest.raises(ValueError, match="model.schedule"):
        CnnGru(geometry=g, schedule="cosine", **TINY).fit(x, y)


@pytest.mark.parametrize("n, max_epochs", [(4, 1), (8, 1), (24, 1), (8, 4)])
def test_onecycle_schedule_fits_runs_of_very_few_steps(n, max_epochs):
    """1 to 12 optimizer steps in all: torch's one-cycle divides by zero for a warm-up under 2 steps."""
    x, y = toy_xy(12, n=n, seed=2)
    g = geometry((3, 4), 12, True)
    m = CnnGru(geometry=g, schedule="onecycle", val_fraction=0.0, **{**TINY, "max_epochs": max_epochs}).fit(x, y)
    assert len(m.history_) == max_epochs
    assert np.isfinite(m.predict_proba(x)).all()


def test_thread_count_changes_predictions_only_by_rounding():
    """Same seed, 1 or 2 torch threads -> the same predictions to float rounding, NOT bit-identical.

    Measured: oneDNN's convolution backward splits its reductions by thread,
    so probabilities differ in the 8th digit after 2 tiny epochs; over a
    full-size fit such differences can grow (the run-to-run spread of about
    2 points between thread settings). The thread count is therefore a
    setting that changes results (``model.threads`` / the CV's share).
    """
    x, y = toy_xy(12, seed=1)
    g = geometry((3, 4), 12, True)
    for precision in ("float32", "auto"):
        kw = dict(TINY, precision=precision, dedupe_frames=True)
        kw.pop("threads")
        a = CnnGru(geometry=g, threads=1, **kw).fit(x, y)
        b = CnnGru(geometry=g, threads=2, **kw).fit(x, y)
        np.testing.assert_allclose(a.predict_proba(x), b.predict_proba(x), rtol=1e-4, atol=1e-5)


def test_a_small_study_trains_every_epoch_instead_of_stopping_on_one_persons_loss(caplog, monkeypatch):
    """5 training participants x 15 % is one held-out person: early stopping on that one loss kept an
    almost untrained model on the built-in chain. Below model.min_val_participants held-out participants
    the model trains all epochs without a split, and says so once per process (not once per fold); 17
    keep the paper's split."""
    import logging

    from sphri.models import cnn_gru

    monkeypatch.setattr(cnn_gru, "_WARNED", set())  # warnings given by earlier tests in this process

    rng = np.random.default_rng(3)
    x = (rng.random((50, 5, 6)) < 0.3).astype(np.float32)
    y = np.arange(50) % 4
    groups = np.repeat([f"p{i}" for i in range(5)], 10)
    settings = dict(
        geometry=geometry((2, 3), 6, False), val_fraction=0.15, patience=1, seed=0, **{**TINY, "max_epochs": 6}
    )
    with caplog.at_level(logging.WARNING, logger="sphri.models.cnn_gru"):
        m = CnnGru(**settings).fit(x, y, groups=groups)
        CnnGru(**settings).fit(x, y, groups=groups)  # the next fold of the same job: no second warning
    assert m.n_val_ == 0 and len(m.history_) == 6  # every epoch, no split
    assert "min_val_participants=3" in caplog.text and "1 of 5" in caplog.text
    assert caplog.text.count("early stopping would hold out") == 1
    old = CnnGru(**settings, min_val_participants=1).fit(x, y, groups=groups)  # the earlier behaviour, when asked
    assert old.n_val_ == 10
    assert (
        CnnGru(min_val_participants=3, val_fraction=0.15).early_stopping_fraction(
            np.repeat([f"p{i}" for i in range(17)], 2)
        )
        == 0.15
    )  # the paper's 18 participants: 3 held out, unchanged


def test_cnn_gru_beats_chance_on_a_small_study(tmp_path):
    """Issue 31, item 6: on a small study the CNN-GRU learns (it used to keep an almost untrained model
    that early stopping chose on one held-out person: macro-F1 0.111 at res 18, 6 participants x 10
    repetitions, below chance 0.125). Smaller than that command: res 6, 6 participants x 10 repetitions,
    the first 3 of the 6 LOSO folds, one thread per fold (about 35 CPU s from an empty cache with bf16,
    80-90 s with float32 on an AVX2-only CPU).

    Measured with this configuration (macro-F1 over the 3 folds, seed=0 / 1 / 2):
    - 2-core AMD EPYC with avx512_bf16 (precision=auto is bf16), 2026-11-26: 0.304 / 0.226 / 0.293;
    - 2-core AMD EPYC with AVX2 only (precision=auto is float32), 2026-11-27: 0.278 / 0.174 / 0.295;
    - the same AVX2 machine with the earlier behaviour (model.min_val_participants=1: early stopping on
      one held-out person): 0.093 / 0.098 / 0.084.
    The test runs seed 0 and asks for more than 0.135, midway between the earlier behaviour's best
    (0.098) and this one's worst (0.174), so that neither a seed nor the precision decides it (the
    threshold was chance + 0.05 = 0.175 until the float32 seeds were measured: seed 1 fell under it).
    Smaller sizes do not separate the two (same AVX2 machine, float32, seed 0 / 1 / 2): the first 2 folds
    gave 0.259 / 0.133 / 0.266 (the earlier behaviour, seed 0: 0.076), and 2 folds of 10 epochs instead
    of 20 gave 0.061 / 0.099 / 0.128. Rerun: ``python -m sphri model=cnn_gru layout.res=6
    data.participants=6 data.repetitions=10 cv.max_folds=3 seed=S`` (``model.min_val_participants=1``
    for the earlier behaviour, ``cv.max_folds=2 model.max_epochs=10`` for the smaller sizes).
    """
    from sphri import pipeline
    from sphri.config import compose
    from sphri.evaluate.metrics import chance_level

    cfg = compose(
        [
            "model=cnn_gru",
            "layout.res=6",
            "data.participants=6",
            "data.repetitions=10",
            "cv.max_folds=3",
            "cv.threads_per_worker=1",
            "cv.progress=false",
            "tracking.enabled=false",
            f"output_dir={tmp_path}",
        ]
    )
    result = pipeline.run(cfg)
    assert len(result.cv.folds) == 3
    assert chance_level(result.cv) == pytest.approx(0.125)
    f1 = float(np.mean([f.macro_f1 for f in result.cv.folds]))
    acc = float(np.mean([f.accuracy for f in result.cv.folds]))
    assert f1 > 0.135, f"macro-F1 {f1:.3f} (accuracy {acc:.3f}): no better than the earlier behaviour (<= 0.098)"
