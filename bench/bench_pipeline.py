"""End-to-end benchmark: stage-by-stage time and peak memory, and what the stage cache saves.

Two jobs, each in its own subprocess (a fresh interpreter, so that one
job's memory does not show in the other's peaks):

- ``default``: the default run (``data=synthetic``, arm, res 18, Random
  Forest LOSO) on an empty cache, stage by stage in chain order: exclusive
  wall and CPU seconds and the process's peak resident memory (RSS) during
  each stage; then the same run again on the filled cache (warm).
- ``sweep``: the Random Forest resolution sweep, its points run one after
  another in-process through :func:`sphri.pipeline.run` with one shared
  :class:`~sphri.cache.StageCache`: cold (empty cache: data, contact, the
  surface and the window plan are computed at the first point and loaded at
  the others), then warm (every point again: each loads its finished
  evaluation). Without a cache every point would recompute everything: that
  cost is measured directly in ``--quick`` mode and estimated at full size
  (each point's cache-loaded stages at the cost the first point paid;
  the quick run reports the estimate beside the measurement). The cache's
shares are computed on CPU seconds (all threads), which depend less than
wall seconds on what else runs on the machine; both are in the JSON.

Each child first runs a tiny chain without a cache (imports, numba's
compiled-function caches, first calls), so that the numbers are steady-state
costs; its seconds are reported as ``warm_up_s``.

Peak memory: the kernel's high-water mark of the process (``VmHWM``),
reset at every stage boundary (``/proc/self/clear_refs``), so each stage's
peak is its own; where the reset is not allowed the peak is the process's
running maximum (``ru_maxrss``) and the JSON says so. Times are exclusive:
a stage's time excludes the upstream stages it asked for.

Sizes: full = the default synthetic data (18 participants x 8 gestures x 20
repetitions) and resolutions 1, 4, 8, 18, 30, 50; ``--quick`` = 4
participants and resolutions 4, 18, 36. Writes ``outputs/bench/pipeline.json``
and ``outputs/bench/pipeline.png``.

    python bench/bench_pipeline.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import OUT, figure, machine, write_json  # noqa: E402

#: Chain order of the pipeline's stages.
STAGES = ("hand", "robot", "data", "contact", "surface", "layout", "plan", "encode", "noise", "filter", "evaluate")
#: Persisted stages that a later sweep point loads instead of computing.
SHARED = ("data", "contact", "surface", "plan")

FULL = {"participants": 18, "repetitions": 20, "resolutions": [1, 4, 8, 18, 30, 50], "default_res": 18}
QUICK = {"participants": 4, "repetitions": 20, "resolutions": [4, 18, 36], "default_res": 18}


# --------------------------------------------------------------------------- memory


def _clear_refs() -> bool:
    """Reset this process's peak RSS (VmHWM) to its current RSS; False where not allowed."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _status_mb(key: str) -> float | None:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


class MemoryProbe:
    """Peak RSS per interval: VmHWM reset at each boundary, else the running ru_maxrss."""

    def __init__(self) -> None:
        self.resettable = _clear_refs() and _status_mb("VmHWM") is not None
        self.method = "VmHWM reset per stage" if self.resettable else "ru_maxrss (running maximum of the process)"

    def rss_mb(self) -> float:
        v = _status_mb("VmRSS")
        return v if v is not None else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    def boundary(self) -> float:
        """Peak RSS (MB) since the previous boundary; starts a new interval."""
        if self.resettable:
            peak = _status_mb("VmHWM") or 0.0
            _clear_refs()
            return peak
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# --------------------------------------------------------------------------- stage probe


class StageProbe:
    """Exclusive wall/CPU seconds and peak RSS of every stage a pipeline computes or loads.

    Installed on a :class:`~sphri.pipeline.Pipeline` instance (its ``get``
    is wrapped): nested requests (a stage asking for its inputs) pause the
    outer stage's clock and memory interval.
    """

    def __init__(self, memory: MemoryProbe) -> None:
        self.memory = memory
        self.stats: dict[str, dict[str, Any]] = {}
        self._stack: list[str] = []
        self._mark = (0.0, 0.0)

    def _charge(self) -> None:
        """Charge the time and peak since the last mark to the running stage."""
        wall, cpu = time.perf_counter(), time.process_time()
        peak = self.memory.boundary()
        if self._stack:
            s = self.stats[self._stack[-1]]
            s["wall_s"] += wall - self._mark[0]
            s["cpu_s"] += cpu - self._mark[1]
            s["peak_rss_mb"] = max(s["peak_rss_mb"], peak)
        self._mark = (wall, cpu)

    def install(self, pipeline: Any) -> Any:
        orig = type(pipeline).get.__get__(pipeline)

        def get(name: str) -> Any:
            node = pipeline.node(name)  # wired when first asked for
            if node.done:
                return node.value
            self._charge()
            self.stats.setdefault(
                name, {"wall_s": 0.0, "cpu_s": 0.0, "peak_rss_mb": 0.0, "rss_start_mb": self.memory.rss_mb()}
            )
            self._stack.append(name)
            try:
                return orig(name)
            finally:
                self._charge()
                self._stack.pop()
                rec = pipeline.records.get(name)
                self.stats[name]["source"] = rec.source if rec is not None else "?"
                self.stats[name]["rss_end_mb"] = self.memory.rss_mb()

        pipeline.get = get  # the stages' closures call pipeline.get(...): they see the wrapper
        return pipeline


@contextmanager
def probed_pipelines(memory: MemoryProbe) -> Iterator[list[StageProbe]]:
    """Every pipeline that :func:`sphri.pipeline.run` makes inside the block gets a :class:`StageProbe`."""
    import sphri.pipeline as sp

    probes: list[StageProbe] = []
    original = sp.make_pipeline

    def make(cfg, cache):
        probe = StageProbe(memory)
        probes.append(probe)
        return probe.install(original(cfg, cache))

    sp.make_pipeline = make
    try:
        yield probes
    finally:
        sp.make_pipeline = original


def compose_cfg(participants: int, repetitions: int, res: int) -> Any:
    from sphri.config import compose

    return compose(
        [
            "data=synthetic",
            "data.regions=[arm]",
            f"data.participants={participants}",
            f"data.repetitions={repetitions}",
            f"layout.res={res}",
            "cv.progress=false",
        ]
    )


def warm_up() -> float:
    """Run a tiny chain once without a cache (imports, numba caches, first-call costs); its seconds."""
    from sphri.cache import StageCache
    from sphri.pipeline import run

    t0 = time.perf_counter()
    run(compose_cfg(2, 1, 4), StageCache(root=tempfile.gettempdir(), enabled=False))
    return time.perf_counter() - t0


def _round(d: dict) -> dict:
    return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in d.items()}


# --------------------------------------------------------------------------- child jobs


def child_default(args: argparse.Namespace) -> dict:
    """The default run, stage by stage on an empty cache, then again on the filled cache."""
    from sphri.cache import StageCache
    from sphri.pipeline import make_pipeline, run

    memory = MemoryProbe()
    rss0 = memory.rss_mb()
    warm_up_s = warm_up()
    cfg = compose_cfg(args.participants, args.repetitions, args.res)
    with tempfile.TemporaryDirectory(prefix="sphri-bench-") as tmp:
        cache = StageCache(root=tmp)
        probe = StageProbe(memory)
        p = probe.install(make_pipeline(cfg, cache))
        t0 = time.perf_counter()
        memory.boundary()
        for name in STAGES:
            p.get(name)
        cold = time.perf_counter() - t0
        cv, meta = p.get("evaluate")
        t0 = time.perf_counter()
        warm_result = run(cfg, cache)
        warm = time.perf_counter() - t0
        cache_mb = sum(f.stat().st_size for f in Path(tmp).rglob("*.entry")) / 2**20
    acc = [f.accuracy for f in cv.folds]
    return {
        "participants": args.participants,
        "repetitions": args.repetitions,
        "res": args.res,
        "n_frames": meta.n_frames,
        "n_trials": meta.n_trials,
        "n_windows": meta.n_windows,
        "n_taxels": meta.resolution["n_taxels"],
        "accuracy_mean": sum(acc) / len(acc),
        "memory_method": memory.method,
        "rss_after_imports_mb": rss0,
        "warm_up_s": warm_up_s,
        "stages": {k: _round(v) for k, v in probe.stats.items()},
        "cold_wall_s": cold,
        "warm_wall_s": warm,
        "warm_sources": {k: r.source for k, r in warm_result.stages.items()},
        "cache_size_mb": cache_mb,
    }


def _sweep_pass(resolutions, participants, repetitions, cache, memory) -> list[dict]:
    from sphri.pipeline import run

    points = []
    for res in resolutions:
        cfg = compose_cfg(participants, repetitions, res)
        with probed_pipelines(memory) as probes:
            t0, c0 = time.perf_counter(), time.process_time()
            result = run(cfg, cache)
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        stats = probes[-1].stats
        points.append(
            {
                "res": res,
                "wall_s": wall,
                "cpu_s": cpu,
                "accuracy_mean": result.cv.summary()["accuracy_mean"],
                "peak_rss_mb": max((s["peak_rss_mb"] for s in stats.values()), default=0.0),
                "stages": {k: _round(v) for k, v in stats.items()},
            }
        )
    return points


def child_sweep(args: argparse.Namespace) -> dict:
    """The sweep's points in-process with one shared cache: cold, warm, and (optionally) uncached."""
    from sphri.cache import StageCache

    memory = MemoryProbe()
    warm_up_s = warm_up()
    res = [int(r) for r in args.resolutions.split(",")]
    with tempfile.TemporaryDirectory(prefix="sphri-bench-") as tmp:
        cache = StageCache(root=tmp)
        cold = _sweep_pass(res, args.participants, args.repetitions, cache, memory)
        warm = _sweep_pass(res, args.participants, args.repetitions, cache, memory)
    out = {
        "participants": args.participants,
        "repetitions": args.repetitions,
        "resolutions": res,
        "memory_method": memory.method,
        "warm_up_s": warm_up_s,
        "cold": cold,
        "warm": warm,
    }
    if args.measure_uncached:
        out["uncached"] = _sweep_pass(
            res, args.participants, args.repetitions, StageCache(root="/nonexistent", enabled=False), memory
        )
    return out


def estimate_uncached(cold: list[dict], key: str = "cpu_s") -> float:
    """Seconds (``key``: cpu_s or wall_s) of the sweep without a cache.

    Each point's cold cost, plus, for every shared stage it loaded from the
    cache, what computing it cost the first point minus what loading it cost.
    """
    first = cold[0]["stages"]
    total = 0.0
    for point in cold:
        total += point[key]
        for name in SHARED:
            s = point["stages"].get(name)
            if s is not None and s.get("source") == "cache" and name in first:
                total += first[name][key] - s[key]
    return total


# --------------------------------------------------------------------------- parent


def run_child(kind: str, extra: list[str], timeout_s: float) -> dict:
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as fh:
        path = fh.name
    cmd = [sys.executable, __file__, "--child", kind, "--json", path] + extra
    print("  $", " ".join(Path(c).name if c == __file__ else c for c in cmd[1:]), flush=True)
    try:
        proc = subprocess.run(cmd, timeout=timeout_s)
        if proc.returncode != 0:
            return {"error": f"child {kind} exited with {proc.returncode}"}
        return json.loads(Path(path).read_text())
    except subprocess.TimeoutExpired:
        return {"error": f"child {kind} ran past {timeout_s:.0f} s"}
    finally:
        Path(path).unlink(missing_ok=True)


def summarize(default: dict, sweep: dict, quick: bool) -> dict:
    head: dict[str, Any] = {}
    if "stages" in default:
        st = default["stages"]
        total = sum(s["wall_s"] for s in st.values())
        head["default_cold_cpu_s"] = sum(s["cpu_s"] for s in st.values())
        head["default_cold_wall_s"] = default["cold_wall_s"]
        head["default_warm_wall_s"] = default["warm_wall_s"]
        head["default_warm_vs_cold"] = default["warm_wall_s"] / default["cold_wall_s"]
        head["default_peak_rss_mb"] = max(s["peak_rss_mb"] for s in st.values())
        slowest = max(st, key=lambda k: st[k]["wall_s"])
        head["default_slowest_stage"] = slowest
        head["default_slowest_share"] = st[slowest]["wall_s"] / total
        head["default_hungriest_stage"] = max(st, key=lambda k: st[k]["peak_rss_mb"] - st[k]["rss_start_mb"])
    if "cold" in sweep:
        # CPU seconds (all threads) carry the cache comparison: wall time follows the machine's load
        for key, tag in (("cpu_s", "cpu"), ("wall_s", "wall")):
            cold = sum(p[key] for p in sweep["cold"])
            warm = sum(p[key] for p in sweep["warm"])
            est = estimate_uncached(sweep["cold"], key)
            head[f"sweep_cold_{tag}_s"] = cold
            head[f"sweep_warm_{tag}_s"] = warm
            head[f"sweep_uncached_estimate_{tag}_s"] = est
            if "uncached" in sweep:
                measured = sum(p[key] for p in sweep["uncached"])
                head[f"sweep_uncached_measured_{tag}_s"] = measured
                head[f"sweep_uncached_estimate_error_{tag}"] = est / measured - 1.0
            if tag == "cpu":
                base = head.get("sweep_uncached_measured_cpu_s", est)
                head["sweep_points"] = len(sweep["cold"])
                head["sweep_warm_share_saved"] = 1.0 - warm / cold
                head["sweep_cold_share_saved"] = 1.0 - cold / base
                head["sweep_warm_share_saved_vs_uncached"] = 1.0 - warm / base
                ev = sum(p["stages"].get("evaluate", {}).get(key, 0.0) for p in sweep["cold"])
                head["sweep_evaluate_share_of_cold"] = ev / cold
        head["sweep_peak_rss_mb"] = max(p["peak_rss_mb"] for p in sweep["cold"])
    return head


def plot(default: dict, sweep: dict, path: Path) -> None:
    """Left: exclusive seconds per stage of the default run; right: the sweep cold, warm, uncached."""
    with figure(path, 3, (15, 4.5)) as (fig, axes):
        if "stages" in default:
            st = default["stages"]
            names = [s for s in STAGES if s in st]
            axes[0].barh(names, [st[s]["wall_s"] for s in names], color="C0", label="wall")
            axes[0].barh(names, [st[s]["cpu_s"] for s in names], color="C1", alpha=0.5, label="CPU (all threads)")
            axes[0].invert_yaxis()
            axes[0].set_xlabel("seconds (exclusive)")
            axes[0].set_title(f"default run, cold: {default['n_trials']} trials, res {default['res']}")
            axes[0].legend(fontsize=8)
            axes[1].barh(names, [st[s]["peak_rss_mb"] for s in names], color="C2", label="peak RSS")
            axes[1].barh(names, [st[s]["rss_start_mb"] for s in names], color="k", alpha=0.3, label="RSS at start")
            axes[1].invert_yaxis()
            axes[1].set_xlabel("MB")
            axes[1].set_title(f"memory per stage ({default['memory_method']})", fontsize=9)
            axes[1].legend(fontsize=8)
        if "cold" in sweep:
            res = [str(p["res"]) for p in sweep["cold"]]
            x = list(range(len(res)))
            bottom = [0.0] * len(res)
            for i, name in enumerate(STAGES):
                vals = [p["stages"].get(name, {}).get("wall_s", 0.0) for p in sweep["cold"]]
                if max(vals) < 0.02:
                    continue
                axes[2].bar([xi - 0.2 for xi in x], vals, 0.4, bottom=bottom, label=f"cold: {name}", color=f"C{i % 10}")
                bottom = [b + v for b, v in zip(bottom, vals)]
            axes[2].bar(
                [xi + 0.2 for xi in x], [p["wall_s"] for p in sweep["warm"]], 0.4, color="k", label="warm (cached)"
            )
            if "uncached" in sweep:
                axes[2].scatter(
                    x, [p["wall_s"] for p in sweep["uncached"]], color="r", marker="_", s=400, label="no cache"
                )
            axes[2].set_xticks(x, res)
            axes[2].set_xlabel("layout.res (sweep point, in run order)")
            axes[2].set_ylabel("wall seconds")
            axes[2].set_title(f"RF sweep, {sweep['participants']} participants: cold vs warm cache")
            axes[2].legend(fontsize=7)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="4 participants, 3 resolutions")
    ap.add_argument("--child", choices=["default", "sweep"], help=argparse.SUPPRESS)
    ap.add_argument("--json", help=argparse.SUPPRESS)
    ap.add_argument("--participants", type=int, default=None)
    ap.add_argument("--repetitions", type=int, default=None)
    ap.add_argument("--res", type=int, default=18)
    ap.add_argument("--resolutions", default=None, help="comma-separated sweep resolutions")
    ap.add_argument("--measure-uncached", action="store_true", help="also run the sweep without a cache")
    args = ap.parse_args(argv)
    if args.child:
        import logging

        logging.basicConfig(level=logging.WARNING)
        out = child_default(args) if args.child == "default" else child_sweep(args)
        Path(args.json).write_text(json.dumps(out))
        return 0

    size = QUICK if args.quick else FULL
    p = args.participants or size["participants"]
    r = args.repetitions or size["repetitions"]
    res = args.resolutions or ",".join(str(x) for x in size["resolutions"])
    info = {
        **machine(),
        "mode": "quick" if args.quick else "full",
        "participants": p,
        "repetitions": r,
        "sweep_resolutions": [int(x) for x in res.split(",")],
        "note": "wall_s/cpu_s exclusive per stage; peak_rss_mb = process peak during the stage",
    }
    t0 = time.perf_counter()
    print(f"default run: {p} participants x {r} repetitions, res {size['default_res']}", flush=True)
    default = run_child(
        "default",
        ["--participants", str(p), "--repetitions", str(r), "--res", str(size["default_res"])],
        timeout_s=1800,
    )
    print(f"RF sweep over res {res}", flush=True)
    extra = ["--participants", str(p), "--repetitions", str(r), "--resolutions", res]
    sweep = run_child(
        "sweep", extra + (["--measure-uncached"] if args.quick or args.measure_uncached else []), timeout_s=3600
    )
    info["wall_s"] = time.perf_counter() - t0
    info["loadavg_1min_end"] = machine()["loadavg_1min"]
    head = summarize(default, sweep, args.quick)
    path = write_json("pipeline", {"info": info, "headline": head, "default_run": default, "sweep": sweep})
    plot(default, sweep, OUT / "pipeline.png")
    for k, v in head.items():
        print(f"  {k}: {v:.4g}" if isinstance(v, float) else f"  {k}: {v}")
    print(f"wrote {path} and {OUT / 'pipeline.png'}")
    return 0 if "error" not in default and "error" not in sweep else 1


if __name__ == "__main__":
    sys.exit(main())
