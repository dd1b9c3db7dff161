"""Benchmark the data stage: synthetic generation, writing and loading the recorded layout.

Writes ``outputs/bench/data.json``. Full mode generates the study's size (18
participants x 8 gestures x 20 repetitions) on the arm, then on arm + torso
(target: under 30 s on 2 cores), writes the arm dataset in the recorded layout
and loads it back with ``data=vr_gesture`` (checking the poses are identical).
``--quick`` uses 4 participants.

    python bench/bench_data.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
from hydra.utils import instantiate

from sphri.config import component_node
from sphri.data.synthetic import SyntheticData
from sphri.data.vr_gesture import VRGestureData
from sphri.data.writer import write_dataset

OUT = Path(__file__).resolve().parent.parent / "outputs" / "bench"


def component(group: str, name: str):
    return instantiate(component_node(group, name), _convert_="all")


def timed(fn):
    t = time.perf_counter()
    c = time.process_time()
    out = fn()
    timed.cpu = time.process_time() - c
    return out, time.perf_counter() - t


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="4 participants instead of 18")
    args = parser.parse_args()
    result_load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    participants = 4 if args.quick else 18
    hand = component("hand", "quest_capsules").build()
    robot = component("robot", "reachy").build()
    result: dict = {
        "participants": participants,
        "repetitions": 20,
        "cpu_count": os.cpu_count(),
        "robot": robot.name,
        "load_average_at_start": round(result_load, 2),
    }
    for regions in (["arm"], ["arm", "torso"]):
        gen = SyntheticData(participants=participants, repetitions=20, regions=regions)
        ds, dt = timed(lambda: gen.load(hand=hand, robot=robot))
        key = "+".join(regions)
        result[f"generate_{key}"] = {
            "seconds": round(dt, 3),
            "cpu_seconds": round(timed.cpu, 3),
            "trials": len(ds.trials),
            "frames": ds.n_frames,
            "frames_per_second": round(ds.n_frames / dt),
            "under_30s": bool(dt < 30.0),
        }
        print(
            f"generate {key}: {len(ds.trials)} trials, {ds.n_frames} frames in {dt:.2f} s ({timed.cpu:.2f} s CPU)",
            flush=True,
        )
        if regions == ["arm"]:
            arm = ds
    with tempfile.TemporaryDirectory() as tmp:
        _, dt_w = timed(lambda: write_dataset(arm, robot, tmp))
        size = sum(p.stat().st_size for p in Path(tmp).rglob("*") if p.is_file())
        loaded, dt_l = timed(lambda: VRGestureData(root=tmp, regions=["arm"]).load(hand=hand, robot=robot))
        sub, dt_s = timed(
            lambda: VRGestureData(root=tmp, regions=["arm"], gestures=["poke"]).load(hand=hand, robot=robot)
        )
    identical = bool(np.array_equal(loaded.poses, arm.poses) and loaded.trials.equals(arm.trials))
    result["write_arm"] = {"seconds": round(dt_w, 3), "megabytes": round(size / 1e6, 1)}
    result["load_arm"] = {"seconds": round(dt_l, 3), "identical_to_generated": identical}
    result["load_arm_one_gesture"] = {"seconds": round(dt_s, 3), "trials": len(sub.trials)}
    print(
        f"write {dt_w:.2f} s ({size / 1e6:.1f} MB), load {dt_l:.2f} s (identical: {identical}), "
        f"one gesture {dt_s:.2f} s",
        flush=True,
    )
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "data.json").write_text(json.dumps(result, indent=2) + "\n")
    return 0 if identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
