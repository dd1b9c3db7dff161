"""The whole chain in debug mode, and what the stage cache recomputes."""

from __future__ import annotations

import os
from pathlib import Path

import forked_cli
import numpy as np
import pytest

from sphri import pipeline
from sphri.cache import StageCache
from sphri.config import compose

FAST = ["+debug=fast", "tracking.enabled=false"]


def run(cache: StageCache, *overrides: str) -> pipeline.RunResult:
    cfg = compose([*FAST, f"cache.dir={cache.root}", *overrides])
    return pipeline.run(cfg, cache)


def sources(result: pipeline.RunResult) -> dict[str, str]:
    return {name: rec.source for name, rec in result.stages.items()}


def test_debug_chain_runs_end_to_end(tmp_path: Path):
    result = run(StageCache(tmp_path), "layout.res=6")
    assert set(sources(result).values()) == {"computed"}
    assert len(result.cv.folds) == 3, "LOSO over the 3 debug participants"
    s = result.summary()
    assert 0.0 <= s["accuracy_mean"] <= 1.0
    assert result.meta.synthetic is True
    assert result.meta.resolution["n_taxels"] > 0
    for fold in result.cv.folds:
        assert fold.confusion.shape == (8, 8)
        assert np.isfinite(fold.accuracy)


def test_resolution_change_reuses_data_and_contact(tmp_path: Path):
    cache = StageCache(tmp_path)
    r4 = run(cache, "layout.res=4")
    assert sources(r4)["contact"] == "computed"
    r8 = run(cache, "layout.res=8")
    s8 = sources(r8)
    assert s8["data"] == "cache" and s8["contact"] == "cache" and s8["plan"] == "cache"
    assert s8["layout"] == "computed" and s8["encode"] == "computed" and s8["evaluate"] == "computed"
    assert r8.meta.resolution["n_taxels"] > r4.meta.resolution["n_taxels"]
    # the same command again recomputes nothing and does not even load contact
    again = sources(run(cache, "layout.res=8"))
    assert again["evaluate"] == "cache"
    assert "computed" not in again.values()
    assert again["contact"] == "skipped" and again["data"] == "skipped"
    assert not {"sessions", "body_contact"} & set(again), "the study's rows are no stage of a gesture job"


def test_contact_change_recomputes_contact_and_below(tmp_path: Path):
    cache = StageCache(tmp_path)
    run(cache, "layout.res=4")
    changed = sources(run(cache, "layout.res=4", "contact=spheres"))
    assert changed["data"] == "cache"
    for stage in ("contact", "plan", "encode", "noise", "evaluate"):
        assert changed[stage] == "computed", stage
    assert changed["surface"] == "cache" and changed["layout"] == "cache"


def test_density_layout_from_contacts_is_keyed_on_them(tmp_path: Path):
    cache = StageCache(tmp_path)
    dens = ["layout=density", "encoder=coverage", "layout.res=4"]
    first = run(cache, *dens)
    assert first.meta.resolution["layout_kind"] == "density"
    # the run's seed draws the density layout's candidate points (conf/layout/density.yaml: seed: ${seed})
    assert sources(run(cache, *dens, "seed=1"))["layout"] == "computed"
    # other contacts, another placement: the layout is recomputed (a grid layout would be reused)
    assert sources(run(cache, *dens, "contact=spheres"))["layout"] == "computed"


def test_cache_disabled_computes_everything(tmp_path: Path):
    cfg = compose([*FAST, f"cache.dir={tmp_path}", "cache.enabled=false", "layout.res=3"])
    result = pipeline.run(cfg)
    assert set(sources(result).values()) == {"computed"}
    assert not any(tmp_path.iterdir())


def test_wrong_value_fails_before_any_stage(tmp_path: Path):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = forked_cli.run(["-m", "sphri", "layout.res=0", f"output_dir={tmp_path}"], tmp_path, env, 300)
    assert proc.returncode == 2
    assert "layout.res" in proc.stderr
    assert "computing" not in proc.stdout + proc.stderr
    assert not (tmp_path / "cache").exists()


def test_synthetic_data_is_keyed_on_the_robot(tmp_path: Path):
    """Synthetic gestures are placed on the robot: another robot is other data."""
    cache = StageCache(tmp_path)
    nao = run(cache, "robot=nao_child", "layout.res=3")
    reachy = sources(run(cache, "robot=reachy", "layout.res=3"))
    assert reachy["data"] == "computed"
    assert nao.stages["data"].key != run(cache, "robot=reachy", "layout.res=3").stages["data"].key


def test_config_hash_follows_component_versions(monkeypatch):
    """Resume finds finished jobs by this hash: a changed component must not reuse their results."""
    from sphri.layout.grid import HexLayout

    cfg = compose(["layout=hex", *FAST])
    before = pipeline.config_hash(cfg)
    assert pipeline.config_hash(compose(["layout=hex", *FAST])) == before
    assert pipeline.component_versions(cfg)["layout"] == HexLayout.VERSION
    monkeypatch.setattr(HexLayout, "VERSION", HexLayout.VERSION + "-changed")
    assert pipeline.config_hash(cfg) != before
    # tracking is not part of a job's result
    assert "tracking" not in pipeline.component_versions(cfg)


def test_non_finite_encoder_frames_stop_at_the_stage_boundary():
    """A float encoder over a degenerate chart can divide by zero: the encode stage names it, one line,
    before noise, filter or a model ever see the frames."""
    from types import SimpleNamespace

    from sphri.errors import kind_of
    from sphri.finite import NonFiniteError
    from sphri.pipeline import COMPUTE

    class ZeroScaleEncoder:
        def encode(self, contacts, link, surface, layout, frame_index):
            values = np.zeros((len(frame_index), 4), dtype=np.float32)
            with np.errstate(divide="ignore", invalid="ignore"):
                values[1] = values[1] / 0.0  # 0/0: NaN
            return SimpleNamespace(values=values)

    plan = SimpleNamespace(selected_frames=lambda: np.arange(3))
    p = SimpleNamespace(
        get=lambda name: plan if name == "plan" else None,
        link=lambda: None,
        components={"encoder": ZeroScaleEncoder()},
    )
    with pytest.raises(NonFiniteError) as err:
        COMPUTE["encode"].compute(p)
    assert str(err.value) == (
        "encoder=ZeroScaleEncoder frames: 4 of 12 values are not finite (4 NaN, 0 infinite; shape (3, 4))"
    )
    assert kind_of(err.value) == "numerical error"
    ok = SimpleNamespace(encode=lambda *a: SimpleNamespace(values=np.ones((3, 4), dtype=np.uint8)))
    assert COMPUTE["encode"].compute(SimpleNamespace(**{**vars(p), "components": {"encoder": ok}})).values.sum() == 12
