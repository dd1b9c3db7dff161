"""Benchmark the finite checks (:mod:`sphri.finite`): what leaving them on costs, as ratios in one run.

- Encoder boundary: :func:`sphri.finite.require_finite` over float32 frames (coverage-encoder output at
  res 18 and 50, 10,000 frames) against one RF feature extraction over the same frames (the work those
  frames feed), and over uint8 frames (binary encoders: no pass at all).
- Random Forest: the check of the (n, 32) features against extracting them.
- CNN-GRU training: one fit with the per-step loss and gradient-norm check against the same fit with
  the gradient norm stubbed out (alternating A/B, best of ``repeat``), at res 18 on the default network.

Writes ``outputs/bench/finite.json`` with the machine (CPU model and flags). Run:
``python bench/bench_finite.py`` (``--quick``: fewer repeats and a smaller fit).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np  # noqa: E402
from _common import machine, timeit, write_json  # noqa: E402

from sphri.finite import require_finite  # noqa: E402
from sphri.models.features import extract_features  # noqa: E402
from sphri.testing.toy_windows import blob_windows  # noqa: E402


def frames_rows(repeat: int) -> list[dict]:
    rows = []
    for res in (18, 50):
        w = blob_windows(participants=5, repetitions=5, res=res, length=50, noise_p=0.01)
        frames = w.x.reshape(-1, w.x.shape[2]).astype(np.float32)
        as_uint8 = frames.astype(np.uint8)
        check = timeit(lambda: require_finite(frames, "frames"), repeat=repeat)
        check_u8 = timeit(lambda: require_finite(as_uint8, "frames"), repeat=repeat)
        feats = timeit(lambda: extract_features(w.x, w.geometry), repeat=repeat)
        f = extract_features(w.x, w.geometry)
        check_feats = timeit(lambda: require_finite(f, "features"), repeat=repeat)
        rows.append(
            {
                "res": res,
                "frames": frames.shape[0],
                "taxels": frames.shape[1],
                "check_float32_ms": check["best_s"] * 1e3,
                "check_uint8_ms": check_u8["best_s"] * 1e3,
                "features_ms": feats["best_s"] * 1e3,
                "check_features_ms": check_feats["best_s"] * 1e3,
                "check_float32_over_features": check["best_s"] / feats["best_s"],
            }
        )
        print(
            f"res {res}: check of {frames.shape} float32 frames {check['best_s'] * 1e3:.2f} ms "
            f"({rows[-1]['check_float32_over_features']:.2%} of the features' {feats['best_s'] * 1e3:.0f} ms); "
            f"uint8 {check_u8['best_s'] * 1e3:.3f} ms; features check {check_feats['best_s'] * 1e3:.3f} ms",
            flush=True,
        )
    return rows


def training_row(repeat: int, quick: bool) -> dict:
    import time

    import torch

    from sphri.models.cnn_gru import CnnGru

    w = blob_windows(participants=3 if quick else 6, repetitions=2, res=18, length=50, noise_p=0.01)
    real = torch.nn.utils.get_total_norm

    def fit(checked: bool) -> float:
        torch.nn.utils.get_total_norm = real if checked else (lambda tensors, *a, **k: torch.zeros(()))
        try:
            c0 = time.process_time()
            CnnGru(geometry=w.geometry, max_epochs=1, val_fraction=0.0, precision="float32", threads=1).fit(w.x, w.y)
            return time.process_time() - c0
        finally:
            torch.nn.utils.get_total_norm = real

    fit(True)  # warm-up: kernels, allocator
    on, off = [], []
    for _ in range(repeat):
        on.append(fit(True))
        off.append(fit(False))
    row = {
        "trials": int(w.x.shape[0]),
        "grid": list(w.geometry.grid_shape or ()),
        "cpu_s_checked": min(on),
        "cpu_s_unchecked": min(off),
        "ratio_checked_over_unchecked": min(on) / min(off),
    }
    print(
        f"CNN-GRU res 18, one epoch on {row['trials']} trials, 1 thread: {min(on):.2f} CPU s checked, "
        f"{min(off):.2f} unchecked (ratio {row['ratio_checked_over_unchecked']:.3f})",
        flush=True,
    )
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    repeat = 3 if args.quick else 5
    out = {
        "machine": machine(),
        "frames": frames_rows(repeat),
        "cnn_gru_training": training_row(repeat, args.quick),
    }
    print(write_json("finite", out))


if __name__ == "__main__":
    main()
