"""Benchmark of the whole-body scenario study: contact on many links, and the study end to end.

1. Contact. The whole-body pass (both hands, 19 capsules each, against all 15
   links of robot=reachy_full at each frame's pose, bounding-sphere culling)
   against the same pass without culling and against the arm-only contact
   stage (one hand, one link: ``contact=exact`` on the synthetic gesture
   study's arm trials), in microseconds per frame, after a warm-up.
2. The study. ``sphri coverage +experiment=scenario_study`` from an
   empty cache (12 participants x 5 scenarios x 3 repetitions; ``--quick``:
   +debug=fast, 3 x 5 x 2), per phase, MLflow off.

    python bench/bench_scenario_study.py            # full study
    python bench/bench_scenario_study.py --quick

Writes ``outputs/bench/scenario_study.json`` (``scenario_study_quick.json`` with --quick).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _common import machine, timeit, write_json  # noqa: E402


def contact_bench(quick: bool) -> dict:
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.sessions.contact import body_contacts

    size = ["data.participants=3", "data.repetitions=1"] if quick else ["data.participants=12", "data.repetitions=1"]
    cfg = compose(["data=synthetic_sessions", "robot=reachy_full", *size])
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    ds = instantiate(cfg.data).load(hand, robot)
    stage = instantiate(cfg.contact)
    body_contacts(ds, robot, stage)  # warm-up (numba)
    culled = timeit(lambda: body_contacts(ds, robot, stage), repeat=3)
    bc = body_contacts(ds, robot, stage)
    full = timeit(lambda: body_contacts(ds, robot, stage, cull=False), repeat=1)
    acfg = compose(["data.participants=3", "data.repetitions=4" if quick else "data.repetitions=10"])
    ahand, arobot = instantiate(acfg.hand).build(), instantiate(acfg.robot).build()
    arm = instantiate(acfg.data).load(ahand, arobot)
    astage = instantiate(acfg.contact)
    astage.compute(arm, arobot)
    arm_t = timeit(lambda: astage.compute(arm, arobot), repeat=3)
    us = lambda t, n: 1e6 * t["best_s"] / n  # noqa: E731
    touched = len(set(zip(bc.frame.tolist(), bc.link.tolist())))
    return {
        "whole_body": {
            "frames": ds.n_frames,
            "links": len(ds.links),
            "hands": 2,
            "us_per_frame": us(culled, ds.n_frames),
            "cpu_s": culled["cpu_s"],
            "triples": bc.stats["triples"],
            "triples_tested": bc.stats["tested"],
            "share_tested": bc.stats["tested"] / bc.stats["triples"],
            "frame_link_pairs_touched": touched,
            "contact_rows": bc.n_contacts,
        },
        "whole_body_no_culling": {"us_per_frame": us(full, ds.n_frames), "cpu_s": full["cpu_s"]},
        "arm_only_stage": {"frames": arm.n_frames, "links": 1, "hands": 1, "us_per_frame": us(arm_t, arm.n_frames)},
        "culling_speedup": full["best_s"] / culled["best_s"],
        "whole_body_vs_arm_only_per_frame": us(culled, ds.n_frames) / us(arm_t, arm.n_frames),
    }


def study_bench(quick: bool) -> dict:
    from sphri.sessions.study import run_study

    with tempfile.TemporaryDirectory() as tmp:
        ov = ["+experiment=scenario_study", f"output_dir={tmp}", f"cache.dir={tmp}/cache"] + (
            ["+debug=fast"] if quick else []
        )
        t0 = time.perf_counter()
        c0 = time.process_time()
        res = run_study(ov, out=Path(tmp) / "study", log_mlflow=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        t1 = time.perf_counter()
        run_study(ov, out=Path(tmp) / "study2", log_mlflow=False)  # sessions and contacts from the stage cache
        again = time.perf_counter() - t1
    s = res.sessions
    return {
        "participants": int(s["participant"].nunique()),
        "scenarios": int(s["scenario"].nunique()),
        "repetitions": int(s["repetition"].max()),
        "sessions": len(s),
        "coded_episodes": len(res.coded),
        "wall_s": wall,
        "cpu_s": cpu,
        "rerun_with_cache_s": again,
        "phases_s": {k: round(v, 2) for k, v in res.seconds.items()},
        "gesture_model_loso_accuracy": res.gesture_accuracy,
        "sentences": res.sentences,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="debug sizes")
    args = parser.parse_args()
    import logging

    logging.basicConfig(level=logging.WARNING)
    data = {
        "mode": "quick" if args.quick else "full",
        "machine": machine(),
        "contact": contact_bench(args.quick),
        "study": study_bench(args.quick),
    }
    path = write_json("scenario_study_quick" if args.quick else "scenario_study", data)
    c, st = data["contact"], data["study"]
    print(
        f"contact: whole body {c['whole_body']['us_per_frame']:.0f} us/frame ({100 * c['whole_body']['share_tested']:.1f} % "
        f"of (frame, hand, link) triples tested), no culling {c['whole_body_no_culling']['us_per_frame']:.0f}, "
        f"arm-only stage {c['arm_only_stage']['us_per_frame']:.0f}"
    )
    print(
        f"study: {st['sessions']} sessions in {st['wall_s']:.1f} s wall ({st['cpu_s']:.1f} s CPU); rerun {st['rerun_with_cache_s']:.1f} s"
    )
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
