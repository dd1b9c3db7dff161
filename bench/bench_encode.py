"""Benchmark the encoders: speed at full dataset size and error against references.

Writes ``outputs/bench/encode.json``. Contacts are synthetic with the real
study's statistics (``sphri.testing.synthetic_contacts``: 3-8 capsules per contact frame,
finger-sized patches, 70 % of window frames in contact) on the Reachy arm hull
from ../shared when present, else on a cylinder of the same size. Full size is
2,880 trials x 50 window frames = 144,000 frames (``--quick``: 20,000).

Per resolution (18, 50, 200 taxels along the arm):

- times (wall and CPU) of ``ellipse``, ``coverage`` (grid raster and, on a
  random layout of the same count, 3-D taxel discs) and ``proximity``;
  res 200 is encoded in 36,000-frame calls (its output is 5.4 GB at full size);
- ``ellipse`` error: IoU of the binary raster against a supersampled raster of
  the same ellipses, and the covered-fraction error (``binary: false``);
- ``coverage`` on the random layout: error against 4096 samples per taxel;
- ``proximity`` has no sampling (it is compared with brute force in the tests);
- ratio: fast raster vs the brute-force supersampled reference, same frames.

Run: ``python bench/bench_encode.py [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402

from sphri.encode.common import select_rows  # noqa: E402
from sphri.encode.coverage import CoverageEncoder, encode_3d_coverage  # noqa: E402
from sphri.encode.ellipse import EllipseEncoder  # noqa: E402
from sphri.encode.proximity import ProximityEncoder  # noqa: E402
from sphri.encode.raster import patch_ellipses  # noqa: E402
from sphri.layout.common import row_offsets  # noqa: E402
from sphri.layout.grid import GridLayout  # noqa: E402
from sphri.layout.poisson import RandomLayout  # noqa: E402
from sphri.layout.units import describe  # noqa: E402
from sphri.surface.cylinder import CylinderSurface  # noqa: E402
from sphri.surface.meshutil import link_from_trimesh  # noqa: E402
from sphri.testing.raster_reference import iou, reference_raster  # noqa: E402
from sphri.testing.synthetic_contacts import synthetic_contacts  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("SPHRI_SHARED", REPO.parent / "shared"))
FULL_FRAMES = 2880 * 50
CHUNK = 36_000  # frames per encode call at res 200 (bounds the output's memory)
GOALS_S = {18: 5.0, 50: 15.0}  # full-size ellipse encoding budgets on 2 cores


def load_link():
    arm = SHARED / "vr-gesture-dataset/assets/arm_mesh.obj"
    if arm.is_file():
        return link_from_trimesh(trimesh.load(arm, process=False), "reachy_l_arm"), "reachy arm hull (../shared)"
    mesh = trimesh.creation.cylinder(radius=0.036, height=0.241, sections=64)
    return link_from_trimesh(mesh, "cylinder"), "cylinder r=36 mm, 241 mm (../shared absent)"


def timed_encode(enc, contacts, link, surface, layout, frame_index, chunk):
    """Wall and CPU seconds to encode ``frame_index`` in calls of ``chunk`` frames, and the non-zeros."""
    enc.encode(contacts, link, surface, layout, frame_index[:500])  # compile / warm up
    t0, c0 = time.perf_counter(), time.process_time()
    nnz = 0
    for i in range(0, len(frame_index), chunk):
        out = enc.encode(contacts, link, surface, layout, frame_index[i : i + chunk]).values
        nnz += int(np.count_nonzero(out))
        del out
    return time.perf_counter() - t0, time.process_time() - c0, nnz


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20,000 frames instead of 144,000")
    ap.add_argument("--frames", type=int, default=None, help="frames to encode (default 144,000; quick 20,000)")
    args = ap.parse_args(argv)
    frames = args.frames or (20_000 if args.quick else FULL_FRAMES)
    n_err = 150 if args.quick else 400

    link, link_desc = load_link()
    surface = CylinderSurface().fit(link)
    t0 = time.perf_counter()
    contacts = synthetic_contacts(link, frames, contact_fraction=0.7, seed=0)
    t_synth = time.perf_counter() - t0
    fi = np.arange(frames, dtype=np.int64)
    per_frame = np.bincount(contacts.frame, minlength=frames)
    info = {
        **machine(),
        "numba_threads": numba.get_num_threads(),
        "link": link_desc,
        "surface_fit_residual_mm": surface.fit_residual_m * 1e3,
        "frames": frames,
        "full_size": frames == FULL_FRAMES,
        "contacts": contacts.n_contacts,
        "contact_frames": int((per_frame > 0).sum()),
        "contacts_per_contact_frame": float(per_frame[per_frame > 0].mean()),
        "synthesis_s": t_synth,
        "note": "*_s: wall seconds; *_cpu_s: CPU seconds of all threads (less sensitive to other jobs)",
    }
    err_fi = fi[np.flatnonzero(per_frame > 0)[:n_err]]
    results, goal, ratios = {}, {}, {}
    for res in (18, 50, 200):
        layout = GridLayout().build(link, surface, res)
        units = describe(layout, surface)
        chunk = frames if res <= 50 else CHUNK
        entry = {"grid_shape": list(layout.grid_shape), "pitch_u_mm": units["pitch_u_mm"], "n_taxels": layout.n_taxels}
        for name, enc in (
            ("ellipse", EllipseEncoder()),
            ("coverage_grid", CoverageEncoder()),
            ("proximity", ProximityEncoder()),
        ):
            secs, cpu, nnz = timed_encode(enc, contacts, link, surface, layout, fi, chunk)
            entry[f"{name}_s"] = secs
            entry[f"{name}_cpu_s"] = cpu
            entry[f"{name}_active_fraction"] = nnz / (frames * layout.n_taxels)
        # errors against the supersampled reference, and the speed ratio on the same frames
        ss = 32 if res < 200 else 8
        rows, start = select_rows(contacts, err_fi)
        ell = patch_ellipses(
            surface, contacts.point_m[rows], contacts.normal[rows], contacts.patch_radius_m[rows], layout.grid_shape
        )
        off = row_offsets(layout.uv, layout.grid_shape)
        t_ref = time.perf_counter()
        ref_b = reference_raster(start, *ell, layout.grid_shape, off, surface.wrap_v, ss, True)
        t_ref = time.perf_counter() - t_ref
        ref_c = reference_raster(start, *ell, layout.grid_shape, off, surface.wrap_v, ss, False)
        t_fast = time.perf_counter()
        fast_b = EllipseEncoder().encode(contacts, link, surface, layout, err_fi).values
        t_fast = time.perf_counter() - t_fast
        fast_c = EllipseEncoder(binary=False).encode(contacts, link, surface, layout, err_fi).values
        entry["reference_subsamples"] = ss
        entry["ellipse_iou_vs_supersampled"] = iou(fast_b, ref_b)
        entry["ellipse_coverage_mae_vs_supersampled"] = float(np.abs(fast_c - ref_c).mean())
        entry["ellipse_coverage_max_err_vs_supersampled"] = float(np.abs(fast_c - ref_c).max())
        ratios[f"res_{res}_ellipse_speedup_vs_reference"] = t_ref / max(t_fast, 1e-9)
        # coverage on a non-grid layout with the same taxel count
        rnd = RandomLayout().build(link, surface, res)
        secs, cpu, _ = timed_encode(CoverageEncoder(), contacts, link, surface, rnd, fi, chunk)
        entry["coverage_random_s"] = secs
        entry["coverage_random_cpu_s"] = cpu
        fast = encode_3d_coverage(contacts, surface, rnd, err_fi, 32, "bench").values
        ref = encode_3d_coverage(contacts, surface, rnd, err_fi, 4096, "bench").values
        entry["coverage_random_mae_vs_4096_samples"] = float(np.abs(fast - ref).mean())
        results[f"res_{res}"] = entry
        if res in GOALS_S:
            scaled = entry["ellipse_s"] * FULL_FRAMES / frames
            goal[f"res_{res}_ellipse_full_size_s"] = scaled
            goal[f"res_{res}_budget_s"] = GOALS_S[res]
            goal[f"res_{res}_met"] = bool(scaled < GOALS_S[res])
        print(
            f"res {res}: ellipse {entry['ellipse_s']:.2f} s, IoU {entry['ellipse_iou_vs_supersampled']:.4f}", flush=True
        )

    info["loadavg_1min_end"] = machine()["loadavg_1min"]
    path = write_json("encode", {"info": info, "goal": goal, "ratios": ratios, "results": results})
    print(f"wrote {path}")
    return results


if __name__ == "__main__":
    main()
