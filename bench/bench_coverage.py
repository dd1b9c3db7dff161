"""Benchmark of the coverage analysis: maps, curves and the pairwise test matrix.

Target (issue 8): contact maps and the full pairwise test matrix for 8
gestures x 18 participants in under 2 minutes on 2 cores. The data and
contact stages come from the built-in synthetic study through the pipeline
(cached under ``outputs/cache``; their time is reported apart), then the
analysis is timed by phase: surface samples and kernel, contact footprints,
maps + curves (+ held-out check), the 28 paired SWD tests, and the files
(PNG renders, PLY, .npz, CSV). The files are then written again, in turn with
``formats=png`` and with the default PNG, PDF and SVG (``--format-rounds``
rounds, A B A B ...), and the ratio of the two medians is reported: what the
quick-look setting saves, measured in the same run. The machine (CPU model,
SIMD flags, load) is recorded beside the numbers.

    python bench/bench_coverage.py            # 18 participants x 20 repetitions, arm
    python bench/bench_coverage.py --quick    # 18 participants x 4 repetitions
    python bench/bench_coverage.py --region torso

Writes ``outputs/bench/coverage.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "outputs" / "bench"
TARGET_S = 120.0

sys.path.insert(0, str(HERE))
from _common import machine  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="4 repetitions per gesture instead of 20")
    parser.add_argument("--region", default="arm", help="skin region (arm or torso)")
    parser.add_argument("--participants", type=int, default=18)
    parser.add_argument("--no-render", action="store_true", help="skip PNG/PLY output")
    parser.add_argument(
        "--format-rounds", type=int, default=2, help="rounds of the formats=png vs PNG+PDF+SVG comparison (0: none)"
    )
    args = parser.parse_args()

    from sphri.analysis.coverage import ALL, write_region
    from sphri.cache import StageCache
    from sphri.config import compose
    from sphri.coverage import analysis_from, load_settings
    from sphri.figures import FORMATS, only_formats
    from sphri.pipeline import make_pipeline

    reps = 4 if args.quick else 20
    overrides = [f"data.participants={args.participants}", f"data.repetitions={reps}", f"data.regions=[{args.region}]"]
    cfg = compose(overrides)
    p = make_pipeline(cfg, StageCache(cfg.cache.dir, enabled=bool(cfg.cache.enabled)))
    t0 = time.perf_counter()
    dataset, contacts = p.get("data"), p.get("contact")
    robot, surface = p.get("robot"), p.get("surface")
    link = robot.link_for(args.region)
    t_stages = time.perf_counter() - t0

    settings = load_settings([f"render={'false' if args.no_render else 'true'}"])
    analysis = analysis_from(settings)
    t1 = time.perf_counter()
    result = analysis.analyze(dataset, contacts, link, surface, args.region)
    t2 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="sphri-bench-coverage-") as tmp:
        files = write_region(result, tmp, link, surface, settings.render, settings.views)
        n_files = len(files)
    t3 = time.perf_counter()

    def files_s(formats: tuple[str, ...]) -> float:
        with tempfile.TemporaryDirectory(prefix="sphri-bench-coverage-") as tmp, only_formats(formats):
            t = time.perf_counter()
            write_region(result, tmp, link, surface, True, settings.views)
            return time.perf_counter() - t

    rounds: dict[str, list[float]] = {"png": [], "png_pdf_svg": []}
    for _ in range(args.format_rounds if not args.no_render else 0):
        rounds["png"].append(files_s(("png",)))
        rounds["png_pdf_svg"].append(files_s(FORMATS))
    formats = {k: [round(v, 3) for v in vs] for k, vs in rounds.items()}
    if rounds["png"]:
        median = {k: statistics.median(vs) for k, vs in rounds.items()}
        formats["ratio_png_pdf_svg_to_png"] = round(median["png_pdf_svg"] / median["png"], 2)

    total = t3 - t1
    table = result.comparison.table if result.comparison is not None else None
    out = {
        "machine": machine(),
        "mode": "quick" if args.quick else "full",
        "region": args.region,
        "link": link.name,
        "participants": int(dataset.trials["participant"].nunique()),
        "repetitions": reps,
        "gestures": len(result.groups),
        "trials": int(len(dataset.trials)),
        "frames": int(dataset.n_frames),
        "contact_rows": int(contacts.n_contacts),
        "contact_frames": int(result.curves[ALL].n_frames),
        "elements": int(result.samples.n),
        "pairs_tested": int(len(table)) if table is not None else 0,
        "pairs_significant": int(table["significant"].sum()) if table is not None else 0,
        "permutations": sorted({int(x) for x in table["n_permutations"]}) if table is not None else [],
        "area_share_for_90pct_all": float(result.curves[ALL].area_at_capture),
        "seconds": {
            "stages_data_contact_surface": round(t_stages, 3),
            **{k: round(v, 3) for k, v in result.seconds.items() if k != "render"},
            "analysis": round(t2 - t1, 3),
            "files": round(t3 - t2, 3),
            "render": round(result.seconds.get("render", 0.0), 3),
            "total_maps_tests_files": round(total, 3),
        },
        "files_seconds_by_formats": formats,
        "n_files": n_files,
        "target_s": TARGET_S,
        "meets_target": bool(total < TARGET_S),
    }
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "coverage.json").write_text(json.dumps(out, indent=2))
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
