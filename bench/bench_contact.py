"""Benchmark the contact engine: exact capsules vs k spheres vs trimesh.proximity.

On the hard set (capsules of radius 1-2.5 cm and height 5-9 cm around the
study's arm hull, 30 % near the surface, 1 % wholly inside; a parametric
stand-in when ../shared is absent) it measures, in one run:

- ``contact=exact`` (``capsule_mesh_query``): capsules per second, and its
  disagreements with the brute-force float64 reference on every capsule;
- ``contact=spheres`` for k = 1, 3, 5, 9, 17: speed and error against the
  same reference (distance error, contact disagreements, missed insides);
- ``trimesh.proximity.closest_point`` on 5 spheres per capsule (the paper's
  tool), on a subsample;
- the numpy reference itself, and a far-dominated stream like real data.

Absolute times depend on the machine and on what else runs on it (the JSON
records the load average): read the ratios, measured in the same run. CPU
seconds (all threads) are reported beside wall seconds. Writes
``outputs/bench/contact.json`` and ``outputs/bench/contact.png``.

    python bench/bench_contact.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import OUT, figure, machine, timeit, write_json  # noqa: E402

from sphri.contact import capsule_mesh_query, prepare_mesh, sphere_mesh_query  # noqa: E402
from sphri.testing.contact_reference import arm_stand_in, compare, random_capsules, reference_query  # noqa: E402

SHARED_ARM = Path(__file__).resolve().parents[2] / "shared" / "vr-gesture-dataset" / "assets" / "arm_mesh.obj"
SPHERE_KS = (1, 3, 5, 9, 17)


def load_arm() -> tuple[np.ndarray, np.ndarray, str]:
    if SHARED_ARM.is_file():
        import trimesh

        m = trimesh.load(SHARED_ARM, process=False)
        return np.asarray(m.vertices), np.asarray(m.faces), "shared arm_mesh.obj"
    v, f = arm_stand_in()
    return v, f, "parametric stand-in (../shared absent)"


def sphere_errors(dist, in_contact, ref, r) -> dict:
    """Errors of an approximation against the exact reference."""
    outside_contact = ref.in_contact & ~ref.inside
    err = np.abs(dist - ref.distance)[outside_contact & np.isfinite(dist)]
    return {
        "contact_disagreements": int((in_contact != ref.in_contact).sum()),
        "missed_contacts": int((ref.in_contact & ~in_contact).sum()),
        "false_contacts": int((in_contact & ~ref.in_contact).sum()),
        "missed_inside": int((ref.inside & ~in_contact).sum()),
        "max_distance_error_m": float(err.max()) if err.size else 0.0,
        "p99_distance_error_m": float(np.quantile(err, 0.99)) if err.size else 0.0,
    }


def trimesh_spheres(v, f, p0, p1, r, k=5):
    import trimesh

    mesh = trimesh.Trimesh(v, f, process=False)
    ts = np.linspace(0.0, 1.0, k)
    centres = (p0[:, None, :] + ts[None, :, None] * (p1 - p0)[:, None, :]).reshape(-1, 3)
    _, d, _ = trimesh.proximity.closest_point(mesh, centres)
    d = d.reshape(-1, k).min(axis=1)
    return d, d < r


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="20,000 capsules instead of 200,000")
    args = ap.parse_args()
    n = 20_000 if args.quick else 200_000
    n_trimesh = 300 if args.quick else 2_000
    import numba

    v, f, source = load_arm()
    info = {"mesh": source, "faces": int(len(f)), "n_capsules": n, "threads": numba.get_num_threads()}
    info.update(machine())
    p0, p1, r, kind = random_capsules(v, f, n, seed=0)
    t0 = time.perf_counter()
    capsule_mesh_query(v, f, p0[:100], p1[:100], r[:100])  # compile (cached after the first run)
    sphere_mesh_query(v, f, p0[:100], p1[:100], r[:100], k=3)
    info["compile_or_cache_load_s"] = time.perf_counter() - t0
    info["inside_mode"] = prepare_mesh(v, f).inside_mode
    print(f"{source}: {len(f)} faces, {n} capsules, {info['threads']} threads, load {info['loadavg_1min']:.1f}")

    # the reference (every capsule, float64, no culling)
    t0, c0 = time.perf_counter(), time.process_time()
    ref = reference_query(v, f, p0, p1, r, inside=info["inside_mode"])
    ref_t = {"best_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
    print(f"reference: {n / ref_t['best_s']:,.0f} capsules/s")

    results = {}
    q = capsule_mesh_query(v, f, p0, p1, r)
    t = timeit(lambda: capsule_mesh_query(v, f, p0, p1, r), repeat=5)
    results["exact"] = {
        **t,
        "capsules_per_s": n / t["best_s"],
        "capsules_per_cpu_s": n / t["cpu_s"],
        **compare(q, ref, r),
    }
    print(f"exact: {n / t['best_s']:,.0f} capsules/s (cpu: {n / t['cpu_s']:,.0f}/s), {compare(q, ref, r)}")
    for k in SPHERE_KS:
        s = sphere_mesh_query(v, f, p0, p1, r, k=k)
        t = timeit(lambda k=k: sphere_mesh_query(v, f, p0, p1, r, k=k), repeat=3)
        results[f"spheres_k{k}"] = {
            **t,
            "capsules_per_s": n / t["best_s"],
            "capsules_per_cpu_s": n / t["cpu_s"],
            **sphere_errors(s.distance, s.in_contact, ref, r),
        }
        print(f"spheres k={k}: {n / t['best_s']:,.0f}/s, {sphere_errors(s.distance, s.in_contact, ref, r)}")
    sub = np.random.default_rng(1).choice(n, size=n_trimesh, replace=False)
    sub_ref = reference_query(v, f, p0[sub], p1[sub], r[sub], inside=info["inside_mode"])
    t0, c0 = time.perf_counter(), time.process_time()
    d, hit = trimesh_spheres(v, f, p0[sub], p1[sub], r[sub])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    results["trimesh_proximity_k5"] = {
        "best_s": wall,
        "cpu_s": cpu,
        "n_capsules": n_trimesh,
        "capsules_per_s": n_trimesh / wall,
        "capsules_per_cpu_s": n_trimesh / cpu,
        **sphere_errors(d, hit, sub_ref, r[sub]),
    }
    print(f"trimesh.proximity k=5: {n_trimesh / wall:,.0f}/s, {results['trimesh_proximity_k5']}")
    results["reference_numpy"] = {
        **ref_t,
        "capsules_per_s": n / ref_t["best_s"],
        "capsules_per_cpu_s": n / ref_t["cpu_s"],
    }

    # a far-dominated stream (most capsules touch nothing), as in recorded data
    fp0, fp1, fr, _ = random_capsules(v, f, n, seed=2, near_fraction=0.05, inside_fraction=0.002)
    t = timeit(lambda: capsule_mesh_query(v, f, fp0, fp1, fr), repeat=5)
    results["exact_far_dominated"] = {**t, "capsules_per_s": n / t["best_s"], "capsules_per_cpu_s": n / t["cpu_s"]}

    ex = results["exact"]
    ratios = {
        "exact_vs_trimesh_speed": ex["capsules_per_s"] / results["trimesh_proximity_k5"]["capsules_per_s"],
        "exact_vs_reference_speed": ex["capsules_per_s"] / results["reference_numpy"]["capsules_per_s"],
        "exact_vs_spheres_k5_speed": ex["capsules_per_s"] / results["spheres_k5"]["capsules_per_s"],
        "far_dominated_vs_hard_speed": results["exact_far_dominated"]["capsules_per_s"] / ex["capsules_per_s"],
    }
    goal = {
        "capsules_per_s": 1.5e6,
        "met_wall": ex["capsules_per_s"] >= 1.5e6,
        "met_cpu_per_core": ex["capsules_per_cpu_s"] >= 1.5e6 / info["threads"],
        "exact": ex["contact_disagreements"] == 0 and ex["distance_over_tol"] == 0 and ex["missed_inside"] == 0,
    }
    info["loadavg_1min_end"] = machine()["loadavg_1min"]
    path = write_json("contact", {"info": info, "goal": goal, "ratios": ratios, "results": results})
    plot(results, OUT / "contact.png", n)
    print(f"ratios: {ratios}\nwrote {path} and {OUT / 'contact.png'}")
    return 0


def plot(results: dict, path: Path, n: int) -> None:
    """Run time per capsule against two errors: contact disagreements and distance error."""
    floor_rate, floor_err = 1e-3, 1e-6
    with figure(path, 2, (11, 4.5), dpi=120) as (fig, axes):
        for name, res in results.items():
            if "contact_disagreements" not in res:
                continue
            m = res.get("n_capsules", n)
            us = 1e6 / res["capsules_per_s"]
            rate = max(100.0 * res["contact_disagreements"] / m, floor_rate)
            err = max(1000.0 * res.get("p99_distance_error_m", res.get("max_distance_error_m", 0.0)), floor_err)
            label = name.replace("_proximity_k5", ".proximity k=5").replace("spheres_k", "k=")
            color = "C3" if name.startswith("exact") else ("C2" if name.startswith("trimesh") else "C0")
            for ax, y in zip(axes, (rate, err)):
                ax.scatter(us, y, s=40, color=color)
                ax.annotate(label, (us, y), textcoords="offset points", xytext=(4, 5), fontsize=8, rotation=20)
        axes[0].set_ylabel(f"contact disagreements with the exact reference (%)\n(0 drawn at {floor_rate:g})")
        axes[1].set_ylabel(f"p99 distance error of contacts (mm)\n(0 drawn at {floor_err:g})")
        for ax in axes:
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel("wall time per capsule (microseconds, log)")
            ax.grid(True, which="both", alpha=0.3)
        fig.suptitle("capsule vs arm hull, hard set: exact kernel (red), k spheres (blue), trimesh.proximity (green)")


if __name__ == "__main__":
    sys.exit(main())
