"""Benchmark the link geometry the stages ask for: first call on a link, and again on the same mesh.

On the study's arm hull (``../shared``; the parametric stand-in of
:func:`sphri.testing.contact_reference.arm_stand_in` when absent) it times,
in one process, what the chain and the analyses compute from a link's mesh:
the cylinder chart (``surface=cylinder``), the synthetic generator's
:class:`~sphri.data.linkgeom.LinkSurface`, the coverage analysis' surface
elements and geodesic kernel (``sample_link`` + ``SurfaceKernel``),
closest points (``layout=file``) and projection along normals (layouts),
and the contact kernels' acceleration data (``prepare_mesh``). Each step
runs on a fresh :class:`~sphri.types.Link` (``first``), then on another
fresh ``Link`` with the same mesh, as the next job of a sweep loads it
(``again``). Only public functions that predate :mod:`sphri.geometry` are
called, so the script runs unchanged on an older checkout for a
before/after comparison on the same machine.

Wall and CPU seconds (all threads) per step; the JSON records the load
average. Writes ``outputs/bench/geometry.json``.

    python bench/bench_geometry.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402

from sphri.contact import prepare_mesh  # noqa: E402
from sphri.data.linkgeom import LinkSurface  # noqa: E402
from sphri.surface.cylinder import fit_cylinder  # noqa: E402
from sphri.surface.density import SurfaceKernel, sample_link  # noqa: E402
from sphri.surface.meshutil import closest_points, project_along, sample_surface  # noqa: E402
from sphri.testing.contact_reference import arm_stand_in  # noqa: E402
from sphri.types import Link  # noqa: E402

SHARED_ARM = Path(__file__).resolve().parents[2] / "shared" / "vr-gesture-dataset" / "assets" / "arm_mesh.obj"


def arm() -> tuple[np.ndarray, np.ndarray, str]:
    if SHARED_ARM.is_file():
        import trimesh

        m = trimesh.load(SHARED_ARM, process=False, force="mesh")
        return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64), "shared arm_mesh.obj"
    v, f = arm_stand_in()
    return v, f, "parametric arm stand-in"


def steps(v: np.ndarray, f: np.ndarray) -> dict:
    rng = np.random.default_rng(0)
    queries = rng.normal(scale=0.03, size=(2000, 3)) + v.mean(axis=0)

    def on_surface(link: Link) -> None:
        pts, face = sample_surface(link, 2000, 7)
        project_along(link, pts + 0.002, np.tile([1.0, 0.0, 0.0], (len(pts), 1)), 0.01)

    return {
        "surface_cylinder": lambda link: fit_cylinder(link),
        "link_surface": lambda link: LinkSurface(link),
        "coverage_elements_kernel": lambda link: SurfaceKernel(sample_link(link, 4.0, 0), 10.0),
        "closest_points_x5": lambda link: [closest_points(link, queries) for _ in range(5)],
        "project_along": on_surface,
        "prepare_mesh": lambda link: prepare_mesh(link.vertices, link.faces, "auto"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="'again' calls per step (the best is reported)")
    args = ap.parse_args()
    v, f, source = arm()
    out: dict = {"mesh": source, "faces": int(len(f)), "machine": machine(), "steps": {}}
    # warm-up on another mesh: imports, numba caches, first calls
    wv, wf = arm_stand_in(n_around=12)
    for fn in steps(wv, wf).values():
        fn(Link("warm", wv, wf, False))
    for name, fn in steps(v, f).items():
        row = {}
        for label, n in (("first", 1), ("again", args.repeat)):
            best = (np.inf, np.inf)
            for _ in range(n):
                link = Link("l_arm", v.copy(), f.copy(), False)
                w0, c0 = time.perf_counter(), time.process_time()
                fn(link)
                best = min(best, (time.perf_counter() - w0, time.process_time() - c0))
            row[f"{label}_wall_s"], row[f"{label}_cpu_s"] = best
        out["steps"][name] = row
        print(
            f"{name:26s} first {row['first_wall_s']:.3f} s wall ({row['first_cpu_s']:.3f} cpu)   "
            f"again {row['again_wall_s']:.3f} s wall ({row['again_cpu_s']:.3f} cpu)"
        )
    print(f"{source}, {len(f)} faces; load {out['machine'].get('loadavg_1min')}")
    print(f"wrote {write_json('geometry', out)}")


if __name__ == "__main__":
    main()
