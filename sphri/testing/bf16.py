"""How far a grid encoder's bf16 pass is from its float32 pass: the oracle of ``bench/bf16_grid_sweep.py``
and of the test that the precision rule avoids every grid a CPU's oneDNN computes wrong in bf16."""

from __future__ import annotations

import torch

#: Above this error a call is wrong: bf16's own rounding stayed within half of it (0.125) on every grid
#: probed on an AMX Xeon; oneDNN's defect gives NaN or errors orders of magnitude larger (docs/BENCHMARKS.md).
WRONG = 0.25


def bf16_error(encoder: torch.nn.Module, x: torch.Tensor) -> float:
    """The largest of the embeddings' and the convolution weight gradients' bf16 error, |bf16 - float32| /
    (1 + |float32|) at their largest, for one forward and backward pass of ``encoder`` (a
    :class:`~sphri.models.cnn_gru.GridEncoder`) on ``x``; inf when bf16 gave a non-finite value."""
    out = []
    for bf16 in (True, False):
        encoder.zero_grad(set_to_none=True)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            y = encoder(x)
        y.float().sum().backward()
        out.append([y.detach().float()] + [conv.weight.grad.clone() for conv in encoder.convs])
    worst = 0.0
    for got, ref in zip(*out):
        if not torch.isfinite(got).all():
            return float("inf")
        worst = max(worst, float((got - ref).abs().max() / (1.0 + ref.abs().max())))
    return worst
