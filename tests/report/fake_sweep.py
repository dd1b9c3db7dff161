"""Fake sweeps for the report tests, logged through the real tracker.

:func:`make_sweep` logs one MLflow parent run and one child per (group,
resolution) with :meth:`MlflowTracker.log_job`, exactly as a multirun does
(parent file in the sweep dir, job dirs with ``sphri_status.json``), from
fake CV results whose accuracy follows a known saturating curve with a
per-participant offset and per-job noise.
"""

from __future__ import annotations

import json
import sys
import types
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from sphri.pipeline import RunResult, StageRecord
from sphri.testing.runs import toy_meta
from sphri.tracking.mlflow_tracker import PARENT_FILE, MlflowTracker, default_uri
from sphri.types import GESTURES, CVResult, FoldResult

LENGTH_MM = 241.0  # the Reachy arm's long axis
CIRCUMFERENCE_MM = 258.0


def _ensure_summarize() -> None:
    """``log_job`` imports ``sphri.evaluate.metrics.summarize``; stand in for it until that module exists."""
    try:
        from sphri.evaluate.metrics import summarize  # noqa: F401
    except ImportError:
        mod = types.ModuleType("sphri.evaluate.metrics")
        mod.summarize = lambda cv: cv.summary()  # type: ignore[attr-defined]
        sys.modules["sphri.evaluate.metrics"] = mod
        import sphri.evaluate as ev

        ev.metrics = mod  # type: ignore[attr-defined]


def grid_resolution(res: int) -> dict:
    """What ``sphri.layout.units.describe`` reports for a res-``res`` grid on the arm."""
    h, w = res, max(1, int(round(res * CIRCUMFERENCE_MM / LENGTH_MM)))
    pu, pv = LENGTH_MM / h, CIRCUMFERENCE_MM / w
    return {
        "layout_kind": "grid",
        "surface_kind": "cylinder",
        "n_taxels": h * w,
        "n_taxels_on_surface": h * w,
        "grid_h": h,
        "grid_w": w,
        "pitch_u_mm": pu,
        "pitch_v_mm": pv,
        "area_per_taxel_cm2": pu * pv / 100.0,
        "skin_area_cm2": LENGTH_MM * CIRCUMFERENCE_MM / 100.0,
        "taxels_per_cm_u": 10 / pu,
        "taxels_per_cm_v": 10 / pv,
        "taxels_per_24cm": 240.0 / pu,
        "link_length_mm": LENGTH_MM,
        "circumference_mm": CIRCUMFERENCE_MM,
        "fit_residual_mm": 1.0,
    }


def true_curve(res: np.ndarray, top: float, tau: float) -> np.ndarray:
    """Saturating accuracy: chance at res -> 0, ``top`` at res -> inf, time constant ``tau`` taxels."""
    return 0.125 + (top - 0.125) * (1.0 - np.exp(-np.asarray(res, float) / tau))


def _fold(name: str, acc: float, rng: np.random.Generator, per_gesture: int, res: int) -> FoldResult:
    """A fold whose confusion matrix has about ``acc`` accuracy; poke and tap need finer skin."""
    g = len(GESTURES)
    conf = np.zeros((g, g), dtype=np.int64)
    for i, gest in enumerate(GESTURES):
        need = {"poke": 6.0, "tap": 4.0}.get(gest, 1.0)
        r = np.clip(acc - 0.15 * np.exp(-res / need) + rng.normal(0, 0.03), 0, 1)
        k = int(round(r * per_gesture))
        conf[i, i] = k
        conf[i, (i + 1) % g] += per_gesture - k
    n = int(conf.sum())
    a = float(np.trace(conf) / n)
    recall = np.diag(conf) / conf.sum(1)
    prec = np.divide(np.diag(conf), conf.sum(0), out=np.zeros(g), where=conf.sum(0) > 0)
    f1 = np.divide(2 * prec * recall, prec + recall, out=np.zeros(g), where=(prec + recall) > 0)
    return FoldResult(name, n, a, float(f1.mean()), conf, recall)


def fake_cfg(
    output_dir: Path, res: int, model: str, robot: str = "reachy", variant: str | None = None, noise_p: float = 0.02
) -> OmegaConf:
    target = {"rf": "sphri.models.rf.RandomForest", "cnn_gru": "sphri.models.cnn_gru.CnnGru"}.get(
        model, "sphri.models.X"
    )
    cfg = {
        "seed": 0,
        "output_dir": str(output_dir),
        "data": {"_target_": "sphri.data.synthetic.SyntheticGestures", "seed": 0, "participants": 8},
        "robot": {"_target_": f"sphri.robots.{robot}.Robot"},
        "contact": {"_target_": "sphri.contact.Exact"},
        "surface": {"_target_": "sphri.surface.Cylinder"},
        "layout": {"_target_": "sphri.layout.grid.Grid"},
        "encoder": {"_target_": "sphri.encode.ellipse.Ellipse", "res": res},
        "noise": {"_target_": "sphri.noise.SaltPepper", "p": noise_p},
        "filter": {"_target_": "sphri.filter.components.NoFilter"},
        "window": {"_target_": "sphri.window.Onset", "frames": 50},
        "model": {"_target_": target, **({"n_estimators": 100} if model == "rf" else {"hidden": 32})},
        "cv": {"_target_": "sphri.evaluate.Loso"},
        "tracking": {"_target_": "sphri.tracking.mlflow_tracker.MlflowTracker"},
        "variant": variant,
    }
    return OmegaConf.create(cfg)


@dataclass
class FakeSweep:
    output_dir: Path
    sweep_dir: Path
    parent_id: str
    uri: str
    res: list[int]
    labels: list[str]
    """Group labels (model name, or robot=..., model=...)."""
    accuracy: dict[str, np.ndarray] = field(default_factory=dict)
    """label -> (P, R) per-participant accuracy as logged (NaN for failed jobs)."""
    participants: list[str] = field(default_factory=list)


def make_sweep(
    out: Path,
    sweep_dir: Path,
    res: list[int],
    models: list[str] = ("rf",),
    robots: list[str] = ("reachy",),
    n_participants: int = 8,
    synthetic: bool = True,
    fail: set[tuple[str, int]] = frozenset(),
    artifacts: bool = True,
    confusion_png: bool = False,
    seed: int = 0,
    top: dict[str, float] | None = None,
    tau: float = 3.0,
    variants: dict[str, tuple[float, float]] | None = None,
) -> FakeSweep:
    """Log a fake sweep into the store at ``out`` (its output_dir), sweep dir ``sweep_dir``; return its truth.

    Several sweeps may share one store (creating an MLflow database takes seconds).
    ``variants``: an assumption-variant sweep instead (one model, one robot): name -> (tau, noise.p), each
    logged with its ``variant`` param and its own curve time constant (a larger tau saturates finer).
    """
    _ensure_summarize()
    rng = np.random.default_rng(seed)
    sweep_dir.mkdir(parents=True, exist_ok=True)
    # The report redraws confusion matrices from confusion.csv; a job's own PNG (tests/test_tracking.py) would
    # cost about 0.3 s for each of the fake jobs.
    tracker = MlflowTracker(artifacts=artifacts, confusion_png=confusion_png)
    sweep_id = sweep_dir.name
    parent_id = tracker.start_parent(str(out), str(sweep_dir), sweep_id, ["layout.res=" + ",".join(map(str, res))])
    (sweep_dir / PARENT_FILE).write_text(
        json.dumps({"run_id": parent_id, "sweep_id": sweep_id, "uri": default_uri(out)})
    )
    parent = {"run_id": parent_id, "sweep_id": sweep_id}
    participants = [f"participant_{i + 1:02d}" for i in range(n_participants)]
    offsets = rng.normal(0, 0.04, n_participants)
    truth = FakeSweep(out, sweep_dir, parent_id, default_uri(out), list(res), [], participants=participants)
    top = top or {}
    job = 0
    n_fail = 0
    combos = (
        [(robots[0], models[0], v) for v in variants]
        if variants
        else [(robot, model, None) for robot in robots for model in models]
    )
    for robot, model, variant in combos:
        label = (
            variant
            if variant is not None
            else f"robot={robot}, model={model}"
            if len(robots) > 1 and len(models) > 1
            else robot
            if len(robots) > 1
            else model
        )
        truth.labels.append(label)
        mat = np.full((n_participants, len(res)), np.nan)
        v_tau, v_p = variants[variant] if variant is not None else (tau, 0.02)
        curve = true_curve(np.array(res), top.get(model, 0.85), v_tau)
        for j, r in enumerate(res):
            cfg = fake_cfg(out, r, model, robot, variant, v_p)
            job_dir = sweep_dir / str(job)
            job_dir.mkdir(parents=True, exist_ok=True)
            choices = {"model": model, "robot": robot, "layout": "grid", "noise": "salt_pepper"}
            if (model, r) in fail:
                rid = tracker.log_failure(
                    cfg, RuntimeError(f"boom at res {r}"), job_dir, parent=parent, choices=choices
                )
                status = {
                    "job": job,
                    "status": "FAILED",
                    "error": f"RuntimeError: boom at res {r}",
                    "mlflow_run_id": rid,
                }
                n_fail += 1
            else:
                folds = []
                for i, p in enumerate(participants):
                    acc = float(np.clip(curve[j] + offsets[i] + rng.normal(0, 0.02), 0.0, 1.0))
                    folds.append(_fold(p, acc, rng, per_gesture=20, res=r))
                    mat[i, j] = folds[-1].accuracy
                meta = toy_meta(
                    dataset="synthetic" if synthetic else "vr_gesture",
                    synthetic=synthetic,
                    n_participants=n_participants,
                    n_trials=16 * n_participants,
                    n_frames=1000,
                    robot=robot,
                    link="r_arm",
                    surface_fit_residual_mm=1.0,
                    n_windows=160,
                    resolution=grid_resolution(r),
                )
                result = RunResult(
                    CVResult("loso", model, folds),
                    meta,
                    {"contact": StageRecord("contact", "k", "cache", 0.1)},
                    f"hash-{robot}-{model}-{variant}-{r}",
                )
                rid = tracker.log_job(cfg, result, job_dir, parent=parent, choices=choices)
                status = {"job": job, "status": "FINISHED", "error": None, "mlflow_run_id": rid}
            (job_dir / "sphri_status.json").write_text(json.dumps(status))
            job += 1
        truth.accuracy[label] = mat
    tracker.end_parent(str(out), parent_id, job, n_fail)
    return truth
