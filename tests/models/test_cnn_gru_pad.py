"""The CNN-GRU's circular pad along v (``CircularPadV``): its hand-written backward, which folds the pad
columns' gradients back, gives exactly the gradients of torch's own circular pad, in float32 and bf16,
for every width down to 1 (where both pad columns copy the same column), alone and inside the encoder."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

import sphri.models.cnn_gru as cnn_gru
from sphri.models.cnn_gru import CircularPadV, GridEncoder


def reference_pad(x: torch.Tensor) -> torch.Tensor:
    return F.pad(x, (1, 1, 0, 0), mode="circular")


@pytest.mark.parametrize("dtype", [torch.float32, torch.bfloat16])
@pytest.mark.parametrize("width", [1, 2, 3, 7])
def test_pad_forward_and_gradient_equal_torch_circular_pad(dtype, width):
    torch.manual_seed(width)
    x = torch.randn(4, 3, 5, width, dtype=dtype, requires_grad=True)
    upstream = torch.randn(4, 3, 5, width + 2, dtype=dtype)
    ref = reference_pad(x)
    (ref_grad,) = torch.autograd.grad(ref, x, upstream)
    out = CircularPadV.apply(x)
    (grad,) = torch.autograd.grad(out, x, upstream)
    assert torch.equal(out, ref)
    # exactly equal: each column sums the same terms in the same order (width 1: three terms)
    torch.testing.assert_close(grad, ref_grad, rtol=0, atol=0)
    assert grad.dtype == dtype and grad.shape == x.shape


def test_pad_gradient_of_a_non_contiguous_upstream():
    x = torch.randn(2, 4, 6, 5, requires_grad=True)
    upstream = torch.randn(2, 4, 7, 6).transpose(-1, -2)  # (2, 4, 6, 7), not contiguous
    (ref_grad,) = torch.autograd.grad(reference_pad(x), x, upstream)
    (grad,) = torch.autograd.grad(CircularPadV.apply(x), x, upstream)
    torch.testing.assert_close(grad, ref_grad, rtol=0, atol=0)


def _encoder_grads(enc: GridEncoder, frames: torch.Tensor, bf16: bool) -> list[torch.Tensor]:
    enc.zero_grad(set_to_none=True)
    with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
        out = enc(frames)
    (out.float() ** 2).sum().backward()
    return [p.grad.clone() for p in enc.parameters()]


@pytest.mark.parametrize("bf16", [False, True], ids=["float32", "bf16-autocast"])
@pytest.mark.parametrize("shape", [(3, 3), (18, 19), (4, 2)])
def test_encoder_parameter_gradients_equal_those_with_torch_circular_pad(monkeypatch, shape, bf16):
    """The whole encoder (strides 2, 2, 1: v shrinks to 1 on small grids) trains on the same gradients."""
    torch.manual_seed(0)
    enc = GridEncoder(shape, [4, 8, 8], [2, 2, 1], wrap_v=True, embed_size=2)
    frames = (torch.rand(6, 1, *shape) < 0.4).float()
    ours = _encoder_grads(enc, frames, bf16)
    monkeypatch.setattr(cnn_gru.CircularPadV, "apply", reference_pad)
    theirs = _encoder_grads(enc, frames, bf16)
    assert len(ours) == len(theirs) == 6
    for a, b in zip(ours, theirs):
        # identical, also under bf16 autocast (the pad sees bf16 activations there)
        torch.testing.assert_close(a, b, rtol=0, atol=0)
        assert a.abs().sum() > 0
