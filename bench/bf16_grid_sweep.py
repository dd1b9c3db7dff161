"""Which grid shapes the CNN-GRU's convolutions get wrong in bf16 on this CPU, against the rule
``model.precision=auto`` follows (:func:`sphri.models.cnn_gru.bf16_hazard`).

For every grid H x W in 1..``--max-side``, and on 18 x 1, 18 x 2, 1 x 18, 2 x 18, 50 x 1 and the arm
grids of res 18 and 50 (18 x 17, 50 x 47), with and without wrap along v, the default network's :class:`~sphri.models.cnn_gru.GridEncoder`
(channels 16/32/64, strides 2/2/1, embed 2) runs ``--calls`` forward and backward passes on random
batches of 64 frames, once under bf16 autocast and once in float32 with the same weights and inputs.
A call is **wrong** when the bf16 embeddings or any weight gradient are non-finite, or differ from
float32 by more than a quarter of (1 + float32's largest entry): bf16's own rounding stayed within an
eighth of it on every shape on an AMX Xeon (the largest error of the shapes judged right is printed),
the defect's errors are NaN or orders of magnitude larger. A shape is **bad** when any call is wrong. The script prints and writes (``outputs/bench/bf16_grid_sweep.json``) the bad shapes,
whether the rule flags each, and the largest error of the shapes judged right; it exits 1 when a bad
shape is not flagged (the rule would train it in bf16). Run:
``python bench/bf16_grid_sweep.py [--max-side 12] [--calls 20]``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import torch  # noqa: E402
from _common import machine, write_json  # noqa: E402

from sphri.models.cnn_gru import GridEncoder, bf16_hazard, native_bf16  # noqa: E402
from sphri.testing.bf16 import WRONG, bf16_error  # noqa: E402

CHANNELS, STRIDES, EMBED = [16, 32, 64], [2, 2, 1], 2


def sweep(shapes: list[tuple[int, int]], calls: int) -> list[dict]:
    rows = []
    for h, w in shapes:
        for wrap in (False, True):
            torch.manual_seed(0)
            enc = GridEncoder((h, w), CHANNELS, STRIDES, wrap, EMBED)
            errs = [bf16_error(enc, torch.randn(64, 1, h, w)) for _ in range(calls)]
            rows.append(
                {
                    "grid": [h, w],
                    "wrap_v": wrap,
                    "wrong_calls": sum(e > WRONG for e in errs),
                    "worst": max(errs),
                    "flagged": bf16_hazard((h, w), STRIDES) is not None,
                }
            )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--max-side", type=int, default=12)
    ap.add_argument("--calls", type=int, default=20)
    args = ap.parse_args()
    torch.set_num_threads(1)
    shapes = [(h, w) for h in range(1, args.max_side + 1) for w in range(1, args.max_side + 1)]
    shapes += [(18, 1), (18, 2), (1, 18), (2, 18), (50, 1), (18, 17), (50, 47)]
    rows = sweep(shapes, args.calls)
    bad = [r for r in rows if r["wrong_calls"]]
    missed = [r for r in bad if not r["flagged"]]
    right = [r["worst"] for r in rows if not r["wrong_calls"]]
    flagged_right = [r for r in rows if r["flagged"] and not r["wrong_calls"]]
    summary = {
        "shapes": len(rows),
        "calls_per_shape": args.calls,
        "bad": len(bad),
        "bad_not_flagged": len(missed),
        "flagged_but_right": len(flagged_right),
        "largest_relative_error_of_right_shapes": max(right) if right else None,
    }
    print(
        write_json(
            "bf16_grid_sweep",
            {"machine": machine(), "native_bf16": native_bf16(torch.device("cpu")), "summary": summary, "rows": rows},
        )
    )
    print(summary)
    for r in bad:
        print(
            f"bad: {r['grid'][0]} x {r['grid'][1]} wrap={r['wrap_v']}: {r['wrong_calls']}/{args.calls} calls wrong, "
            f"{'flagged' if r['flagged'] else 'NOT FLAGGED'}"
        )
    sys.exit(1 if missed else 0)


if __name__ == "__main__":
    main()
