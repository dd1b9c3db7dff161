"""Benchmark the hardware path: skin decoding throughput and live prediction rate.

    python bench/bench_hardware.py [--quick]

1. Decoder: frames per second that :class:`SkinDecoder` turns from bytes
   into arrays (306-taxel frames, the default resolution's grid), clean and
   with 5 % corrupt frames.
2. Model: the configured Random Forest (``model=rf``, 100 trees) trained on
   the synthetic pipeline's windows; milliseconds per single-window
   ``predict_proba`` and per :meth:`LiveClassifier.push` (touch detection).
3. End to end: the skin simulator streams synthetic trials in real time over
   a socket to ``skin live``; predictions per second actually delivered and
   their latency (frame arrival to prediction).

Writes ``outputs/bench/hardware.json``. The requirement: at least 10
predictions per second on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parent.parent / "outputs" / "bench"


def bench_decoder(n_frames: int, n_taxels: int = 306) -> dict:
    from sphri.hardware.skin_protocol import SkinDecoder, ValueFormat, encode_frame

    rng = np.random.default_rng(0)
    out = {}
    for fmt in (ValueFormat.BITS, ValueFormat.U8):
        frames = [encode_frame(i, i * 33333, (rng.random(n_taxels) < 0.05).astype(float), fmt) for i in range(n_frames)]
        for label, corrupt in (("clean", 0.0), ("corrupt5pct", 0.05)):
            blobs = []
            for f in frames:
                if rng.random() < corrupt:
                    b = bytearray(f)
                    b[len(b) // 2] ^= 0xFF
                    f = bytes(b)
                blobs.append(f)
            data = b"".join(blobs)
            dec = SkinDecoder(expected_taxels=n_taxels)
            t0 = time.perf_counter()
            got = 0
            for i in range(0, len(data), 4096):
                got += len(dec.feed(data[i : i + 4096]))
            dt = time.perf_counter() - t0
            out[f"{fmt.name.lower()}_{label}_frames_per_s"] = got / dt
    return out


def bench_model(overrides: list[str], reps: int) -> tuple[dict, Path]:
    from sphri.export.model_file import save_model
    from sphri.export.train import fit_bundle, training_windows
    from sphri.hardware.live import LiveClassifier, auto_stride
    from sphri.hardware.source import open_pipeline

    p = open_pipeline(overrides)
    t0 = time.perf_counter()
    bundle = fit_bundle(p, None, overrides)
    fit_s = time.perf_counter() - t0
    path = save_model(bundle, OUT / "hardware_rf.sphrimodel")
    x = training_windows(p).x
    times = []
    for i in range(reps):
        t = time.perf_counter()
        bundle.predict_proba(x[i % len(x)][None])
        times.append((time.perf_counter() - t) * 1000)
    clf = LiveClassifier(bundle, stride=10**9, cluster_taxels=6)
    flat = x.reshape(-1, x.shape[-1])[:3000]
    t = time.perf_counter()
    for f in flat:
        clf.push(f)
    push_ms = (time.perf_counter() - t) * 1000 / len(flat)
    ms = float(np.median(times))
    return {
        "n_taxels": int(bundle.n_taxels),
        "window_frames": int(bundle.window_length),
        "frame_rate_hz": float(bundle.frame_rate_hz),
        "n_train": int(bundle.meta["n_train"]),
        "fit_s": fit_s,
        "predict_ms_median": ms,
        "predict_ms_p95": float(np.percentile(times, 95)),
        "push_ms_per_frame": push_ms,
        "capacity_predictions_per_s": 1000.0 / (ms + push_ms * auto_stride(bundle.frame_rate_hz)),
    }, path


def bench_end_to_end(overrides: list[str], model: Path, trials: int, rate_hz: float) -> dict:
    from sphri.hardware.settings import SkinLiveSettings
    from sphri.hardware.simulate import SkinSimSettings, SkinSimulator, make_endpoint, pipeline_stream, start_in_thread
    from sphri.hardware.skin import live

    stream = pipeline_stream(overrides, trials, None, 0.5, 1)
    s = SkinSimSettings(port="socket://127.0.0.1:0", realtime=True, rate_hz=rate_hz, hold_s=30.0)
    sim = SkinSimulator(stream, s, make_endpoint(s), say=lambda m: None)
    th = start_in_thread(sim)
    try:
        summary = live(
            SkinLiveSettings(port=sim.endpoint.url, model=str(model), idle_s=0.5, show="off"), out=lambda m: None
        )
    finally:
        sim.stop.set()
        th.join(10)
    keys = (
        "frames",
        "predictions",
        "touches",
        "stream_rate_hz",
        "predictions_per_s",
        "latency_ms_median",
        "latency_ms_p95",
        "model_ms_mean",
        "capacity_predictions_per_s",
    )
    return {k: summary[k] for k in keys}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes")
    args = parser.parse_args()
    logging.basicConfig(level=logging.ERROR)
    OUT.mkdir(parents=True, exist_ok=True)
    overrides = ["+debug=fast", f"output_dir={OUT.parent}"] + (["data.participants=2"] if args.quick else [])
    result = {"cores": os.cpu_count(), "decoder": bench_decoder(1000 if args.quick else 5000)}
    result["model"], path = bench_model(overrides, 50 if args.quick else 300)
    # 30 Hz frames (the synthetic data's rate) in real time
    result["live"] = bench_end_to_end(overrides, path, 3 if args.quick else 8, result["model"]["frame_rate_hz"])
    result["meets_10_predictions_per_s"] = bool(
        result["live"]["predictions_per_s"] >= 10.0 and result["model"]["capacity_predictions_per_s"] >= 10.0
    )
    (OUT / "hardware.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result, indent=1))
    return 0 if result["meets_10_predictions_per_s"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
