"""Probe oneDNN's bf16 convolution for the shapes where it was measured wrong: weight gradients of a
stride-2, 3x3 convolution over inputs 1 wide, with the zero padding along W inside the convolution
(``pw1``) and explicit before it (what sphri's CNN-GRU does), against float32 on the same inputs.

Prints, per variant, how many of ``--calls`` calls gave a NaN gradient and how many a finite one off
float32 by more than 0.5 + 5 % of its largest entry, and how many forward outputs were off float32 by
more than 0.05 + 2 % of its largest entry (bf16 rounding is about 0.4 %), with the CPU model and flags. Writes
``outputs/bench/bf16_conv_probe.json``. Run: ``python bench/bf16_conv_probe.py [--calls 100]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from _common import machine, write_json  # noqa: E402


def probe(calls: int, explicit: bool, shape: tuple[int, int]) -> dict[str, int]:
    torch.manual_seed(0)
    nan = wrong = fwd_wrong = 0
    for _ in range(calls):
        conv = torch.nn.Conv2d(1, 16, 3, stride=2, padding=(1, 0) if explicit else (1, 1))
        x = torch.randn(64, 1, *shape)
        xin = F.pad(x, (1, 1)) if explicit else x
        with torch.autocast("cpu", dtype=torch.bfloat16):
            y = conv(xin)
        with torch.no_grad():
            y_ref = conv(xin)
        if not torch.isfinite(y).all() or (y.float() - y_ref).abs().max() > 0.05 + 0.02 * y_ref.abs().max():
            fwd_wrong += 1
        y.float().sum().backward()
        g = conv.weight.grad.clone()
        conv.weight.grad = None
        conv(xin).sum().backward()
        ref = conv.weight.grad
        if not torch.isfinite(g).all():
            nan += 1
        elif (g - ref).abs().max() > 0.5 + 0.05 * ref.abs().max():
            wrong += 1
    return {"calls": calls, "nan": nan, "wrong": wrong, "forward_wrong": fwd_wrong}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--calls", type=int, default=100)
    parser.add_argument("--quick", action="store_true", help="20 calls")
    args = parser.parse_args()
    calls = 20 if args.quick else args.calls
    out: dict = {
        "machine": machine(),
        "native_bf16": bool(torch.cpu._is_avx512_bf16_supported() or torch.cpu._is_amx_tile_supported()),
        "rows": [],
    }
    for shape in ((3, 1), (1, 1), (18, 1)):
        for explicit in (False, True):
            row = {"input": list(shape), "padding_w": "explicit" if explicit else "in the convolution"}
            row.update(probe(calls, explicit, shape))
            out["rows"].append(row)
            print(
                f"input {shape}, W padding {row['padding_w']}: {row['nan']} NaN, {row['wrong']} wrong of {calls} weight gradients; "
                f"{row['forward_wrong']} wrong outputs"
            )
    print(write_json("bf16_conv_probe", out))


if __name__ == "__main__":
    main()
