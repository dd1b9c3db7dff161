"""Tiny helpers shared by benchmarks: timing and JSON output under outputs/bench/."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

#: Where benchmarks write their JSON and plots.
OUT = Path(__file__).resolve().parent.parent / "outputs" / "bench"


def timeit(fn: Callable[[], Any], repeat: int = 3) -> dict[str, float]:
    """Run ``fn`` ``repeat`` times: best and median wall seconds, and CPU seconds of the best run.

    CPU time (all threads of this process) is less sensitive than wall time
    to other processes competing for the cores.
    """
    walls, cpus = [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    i = int(np.argmin(walls))
    return {"best_s": walls[i], "median_s": float(np.median(walls)), "cpu_s": cpus[i]}


def machine() -> dict[str, Any]:
    """The machine a timing was taken on: CPU model and SIMD flags, cores, load average, Python, and
    the GPU if torch sees one (timings are never carried from one machine to another). The CPU part
    is the one every MLflow run records (:mod:`sphri.tracking.machine`)."""
    import platform

    from sphri.tracking.machine import cpu

    info: dict[str, Any] = {
        **cpu(),
        "cpu_count": os.cpu_count(),
        "loadavg_1min": os.getloadavg()[0],
        "python": platform.python_version(),
    }
    try:
        import torch

        info["torch"] = torch.__version__
        info["gpu"] = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    except ImportError:
        info["gpu"] = None
    return info


def write_json(name: str, data: dict[str, Any]) -> Path:
    """Write ``outputs/bench/<name>.json`` (pretty, numpy scalars converted)."""
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.json"

    def conv(x):
        if isinstance(x, np.generic):
            return x.item()
        if isinstance(x, np.ndarray):
            return x.tolist()
        raise TypeError(f"not JSON serializable: {type(x)}")

    path.write_text(json.dumps(data, indent=2, default=conv) + "\n")
    return path


@contextmanager
def figure(path: Path, ncols: int, figsize: tuple[float, float], dpi: int = 110) -> Iterator[tuple[Any, Any]]:
    """``(fig, axes)``: one row of ``ncols`` axes on the headless Agg backend; on leaving the block the figure is
    laid out and saved to ``path`` (closed in any case)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, ncols, figsize=figsize)
    try:
        yield fig, axes
        fig.tight_layout()
        fig.savefig(path, dpi=dpi)
    finally:
        plt.close(fig)


def begin(doc: str, quick_help: str, argv: list[str] | None) -> tuple[bool, dict[str, Any], float]:
    """Start a benchmark whose only option is ``--quick`` (its smallest size): parse the command line, set
    logging to errors only; returns (whether ``--quick`` was given, :func:`machine` now, ``time.perf_counter()``),
    what :func:`run_info` reports from."""
    import argparse
    import logging

    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help=quick_help)
    quick = ap.parse_args(argv).quick
    logging.basicConfig(level=logging.ERROR)
    return quick, machine(), time.perf_counter()


def run_info(start: dict[str, Any], quick: bool, t0: float, **extra: Any) -> dict[str, Any]:
    """A benchmark JSON's ``info``: the machine at the start (:func:`machine`), the mode, the wall seconds since
    ``t0`` (``time.perf_counter``), the load average at the end, then ``extra``."""
    return {
        **start,
        "mode": "quick" if quick else "full",
        "wall_s": time.perf_counter() - t0,
        "loadavg_1min_end": machine()["loadavg_1min"],
        **extra,
    }


def scenario_study(overrides: tuple[str, ...] = ("+experiment=scenario_study", "robot=reachy2")):
    """(hand, robot, session generator, priors table) of the scenario study composed from ``overrides``: what the
    session benches regenerate touches with, with the study's own random streams."""
    from hydra.utils import instantiate

    from sphri.config import compose
    from sphri.sessions import synthetic as syn

    cfg = compose(list(overrides))
    hand, robot = instantiate(cfg.hand).build(), instantiate(cfg.robot).build()
    gen = instantiate(cfg.data)
    table = syn.load_priors(gen.priors, [p.name for p in robot.parts], list(robot.tree.joint_names))
    return hand, robot, gen, table


def header(script: str, doc: str | None) -> dict[str, Any]:
    """The first keys of a benchmark JSON: date, :func:`machine`, the command that made it (``script`` with this
    process's arguments) and what it measures (the first line of the script's ``doc``)."""
    import sys

    return {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "machine": machine(),
        "command": f"python bench/{script} " + " ".join(sys.argv[1:]),
        "what": (doc or "").splitlines()[0],
    }
