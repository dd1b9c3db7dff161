"""The requirement rule's promise and the smallest tolerance it certifies, on simulated curves.

Curves: :mod:`sphri.report.simulate` (the 16-point grid of the requirement map; shapes flat, saturating,
clean_row, dip), ``scores = mu + participant level (sd 0.06) + participant x resolution effect (sd 0.02) + rerun
noise per seed (sd 0.026)``. For each shape, 200 seeded draws with 18 participants and 3 seeds: the share of draws
whose reported pitch breaks the promise (some point from it on is truly more than the tolerance used below the
true best) and the median tolerance used, asked for 1 point. Then the smallest certifiable tolerance T* (median
and 90th percentile over 200 draws of the flat curve) for 6 to 54 participants and 1, 3 and 5 seeds.

``--old-rule REV`` also measures the envelope rule of git revision REV (its ``envelope_saturation`` with a 1-point
tolerance and its noise floor; its promise: within the tolerance it reports) on the same draws.

Writes ``outputs/bench/certifiable_t.json``. Run: ``python bench/certifiable_t.py [--old-rule main]``.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, write_json  # noqa: E402

from sphri.report.saturation import certified_saturation, certify_index  # noqa: E402
from sphri.report.simulate import GRID, SHAPES, Noise, draw, violation_rate  # noqa: E402

DRAWS = 200


def _old_rule(rev: str):
    """``envelope_saturation`` of ``sphri/report/saturation.py`` at git revision ``rev``, as a (index, T) rule."""
    root = Path(__file__).resolve().parent.parent
    src = subprocess.run(
        ["git", "-C", str(root), "show", f"{rev}:sphri/report/saturation.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = Path(tempfile.mkdtemp()) / "old_saturation.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("old_saturation", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["old_saturation"] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)

    def rule(scores: np.ndarray) -> tuple[int, float]:
        sat, _ = mod.envelope_saturation(scores, "0.01", n_boot=0)
        return sat.index, sat.tolerance

    return rule


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--old-rule", default=None, help="git revision whose envelope rule to measure on the same draws")
    args = ap.parse_args()
    noise = Noise()
    out: dict = {"machine": machine(), "draws": DRAWS, "noise": noise.__dict__, "grid": GRID, "promise": []}
    old = _old_rule(args.old_rule) if args.old_rule else None
    for name, f in SHAPES.items():
        mu = f(GRID)
        rate, t = violation_rate(lambda s: certify_index(s, 0.01), mu, noise, DRAWS, seed=11)
        row = {"shape": name, "mu": mu, "violation_rate": rate, "median_tolerance": t}
        if old is not None:
            row["old_rule"] = args.old_rule
            row["old_violation_rate"], row["old_median_tolerance"] = violation_rate(old, mu, noise, DRAWS, seed=11)
        out["promise"].append(row)
        print(row)
    out["certifiable"] = []
    flat = SHAPES["flat"](GRID)
    for seeds in (1, 3, 5):
        for p in (6, 12, 18, 24, 36, 54):
            rng = np.random.default_rng(100 + p + 1000 * seeds)
            n = Noise(participants=p, seeds=seeds)
            ts = [certified_saturation(draw(flat, n, rng), "0.01", n_boot=0)[1].certifiable for _ in range(DRAWS)]
            row = {
                "participants": p,
                "seeds": seeds,
                "t_star_median": float(np.median(ts)),
                "t_star_p90": float(np.quantile(ts, 0.9)),
            }
            out["certifiable"].append(row)
            print(row)
    print(write_json("certifiable_t", out))


if __name__ == "__main__":
    main()
