"""Benchmark the recorder's partial file: frames per second :class:`PartialWriter` takes.

    python bench/bench_recording.py [--frames 20000] [--taxels 108] [--dir DIR] [--out FILE]

Appends ``--frames`` frames of ``--taxels`` float32 values to a
``PartialWriter`` in ``--dir`` (default: a folder under outputs/bench, i.e.
the disk the recordings go to) with ``chunk_frames=50`` and reports frames
per second, median and p99 microseconds per append. Run it against an
older checkout (``PYTHONPATH=<checkout>``) to compare writers; a skin
streams 100-1000 frames per second, so any rate far above that costs
nothing. Writes JSON to ``--out`` (default ``outputs/bench/recording.json``).
"""

from __future__ import annotations

import argparse
import inspect
import json
import shutil
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "outputs" / "bench"


def bench(n_frames: int, n_taxels: int, folder: Path, repeats: int = 3) -> dict:
    import sphri.hardware.recording as recording

    rng = np.random.default_rng(0)
    values = (rng.random((256, n_taxels)) < 0.1).astype(np.float32)
    kw = {"sync_interval_s": 1.0} if "sync_interval_s" in inspect.signature(recording.PartialWriter).parameters else {}
    rates, per = [], []
    for r in range(repeats):
        d = folder / f"run{r}"
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        w = recording.PartialWriter(d / "rec.npz", chunk_frames=50, **kw)
        t_each = np.empty(n_frames)
        t0 = time.perf_counter()
        for i in range(n_frames):
            a = time.perf_counter()
            w.append(values[i % 256], time.time(), i * 1000, i & 0xFFFF, 0)
            t_each[i] = time.perf_counter() - a
        w.flush()
        wall = time.perf_counter() - t0
        w.remove()
        rates.append(n_frames / wall)
        per.append(t_each)
    each = np.concatenate(per) * 1e6
    return {
        "module": recording.__file__,
        "frames": n_frames,
        "taxels": n_taxels,
        "repeats": repeats,
        "frames_per_s": [round(x) for x in rates],
        "frames_per_s_median": round(float(np.median(rates))),
        "append_us_median": round(float(np.median(each)), 2),
        "append_us_p99": round(float(np.percentile(each, 99)), 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20_000)
    ap.add_argument("--taxels", type=int, default=108)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", type=Path, default=OUT / "recording_tmp")
    ap.add_argument("--out", type=Path, default=OUT / "recording.json")
    a = ap.parse_args()
    res = bench(a.frames, a.taxels, a.dir, a.repeats)
    shutil.rmtree(a.dir, ignore_errors=True)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(res, indent=2) + "\n")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
