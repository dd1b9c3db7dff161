"""Benchmark the spatial skin filter ``filter=despeckle``: time per 1000 frames at res 18 and 50.

Windows are :func:`sphri.testing.blob_windows` (elliptical touches on the
24.1 x 26 cm synthetic arm, 1 % of readings flipped: the false-on rate of the
default 2 % replace noise), 200 trials x 50 frames = 10,000 frames per
resolution, on the wrapped grid (res 18: 18 x 19 taxels; res 50: 50 x 54)
and on the scattered layout of the same count (the neighbour-graph path).
The filter runs at the default ``min_area_mm2`` (100) and at 200. Reports the
best of 3 runs (wall and CPU seconds) per 1000 frames, and the share of
on-readings cleared. Writes ``outputs/bench/despeckle.json``.

Run: ``python bench/bench_despeckle.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, timeit, write_json  # noqa: E402

from sphri.filter.components import DespeckleFilter  # noqa: E402
from sphri.testing.toy_windows import blob_windows  # noqa: E402


def main() -> None:
    out: dict = {"machine": machine(), "frames": 10_000, "rows": []}
    for layout in ("grid", "scatter"):
        for res in (18, 50):
            w = blob_windows(participants=5, repetitions=5, res=res, length=50, noise_p=0.01, layout=layout)
            frames = w.x.shape[0] * w.x.shape[1]
            for area in (100.0, 200.0):
                flt = DespeckleFilter(min_area_mm2=area)
                t = timeit(lambda: flt.apply(w), repeat=3)
                on = w.x >= 0.5
                cleared = float((on & (flt.apply(w).x < 0.5)).sum() / on.sum())
                row = {
                    "layout": layout,
                    "res": res,
                    "taxels": w.x.shape[2],
                    "min_area_mm2": area,
                    "s_per_1000_frames": t["best_s"] * 1000 / frames,
                    "cpu_s_per_1000_frames": t["cpu_s"] * 1000 / frames,
                    "cleared_share": cleared,
                }
                out["rows"].append(row)
                print(
                    f"{layout:7s} res {res:2d} ({row['taxels']} taxels) min_area {area:5.0f} mm^2: "
                    f"{row['s_per_1000_frames'] * 1e3:6.1f} ms per 1000 frames (CPU {row['cpu_s_per_1000_frames'] * 1e3:6.1f} ms), "
                    f"cleared {cleared:.1%} of on-readings"
                )
    print(
        f"load average {out['machine']['loadavg_1min']:.1f} on {out['machine']['cpu_count']} cores; "
        f"written {write_json('despeckle', out)}"
    )


if __name__ == "__main__":
    main()
