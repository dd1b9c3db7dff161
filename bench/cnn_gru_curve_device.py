"""The CNN-GRU's resolution curve on a lent accelerator, and how it agrees with the CPU sweep (issue 31).

``run`` evaluates the CNN-GRU at the given resolutions with the config of the README's sweep
(``+experiment=resolution_sweep model=cnn_gru``, ``model.device=auto``: CUDA when torch sees it, bf16
where the device has it), in this process's stage cache, without MLflow (the accelerator machine has
no MLflow; nothing else differs from a job). After each resolution it writes its folds, the
evaluation's wall time, the machine, and the content key of the noisy windows the model saw
(:func:`sphri.pipeline.content_key`) to one JSON file, so a run stopped at its time limit keeps what
it finished. ``--budget-s``: no resolution is started after that many seconds.

    python bench/cnn_gru_curve_device.py run 40,50,18,33,27,22,12,8 cv.workers=8 cv.threads_per_worker=2 \\
        --out outputs/bench/cnn_gru_curve_h100.json

``compare`` reads that file and the MLflow store of the CPU sweep (the README's command, run in
``CPU_OUTPUT_DIR``), and writes ``outputs/bench/cnn_gru_curve_device_compare.json``, a Markdown
summary on stdout and, with ``--figure``, RF and CNN-GRU accuracy against resolution with the
accelerator's points marked:

- at each resolution computed on both: the two jobs' mean accuracy and their per-participant
  (paired) differences; over all shared resolutions, the mean paired difference with a 95 %
  bootstrap interval (10,000 resamples, seed 0);
- the accelerator's results at resolutions the CPU sweep has not finished.

No saturation point is computed on a curve mixed from two machines: the report
(``sphri report``) gives it for the CPU sweep's own jobs.

    python bench/cnn_gru_curve_device.py compare CPU_OUTPUT_DIR --device-json outputs/bench/cnn_gru_curve_h100.json \\
        --figure docs/figures/resolution_rf_cnn_gru_cpu_h100.png

``stages`` prints the content key of every stage up to the windows at one resolution, and a key of
the readings alone (:func:`readings_key`): run on two machines, it shows where their computations part
and whether the model's inputs are bit-identical.

    python bench/cnn_gru_curve_device.py stages 18 model=rf --cache-dir /tmp/sphri_cache
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import OUT, figure, machine, write_json  # noqa: E402

SWEEP = ["+experiment=resolution_sweep", "model=cnn_gru"]


def readings_key(windows: Any) -> str:
    """The content key (:func:`sphri.pipeline.content_key`) of what the model is trained and tested on (a
    :class:`sphri.types.WindowedFrames`' readings, labels and participants), without the taxels' geometry:
    two machines whose readings keys agree fed the model bit-identical inputs even where a last-bit
    difference in the fitted surface changes the windows' own content key."""
    from sphri.pipeline import content_key

    return content_key("readings", {"x": windows.x, "y": windows.y, "groups": windows.groups})


def _overrides(res: int, overrides: list[str], cache_dir: str) -> list[str]:
    """The README sweep's CNN-GRU job at ``res``, without MLflow, in ``cache_dir``."""
    return [*SWEEP, f"layout.res={res}", *overrides, "tracking.enabled=false", f"cache.dir={cache_dir}"]


def stages(res: int, overrides: list[str], cache_dir: str) -> dict[str, str]:
    """The content key of every stage up to the noisy windows at ``res``, and the readings key: run on two
    machines, the first stage whose keys differ is where their computations part."""
    from sphri import pipeline
    from sphri.config import compose

    cfg = compose(_overrides(res, overrides, cache_dir))
    p = pipeline.make_pipeline(cfg, pipeline.open_cache(cfg))
    keys = {}
    p.key("evaluate")  # wires the chain (a pipeline keys a stage when first asked for)
    for st in [name for name in p.nodes if name != "evaluate"]:
        try:
            keys[st] = pipeline.content_key(st, p.get(st))
        except TypeError as exc:  # a value the codec cannot key
            keys[st] = f"not keyed ({exc})"
    keys["readings"] = readings_key(p.get("noise"))
    return keys


def run(resolutions: list[int], overrides: list[str], out: Path, budget_s: float, cache_dir: str) -> dict[str, Any]:
    """Evaluate each resolution in turn, rewriting ``out`` after each; returns its content."""
    from sphri import pipeline
    from sphri.config import compose

    t0 = time.time()
    try:
        doc: dict[str, Any] = json.loads(out.read_text()) if out.is_file() else {}
    except ValueError as exc:
        raise SystemExit(
            f"cnn_gru_curve_device: {out} is not this script's JSON ({exc}); move it or give --out"
        ) from None
    doc.setdefault("results", {})
    here = machine()
    doc["machine"] = here  # the last run's; each result keeps its own
    for res in resolutions:
        if time.time() - t0 > budget_s:
            print(f"budget {budget_s:.0f} s reached: res {res} and after not started", flush=True)
            break
        args = _overrides(res, overrides, cache_dir)
        cfg = compose(args)
        p = pipeline.make_pipeline(cfg, pipeline.open_cache(cfg))
        t = time.time()
        windows = p.get("noise")
        windows_key = pipeline.content_key("noise", windows)
        data_s = time.time() - t
        t = time.time()
        cv, _meta = p.get("evaluate")
        wall = time.time() - t
        folds = [{"fold": f.fold, "n_test": f.n_test, "accuracy": f.accuracy, "macro_f1": f.macro_f1} for f in cv.folds]
        doc["results"][str(res)] = {
            "overrides": args,
            "windows_content_key": windows_key,
            "readings_key": readings_key(windows),
            "data_to_windows_s": round(data_s, 1),
            "evaluate_wall_s": round(wall, 1),
            "summary": cv.summary(),
            "folds": folds,
            "machine": here,
        }
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(out.name + ".partial")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(out)  # whole or not at all: what earlier resolutions wrote is never half-overwritten
        s = cv.summary()
        print(
            f"res {res}: accuracy {s['accuracy_mean']:.3f} macro-F1 {s['macro_f1_mean']:.3f} "
            f"evaluate {wall:.0f} s (elapsed {time.time() - t0:.0f} s)",
            flush=True,
        )
    return doc


def cpu_sweep(output_dir: Path) -> dict[str, dict[int, dict[str, float]]]:
    """``{model: {res: {participant: accuracy}}}`` of the FINISHED jobs of the CPU sweep's MLflow store
    (the latest run of each (model, res))."""
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import default_uri

    db = output_dir / "mlflow.db"
    if not db.is_file():
        raise SystemExit(f"cnn_gru_curve_device: no MLflow store at {db} (run the README's sweep there)")
    client = MlflowClient(default_uri(output_dir))
    found: dict[str, dict[int, dict[str, float]]] = {}
    for exp in client.search_experiments():
        runs = client.search_runs(
            [exp.experiment_id],
            "attributes.status = 'FINISHED' and tags.`sphri.kind` = 'job'",
            order_by=["attributes.start_time ASC"],
        )
        for r in runs:
            model, res = r.data.params.get("model"), r.data.params.get("layout.res", r.data.params.get("encoder.res"))
            if model is None or res is None:
                continue
            scores = {
                k.split("/")[1]: v
                for k, v in r.data.metrics.items()
                if k.startswith("participant/") and k.endswith("/accuracy")
            }
            if scores:
                found.setdefault(model, {})[int(res)] = scores
    return found


def compare(cpu_dir: Path, device_json: Path, figure: Path | None) -> dict[str, Any]:
    from sphri.evaluate.metrics import bootstrap_ci

    if not device_json.is_file():
        raise SystemExit(f"cnn_gru_curve_device: no accelerator results at {device_json} (the 'run' step)")
    doc = json.loads(device_json.read_text())
    device = {int(r): {f["fold"]: f["accuracy"] for f in v["folds"]} for r, v in doc["results"].items()}
    cpu = cpu_sweep(cpu_dir)
    cnn = cpu.get("cnn_gru", {})
    shared = sorted(set(cnn) & set(device))
    rows, diffs = [], []
    for r in shared:
        people = sorted(set(cnn[r]) & set(device[r]))
        a = np.array([cnn[r][p] for p in people])
        b = np.array([device[r][p] for p in people])
        diffs.extend(b - a)
        rows.append(
            {
                "res": r,
                "cpu": float(a.mean()),
                "device": float(b.mean()),
                "diff": float(b.mean() - a.mean()),
                "mean_abs_paired_diff": float(np.abs(b - a).mean()),
                "max_abs_paired_diff": float(np.abs(b - a).max()),
                "n": len(people),
            }
        )
    d = np.asarray(diffs, dtype=float)
    lo, hi = bootstrap_ci(d, n_boot=10_000, seed=0) if d.size > 1 else (float("nan"), float("nan"))
    result = {
        "device_machine": doc.get("machine"),
        "shared_resolutions": rows,
        "paired": {"n": int(d.size), "mean_diff": float(d.mean()) if d.size else None, "ci95": [lo, hi]},
        "device_only": {str(r): float(np.mean(list(device[r].values()))) for r in sorted(set(device) - set(cnn))},
    }
    if figure is not None:
        _figure(cpu, device, figure)
        result["figure"] = str(figure)
    return result


def _figure(cpu: dict[str, dict[int, dict[str, float]]], device: dict[int, dict[str, float]], path: Path) -> None:
    def curve(points: dict[int, dict[str, float]]) -> tuple[list[int], list[float]]:
        res = sorted(points)
        return res, [float(np.mean(list(points[r].values()))) for r in res]

    path.parent.mkdir(parents=True, exist_ok=True)
    with figure(path, 1, (7.0, 4.0)) as (_fig, ax):
        if cpu.get("rf"):
            ax.plot(*curve(cpu["rf"]), "o-", color="tab:blue", label="RF (CPU)")
        if cpu.get("cnn_gru"):
            ax.plot(*curve(cpu["cnn_gru"]), "s-", color="tab:orange", label="CNN-GRU (CPU, bf16)")
        ax.plot(*curve(device), "D", mfc="none", color="tab:red", label="CNN-GRU (accelerator, bf16)")
        ax.axhline(0.125, color="grey", lw=0.8, ls=":", label="chance")
        ax.set_xscale("log")
        ticks = [1, 2, 3, 4, 6, 8, 12, 18, 27, 40, 50]
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.minorticks_off()
        ax.set_xlabel("layout.res (taxel grid resolution)")
        ax.set_ylabel("mean accuracy over participants (LOSO)")
        ax.set_title("SYNTHETIC data: RF and CNN-GRU against resolution", fontsize=10)
        ax.legend(fontsize=8, loc="lower right")
        ax.grid(alpha=0.3)


def _markdown(c: dict[str, Any]) -> str:
    lines = ["| res | CPU | accelerator | difference | mean abs paired | n |", "| --- | --- | --- | --- | --- | --- |"]
    for r in c["shared_resolutions"]:
        lines.append(
            f"| {r['res']} | {r['cpu']:.3f} | {r['device']:.3f} | {r['diff']:+.3f} | "
            f"{r['mean_abs_paired_diff']:.3f} | {r['n']} |"
        )
    p = c["paired"]
    if p["n"]:
        lines.append(
            f"\npaired over {p['n']} (resolution, participant): mean {p['mean_diff']:+.4f}, "
            f"95 % interval {p['ci95'][0]:+.4f} to {p['ci95'][1]:+.4f}"
        )
    for r, v in c["device_only"].items():
        lines.append(f"accelerator only: res {r}: {v:.3f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="evaluate the CNN-GRU at the given resolutions here")
    r.add_argument("resolutions", help="comma-separated, e.g. 40,50,18")
    r.add_argument("overrides", nargs="*", help="more config overrides (cv.workers=8 ...)")
    r.add_argument("--out", type=Path, default=OUT / "cnn_gru_curve_device.json")
    r.add_argument("--budget-s", type=float, default=float("inf"))
    r.add_argument("--cache-dir", default="outputs/cache")
    k = sub.add_parser("stages", help="print every stage's content key and the readings key at one resolution")
    k.add_argument("res", type=int)
    k.add_argument("overrides", nargs="*", help="more config overrides (model=rf where torch is missing ...)")
    k.add_argument("--cache-dir", default="outputs/cache")
    c = sub.add_parser("compare", help="compare with the CPU sweep's MLflow store")
    c.add_argument("cpu_output_dir", type=Path)
    c.add_argument("--device-json", type=Path, default=OUT / "cnn_gru_curve_device.json")
    c.add_argument("--figure", type=Path, default=None)
    a = ap.parse_args(argv)
    if a.cmd == "run":
        try:
            resolutions = [int(x) for x in a.resolutions.split(",")]
        except ValueError:
            ap.error(f"resolutions={a.resolutions!r}: give comma-separated integers, e.g. 40,50,18")
        run(resolutions, a.overrides, a.out, a.budget_s, a.cache_dir)
        return 0
    if a.cmd == "stages":
        for name, key in stages(a.res, a.overrides, a.cache_dir).items():
            print(f"{name:10s} {key}")
        return 0
    result = compare(a.cpu_output_dir, a.device_json, a.figure)
    path = write_json("cnn_gru_curve_device_compare", result)
    print(_markdown(result))
    print(f"\nwritten: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
