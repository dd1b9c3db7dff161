"""Every experiment in conf/experiment/: its jobs compose and validate (all of them, or for long
numeric ranges the ends of each range with every other value), and a covering set of its jobs runs
through the whole chain in debug mode."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hydra import compose as hydra_compose
from hydra import initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from sweeper_jobs import hydras_own, plain_task, sweeper

from sphri import pipeline
from sphri.cache import StageCache
from sphri.config import CONF_DIR, compose, register_schemas

#: Sweeps of the classification chain (the scenario study, run by sphri.coverage, has its own tests in tests/sessions).
EXPERIMENTS = sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml") if "scenario_study:" not in p.read_text())
FAST = ["+debug=fast", "tracking.enabled=false"]


def sweep_params(name: str) -> dict[str, list[str]]:
    """The experiment's swept keys and their values, as Hydra's basic sweeper expands them."""
    register_schemas()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = hydra_compose("config", overrides=[f"experiment={name}"], return_hydra_config=True)
    return swept_values(name, dict(cfg.hydra.sweeper.params or {}))


def swept_values(name: str, params: dict[str, str]) -> dict[str, list[str]]:
    """``hydra.sweeper.params`` of experiment ``name`` -> each swept key's values."""
    assert params, f"conf/experiment/{name}.yaml sweeps nothing (hydra.sweeper.params is empty)"
    parsed = OverridesParser.create().parse_overrides([f"{k}={v}" for k, v in params.items()])
    return {
        o.get_key_element(): list(o.sweep_string_iterator())
        if o.is_sweep_override()
        else [o.get_value_element_as_str()]
        for o in parsed
    }


def all_jobs(params: dict[str, list[str]]) -> list[list[str]]:
    """Every job's overrides (the full product)."""
    jobs: list[list[str]] = [[]]
    for key, values in params.items():
        jobs = [job + [f"{key}={v}"] for job in jobs for v in values]
    return jobs


def _numeric(values: list[str]) -> bool:
    try:
        [float(v) for v in values]
    except ValueError:
        return False
    return True


def covering_jobs(params: dict[str, list[str]], numeric_ends: bool = False) -> list[list[str]]:
    """A few jobs in which every value of every key appears (long numeric ranges: their ends;
    ``numeric_ends``: the ends of every numeric range, a component or other word every value)."""
    picks = {k: (v if len(v) <= 6 and not (numeric_ends and _numeric(v)) else [v[0], v[-1]]) for k, v in params.items()}
    first = {k: v[0] for k, v in picks.items()}
    jobs, seen = [], set()
    for key, values in picks.items():
        for value in values:
            job = tuple(f"{k}={value if k == key else first[k]}" for k in picks)
            if job not in seen:
                seen.add(job)
                jobs.append(list(job))
    return jobs


def test_there_are_the_documented_experiments():
    assert {"resolution_sweep", "layout_compare", "morphology_compare", "noise_robustness"} <= set(EXPERIMENTS)


def test_resolution_sweep_is_the_studys_grid():
    params = sweep_params("resolution_sweep")
    assert params["layout.res"] == [str(r) for r in range(1, 51)]
    assert params["model"] == ["rf", "cnn_gru"]


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_every_job_of_every_experiment_validates(name: str):
    """Every job as ``python -m sphri -m +experiment=NAME`` checks it before starting any: the sweeper's own
    expansion, composition (checked here equal to Hydra's on the last job, and on a whole sweep in
    test_sweeps_store) and validation. Sweeps of more than 30 jobs (long numeric ranges): the jobs holding
    the ends of each range with every other value."""
    with sweeper([f"experiment={name}"]) as (found, loader, jobs):
        params = swept_values(name, found.params or {})
        assert len(jobs) == len(all_jobs(params))
        if len(jobs) > 30:
            wanted = [set(job) for job in covering_jobs(params)]
            jobs = [job for job in jobs if any(w <= set(job) for w in wanted)]
            assert len(jobs) == len(wanted)
        assert found.invalid_points(jobs) == []  # (job number, overrides, the one-line error) of each failure
        # the config the sweeper composed for the last job (kept for its run) is Hydra's own for that job
        assert plain_task(found._configs[len(jobs) - 1]) == hydras_own(found, loader, jobs[-1]), jobs[-1]


@pytest.mark.parametrize("name", EXPERIMENTS)
def test_experiment_smoke_runs_in_debug_mode(name: str, tmp_path: Path):
    params = sweep_params(name)
    cache = StageCache(tmp_path)
    ran = []
    # `make test`: every component, and numbers at their range's ends (the same code path between);
    # SPHRI_DEEP_TESTS=1 (`make test-all`): every value of a range of up to 6 values too
    for job in covering_jobs(params, numeric_ends=not os.environ.get("SPHRI_DEEP_TESTS")):
        extra = ["layout.res=3"] if name == "resolution_sweep" and job[0] != "model=rf" else []
        if extra:  # the CNN-GRU at res 50 is not a smoke test; the model is, at a small grid
            job = [o for o in job if not o.startswith("layout.res=")]
        cfg = compose([f"+experiment={name}", *FAST, f"cache.dir={tmp_path}", *job, *extra])
        result = pipeline.run(cfg, cache)
        assert len(result.cv.folds) == 3, (name, job)
        assert 0.0 <= result.summary()["accuracy_mean"] <= 1.0
        ran.append(job)
    covered = {o for job in ran for o in job}
    for key, _values in params.items():
        assert any(o.startswith(f"{key}=") for o in covered), f"{name}: {key} never varied in the smoke run"
