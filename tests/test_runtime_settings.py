"""One notion of "same experiment": settings that cannot change a result (threads, workers,
progress, chunk sizes; declared with ``sphri.config.setting(..., runtime=True)``) change neither the
config hash nor any stage key, so changing them never recomputes or reruns anything."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import forked_cli
import pytest
import yaml
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from sphri.cache import StageCache
from sphri.config import CONF_DIR, STAGE_GROUPS, compose, register_schemas, runtime_fields
from sphri.pipeline import config_hash, make_pipeline

REPO = Path(__file__).resolve().parents[1]


def _keys(overrides: list[str], tmp_path: Path) -> tuple[str, dict[str, str]]:
    cfg = compose(["+debug=fast", f"output_dir={tmp_path}", *overrides])
    p = make_pipeline(cfg, StageCache(tmp_path / "cache", enabled=False))
    for last in ("evaluate", "body_contact"):  # wires the chain and the study's rows
        p.key(last)
    return config_hash(cfg), {name: node.key for name, node in p.nodes.items()}


def _changed(value):
    if isinstance(value, bool):
        return not value
    if value is None:
        return 2
    if isinstance(value, str):  # a choice (cv.backend); a new string setting names its other value here
        return {"local": "ray"}[value]
    return value + 3


def _schema_of(group: str, path: Path):
    """The schema dataclass a component YAML opts into (its ``/schema_<group>_<name>@_here_`` default), or None."""
    defaults = (yaml.safe_load(path.read_text()) or {}).get("defaults", [])
    names = [
        d[1:].removesuffix("@_here_") for d in defaults if isinstance(d, str) and d.startswith(f"/schema_{group}_")
    ]
    if not names:
        return None
    return OmegaConf.get_type(ConfigStore.instance().repo[names[0] + ".yaml"].node)


def _runtime_settings() -> list[tuple[str, str, str]]:
    """(group, option, field) for every runtime field of every component YAML in conf/."""
    register_schemas()
    found = []
    for group in STAGE_GROUPS:
        if group == "tracking" or not (CONF_DIR / group).is_dir():
            continue
        for path in sorted((CONF_DIR / group).glob("*.yaml")):
            found += [(group, path.stem, name) for name in runtime_fields(_schema_of(group, path))]
    return found


RUNTIME = _runtime_settings()


def test_the_known_runtime_settings_are_declared():
    names = {f"{g}.{f}" for g, _, f in RUNTIME}
    assert {
        "cv.workers",
        "cv.threads_per_worker",
        "cv.progress",
        "model.n_jobs",
        "model.threads",
        "contact.chunk_frames",
    } <= names, names


@pytest.mark.parametrize("group,option,name", RUNTIME, ids=[f"{g}={o}.{f}" for g, o, f in RUNTIME])
def test_a_runtime_setting_changes_neither_the_hash_nor_a_stage_key(tmp_path, group, option, name):
    default = compose(["+debug=fast", f"{group}={option}"])[group][name]
    base = _keys([f"{group}={option}"], tmp_path)
    other = _keys([f"{group}={option}", f"{group}.{name}={_changed(default)}"], tmp_path)
    assert other[0] == base[0], "config hash changed"
    assert other[1] == base[1], "stage keys changed"


@pytest.mark.parametrize(
    "override,stages",
    [
        ("layout.res=5", {"layout", "encode", "noise", "filter", "evaluate"}),
        ("model.n_estimators=7", {"evaluate"}),
        ("contact.margin_m=0.001", {"contact", "plan", "encode", "noise", "filter", "evaluate"}),
    ],
)
def test_a_result_setting_changes_the_hash_and_its_stages(tmp_path, override, stages):
    h0, k0 = _keys([], tmp_path)
    h1, k1 = _keys([override], tmp_path)
    assert h1 != h0
    assert {s for s in k0 if k0[s] != k1[s]} >= stages


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    return forked_cli.run(["-m", "sphri", *args], cwd, env, 900)


def _job_runs(out: Path) -> list:
    from mlflow.tracking import MlflowClient

    from sphri.tracking.mlflow_tracker import default_uri

    client = MlflowClient(default_uri(out))
    exp = client.get_experiment_by_name("sphri-debug")
    return [r for r in client.search_runs([exp.experiment_id]) if r.data.tags.get("sphri.kind") == "job"]


def test_a_rerun_that_changes_nothing_is_recorded_once(tmp_path):
    out = tmp_path / "out"
    args = ["+debug=fast", "layout.res=3", f"output_dir={out}"]
    first = _run(args, tmp_path)
    assert first.returncode == 0, (first.stdout + first.stderr)[-3000:]
    assert "accuracy" in first.stdout and "SYNTHETIC" in first.stdout
    again = _run([*args, "cv.progress=false"], tmp_path)
    assert again.returncode == 0, (again.stdout + again.stderr)[-3000:]
    log = again.stdout + again.stderr
    assert "from cache" in log and "computing" not in log, log[-3000:]
    runs = _job_runs(out)
    assert len(runs) == 1, [r.info.run_id for r in runs]
    assert runs[0].data.tags["sphri.reruns"] == "1"
    assert f"already recorded: MLflow run {runs[0].info.run_id}" in again.stdout
    # another experiment is a run of its own: tests/test_tracking.py's sweep (four resolutions, four runs)


def test_the_run_seed_reaches_random_layouts(tmp_path):
    for layout in ("random", "density"):
        a = compose(["+debug=fast", f"layout={layout}", "encoder=coverage", "seed=3"])
        assert a.layout.seed == 3
        _, k0 = _keys([f"layout={layout}", "encoder=coverage"], tmp_path)
        _, k1 = _keys([f"layout={layout}", "encoder=coverage", "seed=3"], tmp_path)
        assert k0["layout"] != k1["layout"]
    grid0 = _keys(["layout=grid"], tmp_path)[1]["layout"]
    assert _keys(["layout=grid", "seed=3"], tmp_path)[1]["layout"] == grid0  # a grid is the same skin for every seed
